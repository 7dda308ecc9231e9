"""The a5_cubemap environment emitter (SPEC A.4): major-axis face choice (ties x, then y), the u/v table,
and the A.4 texture lookup on each face."""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pytest
from helpers import read_bmp24, write_image

FACES = ["left", "right", "up", "down", "front", "back"]


def _face_pixels(k: int) -> np.ndarray:
    """2x2 face number k: red = 40k + (0, 10 / 20, 30) (top row / bottom row), green = 40k, blue = 200."""
    red = np.array([[0, 10], [20, 30]]) + 40 * k
    return np.stack([red, np.full((2, 2), 40 * k), np.full((2, 2), 200)], axis=2).astype(np.uint8)


@pytest.fixture
def cube_dir(tmp_path: Path) -> Path:
    folder = tmp_path / "cube"
    folder.mkdir()
    for k, face in enumerate(FACES):
        write_image(folder / f"{face}.{'bmp' if k % 2 else 'png'}", _face_pixels(k))  # mixed extensions
    return folder


def _load(folder: Path):
    import mitsuba as mi

    return mi.load_dict({"type": "a5_cubemap", "filename": str(folder)})


def _lookup(em, dirs: list[tuple[float, float, float]]) -> np.ndarray:
    import mitsuba as mi

    d = mi.Vector3f(*(np.array([p[k] for p in dirs], dtype=np.float32) for k in range(3)))
    return np.asarray(em.lookup(d)).T * 255


def _bilinear(p: np.ndarray, x: float, y: float) -> np.ndarray:
    """A.4 with clamping, for an (H, W, C) array."""
    h, w = p.shape[:2]
    ix, iy = int(x), int(y)
    a, b = x - ix, y - iy
    cx = [min(max(i, 0), w - 1) for i in (ix, ix + 1)]
    cy = [min(max(i, 0), h - 1) for i in (iy, iy + 1)]
    p = p.astype(np.float64)
    return (
        (1 - a) * (1 - b) * p[cy[0], cx[0]]
        + a * (1 - b) * p[cy[0], cx[1]]
        + (1 - a) * b * p[cy[1], cx[0]]
        + a * b * p[cy[1], cx[1]]
    )


def test_a4_cubemap_flags(variant: str, cube_dir: Path) -> None:
    import mitsuba as mi

    em = _load(cube_dir)
    assert em.is_environment()
    assert mi.has_flag(em.flags(), mi.EmitterFlags.Infinite)
    scene = mi.load_dict({"type": "scene", "bg": em})
    assert scene.environment() is not None


# Face centres: u = v = 1/2 gives x = y = 1 on a 2x2 face, i.e. exactly the bottom-right pixel (40k + 30).
CENTRES = {
    "right": (1, 0, 0),
    "left": (-1, 0, 0),
    "up": (0, 1, 0),
    "down": (0, -1, 0),
    "front": (0, 0, 1),
    "back": (0, 0, -1),
}
# (u, v) = (0.3, 0.9) on each face, by inverting the A.4 table with 2u-1 = -0.4, 2v-1 = 0.8.
OFF_CENTRE = {
    "right": (1, 0.8, -0.4),  # z/x = 2u-1, y/x = 2v-1
    "left": (-1, 0.8, 0.4),  # z/x = 2u-1, y/x = 1-2v
    "up": (-0.4, 1, 0.8),  # x/y = 2u-1, z/y = 2v-1
    "down": (-0.4, -1, 0.8),  # x/y = 1-2u, z/y = 1-2v
    "front": (0.4, 0.8, 1),  # x/z = 1-2u, y/z = 2v-1
    "back": (0.4, 0.8, -1),  # x/z = 2u-1, y/z = 1-2v
}


def test_a4_cubemap_face_centres(variant: str, cube_dir: Path) -> None:
    em = _load(cube_dir)
    got = _lookup(em, [CENTRES[f] for f in FACES])
    for k, face in enumerate(FACES):
        assert got[k] == pytest.approx([40 * k + 30, 40 * k, 200], abs=1e-3), face


def test_a4_cubemap_off_centre(variant: str, cube_dir: Path) -> None:
    """u = 0.3, v = 0.9: x = 0.6, y = 0.2, so red = 0.32 P00 + 0.48 P10 + 0.08 P01 + 0.12 P11."""
    em = _lookup(_load(cube_dir), [OFF_CENTRE[f] for f in FACES])
    for k, face in enumerate(FACES):
        red = 0.32 * (40 * k) + 0.48 * (40 * k + 10) + 0.08 * (40 * k + 20) + 0.12 * (40 * k + 30)
        assert em[k] == pytest.approx([red, 40 * k, 200], abs=2e-3), face


def test_a4_cubemap_ties(variant: str, cube_dir: Path) -> None:
    """|x| = |y| goes to x, |y| = |z| > |x| goes to y, |x| = |y| = |z| goes to x."""
    got = _lookup(_load(cube_dir), [(1, 1, 0), (0, 1, 1), (-1, -1, -1), (1, 0, 1), (0, -2, 2)])
    right, left, up, down = 1, 0, 2, 3
    assert got[0] == pytest.approx([40 * right + 10, 40 * right, 200], abs=1e-3)  # u=.5, v=1: top-right
    assert got[1] == pytest.approx([40 * up + 10, 40 * up, 200], abs=1e-3)  # u=.5, v=1
    assert got[2] == pytest.approx([40 * left + 30, 40 * left, 200], abs=1e-3)  # u=1, v=0: clamped corner
    assert got[3] == pytest.approx([40 * right + 30, 40 * right, 200], abs=1e-3)  # u=1, v=.5
    assert got[4] == pytest.approx([40 * down + 10, 40 * down, 200], abs=1e-3)  # u=.5, v=1-(-1+1)/2=1


def test_a4_cubemap_eval_uses_minus_wi(variant: str, cube_dir: Path) -> None:
    """eval(si) looks up -si.wi: a missed ray travelling +z sees the front face."""
    import drjit as dr
    import mitsuba as mi

    em = _load(cube_dir)
    si = dr.zeros(mi.SurfaceInteraction3f, 1)
    si.wi = mi.Vector3f(0, 0, -3)  # ray direction (0, 0, 3), any length
    assert np.asarray(em.eval(si)).ravel() * 255 == pytest.approx([40 * 4 + 30, 160, 200], abs=1e-3)


def test_a4_cubemap_sample_direction(variant: str, cube_dir: Path) -> None:
    """Uniform sphere sampling: pdf = 1/4pi, value = lookup(d)/pdf, consistent with pdf_direction."""
    import mitsuba as mi

    em = _load(cube_dir)
    import drjit as dr

    it = dr.zeros(mi.Interaction3f, 4)
    ds, value = em.sample_direction(it, mi.Point2f([0.1, 0.4, 0.6, 0.9], [0.2, 0.5, 0.7, 0.95]))
    assert np.allclose(np.asarray(ds.pdf), 1 / (4 * math.pi))
    assert np.allclose(np.asarray(em.pdf_direction(it, ds)), 1 / (4 * math.pi))
    assert not np.any(np.asarray(ds.delta))
    want = np.asarray(em.lookup(ds.d)).T * 4 * math.pi
    assert np.allclose(np.asarray(value).T, want, rtol=1e-5)


def test_a4_cubemap_missing_face(variant: str, cube_dir: Path, tmp_path: Path) -> None:
    partial = tmp_path / "partial"
    shutil.copytree(cube_dir, partial)
    next(partial.glob("up.*")).unlink()
    with pytest.raises(Exception, match="face 'up' not found"):
        _load(partial)
    with pytest.raises(Exception, match="not a folder"):
        _load(tmp_path / "nowhere")


def test_a4_cubemap_church_spot_check(variant: str, scenes_dir: Path) -> None:
    """The church map against an independent BMP decoder and the A.4 table written out in Python."""
    folder = scenes_dir / "tex" / "church"
    faces = {f: read_bmp24(folder / f"{f}.bmp") for f in FACES}
    dirs = [(0.3, -0.2, -1.0), (1.0, 0.45, 0.1), (-0.7, 0.2, 0.5), (0.1, 1.0, -0.3), (-0.2, -1.0, 0.6), (0.2, 0.3, 1.0)]
    want = []
    for d in dirs:
        n = math.sqrt(sum(c * c for c in d))
        x, y, z = (c / n for c in d)
        if abs(x) >= abs(y) and abs(x) >= abs(z):
            face, u, v = (
                ("right", (z / x + 1) / 2, (y / x + 1) / 2) if x > 0 else ("left", (z / x + 1) / 2, 1 - (y / x + 1) / 2)
            )
        elif abs(y) >= abs(z):
            face, u, v = (
                ("up", (x / y + 1) / 2, (z / y + 1) / 2)
                if y > 0
                else ("down", 1 - (x / y + 1) / 2, 1 - (z / y + 1) / 2)
            )
        else:
            face, u, v = (
                ("front", 1 - (x / z + 1) / 2, (y / z + 1) / 2)
                if z > 0
                else ("back", (x / z + 1) / 2, 1 - (y / z + 1) / 2)
            )
        img = faces[face]
        want.append(_bilinear(img, u * img.shape[1], (1 - v) * img.shape[0]))
    got = _lookup(_load(folder), dirs)
    assert np.allclose(got, np.array(want), atol=0.05)  # float32 vs double u, v on a 512x512 face
    assert np.ptp(np.array(want)) > 20  # the probes see different parts of the map

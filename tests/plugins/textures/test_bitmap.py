"""The a5_bitmap texture and the shared A.4 lookup (SPEC A.4): x = uW, y = (1-v)H, clamped bilinear, /255."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from helpers import read_bmp24, write_image

# 3 wide, 2 high, row 0 = top. Red channel below; green = 255 - red; blue = 7.
RED = np.array([[0, 30, 60], [90, 120, 240]], dtype=np.uint8)


def _image() -> np.ndarray:
    return np.stack([RED, 255 - RED, np.full_like(RED, 7)], axis=2)


def _eval(tex, uv: list[tuple[float, float]]) -> np.ndarray:
    import drjit as dr
    import mitsuba as mi

    si = dr.zeros(mi.SurfaceInteraction3f, len(uv))
    si.uv = mi.Point2f([p[0] for p in uv], [p[1] for p in uv])
    return np.asarray(tex.eval(si)).T


def _load(path: Path):
    import mitsuba as mi

    return mi.load_dict({"type": "a5_bitmap", "filename": str(path)})


@pytest.mark.parametrize("ext", ["bmp", "png"])
def test_a4_bitmap_hand_values(variant: str, tmp_path: Path, ext: str) -> None:
    tex = _load(write_image(tmp_path / f"t.{ext}", _image()))
    uv = [(0.0, 1.0), (0.5, 0.5), (1.0, 0.0), (0.25, 0.75), (0.9, 0.9)]
    red = [
        0.0,  # x=0, y=0: the top-left pixel
        (120 + 240) / 2,  # x=1.5, y=1: a=0.5, b=0 on the bottom row
        240.0,  # x=3, y=2: both neighbours clamped to the bottom-right pixel
        0.125 * 0 + 0.375 * 30 + 0.125 * 90 + 0.375 * 120,  # x=0.75, y=0.5
        0.8 * 60 + 0.2 * 240,  # x=2.7 (right column clamped), y=0.2
    ]
    got = _eval(tex, uv)
    want_red = np.array(red) / 255
    assert np.allclose(got[:, 0], want_red, atol=2e-6)
    assert np.allclose(got[:, 1], 1 - want_red, atol=2e-6)  # green = 255 - red, same weights
    assert np.allclose(got[:, 2], 7 / 255, atol=1e-7)


def test_a4_bitmap_no_half_texel_offset_no_wrap(variant: str, tmp_path: Path) -> None:
    """Pixel corners (not centres) sit on integer x; u outside [0, 1] clamps instead of wrapping."""
    tex = _load(write_image(tmp_path / "t.png", _image()))
    got = _eval(tex, [(1 / 3, 1.0), (1.5, 1.0), (-0.5, 0.0)])[:, 0] * 255
    assert got[0] == pytest.approx(30, abs=1e-3)  # x = 1: exactly pixel 1 of the top row
    assert got[1] == pytest.approx(60, abs=1e-4)  # x = 4.5, clamped to the last column
    # x = -1.5: (int) truncates to -1, a = -0.5; both taps clamp to column 0, weights still sum to 1
    assert got[2] == pytest.approx(90, abs=1e-4)


def test_a4_bitmap_course_texture(variant: str, scenes_dir: Path) -> None:
    """head.bmp against an independent BMP decoder and the A.4 formula written out in numpy."""
    path = scenes_dir / "tex" / "head.bmp"
    img = read_bmp24(path).astype(np.float64)
    h, w = img.shape[:2]
    uv = [(0.37, 0.61), (0.5, 0.5), (0.83, 0.12), (0.05, 0.97)]
    want = []
    for u, v in uv:
        x, y = np.float32(u) * np.float32(w), (np.float32(1) - np.float32(v)) * np.float32(h)
        ix, iy = int(x), int(y)
        a, b = float(x) - ix, float(y) - iy
        cx = [min(max(ix, 0), w - 1), min(max(ix + 1, 0), w - 1)]
        cy = [min(max(iy, 0), h - 1), min(max(iy + 1, 0), h - 1)]
        c = (
            (1 - a) * (1 - b) * img[cy[0], cx[0]]
            + a * (1 - b) * img[cy[0], cx[1]]
            + (1 - a) * b * img[cy[1], cx[0]]
            + a * b * img[cy[1], cx[1]]
        )
        want.append(c / 255)
    got = _eval(_load(path), uv)
    assert np.allclose(got, np.array(want), atol=1e-5)
    assert np.ptp(np.array(want)) > 0.05  # the probes do not all land on one flat colour


def test_a4_bitmap_missing_file(variant: str, tmp_path: Path) -> None:
    missing = tmp_path / "nope.bmp"
    with pytest.raises(Exception, match=r"filename.*nope\.bmp"):
        _load(missing)


def test_a4_bitmap_corrupt_file(variant: str, tmp_path: Path) -> None:
    bad = tmp_path / "bad.bmp"
    bad.write_bytes(b"BM this is not a bitmap")
    with pytest.raises(Exception, match=r"filename.*bad\.bmp"):
        _load(bad)

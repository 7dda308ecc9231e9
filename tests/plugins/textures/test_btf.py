"""View-dependent textures (docs/EXTENSIONS.md E.19): the ``a5_btf`` lookup at the sampled angles and between them
against the bilinear formula, the render kernel's view direction, the grammar (its errors:
tests/converters/test_surface_ext.py)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from helpers import ROOT, converted_material

from a5mi.converters.a5_parser import parse_text

SCENES = ROOT / "scenes"
ELEV, AZIM = (0.0, 30.0, 60.0), (0.0, 90.0, 180.0, 270.0)


def _images(seed: int = 3) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    return [rng.integers(0, 256, size=(5, 7, 3), dtype=np.uint8) for _ in range(len(ELEV) * len(AZIM))]


def _a4(img: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """SPEC A.4 in numpy: x = uW, y = (1 − v)H, truncation, clamped neighbours, bilinear, /255."""
    h, w = img.shape[:2]
    x, y = (u * w).astype(np.float32), ((1 - v) * h).astype(np.float32)
    ix, iy = np.trunc(x).astype(int), np.trunc(y).astype(int)
    a, b = (x - ix)[:, None], (y - iy)[:, None]
    x0, x1, y0, y1 = (np.clip(c, 0, m - 1) for c, m in ((ix, w), (ix + 1, w), (iy, h), (iy + 1, h)))
    p = img.astype(np.float64)
    return ((1 - a) * (1 - b) * p[y0, x0] + a * (1 - b) * p[y0, x1] + (1 - a) * b * p[y1, x0] + a * b * p[y1, x1]) / 255


def _formula(images: list[np.ndarray], wi: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The E.19 interpolation, written independently of the plugin (numpy, double)."""
    theta = np.degrees(np.arccos(np.clip(np.abs(wi[:, 2]), 0, 1)))
    phi = np.degrees(np.arctan2(wi[:, 1], wi[:, 0])) % 360.0
    out = np.zeros((len(u), 3))
    for k in range(len(u)):
        th = min(max(theta[k], ELEV[0]), ELEV[-1])
        i = max(m for m in range(len(ELEV) - 1) if ELEV[m] <= th) if th < ELEV[-1] else len(ELEV) - 2
        s = (th - ELEV[i]) / (ELEV[i + 1] - ELEV[i])
        ext = [*AZIM, AZIM[0] + 360.0]
        j = max(m for m in range(len(AZIM)) if ext[m] <= phi[k])
        t = (phi[k] - ext[j]) / (ext[j + 1] - ext[j])
        j1 = (j + 1) % len(AZIM)
        for (ii, jj), wgt in (((i, j), (1 - s) * (1 - t)), ((i, j1), (1 - s) * t), ((i + 1, j), s * (1 - t)),
                              ((i + 1, j1), s * t)):
            out[k] += wgt * _a4(images[ii * len(AZIM) + jj], u[k:k + 1], v[k:k + 1])[0]
    return out


def _texture(mi: Any, images: list[np.ndarray]) -> Any:
    d: dict[str, Any] = {"type": "a5_btf", "elevations": " ".join(map(str, ELEV)), "azimuths": " ".join(map(str, AZIM))}
    for k, img in enumerate(images):
        d[f"bitmap_{k // len(AZIM)}_{k % len(AZIM)}"] = mi.Bitmap(img)
    return mi.load_dict(d)


def _lookup(mi: Any, tex: Any, wi: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    import drjit as dr

    si = dr.zeros(mi.SurfaceInteraction3f, len(u))
    si.wi = mi.Vector3f(*(wi[:, c].astype(np.float32) for c in range(3)))
    si.uv = mi.Point2f(u.astype(np.float32), v.astype(np.float32))
    return np.asarray(tex.eval(si)).reshape(3, -1).T.astype(np.float64)


def _dirs(theta_deg: np.ndarray, phi_deg: np.ndarray) -> np.ndarray:
    t, p = np.radians(theta_deg), np.radians(phi_deg)
    return np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], axis=1)


def test_lookup_at_a_sampled_angle_is_that_image(mi: Any) -> None:
    """At every (elevation, azimuth) of the set the lookup is the A.4 lookup of that image (the other weights
    vanish; 2e-6 = the float32 rounding of the angle). Straight above the surface (elevation 0) the azimuth is
    undefined, ``atan2(0, 0) = 0``: that view gets image (0, 0)."""
    images = _images()
    tex = _texture(mi, images)
    rng = np.random.default_rng(0)
    for i, e in enumerate(ELEV):
        for j, a in enumerate(AZIM):
            n = 64
            u, v = rng.uniform(-0.1, 1.1, n), rng.uniform(-0.1, 1.1, n)
            got = _lookup(mi, tex, _dirs(np.full(n, e), np.full(n, a)), u, v)
            np.testing.assert_allclose(got, _a4(images[i * len(AZIM) + (j if e > 0 else 0)], u, v), atol=2e-6)


def test_lookup_between_angles_follows_the_bilinear_formula(mi: Any) -> None:
    """Random view directions (both hemispheres, beyond the last elevation, across the 270 -> 360 seam) against
    the formula of E.19 evaluated in numpy (1e-5: float32 angles)."""
    images = _images(7)
    tex = _texture(mi, images)
    rng = np.random.default_rng(1)
    n = 400
    wi = rng.normal(size=(n, 3))
    wi /= np.linalg.norm(wi, axis=1)[:, None]
    u, v = rng.uniform(0, 1, n), rng.uniform(0, 1, n)
    np.testing.assert_allclose(_lookup(mi, tex, wi, u, v), _formula(images, wi, u, v), atol=1e-5)
    # halfway between two elevations and two azimuths: the mean of the four images
    half = _lookup(mi, tex, _dirs(np.array([45.0]), np.array([135.0])), np.array([0.3]), np.array([0.6]))
    four = [images[i * 4 + j] for i in (1, 2) for j in (1, 2)]
    np.testing.assert_allclose(half[0], np.mean([_a4(m, np.array([0.3]), np.array([0.6]))[0] for m in four], axis=0),
                               atol=1e-5)


SCENE = """PerspectiveCamera {{ center 0 3 3 direction 0 -1 -1 up 0 1 0 angle 40 }}
Lights {{ numLights 1 DirectionalLight {{ direction 0 -1 0 color 1 1 1 }} }}
Background {{ color 0 0 0 ambientLight 0 0 0 }}
Materials {{ numMaterials 1 Material {{ diffuseColor 1 1 1 {btf} }} }}
Group {{ numObjects 1 MaterialIndex 0 TriangleMesh {{ obj_file {tile} }} }}
"""
BTF = "btf { images tex/btf/silk_%d_%d.bmp elevations 0 30 60 azimuths 0 90 180 270 }"


def _scene_text(btf: str = BTF) -> str:
    return SCENE.format(btf=btf, tile=SCENES / "meshes" / "tile.obj")


def test_render_kernel_looks_up_with_the_view_direction(mi: Any, tmp_path: Path) -> None:
    """Rays traced by ``a5_whitted`` onto the generated silk tile (lit head-on by a white directional light, so
    the colour is kd): each equals the formula at the ray's own view direction in the shading frame."""
    import drjit as dr

    from a5mi.converters.describe import describe
    from a5mi.platform.imageio import read_uint8
    from a5mi.render.options import RenderOptions
    from a5mi.render.session import build_scene

    model = parse_text(_scene_text(), str(SCENES / "btf_test.txt"))
    scene = build_scene(describe(model), RenderOptions())
    rng = np.random.default_rng(2)
    n = 256
    target = np.stack([rng.uniform(-0.9, 0.9, n), np.zeros(n), rng.uniform(-0.9, 0.9, n)], axis=1)
    theta, phi = np.radians(rng.uniform(0, 80, n)), rng.uniform(0, 2 * math.pi, n)
    d = -np.stack([np.sin(theta) * np.cos(phi), np.cos(theta), np.sin(theta) * np.sin(phi)], axis=1)
    o = target - 3.0 * d
    ray = mi.Ray3f(mi.Point3f(*(o[:, c].astype(np.float32) for c in range(3))),
                   mi.Vector3f(*(d[:, c].astype(np.float32) for c in range(3))))
    color = np.asarray(scene.integrator().trace(scene, ray)[0]).reshape(3, -1).T
    si = scene.ray_intersect(ray)
    assert bool(dr.all(si.is_valid()))
    wi = np.asarray(si.wi).reshape(3, -1).T.astype(np.float64)
    uv = np.asarray(si.uv).reshape(2, -1).T.astype(np.float64)
    images = [read_uint8(SCENES / "tex" / "btf" / f"silk_{i}_{j}.bmp") for i in range(3) for j in range(4)]
    np.testing.assert_allclose(color, _formula(images, wi, uv[:, 0], uv[:, 1]), atol=2e-5)


def test_btf_parses_and_converts() -> None:
    mat, d, stock, warnings = converted_material(_scene_text())
    assert mat.btf is not None and mat.btf.elevations == ELEV and mat.btf.azimuths == AZIM
    assert mat.btf.file_name(2, 3) == "tex/btf/silk_2_3.bmp"
    assert d["kd"]["type"] == "a5_btf" and d["kd"]["filename_2_3"].endswith("silk_2_3.bmp")
    assert stock["reflectance"]["type"] == "bitmap"
    assert any("btf replaced by its first image" in w for w in warnings)


def test_btf_with_another_colour_source_is_an_error() -> None:
    from a5mi.converters.describe import describe
    from a5mi.converters.errors import SceneSemanticError

    text = _scene_text(BTF + " texture tex/checker.bmp")
    with pytest.raises(SceneSemanticError, match="one colour source: 'btf' and texture"):
        describe(parse_text(text, str(SCENES / "x.txt")))

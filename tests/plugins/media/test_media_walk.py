"""Multiple scattering in media (``-media_bounces N``, docs/EXTENSIONS.md E.8) against Mitsuba's ``volpath``.

A constant-density Volume (box [−1, 1]³, optical depth 3 across, albedo 0.8, Henyey-Greenstein ``g``) lit by a
point light over a black floor, black background (the light's ``falloff 1e6`` makes the a5 light
``color/(1 + 10⁶ d²)`` the inverse-square law of the stock ``point`` to 1e-6; ``volpath`` renders no
directional light inside a medium): a5 with ``-media_bounces N -shadows`` scatters up to
``N`` times, ``volpath`` on the stock conversion with ``max_depth = N + 1`` the same paths; the a5 light is on the
scale ``P = π p`` (E.8), so ``a5 / π`` is compared with ``volpath``: the mean over rays into the box's central
region within 4 combined standard errors (sample standard deviations of the lanes / sqrt of their number).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import positioned_error_test
from test_media import WALL, _scene, _trace

from a5mi.converters import volgrid
from a5mi.converters.a5_parser import parse_text

BOX = """PerspectiveCamera {{ center 0 0 5 direction 0 0 -1 up 0 1 0 angle 30 }}
Lights {{ numLights 1 PointLight {{ position 2 4 1 color 2e7 2e7 2e7 falloff 1e6 }} }}
Background {{ color 0 0 0 ambientLight 0 0 0 }}
Volume {{ grid one.vol density 1.5 min -1 -1 -1 max 1 1 1 color 0.8 0.8 0.8 steps 64 g {g} }}
Materials {{ numMaterials 1 Material {{ diffuseColor 0 0 0 }} }}
Group {{ numObjects 1 MaterialIndex 0 Plane {{ normal 0 1 0 offset -3 }} }}
"""


test_phase_g_errors_are_positioned = positioned_error_test(
    lambda block: WALL.format(light="0 0 -1", medium=block, wall="1 1 1", n=1, extra=""), [
        ("Fog { color 1 1 1 density 0.5 ^g 1 }", "Fog g must be between -1 and 1"),
        ("Fog { color 1 1 1 density 0.5 ^g -1.5 }", "Fog g must be between -1 and 1"),
    ])


def test_phase_g_reaches_both_conversions() -> None:
    """``g`` becomes ``medium_g`` of ``a5_whitted`` and an ``hg`` phase of the stock medium; ``g 0`` adds
    nothing to the a5 dict (course-era dicts unchanged) and keeps the stock ``isotropic``."""
    from a5mi.converters.describe import describe
    from a5mi.converters.ext_mitsuba import medium_params, stock_medium

    for g, phase in ((0.4, {"type": "hg", "g": 0.4}), (0.0, {"type": "isotropic"})):
        med = describe(parse_text(WALL.format(light="0 0 -1", wall="1 1 1", n=1, extra="",
                                              medium=f"Fog {{ color 1 1 1 density 0.5 g {g} }}"))).medium
        assert medium_params(med, None).get("medium_g") == (g or None)
        assert stock_medium(med, None)["phase"] == phase


def _volpath(mi: Any, text: str, path: str, bounces: int, o: np.ndarray, d: np.ndarray) -> np.ndarray:
    from a5mi.converters.describe import describe
    from a5mi.converters.to_mitsuba import to_dict
    from a5mi.render.options import RenderOptions

    scene = mi.load_dict(to_dict(describe(parse_text(text, path)), RenderOptions(shadows=True), stock=True))
    integ = mi.load_dict({"type": "volpath", "max_depth": bounces + 1})
    sampler = mi.load_dict({"type": "independent"})
    sampler.seed(3, len(o))
    ray = mi.RayDifferential3f(mi.Point3f(*o.T.astype(np.float32)), mi.Vector3f(*d.T.astype(np.float32)))
    rgb = integ.sample(scene, sampler, ray, scene.sensors()[0].get_medium(), mi.Bool(True))[0]
    return np.stack([np.asarray(rgb.x), np.asarray(rgb.y), np.asarray(rgb.z)], axis=-1).astype(np.float64)


def _compare(mi: Any, tmp_path: Path, g: float, bounces: int, reps: int) -> None:
    volgrid.write_vol(tmp_path / "one.vol", np.ones((2, 2, 2), dtype=np.float32))
    text = BOX.format(g=g)
    path = str(tmp_path / "box.txt")
    (tmp_path / "box.txt").write_text(text)
    rng = np.random.default_rng(4)
    target = np.c_[rng.uniform(-0.6, 0.6, (16, 2)), np.zeros(16)]
    d = target - [0.0, 0.0, 5.0]
    d = np.repeat(d / np.linalg.norm(d, axis=1, keepdims=True), reps, axis=0)
    o = np.tile([0.0, 0.0, 5.0], (len(d), 1))
    a5 = _trace(mi, _scene(text, path, media_bounces=bounces), o, d, seed=13)[:, 0] / np.pi
    ref = _volpath(mi, text, path, bounces, o, d)[:, 0]
    se = np.sqrt(a5.var(ddof=1) / len(a5) + ref.var(ddof=1) / len(ref))
    assert abs(a5.mean() - ref.mean()) < 4.0 * se, (a5.mean(), ref.mean(), se)


@pytest.mark.parametrize("g", [0.0, 0.6])
def test_multiple_scattering_matches_volpath(mi: Any, tmp_path: Path, g: float) -> None:
    """``-media_bounces 4`` against ``volpath`` ``max_depth 5``, 16 rays x 64 samples (fast, seeded)."""
    _compare(mi, tmp_path, g, 4, 64)


@pytest.mark.slow
@pytest.mark.parametrize("g", [0.0, 0.6])
def test_multiple_scattering_matches_volpath_slow(mi: Any, tmp_path: Path, g: float) -> None:
    """As the fast test with ``-media_bounces 12`` (``max_depth 13``) and 16 rays x 1024 samples."""
    _compare(mi, tmp_path, g, 12, 1024)

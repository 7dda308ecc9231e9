"""The a5_marble texture (SPEC B.4): t = clamp(0.5 sin(f x + a N) + 0.5), kd = t c1 + (1 - t) c2."""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_perlin import ref_octave_noise

C1 = [0.9, 0.8, 0.1]
C2 = [0.1, 0.3, 0.7]


def _marble(octaves: int = 0, frequency: float = 1.0, amplitude: float = 1.0):
    import mitsuba as mi

    return mi.load_dict(
        {
            "type": "a5_marble",
            "color1": {"type": "rgb", "value": C1},
            "color2": {"type": "rgb", "value": C2},
            "octaves": octaves,
            "frequency": frequency,
            "amplitude": amplitude,
        }
    )


def _eval(tex, pts: np.ndarray) -> np.ndarray:
    import drjit as dr
    import mitsuba as mi

    si = dr.zeros(mi.SurfaceInteraction3f, len(pts))
    si.p = mi.Point3f(*(pts[:, k].astype(np.float32) for k in range(3)))
    return np.asarray(tex.eval(si)).T


def _ref_kd(p: np.ndarray, octaves: int, frequency: float, amplitude: float) -> np.ndarray:
    n = ref_octave_noise(p, octaves)
    arg = float(np.float32(p[0]) * np.float32(frequency)) + float(np.float32(amplitude)) * n
    t = np.float32(min(max(0.5 * math.sin(arg) + 0.5, 0.0), 1.0))
    return t * np.float32(C1) + (np.float32(1) - t) * np.float32(C2)


def test_b4_mean_at_x0_with_zero_noise(variant: str) -> None:
    """At x = 0 with N = 0 (octaves 0, or any integer point), t = 1/2: kd is the mean of the colours."""
    pts = np.array([[0.0, 0.25, -3.5], [0.0, 2.0, 5.0]], dtype=np.float32)
    mean = 0.5 * (np.array(C1) + np.array(C2))
    assert np.allclose(_eval(_marble(octaves=0), pts), mean, atol=1e-7)
    # p integer: every octave's noise vanishes, so N = 0 even with octaves > 0.
    assert np.allclose(_eval(_marble(octaves=6, amplitude=3.0), pts[1:]), mean, atol=1e-7)


def test_b4_pure_sine_stripes(variant: str) -> None:
    """octaves 0: t = (sin(f x) + 1)/2; sin = 1 at f x = pi/2 gives color1, -1 gives color2."""
    f = 2.0
    pts = np.array([[math.pi / 4, 0.3, 0.1], [-math.pi / 4, 0.3, 0.1], [0.1, 7.0, -2.0]], dtype=np.float32)
    got = _eval(_marble(frequency=f), pts)
    assert np.allclose(got[0], C1, atol=1e-6)
    assert np.allclose(got[1], C2, atol=1e-6)
    t = 0.5 * math.sin(f * float(pts[2, 0])) + 0.5
    assert np.allclose(got[2], t * np.array(C1) + (1 - t) * np.array(C2), atol=1e-6)


@pytest.mark.parametrize(
    ("octaves", "frequency", "amplitude"), [(1, 1.0, 1.0), (4, 3.0, 2.5), (8, 0.5, 10.0)]
)
def test_b4_matches_reference_formula(variant: str, octaves: int, frequency: float, amplitude: float) -> None:
    pts = np.random.default_rng(octaves).uniform(-5.0, 5.0, size=(500, 3)).astype(np.float32)
    got = _eval(_marble(octaves, frequency, amplitude), pts)
    want = np.array([_ref_kd(p, octaves, frequency, amplitude) for p in pts])
    assert np.max(np.abs(got - want)) < 1e-6


def test_b4_kernel_reused_across_parameters(variant: str) -> None:
    """Parameters are opaque: marbles with other colours/octaves/frequency run the same kernel."""
    import drjit as dr

    pts = np.random.default_rng(3).uniform(-1, 1, size=(64, 3)).astype(np.float32)
    hashes = []
    for args in [(2, 1.0, 1.0), (5, 4.0, 0.3)]:
        dr.kernel_history_clear()
        with dr.scoped_set_flag(dr.JitFlag.KernelHistory, True):
            _eval(_marble(*args), pts)
            hashes.append([k["hash"] for k in dr.kernel_history() if k["type"] == dr.KernelType.JIT])
    assert hashes[0] and hashes[0] == hashes[1]


def test_b4_traverse_and_update(variant: str) -> None:
    import mitsuba as mi

    tex = _marble(octaves=0, frequency=1.0)
    params = mi.traverse(tex)
    assert {"color1", "color2", "octaves", "frequency", "amplitude"} <= set(params.keys())
    params["color1"] = mi.Color3f(1, 1, 1)
    params["color2"] = mi.Color3f(0, 0, 0)
    params.update()
    got = _eval(tex, np.array([[math.pi / 2, 0, 0]], dtype=np.float32))
    assert np.allclose(got, 1.0, atol=1e-6)


def test_b4_rejects_bad_octaves(variant: str) -> None:
    import mitsuba as mi

    with pytest.raises(Exception, match="octaves"):
        mi.load_dict({"type": "a5_marble", "octaves": -1})

"""SPEC B.3 helpers (plugins/optics.py): mirror direction, Snell, and the three Fresnel weights, in closed form."""

from __future__ import annotations

import math

import numpy as np
import pytest


@pytest.fixture(scope="module")
def common(variant):
    from a5mi.plugins import optics as common

    return common


def _v(mi, x, y, z):
    return mi.Vector3f(x, y, z)


def _np(v) -> np.ndarray:
    return np.array(v, dtype=np.float64).reshape(-1)


def _exact_fresnel(cos_i: float, eta: float) -> float:
    """Unpolarised dielectric Fresnel reflectance (textbook), eta = nt/n."""
    sin_t2 = (1.0 - cos_i * cos_i) / (eta * eta)
    if sin_t2 >= 1.0:
        return 1.0
    cos_t = math.sqrt(1.0 - sin_t2)
    rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
    rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
    return 0.5 * (rs * rs + rp * rp)


def test_b3_reflect_is_mirror_and_sign_free(common):
    import mitsuba as mi

    d = _v(mi, 0.6, 0.0, -0.8)
    n = _v(mi, 0.0, 0.0, 1.0)
    assert np.allclose(_np(common.reflect(d, n)), [0.6, 0.0, 0.8], atol=1e-7)
    assert np.allclose(_np(common.reflect(d, -n)), [0.6, 0.0, 0.8], atol=1e-7)


def test_b3_snell_bends_by_index_ratio(common):
    import mitsuba as mi

    theta = math.radians(40.0)
    d = _v(mi, math.sin(theta), 0.0, -math.cos(theta))
    n = _v(mi, 0.0, 0.0, 1.0)
    t, exists = common.snell(d, n, mi.Float(1.0), mi.Float(1.5))
    sin_t = math.sin(theta) / 1.5
    assert bool(exists[0])
    assert np.allclose(_np(t), [sin_t, 0.0, -math.sqrt(1 - sin_t * sin_t)], atol=1e-6)


def test_b3_snell_total_internal_reflection(common):
    import mitsuba as mi

    theta = math.radians(60.0)  # 1.5 sin 60° = 1.30 > 1
    d = _v(mi, math.sin(theta), 0.0, -math.cos(theta))
    t, exists = common.snell(d, _v(mi, 0.0, 0.0, 1.0), mi.Float(1.5), mi.Float(1.0))
    assert not bool(exists[0])
    assert np.allclose(_np(t), 0.0)


@pytest.mark.parametrize("mode", ["a5", "schlick", "exact"])
def test_b3_fresnel_normal_incidence_from_air_is_004(common, mode):
    import mitsuba as mi

    d = _v(mi, 0.0, 0.0, -1.0)
    n = _v(mi, 0.0, 0.0, 1.0)
    t, _ = common.snell(d, n, mi.Float(1.0), mi.Float(1.5))
    r = common.fresnel_weight(mode, d, n, t, mi.Float(1.0), mi.Float(1.5))
    assert r[0] == pytest.approx(0.04, abs=1e-6)


@pytest.mark.parametrize("mode", ["a5", "schlick", "exact"])
def test_b3_fresnel_grazing_incidence(common, mode):
    import mitsuba as mi

    theta = math.radians(85.0)
    c = math.cos(theta)
    d = _v(mi, math.sin(theta), 0.0, -c)
    n = _v(mi, 0.0, 0.0, 1.0)
    t, _ = common.snell(d, n, mi.Float(1.0), mi.Float(1.5))
    r = common.fresnel_weight(mode, d, n, t, mi.Float(1.0), mi.Float(1.5))[0]
    # From air, nt > n, so c = |d.N| and both Schlick variants have R0 = 0.04.
    expected = _exact_fresnel(c, 1.5) if mode == "exact" else 0.04 + 0.96 * (1 - c) ** 5
    assert r == pytest.approx(expected, rel=1e-5)


def test_b3_fresnel_leaving_glass_a5_quirk(common):
    """Leaving glass into air (n = 1.5, nt = 1): the binary's R0 = ((1-1)/(1+1))² = 0, textbook 0.04."""
    import mitsuba as mi

    theta_i = math.radians(20.0)
    d = _v(mi, math.sin(theta_i), 0.0, -math.cos(theta_i))
    n = _v(mi, 0.0, 0.0, 1.0)
    n_medium, nt = mi.Float(1.5), mi.Float(1.0)
    t, exists = common.snell(d, n, n_medium, nt)
    assert bool(exists[0])
    sin_t = 1.5 * math.sin(theta_i)
    c = math.sqrt(1 - sin_t * sin_t)  # nt < n: c = |T.N|
    assert common.fresnel_weight("a5", d, n, t, n_medium, nt)[0] == pytest.approx((1 - c) ** 5, rel=1e-4)
    assert common.fresnel_weight("schlick", d, n, t, n_medium, nt)[0] == pytest.approx(
        0.04 + 0.96 * (1 - c) ** 5, rel=1e-5)
    assert common.fresnel_weight("exact", d, n, t, n_medium, nt)[0] == pytest.approx(
        _exact_fresnel(math.cos(theta_i), 1 / 1.5), rel=1e-4)


def test_b3_r0_formulas(common):
    import mitsuba as mi

    assert common.r0_a5(mi.Float(1.5))[0] == pytest.approx(0.04)
    assert common.r0_a5(mi.Float(1.0))[0] == 0.0
    assert common.r0_schlick(mi.Float(1.5), mi.Float(1.0))[0] == pytest.approx(0.04)
    assert common.schlick(mi.Float(0.0), mi.Float(0.04))[0] == pytest.approx(1.0)
    assert common.schlick(mi.Float(1.0), mi.Float(0.04))[0] == pytest.approx(0.04)


def test_b3_fresnel_unknown_mode_raises(common):
    import mitsuba as mi

    v = _v(mi, 0.0, 0.0, 1.0)
    with pytest.raises(ValueError, match="fresnel"):
        common.fresnel_weight("fast", v, v, v, mi.Float(1.0), mi.Float(1.5))

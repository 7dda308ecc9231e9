"""a5_material (SPEC A.5, B.3): the a5 attribute channel through BSDFPtr vcalls, and the physical BSDF."""

from __future__ import annotations

import math

import drjit as dr
import numpy as np
import pytest


def _rgb(*v: float) -> dict:
    return {"type": "rgb", "value": list(v)}


def _np(v) -> np.ndarray:
    return np.array(v, dtype=np.float64)


@dr.syntax
def _attributes_in_loop(scene, o, d):
    """Read every a5 attribute through ``si.bsdf()`` (a BSDFPtr vcall) inside a symbolic loop, twice."""
    import mitsuba as mi

    width = dr.width(o)
    i = dr.zeros(mi.UInt32, width)
    dc = dr.zeros(mi.Color3f, width)
    kd = dr.zeros(mi.Color3f, width)
    sc = dr.zeros(mi.Color3f, width)
    ior = dr.zeros(mi.Float, width)
    shin = dr.zeros(mi.Float, width)
    has = dr.zeros(mi.Float, width)
    while i < 2:
        si = scene.ray_intersect(mi.Ray3f(o, d))
        bsdf = si.bsdf()
        ok = si.is_valid()
        dc += bsdf.eval_attribute_3("diffuse_color", si, ok)
        sc += bsdf.eval_attribute_3("specular_color", si, ok)
        kd += bsdf.eval_diffuse_reflectance(si, ok)
        ior += bsdf.eval_attribute_1("refraction_index", si, ok)
        shin += bsdf.eval_attribute_1("shininess", si, ok)
        has += dr.select(bsdf.has_attribute("diffuse_color", ok), 1.0, 0.0)
        i += 1
    return dc, kd, sc, ior, shin, has


def test_a5_attributes_reach_python_through_bsdfptr_vcall_in_symbolic_loop(mi):
    scene = mi.load_dict({
        "type": "scene",
        "a": {"type": "sphere", "center": [0, 0, 0], "radius": 1, "bsdf": {
            "type": "a5_material", "diffuse_color": _rgb(0.1, 0.2, 0.3), "kd": _rgb(0.7, 0.6, 0.5),
            "specular_color": _rgb(0.25, 0.5, 0.75), "shininess": 20.0, "refraction_index": 1.5}},
        "b": {"type": "sphere", "center": [5, 0, 0], "radius": 1, "bsdf": {
            "type": "a5_material", "diffuse_color": _rgb(0.4, 0.4, 0.4)}},
        "c": {"type": "sphere", "center": [10, 0, 0], "radius": 1, "bsdf": {
            "type": "diffuse", "reflectance": _rgb(0.3, 0.3, 0.3)}},
    })
    o = mi.Point3f(mi.Float(0, 5, 10, 20), 0, -5)
    dc, kd, sc, ior, shin, has = _attributes_in_loop(scene, o, mi.Vector3f(0, 0, 1))
    # two loop iterations: every value doubled; lane 3 misses, lane 2 is a stock BSDF
    assert np.allclose(_np(dc).T, [[0.2, 0.4, 0.6], [0.8, 0.8, 0.8], [0, 0, 0], [0, 0, 0]], atol=1e-6)
    assert np.allclose(_np(kd).T, [[1.4, 1.2, 1.0], [0.8, 0.8, 0.8], [0.6, 0.6, 0.6], [0, 0, 0]], atol=1e-6)
    assert np.allclose(_np(sc).T, [[0.5, 1.0, 1.5], [0, 0, 0], [0, 0, 0], [0, 0, 0]], atol=1e-6)
    assert np.allclose(_np(ior), [3.0, 0, 0, 0])
    assert np.allclose(_np(shin), [40.0, 0, 0, 0])
    assert np.allclose(_np(has), [2, 2, 0, 0])


def test_a5_defaults_and_traverse(mi):
    bsdf = mi.load_dict({"type": "a5_material"})
    params = mi.traverse(bsdf)
    assert np.allclose(_np(params["diffuse_color"]).ravel(), [1, 1, 1])
    assert np.allclose(_np(params["kd.value"]).ravel(), [1, 1, 1])  # kd defaults to diffuse_color
    assert np.allclose(_np(params["specular_color"]).ravel(), [0, 0, 0])
    assert params["shininess"][0] == 0.0 and params["refraction_index"][0] == 0.0
    # pure Lambert: one component, no delta lobe
    assert not mi.has_flag(bsdf.flags(), mi.BSDFFlags.Delta)


def test_a5_negative_refraction_index_is_rejected(mi):
    # Mitsuba re-raises plugin constructor errors as RuntimeError carrying the original message.
    with pytest.raises((ValueError, RuntimeError), match="refraction_index. must be >= 0"):
        mi.load_dict({"type": "a5_material", "refraction_index": -1.0})


def _si(mi, wi):
    si = dr.zeros(mi.SurfaceInteraction3f)
    si.wi = wi
    si.sh_frame = mi.Frame3f(mi.Vector3f(0, 0, 1))
    return si


def test_a5_physical_eval_is_lambert(mi):
    bsdf = mi.load_dict({"type": "a5_material", "kd": _rgb(0.5, 0.25, 1.0)})
    ctx = mi.BSDFContext()
    si = _si(mi, mi.Vector3f(0, 0, 1))
    wo = mi.Vector3f(0.6, 0, 0.8)
    assert np.allclose(_np(bsdf.eval(ctx, si, wo)).ravel(), np.array([0.5, 0.25, 1.0]) * 0.8 / math.pi,
                       atol=1e-6)
    assert bsdf.pdf(ctx, si, wo)[0] == pytest.approx(0.8 / math.pi, rel=1e-6)
    # back side: nothing
    assert np.allclose(_np(bsdf.eval(ctx, _si(mi, mi.Vector3f(0, 0, -1)), wo)), 0.0)


def test_a5_physical_mirror_sample(mi):
    """kd = 0.2, spec = 0.6: p_s = 0.6/0.8 = 0.75; a delta sample returns the mirror direction, weight spec/p_s."""
    bsdf = mi.load_dict({"type": "a5_material", "diffuse_color": _rgb(0.2, 0.2, 0.2),
                         "specular_color": _rgb(0.6, 0.6, 0.6)})
    ctx = mi.BSDFContext()
    si = _si(mi, mi.Vector3f(0.6, 0, 0.8))
    bs, w = bsdf.sample(ctx, si, mi.Float(0.5), mi.Point2f(0.5, 0.5))
    assert np.allclose(_np(bs.wo).ravel(), [-0.6, 0, 0.8], atol=1e-6)
    assert bs.pdf[0] == pytest.approx(0.75)
    assert np.allclose(_np(w).ravel(), 0.8, atol=1e-6)
    bs, w = bsdf.sample(ctx, si, mi.Float(0.9), mi.Point2f(0.5, 0.5))  # diffuse lobe
    assert bs.wo[2][0] > 0.0
    assert np.allclose(_np(w).ravel(), 0.2 / 0.25, atol=1e-6)


def test_a5_physical_dielectric_sample_at_normal_incidence(mi):
    """Black kd, spec 1, ior 1.5: p_s = 1; F = 0.04, so u < 0.04 reflects and u > 0.04 refracts (1/η² scaling)."""
    bsdf = mi.load_dict({"type": "a5_material", "diffuse_color": _rgb(0, 0, 0),
                         "specular_color": _rgb(1, 1, 1), "refraction_index": 1.5})
    ctx = mi.BSDFContext()
    si = _si(mi, mi.Vector3f(0, 0, 1))
    bs, w = bsdf.sample(ctx, si, mi.Float(0.02), mi.Point2f(0.5, 0.5))
    assert np.allclose(_np(bs.wo).ravel(), [0, 0, 1], atol=1e-6)
    assert bs.pdf[0] == pytest.approx(0.04, rel=1e-5)
    bs, w = bsdf.sample(ctx, si, mi.Float(0.5), mi.Point2f(0.5, 0.5))
    assert np.allclose(_np(bs.wo).ravel(), [0, 0, -1], atol=1e-6)
    assert bs.pdf[0] == pytest.approx(0.96, rel=1e-5)
    assert np.allclose(_np(w).ravel(), 1 / 1.5**2, atol=1e-6)

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
    # wo on the other side of the surface than wi: nothing (either side)
    back = _si(mi, mi.Vector3f(0, 0, -1))
    assert np.allclose(_np(bsdf.eval(ctx, back, wo)), 0.0) and bsdf.pdf(ctx, back, wo)[0] == 0.0
    assert np.allclose(_np(bsdf.eval(ctx, si, mi.Vector3f(0.6, 0, -0.8))), 0.0)
    # E.13 two-sided Lambert: both on the back side, the mirrored frame gives the same kd/π |cosθ_o|
    wo_back = mi.Vector3f(0.6, 0, -0.8)
    assert np.allclose(_np(bsdf.eval(ctx, back, wo_back)).ravel(), np.array([0.5, 0.25, 1.0]) * 0.8 / math.pi,
                       atol=1e-6)
    assert bsdf.pdf(ctx, back, wo_back)[0] == pytest.approx(0.8 / math.pi, rel=1e-6)


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


def _uniform_sphere(n: int) -> np.ndarray:
    """``n`` directions on an equal-area (θ, φ) grid: midpoints in ``cosθ`` and ``φ``, each of solid angle 4π/n."""
    m = int(round(math.sqrt(n / 2)))
    z = (np.arange(m) + 0.5) / m * 2.0 - 1.0
    phi = (np.arange(2 * m) + 0.5) / (2 * m) * 2.0 * math.pi
    zz, pp = np.meshgrid(z, phi, indexing="ij")
    r = np.sqrt(1.0 - zz**2)
    return np.stack([r * np.cos(pp), r * np.sin(pp), zz], axis=-1).reshape(-1, 3)


WI_BOTH_SIDES = [(0.6, 0.0, 0.8), (0.0, 0.28, 0.96), (0.6, 0.0, -0.8), (-0.28, 0.0, -0.96)]


@pytest.mark.parametrize("wi", WI_BOTH_SIDES)
def test_a5_diffuse_pdf_integrates_to_the_diffuse_probability_on_either_side(mi, wi):
    """E.13 two-sided Lambert: ``∫ pdf dω = 1 - p_s`` over the sphere (midpoint quadrature on an equal-area grid
    of 20,000 cells, error O(1/m²) ~ 1e-4), all of it on ``wi``'s side; ``∫ eval dω = kd`` (albedo);
    reciprocity ``eval(wi, wo)/|cos wo| = eval(wo, wi)/|cos wi|``."""
    kd, ks = 0.6, 0.2
    bsdf = mi.load_dict({"type": "a5_material", "diffuse_color": _rgb(kd, kd, kd),
                         "specular_color": _rgb(ks, ks, ks)})
    p_s = ks / (kd + ks)
    ctx = mi.BSDFContext()
    dirs = _uniform_sphere(20_000)
    d_omega = 4.0 * math.pi / len(dirs)
    si = _si(mi, mi.Vector3f(*[mi.Float(c) for c in wi]))
    si = dr.gather(type(si), si, dr.zeros(mi.UInt32, len(dirs)))
    wo = mi.Vector3f(*[mi.Float(dirs[:, k]) for k in range(3)])
    pdf = _np(bsdf.pdf(ctx, si, wo))
    f = _np(bsdf.eval(ctx, si, wo))[0]
    same_side = np.sign(dirs[:, 2]) == np.sign(wi[2])
    assert pdf.sum() * d_omega == pytest.approx(1.0 - p_s, abs=2e-3)
    assert np.all(pdf[~same_side] == 0.0) and np.all(f[~same_side] == 0.0)
    assert f.sum() * d_omega == pytest.approx(kd, abs=2e-3)
    # reciprocity on a handful of pairs (both in wi's hemisphere)
    pick = np.flatnonzero(same_side)[::997]
    for j in pick:
        a, b = [float(c) for c in wi], [float(c) for c in dirs[j]]
        f_ab = _np(bsdf.eval(ctx, _si(mi, mi.Vector3f(*a)), mi.Vector3f(*b))).ravel()[0] / abs(b[2])
        f_ba = _np(bsdf.eval(ctx, _si(mi, mi.Vector3f(*b)), mi.Vector3f(*a))).ravel()[0] / abs(a[2])
        assert f_ab == pytest.approx(f_ba, rel=1e-5) and f_ab == pytest.approx(kd / math.pi, rel=1e-5)


@pytest.mark.parametrize("wi", WI_BOTH_SIDES)
def test_a5_diffuse_sample_agrees_with_eval_and_pdf_on_either_side(mi, wi):
    """Every diffuse sample lies on ``wi``'s side, its pdf is ``pdf(wo)`` and its weight ``eval(wo)/pdf(wo)``
    (= kd/(1 - p_s)); the fraction of samples with ``|cosθ_o| < 1/2`` is the cosine lobe's 1/4 (4,096 seeded
    samples: binomial sigma sqrt(0.25·0.75/4096) = 0.0068, tolerance 5 sigma)."""
    kd, ks = 0.6, 0.2
    bsdf = mi.load_dict({"type": "a5_material", "diffuse_color": _rgb(kd, kd, kd),
                         "specular_color": _rgb(ks, ks, ks)})
    p_s = ks / (kd + ks)
    ctx = mi.BSDFContext()
    n = 4096
    rng = np.random.default_rng(5)
    si = _si(mi, mi.Vector3f(*[mi.Float(c) for c in wi]))
    si = dr.gather(type(si), si, dr.zeros(mi.UInt32, n))
    u1 = mi.Float(p_s + (1.0 - p_s) * rng.random(n))  # the diffuse lobe: sample1 >= p_s
    bs, weight = bsdf.sample(ctx, si, u1, mi.Point2f(mi.Float(rng.random(n)), mi.Float(rng.random(n))))
    wo = _np(bs.wo)
    assert np.all(np.sign(wo[2]) == np.sign(wi[2]))
    assert np.all(_np(bs.sampled_type) == int(mi.BSDFFlags.DiffuseReflection))
    pdf = _np(bsdf.pdf(ctx, si, bs.wo))
    f = _np(bsdf.eval(ctx, si, bs.wo))[0]
    assert np.allclose(_np(bs.pdf), pdf, rtol=1e-5)
    assert np.allclose(_np(bs.pdf), (1.0 - p_s) * np.abs(wo[2]) / math.pi, rtol=1e-5)
    assert np.allclose(_np(weight)[0], f / pdf, rtol=1e-4)
    assert np.allclose(_np(weight)[0], kd / (1.0 - p_s), rtol=1e-5)
    assert np.mean(np.abs(wo[2]) < 0.5) == pytest.approx(0.25, abs=5 * 0.0068)


@pytest.mark.parametrize("side", [1.0, -1.0])
def test_a5_diffuse_plane_lit_and_seen_from_either_side_under_stock_path(mi, side):
    """A plane of kd = 0.5 under a directional light of irradiance E = 2 at cosθ = 0.8, camera and light on the
    same side (``side`` = -1: the back of the rectangle, whose normal is +z): stock ``path`` at direct light only
    sees ``kd/π · cosθ · E`` at every pixel (E.13's two-sided Lambert; the light sample is deterministic, so the
    value is exact to float rounding)."""
    import mitsuba

    kd, e, cos_l = 0.5, 2.0, 0.8
    light_dir = [0.6 * side, 0.0, -0.8 * side]  # travelling toward the plane from its `side`
    scene = mi.load_dict({
        "type": "scene", "integrator": {"type": "path", "max_depth": 2, "hide_emitters": True},
        "sensor": {"type": "perspective", "fov": 20,
                   "to_world": mitsuba.ScalarTransform4f().look_at(origin=[0, 0, 5 * side], target=[0, 0, 0],
                                                                   up=[0, 1, 0]),
                   "film": {"type": "hdrfilm", "width": 8, "height": 8, "rfilter": {"type": "box"}},
                   "sampler": {"type": "independent", "sample_count": 4}},
        "plane": {"type": "rectangle", "to_world": mitsuba.ScalarTransform4f().scale(10),
                  "bsdf": {"type": "a5_material", "diffuse_color": _rgb(kd, kd, kd)}},
        "sun": {"type": "directional", "direction": light_dir, "irradiance": _rgb(e, e, e)},
    })
    image = np.asarray(mi.render(scene, seed=3))
    assert np.allclose(image, kd / math.pi * cos_l * e, rtol=1e-4)


# ------------------------------------------------------------------------- a parallel load (docs/MITSUBA.md)
#: Stock plugins of as many kinds, each loaded for the first time during the load: Mitsuba finds a plugin's
#: library through its global file resolver, which a load inside a constructor swapped and freed.
FIRST_LOADS = (
    '<bsdf type="diffuse"/>', '<bsdf type="conductor"/>', '<bsdf type="roughconductor"/>', '<bsdf type="plastic"/>',
    '<bsdf type="dielectric"/>', '<bsdf type="thindielectric"/>', '<bsdf type="roughplastic"/>',
    '<bsdf type="roughdielectric"/>', '<bsdf type="principled"/>', '<bsdf type="null"/>',
    '<bsdf type="twosided"><bsdf type="diffuse"/></bsdf>', '<texture type="checkerboard"/>',
    '<emitter type="point"><point name="position" value="0, 0, 1"/></emitter>', '<emitter type="spot"/>',
    '<sampler type="independent"/>', '<sampler type="multijitter"/>', '<sampler type="orthogonal"/>',
    '<sampler type="ldsampler"/>', '<rfilter type="gaussian"/>', '<rfilter type="tent"/>', '<rfilter type="lanczos"/>',
    '<rfilter type="mitchell"/>', '<rfilter type="catmullrom"/>', '<shape type="sphere"/>', '<shape type="rectangle"/>',
    '<shape type="cube"/>', '<shape type="disk"/>', '<shape type="cylinder"/>', '<phase type="isotropic"/>',
    '<phase type="hg"/>', '<medium type="homogeneous"/>')
#: Mitsuba's default load (parallel) in a fresh process: every plugin library is loaded for the first time.
PARALLEL_LOAD = """
import sys
import mitsuba as mi
mi.set_variant("llvm_ad_rgb")
from a5mi.plugins import register_all
register_all()
mi.load_file(sys.argv[1])
"""


def many_materials_xml(materials: int = 240) -> str:
    """A scene of ``materials`` ``a5_material`` BSDFs of plain colours (distinct: Mitsuba merges equal objects),
    one of :data:`FIRST_LOADS` after every seventh, and a camera with a film and a box filter."""
    parts = []
    for k in range(materials):
        parts.append(f'<bsdf type="a5_material" id="m{k}"><rgb name="diffuse_color" value="{k / 200:.4f}, 0.5, '
                     '0.25"/></bsdf>')
        if k % 7 == 6 and k // 7 < len(FIRST_LOADS):
            parts.append(FIRST_LOADS[k // 7].replace(" ", f' id="s{k}" ', 1))
    camera = ('<sensor type="perspective"><film type="hdrfilm"><integer name="width" value="8"/>'
              '<integer name="height" value="8"/><rfilter type="box"/></film></sensor>')
    return '<scene version="3.0.0">\n' + "\n".join(parts) + "\n" + camera + "\n</scene>\n"


def test_a_parallel_load_of_many_materials_in_fresh_processes(tmp_path) -> None:
    """docs/MITSUBA.md "Loading in parallel": the materials' constructors run on Mitsuba's pool beside the first
    loads of the stock plugins. With a5_material's texture made by ``mi.load_dict`` (85993f9), 7 of 40 processes
    loading this scene failed (``basic_string::_M_create``, ``std::bad_alloc``, a segmentation fault), and this
    test failed 10 times in 10 (BENCHMARKS.md "Loading"). Now every process must load it."""
    import subprocess
    import sys

    xml = tmp_path / "materials.xml"
    xml.write_text(many_materials_xml())

    def load(_: int) -> subprocess.CompletedProcess[str]:
        return subprocess.run([sys.executable, "-c", PARALLEL_LOAD, str(xml)], capture_output=True, text=True,
                              timeout=300)

    runs = [load(k) for k in range(16)]  # one at a time: a process alone on the cores races more often
    failed = [f"status {p.returncode}: {p.stderr.strip()[-300:]}" for p in runs if p.returncode != 0]
    assert failed == []

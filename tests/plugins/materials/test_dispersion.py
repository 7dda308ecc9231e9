"""Dispersion (docs/EXTENSIONS.md E.10): grammar, wavelength weights, Snell's law with Cauchy's index through the
kernel, B = 0 and non-dispersive paths bit for bit, the stock mapping."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from conftest import positioned_error_test
from helpers import ROOT, render_text

from a5mi.converters.a5_parser import parse_text

A, B = 1.6, 0.02
APEX = 60.0
ROTATE = 24.6          # degrees about y: the entry face's normal at 30° + 24.6° from +z

SCENE = """PerspectiveCamera {{ center 0 0 7 direction 0 0 -1 up 0 1 0 angle 30 }}
Lights {{ numLights 1 PointLight {{ position 0 5 5 color 1 1 1 }} }}
Background {{ color 0.2 0.3 0.4 ambientLight 0.1 0.1 0.1 }}
Materials {{ numMaterials 2
    Material {{ diffuseColor 0.8 0.4 0.2 specularColor 0.3 0.3 0.3 }}
    Material {{ diffuseColor 0 0 0 specularColor 1 1 1 refractionIndex {glass} }} }}
Group {{ numObjects {n} MaterialIndex 0 Plane {{ normal 0 1 0 offset -1 }} {objects} }}
"""


def _prism_vertices() -> np.ndarray:
    """Equilateral prism, y in [-1, 1], cross-section vertices at unit distance from the y axis (one at +x),
    rotated by ROTATE degrees about y (x' = x cos t + z sin t, z' = -x sin t + z cos t)."""
    ring = [(math.cos(a), math.sin(a)) for a in (0.0, 2 * math.pi / 3, 4 * math.pi / 3)]
    t = math.radians(ROTATE)
    ring = [(x * math.cos(t) + z * math.sin(t), -x * math.sin(t) + z * math.cos(t)) for x, z in ring]
    return np.array([(x, y, z) for y in (-1.0, 1.0) for x, z in ring])


def _prism_triangles() -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    v = _prism_vertices()
    faces = [(0, 2, 1), (3, 4, 5)]
    for i in range(3):
        j = (i + 1) % 3
        faces += [(i, i + 3, j + 3), (i, j + 3, j)]
    out = []
    for f in faces:
        a, b, c = v[list(f)]
        if np.cross(b - a, c - a) @ ((a + b + c) / 3) < 0:   # outward winding (SPEC: n = (v1-v0) x (v2-v0))
            b, c = c, b
        out.append((a, b, c))
    return out


def _prism_text() -> str:
    def f(p: np.ndarray) -> str:
        return " ".join(f"{x:.9g}" for x in p)
    return " ".join(f"Triangle {{ vertex0 {f(a)} vertex1 {f(b)} vertex2 {f(c)} }}" for a, b, c in _prism_triangles())


def _scene_text(glass: str, objects: str, n: int) -> str:
    return SCENE.format(glass=glass, objects="MaterialIndex 1 " + objects, n=n)


# ------------------------------------------------------------------------------------------------ grammar
def test_dispersion_keyword_parses() -> None:
    text = _scene_text(f"dispersion {A} {B}", "Sphere { center 0 0 0 radius 1 }", 2)
    mat = parse_text(text).materials[1]
    assert (mat.refraction_index, mat.dispersion) == (A, B)
    plain = parse_text(_scene_text("1.5", "Sphere { center 0 0 0 radius 1 }", 2)).materials[1]
    assert (plain.refraction_index, plain.dispersion) == (1.5, None)
    # the last refractionIndex of a Material wins, as for every A.5 keyword
    again = parse_text(_scene_text(f"dispersion {A} {B} refractionIndex 1.4", "Sphere { center 0 0 0 radius 1 }", 2))
    assert (again.materials[1].refraction_index, again.materials[1].dispersion) == (1.4, None)


# Each error sits at the offending number (line 6, its column), as the course grammar's errors do.
test_dispersion_errors_are_positioned = positioned_error_test(
    lambda glass: _scene_text(glass, "Sphere { center 0 0 0 radius 1 }", 2), [
        ("dispersion ^0 0.01", "dispersion A (the index far in the infrared) must be positive, found 0"),
        ("dispersion 1.5 ^-0.5", "gives the index -1.625 at 400 nm"),
        ("dispersion 1.5 ^}", "expected a number after 'dispersion', found '}'"),
        ("dispersion ^x 1", "expected a number after 'dispersion', found 'x'"),
    ])


# ------------------------------------------------------------------------------------------------ weights
def test_wavelength_weights_average_to_one(mi: Any) -> None:
    """w(λ) has mean (1, 1, 1) over 400-700 nm: exactly for the table's trapezoid rule, to float precision for
    the kernel's interpolation on a fine grid and within noise for the kernel's stratified samples; the table
    is Mitsuba's CIE 1931 through its own XYZ -> sRGB conversion, up to one scale per channel."""
    import drjit as dr

    from a5mi.plugins.materials import spectral
    from a5mi.plugins.sampling import pixel_keys

    table = spectral.rgb_table()
    lam = spectral.table_wavelengths()
    assert lam[0] == 400.0 and lam[-1] == 700.0 and len(lam) == 61
    np.testing.assert_allclose(0.5 * (table[:-1] + table[1:]).mean(axis=0), 1.0, rtol=1e-12)
    srgb = mi.xyz_to_srgb(mi.cie1931_xyz(mi.Float(lam.astype(np.float32))))
    ref = np.array([np.asarray(srgb[i]) for i in range(3)]).T
    np.testing.assert_allclose(table * (ref[30] / table[30]), ref, rtol=1e-4, atol=1e-5)
    grid = 400.0 + 300.0 * (np.arange(30000) + 0.5) / 30000
    w = spectral.rgb_weight(mi.Float(grid.astype(np.float32)))
    np.testing.assert_allclose([float(np.mean(np.asarray(w[i]))) for i in range(3)], 1.0, atol=2e-4)
    # the kernel's samples: 64 passes of 2000 pixels, stratified per pixel
    passes, pixels = 64, 2000
    total = np.zeros(3)
    for k in range(passes):
        pk, qk = pixel_keys(dr.arange(mi.UInt32, pixels), dr.opaque(mi.UInt32, 3), dr.opaque(mi.UInt32, k))
        lam_k = spectral.wavelength(pk, qk, dr.opaque(mi.UInt32, k), dr.opaque(mi.UInt32, passes))
        lam_np = np.asarray(lam_k)
        assert lam_np.min() >= 400.0 and lam_np.max() < 700.0
        w = spectral.rgb_weight(lam_k)
        total += [float(np.sum(np.asarray(w[i]))) for i in range(3)]
    np.testing.assert_allclose(total / (passes * pixels), 1.0, atol=2e-3)


def test_wavelengths_are_stratified_over_the_passes(mi: Any) -> None:
    """The N passes of a pixel put one wavelength in each of N equal strata of 400-700 nm."""
    import drjit as dr

    from a5mi.plugins.materials import spectral
    from a5mi.plugins.sampling import pixel_keys

    n = 16
    lams = []
    for k in range(n):
        pk, qk = pixel_keys(dr.arange(mi.UInt32, 50), dr.opaque(mi.UInt32, 0), dr.opaque(mi.UInt32, k))
        lams.append(np.asarray(spectral.wavelength(pk, qk, dr.opaque(mi.UInt32, k), dr.opaque(mi.UInt32, n))))
    strata = np.sort(np.floor((np.array(lams) - 400.0) / (300.0 / n)).astype(int), axis=0)
    assert np.array_equal(strata, np.repeat(np.arange(n)[:, None], 50, axis=1))


# ------------------------------------------------------------------------------------------------ Snell
def _snell_exit_angle(n: np.ndarray, theta1: float) -> np.ndarray:
    """Analytic exit angle (from the exit face's normal) of a ray in the cross-section plane of a prism of
    apex angle APEX: sin θ1 = n sin θ1', θ2 = APEX − θ1', n sin θ2 = sin θ_out."""
    inner = np.arcsin(np.sin(theta1) / n)
    return np.arcsin(n * np.sin(math.radians(APEX) - inner))


def test_prism_exit_angles_follow_snell_with_cauchy_index(mi: Any) -> None:
    """One ray per lane through the prism, traced by the render kernel (a5mi trace's recorder reads each
    node's direction and weight); every lane has its own wavelength. The exit angle equals the two-refraction
    Snell computation with n(λ) = A + B/λ², red leaves less deviated than blue, the rays stay in the plane, and
    the path weight is multiplied by w(λ) once."""
    import drjit as dr

    from a5mi.converters.describe import describe
    from a5mi.plugins.kernel.record import NODE_LAYOUT, TreeRecorder
    from a5mi.plugins.materials import spectral
    from a5mi.plugins.sampling import SamplePass, pixel_keys
    from a5mi.render.options import RenderOptions
    from a5mi.render.session import build_scene

    text = _scene_text(f"dispersion {A} {B}", _prism_text(), 9)
    scene = build_scene(describe(parse_text(text)), RenderOptions(reflection=False, bounces=4))
    integ = scene.integrator()
    assert integ.dispersion
    lanes, seed, passes = 256, 5, 4
    d_in = np.array([0.0, 0.0, -1.0])
    o = mi.Point3f(np.zeros(lanes), np.full(lanes, 0.2), np.full(lanes, 5.0))
    ray = mi.Ray3f(o, mi.Vector3f(*(np.full(lanes, c, dtype=np.float32) for c in d_in)))
    rec = TreeRecorder(lanes, 4, 1)
    integ.trace(scene, ray, record=rec, sample_pass=SamplePass(0, 1, passes, seed))
    nodes, _, count = rec.read()
    pk, qk = pixel_keys(dr.arange(mi.UInt32, lanes), dr.opaque(mi.UInt32, seed), dr.opaque(mi.UInt32, 1))
    lam = np.asarray(spectral.wavelength(pk, qk, dr.opaque(mi.UInt32, 1), dr.opaque(mi.UInt32, passes)))
    n = A + B / (lam * 1e-3) ** 2

    tris = _prism_triangles()
    normals = [np.cross(b - a, c - a) / np.linalg.norm(np.cross(b - a, c - a)) for a, b, c in tris]
    n1 = max(normals, key=lambda m: -m @ d_in)            # the entry face faces the ray
    off, _ = NODE_LAYOUT["d"]
    d_out = nodes[:, 2, off:off + 3].astype(np.float64)
    assert np.all(count >= 3)
    n2 = next(m for m in normals if abs(m[1]) < 0.5 and m @ d_out[0] > 0.5)    # the face the ray leaves by
    theta1 = math.acos(-n1 @ d_in)
    assert math.isclose(math.degrees(math.acos(np.clip(n1 @ n2, -1, 1))), 180.0 - APEX, abs_tol=1e-4)
    np.testing.assert_allclose(d_out[:, 1], 0.0, atol=1e-6)
    exit_angle = np.arccos(np.clip(d_out @ n2, -1.0, 1.0))
    np.testing.assert_allclose(exit_angle, _snell_exit_angle(n, theta1), atol=3e-5)
    deviation = np.degrees(np.arccos(np.clip(d_out @ d_in, -1.0, 1.0)))
    red, blue = lam > 620.0, lam < 450.0
    assert red.sum() > 20 and blue.sum() > 20
    assert deviation[red].max() < deviation[blue].min() - 2.0   # B = 0.02: several degrees between them
    # the camera ray and the ray inside are the kernel's too: the inside direction obeys the first refraction
    inside = nodes[:, 1, off:off + 3].astype(np.float64)
    np.testing.assert_allclose(np.arccos(np.clip(-inside @ n1, -1, 1)), np.arcsin(np.sin(theta1) / n), atol=3e-5)
    # the path is weighted once, at its first dispersive refraction: inside, weight = (1 - R1) w(λ); outside,
    # weight = (1 - R1)(1 - R2) w(λ) (grey factors 1 - R, the specularColor is white)
    woff, _ = NODE_LAYOUT["weight"]
    w_lam = spectral.rgb_weight(mi.Float(lam))
    w_lam = np.array([np.asarray(w_lam[i]) for i in range(3)]).T.astype(np.float64)
    w1, w2 = (nodes[:, k, woff:woff + 3].astype(np.float64) for k in (1, 2))
    np.testing.assert_allclose(w1 / w_lam, (w1 / w_lam)[:, :1] + np.zeros(3), rtol=1e-4)
    assert np.all((w1 / w_lam)[:, 0] > 0.8) and np.all((w1 / w_lam)[:, 0] < 1.0)
    np.testing.assert_allclose(w2 / w1, (w2 / w1)[:, :1] + np.zeros(3), rtol=1e-4)
    assert np.all((w2 / w1)[:, 0] > 0.8) and np.all((w2 / w1)[:, 0] < 1.0)


# ------------------------------------------------------------------------------------------------ B = 0, paths
def _render(text: str, **opts: Any) -> np.ndarray:
    return render_text(text, **{"width": 32, "height": 32, "shadows": True, "bounces": 4, **opts})


def test_b_zero_renders_the_non_dispersive_image_bit_for_bit(mi: Any) -> None:
    """``dispersion A 0`` compiles the dispersion kernel, yet every pixel equals ``refractionIndex A``."""
    from a5mi.converters.describe import describe
    from a5mi.converters.to_mitsuba import integrator_dict
    from a5mi.render.options import RenderOptions

    objects = "Sphere { center 0.3 0 0 radius 1 } MaterialIndex 0 Sphere { center -1.2 0.5 -2 radius 0.7 }"
    zero = _scene_text("dispersion 1.5 0", objects, 3)
    assert integrator_dict(describe(parse_text(zero)), RenderOptions(), stock=False)["dispersion"] is True
    assert "dispersion" not in integrator_dict(describe(parse_text(_scene_text("1.5", objects, 3))),
                                               RenderOptions(), stock=False)
    plain = _render(_scene_text("1.5", objects, 3), spp=2)
    assert np.array_equal(_render(zero, spp=2), plain)
    assert not np.allclose(_render(_scene_text("dispersion 1.5 0.02", objects, 3), spp=2), plain, atol=1e-3)


def test_paths_without_a_dispersive_refraction_are_unchanged(mi: Any) -> None:
    """With a dispersive prism in the scene, every pixel whose ray tree never meets glass (class AOV < 2) is
    bit for bit the render without dispersion: only dispersively refracted paths carry w(λ)."""
    from a5mi.converters.describe import describe
    from a5mi.render.options import RenderOptions
    from a5mi.render.session import render

    objects = _prism_text() + " MaterialIndex 0 Sphere { center -2.2 0.4 0 radius 0.6 }"
    opts = RenderOptions(width=40, height=40, shadows=True, bounces=4, spp=2, classes=True)
    disp = render(describe(parse_text(_scene_text(f"dispersion {A} {B}", objects, 10))), opts)
    plain = render(describe(parse_text(_scene_text(f"{A}", objects, 10))), opts)
    assert plain.classes is not None and plain.classes.shape == plain.image.shape[:2]
    opaque = plain.classes < 2
    assert 0.2 < opaque.mean() < 0.9
    a, b = np.asarray(disp.image), np.asarray(plain.image)
    assert np.array_equal(a[opaque], b[opaque])
    assert not np.allclose(a[~opaque], b[~opaque], atol=1e-3)


# ------------------------------------------------------------------------------------------------ stock
def test_stock_mapping_uses_the_centre_wavelength(mi: Any) -> None:
    from a5mi.converters import materials
    from a5mi.converters.describe import describe

    desc = describe(parse_text(_scene_text(f"dispersion {A} {B}", "Sphere { center 0 0 0 radius 1 }", 2)),
                    stock=True)
    glass = desc.materials[1]
    a5 = materials.bsdf(glass, False, stock=False)
    assert (a5["refraction_index"], a5["cauchy_b"]) == (A, B)
    stock = materials.bsdf(glass, False, stock=True)
    assert stock["type"] == "dielectric"
    assert stock["int_ior"] == pytest.approx(A + B / 0.55 ** 2, rel=1e-12)
    assert any("dispersion replaced by the index at the centre wavelength" in msg for _, msg in desc.warnings)
    mi.load_dict(stock)
    # a5_material's physical face (for stock integrators) refracts at the same index
    import drjit as dr

    si = dr.zeros(mi.SurfaceInteraction3f)
    si.wi, si.sh_frame = mi.Vector3f(0.6, 0, 0.8), mi.Frame3f(mi.Vector3f(0, 0, 1))
    bs, _ = mi.load_dict(a5).sample(mi.BSDFContext(), si, 0.99, mi.Point2f(0.5, 0.5))
    assert float(bs.eta[0]) == pytest.approx(A + B / 0.55 ** 2, rel=1e-6)


def test_prism_demo_converts_both_ways(mi: Any, tmp_path: Any) -> None:
    """scenes/prism.txt: the a5 dict turns the dispersion kernel on and carries B; the stock dict (and its XML)
    loads in plain Mitsuba with a dielectric at the 550 nm index and renders with the path tracer."""

    from a5mi.converters.a5_parser import parse_file
    from a5mi.converters.describe import describe
    from a5mi.converters.to_mitsuba import to_dict
    from a5mi.converters.to_xml import write_xml
    from a5mi.render.options import RenderOptions

    desc = describe(parse_file(ROOT / "scenes" / "prism.txt"), stock=True)
    options = RenderOptions(width=24, height=24, spp=4)
    a5 = to_dict(desc, options)
    assert a5["integrator"]["dispersion"] is True
    stock = to_dict(desc, options, stock=True)
    assert "dispersion" not in stock["integrator"]
    img = np.asarray(mi.render(mi.load_dict(stock), spp=4))
    assert np.all(np.isfinite(img)) and img.mean() > 0.005
    xml = tmp_path / "prism.xml"
    write_xml(desc, xml, options, stock=True)
    text = xml.read_text()
    assert "dielectric" in text and f"{1.6 + 0.012 / 0.55 ** 2:.6g}"[:6] in text
    mi.load_file(str(xml))


def test_one_lane_launch_without_passes(mi: Any) -> None:
    """A one-lane launch without a SamplePass (what ``a5mi trace`` does) compiles the dispersion kernel (the weight
    table is built before the kernel's loop: built inside it, this launch aborted the process) and gives the
    colour of a lane of a wider launch with the same keys."""
    from a5mi.converters.describe import describe
    from a5mi.plugins.kernel.record import TreeRecorder
    from a5mi.render.options import RenderOptions
    from a5mi.render.session import build_scene

    text = _scene_text(f"dispersion {A} {B}", _prism_text(), 9)
    scene = build_scene(describe(parse_text(text)), RenderOptions(bounces=4))
    integ = scene.integrator()
    colors = []
    for n in (1, 4):
        o = mi.Point3f(np.zeros(n), np.full(n, 0.2), np.full(n, 5.0))
        ray = mi.Ray3f(o, mi.Vector3f(np.full(n, -0.05), np.zeros(n), np.full(n, -1.0)))
        c = integ.trace(scene, ray, mi.Bool(True), record=TreeRecorder(n, 15, 1))[0]
        colors.append(np.array([np.asarray(c[i]) for i in range(3)]).T)
    assert np.all(np.isfinite(colors[0]))
    np.testing.assert_allclose(colors[0][0], colors[1][0], rtol=1e-6, atol=1e-7)

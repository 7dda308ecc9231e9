"""a5mi crosscheck: what physics predicts about the three Fresnel modes and Mitsuba's path integrator.

Scenes are built by hand as dicts (stand-ins for ``converters.to_mitsuba.to_dict``), small and analytic:

* the Fresnel modes agree bit for bit wherever the Whitted ray tree never refracts;
* a clear glass sphere (``kd = 0``, ``specularColor = 1``) in a constant environment, ``bounces 1``, renders
  exactly ``R(θ) · Le``: each mode's formula is recovered per pixel, Schlick equals exact Fresnel at normal
  incidence and differs most at grazing angles;
* with ``bounces B`` the exact-Fresnel Whitted image *is* the expectation of ``path`` with ``max_depth B + 1``
  (the 1/η² of the way in cancels the η² of the way out), within Monte Carlo error;
* what Whitted leaves out and ``path`` has: environment light on diffuse surfaces (furnace: ``kd · Le``),
  indirect light in shadows.
"""

from __future__ import annotations

import json
import math
from types import SimpleNamespace

import numpy as np
import pytest
from conftest import a5_material as _a5
from conftest import rgb as _rgb

from a5mi import crosscheck as xc

CLEAR_GLASS = {"diffuse_color": (0.0, 0.0, 0.0), "specular_color": (1.0, 1.0, 1.0), "refraction_index": 1.5}
ENV = (0.8, 0.6, 0.4)
HEAD_ON = SimpleNamespace(center=(0.0, 0.0, 8.0), direction=(0.0, 0.0, -1.0), up=(0.0, 1.0, 0.0), angle=15.0)


def _scene(**objects) -> dict:
    return {"type": "scene", "integrator": {"type": "a5_whitted"}, **objects}


def _env(rgb=ENV) -> dict:
    return {"type": "constant", "radiance": _rgb(*rgb)}


def _pixel_geometry(camera, w: int, h: int) -> tuple[np.ndarray, np.ndarray]:
    """Unit camera ray directions (HxWx3, row 0 = top) of SPEC B.2 pixel centres, from a5mi's own rays."""
    ray = xc._pixel_rays(camera, w, h)
    d = np.array(ray.d, dtype=np.float64).T.reshape(h, w, 3)[::-1]
    o = np.array(camera.center, dtype=np.float64)
    return o, d


def _sphere_cos(camera, w: int, h: int, center=(0.0, 0.0, 0.0), radius: float = 1.0) -> np.ndarray:
    """|cos θ| of the first hit of each pixel's camera ray with a sphere (NaN on a miss)."""
    o, d = _pixel_geometry(camera, w, h)
    oc = o - np.array(center)
    b = d @ oc
    disc = b * b - (oc @ oc - radius * radius)
    t = -b - np.sqrt(np.where(disc >= 0, disc, np.nan))
    p = o + t[..., None] * d
    n = (p - np.array(center)) / radius
    return np.abs(np.sum(n * d, axis=2))


def _fresnel_exact(cos_i: np.ndarray, eta: float) -> np.ndarray:
    """Unpolarised dielectric Fresnel reflectance from the outside, ½(r_s² + r_p²) (textbook form)."""
    sin_t2 = (1.0 - cos_i**2) / eta**2
    cos_t = np.sqrt(1.0 - sin_t2)
    rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
    rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
    return 0.5 * (rs**2 + rp**2)


# ------------------------------------------------------------------------------------------------ metrics


def test_masked_metrics_by_hand():
    a = np.zeros((4, 5, 3))
    b = np.zeros((4, 5, 3))
    b[1, 3] = [6.0, 0.0, 0.0]  # inside the mask, over 2 levels
    b[3, 0] = [1.0, 1.0, 1.0]  # inside the mask, under the threshold
    b[0, 0] = [100.0, 0.0, 0.0]  # outside the mask: ignored
    mask = np.zeros((4, 5), bool)
    mask[1:, :] = True  # 15 pixels, 45 values
    m = xc.masked_metrics(a, b, mask)
    assert m is not None
    assert m.mean_error == pytest.approx((6.0 + 3.0) / 45)
    assert m.psnr == pytest.approx(10 * math.log10(255.0**2 / ((36.0 + 3.0) / 45)))
    assert m.share_over == pytest.approx(1 / 15)
    assert m.max_error == 6.0
    assert m.bbox == (3, 1, 3, 1)  # image coordinates of the one pixel over the threshold
    assert (m.width, m.height) == (5, 4)
    assert xc.masked_metrics(a, b, np.zeros((4, 5), bool)) is None


def test_levels_are_the_saved_bytes():
    img = np.array([[[0.0, 0.5, 1.5]], [[-0.1, 1.0 / 255.0, 0.999]]], dtype=np.float32)
    assert xc.levels(img).tolist() == [[[0, 127, 255]], [[0, 1, 254]]]


def test_path_depth_counts_segments():
    assert xc.CrosscheckOptions(bounces=0).path_max_depth == 2  # camera segment + light connection
    assert xc.CrosscheckOptions(bounces=4).path_max_depth == 6
    d = xc.path_dict({"type": "scene", "integrator": {"type": "whatever"}, "s": {}}, xc.CrosscheckOptions(bounces=3))
    assert d["integrator"] == {"type": "path", "max_depth": 5, "rr_depth": xc.NO_RR_DEPTH}
    assert "s" in d


# --------------------------------------------------------------------------------- Fresnel modes, classes


def _mixed_scene() -> dict:
    """A glass sphere on a reflective floor next to an opaque red sphere, a light and an environment."""
    return _scene(
        glass={"type": "sphere", "center": [-0.6, 0.0, 0.0], "radius": 0.7,
               "bsdf": _a5(diffuse_color=(0.1, 0.1, 0.1), specular_color=(0.9, 0.9, 0.9), refraction_index=1.3)},
        red={"type": "sphere", "center": [0.9, -0.2, 0.3], "radius": 0.5, "bsdf": _a5(diffuse_color=(1, 0.1, 0.1))},
        floor={"type": "rectangle", "to_world": None,
               "bsdf": _a5(diffuse_color=(0.3, 0.3, 0.3), specular_color=(0.2, 0.2, 0.5))},
        light={"type": "directional", "direction": [0.3, -1.0, -0.4], "irradiance": _rgb(0.7, 0.7, 0.7)},
        env=_env((0.2, 0.1, 0.6)),
    )


@pytest.fixture(scope="module")
def mixed(mi):
    d = _mixed_scene()
    d["floor"]["to_world"] = mi.ScalarTransform4f().translate([0, -0.7, 0]).rotate([1, 0, 0], -90).scale(6)
    d["integrator"] = {"type": "a5_whitted", "ambient": _rgb(0.2, 0.2, 0.2)}
    camera = SimpleNamespace(center=(0.0, 0.8, 5.0), direction=(0.0, -0.2, -1.0), up=(0.0, 1.0, 0.0), angle=35.0)
    opts = xc.CrosscheckOptions(width=72, height=72, bounces=4)
    scene = mi.load_dict(d)
    images = {m: xc.render_whitted(scene, camera, d["integrator"], opts, m) for m in xc.FRESNEL_MODES}
    classes = xc.pixel_classes(scene, camera, opts.width, opts.height, opts.bounces)
    return SimpleNamespace(images=images, classes=classes, camera=camera, opts=opts)


def test_modes_agree_exactly_off_glass(mixed):
    glass = mixed.classes == xc.GLASS
    for a, b in (("a5", "schlick"), ("a5", "exact"), ("schlick", "exact")):
        ia, ib = mixed.images[a], mixed.images[b]
        assert np.array_equal(ia[~glass], ib[~glass]), f"{a} vs {b} differ off the glass pixels"
        # ... and do differ on them: the mask is where the Fresnel weight lives.
        assert np.abs(ia[glass] - ib[glass]).max() > 1e-3
    # Every pixel where some pair differs is classed glass (the mask is not too small) ...
    differ = np.zeros(glass.shape, bool)
    for a, b in (("a5", "schlick"), ("a5", "exact")):
        differ |= np.any(mixed.images[a] != mixed.images[b], axis=2)
    assert np.all(glass[differ])


def test_classes_follow_the_ray_tree(mixed):
    w, h = mixed.opts.width, mixed.opts.height
    direct = ~np.isnan(_sphere_cos(mixed.camera, w, h, (-0.6, 0.0, 0.0), 0.7))
    glass = mixed.classes == xc.GLASS
    assert np.all(glass[direct])  # every camera ray hitting the glass sphere
    # ... and the reflections of the glass sphere in the floor: glass pixels whose camera ray does not hit it.
    assert (glass & ~direct).sum() > 20
    assert (mixed.classes == xc.BACKGROUND).sum() > 0 and (mixed.classes == xc.OPAQUE).sum() > 0
    # Background pixels are exactly the environment colour in every mode.
    bg = mixed.classes == xc.BACKGROUND
    assert np.allclose(mixed.images["a5"][bg], [0.2, 0.1, 0.6], atol=1e-7)


# ---------------------------------------------------------------------- Schlick vs exact, by incidence angle


@pytest.fixture(scope="module")
def clear_sphere(mi):
    """bounces 1: pixel = R(θ)·Le + (1 − R)·(inside hit, kd = 0 and no lights: 0) = R(θ)·Le exactly."""
    d = _scene(s={"type": "sphere", "bsdf": _a5(**CLEAR_GLASS)}, env=_env())
    scene = mi.load_dict(d)
    opts = xc.CrosscheckOptions(width=96, height=96, bounces=1)
    images = {m: xc.render_whitted(scene, HEAD_ON, {}, opts, m) for m in xc.FRESNEL_MODES}
    cos = _sphere_cos(HEAD_ON, opts.width, opts.height)
    return SimpleNamespace(R={m: img[..., 0] / ENV[0] for m, img in images.items()}, images=images, cos=cos)


def test_each_mode_is_its_formula(clear_sphere):
    hit = ~np.isnan(clear_sphere.cos)
    c = clear_sphere.cos[hit]
    r0 = ((1.5 - 1.0) / (1.5 + 1.0)) ** 2
    assert np.allclose(clear_sphere.R["exact"][hit], _fresnel_exact(c, 1.5), atol=2e-4)
    assert np.allclose(clear_sphere.R["schlick"][hit], r0 + (1 - r0) * (1 - c) ** 5, atol=2e-4)
    # Entering from air (n = 1) the binary's R0 = ((nt−1)/(nt+1))² is the textbook one: a5 == schlick.
    assert np.array_equal(clear_sphere.images["a5"], clear_sphere.images["schlick"])
    # The three channels carry the same R (white specularColor).
    img = clear_sphere.images["exact"][hit]
    assert np.allclose(img / np.array(ENV), img[:, :1] / ENV[0], atol=1e-6)


def test_schlick_equals_exact_head_on_and_differs_most_at_grazing(clear_sphere):
    hit = ~np.isnan(clear_sphere.cos)
    theta = np.degrees(np.arccos(np.clip(clear_sphere.cos, 0, 1)))
    diff = np.abs(clear_sphere.R["schlick"] - clear_sphere.R["exact"])
    head_on = hit & (theta < 10)
    grazing = hit & (theta > 75)
    assert head_on.sum() > 10 and grazing.sum() > 10
    assert diff[head_on].max() < 2e-4  # both are R0 = 0.04 at θ = 0
    assert clear_sphere.R["exact"][head_on].min() == pytest.approx(0.04, abs=2e-3)
    # The largest difference sits at grazing incidence, and is much larger than anywhere near normal.
    worst = np.unravel_index(np.nanargmax(np.where(hit, diff, np.nan)), diff.shape)
    assert theta[worst] > 75
    assert diff[grazing].max() > 0.02 > 50 * diff[head_on].max()
    # Binned by angle, the mean difference grows from normal incidence to the two ends of the grazing range.
    bins = [diff[hit & (theta >= lo) & (theta < lo + 15)].mean() for lo in (0, 15, 30, 45)]
    assert bins == sorted(bins)


def test_a5_differs_from_schlick_only_on_the_way_out(mi):
    """bounces 2 reaches the exit interface, where the binary's R0 uses 1 in place of n: R0 = 0 there."""
    scene = mi.load_dict(_scene(s={"type": "sphere", "bsdf": _a5(**CLEAR_GLASS)}, env=_env()))
    opts = xc.CrosscheckOptions(width=48, height=48, bounces=2)
    a5 = xc.render_whitted(scene, HEAD_ON, {}, opts, "a5")
    schlick = xc.render_whitted(scene, HEAD_ON, {}, opts, "schlick")
    hit = ~np.isnan(_sphere_cos(HEAD_ON, 48, 48))
    # Exit: the a5 R is smaller (R0 = 0 instead of 0.04), so more light is transmitted out: a5 is brighter.
    assert np.all(a5[hit] >= schlick[hit] - 1e-6)
    assert (a5[hit] - schlick[hit]).max() > 0.01
    assert np.array_equal(a5[~hit], schlick[~hit])


# --------------------------------------------------------------------------------------- against path


@pytest.mark.parametrize("stock_bsdf", ["dielectric", "a5_material"])
def test_exact_whitted_is_the_mean_of_path_on_clear_glass(mi, stock_bsdf):
    """No lights, kd = 0: Whitted with exact Fresnel sums the same delta paths that ``path`` samples.
    Mitsuba scales radiance by 1/η² entering glass and η² leaving it; every camera-to-environment path does
    both, so the scaling cancels (a factor 1/2.25 or 2.25 would be far outside the tolerance)."""
    bounces = 3
    w = h = 32
    a5_scene = mi.load_dict(_scene(s={"type": "sphere", "bsdf": _a5(**CLEAR_GLASS)}, env=_env()))
    opts = xc.CrosscheckOptions(width=w, height=h, bounces=bounces)
    whitted = xc.render_whitted(a5_scene, HEAD_ON, {}, opts, "exact")
    bsdf = ({"type": "dielectric", "int_ior": 1.5, "ext_ior": 1.0} if stock_bsdf == "dielectric"
            else _a5(**CLEAR_GLASS))
    stock = mi.load_dict({"type": "scene", "s": {"type": "sphere", "bsdf": bsdf}, "env": _env()})
    spp = 256
    path, stderr = xc.render_path(stock, HEAD_ON, w, h, spp, bounces + 1, seed=7)
    assert 0 < stderr < 20
    hit = ~np.isnan(_sphere_cos(HEAD_ON, w, h))
    # Misses: both the environment, exactly.
    assert np.allclose(path[~hit], ENV, atol=1e-6) and np.allclose(whitted[~hit], ENV, atol=1e-7)
    # Hits: the image means agree to a few standard errors of the mean (independent pixels).
    err = path[hit] - whitted[hit]
    sigma = np.sqrt(np.mean(whitted[hit] * (np.array(ENV) - whitted[hit])) / spp / err.size)  # Bernoulli-like bound
    assert abs(err.mean()) < 5 * sigma + 1e-4
    assert np.abs(err).mean() < 0.06
    # The head-on pixel (θ ≈ 0 everywhere on the axis, R0 = 0.04, 3 bounces): R0 reflected, (1 − R0)² through,
    # (1 − R0)² R0 after one inner round trip (the second needs a 4th bounce); no light is lost in glass.
    r0 = 0.04
    centre = whitted[h // 2, w // 2]
    assert centre[0] / ENV[0] == pytest.approx(r0 + (1 - r0) ** 2 * (1 + r0), abs=1e-3)


def test_path_has_environment_light_whitted_has_none(mi):
    """Furnace: a convex diffuse sphere in a constant environment Le is ``kd · Le`` under path (every point
    sees the environment over its whole hemisphere), black under Whitted with no lights and no ambient."""
    kd = 0.5
    w = h = 24
    a5_scene = mi.load_dict(_scene(s={"type": "sphere", "bsdf": _a5(diffuse_color=(kd, kd, kd))}, env=_env()))
    whitted = xc.render_whitted(a5_scene, HEAD_ON, {}, xc.CrosscheckOptions(width=w, height=h), "exact")
    stock = mi.load_dict({"type": "scene", "s": {"type": "sphere", "bsdf": {
        "type": "diffuse", "reflectance": _rgb(kd, kd, kd)}}, "env": _env()})
    path, _ = xc.render_path(stock, HEAD_ON, w, h, 64, 2)
    hit = ~np.isnan(_sphere_cos(HEAD_ON, w, h))
    assert np.all(whitted[hit] == 0.0)
    assert np.allclose(path[hit].mean(axis=0), kd * np.array(ENV), rtol=0.02)


def test_indirect_light_fills_whitted_shadows(mi):
    """A diffuse sphere over a diffuse floor, one directional light: the floor in the sphere's shadow is 0
    under Whitted (no ambient), lit only by light bounced off the sphere under path."""
    w = h = 40
    light = {"type": "directional", "direction": [0.0, -1.0, 0.0], "irradiance": _rgb(1.0, 1.0, 1.0)}
    camera = SimpleNamespace(center=(0.0, 3.0, 6.0), direction=(0.0, -0.5, -1.0), up=(0.0, 1.0, 0.0), angle=30.0)

    def objects(bsdf):
        import mitsuba

        floor = mitsuba.ScalarTransform4f().translate([0, -1.0, 0]).rotate([1, 0, 0], -90).scale(5)
        return {"ball": {"type": "sphere", "center": [0, 0.2, 0], "radius": 0.8, "bsdf": bsdf},
                "floor": {"type": "rectangle", "to_world": floor, "bsdf": bsdf}, "light": light}

    a5_scene = mi.load_dict(_scene(**objects(_a5(diffuse_color=(0.8, 0.8, 0.8)))))
    whitted = xc.render_whitted(a5_scene, camera, {}, xc.CrosscheckOptions(width=w, height=h, bounces=2), "exact")
    stock = mi.load_dict({"type": "scene", **objects({"type": "diffuse", "reflectance": _rgb(0.8, 0.8, 0.8)})})
    path, _ = xc.render_path(stock, camera, w, h, 64, 4)
    o, d = _pixel_geometry(camera, w, h)
    t = (-1.0 - o[1]) / d[..., 1]
    p = o + t[..., None] * d
    in_shadow = (t > 0) & (np.hypot(p[..., 0], p[..., 2]) < 0.6) & (np.abs(p[..., 0]) < 5)
    # ... and not hidden behind the ball: the camera ray's first hit is the floor (Whitted's normal is +y).
    assert in_shadow.sum() > 5
    assert np.all(whitted[in_shadow] == 0.0)
    assert path[in_shadow].mean() > 0.01


# ---------------------------------------------------------------------------------------- whole command


def test_crosscheck_dicts_table_and_montage(mi, tmp_path):
    d = _mixed_scene()
    d["floor"]["to_world"] = mi.ScalarTransform4f().translate([0, -0.7, 0]).rotate([1, 0, 0], -90).scale(6)
    stock = dict(d)
    camera = SimpleNamespace(center=(0.0, 0.8, 5.0), direction=(0.0, -0.2, -1.0), up=(0.0, 1.0, 0.0), angle=35.0)
    r = xc.crosscheck_dicts(d, stock, camera, xc.CrosscheckOptions(width=40, height=40, spp=8))
    assert set(r.images) == set(xc.LABELS)
    by = {(p.a, p.b, p.region): p for p in r.pairs}
    assert len(by) == 2 * len(xc.PAIRS)
    for a, b in xc.PAIRS[:3]:
        assert by[a, b, "other"].metrics.max_error == 0.0
        assert by[a, b, "glass"].pixels == int(r.glass.sum()) > 0
    text = xc.table(r)
    assert "glass" in text and "path" in text and "max_depth 6" in text
    js = json.loads(xc.to_json(r))
    assert js["pixels"]["glass"] == int(r.glass.sum()) and len(js["pairs"]) == 12
    out = tmp_path / "m.png"
    xc.write_montage(r, out)
    from a5mi.platform.imageio import read_image

    img = read_image(out)
    assert img.shape[1] == 4 * 40 + 3 * 4 and img.shape[0] == 3 * (40 + 18 + 4)
    # The top-left tile is the a5 render, byte for byte.
    assert np.array_equal(np.round(img[:40, :40] * 255).astype(int), xc.levels(r.images["a5"]).astype(int))


def _run(argv: list[str]) -> int:
    from a5mi.cli import run_a5mi

    return run_a5mi(["crosscheck", *argv])


def test_cli_usage_errors(capsys):
    assert _run(["-h"]) == 0
    assert "usage: a5mi crosscheck" in capsys.readouterr().out
    assert _run([]) == 2
    assert "a5mi crosscheck: error: missing SCENE.txt" in capsys.readouterr().err
    assert _run(["x.txt", "--bogus"]) == 2
    assert "unknown flag '--bogus'" in capsys.readouterr().err
    assert _run(["x.txt", "--spp", "zero"]) == 2
    assert "--spp expects an integer" in capsys.readouterr().err
    assert _run(["x.txt", "-size", "4"]) == 2
    assert "-size expects 2 values" in capsys.readouterr().err


def test_scene10_end_to_end(variant, scenes_dir, tmp_path, capsys):
    out = tmp_path / "m.png"
    rc = _run([str(scenes_dir / "scene10_sphere.txt"), "-size", "48", "48", "--spp", "8", "-o", str(out),
                 "--json"])
    assert rc == 0, capsys.readouterr().err
    js = json.loads(capsys.readouterr().out)
    assert js["pixels"]["glass"] > 100  # the glass sphere and its reflection in the marble floor
    for p in js["pairs"]:
        if p["b"] != "path" and p["region"] == "other":
            assert p["metrics"]["max_error"] == 0.0
    assert out.is_file()


def test_explain_terms_add_up_to_the_total(variant, a5_data) -> None:
    """The decomposition of (stock path − exact Whitted) is exact: the five terms sum to the total."""
    from a5mi.converters.a5_parser import parse_file
    from a5mi.crosscheck import CrosscheckOptions, explain

    terms = explain(parse_file(a5_data / "scenes" / "scene10_sphere.txt"),
                    CrosscheckOptions(width=24, height=24, spp=2))
    *parts, total = terms
    assert total.term.startswith("total")
    assert sum(t.glass for t in parts) == pytest.approx(total.glass, abs=1e-6)
    assert sum(t.other for t in parts) == pytest.approx(total.other, abs=1e-6)
    ambient = next(t for t in parts if "ambient" in t.term)
    assert ambient.glass < 0 and ambient.other < 0  # removing ambient can only darken


def test_montage_error_scale_follows_what_the_row_shows() -> None:
    """The path row is scaled to its 99th-percentile error (a power of two), not a fixed 64/255 that saturates."""
    errs = [np.full(1000, 40.0), np.full(1000, 3.0)]
    assert xc.error_scale(errs) == 64.0  # p99 = 40 -> 64
    assert xc.error_scale([np.full(100, 0.0)]) == 4.0 and xc.error_scale([np.full(100, 900.0)]) == 256.0
    assert xc.error_scale([np.r_[np.zeros(990), np.full(10, 200.0)]]) == 4.0  # 1% outliers do not set it


def test_sample_statistics_with_inf_samples_warn_nothing() -> None:
    """Two pixels of 4 samples: (1, 3, 1, 3) has mean 2 and unbiased variance 4/3, so a standard error of
    sqrt(4/3 / 4) = 0.577 (147.2 levels); a pixel of inf samples (a scene scaled by 1e30) keeps its inf mean and
    is left out of the standard error, with no RuntimeWarning (inf − inf)."""
    import warnings

    from a5mi.crosscheck.core import sample_statistics

    samples = np.array([[1.0, 3.0, 1.0, 3.0], [np.inf] * 4])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        mean, stderr = sample_statistics(samples.sum(axis=1), (samples * samples).sum(axis=1), 4)
    assert mean[0] == 2.0 and mean[1] == np.inf
    assert stderr == pytest.approx(math.sqrt(4.0 / 3.0 / 4.0) * 255.0)
    assert sample_statistics(np.array([np.inf]), np.array([np.inf]), 4)[1] == 0.0

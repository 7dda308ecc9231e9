"""``a5_irradiancecache`` (docs/EXTENSIONS.md E.23) as a Mitsuba plugin and through ``a5``: parameters, the
records picture, reuse of records, and its indirect light against path tracing (``-integrator path``, E.14).

The comparison with path tracing traces the same pixel-centre camera rays: the cache's colour splits into the
part it computes per pixel (delta lobes, emission, next-event estimation: deterministic for delta lights) and
``β kd/π ⊙ E`` from the records; path tracing's indirect light is its mean minus that first part. σ is the
standard error of the path estimate, from the per-pixel variance over its passes.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from helpers import ROOT

from a5mi import cli
from a5mi.converters.a5_parser import parse_file
from a5mi.converters.describe import describe
from a5mi.platform import imageio
from a5mi.render import session
from a5mi.render.driver import render_scene
from a5mi.render.options import RenderOptions

SCENES = ROOT / "scenes"


def _options(size: int, **kw: Any) -> RenderOptions:
    return RenderOptions(width=size, height=size, integrator="irradiancecache", **kw)


def _load(path: Path) -> Any:
    return describe(parse_file(str(path)))


def _rays(mi: Any, desc: Any, w: int, h: int) -> Any:
    from a5mi.plugins.sensors.camera import camera_rays

    c = desc.camera
    i, j = np.tile(np.arange(w), h), np.repeat(np.arange(h), w)
    return camera_rays(c.center, c.direction, c.up, c.angle, mi.Float(i.astype(np.float32)),
                       mi.Float(j.astype(np.float32)), w, h)


def _indirect_against_path(mi: Any, desc: Any, size: int, spp: int, samples: int) -> tuple[np.ndarray, ...]:
    """``(cache's indirect, path's indirect mean, variance of one path pass)`` per pixel (W·H values, the three
    channels summed) over pixel centres (module docstring)."""
    import drjit as dr

    from a5mi.plugins.sampling import SamplePass, Stochastic, pixel_keys

    opts = _options(size, ic_samples=samples, bounces=6)
    scene = session.build_scene(desc, opts)
    ray = _rays(mi, desc, size, size)
    direct, indirect, _ = scene.integrator().trace(scene, ray, sample_pass=SamplePass(0, 0, 1, 0))
    direct = np.asarray(direct, np.float64).sum(axis=0)
    path_scene = session.build_scene(desc, dataclasses.replace(opts, integrator="path"))
    path = path_scene.integrator()
    total, total2 = np.zeros_like(direct), np.zeros_like(direct)
    pixels = size * size
    chunk = max(1, min(spp, (1 << 20) // pixels))          # passes per launch: the keys of SamplePass(0, k, spp, 7)
    rays = _rays(mi, desc, size, size)
    many = type(rays)(*(type(v)(*(dr.tile(c, chunk) for c in v)) for v in (rays.o, rays.d)))
    for start in range(0, spp, chunk):
        lane = np.arange(chunk * pixels)
        k = start + lane // pixels
        pk, pass_key = pixel_keys(mi.UInt32(lane % pixels), dr.opaque(mi.UInt32, 7), mi.UInt32(k))
        rng = Stochastic(pk, pass_key, mi.UInt32(k), dr.opaque(mi.UInt32, spp), dr.opaque(mi.UInt32, 1))
        rgb = path.trace(path_scene, many, rng=rng)[0]
        value = np.asarray(rgb, np.float64).sum(axis=0).reshape(chunk, pixels)[: spp - start]
        total += value.sum(axis=0)
        total2 += (value * value).sum(axis=0)
    mean = total / spp
    var = np.maximum(total2 / spp - mean * mean, 0.0) * spp / (spp - 1)
    return indirect.sum(axis=1), mean - direct, var


def test_load_dict_and_parameter_checks(mi: Any) -> None:
    integ = mi.load_dict({"type": "a5_irradiancecache", "error": 0.2, "samples": 64, "gradients": False})
    assert "error=0.2" in str(integ) and "samples=64 (5x13)" in str(integ)
    for bad in ({"error": 0.0}, {"error": 1.5}, {"samples": 5}, {"min_pixels": 4.0, "max_pixels": 2.0},
                {"medium": "fog"}, {"aovs": "class"}, {"gradients": 1}):
        with pytest.raises(Exception, match="a5_irradiancecache"):
            mi.load_dict({"type": "a5_irradiancecache", **bad})


def test_records_cover_every_diffuse_hit_and_spp_reuses_them(mi: Any) -> None:
    """Every diffuse node found gets a record within reach (the lookup covers all), a render is reproducible,
    and the passes of ``-spp 2`` after the first add no record."""
    desc = _load(SCENES / "ic_bleed.txt")
    opts = _options(20, ic_samples=64)
    scene = session.build_scene(desc, opts)
    first = render_scene(scene, desc.camera, opts)
    stats = dict(first.extras["irradiance_cache_stats"])
    assert stats["records"] > 10 and stats["nodes"] >= 20 * 20 * 0.9
    again = render_scene(scene, desc.camera, opts)
    assert np.array_equal(first.image, again.image)
    two = render_scene(scene, desc.camera, dataclasses.replace(opts, spp=2))
    assert two.extras["irradiance_cache_stats"]["hemisphere_rays"] == stats["hemisphere_rays"]
    assert np.allclose(two.image, first.image, atol=1e-6)        # delta lights: every pass alike


def test_mi_render_of_the_converted_scene(mi: Any) -> None:
    """``mi.render`` of the scene dict (the ``a5_camera`` sensor, one call per pass) builds its own cache; its
    image agrees with the a5 driver's in the mean (records differ: other lanes pick them)."""
    desc = _load(SCENES / "ic_bleed.txt")
    opts = _options(20, ic_samples=64)
    scene = session.build_scene(desc, opts)
    ours = render_scene(scene, desc.camera, opts).image
    theirs = np.asarray(mi.render(scene, spp=1))
    assert theirs.shape == ours.shape
    assert abs(theirs.mean() / ours.mean() - 1) < 0.03


def test_records_picture(mi: Any) -> None:
    """The picture marks each record's projection (SPEC B.2 inverted) with a dot and its reach with a ring."""
    from a5mi.plugins.integrators.irradiance_cache.grid import RecordSet
    from a5mi.render.ic_records import DOT, RING, RING_ALPHA, picture, project

    desc = _load(SCENES / "ic_bleed.txt")
    cam = desc.camera
    target = np.asarray(cam.center) + 5.0 * np.asarray(cam.direction) / np.linalg.norm(cam.direction)
    x, y, depth = project(target[None, :], cam, (41, 41))
    assert depth[0] > 0 and x[0] == pytest.approx(20.0, abs=1e-3) and y[0] == pytest.approx(20.0, abs=1e-3)
    records = RecordSet(a=0.5)
    z3 = np.zeros((1, 3, 3))
    records.add(target[None, :], np.array([[0.0, 0.0, 1.0]]), np.ones((1, 3)), np.array([1.0]), z3, z3,
                np.array([0.05]))                                     # reach 0.5 / 0.05 = 10 pixels
    out = picture(np.ones((41, 41, 3), np.float32), cam, (41, 41), records)
    ring = (1 - RING_ALPHA) * 0.5 + RING_ALPHA * RING
    assert np.array_equal(out[20, 20], DOT) and np.allclose(out[20, 30], ring) and np.allclose(out[20, 10], ring)
    assert np.array_equal(out[0, 0], [0.5, 0.5, 0.5]) and np.array_equal(out[20, 21], [0.5, 0.5, 0.5])


def test_cli_writes_the_records_picture(tmp_path: Path, capsys: Any) -> None:
    out, rec = tmp_path / "o.png", tmp_path / "r.png"
    argv = ["-input", str(SCENES / "ic_bleed.txt"), "-output", str(out), "-size", "16", "16"]
    assert cli.run([*argv, "-integrator", "irradiancecache", "-ic_samples", "32", "-ic_records", str(rec)]) == 0
    image, picture = imageio.read_image(out), imageio.read_image(rec)
    assert picture.shape == image.shape
    dots = np.all(np.isclose(picture, [1.0, 0.1, 0.1], atol=0.01), axis=2)
    assert dots.sum() > 5
    assert cli.run([*argv, "-ic_records", str(rec)]) == 2
    assert "-ic_records needs -integrator irradiancecache" in capsys.readouterr().err
    assert cli.run([*argv, "-integrator", "irradiancecache", "-ic_error", "0"]) == 2
    trace = ["trace", "-input", str(SCENES / "ic_bleed.txt"), "-pixel", "1", "1", "-integrator", "irradiancecache"]
    assert cli.run_a5mi(trace) == 2
    assert "a5mi trace follows -integrator whitted (its ray tree" in capsys.readouterr().err


def test_indirect_light_matches_path_tracing(mi: Any, scenes_dir: Path) -> None:
    """scene11 (a diffuse floor lit by the church cube map and two lamps), 24 x 24 pixel centres: the cache's
    indirect light summed over the image is within 5% of path tracing's (64 passes); σ of the path sum is
    below 1.25% (checked), so 5% is 4σ beyond the reference's noise."""
    ic, path, var = _indirect_against_path(mi, _load(scenes_dir / "scene11_cube.txt"), 24, 64, 128)
    s_ic, s_path = ic.sum(), path.sum()
    sigma = np.sqrt(var.sum() / 64)
    assert sigma < 0.0125 * s_path
    assert abs(s_ic / s_path - 1) < 0.05


@pytest.mark.slow
@pytest.mark.parametrize("name", ["scene10_sphere.txt", "scene11_cube.txt"])
def test_indirect_light_per_block_matches_path_tracing(mi: Any, scenes_dir: Path, name: str) -> None:
    """64 x 64 pixel centres, path tracing at 1024 passes, compared over 4 x 4 pixel blocks: the mean relative
    error Σ|I_ic − I_path| / Σ I_path is below 5%, with the reference's own noise (E|n| = sqrt(2/π) σ per
    block) below 1% of Σ I_path (checked)."""
    ic, path, var = _indirect_against_path(mi, _load(scenes_dir / name), 64, 1024, 256)

    def blocks(a: np.ndarray) -> np.ndarray:
        return a.reshape(16, 4, 16, 4).sum(axis=(1, 3))

    b_ic, b_path = blocks(ic), blocks(path)
    sigma = np.sqrt(blocks(var) / 1024)                 # pixels are independent: block variance = Σ var
    print(f"\n{name}: block error {np.abs(b_ic - b_path).sum() / b_path.sum():.4f}, reference noise "
          f"{np.sqrt(2 / np.pi) * sigma.sum() / b_path.sum():.4f}, "
          f"pixel error {np.abs(ic - path).sum() / path.sum():.4f}")
    assert np.sqrt(2 / np.pi) * sigma.sum() < 0.01 * b_path.sum()
    assert np.abs(b_ic - b_path).sum() / b_path.sum() < 0.05

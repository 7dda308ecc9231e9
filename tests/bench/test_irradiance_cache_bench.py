"""The point of the irradiance cache (docs/EXTENSIONS.md E.23): at equal error it costs less than ``-indirect N``
(E.15), counted in rays cast, not in seconds (times are benchmarks/indirect_vs_path.py's, quoted in BENCHMARKS.md).

The scene is ``scenes/ic_sky.txt`` (a white floor and back wall between a red and a green panel, lit by the
background colour alone), 32 x 32: lit by the background, ``-indirect N -bounces 2 -shadows`` and
``-integrator irradiancecache -bounces 1`` estimate the image of ``-integrator path -bounces 1`` (E.15, E.23).
Reference: ``a5_path -bounces 1`` at 16,384 passes per pixel centre (many passes per launch, seed 99); its own
share of the error, ``sqrt(2/π)`` times its mean standard error over the mean (0.0044), is checked below a
quarter of every error compared (the errors add about in quadrature: at most +3 % on a compared error).
Error: mean |image − reference| over pixels and channels / the reference's mean. Rays: all
rays a render casts (camera rays, reflected and gathered, refracted, shadow; the cache's hemisphere paths with
their continuation and shadow rays), as the ``counts`` AOV and the cache's statistics report them.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from helpers import ROOT

from a5mi.converters.a5_parser import parse_file
from a5mi.converters.describe import describe
from a5mi.render import session
from a5mi.render.driver import render_scene
from a5mi.render.options import RenderOptions

SCENE = ROOT / "scenes" / "ic_sky.txt"
SIZE, REFERENCE_PASSES = 32, 16384
INDIRECT = [{"integrator": "whitted", "shadows": True, "indirect": n, "bounces": 2} for n in (4, 16, 36)]
CACHE = [{"integrator": "irradiancecache", "ic_samples": m, "ic_error": a, "bounces": 1}
         for m, a in ((64, 0.5), (1024, 0.1))]


def reference(mi: Any, desc: Any, size: int, passes: int, seed: int = 99,
              bounces: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """``(mean image HxWx3 row 0 = top, its standard error)`` of ``a5_path -bounces B`` at the pixel centres,
    ``passes`` passes per pixel, as many per launch as fit in 2^20 lanes."""
    import drjit as dr

    from a5mi.crosscheck import _pixel_rays
    from a5mi.plugins.sampling import Stochastic, pixel_keys

    scene = session.build_scene(desc, RenderOptions(width=size, height=size, integrator="path", bounces=bounces))
    pixels = size * size
    chunk = max(1, min(passes, (1 << 20) // pixels))
    total, total2 = np.zeros((3, pixels)), np.zeros((3, pixels))
    ray = _pixel_rays(desc.camera, size, size, repeat=chunk)
    for start in range(0, passes, chunk):
        lane = np.arange(chunk * pixels)
        k = start + lane // pixels
        pk, pass_key = pixel_keys(mi.UInt32(lane % pixels), dr.opaque(mi.UInt32, seed), mi.UInt32(k))
        rng = Stochastic(pk, pass_key, mi.UInt32(k), dr.opaque(mi.UInt32, passes), dr.opaque(mi.UInt32, 1))
        c = scene.integrator().trace(scene, ray, rng=rng)[0]
        dr.eval(c)
        c = np.asarray(c, np.float64).reshape(3, chunk, pixels)[:, : passes - start]
        total += c.sum(axis=1)
        total2 += (c * c).sum(axis=1)
    mean = total / passes
    sem = np.sqrt(np.maximum(total2 / passes - mean * mean, 0.0) / (passes - 1))
    # lanes are pixels row-major from the bottom row
    return mean.T.reshape(size, size, 3)[::-1], sem.T.reshape(size, size, 3)[::-1]


def error_and_rays(desc: Any, ref: np.ndarray, **kw: Any) -> tuple[float, int]:
    """``(relative mean absolute error, rays cast)`` of one render (module docstring)."""
    opts = RenderOptions(width=SIZE, height=SIZE, count_rays=True, **kw)
    result = render_scene(session.build_scene(desc, opts), desc.camera, opts)
    rays = result.camera_rays + sum(result.ray_counts.values())
    rays += result.extras.get("irradiance_cache_stats", {}).get("gather_rays", 0)
    return float(np.mean(np.abs(result.image - ref)) / ref.mean()), rays


def rays_at_error(points: list[tuple[float, float]], error: float) -> float:
    """Rays a mode needs for ``error``: log-log interpolation between its ``(error, rays)`` points (extrapolated
    with the nearest two beyond them)."""
    pts = sorted(points, reverse=True)
    for (e0, r0), (e1, r1) in zip(pts, pts[1:], strict=False):
        if e1 <= error or (e1, r1) == pts[-1]:
            slope = (math.log(r1) - math.log(r0)) / (math.log(e1) - math.log(e0))
            return math.exp(math.log(r0) + slope * (math.log(error) - math.log(e0)))
    return pts[0][1]


def test_rays_at_error_interpolates_in_log_log() -> None:
    pts = [(0.1, 1000.0), (0.05, 4000.0), (0.025, 16000.0)]          # rays ∝ error^-2
    assert rays_at_error(pts, 0.0707) == pytest.approx(2000.0, rel=1e-2)
    assert rays_at_error(pts, 0.2) == pytest.approx(250.0)
    assert rays_at_error(pts, 0.0125) == pytest.approx(64000.0)


@pytest.mark.slow
def test_irradiance_cache_casts_fewer_rays_than_indirect_at_equal_error(mi: Any) -> None:
    """The point of the method: for the error the cache reaches, ``-indirect N`` casts more rays."""
    desc = describe(parse_file(str(SCENE)))
    ref, sem = reference(mi, desc, SIZE, REFERENCE_PASSES)
    indirect = [error_and_rays(desc, ref, **kw) for kw in INDIRECT]
    cache = [error_and_rays(desc, ref, **kw) for kw in CACHE]
    print("\n-indirect", indirect, "\ncache", cache)
    assert math.sqrt(2 / math.pi) * sem.mean() / ref.mean() < 0.25 * min(e for e, _ in indirect + cache)
    for err, rays in cache:
        assert rays < rays_at_error(indirect, err), (err, rays)


def test_cache_statistics_count_every_gathered_ray(mi: Any) -> None:
    """``gather_rays`` counts the hemisphere rays themselves and more (their continuations, shadow rays)."""
    desc = describe(parse_file(str(SCENE)))
    opts = RenderOptions(width=12, height=12, **CACHE[0])
    stats = render_scene(session.build_scene(desc, opts), desc.camera, opts).extras["irradiance_cache_stats"]
    assert stats["records"] > 0
    assert stats["hemisphere_rays"] < stats["gather_rays"] <= 8 * stats["hemisphere_rays"]


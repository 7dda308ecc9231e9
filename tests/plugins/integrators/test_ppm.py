"""``-integrator ppm``: the radius schedule and its passes on Dask (docs/EXTENSIONS.md E.17)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from helpers import ROOT

from a5mi.render.options import RenderOptions

SCENE = ROOT / "scenes" / "caustic_sphere.txt"


@pytest.fixture(autouse=True)
def _no_warm_scene_left():
    """Drop the scene a5mi/photons/passes.py keeps per process after each test: a live ``a5_point`` (which has
    no ``sample_wavelengths``) would be traced by the vcalls of a later stock ``ptracer`` render."""
    yield
    import gc

    from a5mi.photons import passes

    passes._WARM.clear()
    gc.collect()


def test_radius_schedule_is_the_papers_recursion(mi) -> None:
    from a5mi.plugins.integrators.photon.ppm import radius_at

    alpha, r1 = 2.0 / 3.0, 0.3
    r2 = r1 * r1
    for i in range(1, 12):
        assert math.isclose(radius_at(r1, alpha, i) ** 2, r2, rel_tol=1e-12), i
        r2 = r2 * (i + alpha) / (i + 1)       # r_(i+1)^2 = r_i^2 (i + alpha)/(i + 1)
    # Knaus and Zwicker: r_i^2 falls as i^(alpha - 1); the ratio over a factor 4 of passes tends to 4^(alpha-1)
    ratio = radius_at(r1, alpha, 4000) ** 2 / radius_at(r1, alpha, 1000) ** 2
    assert math.isclose(ratio, 4.0 ** (alpha - 1.0), rel_tol=2e-3)


def test_mean_of_passes_sums_in_pass_order_in_float32() -> None:
    from a5mi.photons.passes import mean_of_passes

    rng = np.random.default_rng(3)
    imgs = {k: rng.random((4, 4, 3), dtype=np.float32) for k in range(5)}
    want = np.zeros((4, 4, 3), np.float32)
    for k in range(5):
        want = want + imgs[k]
    shuffled = {k: imgs[k] for k in (3, 0, 4, 1, 2)}
    assert np.array_equal(mean_of_passes(shuffled), want * np.float32(0.2))


def test_passes_are_independent_and_differ(mi) -> None:
    from a5mi.photons.passes import render_pass

    opts = RenderOptions(width=12, height=12, shadows=True, integrator="ppm", photons=1500, caustic_photons=1500,
                         bounces=6)
    a0 = render_pass(str(SCENE), opts, 0)
    a1 = render_pass(str(SCENE), opts, 1)
    assert np.array_equal(render_pass(str(SCENE), opts, 0), a0)   # seeded: pass 0 again is the same image
    assert not np.array_equal(a0, a1)                               # pass 1: other photons, smaller radius
    assert np.isfinite(a0).all() and a0.mean() > 0.0


def test_passes_on_two_dask_workers_sum_to_the_one_process_image(mi) -> None:
    from distributed import LocalCluster

    from a5mi.photons.passes import render_ppm

    opts = RenderOptions(width=12, height=12, shadows=True, integrator="ppm", photons=1500, caustic_photons=1500,
                         bounces=6, seed=5)
    here, info_here = render_ppm(SCENE, opts, 4)
    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                           dashboard_address="127.0.0.1:0", silence_logs=50)  # never 8787: a second suite may hold it
    try:
        there, info = render_ppm(SCENE, opts, 4, scheduler=cluster.scheduler_address)
    finally:
        cluster.close()
    assert len(info["seconds"]) == 4 and info_here["pids"] != info["pids"]
    assert np.array_equal(here, there)
    other, _ = render_ppm(SCENE, dataclasses.replace(opts, seed=6), 1)
    assert not np.array_equal(here, other)


def test_ppm_refuses_other_integrators() -> None:
    from a5mi.photons.passes import render_ppm

    with pytest.raises(ValueError):
        render_ppm(SCENE, RenderOptions(), 2)

"""Photon mapping speed and time to a given error (BENCHMARKS.md; docs/EXTENSIONS.md E.16).

    A5_DATA=... .venv/bin/python benchmarks/photon.py [--json OUT.json]

On scenes/caustic_sphere.txt (64 x 64, ``-fresnel exact``, the stock point light of the stock conversion):

* photons/s: ``a5_photon.photon_set`` for the global and the caustic map (emission, tracing, storing), warm;
* kNN queries/s: ``PhotonMap.knn`` (query + front-side filter + filter weights + the sum) against
  ``cKDTree.query`` alone on the same points and k;
* ppm: the floor's relative RMSE of the running mean of 1 .. 32 passes and its log-log slope;
* time to error: photon mapping with more caustic photons and ptracer with more spp, each timed and scored by
  the relative error of the caustic-region mean and the floor's mean relative error ``Σ|p − r| / Σ r`` against
  a ptracer reference of 8 x 1024 spp.

``--scene10 OUT.png [--size N] [--passes P]``: instead, the course's scene10 (``$A5_DATA/scenes``, read in place)
from :data:`a5mi.photons.versus.SCENE10_VIEW` (its own camera hides the caustic behind the ball), ``-integrator
ppm`` (P passes of 20 k global + 50 k caustic photons) against ptracer (4 x 1024 spp) on the same scene
(:mod:`a5mi.photons.versus`): the figure photon | ptracer | difference (red: photon brighter, blue: darker,
full scale at 25 % of the brightest reference pixel) and the figures as JSON (``--json``).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--json")
    ap.add_argument("--scene10")
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--passes", type=int, default=16)
    args = ap.parse_args()
    if args.scene10:
        scene10(args.scene10, args.size, args.passes, args.json)
        return
    from a5mi.runtime.variant import activate

    activate()
    import mitsuba as mi
    from scipy.spatial import cKDTree
    from test_photon_caustic import SIZE, _caustic_region, _dicts, _ptracer

    from a5mi.plugins.integrators.photon.maps import PhotonMap
    from a5mi.plugins.integrators.photon.trace import CAUSTIC, DIRECT, INDIRECT
    from a5mi.render.options import RenderOptions

    out: dict = {"load_average": os.getloadavg()}
    base = RenderOptions(width=SIZE, height=SIZE, shadows=True, fresnel="exact", integrator="photon",
                         photons=20000, caustic_photons=100000, photon_k=50, bounces=8)
    desc, a5, stock = _dicts(mi, base)
    shadow, floor = _caustic_region(desc, SIZE)
    scene = mi.load_dict(a5)
    integ = scene.integrator()
    integ.photon_set(scene, 20000, 0, 0, (DIRECT, CAUSTIC, INDIRECT))          # warm-up: compile
    integ.photon_set(scene, 20000, 0, 1, (CAUSTIC,))
    for name, keep, n in (("global", (DIRECT, CAUSTIC, INDIRECT), 200000), ("caustic", (CAUSTIC,), 200000)):
        t0 = time.perf_counter()
        ps = integ.photon_set(scene, n, 1, 2, keep)
        dt = time.perf_counter() - t0
        out[f"{name}_photons_per_s"] = n / dt
        out[f"{name}_stored"] = len(ps.pos)
    ps = integ.photon_set(scene, 200000, 1, 3, (DIRECT, CAUSTIC, INDIRECT))
    pm = PhotonMap(ps.pos, ps.dir, ps.power)
    rng = np.random.default_rng(0)
    q = ps.pos[rng.choice(len(ps.pos), 100000)] + rng.normal(0, 0.01, (100000, 3))
    n_up = np.tile([0.0, 1.0, 0.0], (len(q), 1))
    kd = np.full((len(q), 3), 0.8)
    tree = cKDTree(ps.pos)
    t0 = time.perf_counter()
    tree.query(q, k=50)
    out["ckdtree_query_per_s"] = len(q) / (time.perf_counter() - t0)
    t0 = time.perf_counter()
    pm.knn(q, n_up, kd, 50, "cone")
    out["knn_estimate_per_s"] = len(q) / (time.perf_counter() - t0)

    ref_imgs = _ptracer(mi, stock, 1024, 8)
    ref = np.mean(ref_imgs, axis=0)

    def score(img: np.ndarray) -> tuple[float, float]:
        return (abs(img[shadow].mean() / ref[shadow].mean() - 1.0),
                float(np.abs(img[floor] - ref[floor]).sum() / ref[floor].sum()))

    rows = []
    for n in (25000, 100000, 400000):
        d = dict(a5, integrator=dict(a5["integrator"], caustic_photons=n, photons=n // 4, seed=11))
        t0 = time.perf_counter()
        img = np.asarray(mi.render(mi.load_dict(d)))[..., 0]
        rows.append({"method": "a5_photon", "caustic_photons": n, "seconds": time.perf_counter() - t0,
                     "caustic_err": score(img)[0], "floor_err": score(img)[1]})
    for spp in (64, 256, 1024):
        t0 = time.perf_counter()
        img = _ptracer(mi, stock, spp, 1)[0]
        rows.append({"method": "ptracer", "spp": spp, "seconds": time.perf_counter() - t0,
                     "caustic_err": score(img)[0], "floor_err": score(img)[1]})
    out["time_to_error"] = rows

    # progressive photon mapping: error of the running mean of N passes (RMSE over the floor, relative to the
    # reference's mean there) and its log-log slope against N
    ppm = dict(a5, integrator=dict(a5["integrator"], type="a5_ppm", seed=3, photons=10000, caustic_photons=25000))
    for key in ("k", "final_gather"):
        ppm["integrator"].pop(key, None)
    running, errs, t0 = None, [], time.perf_counter()
    counts = (1, 2, 4, 8, 16, 32)
    for k in range(counts[-1]):
        scene_k = mi.load_dict(dict(ppm, integrator=dict(ppm["integrator"], first_pass=k, passes=1)))
        img = np.asarray(mi.render(scene_k))[..., 0].astype(np.float64)
        running = img if running is None else running + img
        if k + 1 in counts:
            mean = running / (k + 1)
            errs.append(float(np.sqrt(np.mean((mean[floor] - ref[floor]) ** 2)) / ref[floor].mean()))
    slope = float(np.polyfit(np.log(counts), np.log(errs), 1)[0])
    out["ppm"] = {"passes": counts, "rel_rmse": errs, "slope": slope, "seconds": time.perf_counter() - t0}
    out["load_average_end"] = os.getloadavg()
    text = json.dumps(out, indent=1, default=float)
    print(text)
    if args.json:
        Path(args.json).write_text(text + "\n")


def scene10(out_png: str, size: int, passes: int, json_out: str | None) -> None:
    """The scene10 figure and figures (module docstring)."""
    from a5mi.photons import versus
    from a5mi.platform import imageio
    from a5mi.render.options import RenderOptions
    from a5mi.render.session import describe_file
    from a5mi.runtime.variant import activate

    activate()
    import mitsuba as mi

    desc, _ = describe_file(os.path.join(os.environ.get("A5_DATA", "../shared/a5"), "scenes", "scene10_sphere.txt"))
    centre, target, angle = versus.SCENE10_VIEW
    desc = versus.with_camera(desc, centre, target, angle=angle)
    opts = RenderOptions(width=size, height=size, shadows=True, integrator="ppm", photons=20000,
                         caustic_photons=50000, seed=1)
    load = os.getloadavg()
    r = versus.render_versus(mi, desc, opts, passes, 4, 1024, 4)
    p, ref = r["photon"], r["ptracer"]
    diff = (p - ref).mean(axis=-1) / (0.25 * ref.mean(axis=-1).max())
    dimg = np.stack([np.clip(diff, 0, 1), np.zeros_like(diff), np.clip(-diff, 0, 1)], axis=-1)
    gap = np.ones((size, 2, 3))
    tone = [np.clip(x * 2.0, 0.0, 1.0) ** (1.0 / 2.2) for x in (p, ref)]
    imageio.write_images([(out_png, np.concatenate([tone[0], gap, tone[1], gap, dimg], axis=1).astype(np.float32))])
    fig = {"size": size, "passes": passes, "photons_per_pass": [20000, 50000], "ptracer_spp": [4, 1024],
           "region_pixels": int(r["region"].sum()), **r["metrics"], "photon_seconds": r["photon_seconds"],
           "ptracer_seconds": r["ptracer_seconds"], "load_average": [load, os.getloadavg()],
           "region_mean": [float(p.mean(-1)[r["region"]].mean()), float(ref.mean(-1)[r["region"]].mean())],
           "image_mean": [float(p.mean()), float(ref.mean())]}
    text = json.dumps(fig, indent=1, default=float)
    print(text)
    if json_out:
        Path(json_out).write_text(text + "\n")


if __name__ == "__main__":
    main()

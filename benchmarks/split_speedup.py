"""Speed-up of a split render (docs/EXTENSIONS.md E.24, a5mi/render/bands.py) on a local 2-worker Dask cluster against
one process, the same render, one run on whatever else the machine does (the load average is printed).

* one process: :func:`a5mi.render.session.render` after a warm-up render (scene loaded, kernels cached): the
  in-process cost of the samples;
* split, cold: :func:`a5mi.render.bands.render_split` with ``workers=2`` as ``a5 -workers 2`` runs it (cluster start,
  each worker's scene load and kernel cache, the bands);
* split, warm: a second render on the same client (workers keep their scene): the bands alone.

Every image is checked bit for bit against the one-process image. Dr.Jit already runs one process on every
core, so on one machine the split can only add overhead; the figure for N machines is the model
``T_N ≈ t_cluster + t_load + T_1 / N`` with the measured terms.

    .venv/bin/python benchmarks/split_speedup.py [SCENE.txt] [W] [SPP]
"""

from __future__ import annotations

import os
import sys
import time

import numpy as np


def main() -> None:
    scene = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), "..", "scenes",
                                                                 "colour_bleeding.txt")
    width = int(sys.argv[2]) if len(sys.argv) > 2 else 96
    spp = int(sys.argv[3]) if len(sys.argv) > 3 else 256
    from a5mi.render.bands import render_split
    from a5mi.render.options import RenderOptions
    from a5mi.render.session import describe_file, render
    from a5mi.runtime import cluster
    from a5mi.runtime.variant import activate

    activate()
    options = RenderOptions(width=width, height=width, integrator="path", bounces=4, spp=spp, seed=1)
    desc, _ = describe_file(scene)
    render(desc, options)                                                   # warm-up
    t0 = time.perf_counter()
    one = render(desc, options).image
    t_one = time.perf_counter() - t0
    t0 = time.perf_counter()
    with cluster.start_client(2) as client:
        t_cluster = time.perf_counter() - t0
        cold, info_cold = render_split(scene, options, client=client)
        t_cold = time.perf_counter() - t0
        t1 = time.perf_counter()
        warm, info_warm = render_split(scene, options, client=client)
        t_warm = time.perf_counter() - t1
    load = os.getloadavg()[0]
    assert np.array_equal(cold.image, one) and np.array_equal(warm.image, one)
    n = width * width * spp
    print(f"{os.path.basename(scene)} -integrator path -bounces 4, {width}x{width}, {spp} spp ({n:,} samples), "
          f"{os.cpu_count()} CPUs, load average (1 min) {load:.1f}; images bit-identical\n")
    print("| render | wall s | samples/s | vs one process |")
    print("|---|---|---|---|")
    for name, t in (("one process (warm)", t_one), ("2 workers, cold (cluster start + load + bands)", t_cold),
                    ("2 workers, warm (bands only)", t_warm)):
        print(f"| {name} | {t:.2f} | {n / t:,.0f} | {t_one / t:.2f}x |")
    load_s = max(info_cold["seconds"]) - min(info_warm["seconds"])
    print(f"\ncluster start {t_cluster:.2f} s; bands {len(info_cold['bands'])}; slowest cold band "
          f"{max(info_cold['seconds']):.2f} s, fastest warm band {min(info_warm['seconds']):.2f} s "
          f"(scene load + compile ~{load_s:.2f} s)")


if __name__ == "__main__":
    main()

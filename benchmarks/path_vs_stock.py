"""Samples per second of ``-integrator path`` (a5_path, docs/EXTENSIONS.md E.14) against Mitsuba's stock ``path``
on the ``--stock`` conversion of the same scene (tests/plugins/integrators/test_path_stock.py's scene, where the
conversion is the E.13 reading), one run, on whatever else the machine is doing (the load average is printed).

Both render W x H pixel centres (SPEC B.2) with ``spp`` samples each, ``-bounces 4`` (stock ``max_depth`` 6),
Russian roulette from 5, after one warm-up render each (kernels compiled and cached), then REPEATS renders of
each, alternating, the medians compared: a5mi through :func:`a5mi.render.driver.render_scene` (the E.5 wavefront: up
to 2^20 samples of many ``-spp`` passes per launch, as ``a5`` renders), stock through
:func:`a5mi.crosscheck.render_path` (up to 2^20 samples per launch). Prints a markdown table.

    .venv/bin/python benchmarks/path_vs_stock.py [W] [SPP] [REPEATS]
"""

from __future__ import annotations

import os
import statistics
import sys
import time


def main() -> None:
    width = int(sys.argv[1]) if len(sys.argv) > 1 else 128
    spp = int(sys.argv[2]) if len(sys.argv) > 2 else 64
    repeats = int(sys.argv[3]) if len(sys.argv) > 3 else 3
    sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "tests"))
    from a5mi.runtime.variant import activate

    activate()
    import mitsuba as mi
    from path_helpers import load
    from test_path_stock import SCENE

    from a5mi.crosscheck import render_path
    from a5mi.render.driver import render_scene

    desc, scene, ro = load(mi, SCENE, integrator="path", bounces=4, fresnel="exact", width=width, height=width,
                           spp=spp)
    sdesc, sscene, _ = load(mi, SCENE, stock=True, bounces=4)
    rows = []
    render_scene(scene, desc.camera, ro)                                   # warm-up: compile
    render_path(sscene, sdesc.camera, width, width, spp, 6, seed=1)        # warm-up
    times_a5, times_stock = [], []
    for r in range(repeats):                                               # paired: a5, stock, a5, stock ...
        t0 = time.perf_counter()
        render_scene(scene, desc.camera, ro)
        times_a5.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        render_path(sscene, sdesc.camera, width, width, spp, 6, seed=2 + r)
        times_stock.append(time.perf_counter() - t0)
    t_a5, t_stock = statistics.median(times_a5), statistics.median(times_stock)
    load_a5 = load_stock = os.getloadavg()[0]
    n = width * width * spp
    rows.append(("a5_path (`-integrator path`)", t_a5, n / t_a5, load_a5))
    rows.append(("stock `path` (`--stock`)", t_stock, n / t_stock, load_stock))
    print(f"{width}x{width}, {spp} spp, median of {repeats} paired renders, -bounces 4 (stock max_depth 6), "
          f"rr_depth 5, {os.cpu_count()} CPUs\n")
    print("| integrator | seconds | samples/s | load average (1 min) |")
    print("|---|---|---|---|")
    for name, t, rate, la in rows:
        print(f"| {name} | {t:.2f} | {rate:,.0f} | {la:.1f} |")
    print(f"\nratio a5_path / stock path: {t_stock / t_a5:.2f} (samples/s)")


if __name__ == "__main__":
    main()

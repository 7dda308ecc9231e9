"""Error against time of ``-indirect N`` (E.15) and ``-integrator path`` (E.14) on a scene where both estimate the
same image: tests/test_indirect.py's diffuse spheres on a plane lit by the background alone (``-indirect N
-bounces B`` = ``path -bounces B-1``). One run; prints a markdown table and the load average.

RMSE of a render at ``spp`` = the standard deviation over 8 independent renders of it (both estimators are
unbiased for the same image, so no reference is needed), averaged over pixels and channels; time = wall of one
render of W x W pixels through :func:`a5mi.driver.render_scene` after a warm-up (kernels cached).

    .venv/bin/python benchmarks/indirect_vs_path.py [W]
"""

from __future__ import annotations

import math
import os
import sys
import time


def main() -> None:
    width = int(sys.argv[1]) if len(sys.argv) > 1 else 32
    sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "tests"))
    from a5mi.variant import activate

    activate()
    import mitsuba as mi
    import numpy as np
    from path_helpers import a5_passes, load
    from test_indirect import SCENE

    from a5mi.driver import render_scene

    modes = {"-indirect 2 -bounces 3": {"bounces": 3, "indirect": 2},
             "-indirect 4 -bounces 3": {"bounces": 3, "indirect": 4},
             "-integrator path -bounces 2": {"bounces": 2, "integrator": "path"}}
    print(f"{width}x{width}, load average {os.getloadavg()[0]:.1f}\n")
    print("| mode | spp | seconds | RMSE | RMSE² x seconds |")
    print("|---|---:|---:|---:|---:|")
    for name, opts in modes.items():
        for spp in (1, 4, 16):
            desc, scene, ro = load(mi, SCENE, width=width, height=width, spp=spp, **opts)
            render_scene(scene, desc.camera, ro)
            t0 = time.perf_counter()
            render_scene(scene, desc.camera, ro)
            seconds = time.perf_counter() - t0
            means, _ = a5_passes(mi, scene, scene.integrator(), desc.camera, width, width, spp, seed=11 + spp,
                                 replicas=8)
            rmse = math.sqrt(float(np.mean(np.var(means, axis=0, ddof=1))))
            print(f"| `{name}` | {spp} | {seconds:.2f} | {rmse:.4f} | {rmse * rmse * seconds:.2e} |", flush=True)
    print(f"\nload average at the end {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()

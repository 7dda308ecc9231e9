"""Error against time, and against rays cast, of the three indirect-light modes (docs/EXTENSIONS.md E.14, E.15,
E.23), one process, one run: ``-integrator path -spp S``, ``-indirect N`` (a5_whitted) and ``-integrator
irradiancecache``, on ``scenes/ic_sky.txt`` (a white floor and back wall between a red and a green panel, lit by
the background alone, so Whitted's ``kd`` direct term plays no part: ``path -bounces 1``, ``-indirect N -bounces
2 -shadows`` and ``irradiancecache -bounces 1`` estimate the same image, E.15 / E.23).

Reference: ``a5_path -bounces 1`` at ``REF`` passes per pixel centre, traced many passes per launch
(``A5PathIntegrator.trace(..., rng=)``, tests/bench/test_irradiance_cache_bench.py's ``reference``), seed 99 (no
render below uses it). Error: mean |image − reference| over pixels and channels / the reference's mean; the
reference's own share of it is printed (its standard error).
Time: the render's wall time through :func:`a5mi.render.driver.render_scene` after a first render of the same options
(kernels compiled). Rays: every ray the render cast (camera, reflected / gathered, refracted, shadow; for the
cache its camera trees plus every ray of its hemisphere paths; for ``-spp S`` pass 0's count times ``S``, the
driver reports the AOVs of pass 0). ``-indirect N`` with ``N`` a square: E.5 stratifies a ``q x q`` grid,
``q = floor(sqrt N)``, and draws the other ``N − q²`` uniformly, so ``N = 8`` or ``32`` is noisier than ``4`` or
``16``.

    .venv/bin/python benchmarks/indirect_vs_path.py [W [REF]]
"""

from __future__ import annotations

import dataclasses
import os
import sys
import time
from pathlib import Path

SCENE = Path(__file__).resolve().parent.parent / "scenes" / "ic_sky.txt"
ROWS = [*((f"path -spp {s}", {"integrator": "path", "spp": s, "bounces": 1}) for s in (4, 16, 64, 256)),
        *((f"-indirect {n}", {"integrator": "whitted", "shadows": True, "indirect": n, "bounces": 2})
          for n in (4, 9, 16, 36, 64)),
        *((f"irradiancecache -ic_samples {m} -ic_error {a}", {"integrator": "irradiancecache", "ic_samples": m,
                                                               "ic_error": a, "bounces": 1})
          for m, a in ((64, 0.5), (256, 0.3), (1024, 0.2), (1024, 0.1), (4096, 0.1)))]


def main() -> None:
    width = int(sys.argv[1]) if len(sys.argv) > 1 else 32
    passes = int(sys.argv[2]) if len(sys.argv) > 2 else 8192
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
    from a5mi.runtime.variant import activate

    activate()
    import mitsuba as mi
    import numpy as np
    from test_irradiance_cache_bench import reference

    from a5mi.converters.a5_parser import parse_file
    from a5mi.converters.describe import describe
    from a5mi.render import session
    from a5mi.render.driver import render_scene
    from a5mi.render.options import RenderOptions

    print(f"{width}x{width}, reference {passes} passes, load average {os.getloadavg()[0]:.1f}\n")
    desc = describe(parse_file(str(SCENE)))
    t0 = time.perf_counter()
    ref, sem = reference(mi, desc, width, passes)
    print(f"reference {time.perf_counter() - t0:.1f} s; its own error sqrt(2/pi) mean(sem) / mean = "
          f"{np.sqrt(2 / np.pi) * sem.mean() / ref.mean():.4f}\n")
    print("| mode | seconds | rays cast | relative mean abs. error |")
    print("|---|---:|---:|---:|")
    base = RenderOptions(width=width, height=width, count_rays=True)
    for label, kw in ROWS:
        opts = dataclasses.replace(base, **kw)
        scene = session.build_scene(desc, opts)
        render_scene(scene, desc.camera, opts)
        result = render_scene(scene, desc.camera, opts)
        rays = (result.camera_rays + sum(result.ray_counts.values())) * opts.spp    # counts are pass 0's
        rays += result.extras.get("irradiance_cache_stats", {}).get("gather_rays", 0)
        err = float(np.mean(np.abs(result.image - ref)) / ref.mean())
        print(f"| `{label}` | {result.timings['render']:.2f} | {rays} | {err:.4f} |", flush=True)
    print(f"\nload average at the end {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()

"""Benchmark of ``-crop`` (BENCHMARKS.md "Crop renders", docs/USAGE.md "Crop renders"): a region against the whole
image, in rays and CPU seconds.

One scene at ``--size`` with the a5 flags ``--flags`` (the handout's by default), the whole image and each
``--regions`` ``X0:X1:Y0:Y1``. In one process (a :class:`a5mi.render.session.RenderSession`, the scene built once,
every kernel compiled by a first render that is not counted): per case the camera rays and secondary rays
(the ``counts`` AOV, one more render), and the CPU seconds (``time.process_time``, all threads) of ``--repeat``
renders, median; the region's share of the whole image's samples, rays and CPU. Then whole ``a5`` processes
(what a user waits for: start, parse, build, compile or cache, render, write), the whole image and the first
region alternated ``--repeat`` times, CPU seconds of each child (``RUSAGE_CHILDREN``), median. Printed as
JSON with the load average before and after.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import resource
import shlex
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DATA = Path(os.environ.get("A5_DATA", ROOT.parent / "shared" / "a5"))


def child_cpu(argv: list[str]) -> float:
    """CPU seconds (user + system) of one child process running ``argv``."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run(argv, check=True, capture_output=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default=str(DATA / "scenes" / "scene10_sphere.txt"))
    ap.add_argument("--size", type=int, default=300)
    ap.add_argument("--flags", default="-shadows -bounces 4 -jitter -filter")
    ap.add_argument("--regions", nargs="+", default=["120:180:100:150", "0:150:0:150"])
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args()

    from a5mi.cli import parse_a5_args
    from a5mi.commands.render import render_options
    from a5mi.render import crop
    from a5mi.render.session import RenderSession, describe_file

    load_before = os.getloadavg()
    size = [str(a.size), str(a.size)]
    options = render_options(parse_a5_args(["-input", a.scene, "-output", "x.png", "-size", *size,
                                            *shlex.split(a.flags)]))
    regions = [tuple(int(v) for v in r.split(":")) for r in a.regions]
    session = RenderSession()
    desc = describe_file(a.scene)[0]
    cases = [("whole", options)] + [(f"-crop {' '.join(map(str, r))}", dataclasses.replace(options, crop=r))
                                    for r in regions]
    rows = []
    for name, o in cases:
        session.render(desc, o)                                   # compile (or find) every kernel first
        counted = session.render(desc, dataclasses.replace(o, count_rays=True))
        cpu = []
        for _ in range(a.repeat):
            t0 = time.process_time()
            session.render(desc, o)
            cpu.append(time.process_time() - t0)
        rows.append({"case": name, "saved": list(counted.image.shape[:2][::-1]),
                     "camera_rays": counted.camera_rays, "secondary_rays": sum(counted.ray_counts.values()),
                     "cpu_s": round(statistics.median(cpu), 4), "cpu_runs": [round(c, 4) for c in cpu],
                     "traced_samples": crop.traced_samples(o)})
    whole = rows[0]
    for r in rows:
        for key in ("camera_rays", "secondary_rays", "cpu_s"):
            r[f"{key}_share"] = round(r[key] / whole[key], 4)

    with tempfile.TemporaryDirectory() as tmp:
        base = [sys.executable, "-m", "a5mi", "-input", a.scene, "-size", *size, *shlex.split(a.flags)]
        first = [str(v) for v in regions[0]]
        process: dict[str, list[float]] = {"whole": [], "crop": []}
        for _ in range(a.repeat):
            process["whole"].append(child_cpu([*base, "-output", str(Path(tmp) / "w.png")]))
            process["crop"].append(child_cpu([*base, "-crop", *first, "-output", str(Path(tmp) / "c.png")]))
    print(json.dumps({
        "scene": a.scene, "size": a.size, "flags": a.flags, "commit": subprocess.run(
            ["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip(),
        "load_before": [round(x, 2) for x in load_before], "load_after": [round(x, 2) for x in os.getloadavg()],
        "in_process": rows,
        "a5_process_cpu_s": {k: {"median": round(statistics.median(v), 3), "runs": [round(x, 3) for x in v]}
                             for k, v in process.items()},
        "a5_process_region": "-crop " + " ".join(first),
    }, indent=1))


if __name__ == "__main__":
    main()

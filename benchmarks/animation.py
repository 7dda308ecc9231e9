"""Benchmark of ``a5mi animate`` (BENCHMARKS.md "Animation"): the demo's frames with N local Dask workers.

For each ``--workers`` count the frames ``--frames A:B`` of ``scenes/animation.txt`` are rendered from scratch
(a fresh folder) at ``--size`` with the a5 flags ``--flags``; printed as JSON: wall time of the whole run
(cluster start, scene load and kernel compilation included), per worker process its frames, build, update,
render and kernel-execution seconds (from the chunk records of :func:`a5mi.animate.batch.render_animation`),
kernels by source and peak RSS; and time per warm frame ``(update + render) / frames`` against one frame's
kernel time ``kernel / frames``.
"""

from __future__ import annotations

import argparse
import json
import shlex
import tempfile
from collections import defaultdict
from pathlib import Path

from a5mi.animate import batch
from a5mi.cli import parse_a5_args
from a5mi.commands.render import render_options

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default=str(ROOT / "scenes" / "animation.txt"))
    ap.add_argument("--frames", default="0:240")
    ap.add_argument("--size", type=int, default=300)
    ap.add_argument("--flags", default="-shadows", help="further a5 flags, e.g. '-shadows -spp 4'")
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--keep", help="write the frames of the last run into this folder (kept)")
    a = ap.parse_args()
    first, last = (int(x) for x in a.frames.split(":"))
    options = render_options(parse_a5_args(["-input", a.scene, "-output", "x.png", "-size", str(a.size),
                                            str(a.size), *shlex.split(a.flags)]))
    results = []
    for i, n in enumerate(a.workers):
        with tempfile.TemporaryDirectory() as tmp:
            folder = a.keep if a.keep and i == len(a.workers) - 1 else tmp
            out = batch.render_animation(a.scene, folder, options, range(first, last), workers=n)
        per: dict[int, dict[str, float]] = defaultdict(lambda: defaultdict(float))
        kernels: dict[str, int] = defaultdict(int)
        for r in out.records:
            w = per[r["pid"]]
            for k in ("build_s", "update_s", "render_s", "kernel_s"):
                w[k] += r[k]
            w["frames"] += len(r["frames"])
            w["peak_mb"] = max(w["peak_mb"], r["peak_mb"])
            for k, v in r["kernels"].items():
                kernels[k] += v
        frames = sum(w["frames"] for w in per.values())
        warm = sum(w["update_s"] + w["render_s"] for w in per.values())
        kernel = sum(w["kernel_s"] for w in per.values())
        results.append({"workers": n, "frames": frames, "wall_s": round(out.wall_s, 2),
                        "frames_per_s": round(frames / out.wall_s, 3),
                        "warm_frame_s": round(warm / frames, 4), "kernel_frame_s": round(kernel / frames, 4),
                        "ratio": round(warm / kernel, 3), "kernels": dict(kernels),
                        "per_worker": {str(pid): {k: round(v, 2) for k, v in w.items()} for pid, w in per.items()}})
        print(json.dumps(results[-1]), flush=True)


if __name__ == "__main__":
    main()

"""Benchmark of ``a5mi diagnose`` (BENCHMARKS.md "Diagnosis"): one 300x300 image diagnosed, cold and warm.

The image is a5mi's own render of ``--scene`` with ``--mistake`` and jitter seed 7 (the diagnosis replays glibc's
seed 1). Runs the diagnosis ``--repeat`` times in one process (the first compiles its kernels unless Dr.Jit's disk
cache has them; later ones reuse the session's scenes and the in-memory kernels) and prints per run, as JSON: the
verdict and first cause, wall seconds, CPU seconds of the process (all threads: ``resource.getrusage``), the renders
(small and full size) and the seconds per stage. Target: <= 15 s on 2 cores (docs/MISTAKES.md "Speed"); on a
shared machine the CPU seconds are the figure to compare.
"""

from __future__ import annotations

import argparse
import json
import resource
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default=str(ROOT.parent / "shared" / "a5" / "scenes" / "scene10_sphere.txt"))
    ap.add_argument("--size", type=int, default=300)
    ap.add_argument("--mistake", default="mirror_sign")
    ap.add_argument("--repeat", type=int, default=2)
    a = ap.parse_args()
    from a5mi.diagnose.rank import diagnose
    from a5mi.platform.imageio import quantize
    from a5mi.render.options import RenderOptions
    from a5mi.render.session import RenderSession, describe_file
    from a5mi.runtime.variant import activate

    activate()
    desc = describe_file(a.scene)[0]
    options = RenderOptions(width=a.size, height=a.size, shadows=True, jitter=True, filter=True)
    session = RenderSession()
    image = quantize(session.render(desc, RenderOptions(**{**options.__dict__, "seed": 7,
                                                          "mistakes": tuple(a.mistake.split(","))})).image)
    runs = []
    for k in range(a.repeat):
        c0, t0 = _cpu(), time.perf_counter()
        d = diagnose(image, desc, options, session=session)
        runs.append({"run": k, "verdict": d.verdict, "cause": list(d.causes[0].mistakes) if d.causes else None,
                     "explained": d.causes[0].explained if d.causes else None,
                     "wall_s": round(time.perf_counter() - t0, 2), "cpu_s": round(_cpu() - c0, 2),
                     "renders": d.renders, "stages_s": {s: round(v, 2) for s, v in d.seconds.items()}})
    print(json.dumps({"scene": a.scene, "size": a.size, "mistake": a.mistake, "runs": runs}, indent=1))


if __name__ == "__main__":
    main()

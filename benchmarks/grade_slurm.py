"""Benchmark of ``a5mi grade --slurm`` against the LocalCluster on the same machine (BENCHMARKS.md "Grading on
SLURM").

The class of ``benchmarks/grade_class.py`` (N students, wrappers around ``.venv/bin/a5`` with one seeded defect
or none) on the handout's four cases at SIZE x SIZE, graded by :func:`a5mi.grade.batch.grade_class`

* on a ``LocalCluster`` of 2 worker processes (127.0.0.1, per-run TLS);
* on 2 SLURM jobs of one CPU each (``a5mi grade --slurm --workers 2``: dask-jobqueue, per-run TLS) on the
  single-node SLURM of the tests (``tests/runtime/slurm_daemons.py``: munged, slurmctld and slurmd started
  here as root, two CPUs), alternately, ROUNDS times each.

Printed per run: the time to the first and to every worker (cluster start; for SLURM: sbatch, scheduling and
the job's Python start-up), the grading wall time (``grade_class`` with the client given), and the load average.
References are rendered and cached first; both graders must give the same verdicts.

    .venv/bin/python benchmarks/grade_slurm.py [STUDENTS] [SIZE] [ROUNDS]   (default 6 students, 50 x 50, 2)
"""

from __future__ import annotations

import os
import statistics
import sys
import time
from pathlib import Path

from grade_class import bench_class

from a5mi import PROJECT_ROOT
from a5mi.grade.batch import GradeSettings, grade_class
from a5mi.grade.references import build_reference
from a5mi.runtime.cluster import start_client
from a5mi.runtime.slurm import SlurmOptions, start_slurm_client
from a5mi.sandbox.records import Limits

sys.path.insert(0, str(PROJECT_ROOT / "tests" / "runtime"))
from slurm_daemons import LocalSlurm, slurm_problem  # noqa: E402


def _timed(settings: GradeSettings, start) -> tuple[float, float, float, dict[str, str]]:  # noqa: ANN001
    t0 = time.perf_counter()
    with start() as client:
        client.wait_for_workers(1)
        first = time.perf_counter() - t0
        client.wait_for_workers(2)
        every = time.perf_counter() - t0
        t1 = time.perf_counter()
        out = grade_class(settings, client=client)
        wall = time.perf_counter() - t1
    return first, every, wall, {r["key"]: r["verdict"] for r in out.records}


def main(argv: list[str]) -> int:
    n = int(argv[0]) if argv else 6
    size = int(argv[1]) if len(argv) > 1 else 50
    rounds = int(argv[2]) if len(argv) > 2 else 2
    why = slurm_problem()
    if why:
        print(f"grade_slurm: cannot start the local SLURM: {why}", file=sys.stderr)
        return 2
    with bench_class("a5mi-slurmbench-", n, size) as (base, scenes, subs, cases, cache, allow):
        for c in cases:
            build_reference(Path(scenes) / c.scene, c.options, cache)
        rows: dict[str, list[tuple[float, float, float, float]]] = {"LocalCluster, 2 workers": [],
                                                                      "SLURM, 2 jobs (--slurm)": []}
        verdicts = []
        with LocalSlurm(base / "slurm-daemons"):
            for k in range(rounds):
                for name in rows:
                    report = base / f"report-{k}-{len(verdicts)}"
                    settings = GradeSettings(str(subs), str(report), cases, scenes, str(cache), workers=2,
                                             limits=Limits(timeout=120), read_only=allow, flip=False)
                    if name.startswith("SLURM"):
                        opts = SlurmOptions(jobs=2, memory="1GB")
                        start = lambda r=report, o=opts: start_slurm_client(o, r / "slurm")  # noqa: E731
                    else:
                        start = lambda: start_client(2)  # noqa: E731
                    load = os.getloadavg()[0]
                    first, every, wall, v = _timed(settings, start)
                    verdicts.append(v)
                    rows[name].append((first, every, wall, load))
                    print(f"{name}: workers {first:.1f} / {every:.1f} s, grading {wall:.1f} s (load {load:.1f})",
                          file=sys.stderr, flush=True)
        assert all(v == verdicts[0] for v in verdicts), "the graders' verdicts differ"
        cases_n = len(verdicts[0])
        print(f"{n} students x {len(cases)} cases = {cases_n} cases at {size}x{size} (no FLIP), "
              f"{sum(x == 'match' for x in verdicts[0].values())} match; {os.cpu_count()} CPUs; {rounds} rounds, "
              f"alternating\n")
        print("| grader | first worker | both workers | grading wall (median) | cases/s | runs | load (1 min) |")
        print("| --- | --- | --- | --- | --- | --- | --- |")
        for name, runs in rows.items():
            med = statistics.median(r[2] for r in runs)
            print(f"| {name} | {statistics.median(r[0] for r in runs):.1f} s | "
                  f"{statistics.median(r[1] for r in runs):.1f} s | {med:.1f} s | {cases_n / med:.2f} | "
                  f"{', '.join(f'{r[2]:.1f}' for r in runs)} s | {', '.join(f'{r[3]:.1f}' for r in runs)} |")
        return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

"""Benchmark of ``a5mi grade`` (the table of BENCHMARKS.md "Grading a class").

A generated class of N students x the handout's four cases (at SIZE x SIZE), each student a small wrapper
around ``.venv/bin/a5`` with one seeded defect or none, graded

* in a plain loop in one process (the same sandboxed runs and verdicts, no Dask): the baseline;
* on a ``LocalCluster`` of 1 and of 2 worker processes (127.0.0.1).

Printed: wall time, cases per second, scheduling overhead per case (cluster wall x workers - plain wall,
over the cases), peak RSS of each worker process and of the largest sandboxed run. References are rendered
(and cached) before any timing.

    .venv/bin/python benchmarks/grade_class.py [STUDENTS] [SIZE] [KEEP_DIR]   (default 40 students, 50 x 50)

KEEP_DIR: copy the 2-worker report there (the README's screenshot is of that page).
"""

from __future__ import annotations

import os
import resource
import shutil
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from a5mi import PROJECT_ROOT, require_data_dir
from a5mi.commands.grade import _options_of
from a5mi.grade.batch import GradeSettings, grade_class, run_plain
from a5mi.grade.cases import DEFAULT_COMMANDS, Case, load_cases
from a5mi.grade.references import build_reference
from a5mi.grade.run import Task
from a5mi.runtime.cluster import start_client
from a5mi.sandbox.records import Limits

A5 = str(Path(sys.executable).with_name("a5"))
#: defect -> what the wrapper adds to / removes from the a5 command line ("" = none, None = no a5 run)
DEFECTS: dict[str, str | None] = {
    "none": "", "seed": "-seed 7", "noshadows": "DROP -shadows", "bounces0": "-bounces 0", "bounces1": "-bounces 1",
    "reflection": "-reflection_off", "refraction": "-refraction_off", "badsize": "-size 53 50",
    "nooutput": None, "crash": None,
}


def wrapper(defect: str) -> str:
    spec = DEFECTS[defect]
    if defect == "nooutput":
        return "#!/bin/sh\nexit 0\n"
    if defect == "crash":
        return "#!/bin/sh\necho 'Assertion failed' >&2\nexit 134\n"
    if spec and spec.startswith("DROP "):
        flag = spec.split()[1]
        return f"#!/bin/sh\nfor a in \"$@\"; do [ \"$a\" = {flag} ] || set -- \"$@\" \"$a\"; shift; done\n" \
               f"exec {A5} \"$@\"\n"
    return f"#!/bin/sh\nexec {A5} \"$@\" {spec}\n"


def make_class(root: Path, n: int) -> list[str]:
    names = []
    for k in range(n):
        defect = list(DEFECTS)[k % len(DEFECTS)]
        d = root / f"student{k:03d}-{defect}"
        d.mkdir(parents=True)
        (d / "a5").write_text(wrapper(defect))
        (d / "a5").chmod(0o755)
        names.append(d.name)
    return names


@contextmanager
def bench_class(prefix: str, n: int, size: int) -> Iterator[tuple[Path, str, Path, list[Case], Path, tuple[str, ...]]]:
    """A fresh folder ``/tmp/PREFIX*`` (0755: the sandbox's user id reaches it), removed afterwards, with the
    class of ``n`` students in ``subs`` (:func:`make_class`) and the handout's cases at ``size`` x ``size``
    (``cases.toml``): ``(base, scenes, subs, cases, cache, allow)``, ``cache`` the reference cache folder and
    ``allow`` the read-only paths a sandboxed run needs (this Python and the project)."""
    base = Path(tempfile.mkdtemp(prefix=prefix, dir="/tmp"))
    base.chmod(0o755)
    try:
        subs = base / "subs"
        make_class(subs, n)
        toml = base / "cases.toml"
        toml.write_text("".join(f'[[case]]\ncommand = "{c.replace("300 300", f"{size} {size}")}"\n\n'
                                for c in DEFAULT_COMMANDS))
        allow = tuple(sorted({sys.prefix, sys.base_prefix, str(PROJECT_ROOT)}
                             | {p for p in sys.path if p and os.path.isdir(p) and not p.startswith("/usr/")}))
        yield (base, str(require_data_dir() / "scenes"), subs, load_cases(toml, _options_of), base / "cache",
               allow)
    finally:
        shutil.rmtree(base, ignore_errors=True)


def main(argv: list[str]) -> int:
    n = int(argv[0]) if argv else 40
    size = int(argv[1]) if len(argv) > 1 else 50
    with bench_class("a5mi-gradebench-", n, size) as (base, scenes, subs, cases, cache, allow):
        t0 = time.perf_counter()
        refs = [build_reference(Path(scenes) / c.scene, c.options, cache) for c in cases]
        print(f"references: {time.perf_counter() - t0:.1f} s for {len(cases)} cases (cached afterwards)",
              file=sys.stderr, flush=True)
        limits = Limits(timeout=120)
        rows = []

        # plain loop
        work = base / "plain"
        work.mkdir()
        work.chmod(0o755)
        tasks = [Task(s, str(subs / s), c, scenes, r.image_path, r.sigma_path, str(work / "w"), str(work), limits,
                      allow) for s in sorted(os.listdir(subs)) for c, r in zip(cases, refs, strict=True)]
        t0 = time.perf_counter()
        plain = run_plain(tasks)
        plain_wall = time.perf_counter() - t0
        child_peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
        rows.append(("plain loop (1 process)", plain_wall, [resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024],
                     child_peak))
        print(f"plain: {plain_wall:.1f} s", file=sys.stderr, flush=True)
        verdicts = {r["key"]: r["verdict"] for r in plain}

        for workers in (1, 2):
            report = base / f"report{workers}"
            settings = GradeSettings(str(subs), str(report), cases, scenes, str(cache), workers=workers,
                                     limits=limits, read_only=allow, cpu=limits.cpu, wall=limits.timeout)
            with start_client(workers) as client:
                client.run(lambda: None)  # workers up before timing
                t0 = time.perf_counter()
                out = grade_class(settings, client=client)
                wall = time.perf_counter() - t0
                peaks = client.run(lambda: resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)
                kids = client.run(lambda: resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024)
            assert {r["key"]: r["verdict"] for r in out.records} == verdicts, "cluster and plain verdicts differ"
            rows.append((f"LocalCluster, {workers} worker{'s' if workers > 1 else ''}", wall, list(peaks.values()),
                         max(kids.values())))
            print(f"{workers} workers: {wall:.1f} s", file=sys.stderr, flush=True)
            if workers == 2 and len(argv) > 2:
                shutil.copytree(report, argv[2], dirs_exist_ok=True)

        cases_n = len(tasks)
        print(f"{n} students x {len(cases)} cases = {cases_n} cases at {size}x{size}, "
              f"{sum(v == 'match' for v in verdicts.values())} match; {os.cpu_count()} CPUs\n")
        print("| grader | wall | cases/s | overhead per case vs plain loop | peak RSS per worker | largest run |")
        print("| --- | --- | --- | --- | --- | --- |")
        for k, (name, wall, peaks, kid) in enumerate(rows):
            workers = max(1, k)
            over = "-" if k == 0 else f"{1000 * (wall * workers - plain_wall) / cases_n:+.0f} ms"
            print(f"| {name} | {wall:.1f} s | {cases_n / wall:.2f} | {over} | "
                  f"{', '.join(f'{p:.0f} MB' for p in peaks)} | {kid:.0f} MB |")
        return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

"""How long ``a5mi grade`` takes for a class, and how it scales with Dask workers (BENCHMARKS.md "Grading a class").

**The model** (docs/GRADING.md; the grade path of :func:`a5mi.grade.batch.grade_class`). A class of N students
on the handout's K = 4 cases, graded by k worker processes on a machine with C free cores:

    T(N, k) = F + N * U / min(k, C)                       (+ at most one task, u_max, as the tail)
    U = sum_c (p_c + s_c + g_c + f * x_c)                 (seconds of one worker per student)
    F = cluster start + references + calibration          (once per class)

* ``p_c``: the student program's CPU seconds for case c (its run's cgroup, ``record["cpu"]``): students of the
  sample solution's speed class (``/usr/local/bin/a5soln``), single-threaded;
* ``s_c``: the sandbox around it: run wall - program CPU - time the run waited for a CPU (``record["waited"]``,
  the cgroup's ``cpu.pressure``): bubblewrap, the run's tmpfs, cgroup and user id, the links to the scenes;
* ``g_c``: the grader's own work on the worker: the Dask task's compute time - the run's wall (reading and
  comparing the image with its noise band, NVIDIA FLIP, the report's images);
* ``x_c``: the cause of a ``wrong`` image (:func:`a5mi.grade.cause.cause_of` traces its worst pixels, about
  two a5mi renders), ``g_c`` of a wrong student - ``g_c`` of a correct one; ``f`` the share of wrong images;
* F: the references (a5mi's K renders x 8 jitter streams per case, cached for later runs of the class), the
  calibration (one a5mi render per case on a worker, the CPU-time bounds), the path checks; the cluster start.

The tasks are single-threaded and CPU-bound, so k workers go k times as fast while k <= C; on a shared machine
the measured wall is the model's stretched by the load (``stretch`` = measured / model).

**Measured** (every run through the real grade path: a TLS ``LocalCluster`` on 127.0.0.1, every case sandboxed):

1. the handout's size (300 x 300): two students, one correct (a wrapper ``exec a5soln "$@"``) and one wrong
   (``a5soln ... -bounces 0``), on 2 workers, references rendered first (timed): p, s, g, x per case and F;
2. the scaling: classes of N in ``--measure`` students (3 correct : 1 wrong) at ``--size`` on ``--measure-workers``
   workers: wall, load, each term of the model from the run's own records, the model's T beside the measured
   one, and the fitted T = A + B N per k (B_1 / B_k = the speed-up).

Printed: the measured points, the terms at 300 x 300 and T(``--students``, k) for each k of ``--workers``: on
k free cores, on this machine (C = its CPUs), on this machine stretched as the 300 x 300 point was by the load
(its measured wall / its model's), and the floor of the programs' CPU alone (N sum p / k); the workers needed for
an hour.

    .venv/bin/python benchmarks/grade_class.py [--students 200] [--workers 1,2,4,8,16] [--measure 4,8,16]
        [--measure-workers 1,2] [--size 40] [--wrong-share 0.25] [--a5soln PATH] [--json OUT.json]
    .venv/bin/python benchmarks/grade_class.py --from-json OUT.json --students 300   # the model again, no run

Without the sample solution binary it says so and exits 2, measuring nothing. The binary is referenced by path
(each student's ``a5`` is a two-line shell wrapper), never copied.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import statistics
import sys
import tempfile
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

A5SOLN = "/usr/local/bin/a5soln"
#: defect -> what the wrapper adds to / removes from the a5 command line ("" = none, None = no a5 run)
DEFECTS: dict[str, str | None] = {
    "none": "", "seed": "-seed 7", "noshadows": "DROP -shadows", "bounces0": "-bounces 0", "bounces1": "-bounces 1",
    "reflection": "-reflection_off", "refraction": "-refraction_off", "badsize": "-size 53 50",
    "nooutput": None, "crash": None,
}
#: The sample-solution class: per 4 students, 3 correct and 1 wrong (``-bounces 0``: every case ``wrong``).
SOLN_KINDS = ("correct", "correct", "correct", "wrong")


def wrapper(defect: str, program: str) -> str:
    """A student's ``a5``: a shell script running ``program`` with the case's arguments and ``defect``."""
    spec = DEFECTS[defect]
    if defect == "nooutput":
        return "#!/bin/sh\nexit 0\n"
    if defect == "crash":
        return "#!/bin/sh\necho 'Assertion failed' >&2\nexit 134\n"
    if spec and spec.startswith("DROP "):
        flag = spec.split()[1]
        return f"#!/bin/sh\nfor a in \"$@\"; do [ \"$a\" = {flag} ] || set -- \"$@\" \"$a\"; shift; done\n" \
               f"exec {program} \"$@\"\n"
    return f"#!/bin/sh\nexec {program} \"$@\" {spec}\n"


def make_class(root: Path, n: int, program: str | None = None, kinds: Sequence[str] = SOLN_KINDS) -> list[str]:
    """``n`` student folders under ``root``, each with an executable ``a5`` wrapper: around ``.venv/bin/a5`` with
    the defects of :data:`DEFECTS` in turn (``program`` None), or around ``program`` (the sample solution) in
    the ``kinds`` in turn (``correct``; ``wrong`` = ``-bounces 0``)."""
    a5 = str(Path(sys.executable).with_name("a5"))
    names = []
    for k in range(n):
        if program is None:
            kind = list(DEFECTS)[k % len(DEFECTS)]
            text = wrapper(kind, a5)
        else:
            kind = kinds[k % len(kinds)]
            text = wrapper("none" if kind == "correct" else "bounces0", program)
        d = root / f"student{k:03d}-{kind}"
        d.mkdir(parents=True)
        (d / "a5").write_text(text)
        (d / "a5").chmod(0o755)
        names.append(d.name)
    return names


@contextmanager
def bench_class(prefix: str, n: int, size: int, program: str | None = None, kinds: Sequence[str] = SOLN_KINDS
                ) -> Iterator[tuple[Path, str, Path, list[Any], Path, tuple[str, ...]]]:
    """A fresh folder ``/tmp/PREFIX*`` (0755: the sandbox's user id reaches it), removed afterwards, with the
    class of ``n`` students in ``subs`` (:func:`make_class`) and the handout's cases at ``size`` x ``size``
    (``cases.toml``; for ``program``, the sample solution, the images are ``.bmp``: it writes ``.bmp`` and
    ``.tga`` only): ``(base, scenes, subs, cases, cache, allow)``, ``cache`` the reference cache folder and
    ``allow`` the read-only paths a sandboxed run needs (this Python and the project for ``a5`` wrappers;
    nothing for a binary under ``/usr``)."""
    from a5mi import PROJECT_ROOT, require_data_dir
    from a5mi.commands.grade import _options_of
    from a5mi.grade.cases import DEFAULT_COMMANDS, load_cases

    base = Path(tempfile.mkdtemp(prefix=prefix, dir="/tmp"))
    base.chmod(0o755)
    try:
        subs = base / "subs"
        make_class(subs, n, program, kinds)
        commands = [c.replace("300 300", f"{size} {size}") for c in DEFAULT_COMMANDS]
        if program is not None:
            commands = [c.replace(".png", ".bmp") for c in commands]
        (base / "cases.toml").write_text("".join(f'[[case]]\ncommand = "{c}"\n\n' for c in commands))
        allow: tuple[str, ...] = ()
        if program is None:
            allow = tuple(sorted({sys.prefix, sys.base_prefix, str(PROJECT_ROOT)}
                                 | {p for p in sys.path if p and os.path.isdir(p) and not p.startswith("/usr/")}))
        cases = load_cases(base / "cases.toml", _options_of)
        yield base, str(require_data_dir() / "scenes"), subs, cases, base / "cache", allow
    finally:
        shutil.rmtree(base, ignore_errors=True)


# ---------------------------------------------------------------------------------------------------- the model
@dataclass(frozen=True)
class CaseTerms:
    """One case's terms of the model (seconds): program CPU ``p``, sandbox ``s``, grading ``g``, cause ``x``."""

    p: float
    s: float
    g: float
    x: float = 0.0

    def per_task(self, wrong_share: float) -> float:
        """u_c = p + s + g + f x: one worker's seconds for this case of one student."""
        return self.p + self.s + self.g + wrong_share * self.x


def per_student(cases: Sequence[CaseTerms], wrong_share: float) -> float:
    """U = sum over the cases of :meth:`CaseTerms.per_task`."""
    return sum(c.per_task(wrong_share) for c in cases)


def class_wall(n: int, workers: int, fixed: float, per_student_s: float, cores: int | None = None) -> float:
    """T(N, k) = F + N U / min(k, C) (``cores`` None: C = k, every worker on a free core)."""
    if n < 0 or workers < 1:
        raise ValueError("n >= 0 and workers >= 1")
    return fixed + n * per_student_s / min(workers, workers if cores is None else cores)


def workers_for(n: int, deadline: float, fixed: float, per_student_s: float, tail: float = 0.0) -> int | None:
    """The fewest workers (each on a free core) with F + N U / k + tail <= deadline; None if F + tail alone
    exceeds it."""
    room = deadline - fixed - tail
    if room <= 0:
        return None
    return max(1, math.ceil(n * per_student_s / room))


def fit_line(xs: Sequence[float], ys: Sequence[float]) -> tuple[float, float]:
    """Least squares y = a + b x: ``(a, b)``."""
    mx, my = statistics.fmean(xs), statistics.fmean(ys)
    sxx = sum((x - mx) ** 2 for x in xs)
    b = sum((x - mx) * (y - my) for x, y in zip(xs, ys, strict=True)) / sxx
    return my - b * mx, b


def terms_of(tasks: Sequence[dict[str, Any]], kind: str = "correct") -> dict[str, CaseTerms]:
    """Per case, the model's terms from measured tasks (:func:`measure`'s ``tasks``): p, s and g medians over the
    students of ``kind``; x = median g of the ``wrong`` students - g of ``kind``'s (0 without wrong ones)."""
    out = {}
    for case in sorted({t["case"] for t in tasks}, key=lambda c: (len(c), c)):  # 6f 10f 11f 12f
        mine = [t for t in tasks if t["case"] == case and t["kind"] == kind]
        bad = [t for t in tasks if t["case"] == case and t["kind"] == "wrong"]
        g = statistics.median(t["busy"] - t["run_wall"] for t in mine)
        x = statistics.median(t["busy"] - t["run_wall"] for t in bad) - g if bad else 0.0
        out[case] = CaseTerms(p=statistics.median(t["cpu"] for t in mine),
                              s=statistics.median(max(0.0, t["run_wall"] - t["cpu"] - t["waited"]) for t in mine),
                              g=g, x=x)
    return out


def point_model(point: dict[str, Any]) -> float:
    """The model's T for a measured point from its own tasks: F (the point's) + sum of the tasks' p + s + g
    (+ x for the wrong ones: their g) over min(k, C) workers."""
    work = sum(t["cpu"] + max(0.0, t["run_wall"] - t["cpu"] - t["waited"]) + (t["busy"] - t["run_wall"])
               for t in point["tasks"])
    return point["fixed"] + work / min(point["workers"], point["cores"])


# ---------------------------------------------------------------------------------------------- the measuring
def _own_cpu() -> float:
    """CPU seconds of this process, every thread (user + system): on a worker, the grader's own work."""
    import resource

    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def measure(program: str, n: int, workers: int, size: int, cache: Path | None = None,
            kinds: Sequence[str] = SOLN_KINDS) -> dict[str, Any]:
    """Grade a class of ``n`` sample-solution students at ``size`` on ``workers`` workers (references built
    first, in this process, and timed; ``cache`` reuses a folder of them): the point's wall, load averages,
    cluster start, F (grading start to the first student task's start) and, per task, its student's kind, case,
    compute time on its worker (``busy``), the run's wall, CPU and CPU wait, and verdict; ``grader_cpu``: the CPU
    seconds of the workers and of this process (client and scheduler) while grading, the student programs' not
    included (they run in their own processes)."""
    from distributed import get_task_stream

    from a5mi.grade.batch import GradeSettings, grade_class
    from a5mi.grade.references import build_reference
    from a5mi.runtime.cluster import start_client

    with bench_class("a5mi-gradeclass-", n, size, program, kinds) as (base, scenes, subs, cases, own_cache, allow):
        cache = cache or own_cache
        t0 = time.perf_counter()
        for c in cases:
            build_reference(Path(scenes) / c.scene, c.options, cache)
        refs = time.perf_counter() - t0
        settings = GradeSettings(str(subs), str(base / "report"), cases, scenes, str(cache), workers=workers,
                                 read_only=allow)
        load0 = os.getloadavg()
        t0 = time.perf_counter()
        with start_client(workers) as client:
            client.run(lambda: None)
            started = time.perf_counter() - t0
            cpu0, own0 = client.run(_own_cpu), _own_cpu()
            with get_task_stream(client) as stream:
                w0 = time.time()
                out = grade_class(settings, client=client)
                wall = time.time() - w0
            cpu1, own1 = client.run(_own_cpu), _own_cpu()
            grader_cpu = sum(cpu1.values()) - sum(cpu0.values()) + own1 - own0
        load1 = os.getloadavg()
    records = {r["key"]: r for r in out.records}
    tasks, first = [], math.inf
    for entry in stream.data:
        key = str(entry["key"])
        if not key.startswith("a5mi-"):
            continue
        unit = key[len("a5mi-"):].rsplit("-", 1)[0]
        span = [s for s in entry["startstops"] if s["action"] == "compute"]
        if unit not in records or not span:
            continue
        r = records[unit]
        first = min(first, span[0]["start"])
        tasks.append({"student": r["student"], "kind": r["student"].rsplit("-", 1)[1], "case": r["case"],
                      "busy": sum(s["stop"] - s["start"] for s in span), "run_wall": r.get("wall", 0.0),
                      "cpu": r.get("cpu", 0.0), "waited": r.get("waited", 0.0), "verdict": r["verdict"]})
    return {"students": n, "workers": workers, "size": size, "cores": os.cpu_count() or 1, "wall": wall,
            "fixed": first - w0, "cluster_start": started, "references": refs, "grader_cpu": grader_cpu,
            "load": [load0[0], load1[0]], "tasks": tasks}


def _check_verdicts(point: dict[str, Any]) -> list[str]:
    """The tasks whose verdict is not their kind's (``match`` for a correct student, ``wrong`` for a wrong one),
    and a missing task, as ``student/case: verdict`` lines."""
    want = {"correct": "match", "wrong": "wrong"}
    bad = [f"{t['student']}/{t['case']}: {t['verdict']}" for t in point["tasks"] if t["verdict"] != want[t["kind"]]]
    missing = 4 * point["students"] - len(point["tasks"])
    return bad + ([f"{missing} tasks missing from the task stream"] if missing else [])


# ------------------------------------------------------------------------------------------------ the report
def report(data: dict[str, Any], students: int, workers: Sequence[int], wrong_share: float) -> str:
    """The tables of BENCHMARKS.md "Grading a class" from measured ``data`` (``full``: the 300 x 300 point,
    ``points``: the scaling points)."""
    full, points = data["full"], data["points"]
    cores = full["cores"]
    lines = [f"{data['cpu_model']}, {cores} CPUs; commit {data['commit']}; {data['when']}", "",
             f"Scaling points (size {points[0]['size'] if points else '-'}): the model's T from each point's own "
             "tasks beside the measured wall", "",
             "| students | workers | load (1 min, start-end) | F s | sum p s | sum s s | sum g s | model T s | "
             "measured T s | stretch | cases/s | grader CPU s |", "|---:|---:|---|" + "---:|" * 9]
    for pt in points:
        ts = pt["tasks"]
        model = point_model(pt)
        lines.append(f"| {pt['students']} | {pt['workers']} | {pt['load'][0]:.1f}-{pt['load'][1]:.1f} | "
                     f"{pt['fixed']:.1f} | {sum(t['cpu'] for t in ts):.1f} | "
                     f"{sum(max(0.0, t['run_wall'] - t['cpu'] - t['waited']) for t in ts):.1f} | "
                     f"{sum(t['busy'] - t['run_wall'] for t in ts):.1f} | {model:.1f} | {pt['wall']:.1f} | "
                     f"{pt['wall'] / model:.2f} | {len(ts) / pt['wall']:.2f} | {_cpu(pt)} |")
    slopes = {}
    for k in sorted({pt["workers"] for pt in points}):
        mine = [pt for pt in points if pt["workers"] == k]
        if len(mine) >= 2:
            a, slopes[k] = fit_line([pt["students"] for pt in mine], [pt["wall"] for pt in mine])
            lines.append(f"\nfit, {k} worker(s): T = {a:.1f} s + {slopes[k]:.2f} s x N")
            if all("grader_cpu" in pt for pt in mine):
                ca, cb = fit_line([pt["students"] for pt in mine], [pt["grader_cpu"] for pt in mine])
                lines.append(f"grader CPU = {ca:.1f} s + {cb:.2f} s x N (wall s + g + x per student: "
                             f"{statistics.fmean(_overhead(pt) / pt['students'] for pt in mine):.2f} s)")
    if 1 in slopes and len(slopes) > 1:
        lines.append("speed-up (slope at 1 worker / slope at k): " + ", ".join(
            f"{k} workers {slopes[1] / b:.2f}x" for k, b in sorted(slopes.items()) if k > 1))
    terms = terms_of(full["tasks"])
    fixed = full["cluster_start"] + full["references"] + full["fixed"]
    u = per_student(list(terms.values()), wrong_share)
    program = sum(c.p for c in terms.values())
    tail = max(c.per_task(0.0) for c in terms.values())
    stretch = full["wall"] / point_model(full)
    lines += ["", f"The terms at {full['size']} x {full['size']} (one correct and one wrong sample-solution "
              f"student on {full['workers']} workers, load {full['load'][0]:.1f}-{full['load'][1]:.1f}; "
              f"measured T {full['wall']:.1f} s, the model's {point_model(full):.1f} s: stretch {stretch:.2f}), s:",
              "", "| case | p (program CPU) | s (sandbox) | g (grading) | x (cause of a wrong image) | u at f = "
              f"{wrong_share:g} |", "|---|---:|---:|---:|---:|---:|"]
    for case, c in terms.items():
        lines.append(f"| {case} | {c.p:.2f} | {c.s:.2f} | {c.g:.2f} | {c.x:.2f} | {c.per_task(wrong_share):.2f} |")
    lines += [f"| **U (one student)** | {program:.1f} | {sum(c.s for c in terms.values()):.1f} | "
              f"{sum(c.g for c in terms.values()):.1f} | {sum(c.x for c in terms.values()):.1f} | **{u:.1f}** |", "",
              f"F = {fixed:.1f} s: cluster start {full['cluster_start']:.1f} + references {full['references']:.1f} "
              f"(4 cases x 8 renders, in one process) + calibration and checks {full['fixed']:.1f}; "
              f"tail at most one task, {tail:.1f} s; the grader's own CPU in this point (calibration included): "
              f"{_cpu(full)} s, against {_overhead(full):.1f} s of s + g + x wall", "",
              f"{students} students x 4 cases at {full['size']} x {full['size']}, {wrong_share:.0%} of the images "
              f"wrong: T = F + N U / min(k, C)", "",
              f"| workers k | k free cores | this machine (C = {cores}) | this machine at the 300 x 300 point's load "
              f"(x {stretch:.2f}) | programs' CPU alone (N p / k) |", "|---:|---:|---:|---:|---:|"]
    for k in workers:
        here = class_wall(students, k, fixed, u, cores)
        lines.append(f"| {k} | {_hours(class_wall(students, k, fixed, u))} | {_hours(here)} | "
                     f"{_hours(here * stretch)} | {_hours(class_wall(students, k, 0.0, program))} |")
    need = workers_for(students, 3600.0, fixed, u, tail)
    lines += ["", f"one hour for {students} students: {need} worker(s) on free cores (F + N U / k + tail <= 3600 s)"
              if need else f"one hour for {students} students: not reachable (F + tail > 3600 s)"]
    return "\n".join(lines)


def _overhead(point: dict[str, Any]) -> float:
    """Sum over a point's tasks of the wall seconds beyond the program's CPU and its wait: s + g (+ x)."""
    return sum(t["busy"] - t["cpu"] - t["waited"] for t in point["tasks"])


def _cpu(point: dict[str, Any]) -> str:
    return f"{point['grader_cpu']:.1f}" if "grader_cpu" in point else "-"


def _hours(seconds: float) -> str:
    return f"{seconds / 3600:.2f} h" if seconds >= 3600 else f"{seconds / 60:.1f} min"


def _ints(text: str) -> list[int]:
    return [int(x) for x in text.split(",") if x.strip()]


def main(argv: Sequence[str]) -> int:
    ap = argparse.ArgumentParser(prog="grade_class.py", description=__doc__.split("\n\n")[0])
    ap.add_argument("--students", type=int, default=200, help="class size of the estimate (200)")
    ap.add_argument("--workers", type=_ints, default=[1, 2, 4, 8, 16], help="worker counts of the estimate")
    ap.add_argument("--measure", type=_ints, default=[4, 8, 16], help="class sizes measured (4,8,16)")
    ap.add_argument("--measure-workers", type=_ints, default=[1, 2], help="worker counts measured (1,2)")
    ap.add_argument("--size", type=int, default=40, help="image size of the scaling points (40)")
    ap.add_argument("--full-size", type=int, default=300, help="size of the terms' point (the handout's 300)")
    ap.add_argument("--wrong-share", type=float, default=0.25, help="share of wrong images in the estimate")
    ap.add_argument("--a5soln", default=A5SOLN, help=f"the sample solution binary ({A5SOLN})")
    ap.add_argument("--json", help="write the measured points here")
    ap.add_argument("--from-json", help="no run: the model from points written by --json")
    a = ap.parse_args(argv)
    if a.from_json:
        data = json.loads(Path(a.from_json).read_text())
    else:
        if not (os.path.isfile(a.a5soln) and os.access(a.a5soln, os.X_OK)):
            print(f"grade_class: no sample solution binary at {a.a5soln}: nothing measured (--a5soln PATH)",
                  file=sys.stderr)
            return 2
        data = run_all(a)
        if a.json:
            Path(a.json).write_text(json.dumps(data, indent=1))
    print(report(data, a.students, a.workers, a.wrong_share))
    return 0


def run_all(a: argparse.Namespace) -> dict[str, Any]:
    """Measure the 300 x 300 point and the scaling points (module docstring), printing progress on stderr."""
    import subprocess

    from a5mi import PROJECT_ROOT

    def say(pt: dict[str, Any]) -> None:
        pt["unexpected"] = _check_verdicts(pt)
        if pt["unexpected"]:
            print(f"grade_class: unexpected verdicts: {', '.join(pt['unexpected'][:6])}", file=sys.stderr)
        print(f"{pt['students']} students x {pt['workers']} workers at {pt['size']}: {pt['wall']:.1f} s "
              f"(F {pt['fixed']:.1f} s, load {pt['load'][0]:.1f}-{pt['load'][1]:.1f})", file=sys.stderr, flush=True)

    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=PROJECT_ROOT, capture_output=True,
                            text=True).stdout.strip()
    cpu_model = next((line.split(":", 1)[1].strip() for line in Path("/proc/cpuinfo").read_text().splitlines()
                      if line.startswith("model name")), "?")
    when = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    data: dict[str, Any] = {"commit": commit, "cpu_model": cpu_model, "when": when, "points": []}
    data["full"] = measure(a.a5soln, 2, 2, a.full_size, kinds=("correct", "wrong"))
    say(data["full"])
    with tempfile.TemporaryDirectory(prefix="a5mi-gradeclass-refs-") as cache:
        for n in a.measure:
            for k in a.measure_workers:
                if a.json:  # what is measured so far survives an interrupted run
                    Path(a.json).write_text(json.dumps(data, indent=1))
                data["points"].append(measure(a.a5soln, n, k, a.size, Path(cache)))
                say(data["points"][-1])
    return data


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))


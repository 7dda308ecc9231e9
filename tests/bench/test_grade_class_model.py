"""The arithmetic of ``benchmarks/grade_class.py``'s model of grading a class (BENCHMARKS.md "Grading a class"):
T(N, k) = F + N U / min(k, C), U = sum_c (p_c + s_c + g_c + f x_c), the terms taken from measured tasks, checked
on hand-made numbers. Timing is the benchmark's, not a test's."""

from __future__ import annotations

import importlib.util
import json
import math
import sys
from pathlib import Path
from typing import Any

import pytest
from helpers import ROOT

pytestmark = pytest.mark.unit  # the fast tier (`make check`): no Mitsuba, no child process

spec = importlib.util.spec_from_file_location("grade_class_bench", ROOT / "benchmarks" / "grade_class.py")
assert spec is not None and spec.loader is not None
gc = importlib.util.module_from_spec(spec)
sys.modules[spec.name] = gc  # dataclasses look their module up
spec.loader.exec_module(gc)


def task(case: str, kind: str, busy: float, run_wall: float, cpu: float, waited: float = 0.0) -> dict[str, Any]:
    return {"student": f"s-{kind}", "kind": kind, "case": case, "busy": busy, "run_wall": run_wall, "cpu": cpu,
            "waited": waited, "verdict": "match" if kind == "correct" else "wrong"}


def test_class_wall_divides_the_students_work_by_the_workers_on_free_cores() -> None:
    assert gc.class_wall(200, 1, 100.0, 190.0) == pytest.approx(100 + 200 * 190)
    assert gc.class_wall(200, 4, 100.0, 190.0) == pytest.approx(100 + 200 * 190 / 4)
    # more workers than cores: the cores bound the speed
    assert gc.class_wall(200, 4, 100.0, 190.0, cores=2) == pytest.approx(100 + 200 * 190 / 2)
    assert gc.class_wall(200, 1, 100.0, 190.0, cores=2) == pytest.approx(100 + 200 * 190)
    with pytest.raises(ValueError):
        gc.class_wall(10, 0, 1.0, 1.0)


def test_per_student_adds_the_cause_only_for_the_wrong_share() -> None:
    cases = [gc.CaseTerms(p=10.0, s=0.5, g=0.3, x=2.0), gc.CaseTerms(p=150.0, s=0.5, g=0.4, x=4.0)]
    assert gc.per_student(cases, 0.0) == pytest.approx(10.8 + 150.9)
    assert gc.per_student(cases, 0.25) == pytest.approx(10.8 + 150.9 + 0.25 * 6.0)


def test_workers_for_an_hour_is_the_smallest_k_that_fits() -> None:
    # 200 x 190 s = 38,000 s of work; 3600 - 100 - 150 = 3350 s of room: 38000 / 3350 = 11.34 -> 12
    k = gc.workers_for(200, 3600.0, 100.0, 190.0, tail=150.0)
    assert k == 12
    assert gc.class_wall(200, k, 100.0, 190.0) + 150.0 <= 3600.0 < gc.class_wall(200, k - 1, 100.0, 190.0) + 150.0
    assert gc.workers_for(200, 3600.0, 3500.0, 190.0, tail=150.0) is None


def test_fit_line_recovers_a_line() -> None:
    a, b = gc.fit_line([4, 8, 16], [30 + 7.5 * n for n in (4, 8, 16)])
    assert (a, b) == (pytest.approx(30.0), pytest.approx(7.5))


def test_terms_split_a_task_into_program_sandbox_grading_and_cause() -> None:
    tasks = [task("10f", "correct", busy=14.0, run_wall=13.0, cpu=12.0, waited=0.6),
             task("10f", "correct", busy=16.0, run_wall=15.0, cpu=12.2, waited=2.4),
             task("10f", "wrong", busy=5.0, run_wall=1.5, cpu=1.0)]
    t = gc.terms_of(tasks)["10f"]
    assert t.p == pytest.approx(12.1)              # median program CPU of the correct students
    assert t.s == pytest.approx(0.4)               # run wall - CPU - waited: 0.4 and 0.4
    assert t.g == pytest.approx(1.0)               # task - run wall
    assert t.x == pytest.approx(3.5 - 1.0)         # the wrong student's grading beyond a correct one's


def test_point_model_is_f_plus_the_tasks_work_over_the_workers() -> None:
    tasks = [task("6f", "correct", busy=3.0, run_wall=2.5, cpu=2.0, waited=0.3),
             task("6f", "wrong", busy=4.0, run_wall=1.0, cpu=0.8)]
    work = (2.0 + 0.2 + 0.5) + (0.8 + 0.2 + 3.0)
    point = {"fixed": 5.0, "workers": 2, "cores": 2, "tasks": tasks}
    assert gc.point_model(point) == pytest.approx(5.0 + work / 2)
    assert gc.point_model({**point, "workers": 4}) == pytest.approx(5.0 + work / 2)  # 2 cores
    assert gc.point_model({**point, "workers": 1}) == pytest.approx(5.0 + work)


def test_the_report_states_the_estimate_from_json(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    full_tasks = []
    for case, p in (("6f", 14.0), ("10f", 12.0), ("11f", 9.0), ("12f", 150.0)):
        full_tasks.append(task(case, "correct", busy=p + 1.5, run_wall=p + 0.5, cpu=p))
        full_tasks.append(task(case, "wrong", busy=4.0, run_wall=1.0, cpu=0.5))
    full = {"students": 2, "workers": 2, "size": 300, "cores": 2, "wall": 200.0, "fixed": 10.0,
            "cluster_start": 5.0, "references": 45.0, "load": [1.0, 1.2], "tasks": full_tasks}
    points = [{"students": n, "workers": k, "size": 40, "cores": 2, "wall": 10 + 8 * n / k, "fixed": 10.0,
               "load": [1.0, 1.0], "tasks": [task("6f", "correct", busy=8.0, run_wall=7.0, cpu=6.0)] * n}
              for n in (4, 8) for k in (1, 2)]
    data = {"commit": "abc1234", "cpu_model": "Test CPU", "when": "now", "full": full, "points": points}
    path = tmp_path / "points.json"
    path.write_text(json.dumps(data))
    assert gc.main(["--from-json", str(path), "--students", "200", "--workers", "1,2,4", "--wrong-share", "0"]) == 0
    out = capsys.readouterr().out
    # U = sum (p + s + g) = 185 + 4 x 0.5 + 4 x 1.0 = 191 s; F = 5 + 45 + 10 = 60 s
    u, f = 191.0, 60.0
    assert f"**{u:.1f}**" in out and "F = 60.0 s" in out
    # the 300 x 300 point's own model: F 10 + (4 correct tasks of p + 1.5, 4 wrong of 4.0) / 2 workers
    stretch = 200.0 / (10.0 + (185.0 + 4 * 1.5 + 4 * 4.0) / 2)
    assert f"stretch {stretch:.2f}" in out
    here = (f + 200 * u / 2) / 3600
    assert (f"| 4 | {(f + 200 * u / 4) / 3600:.2f} h | {here:.2f} h | {here * stretch:.2f} h | "
            f"{200 * 185.0 / 4 / 3600:.2f} h |") in out
    assert "fit, 1 worker(s): T = 10.0 s + 8.00 s x N" in out and "2 workers 2.00x" in out
    need = math.ceil(200 * u / (3600 - f - 151.5))
    assert f"one hour for 200 students: {need} worker(s)" in out


def test_without_the_binary_it_says_so_and_measures_nothing(capsys: pytest.CaptureFixture[str]) -> None:
    assert gc.main(["--a5soln", "/nonexistent/a5soln"]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.strip() == ("grade_class: no sample solution binary at /nonexistent/a5soln: nothing "
                                    "measured (--a5soln PATH)")

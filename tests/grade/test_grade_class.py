"""a5mi grade end to end: a generated class covering every verdict, on a 2-worker LocalCluster (docs/GRADING.md).

Each "student" is a small script wrapping ``.venv/bin/a5`` with one seeded defect (or none), or a folder of
images. The class is graded three times on a ``LocalCluster`` of 2 worker processes bound to 127.0.0.1:
cleanly, again while one worker is SIGKILLed mid-run (its task is retried, nothing is lost), and with
``--resume`` (nothing is re-graded). The cases are small (30 x 30) so the whole test takes about a minute.
"""

from __future__ import annotations

import json
import os
import shlex
import signal
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from helpers import sandbox_class_root

A5 = str(Path(sys.executable).with_name("a5"))
SIZE = 30
CASES = f"""
[[case]]
command = "-input scene10_sphere.txt -size {SIZE} {SIZE} -output 10f.png -shadows -bounces 4 -jitter -filter"
points = 40

[[case]]
name = "cube"
command = "-input scene11_cube.txt -size {SIZE} {SIZE} -output 11f.png -shadows -bounces 4 -jitter -filter"
points = 60
"""


def _wrapper(extra_py: str) -> str:
    """A Python student: transform argv (``args``), then exec the real a5."""
    return f"""#!/usr/bin/python3
import os, sys
args = sys.argv[1:]
{extra_py}
os.execv({A5!r}, ["a5", *args])
"""


#: Stands for a wrapper ``exec VENV/bin/a5`` (tests/hostile.py ``pyenv_wrapper``), written by the fixture.
PYENV_WRAPPER = "pyenv-style wrapper"
#: student -> (script or None for an image submission, expected verdict per case)
CLASS: dict[str, tuple[str | None, str]] = {
    "good": (f"#!/bin/sh\nexec {A5} \"$@\"\n", "match"),
    "otherseed": (f"#!/bin/sh\nexec {A5} \"$@\" -seed 7\n", "match"),
    "athome": (None, "match"),
    "nearly": (None, "close"),
    "noshadows": (_wrapper("args = [a for a in args if a != '-shadows']"), "wrong"),
    "nobounces": (_wrapper("args += ['-bounces', '0']"), "wrong"),
    "badsize": (_wrapper(f"args += ['-size', '{SIZE + 3}', '{SIZE}']"), "wrong size"),
    "silent": ("#!/bin/sh\necho rendering...\nexit 0\n", "no output"),
    "empty": (None, "no output"),
    "garbage": ("#!/bin/sh\n"
                "while [ $# -gt 0 ]; do [ \"$1\" = -output ] && echo 'P6 not really' > \"$2\"; shift; done\n",
                "unreadable"),
    "segfault": ("#!/bin/sh\necho 'Segmentation fault ahead' >&2\nkill -SEGV $$\n", "crash"),
    "throws": ("#!/usr/bin/python3\nraise SystemExit('assertion failed: ray.direction is not unit length')\n",
               "crash"),
    "sleeper": ("#!/bin/sh\nsleep 1000\n", "timeout"),
    "hog": ("#!/usr/bin/python3\nbuf = bytearray(20 << 30)\n", "over memory"),
    "pyenvwrap": (PYENV_WRAPPER, "crash"),  # exec VENV/bin/a5, whose interpreter is outside /usr: not allowed
}


def _allow_read() -> str:
    """What the wrappers need to start the real a5: this interpreter, its packages and the project."""
    from a5mi import PROJECT_ROOT

    paths = {sys.prefix, sys.base_prefix, str(PROJECT_ROOT)}
    paths |= {p for p in sys.path if p and os.path.isdir(p) and not p.startswith(("/usr/", "/tmp"))}
    return ":".join(sorted(paths))


@pytest.fixture(scope="module")
def klass(tmp_path_factory, scenes_dir):
    """The class folder, CASES.toml and the reference cache (references rendered here for the image students)."""
    root = sandbox_class_root(tmp_path_factory, "klass")
    subs = root / "subs"
    subs.mkdir()
    (root / "cases.toml").write_text(CASES)
    from a5mi.commands.grade import _options_of
    from a5mi.grade.cases import load_cases
    from a5mi.grade.references import build_reference, render_levels
    from a5mi.platform.imageio import write_image

    cases = load_cases(root / "cases.toml", _options_of)
    cwd = os.getcwd()
    for name, (script, _) in CLASS.items():
        d = subs / name
        d.mkdir()
        if script == PYENV_WRAPPER:
            from hostile import pyenv_wrapper

            script = f'#!/bin/sh\nexec "{pyenv_wrapper(subs)}" "$@"\n'
        if script is not None:
            (d / "a5").write_text(script)
            (d / "a5").chmod(0o755)
    for case in cases:
        os.chdir(scenes_dir)
        try:
            import dataclasses

            home = render_levels(scenes_dir / case.scene, dataclasses.replace(case.options, seed=99))
        finally:
            os.chdir(cwd)
        write_image(subs / "athome" / case.output, (home + 0.5) / 255)
        ref = build_reference(scenes_dir / case.scene, case.options, root / "cache")
        img, _ = ref.load()
        rng = np.random.default_rng(5)
        flat = img.reshape(-1, 3).copy()
        pick = rng.choice(len(flat), size=int(0.0125 * len(flat)), replace=False)  # between 1% and 1.5%
        flat[pick] = np.where(flat[pick] > 127, flat[pick] - 60, flat[pick] + 60)
        write_image(subs / "nearly" / case.output, (flat.reshape(img.shape) + 0.5) / 255)
    return root


def _argv(root: Path, report: Path, *more: str) -> list[str]:
    return ["grade", str(root / "subs"), "-o", str(report), "--cases", str(root / "cases.toml"), "--workers", "2",
            "--cache", str(root / "cache"), "--timeout", "12", "--memory", "3072", "--allow-read", _allow_read(),
            *more]


def _check(report: Path) -> dict:
    doc = json.loads((report / "results.json").read_text())
    got = {(r["student"], r["case"]): r["verdict"] for r in doc["results"]}
    want = {(s, c): v for s, (_, v) in CLASS.items() for c in ("10f", "cube")}
    assert got == want
    return doc


def _workers() -> list:
    import psutil

    out = []
    for p in psutil.Process().children():  # the nannies live in this process; each spawns one worker process
        try:
            cmd = " ".join(p.cmdline())
        except psutil.Error:
            continue
        if "spawn_main" in cmd and "resource_tracker" not in cmd:
            out.append(p)
    return out


def test_class_gets_the_verdicts_its_defects_imply(klass, capsys) -> None:
    from a5mi.cli import run_a5mi

    report = klass / "report1"
    assert run_a5mi(_argv(klass, report)) == 0
    out = capsys.readouterr()
    doc = _check(report)
    assert doc["isolation"] == "bwrap"
    assert doc["students"]["good"] == {"points": 100.0, "max_points": 100.0}
    assert doc["students"]["nearly"] == {"points": 50.0, "max_points": 100.0}  # close earns half
    assert doc["students"]["noshadows"]["points"] == 0.0
    by = {(r["student"], r["case"]): r for r in doc["results"]}
    assert "SIGSEGV" in by["segfault", "10f"]["detail"] and "Segmentation fault ahead" in by["segfault", "10f"][
        "stderr_tail"]
    assert "ray.direction is not unit length" in by["throws", "cube"]["stderr_tail"]
    assert by["badsize", "10f"]["detail"] == f"{SIZE + 3}x{SIZE}, expected {SIZE}x{SIZE}"
    assert 0 < by["noshadows", "10f"]["metrics"]["flip"] < 1
    lines = {ln.split()[0]: ln for ln in out.out.splitlines()}
    assert set(lines) == set(CLASS) and "100 / 100" in lines["good"]
    # a failure shared by every case is said once, with the paths that let the program start
    said = [ln for ln in out.err.splitlines() if "pyenvwrap" in ln]
    assert len(said) == 1 and said[0].startswith("a5mi grade: pyenvwrap: every case: crash: exit status 127"), said
    assert "a5mi grade: badsize: every case: wrong size: 33x30, expected 30x30" in out.err.splitlines()
    assert f"add --allow-read {klass / 'pyenv' / 'versions' / '3.11.7'}:{klass / 'venv'}" in said[0]
    assert (report / "feedback" / "pyenvwrap.md").read_text().count("every case: crash") == 1
    assert by["pyenvwrap", "cube"]["cause"] == by["pyenvwrap", "10f"]["cause"]
    assert "shadow" in by["noshadows", "10f"]["cause"] and by["good", "10f"]["cause"] == ""
    csv = (report / "results.csv").read_text().splitlines()
    assert len(csv) == 1 + 2 * len(CLASS) and csv[0].startswith("student,case,verdict,points")
    assert not (report / ".work").exists()
    for r in doc["results"]:
        for rel in r["images"].values():
            assert (report / rel).is_file()


def test_a_killed_worker_loses_nothing_and_resume_regrades_nothing(klass, capsys) -> None:
    from a5mi.cli import run_a5mi

    report = klass / "report2"
    journal = report / "journal.jsonl"
    killed: list[int] = []

    def killer() -> None:
        end = time.time() + 120
        while time.time() < end and not killed:
            n = len(journal.read_text().splitlines()) if journal.exists() else 0
            workers = _workers()
            if n >= 4 and len(workers) >= 2:
                os.kill(workers[0].pid, signal.SIGKILL)
                killed.append(workers[0].pid)
            time.sleep(0.1)

    t = threading.Thread(target=killer)
    t.start()
    assert run_a5mi(_argv(klass, report)) == 0
    t.join()
    assert killed, "no worker was killed"
    _check(report)
    records = [json.loads(ln) for ln in journal.read_text().splitlines()]
    assert sorted(r["key"] for r in records) == sorted(f"{s}/{c}" for s in CLASS for c in ("10f", "cube"))
    capsys.readouterr()

    mtime = journal.stat().st_mtime_ns
    t0 = time.perf_counter()
    assert run_a5mi(_argv(klass, report, "--resume")) == 0
    assert journal.stat().st_mtime_ns == mtime  # nothing re-graded, nothing appended
    assert f"{2 * len(CLASS)} cases taken from the journal" in capsys.readouterr().err
    assert time.perf_counter() - t0 < 60
    _check(report)


def test_cli_errors_are_one_line_exit_2(tmp_path, capsys) -> None:
    from a5mi.cli import run_a5mi

    (tmp_path / "subs" / "x").mkdir(parents=True)
    bad = tmp_path / "bad.toml"
    bad.write_text('[[case]]\ncommand = "-input a.txt -size 0 10 -output a.png"\n')
    cases = [
        (["grade", str(tmp_path / "subs")], "a5mi grade: error: missing -o REPORT_DIR"),
        (["grade", str(tmp_path / "nope"), "-o", str(tmp_path / "r")],
         f"a5mi grade: error: submissions folder '{tmp_path / 'nope'}' does not exist"),
        (["grade", str(tmp_path / "subs"), "-o", str(tmp_path / "r"), "--cases", str(bad)],
         f"{bad}:2:12: error: case 'a': -size expects an integer in [1, 16384], found 0"),
        (["grade", str(tmp_path / "subs"), "-o", str(tmp_path / "r"), "--scheduler", "localhost:8786"],
         "a5mi grade: error: --scheduler expects tls://HOST:PORT, found 'localhost:8786'"),
        (["grade", str(tmp_path / "subs"), "-o", str(tmp_path / "r"), "--scheduler", "tcp://127.0.0.1:8786"],
         "a5mi grade: error: --scheduler tcp://127.0.0.1:8786: a plain tcp:// scheduler lets anyone who reaches it "
         "run code on its workers; use tls:// with --tls-ca/--tls-cert/--tls-key, or --insecure-scheduler"),
        (["grade", str(tmp_path / "subs"), "-o", str(tmp_path / "r"), "--scheduler", "tls://127.0.0.1:8786",
          "--tls-ca", str(bad)], "a5mi grade: error: --tls-ca needs --tls-cert and --tls-key as well"),
        (["grade", str(tmp_path / "subs"), "-o", str(tmp_path / "r"), "--insecure-scheduler"],
         "a5mi grade: error: --insecure-scheduler needs --scheduler"),
    ]
    for argv, message in cases:
        assert run_a5mi(argv) == 2, argv
        assert capsys.readouterr().err.strip().splitlines() == [message]


def test_cases_file_errors_carry_their_position(tmp_path) -> None:
    from a5mi.grade.cases import CasesError, default_cases, load_cases

    assert [c.output for c in default_cases()] == ["6f.png", "10f.png", "11f.png", "12f.png"]
    assert all(shlex.join(c.argv).endswith("-size 300 300 -shadows -bounces 4 -jitter -filter")
               for c in default_cases())
    p = tmp_path / "c.toml"
    p.write_text('[[case]]\ncommand = "-input a.txt -output a.png"\npoints = "ten"\n')
    with pytest.raises(CasesError, match=rf"^{p}:2:12: error: points must be a number \(found .ten.\)"):
        load_cases(p)
    p.write_text("[[case]\n")
    with pytest.raises(CasesError, match=rf"^{p}:1:\d+: error: "):
        load_cases(p)
    p.write_text('[[case]]\ncommand = "-input a.txt -output out/a.png"\n')
    with pytest.raises(CasesError, match="bare file name"):
        load_cases(p)
    p.write_text('[[case]]\ncommand = "-input a.txt -output a.png"\n[[case]]\ncommand = "-input b.txt -output a.png"\n')
    with pytest.raises(CasesError, match="two cases are named 'a'"):
        load_cases(p)


def test_journal_ignores_a_torn_last_line(tmp_path) -> None:
    from a5mi.runtime.cluster import Journal

    j = Journal(tmp_path / "j.jsonl")
    j.append({"key": "a/1", "verdict": "match"})
    j.append({"key": "a/2", "verdict": "wrong"})
    with open(j.path, "a") as f:
        f.write('{"key": "a/3", "verd')  # the grader was killed mid-write
    assert j.done() == {"a/1", "a/2"}
    j.append({"key": "a/1", "verdict": "close"})  # a later record of a key wins
    assert [r["verdict"] for r in j.records()] == ["close", "wrong"]


def _tls_files(folder: Path):  # noqa: ANN202 - (Security, (ca, cert, key))
    """Throwaway TLS credentials of a cluster started by a test, and the same as PEM files for ``--tls-*``."""
    from distributed.security import Security

    sec = Security.temporary()
    folder.mkdir(mode=0o700)
    files = []
    for name, pem in (("ca.pem", sec.tls_ca_file), ("cert.pem", sec.tls_client_cert), ("key.pem", sec.tls_client_key)):
        (folder / name).write_text(pem)
        files.append(str(folder / name))
    return sec, tuple(files)


def _tls_cluster(sec, n_workers: int = 1):  # noqa: ANN001, ANN202 - a distributed.LocalCluster
    from distributed import LocalCluster

    return LocalCluster(n_workers=n_workers, threads_per_worker=1, host="127.0.0.1", protocol="tls://",
                        security=sec, dashboard_address="127.0.0.1:0",  # never 8787: a second suite may hold it
                        silence_logs=50)


def test_joins_an_existing_cluster_and_reads_given_references(tmp_path, scenes_dir, capsys, monkeypatch) -> None:
    """--scheduler tls://: a cluster started here (127.0.0.1, its workers in another folder) is joined with
    --tls-ca/--tls-cert/--tls-key, not started; every path is given relative to this folder and still reaches
    the workers; --reference DIR supplies the reference images (a5mi's noise band is still rendered for them);
    the identical image's PSNR is "inf" in the JSON and the CSV."""
    from a5mi.cli import run_a5mi
    from a5mi.commands.grade import _options_of
    from a5mi.grade.cases import load_cases
    from a5mi.grade.references import render_levels
    from a5mi.platform.imageio import write_image

    toml = tmp_path / "cases.toml"
    toml.write_text('[[case]]\ncommand = "-input scene11_cube.txt -size 20 20 -output 11f.png -shadows -bounces 4 '
                    '-jitter -filter"\nreference = "scene11.given.png"\n')
    case = load_cases(toml, _options_of)[0]
    cwd = os.getcwd()
    os.chdir(scenes_dir)
    try:
        import dataclasses

        given = render_levels(scenes_dir / case.scene, dataclasses.replace(case.options, seed=41))
        other = render_levels(scenes_dir / case.scene, dataclasses.replace(case.options, seed=42))
        dark = render_levels(scenes_dir / case.scene, dataclasses.replace(case.options, shadows=False))
    finally:
        os.chdir(cwd)
    (tmp_path / "refs").mkdir()
    write_image(tmp_path / "refs" / "scene11.given.png", (given + 0.5) / 255)
    for name, img in (("same", given), ("other", other), ("noshadows", dark)):
        (tmp_path / "subs" / name).mkdir(parents=True)
        write_image(tmp_path / "subs" / name / "11f.png", (img + 0.5) / 255)
    sec, (ca, cert, key) = _tls_files(tmp_path / "tls")
    (tmp_path / "elsewhere").mkdir()
    monkeypatch.chdir(tmp_path / "elsewhere")  # the workers' folder
    with _tls_cluster(sec) as cluster:
        monkeypatch.chdir(tmp_path)
        assert cluster.scheduler_address.startswith("tls://")
        argv = ["grade", "subs", "-o", "report", "--cases", "cases.toml", "--reference", "refs", "--scheduler",
                cluster.scheduler_address, "--tls-ca", ca, "--tls-cert", cert, "--tls-key", key, "--cache", "cache"]
        assert run_a5mi(argv) == 0, capsys.readouterr().err
    doc = json.loads((tmp_path / "report" / "results.json").read_text())
    assert {r["student"]: r["verdict"] for r in doc["results"]} == {"same": "match", "other": "match",
                                                                   "noshadows": "wrong"}
    assert doc["references"] == {"11f": str(tmp_path / "refs" / "scene11.given.png")}
    by = {r["student"]: r for r in doc["results"]}
    assert by["same"]["metrics"]["psnr"] == "inf" and float(by["same"]["metrics"]["psnr"]) == float("inf")
    assert isinstance(by["other"]["metrics"]["psnr"], float)
    import csv

    rows = {r["student"]: r for r in csv.DictReader(open(tmp_path / "report" / "results.csv"))}
    assert rows["same"]["psnr"] == "inf" and float(rows["other"]["psnr"]) > 0
    capsys.readouterr()
    (tmp_path / "refs" / "scene11.given.png").unlink()
    assert run_a5mi(argv[:8] + ["--workers", "1"] + argv[-2:]) == 2
    assert "reference image" in capsys.readouterr().err


def test_identical_and_unmeasured_images_differ_in_the_csv_and_json(tmp_path) -> None:
    """PSNR of an identical image is ``inf`` (CSV) / ``"inf"`` (JSON); no metrics is an empty cell / null."""
    from a5mi.grade.cases import make_case
    from a5mi.grade.report import csv_text, write_all

    case = make_case("-input scene10_sphere.txt -output 10f.png", points=10)
    metrics = {"beyond_noise": 0.0, "psnr": None, "mean_error": 0.0, "share_over_2": 0.0, "max_error": 0.0,
               "flip": 0.0}
    records = [{"key": "a/10f", "student": "a", "case": "10f", "verdict": "match", "points": 10.0,
                "max_points": 10.0, "detail": "", "metrics": metrics, "images": {}},
               {"key": "b/10f", "student": "b", "case": "10f", "verdict": "no output", "points": 0.0,
                "max_points": 10.0, "detail": "", "metrics": None, "images": {}}]
    import csv
    import io

    rows = list(csv.DictReader(io.StringIO(csv_text(records))))
    assert [r["psnr"] for r in rows] == ["inf", ""]
    files = write_all(tmp_path, [case], ["a", "b"], records, {})
    doc = json.loads(Path(files["json"]).read_text())
    assert [r["metrics"] for r in doc["results"]][1] is None
    assert doc["results"][0]["metrics"]["psnr"] == "inf"
    assert "PSNR inf dB" in Path(files["html"]).read_text()


def test_a_worker_that_cannot_see_the_submissions_is_an_error(tmp_path, capsys, klass) -> None:
    """A worker (``dask worker`` in its own mount namespace, where the folder holding the submissions is an
    empty tmpfs: another machine without the shared filesystem) makes the run a one-line error, exit 2."""
    import shutil
    import subprocess

    from a5mi.cli import run_a5mi

    if shutil.which("bwrap") is None:
        pytest.skip("bubblewrap is installed by make setup")
    hidden = tmp_path / "hidden"
    shutil.copytree(klass / "subs" / "athome", hidden / "subs" / "athome")
    sec, (ca, cert, key) = _tls_files(tmp_path / "tls")
    with _tls_cluster(sec, n_workers=0) as cluster:
        worker = subprocess.Popen(["bwrap", "--dev-bind", "/", "/", "--tmpfs", str(hidden), "--die-with-parent",
                                   sys.executable, "-m", "distributed.cli.dask_worker", cluster.scheduler_address,
                                   "--tls-ca-file", ca, "--tls-cert", cert, "--tls-key", key, "--nthreads", "1",
                                   "--no-dashboard", "--no-nanny", "--host", "127.0.0.1"],
                                  stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            from distributed import Client

            with Client(cluster) as client:
                client.wait_for_workers(1, timeout=60)
                (address,) = client.scheduler_info()["workers"]
            argv = ["grade", str(hidden / "subs"), "-o", str(tmp_path / "report"), "--cases",
                    str(klass / "cases.toml"), "--cache", str(klass / "cache"), "--scheduler",
                    cluster.scheduler_address, "--tls-ca", ca, "--tls-cert", cert, "--tls-key", key]
            assert run_a5mi(argv) == 2
        finally:
            worker.terminate()
            worker.wait(30)
    assert capsys.readouterr().err.strip().splitlines() == [
        f"a5mi grade: error: worker {address} cannot see {hidden / 'subs'}: the scheduler's workers need a shared "
        f"filesystem"]


def test_nothing_graded_is_an_error_not_a_class_of_zeros(tmp_path, capsys, klass) -> None:
    """Every student's image under a name no case asks for: every case is 'no output', which is a set-up
    mistake: the report is written, the exit status is 2 with one line."""
    from a5mi.cli import run_a5mi

    for student in ("ann", "bob"):
        (tmp_path / "subs" / student).mkdir(parents=True)
        for case in ("10f", "11f"):
            (tmp_path / "subs" / student / f"{case}.bmp").write_bytes(
                (klass / "subs" / "athome" / f"{case}.png").read_bytes())
    argv = ["grade", str(tmp_path / "subs"), "-o", str(tmp_path / "report"), "--cases", str(klass / "cases.toml"),
            "--cache", str(klass / "cache"), "--workers", "1", "--no-flip"]
    assert run_a5mi(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("a5mi grade: error: nothing could be graded: every case of all 2 students is 'no "
                              "output' or a grader error")
    assert (tmp_path / "report" / "report.html").is_file()


def test_resume_regrades_what_changed(tmp_path, capsys, klass) -> None:
    """--resume re-grades a (student, case) whose case command, reference or submission folder changed since it
    was journaled, and only those: a case's -bounces 4 made 0, then one of a student's images replaced."""
    import shutil

    from a5mi.cli import run_a5mi

    for student in ("athome", "nearly"):
        shutil.copytree(klass / "subs" / student, tmp_path / "subs" / student)
    cases = tmp_path / "cases.toml"
    cases.write_text(CASES)
    report = tmp_path / "report"
    argv = ["grade", str(tmp_path / "subs"), "-o", str(report), "--cases", str(cases), "--cache",
            str(klass / "cache"), "--workers", "1", "--no-flip"]

    def verdicts() -> dict[tuple[str, str], str]:
        doc = json.loads((report / "results.json").read_text())
        return {(r["student"], r["case"]): r["verdict"] for r in doc["results"]}

    assert run_a5mi(argv) == 0
    first = {("athome", "10f"): "match", ("athome", "cube"): "match", ("nearly", "10f"): "close",
             ("nearly", "cube"): "close"}
    assert verdicts() == first
    capsys.readouterr()
    assert run_a5mi([*argv, "--resume"]) == 0  # nothing changed: nothing re-graded
    assert "4 cases taken from the journal" in capsys.readouterr().err and verdicts() == first

    cases.write_text(CASES.replace("-output 10f.png -shadows -bounces 4", "-output 10f.png -shadows -bounces 0"))
    assert run_a5mi([*argv, "--resume"]) == 0
    assert "2 cases taken from the journal" in capsys.readouterr().err
    assert verdicts() == {**first, ("athome", "10f"): "wrong", ("nearly", "10f"): "wrong"}

    shutil.copyfile(tmp_path / "subs" / "nearly" / "11f.png", tmp_path / "subs" / "athome" / "11f.png")
    assert run_a5mi([*argv, "--resume"]) == 0  # athome's folder changed: both its cases are graded again
    assert "2 cases taken from the journal" in capsys.readouterr().err
    assert verdicts() == {**first, ("athome", "10f"): "wrong", ("nearly", "10f"): "wrong", ("athome", "cube"): "close"}

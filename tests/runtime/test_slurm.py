"""``a5mi grade --slurm`` on a real SLURM started by the test (docs/GRADING.md "On a SLURM cluster").

The module fixture starts ``munged``, ``slurmctld`` and ``slurmd`` on this machine (:mod:`slurm_daemons`: one
node, two CPUs, loopback only) and stops them afterwards. Where they cannot run (not root, no apt-get) the
module is skipped with one line; where ``make setup`` would have installed them, their absence is a failure.

The class: one 16 x 16 case without jitter (scene10, ``-shadows -bounces 4``) and students that exec the real
``a5`` (``good``), drop ``-shadows`` (``noshadows``), or copy a prepared image after sleeping ``delay`` seconds
(``lazy*``: a correct or a shadowless image). The same class graded on a 2-worker LocalCluster and on two SLURM
jobs gets the same records; with jobs cancelled, jobs reaching their time limit and the client killed and
restarted with ``--resume``, every case is journaled exactly once and the report is the uninterrupted one.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from helpers import sandbox_class_root
from slurm_daemons import LocalSlurm, installable, slurm_problem

A5 = str(Path(sys.executable).with_name("a5"))
A5MI = str(Path(sys.executable).with_name("a5mi"))
SIZE = 16
COMMAND = f"-input scene10_sphere.txt -size {SIZE} {SIZE} -output 10.png -shadows -bounces 4"
CASES = f'[[case]]\nname = "sphere"\ncommand = "{COMMAND}"\npoints = 10\n'
LAZY = """#!/bin/sh
d=$(dirname "$0")
sleep $(cat "$d/delay")
while [ $# -gt 0 ]; do [ "$1" = -output ] && cp "$d/img.png" "$2"; shift; done
"""
#: student -> expected verdict; lazy students: which prepared image they copy.
VERDICTS = {"good": "match", "noshadows": "wrong", "lazy_ok": "match", "lazy_bad": "wrong"}
#: The slow class: these lazy students too (12 x 20 s of sleep on two one-CPU jobs, at least 120 s: longer than
#: the jobs' 1-minute time limit in the job-death test, which SLURM enforces within 30 s of it).
SLOW = {f"lazy{i:02d}": ("match" if i % 2 else "wrong") for i in range(12)}


@pytest.fixture(scope="module")
def slurm():
    why = slurm_problem()
    if why:
        if installable():
            pytest.fail(f"local SLURM not started although make setup installs it here: {why}")
        pytest.skip(f"local SLURM not available: {why}")
    with LocalSlurm() as s:
        yield s


def _allow_read() -> str:
    from a5mi import PROJECT_ROOT

    paths = {sys.prefix, sys.base_prefix, str(PROJECT_ROOT)}
    paths |= {p for p in sys.path if p and os.path.isdir(p) and not p.startswith(("/usr/", "/tmp"))}
    return ":".join(sorted(paths))


def _student(subs: Path, name: str, images: dict[str, Path], delay: int) -> None:
    d = subs / name
    d.mkdir(parents=True)
    if name == "good":
        (d / "a5").write_text(f'#!/bin/sh\nexec {A5} "$@"\n')
    elif name == "noshadows":
        (d / "a5").write_text(f"#!/bin/sh\nfor a; do shift; [ \"$a\" = -shadows ] || set -- \"$@\" \"$a\"; done\n"
                              f'exec {A5} "$@"\n')
    else:
        (d / "a5").write_text(LAZY)
        (d / "delay").write_text(str(delay))
        verdict = VERDICTS.get(name) or SLOW[name]
        (d / "img.png").write_bytes(images[verdict].read_bytes())
    (d / "a5").chmod(0o755)


@pytest.fixture(scope="module")
def klass(tmp_path_factory, scenes_dir):
    """The quick class (``subs``), the slow one (``slow``: delay 20 s), the cases and the reference cache."""
    root = sandbox_class_root(tmp_path_factory, "slurmclass")
    images = {}
    for verdict, drop in (("match", ""), ("wrong", "-shadows")):
        out = root / f"{verdict}.png"
        argv = [A5, *(a for a in COMMAND.split() if a != drop)]
        argv[argv.index("-output") + 1] = str(out)
        subprocess.run(argv, cwd=scenes_dir, check=True, capture_output=True, timeout=300)
        images[verdict] = out
    for name in VERDICTS:
        _student(root / "subs", name, images, 0)
    for name in (*VERDICTS, *SLOW):
        _student(root / "slow", name, images, 20 if name in SLOW else 0)
    (root / "cases.toml").write_text(CASES)
    return root


def _argv(root: Path, subs: str, report: Path, *more: str) -> list[str]:
    return ["grade", str(root / subs), "-o", str(report), "--cases", str(root / "cases.toml"), "--workers", "2",
            "--cache", str(root / "cache"), "--timeout", "60", "--memory", "3072", "--allow-read", _allow_read(),
            "--no-flip", *more]


#: record fields that differ from run to run (:func:`_records`)
MEASURED = frozenset({"wall", "fingerprint", "cpu", "waited", "cpu_bound", "wall_bound", "uid"})


def _records(report: Path) -> dict[tuple[str, str], dict]:
    """The records of ``results.json`` by (student, case), without what differs from run to run: what the run
    measured (``wall``, ``cpu``, ``waited``, and the bounds calibrated from a5mi's own CPU time on the worker,
    ``cpu_bound``, ``wall_bound``), the run's own user id ``uid``, and ``fingerprint`` (it digests the task,
    whose folders name the report folder). The verdict, its detail, cause and ``ended_by`` are compared."""
    doc = json.loads((report / "results.json").read_text())
    out = {}
    for r in doc["results"]:
        r = {k: v for k, v in r.items() if k not in MEASURED}
        out[r["student"], r["case"]] = r
    return out


@pytest.fixture(scope="module")
def local_report(klass):
    """The quick class graded on a 2-worker LocalCluster (the baseline)."""
    from a5mi.cli import run_a5mi

    report = klass / "local"
    assert run_a5mi(_argv(klass, "subs", report)) == 0
    return report


def test_slurm_grades_like_a_local_cluster(slurm, klass, local_report, capsys) -> None:
    from a5mi.cli import run_a5mi

    report = klass / "slurm1"
    assert run_a5mi(_argv(klass, "subs", report, "--slurm", "--slurm-memory", "1GB")) == 0
    out = capsys.readouterr()
    got, want = _records(report), _records(local_report)
    assert {k: r["verdict"] for k, r in got.items()} == {(s, "sphere"): v for s, v in VERDICTS.items()}
    assert got == want
    doc = json.loads((report / "results.json").read_text())
    assert doc["isolation"] == "bwrap"  # the sandbox inside each job
    assert "good" in out.out and "(sandbox: bwrap)" in out.err
    _assert_ended(slurm)
    assert not (report / "slurm" / "tls").exists(), "the run's worker credentials were left on disk"


@pytest.mark.parametrize(("more", "message"), [
    (["--slurm-partition", "cpu"], "--slurm-partition needs --slurm"),
    (["--slurm", "--scheduler", "tls://127.0.0.1:1"], "give --slurm or --scheduler, not both"),
    (["--slurm", "--slurm-walltime", "1h"], "--slurm-walltime expects [D-]HH:MM:SS, found '1h'"),
    (["--slurm", "--slurm-memory", "lots"], "--slurm-memory expects a size like 4GB, found 'lots'"),
    (["--slurm", "--slurm-sbatch", "--qos='short"], "--slurm-sbatch: No closing quotation"),
])
def test_slurm_flags_are_checked_before_anything_runs(tmp_path, capsys, more, message) -> None:
    from a5mi.cli import run_a5mi

    (tmp_path / "subs" / "ann").mkdir(parents=True)
    assert run_a5mi(["grade", str(tmp_path / "subs"), "-o", str(tmp_path / "r"), *more]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err, err
    assert not (tmp_path / "r").exists()


def test_a_job_sbatch_refuses_is_one_line_and_nothing_is_graded(slurm, klass, capsys) -> None:
    from a5mi.cli import run_a5mi

    report = klass / "refused"
    assert run_a5mi(_argv(klass, "subs", report, "--slurm", "--slurm-partition", "nosuch")) == 2
    err = capsys.readouterr().err
    assert "a5mi grade: error: --slurm: sbatch refuses the worker job: invalid partition specified: nosuch" in err
    assert not report.exists() and not slurm.jobs()


def _assert_ended(slurm: LocalSlurm) -> None:
    """No job still in the queue is pending or running: the cluster's close retired its workers (the job
    script ends: ``COMPLETING``, ``COMPLETED``) or cancelled the job (``scancel``: ``CANCELLED``)."""
    states = {j: slurm.job_state(j) for j in slurm.jobs()}
    assert all(s in ("CANCELLED", "COMPLETING", "COMPLETED") for s in states.values()), f"jobs left: {states}"


def _journal(report: Path) -> list[dict]:
    path = report / "journal.jsonl"
    if not path.exists():
        return []
    out = []
    for line in path.read_text().splitlines():
        try:
            out.append(json.loads(line))
        except json.JSONDecodeError:
            pass  # a torn last line
    return out


def test_jobs_die_and_the_client_restarts_yet_nothing_is_lost_or_graded_twice(slurm, klass, local_report) -> None:
    """One run of the slow class on two jobs of a 1-minute time limit: a job is cancelled (``scancel``) once
    the first case is journaled, a job reaches its time limit (SLURM ends it: ``TIMEOUT``; the cluster submits
    a new one), then the client is SIGKILLed and started again with ``--resume`` (jobs of 10 minutes). Every case is
    journaled once, and every record is the one an uninterrupted run gives for the same image."""
    from a5mi.runtime.slurm import job_name

    report = klass / "slurm-deaths"
    name = job_name(report / "slurm")
    argv = [A5MI, *_argv(klass, "slow", report, "--slurm", "--slurm-memory", "1GB", "--slurm-walltime", "00:01:00")]
    log = open(klass / "deaths-client1.log", "wb")  # noqa: SIM115
    client = subprocess.Popen(argv, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    seen: set[str] = set()
    cancelled = None
    total = len(VERDICTS) + len(SLOW)
    try:
        deadline = time.monotonic() + 400  # a bound on SLURM's own timers (time limit: checked every 30 s)
        while time.monotonic() < deadline and client.poll() is None:
            seen |= set(slurm.jobs(name))
            done = len(_journal(report))
            if cancelled is None and done >= 1 and seen:
                running = slurm.run("squeue", "-h", "-t", "R", f"--name={name}", "-o", "%i").split()
                if running:
                    cancelled = running[0]
                    slurm.run("scancel", cancelled)
            timed_out = [j for j in seen if j != cancelled and slurm.job_state(j) == "TIMEOUT"]
            if cancelled and timed_out and done < total:
                break
            time.sleep(1)
        assert client.poll() is None, "the class ended before a job reached its time limit"
        assert cancelled is not None and timed_out, f"no job cancelled ({cancelled}) or timed out ({timed_out})"
        os.killpg(client.pid, signal.SIGKILL)
        client.wait()
    finally:
        if client.poll() is None:
            os.killpg(client.pid, signal.SIGKILL)
            client.wait()
        log.close()
    assert slurm.job_state(cancelled) == "CANCELLED"
    before = len(_journal(report))
    assert 0 < before < total
    left = set(slurm.jobs(name))  # a running worker exits when its scheduler is gone; a pending job would not
    log = klass / "deaths-client2.log"
    with open(log, "wb") as f:
        # jobs that outlive the rest of the class (under load a worker's start-up alone can eat a minute)
        again = [*argv[:-1], "00:10:00", "--resume"]
        rc = subprocess.run(again, stdout=f, stderr=subprocess.STDOUT, timeout=600).returncode
    assert rc == 0, log.read_text()[-3000:]
    # the restarted client cancelled them (or they ended first: their time limit, or no scheduler for 60 s)
    assert all(slurm.job_state(j) in ("CANCELLED", "TIMEOUT", "COMPLETED") for j in left)
    keys = [r["key"] for r in _journal(report)]
    assert sorted(keys) == sorted(f"{s}/sphere" for s in (*VERDICTS, *SLOW)), "a case graded twice or lost"
    assert f"{before} cases taken from the journal (--resume)" in log.read_text()
    got, want = _records(report), _records(local_report)
    for (student, case), rec in got.items():
        twin = student if student in VERDICTS else ("lazy_ok" if SLOW[student] == "match" else "lazy_bad")
        expect = {**want[twin, case], "key": f"{student}/{case}", "student": student}
        expect["images"] = {k: v.replace(f"/{twin}/", f"/{student}/").replace(f"{twin}_", f"{student}_")
                            for k, v in expect["images"].items()} if "images" in expect else None
        if expect["images"] is None:
            expect.pop("images")
        assert rec == expect, (student, rec, expect)
    _assert_ended(slurm)


def _pem_security(folder: Path):
    """A ``Security`` of PEM files in ``folder`` (one self-signed certificate: the CA and every role's), as a
    site makes once with openssl (docs/GRADING.md); the files' paths (ca, cert, key)."""
    from distributed.security import Security

    tmp = Security.temporary()
    folder.mkdir(mode=0o700)
    cert, key = folder / "cert.pem", folder / "key.pem"
    cert.write_text(tmp.tls_ca_file)
    key.touch(mode=0o600)
    key.write_text(tmp.tls_client_key)
    c, k = str(cert), str(key)
    return Security(require_encryption=True, tls_ca_file=c, tls_client_cert=c, tls_client_key=k,
                    tls_scheduler_cert=c, tls_scheduler_key=k, tls_worker_cert=c, tls_worker_key=k), (c, c, k)


def test_renders_split_on_slurm_workers_equal_one_process(slurm, tmp_path, scenes_dir) -> None:
    """``a5 -scheduler`` and ``a5mi animate --scheduler`` on two SLURM-started workers (the cluster the docs'
    snippet starts, with TLS files of the site's): the images are bit for bit the one-process ones. Every
    socket this test's processes listen on (this process: the scheduler; the daemons and their jobs) is on
    127.0.0.1, and a client with a certificate of another CA is refused. A pending job of the same folder's
    name (what a killed client leaves) is cancelled when the cluster starts."""
    import psutil
    from distributed import Client
    from distributed.security import Security

    from a5mi import PROJECT_ROOT
    from a5mi.platform.imageio import read_uint8
    from a5mi.runtime.slurm import SlurmOptions, job_name, start_slurm_client

    tmp_path.chmod(0o755)
    security, (ca, cert, key) = _pem_security(tmp_path / "tls")
    tls = ["-tls_ca", ca, "-tls_cert", cert, "-tls_key", key]
    scene = ["-input", "scene10_sphere.txt", "-size", "24", "24", "-shadows", "-bounces", "2", "-jitter", "-seed", "3"]
    anim = [str(PROJECT_ROOT / "scenes" / "animation.txt"), "--frames", "0:2", "-size", "16", "16"]
    one = tmp_path / "one.png"
    subprocess.run([A5, *scene, "-output", str(one)], cwd=scenes_dir, check=True, capture_output=True, timeout=300)
    subprocess.run([A5MI, "animate", *anim, "-o", str(tmp_path / "frames1")], check=True, capture_output=True,
                   timeout=300)
    # a job a killed client of this folder left pending: the next client cancels it
    stale = slurm.run("sbatch", "--parsable", "--hold", f"--job-name={job_name(tmp_path / 'slurm')}",
                      "-o", "/dev/null", "--wrap", "sleep 600").strip()
    with start_slurm_client(SlurmOptions(jobs=2, memory="1GB"), tmp_path / "slurm", security=security) as client:
        assert slurm.job_state(stale) == "CANCELLED"
        client.wait_for_workers(2, timeout=300)
        address = client.scheduler.address
        assert address.startswith("tls://127.0.0.1:")
        jobs = set(client.run(lambda: os.environ.get("SLURM_JOB_ID")).values())
        assert len(jobs) == 2 and jobs <= set(slurm.jobs())  # each worker is one of this cluster's jobs
        pids = {os.getpid(), *(p.pid for p in slurm.procs), *slurm.descendants()}
        listening = [c for c in psutil.net_connections("tcp") if c.status == psutil.CONN_LISTEN and c.pid in pids]
        assert len(listening) >= 2 + 1 + 4 and all(c.laddr.ip == "127.0.0.1" for c in listening), listening
        with pytest.raises(OSError):
            Client(address, timeout=3, security=Security.temporary())
        split = tmp_path / "split.png"
        r = subprocess.run([A5, *scene, "-output", str(split), "-scheduler", address, *tls], cwd=scenes_dir,
                           capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, r.stderr[-2000:]
        r = subprocess.run([A5MI, "animate", *anim, "-o", str(tmp_path / "frames2"), "--scheduler", address,
                            "--tls-ca", ca, "--tls-cert", cert, "--tls-key", key],
                           capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, r.stderr[-2000:]
        served = client.run(lambda: os.environ.get("SLURM_JOB_ID"))
        assert set(served.values()) <= set(slurm.jobs())
    assert (read_uint8(one) == read_uint8(split)).all()
    names = sorted(p.name for p in (tmp_path / "frames1").glob("frame_*.png"))
    assert len(names) == 2 and names == sorted(p.name for p in (tmp_path / "frames2").glob("frame_*.png"))
    for n in names:
        assert (read_uint8(tmp_path / "frames1" / n) == read_uint8(tmp_path / "frames2" / n)).all(), n
    _assert_ended(slurm)

"""A hostile class (tests/hostile.py) graded by ``a5mi grade`` and run through ``difftest``'s runner.

With bubblewrap every attack is blocked or refused and every honest student is graded right; without it
(``A5MI_NO_BWRAP=1``: the lookup finds no bwrap) executables are refused unless ``--no-sandbox``, which is
loud, and the output checks (links, FIFO, sizes) still hold. One case, 20 x 20, no jitter; about a minute.
"""

from __future__ import annotations

import json
import os
import secrets
import shutil
import socket
import subprocess
import sys
import tempfile
import threading
from pathlib import Path

import numpy as np
import pytest
from hostile import Expect, host_tmp, make_class, sandbox_processes

from a5mi.sandbox.bwrap import UID_BASE, isolation

pytestmark = pytest.mark.skipif(shutil.which("bwrap") is None, reason="make setup installs bubblewrap")

OUTPUT = "11.tga"
CASES = f'[[case]]\ncommand = "-input scene11_cube.txt -size 20 20 -output {OUTPUT} -shadows -bounces 2"\n'


class Listener:
    """A TCP port on 127.0.0.1 that records every connection it accepts."""

    def __init__(self) -> None:
        self.sock = socket.socket()
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen(8)
        self.sock.settimeout(0.2)
        self.port = self.sock.getsockname()[1]
        self.accepted: list[object] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                conn, addr = self.sock.accept()
                self.accepted.append(addr)
                conn.close()
            except OSError:
                pass

    def close(self) -> None:
        self._stop.set()
        self._thread.join()
        self.sock.close()



@pytest.fixture(scope="module")
def klass(scenes_dir):
    """The class folder, its expectations, the secrets, the listener and the reference."""
    # not under pytest's /tmp/pytest-of-USER, which every pytest session makes 0700 again: without bubblewrap the
    # run's user id must reach the submissions through the host's folders
    root = Path(tempfile.mkdtemp(prefix="a5mi-hostile-", dir="/tmp"))
    root.chmod(0o755)
    (root / "cases.toml").write_text(CASES)
    from a5mi.commands.grade import _options_of
    from a5mi.grade.cases import load_cases
    from a5mi.grade.references import build_reference
    from a5mi.platform.imageio import write_image

    case = load_cases(root / "cases.toml", _options_of)[0]
    ref = build_reference(scenes_dir / case.scene, case.options, root / "cache")
    levels, _ = ref.load()
    write_image(root / "good.tga", (levels + 0.5) / 255)
    write_image(root / "wrong.tga", (255 - levels + 0.5) / 255)
    home = root / "home"  # the grader's home, with a readable secret
    home.mkdir(mode=0o755)
    token = secrets.token_hex(16)
    (home / ".netrc").write_text(f"machine example.org password {token}\n")
    (home / ".netrc").chmod(0o644)
    outside = root / "outside"
    outside.mkdir()
    outside.chmod(0o777)
    listener = Listener()
    from a5mi import PROJECT_ROOT

    checkout = PROJECT_ROOT / "pyproject.toml"
    expect = make_class(root / "subs", output=OUTPUT, good=(root / "good.tga").read_bytes(),
                        wrong=(root / "wrong.tga").read_bytes(), reference=Path(ref.image_path),
                        secrets={"home": home / ".netrc", "checkout": checkout}, outside=outside,
                        port=listener.port)
    shadow = Path("/etc/shadow").read_text().splitlines()[0]
    yield {"root": root, "expect": expect, "token": token, "shadow": shadow, "listener": listener,
           "outside": outside, "home": home, "checkout": checkout.read_text().splitlines()[0], "levels": levels}
    listener.close()
    shutil.rmtree(root, ignore_errors=True)


def _grade(klass: dict, report: Path, *more: str) -> int:
    from a5mi.cli import run_a5mi

    root = klass["root"]
    return run_a5mi(["grade", str(root / "subs"), "-o", str(report), "--cases", str(root / "cases.toml"),
                     "--workers", "2", "--cache", str(root / "cache"), "--timeout", "4", "--memory", "1024",
                     "--disk", "64", "--inodes", "2048", "--no-flip", *more])


def _records(report: Path) -> dict[str, dict]:
    doc = json.loads((report / "results.json").read_text())
    return {r["student"]: r for r in doc["results"]}


def _check_all(recs: dict[str, dict], expect: dict[str, Expect], names: list[str] | None = None) -> None:
    """Every student of ``names`` (default all) got what ``expect`` says; lists every one that did not."""
    bad = []
    for name in names or list(expect):
        rec, exp = recs[name], expect[name]
        if rec["verdict"] not in exp.verdicts or exp.detail not in rec["detail"] or \
                not all(s in rec["stderr_tail"] for s in exp.stderr) or exp.cause not in rec.get("cause", ""):
            bad.append((name, rec["verdict"], rec["detail"], rec["stderr_tail"][-200:], rec.get("cause")))
    assert not bad, bad


def test_with_bubblewrap_every_attack_is_blocked(klass, monkeypatch, capsys) -> None:
    assert isolation() == "bwrap"
    monkeypatch.setenv("HOME", str(klass["home"]))
    report = klass["root"] / "report"
    assert _grade(klass, report) == 0
    recs = _records(report)
    assert set(recs) == set(klass["expect"])
    _check_all(recs, klass["expect"])
    everything = (report / "results.json").read_text() + (report / "report.html").read_text()
    for secret in (klass["token"], klass["shadow"], klass["checkout"]):
        assert secret not in everything
    assert recs["secrets"]["stderr_tail"].count("No such file or directory") == 3  # home, checkout, shadow
    for p in (klass["outside"] / "pwned", klass["root"] / "subs" / "athome" / "pwned",
              klass["root"] / "subs" / "pwned", host_tmp(klass["listener"].port),
              klass["root"] / "subs" / "pwned-remount"):
        assert not p.exists(), p
    assert not klass["listener"].accepted
    assert "Operation not permitted" in recs["killer"]["stderr_tail"] or recs["killer"]["verdict"] == "crash"
    assert not sandbox_processes([r.get("uid") for r in recs.values()])
    assert "(sandbox: bwrap)" in capsys.readouterr().err


def test_without_bubblewrap_executables_are_refused_unless_asked(klass, monkeypatch, capsys) -> None:
    monkeypatch.setenv("A5MI_NO_BWRAP", "1")
    monkeypatch.setenv("HOME", str(klass["home"]))
    report = klass["root"] / "report-nobwrap"
    assert _grade(klass, report) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "apt-get install bubblewrap" in err[0] and "--no-sandbox" in err[0]
    assert not report.exists() or not (report / "results.json").exists()

    assert _grade(klass, report, "--no-sandbox") == 0
    err = capsys.readouterr().err
    assert "WARNING: --no-sandbox" in err and "NOT SANDBOXED" in err
    assert "NOT SANDBOXED" in (report / "report.html").read_text()
    recs = _records(report)
    # what does not depend on bubblewrap: the honest students, and every output that is not a regular file
    # the program wrote (links, hard links, FIFO), too large to decode, or not an image
    _check_all(recs, klass["expect"], ["good", "mktemp", "wrongimg", "athome", "symref", "symmate", "hardlink",
                                       "huge", "bomb", "fifo", "shadowlink", "reflink", "hardcopy", "forkstorm",
                                       "diskfill", "inodes"])
    assert {r["isolation"] for r in recs.values() if "image" not in r["isolation"]} == {"rlimits"}
    assert not sandbox_processes([r.get("uid") for r in recs.values()])
    # unsandboxed, the network student reached the host's loopback, and the writer could write where its user
    # id may (a world-writable folder, the host's /tmp)
    klass["listener"].accepted.clear()
    for p in (klass["outside"] / "pwned", host_tmp(klass["listener"].port),
              Path(f"/tmp/a5mi-private-{klass['listener'].port}")):
        if p.exists() and p.stat().st_uid >= UID_BASE:
            p.unlink()


def test_difftest_runner_blocks_the_same_class(klass, tmp_path, monkeypatch) -> None:
    """Each executable student as ``difftest --binary``: the runner gives the same sandbox and output checks."""
    import a5mi.sandbox.bwrap as sandbox_module
    from a5mi.difftest.runner import Binary, run_binary

    uids: list[int | None] = []  # the user ids of these runs: only their processes are looked at
    fresh = sandbox_module.fresh_uid
    monkeypatch.setattr(sandbox_module, "fresh_uid", lambda: uids.append(fresh()) or uids[-1])
    base = tmp_path / "dt"
    base.mkdir()
    for p in (tmp_path, base):
        p.chmod(0o755)
    subs = klass["root"] / "subs"
    for name, exp in klass["expect"].items():
        exe = subs / name / "a5"
        if not exe.exists() or exp.verdicts == ("over disk",):  # difftest's folder is not a tmpfs (GRADING.md)
            continue
        folder = base / name
        folder.mkdir()
        (folder / "scene.txt").write_text("PerspectiveCamera { }\n")
        img, status = run_binary(Binary(exe), folder, [], timeout=4)
        v = exp.verdicts[0]
        if v in ("match", "wrong"):
            assert status == "ok", (name, status)
            assert img is not None and img.shape == klass["levels"].shape
            assert (np.array_equal(img, klass["levels"])) == (v == "match"), name
        elif v == "unreadable" and exp.detail:
            assert status == f"binary failed: out.bmp: {exp.detail.split(': ', 1)[1]}", (name, status)
        elif v == "wrong size":
            assert status == f"binary failed: out.bmp: image size {exp.detail} (not decoded)", (name, status)
        elif v == "timeout":
            assert status in ("timeout", "binary failed: ") or status.startswith("binary failed: "), (name, status)
        else:
            assert status.startswith("binary failed: "), (name, status)
        for secret in (klass["token"], klass["shadow"], klass["checkout"]):
            assert secret not in status
    for p in (klass["outside"] / "pwned", subs / "athome" / "pwned", host_tmp(klass["listener"].port)):
        assert not p.exists(), p
    assert not klass["listener"].accepted
    assert uids and not sandbox_processes(uids)


def test_difftest_cli_refuses_without_bubblewrap(klass, tmp_path) -> None:
    a5mi = shutil.which("a5mi", path=str(Path(sys.executable).parent))
    assert a5mi is not None
    exe = klass["root"] / "subs" / "secrets" / "a5"
    env = {**os.environ, "A5MI_NO_BWRAP": "1"}
    proc = subprocess.run([a5mi, "difftest", "--binary", str(exe), "--count", "1", "--mean-size", "20"], env=env,
                          capture_output=True, text=True, timeout=120, check=False)
    assert proc.returncode == 2 and len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    assert "apt-get install bubblewrap" in proc.stderr and "--no-sandbox" in proc.stderr
    proc = subprocess.run([a5mi, "difftest", "--binary", str(exe), "--count", "1", "--mean-size", "20"],
                          capture_output=True, text=True, timeout=300, check=False)
    assert "binary failed" in proc.stdout, proc.stdout + proc.stderr
    for secret in (klass["token"], klass["shadow"], klass["checkout"]):
        assert secret not in proc.stdout + proc.stderr

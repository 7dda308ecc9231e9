"""a5mi.sandbox.bwrap (the sandbox of grade and difftest): every guarantee proved by a hostile fake submission.

Each fake is a small script in tmp_path graded through :func:`a5mi.grade.run.grade_one` against a tiny
reference (no rendering): it must end in its verdict within seconds, with nothing written outside its private
folder and no process of it left behind. bubblewrap is installed by ``make setup``; the rlimit fallback is
tested with ``A5MI_NO_BWRAP=1`` (``docs/GRADING.md`` "Threat model").
"""

from __future__ import annotations

import os
import socket
import stat
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from hostile import check_confined, confinement_probe, sandbox_processes

from a5mi.grade.cases import make_case
from a5mi.grade.run import Task, grade_one
from a5mi.platform.imageio import write_image
from a5mi.sandbox.bwrap import NOT_SANDBOXED, isolation, run_sandboxed
from a5mi.sandbox.records import Limits, SandboxUnavailable

LIMITS = Limits(timeout=3.0, memory_mb=512, nproc=48, keep_bytes=4096)



@pytest.fixture
def world(tmp_path):
    """A class folder (0755, so the sandbox's user id can read it), a scenes folder, a reference."""
    root = tmp_path / "w"
    for d in ("subs", "scenes", "report", "work", "outside"):
        (root / d).mkdir(parents=True)
    for p in (tmp_path, root, *root.iterdir()):
        p.chmod(0o755)
    (root / "scenes" / "s.txt").write_text("PerspectiveCamera { }\n")
    write_image(root / "ref.png", np.full((4, 4, 3), 0.5))
    np.save(root / "sigma.npy", np.zeros((4, 4, 3), dtype=np.float32))
    return root


def _student(world: Path, name: str, script: str) -> Path:
    d = world / "subs" / name
    d.mkdir()
    d.chmod(0o755)
    exe = d / "a5"
    exe.write_text(script)
    exe.chmod(0o755)
    return d


def _grade(world: Path, name: str, script: str, limits: Limits = LIMITS) -> dict:
    sub = _student(world, name, script)
    case = make_case("-input s.txt -size 4 4 -output out.png", points=10)
    task = Task(name, str(sub), case, str(world / "scenes"), str(world / "ref.png"), str(world / "sigma.npy"),
                str(world / "work"), str(world / "report"), limits)
    t0 = time.perf_counter()
    rec = grade_one(task)
    rec["elapsed"] = time.perf_counter() - t0
    assert rec.get("uid") is not None or os.geteuid() != 0
    assert not sandbox_processes(rec.get("uid")), "a sandboxed process survived its run"
    return rec


PY = "#!/usr/bin/python3\n"


def test_bubblewrap_is_used_here() -> None:
    assert isolation() == "bwrap"  # make setup installs it; the guarantees below are the bwrap ones


def test_writes_outside_its_folder_fail(world) -> None:
    victim = world / "subs" / "victim"
    victim.mkdir()
    targets = [world / "outside" / "pwned", victim / "pwned", world / "scenes" / "pwned", world / "ref.png",
               Path("/tmp") / f"pwned-{os.getpid()}", world / "report" / "pwned"]
    script = PY + f"""import sys
ok = []
for t in {[str(t) for t in targets]!r}:
    try:
        with open(t, "w") as f:
            f.write("x")
        ok.append(t)
    except OSError as exc:
        print("refused", t, exc.strerror, file=sys.stderr)
open("mine.txt", "w").write("inside is fine")
print("WROTE", ok, file=sys.stderr)
"""
    before = (world / "ref.png").read_bytes()
    rec = _grade(world, "writer", script)
    assert rec["verdict"] == "no output"
    # only the private /tmp of the run is writable: the host's /tmp is untouched
    assert "refused" in rec["stderr_tail"] and f"WROTE [{str(targets[4])!r}]" in rec["stderr_tail"]
    for t in targets[:3] + targets[4:]:
        assert not t.exists(), t
    assert (world / "ref.png").read_bytes() == before


def test_socket_cannot_reach_the_host(world) -> None:
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(1)
    server.settimeout(0.2)
    port = server.getsockname()[1]
    got: list[object] = []
    graded = threading.Event()

    def accept() -> None:
        while not graded.is_set() and not got:
            try:
                got.append(server.accept())
            except OSError:
                pass

    t = threading.Thread(target=accept)
    t.start()
    script = PY + f"""import socket, sys
try:
    socket.create_connection(("127.0.0.1", {port}), timeout=1)
    print("CONNECTED", file=sys.stderr)
except OSError as exc:
    print("no network:", exc, file=sys.stderr)
    sys.exit(3)
"""
    rec = _grade(world, "net", script)
    graded.set()
    t.join()
    server.close()
    assert rec["verdict"] == "crash" and rec["detail"] == "exit status 3"
    assert "no network" in rec["stderr_tail"] and not got


def test_fork_bomb_is_bounded_and_cleaned_up(world) -> None:
    script = PY + """import os, sys
n = 0
while True:
    try:
        if os.fork() == 0:
            n = 0
        else:
            n += 1
    except OSError:
        pass
"""
    rec = _grade(world, "forkbomb", script)
    # ended at its CPU bound (all its processes together) or its wall backstop; the CPU it used past the bound
    # is at most what the machine's CPUs give between two polls of its cgroup (0.5 s), plus the kill
    assert rec["verdict"] == "timeout" and rec["ended_by"] in ("cpu", "wall")
    assert rec["cpu"] < LIMITS.cpu + 0.6 * (os.cpu_count() or 1) + 1


def test_twenty_gigabytes_end_over_memory(world) -> None:
    script = PY + "buf = bytearray(20 << 30)\nprint(len(buf))\n"
    rec = _grade(world, "hog", script)
    assert rec["verdict"] == "over memory" and rec["cpu"] < 2  # refused at once: CPU time, not a clock under load
    assert "MemoryError" in rec["stderr_tail"] and "512 MB" in rec["detail"]


def test_sleep_forever_times_out(world) -> None:
    rec = _grade(world, "sleeper", "#!/bin/sh\nsleep 100000 & sleep 100000\n")
    # the backstop counts wall time minus the time the run waited for a CPU (its start-up on a busy machine)
    assert rec["verdict"] == "timeout" and rec["ended_by"] == "wall"
    assert LIMITS.timeout <= rec["elapsed"] and rec["elapsed"] - rec["waited"] < LIMITS.timeout + 3


def test_one_gigabyte_of_stdout_is_drained_not_kept(world) -> None:
    script = PY + """import sys
chunk = b"x" * (1 << 20)
for _ in range(1024):
    sys.stdout.buffer.write(chunk)
sys.stderr.write("done printing\\n")
"""
    rec = _grade(world, "printer", script, Limits(timeout=20.0, memory_mb=512, keep_bytes=4096))
    assert rec["verdict"] == "no output" and rec["stdout_bytes"] == 1 << 30
    assert rec["stderr_tail"] == "done printing\n"


def test_the_capped_reader_keeps_head_and_tail_only(tmp_path) -> None:
    work = tmp_path / "w"
    work.mkdir()
    r = run_sandboxed(["/bin/sh", "-c", "seq 1 200000; seq 1 200000 >&2"], work, Limits(timeout=10, keep_bytes=64))
    assert r.returncode == 0 and len(r.stdout_head) == 64 and r.stdout_head.startswith("1\n2\n3\n")
    assert len(r.stderr_tail) == 64 and r.stderr_tail.endswith("199999\n200000\n")
    assert r.stdout_bytes == r.stderr_bytes > 1_000_000


def test_environment_is_scrubbed_and_the_pid_namespace_fresh(tmp_path, monkeypatch) -> None:
    monkeypatch.setenv("SECRET_TOKEN", "hunter2")
    work = tmp_path / "w"
    work.mkdir()
    r = run_sandboxed(["/bin/sh", "-c", "env; echo pid=$$; ls /proc | grep -c '^[0-9]'; ls /"], work, LIMITS)
    assert "hunter2" not in r.stdout_head and f"HOME={work}" in r.stdout_head
    # the fresh PID namespace: bwrap's init is 1, the unprivileged bwrap (as root: after setpriv) 2, the run 3
    assert ("pid=3" if r.uid is not None else "pid=2") in r.stdout_head
    assert "root\n" not in r.stdout_head and "work\n" not in r.stdout_head.split("pid=")[1]


def test_fallback_without_bubblewrap_still_bounds_and_cleans(monkeypatch) -> None:
    """--no-sandbox (``require_sandbox`` off): rlimits + own user id + process group: the fork bomb, the sleeper
    and the hog end in their verdicts."""
    monkeypatch.setenv("A5MI_NO_BWRAP", "1")
    assert isolation() == NOT_SANDBOXED
    limits = Limits(timeout=3.0, memory_mb=512, nproc=48, keep_bytes=4096, require_sandbox=False)
    base = Path(tempfile.mkdtemp(prefix="a5mi-fallback-", dir="/tmp"))
    try:
        base.chmod(0o755)
        for d in ("subs", "scenes", "report", "work", "outside"):
            (base / d).mkdir()
            (base / d).chmod(0o755)
        (base / "scenes" / "s.txt").write_text("x\n")
        write_image(base / "ref.png", np.full((4, 4, 3), 0.5))
        np.save(base / "sigma.npy", np.zeros((4, 4, 3), dtype=np.float32))
        bomb = _grade(base, "bomb", "#!/bin/sh\nwhile :; do sleep 1000 & done\n", limits)
        assert bomb["verdict"] == "timeout" and bomb["isolation"] == "rlimits"
        hog = _grade(base, "hog", PY + "bytearray(20 << 30)\n", limits)
        assert hog["verdict"] == "over memory"
        outside = base / "outside" / "pwned"
        writer = _grade(base, "writer", f"#!/bin/sh\necho x > {outside}; echo x > out.png\n", limits)
        assert not outside.exists() and writer["verdict"] == "unreadable"
        assert stat.S_IMODE((base / "outside").stat().st_mode) == 0o755
    finally:
        import shutil

        shutil.rmtree(base, ignore_errors=True)


def test_a_run_is_unprivileged_confined_and_cannot_unshare(tmp_path) -> None:
    """No secret, no capability, no user namespace, no remount, no write outside, no network: each attempt is
    made by one program in the sandbox (the one ``grade`` and ``difftest`` share)."""
    outside = tmp_path / "outside"
    outside.mkdir(mode=0o777)
    outside.chmod(0o777)
    listener = socket.socket()
    listener.bind(("127.0.0.1", 0))
    listener.listen(1)
    work = tmp_path / "w"
    work.mkdir()
    (tmp_path / "bin").mkdir(mode=0o755)
    exe = tmp_path / "bin" / "probe"
    exe.write_text(confinement_probe(outside, listener.getsockname()[1]))
    exe.chmod(0o755)
    r = run_sandboxed([str(exe)], work, LIMITS, read_only=[str(tmp_path / "bin")])
    import json

    assert r.returncode == 0, r.stderr_tail
    check_confined(json.loads(r.stdout_head), listener)
    assert not (outside / "pwned").exists()
    listener.close()


def test_without_bubblewrap_a_run_is_refused_unless_asked(monkeypatch, tmp_path) -> None:
    monkeypatch.setenv("A5MI_NO_BWRAP", "1")
    with pytest.raises(SandboxUnavailable, match=r"apt-get install bubblewrap\) or pass --no-sandbox"):
        run_sandboxed(["/bin/true"], tmp_path, LIMITS)
    r = run_sandboxed(["/bin/true"], tmp_path, Limits(timeout=3.0, require_sandbox=False))
    assert r.returncode == 0 and r.isolation == "rlimits"


@pytest.mark.parametrize("reserved_gb", [0, 3])
def test_without_bubblewrap_images_are_still_decoded_unprivileged(monkeypatch, tmp_path, reserved_gb) -> None:
    """An image submission needs no sandbox to run: without bubblewrap its image is decoded by a forked child
    under the rlimits and its own user id, and graded; also from a grader whose address space is already past
    the decoder's 2 GB bound (a worker after renders: ``reserved_gb`` of untouched address space) and whose
    TMPDIR the run's user id cannot enter."""
    import mmap

    monkeypatch.setenv("A5MI_NO_BWRAP", "1")
    private = tmp_path / "private"
    private.mkdir(mode=0o700)
    monkeypatch.setattr(tempfile, "tempdir", str(private))
    reserve = mmap.mmap(-1, reserved_gb << 30) if reserved_gb else None
    base = Path(tempfile.mkdtemp(prefix="a5mi-nobwrap-", dir="/tmp"))
    try:
        base.chmod(0o755)
        for d in ("subs/home", "scenes", "report", "work"):
            (base / d).mkdir(parents=True)
            (base / d).chmod(0o755)
        (base / "scenes" / "s.txt").write_text("x\n")
        write_image(base / "ref.png", np.full((4, 4, 3), 0.5))
        np.save(base / "sigma.npy", np.zeros((4, 4, 3), dtype=np.float32))
        (base / "subs" / "home" / "out.png").write_bytes((base / "ref.png").read_bytes())
        case = make_case("-input s.txt -size 4 4 -output out.png", points=10)
        task = Task("home", str(base / "subs" / "home"), case, str(base / "scenes"), str(base / "ref.png"),
                    str(base / "sigma.npy"), str(base / "work"), str(base / "report"), LIMITS)
        rec = grade_one(task)
        assert rec["verdict"] == "match", rec["detail"]
    finally:
        import shutil

        shutil.rmtree(base, ignore_errors=True)
        if reserve is not None:
            reserve.close()


def test_mktemp_and_an_absolute_home_work_with_a_relative_work_root(world, monkeypatch) -> None:
    """A correct program that uses ``mktemp`` and ``$HOME`` gets its points, also when the report folder
    (where the work folders are) was given as a relative path."""
    import base64

    png = base64.encodebytes((world / "ref.png").read_bytes()).decode()
    script = ('#!/bin/sh\nt=$(mktemp) || exit 7\ncase "$HOME" in /*) ;; *) exit 8;; esac\n'
              'echo cached > "$HOME/.cache-file" || exit 9\n'
              f"base64 -d > \"$t\" <<'EOF'\n{png}EOF\nmv \"$t\" out.png\n")
    sub = _student(world, "tmpuser", script)
    monkeypatch.chdir(world)
    case = make_case("-input s.txt -size 4 4 -output out.png", points=10)
    task = Task("tmpuser", str(sub), case, "scenes", str(world / "ref.png"), str(world / "sigma.npy"), "work",
                "report", LIMITS)
    rec = grade_one(task)
    assert rec["verdict"] == "match", (rec["detail"], rec["stderr_tail"])


def _link_student(world: Path, name: str, script: str) -> dict:
    return _grade(world, name, "#!/bin/sh\n" + script)


def test_only_a_regular_file_the_run_wrote_is_taken(world) -> None:
    """A symbolic link to the reference or to a classmate's image, a hard link, a FIFO: refused without reading
    a byte of them (the reference link earned a 'match' before)."""
    import base64

    mate = world / "subs" / "mate"
    mate.mkdir()
    mate.chmod(0o755)
    (mate / "out.png").write_bytes((world / "ref.png").read_bytes())
    png = base64.encodebytes((world / "ref.png").read_bytes()).decode()
    got = {name: _link_student(world, name, script) for name, script in {
        "symref": f"ln -s {world / 'ref.png'} out.png\n",
        "symmate": f"ln -s {mate / 'out.png'} out.png\n",
        "hardlink": f"base64 -d > mine <<'EOF'\n{png}EOF\nln mine out.png\n",
        "fifo": "mkfifo out.png\n",
    }.items()}
    assert {n: (r["verdict"], r["detail"]) for n, r in got.items()} == {
        "symref": ("unreadable", "out.png: not a regular file (a symbolic link)"),
        "symmate": ("unreadable", "out.png: not a regular file (a symbolic link)"),
        "hardlink": ("unreadable", "out.png: a hard link (2 names for one file)"),
        "fifo": ("unreadable", "out.png: not a regular file (a FIFO)")}


def test_an_image_folder_link_to_a_secret_is_not_read(world) -> None:
    """``out.png -> /etc/shadow`` in an image submission: refused as a link; no byte of it reaches the record."""
    d = world / "subs" / "linker"
    d.mkdir()
    d.chmod(0o755)
    (d / "out.png").symlink_to("/etc/shadow")
    case = make_case("-input s.txt -size 4 4 -output out.png", points=10)
    task = Task("linker", str(d), case, str(world / "scenes"), str(world / "ref.png"), str(world / "sigma.npy"),
                str(world / "work"), str(world / "report"), LIMITS)
    rec = grade_one(task)
    assert (rec["verdict"], rec["detail"]) == ("unreadable", "out.png: not a regular file (a symbolic link)")


def test_a_decompression_bomb_is_not_decoded(world) -> None:
    """A valid 8000 x 8000 PNG of 8 KB (1.5 GB as levels): ``wrong size`` from its header alone."""
    from hostile import png_bomb

    d = world / "subs" / "bomb"
    d.mkdir()
    d.chmod(0o755)
    (d / "out.png").write_bytes(png_bomb(8000))
    case = make_case("-input s.txt -size 4 4 -output out.png", points=10)
    task = Task("bomb", str(d), case, str(world / "scenes"), str(world / "ref.png"), str(world / "sigma.npy"),
                str(world / "work"), str(world / "report"), LIMITS)
    rec = grade_one(task)
    assert (rec["verdict"], rec["detail"]) == ("wrong size", "8000x8000, expected 4x4 (not decoded)")

"""SIGINT, SIGTERM and SIGHUP at any moment end with one line and 128 + signal (ExitStatus.signal), write
nothing and leave no temporary; a render that never ends (a glass ray tree at -bounces 64) stops soon after."""

from __future__ import annotations

import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

A5 = [sys.executable, "-m", "a5mi"]

#: A glass sphere between two mirrors: at -bounces 64 the ray tree has ~2^64 leaves (it never finishes).
ENDLESS = """PerspectiveCamera { center 0 0 0 direction 0 0 -1 up 0 1 0 angle 30 }
Lights { numLights 1 PointLight { position 0 0.5 0 color 1 1 1 } }
Background { color 0.2 0 0.6 ambientLight 0.1 0.1 0.1 }
Materials { numMaterials 2
 Material { diffuseColor 0.1 0.1 0.1 specularColor 0.9 0.9 0.9 }
 Material { diffuseColor 0.1 0.1 0.1 specularColor 0.5 0.5 0.5 refractionIndex 1.5 } }
Group { numObjects 3 MaterialIndex 0
 Plane { normal 0 0 1 offset -5 } Plane { normal 0 0 -1 offset -5 }
 MaterialIndex 1 Sphere { center 0 0 -3 radius 1 } }
"""
SMALL = """PerspectiveCamera { center 0 0 10 direction 0 0 -1 up 0 1 0 angle 20 }
Lights { numLights 1 DirectionalLight { direction -0.2 -0.2 -1 color 1 1 1 } }
Materials { numMaterials 1 Material { diffuseColor 1 0 0 } }
Group { numObjects 1 MaterialIndex 0 Sphere { center 0 0 0 radius 1 } }
"""


def _hangup_default() -> None:
    """In the child before exec: SIGHUP back to its default. Under ``nohup make test`` the children inherit an
    ignored SIGHUP, which a5mi rightly keeps ignoring (a5mi/platform/interrupts.py), so the hang-up cases would
    test nohup instead of the hang-up."""
    signal.signal(signal.SIGHUP, signal.SIG_DFL)


def _start(tmp_path: Path, text: str, *flags: str) -> subprocess.Popen[bytes]:
    (tmp_path / "s.txt").write_text(text)
    return subprocess.Popen([*A5, "-input", "s.txt", "-output", "o.png", *flags], cwd=tmp_path,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, preexec_fn=_hangup_default)


def _leftovers(tmp_path: Path) -> list[str]:
    return sorted(p.name for p in tmp_path.iterdir() if p.name not in ("s.txt",))


def _cpu_seconds(pid: int) -> float:
    """User + system CPU seconds of a running process, all its threads (``/proc/PID/stat`` fields 14, 15)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


@pytest.fixture(scope="module")
def reference_render(tmp_path_factory: pytest.TempPathFactory) -> tuple[float, float]:
    """The machine's pace, measured now (under whatever load it has): the wall and CPU seconds of the ENDLESS
    scene rendered to the end at ``-bounces 1`` (start-up, parse, build, the kernel's compilation or cache
    load, one render)."""
    import resource

    run = tmp_path_factory.mktemp("reference")
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.monotonic()
    p = _start(run, ENDLESS, "-size", "60", "60", "-bounces", "1")
    p.communicate(timeout=600)
    wall = time.monotonic() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    assert p.returncode == 0
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM, signal.SIGHUP], ids=lambda s: s.name)
def test_endless_render_stops_soon_after_a_signal(tmp_path: Path, sig: signal.Signals,
                                                  reference_render: tuple[float, float]) -> None:
    """Inside one kernel that never returns, the watchdog ends the process about GRACE (1 s) after the signal:
    one line, 128 + signal, no output. The signal is sent once the process has used twice the CPU time of the
    whole reference render (so it is inside the endless kernel, however busy the machine); the bounds are
    hang checks scaled to the reference's wall time, measured under the same load."""
    ref_wall, ref_cpu = reference_render
    p = _start(tmp_path, ENDLESS, "-size", "60", "60", "-bounces", "64", "-force")  # over the work estimate
    t0 = time.monotonic()
    while _cpu_seconds(p.pid) < 2 * ref_cpu + 0.5:
        assert p.poll() is None
        assert time.monotonic() - t0 < 60 + 30 * ref_wall, "the endless render used no CPU: a hang before it"
        time.sleep(0.05)
    t0 = time.monotonic()
    p.send_signal(sig)
    _, err = p.communicate(timeout=60 + 30 * ref_wall)
    assert time.monotonic() - t0 < 10 + 5 * ref_wall
    assert p.returncode == 128 + sig, err.decode()
    lines = err.decode().splitlines()
    assert len(lines) == 2 and ": warning: this render may trace up to " in lines[0], lines  # -force: warned
    assert lines[1:] == [f"a5: error: interrupted ({sig.name})"]
    assert _leftovers(tmp_path) == []


def _group(pgid: int) -> dict[int, float]:
    """The processes of process group ``pgid`` (the test's own session) and their CPU seconds."""
    found = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[2]) == pgid:
                found[int(entry.name)] = (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    return found


def test_ctrl_c_of_a_split_render_ends_its_workers_with_one_line(tmp_path: Path,
                                                                 reference_render: tuple[float, float]) -> None:
    """``a5 -workers 2`` and a terminal's Ctrl-C, which reaches the whole foreground process group (the
    command, its two Dask worker processes and the resource tracker): the command alone reports it, closes its
    cluster and ends with one line and 130; no worker traceback or second line, no Dask exit-hook traceback,
    no "leaked semaphore" warning, and nothing of its process group is left. The signal comes once the workers
    have used the CPU time of the whole reference render (they are rendering, however busy the machine)."""
    ref_wall, ref_cpu = reference_render
    (tmp_path / "s.txt").write_text(ENDLESS)
    p = subprocess.Popen([*A5, "-input", "s.txt", "-output", "o.png", "-size", "60", "60", "-bounces", "64",
                          "-force", "-workers", "2"], cwd=tmp_path, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, start_new_session=True)
    t0 = time.monotonic()
    while True:
        workers = {pid: cpu for pid, cpu in _group(p.pid).items() if pid != p.pid}
        if len(workers) >= 3 and sum(sorted(workers.values())[-2:]) > 2 * ref_cpu + 0.5:
            break
        assert p.poll() is None, p.communicate()[1].decode()
        assert time.monotonic() - t0 < 120 + 60 * ref_wall, "the workers used no CPU: a hang before the render"
        time.sleep(0.1)
    os.killpg(p.pid, signal.SIGINT)
    _, err = p.communicate(timeout=120 + 30 * ref_wall)
    lines = err.decode().splitlines()
    assert p.returncode == 130, err.decode()
    assert len(lines) == 2 and ": warning: this render may trace up to " in lines[0], lines
    assert lines[1:] == ["a5: error: interrupted (SIGINT)"]
    deadline = time.monotonic() + 30 + 10 * ref_wall  # the resource tracker ends after its last client
    while _group(p.pid) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert _group(p.pid) == {}
    assert _leftovers(tmp_path) == []


@pytest.mark.slow
def test_sigint_at_random_moments(tmp_path: Path) -> None:
    """SIGINT at random moments of a short render (seeded): each run either finished before the signal
    (exit 0, a complete image), or ends with 130, one line and no file; never a traceback or an abort. A
    signal before the interpreter has installed any handler kills it (-2, nothing printed, nothing written)."""
    rng = random.Random(19)
    seen: dict[int, int] = {}
    for k in range(10):
        run = tmp_path / f"r{k}"
        run.mkdir()
        p = _start(run, SMALL, "-size", "40", "40")
        time.sleep(rng.uniform(0.0, 1.6))
        p.send_signal(signal.SIGINT)
        _, err = p.communicate(timeout=60)
        lines = err.decode().splitlines()
        seen[p.returncode] = seen.get(p.returncode, 0) + 1
        if p.returncode == 0:
            assert lines == [] and _leftovers(run) == ["o.png"]
        elif p.returncode == 130:
            assert lines == ["a5: error: interrupted (SIGINT)"] and _leftovers(run) == []
        else:
            assert p.returncode == -signal.SIGINT and lines == [] and _leftovers(run) == [], (p.returncode, lines)
    assert seen.get(130, 0) >= 3, seen


WRITER = r"""
import os, signal, sys, threading
import numpy as np
from a5mi.platform import imageio, interrupts
interrupts.install(lambda s: None)
img = np.random.default_rng(1).random((3000, 3000, 3), dtype=np.float32)
threading.Timer(0.3, lambda: os.kill(os.getpid(), signal.SIG{name})).start()
try:
    while True:
        imageio.write_images([(sys.argv[1], img), (sys.argv[2], img)])
except interrupts.Interrupted as exc:
    print(exc.status)
"""


@pytest.mark.parametrize("name", ["TERM", "HUP", "INT"])
def test_signal_during_the_atomic_write_leaves_no_temporary(tmp_path: Path, name: str) -> None:
    """A signal while the images are written: the write is finished or undone (never a partial target), the
    temporaries are removed, and the program sees the signal after it."""
    out = [str(tmp_path / "a.exr"), str(tmp_path / "b.png")]
    p = subprocess.run([sys.executable, "-c", WRITER.replace("{name}", name), *out], capture_output=True,
                       text=True, timeout=120, preexec_fn=_hangup_default)
    assert p.stdout.strip() == str(128 + getattr(signal, f"SIG{name}")), p.stderr
    names = sorted(os.listdir(tmp_path))
    assert all(not n.startswith(".") for n in names), names
    for path in out:
        if os.path.exists(path):
            from a5mi.platform import imageio

            assert imageio.read_image(path).shape == (3000, 3000, 3)


def test_closed_pipe_is_quiet(tmp_path: Path) -> None:
    """``a5 -h | true`` (the reader gone before the help is written) ends quietly with 141
    (128 + SIGPIPE), no BrokenPipeError. The pipe's read end is closed before the command starts."""
    r, w = os.pipe()
    os.close(r)
    try:
        p = subprocess.run([*A5, "-h"], stdout=w, stderr=subprocess.PIPE, cwd=tmp_path, timeout=60)
    finally:
        os.close(w)
    assert p.returncode == 141 and p.stderr == b""


# ------------------------------------------------------------------------------------------ standard streams
A5MI = [sys.executable, "-c", "from a5mi.entry import a5mi; a5mi()"]
#: SMALL with a '}' glued to a number: a warning is printed on stderr before the render.
WARNS = SMALL.replace("radius 1 }", "radius 1}")


def _closing(fd: int):
    return lambda: os.close(fd)


@pytest.mark.parametrize("stderr", ["closed", "full"])
def test_a_diagnostic_that_cannot_be_printed_never_costs_the_image(tmp_path: Path, stderr: str) -> None:
    """``a5 ... 2>&-`` and ``2>/dev/full``: the warning is lost, the image is written, exit 0."""
    (tmp_path / "s.txt").write_text(WARNS)
    argv = [*A5, "-input", "s.txt", "-output", "o.png", "-size", "8", "8"]
    if stderr == "closed":
        p = subprocess.run(argv, cwd=tmp_path, stdout=subprocess.PIPE, preexec_fn=_closing(2), timeout=120)
    else:
        with open("/dev/full", "w") as full:
            p = subprocess.run(argv, cwd=tmp_path, stdout=subprocess.PIPE, stderr=full, timeout=120)
    assert p.returncode == 0 and p.stdout == b""
    assert (tmp_path / "o.png").stat().st_size > 0


@pytest.mark.parametrize("argv", [["-h"], ["--version"], ["compare", "-h"]])
def test_a5mi_into_a_closed_pipe_is_quiet(tmp_path: Path, argv: list[str]) -> None:
    """``a5mi -h | true``: 141 and nothing on stderr, as ``a5 -h | true``."""
    r, w = os.pipe()
    os.close(r)
    try:
        p = subprocess.run([*A5MI, *argv], stdout=w, stderr=subprocess.PIPE, cwd=tmp_path, timeout=60)
    finally:
        os.close(w)
    assert p.returncode == 141 and p.stderr == b""


@pytest.mark.parametrize("stdout", ["closed", "full"])
@pytest.mark.parametrize("argv", [["a5mi", "--version"], ["a5mi", "-h"], ["a5", "-h"]])
def test_a_result_that_cannot_be_written_is_one_line(tmp_path: Path, stdout: str, argv: list[str]) -> None:
    """stdout closed (``>&-``) or on ``/dev/full``: one line naming the cause and exit 2, no traceback."""
    cmd = [*(A5 if argv[0] == "a5" else A5MI), *argv[1:]]
    if stdout == "closed":
        p = subprocess.run(cmd, stderr=subprocess.PIPE, cwd=tmp_path, preexec_fn=_closing(1), timeout=60)
        reason = "Bad file descriptor"
    else:
        with open("/dev/full", "w") as full:
            p = subprocess.run(cmd, stdout=full, stderr=subprocess.PIPE, cwd=tmp_path, timeout=60)
        reason = "No space left on device"
    assert p.returncode == 2
    assert p.stderr.decode().splitlines() == [f"{argv[0]}: error: cannot write to standard output: {reason}"]


# ------------------------------------------------------------------------------------------ the earliest signals
EARLY = r"""
import os, signal, sys
if sys.argv[1] == "ignored":  # a shell's background job (cmd &) starts with SIGINT ignored
    signal.signal(signal.SIGINT, signal.SIG_IGN)


class SignalOnImport:  # the signal arrives while a5mi.entry imports a5mi.platform.interrupts
    def find_spec(self, name, path, target=None):
        if name == "a5mi.platform.interrupts":
            os.kill(os.getpid(), signal.SIGINT)
        return None


sys.meta_path.insert(0, SignalOnImport())
sys.argv = ["a5", "-input", "s.txt", "-output", "o.png", "-size", "8", "8"]
from a5mi.entry import a5
a5()
"""


@pytest.mark.parametrize("start", ["default", "ignored"])
def test_sigint_during_the_first_imports_is_130(tmp_path: Path, start: str) -> None:
    """A Ctrl-C while the console script imports its first modules (before a5mi.platform.interrupts is installed):
    recorded by the handler that is a5mi.entry's first statement and raised at the first check: one line,
    130, nothing written; also for a background job (SIGINT ignored at start, which a5 overrides)."""
    (tmp_path / "s.txt").write_text(SMALL)
    p = subprocess.run([sys.executable, "-c", EARLY, start], cwd=tmp_path, capture_output=True, text=True,
                       timeout=120)
    assert p.returncode == 130 and p.stderr.splitlines() == ["a5: error: interrupted (SIGINT)"], p.stderr
    assert _leftovers(tmp_path) == []


def test_a_hangup_ignored_by_nohup_stays_ignored() -> None:
    """``nohup a5 ...``: a hang-up the user asked to ignore is not turned into an interruption (SIGINT and SIGTERM
    are still handled)."""
    code = ("import os, signal, time; from a5mi.platform import interrupts; interrupts.install(lambda s: None); "
            "os.kill(os.getpid(), signal.SIGHUP); time.sleep(0.2); "
            "print('alive', signal.getsignal(signal.SIGHUP) == signal.SIG_IGN)")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                       preexec_fn=lambda: signal.signal(signal.SIGHUP, signal.SIG_IGN))
    assert p.returncode == 0 and p.stdout.strip() == "alive True", (p.returncode, p.stdout, p.stderr)

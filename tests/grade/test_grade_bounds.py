"""Bounds of a graded run (docs/GRADING.md "Bounds"): CPU time over all of a run's processes, a wall-clock
backstop that does not count the time spent waiting for a CPU, bytes and inodes of a per-run tmpfs, and what of
the host a run can see (``/proc/1/cmdline``, mount points).

Each fake student is a small script graded through :func:`a5mi.grade.run.grade_one` against a 4 x 4 reference
(no rendering). Load is made by the test itself: two CPU-bound busy loops it starts and kills by their ids.
"""

from __future__ import annotations

import base64
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hostile import sandbox_processes

from a5mi.grade.cases import make_case
from a5mi.grade.run import Task, grade_one
from a5mi.platform.imageio import write_image
from a5mi.sandbox.bwrap import isolation
from a5mi.sandbox.records import Limits

pytestmark = pytest.mark.skipif(os.geteuid() != 0, reason="the grader runs as root (a user id and a tmpfs per run)")

PY = "#!/usr/bin/python3\n"
#: CPU seconds the slow but correct student burns before writing its image (measured by itself).
SLOW_CPU = 1.5
BOUNDS = Limits(timeout=5.0, cpu_seconds=3.0, memory_mb=512, nproc=48, keep_bytes=4096, disk_mb=8, inodes=256)


@pytest.fixture
def world(tmp_path):
    root = tmp_path / "w"
    for d in ("subs", "scenes", "report", "work"):
        (root / d).mkdir(parents=True)
    for p in (tmp_path, root, *root.iterdir()):
        p.chmod(0o755)
    (root / "scenes" / "s.txt").write_text("PerspectiveCamera { }\n")
    write_image(root / "ref.png", np.full((4, 4, 3), 0.5))
    write_image(root / "wrong.png", np.full((4, 4, 3), 0.1))
    np.save(root / "sigma.npy", np.zeros((4, 4, 3), dtype=np.float32))
    return root


def _writes(world: Path, name: str = "ref.png") -> str:
    data = base64.b64encode((world / name).read_bytes()).decode()
    return (f"import base64, sys\nout = sys.argv[sys.argv.index('-output') + 1]\n"
            f"open(out, 'wb').write(base64.b64decode('{data}'))\n")


def _task(world: Path, name: str, script: str, limits: Limits = BOUNDS) -> Task:
    d = world / "subs" / name
    d.mkdir(exist_ok=True)
    d.chmod(0o755)
    (d / "a5").write_text(script)
    (d / "a5").chmod(0o755)
    case = make_case("-input s.txt -size 4 4 -output out.png", points=10)
    return Task(name, str(d), case, str(world / "scenes"), str(world / "ref.png"), str(world / "sigma.npy"),
                str(world / "work"), str(world / "report"), limits)


def _class(world: Path) -> list[Task]:
    """A correct student that needs SLOW_CPU of CPU, a sleeper, a spinner, two spinning processes, a wrong one."""
    return [
        _task(world, "slow", PY + f"import time\nt = time.process_time()\nwhile time.process_time() - t < {SLOW_CPU}:"
                                 "\n    pass\n" + _writes(world)),
        _task(world, "sleeper", "#!/bin/sh\nsleep 1000\n"),
        _task(world, "spinner", PY + "while True:\n    pass\n"),
        _task(world, "twins", "#!/bin/sh\n(while :; do :; done) &\nwhile :; do :; done\n"),
        _task(world, "wrong", PY + _writes(world, "wrong.png")),
    ]


def _busy_loops(n: int = 2) -> list[subprocess.Popen]:
    return [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(n)]


def test_a_class_graded_idle_and_beside_busy_loops_gets_the_same_verdicts(world) -> None:
    assert isolation() == "bwrap"
    tasks = _class(world)
    idle = [grade_one(t) for t in tasks]
    loops = _busy_loops()
    try:
        loaded = [grade_one(t) for t in tasks]
    finally:
        for p in loops:
            p.kill()
            p.wait()
    want = {"slow": ("match", ""), "sleeper": ("timeout", "wall"), "spinner": ("timeout", "cpu"),
            "twins": ("timeout", "cpu"), "wrong": ("wrong", "")}
    for recs in (idle, loaded):
        assert {r["student"]: (r["verdict"], r["ended_by"]) for r in recs} == want, recs
        assert not sandbox_processes([r["uid"] for r in recs])
    print({r["student"]: (r["wall"], r["cpu"]) for r in idle + loaded})
    by = {r["student"]: r for r in loaded}
    # the slow student used its own CPU time whatever the load; the bound counts every process of a run
    assert SLOW_CPU <= by["slow"]["cpu"] < BOUNDS.cpu
    assert by["twins"]["cpu"] >= BOUNDS.cpu and "CPU time" in by["twins"]["detail"]
    assert "wall-clock backstop" in by["sleeper"]["detail"] and by["sleeper"]["cpu"] < 1


def test_bytes_and_inodes_are_bounded_in_the_sandbox(world) -> None:
    write = _writes(world)
    filler = PY + write + ("import os\nfor d in ('.', '/tmp'):\n    for i in range(3):\n"
                           "        with open(os.path.join(d, f'fill{i}'), 'wb') as f:\n"
                           "            f.write(bytes(2 << 20))\n")
    flood = PY + write + "import os\nfor i in range(100000):\n    open(f'f{i}', 'w').close()\n"
    deep = PY + write + "import os\nfor i in range(1000):\n    os.mkdir('d')\n    os.chdir('d')\n"
    honest = PY + "import tempfile\nwith tempfile.NamedTemporaryFile(dir='/tmp') as f:\n    f.write(bytes(1 << 20))\n" \
        + write
    recs = {name: grade_one(_task(world, name, script))
            for name, script in (("filler", filler), ("flood", flood), ("deep", deep), ("honest", honest))}
    assert {n: r["verdict"] for n, r in recs.items()} == {"filler": "over disk", "flood": "over disk",
                                                          "deep": "over disk", "honest": "match"}, recs
    assert "8 MB / 256 inodes" in recs["filler"]["detail"]
    assert "No space left on device" in recs["flood"]["stderr_tail"]
    assert not list((world / "work").glob("*/*"))  # no run folder is left on the grader's disk
    # "over disk" is decided by the run's own tmpfs being full (a5mi.sandbox.folders.disk_full), so the writes
    # landed there, not on the grader's disk; the host disk's free space is not compared: other processes of the
    # machine (a second test suite) write to it at the same time


def test_a_run_sees_no_host_path_in_its_command_lines_or_mount_points(world) -> None:
    script = ("#!/bin/sh\nfor p in /proc/[0-9]*; do tr '\\0' ' ' < $p/cmdline; echo; done >&2\n"
              "awk '{print \"mount\", $5}' /proc/self/mountinfo >&2\necho \"cwd $(pwd) home $HOME zero $0\" >&2\n"
              "exit 3\n")
    rec = grade_one(_task(world, "looker", script))
    seen = rec["stderr_tail"]
    assert rec["verdict"] == "crash" and "/usr/bin/bwrap --args" in seen, seen
    assert str(world) not in seen and str(world.resolve()) not in seen, seen
    assert "cwd /a5/work home /a5/work zero /a5/submission/a5" in seen
    assert "mount /a5/scenes" in seen and "mount /a5/submission" in seen

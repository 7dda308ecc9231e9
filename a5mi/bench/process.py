"""Child processes of the benchmark: wall time, peak memory and ``a5 -v`` stage reports of real commands."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

# --------------------------------------------------------------------------------------------------------
# Child processes
# --------------------------------------------------------------------------------------------------------
from a5mi.bench.scenes import VERBOSE_STAGES


@dataclass
class ProcessRun:
    """One child process: wall time (s), its own peak RSS (MB), exit status, stderr, and its ``-v`` report."""

    wall: float
    peak_mb: float
    returncode: int
    stderr: str
    stages: dict[str, float] = field(default_factory=dict)
    rays: dict[str, int] = field(default_factory=dict)

    @property
    def startup(self) -> float | None:
        """Wall time not covered by the reported stages (interpreter start, imports, exit); None without ``-v``."""
        if not self.stages:
            return None
        return self.wall - sum(self.stages.get(k, 0.0) for k in VERBOSE_STAGES)


#: Runs the measured command as its own child: on Linux a child's ``ru_maxrss`` starts from the RSS of the
#: process that spawned it (``exec`` keeps the old image's high-water mark), so the command is launched from
#: this small interpreter rather than from the benchmark process, which holds scenes and buffers.
_LAUNCHER = """\
import json, os, subprocess, sys, threading, time
cmd, timeout = json.loads(sys.argv[1]), float(sys.argv[2])
t0 = time.perf_counter()
proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL)
timer = threading.Timer(timeout, proc.kill)
timer.start()
_, status, usage = os.wait4(proc.pid, 0)
timer.cancel()
wall = time.perf_counter() - t0
print(json.dumps({"wall": wall, "maxrss_kb": usage.ru_maxrss, "returncode": os.waitstatus_to_exitcode(status)}))
"""


def run_process(
    cmd: Sequence[str], *, cwd: str | Path | None = None, env: dict[str, str] | None = None, timeout: float = 600.0
) -> ProcessRun:
    """Run ``cmd``: wall time from spawn to reaping, peak memory = that child's own ``ru_maxrss`` (KiB on
    Linux) from ``os.wait4``, both taken by a small launcher interpreter (see :data:`_LAUNCHER`). The child is
    killed after ``timeout`` seconds (returncode then negative); its stderr is returned. ``A5MI_NO_SERVE`` is
    set: a whole process is measured, never one handed to ``a5mi serve`` (docs/SERVE.md)."""
    env = {**(os.environ if env is None else env), "A5MI_NO_SERVE": "1"}
    with tempfile.TemporaryFile() as err:
        proc = subprocess.run([sys.executable, "-c", _LAUNCHER, json.dumps(list(cmd)), str(timeout)], cwd=cwd,
                              env=env, stdout=subprocess.PIPE, stderr=err, check=False)
        err.seek(0)
        text = err.read().decode(errors="replace")
    try:
        m = json.loads(proc.stdout.decode().strip().splitlines()[-1])
    except (ValueError, IndexError):
        raise RuntimeError(f"bench launcher failed (exit {proc.returncode}): {text.strip()[-300:]}") from None
    stages, rays = parse_verbose(text)
    return ProcessRun(wall=m["wall"], peak_mb=m["maxrss_kb"] / 1024.0, returncode=m["returncode"], stderr=text,
                      stages=stages, rays=rays)


_TIMES = re.compile(r"^a5: times (.*)$", re.M)
_TIME_ITEM = re.compile(r"(\w+) ([0-9.]+) s")
_CAMERA = re.compile(r"\((\d+) camera rays")
_SECONDARY = re.compile(r"^a5: secondary rays (.*)$", re.M)
_RAY_ITEM = re.compile(r"(\w+) (\d+)")


def parse_verbose(text: str) -> tuple[dict[str, float], dict[str, int]]:
    """The stage times (s) and ray counts printed by ``a5 -v`` (see :func:`a5mi.cli._render_command`).

    ``a5: times parse 0.010 s, build 0.200 s, ...`` -> ``{'parse': 0.01, 'build': 0.2, ...}``;
    ``(810000 camera rays`` and ``a5: secondary rays reflection 5, refraction 0, shadow 7`` ->
    ``{'camera': 810000, 'reflection': 5, 'refraction': 0, 'shadow': 7}``. Missing lines give empty dicts.
    """
    stages: dict[str, float] = {}
    rays: dict[str, int] = {}
    m = _TIMES.search(text)
    if m:
        stages = {k: float(v) for k, v in _TIME_ITEM.findall(m.group(1))}
    m = _CAMERA.search(text)
    if m:
        rays["camera"] = int(m.group(1))
    m = _SECONDARY.search(text)
    if m:
        rays.update({k: int(v) for k, v in _RAY_ITEM.findall(m.group(1))})
    return stages, rays


def cpu_busy(interval: float = 0.5, stat: str = "/proc/stat") -> float:
    """Fraction of all CPUs busy over ``interval`` s, from the ``cpu`` line of ``/proc/stat``
    (busy = 1 - (idle + iowait) / total jiffies); 0.0 where ``/proc/stat`` is unreadable."""

    def sample() -> tuple[int, int]:
        with open(stat) as f:
            fields = [int(v) for v in f.readline().split()[1:]]
        return fields[3] + (fields[4] if len(fields) > 4 else 0), sum(fields)

    try:
        idle0, total0 = sample()
        time.sleep(interval)
        idle1, total1 = sample()
    except (OSError, ValueError, IndexError):
        return 0.0
    return 1.0 - (idle1 - idle0) / max(1, total1 - total0)


def wait_for_idle(max_wait: float, threshold: float = 0.1) -> float:
    """Wait (up to ``max_wait`` s) until other processes use less than ``threshold`` of the CPUs, so timings
    are not shared with someone else's work; returns the last busy fraction seen."""
    deadline = time.monotonic() + max_wait
    busy = cpu_busy()
    while busy >= threshold and time.monotonic() < deadline:
        busy = cpu_busy()
    return busy


def a5_command() -> list[str]:
    """The installed ``a5`` console script beside this interpreter, else ``python -m a5mi`` (the same entry)."""
    script = Path(sys.executable).with_name("a5")
    if script.is_file() and os.access(script, os.X_OK):
        return [str(script)]
    return [sys.executable, "-m", "a5mi"]


def render_flags(width: int, height: int, bounces: int) -> list[str]:
    """The assignment's test flags at a size: ``-size W H -shadows -bounces N -jitter -filter``."""
    return ["-size", str(width), str(height), "-shadows", "-bounces", str(bounces), "-jitter", "-filter"]


def cache_env(cache_dir: str | Path) -> dict[str, str]:
    """This environment with Dr.Jit's kernel cache (``DRJIT_CACHE_DIR``; default ``~/.drjit``) moved."""
    env = dict(os.environ)
    env["DRJIT_CACHE_DIR"] = str(cache_dir)
    return env

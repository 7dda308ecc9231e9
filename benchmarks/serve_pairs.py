"""Whole processes side by side with the sample solution, with and without ``a5mi serve`` (docs/SERVE.md).

    .venv/bin/python benchmarks/serve_pairs.py A5SOLN [--pairs scene10_sphere=5,scene12_vase=3] [--no-loop]

From ``$A5_DATA/scenes`` (the handout's command, ``-size 300 300 -shadows -bounces 4 -jitter -filter``), per
pair and in this order: ``a5soln``, ``a5`` in-process (``A5MI_NO_SERVE=1``; kernels from Dr.Jit's disk
cache), ``a5`` handed to a running ``a5mi serve`` (started by this script, one untimed served warm-up run per
scene first, so its kernels are in memory as in a student's loop). Each run is a whole process: wall from spawn
to exit; CPU = the child's user + sys (``os.wait4``), plus, for a served run, the server's CPU over the run
(``/proc/PID/stat``): the work done for it wherever it ran. One single-threaded busy loop runs beside the whole
benchmark unless ``--no-loop``. The 1-minute load average is read before each run. Medians per scene; the
ratio is a5soln's median over a5's. Every image is checked byte-identical between the served and the
in-process run of each pair, and every served run checked served (the server's log). Prints a Markdown table
and one line per run. Edit no a5mi module while it runs: the server stops on a changed code tree (docs/SERVE.md).
"""

from __future__ import annotations

import argparse
import os
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

FLAGS = ["-size", "300", "300", "-shadows", "-bounces", "4", "-jitter", "-filter"]
LOOP = "while True: pass"


def _cpu(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _load() -> float:
    return float(Path("/proc/loadavg").read_text().split()[0])


def _run(cmd: list[str], cwd: Path, env: dict[str, str], server: int | None) -> tuple[float, float, float]:
    load = _load()
    s0 = _cpu(server) if server else 0.0
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, cwd=cwd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, ru = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    err = proc.stderr.read().decode(errors="replace") if proc.stderr else ""
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)}: exit {proc.returncode}: {err.strip()[-300:]}")
    cpu = ru.ru_utime + ru.ru_stime + ((_cpu(server) - s0) if server else 0.0)
    return wall, cpu, load


def _served(work: Path) -> int:
    return sum(1 for ln in (work / "server.log").read_text().splitlines() if " served a5 " in ln)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("a5soln")
    ap.add_argument("--pairs", default="scene10_sphere=5,scene12_vase=3")
    ap.add_argument("--no-loop", action="store_true")
    opts = ap.parse_args()
    data = Path(os.environ.get("A5_DATA", Path(__file__).resolve().parents[2] / "shared" / "a5"))
    scenes_dir = data / "scenes"
    bindir = Path(sys.executable).parent
    a5 = [str(bindir / "a5")]
    work = Path(tempfile.mkdtemp(prefix="a5pairs-", dir="/tmp"))
    sock = work / "s.sock"
    base = {k: v for k, v in os.environ.items() if k not in ("A5MI_NO_SERVE", "A5MI_SERVE_SOCKET")}
    local_env = {**base, "A5MI_NO_SERVE": "1"}
    served_env = {**base, "A5MI_SERVE_SOCKET": str(sock)}
    log = open(work / "server.log", "wb")  # noqa: SIM115 - open for the server's life
    server = subprocess.Popen([str(bindir / "a5mi"), "serve", "--socket", str(sock)], env=served_env, stdout=log,
                              stderr=log)
    loop = None if opts.no_loop else subprocess.Popen([sys.executable, "-c", LOOP])
    rows = []
    try:
        while not sock.exists():
            if server.poll() is not None:
                raise SystemExit((work / "server.log").read_text())
            time.sleep(0.05)
        for item in opts.pairs.split(","):
            name, n = item.split("=")
            scene = f"{name}.txt"

            def out(tag: str, scene: str = scene, name: str = name) -> list[str]:
                ext = "bmp" if tag == "soln" else "png"  # a5soln writes .bmp or .tga
                return ["-input", scene, "-output", str(work / f"{name}.{tag}.{ext}"), *FLAGS]

            _run([*a5, *out("warm")], scenes_dir, local_env, None)  # Dr.Jit's disk cache holds the kernels
            _run([*a5, *out("warm")], scenes_dir, served_env, server.pid)  # the server's memory holds them
            runs: dict[str, list[tuple[float, float, float]]] = {"a5soln": [], "a5": [], "a5 served": []}
            for i in range(int(n)):
                for tag, cmd, env, pid in (("a5soln", [opts.a5soln, *out("soln")], base, None),
                                           ("a5", [*a5, *out("local")], local_env, None),
                                           ("a5 served", [*a5, *out("served")], served_env, server.pid)):
                    before = _served(work)
                    runs[tag].append(_run(cmd, scenes_dir, env, pid))
                    if pid is not None and _served(work) != before + 1:
                        raise SystemExit(f"{name}: the served run was not served: {(work / 'server.log').read_text()}")
                    w, c, ld = runs[tag][-1]
                    print(f"{name} pair {i + 1} {tag}: wall {w:.3f} s, CPU {c:.3f} s, load {ld:.2f}", flush=True)
                if (work / f"{name}.served.png").read_bytes() != (work / f"{name}.local.png").read_bytes():
                    raise SystemExit(f"{name}: the served image differs from the in-process one")
            rows.append((name, int(n), runs))
    finally:
        if loop is not None:
            loop.kill()
            loop.wait()
        server.send_signal(signal.SIGTERM)
        server.wait()
        log.close()
    print(f"\nserver: {_served(work)} requests served; busy loop beside: {'no' if opts.no_loop else 'one'}\n")
    print("| scene | pairs | load (1 min) | a5soln wall s | a5soln CPU s | a5 wall s | a5 CPU s | served wall s "
          "| served CPU s | a5soln / a5, wall | a5soln / served, wall | a5soln / served, CPU |")
    print("|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for name, n, runs in rows:
        med = {k: (statistics.median(r[0] for r in v), statistics.median(r[1] for r in v)) for k, v in runs.items()}
        loads = [r[2] for v in runs.values() for r in v]
        s, a, sv = med["a5soln"], med["a5"], med["a5 served"]
        print(f"| {name} | {n} | {min(loads):.1f}-{max(loads):.1f} | {s[0]:.2f} | {s[1]:.2f} | {a[0]:.2f} | "
              f"{a[1]:.2f} | {sv[0]:.2f} | {sv[1]:.2f} | {s[0] / a[0]:.1f}x | **{s[0] / sv[0]:.1f}x** | "
              f"{s[1] / sv[1]:.1f}x |")
    shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())

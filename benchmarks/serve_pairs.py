"""Whole processes side by side with the sample solution, with and without ``a5mi serve`` (docs/SERVE.md).

    .venv/bin/python benchmarks/serve_pairs.py A5SOLN [--pairs scene10_sphere=5,scene12_vase=3] [--no-loop]
                                               [--baseline BINDIR]

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

``--baseline BINDIR``: the ``bin`` folder of another installation (an older checkout's virtual environment): its
own ``a5mi serve`` runs beside this one's (its own socket, warmed the same way), and each pair ends with its
served ``a5``, its image checked byte-identical to this checkout's; a second table compares the two served runs
(medians, and the median of the per-pair ratios baseline / this), all under the same load.
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


def _served(work: Path, log: str = "server.log") -> int:
    return sum(1 for ln in (work / log).read_text().splitlines() if " served a5 " in ln)


def _logged(work: Path, log: str, count: int, wait: float = 5.0) -> bool:
    """Whether the server's log reaches ``count`` served lines within ``wait`` seconds (the server writes its
    line after the client has its exit status: on a loaded machine a moment later)."""
    end = time.monotonic() + wait
    while _served(work, log) < count and time.monotonic() < end:
        time.sleep(0.05)
    return _served(work, log) == count


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("a5soln")
    ap.add_argument("--pairs", default="scene10_sphere=5,scene12_vase=3")
    ap.add_argument("--no-loop", action="store_true")
    ap.add_argument("--baseline", type=Path, help="bin folder of another installation to serve beside this one")
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
    bsock, blog, bserver = work / "b.sock", None, None
    baseline_env = {**base, "A5MI_SERVE_SOCKET": str(bsock)}
    if opts.baseline is not None:
        blog = open(work / "baseline.log", "wb")  # noqa: SIM115 - open for the server's life
        bserver = subprocess.Popen([str(opts.baseline / "a5mi"), "serve", "--socket", str(bsock)], env=baseline_env,
                                   stdout=blog, stderr=blog)
    loop = None if opts.no_loop else subprocess.Popen([sys.executable, "-c", LOOP])
    rows = []
    try:
        for path, proc, lg in ((sock, server, "server.log"), (bsock, bserver, "baseline.log")):
            while proc is not None and not path.exists():
                if proc.poll() is not None:
                    raise SystemExit((work / lg).read_text())
                time.sleep(0.05)
        for item in opts.pairs.split(","):
            name, n = item.split("=")
            scene = f"{name}.txt"

            def out(tag: str, scene: str = scene, name: str = name) -> list[str]:
                ext = "bmp" if tag == "soln" else "png"  # a5soln writes .bmp or .tga
                return ["-input", scene, "-output", str(work / f"{name}.{tag}.{ext}"), *FLAGS]

            _run([*a5, *out("warm")], scenes_dir, local_env, None)  # Dr.Jit's disk cache holds the kernels
            _run([*a5, *out("warm")], scenes_dir, served_env, server.pid)  # the server's memory holds them
            steps = [("a5soln", [opts.a5soln, *out("soln")], base, None, ""),
                     ("a5", [*a5, *out("local")], local_env, None, ""),
                     ("a5 served", [*a5, *out("served")], served_env, server.pid, "server.log")]
            if bserver is not None:
                bcmd = [str(opts.baseline / "a5"), *out("baseline")]
                _run(bcmd, scenes_dir, baseline_env, bserver.pid)
                steps.append(("baseline served", bcmd, baseline_env, bserver.pid, "baseline.log"))
            runs: dict[str, list[tuple[float, float, float]]] = {step[0]: [] for step in steps}
            for i in range(int(n)):
                # the two servers' runs alternate (this, baseline; then baseline, this), an ABBA order
                for tag, cmd, env, pid, lg in steps if i % 2 == 0 else [*steps[:2], *steps[2:][::-1]]:
                    before = _served(work, lg) if lg else 0
                    runs[tag].append(_run(cmd, scenes_dir, env, pid))
                    if lg and not _logged(work, lg, before + 1):
                        raise SystemExit(f"{name}: the {tag} run was not served: {(work / lg).read_text()}")
                    w, c, ld = runs[tag][-1]
                    print(f"{name} pair {i + 1} {tag}: wall {w:.3f} s, CPU {c:.3f} s, load {ld:.2f}", flush=True)
                if (work / f"{name}.served.png").read_bytes() != (work / f"{name}.local.png").read_bytes():
                    raise SystemExit(f"{name}: the served image differs from the in-process one")
                if bserver is not None and (work / f"{name}.baseline.png").read_bytes() != \
                        (work / f"{name}.served.png").read_bytes():
                    raise SystemExit(f"{name}: the baseline's served image differs from this checkout's")
            rows.append((name, int(n), runs))
    finally:
        if loop is not None:
            loop.kill()
            loop.wait()
        for proc in (server, bserver):
            if proc is not None:
                proc.send_signal(signal.SIGTERM)
                proc.wait()
        log.close()
        if blog is not None:
            blog.close()
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
    if bserver is not None:
        print("\n| scene | pairs | served wall s | served CPU s | baseline served wall s | baseline served CPU s "
              "| baseline / this, wall (median of pairs) | baseline / this, CPU |")
        print("|---|---:|---:|---:|---:|---:|---:|---:|")
        for name, n, runs in rows:
            this, other = runs["a5 served"], runs["baseline served"]
            ratio = [statistics.median(b[k] / t[k] for t, b in zip(this, other, strict=True)) for k in (0, 1)]
            print(f"| {name} | {n} | {statistics.median(r[0] for r in this):.3f} | "
                  f"{statistics.median(r[1] for r in this):.3f} | {statistics.median(r[0] for r in other):.3f} | "
                  f"{statistics.median(r[1] for r in other):.3f} | {ratio[0]:.2f}x | {ratio[1]:.2f}x |")
    shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())

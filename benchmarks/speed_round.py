"""Every speed figure of BENCHMARKS.md's "speed where people wait" round, measured in one run, side by side with
the sample solution (BENCHMARKS.md "Run M").

    .venv/bin/python benchmarks/speed_round.py A5SOLN [--out benchmarks/run-m.md] [--base DIR] [--quick]

The steps run one after the other, each a child process of the existing benchmark scripts, so that every figure
comes from the same machine state in one sitting; the 1-minute load average and the wall of each step are written
before and after it, with the commit and the CPU model at the top:

1. ``a5mi bench scene10 scene11 scene06 scene12``: warm processes, the in-process stages, the kernel against the
   traversal of its own rays (the ray-log floor), stock Mitsuba;
2. ``benchmarks/kernel_profile.py scene10_sphere scene11_cube``: where the kernel's time goes (perf) and its IR
   operations per loop iteration; then ``benchmarks/kernel_floor_cpu.py``: the kernel against its floor in CPU
   seconds (the figure a busy machine moves least), alternated with the a5mi packages of ``--base DIR`` if given;
3. ``benchmarks/serve_pairs.py A5SOLN``: whole processes, a5soln / ``a5`` in-process / ``a5`` served, paired,
   with one single-thread busy loop beside them (the issue's machine);
4. ``benchmarks/view_page.py --modes jitter-filter scene10_sphere scene12_vase``: save to image on the page in
   headless Chromium with the handout's flags;
5. ``benchmarks/crop.py``: a region against the whole image;
6. ``benchmarks/diagnose.py``: one 300 x 300 image diagnosed;
7. ``benchmarks/grade_class.py``: a class of 200 on the handout's four cases, the model's terms at 300 x 300 and
   classes of 4 and 8 at 40 x 40 on 1 and 2 Dask workers (its longest step: a5soln's vase twice);
8. ``benchmarks/gpu_check.py``: the CUDA variant against LLVM (says so and measures nothing without a device).

``--quick`` shrinks every step (1 pair, 2 saves, 1 repeat) to check the driver itself. The output file holds every
step's whole output; nothing is summarised by hand. Exit status 0 when every step exited as expected (gpu_check's 2,
"no CUDA device", counts as expected), 1 otherwise.
"""

from __future__ import annotations

import argparse
import os
import shlex
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PY = str(Path(sys.executable))
A5MI = str(Path(sys.executable).with_name("a5mi"))


def steps(a5soln: str, quick: bool, base: str | None = None) -> list[tuple[str, list[str], tuple[int, ...]]]:
    """(title, command, accepted exit statuses) of each step, in the order they run."""
    b = ROOT / "benchmarks"
    paired = ["--base", base] if base else []
    return [
        ("a5mi bench: warm processes, stages, the kernel against its traversal floor",
         [A5MI, "bench", "scene10", "scene11", "scene06", "scene12", "--warm-runs", "1" if quick else "3",
          "--repeat", "1" if quick else "3", "--wait-idle", "5"], (0,)),
        ("kernel_profile: perf split and IR operations",
         [PY, str(b / "kernel_profile.py"), "scene10_sphere.txt", "scene11_cube.txt",
          "--renders", "2" if quick else "6"], (0,)),
        ("kernel_floor_cpu: the kernel against its floor in CPU seconds"
         + (f", alternated with {base}" if base else ""),
         [PY, str(b / "kernel_floor_cpu.py"), "--rounds", "1" if quick else "3", "--repeat", "2" if quick else "5",
          *paired], (0,)),
        ("serve_pairs: whole processes against a5soln, one busy loop beside",
         [PY, str(b / "serve_pairs.py"), a5soln, "--pairs",
          "scene10_sphere=1,scene12_vase=1" if quick else "scene10_sphere=5,scene12_vase=3"], (0,)),
        ("view_page: save to image with -jitter -filter in headless Chromium",
         [PY, str(b / "view_page.py"), "--saves", "2" if quick else "5", "--modes", "jitter-filter",
          "scene10_sphere", "scene12_vase"], (0,)),
        ("crop: a region against the whole image", [PY, str(b / "crop.py"), "--repeat", "1" if quick else "3"], (0,)),
        ("diagnose: one 300 x 300 image", [PY, str(b / "diagnose.py"), "--repeat", "1" if quick else "2"], (0,)),
        ("grade_class: a class of 200 x 4 cases, the model and measured points",
         [PY, str(b / "grade_class.py"), "--a5soln", a5soln, "--measure", "4" if quick else "4,8"], (0,)),
        ("gpu_check: CUDA against LLVM", [PY, str(b / "gpu_check.py")], (0, 2)),
    ]


def _load() -> str:
    return " ".join(Path("/proc/loadavg").read_text().split()[:3])


def _header() -> list[str]:
    commit = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True,
                            text=True).stdout.strip()
    dirty = subprocess.run(["git", "-C", str(ROOT), "status", "--porcelain", "--untracked-files=no"],
                           capture_output=True, text=True).stdout.strip()
    cpu = next((ln.split(":", 1)[1].strip() for ln in Path("/proc/cpuinfo").read_text().splitlines()
                if ln.startswith("model name")), "?")
    return [f"commit {commit}{' (modified tree)' if dirty else ''}, {os.cpu_count()} CPUs ({cpu}), "
            f"started {time.strftime('%Y-%m-%d %H:%M:%S UTC', time.gmtime())}, load {_load()}"]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("a5soln")
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "run-m.md")
    ap.add_argument("--base", help="a5mi packages of another checkout for kernel_floor_cpu.py's pairs")
    ap.add_argument("--quick", action="store_true")
    a = ap.parse_args()
    if not os.access(a.a5soln, os.X_OK):
        print(f"speed_round: {a.a5soln}: not an executable file", file=sys.stderr)
        return 2
    lines = _header()
    ok = True
    tmp = a.out.with_name(a.out.name + ".part")
    with tmp.open("w") as out:
        out.write("\n".join(lines) + "\n")
        for title, cmd, accepted in steps(a.a5soln, a.quick, a.base):
            t0 = time.monotonic()
            out.write(f"\n## {title}\n\n`{shlex.join(cmd)}`\n\nload before: {_load()}\n\n```\n")
            out.flush()
            print(f"[{time.strftime('%H:%M:%S')}] {title}", flush=True)
            rc = subprocess.run(cmd, stdout=out, stderr=subprocess.STDOUT, cwd=ROOT).returncode
            ok &= rc in accepted
            out.write(f"```\n\nexit {rc}, wall {time.monotonic() - t0:.1f} s, load after: {_load()}\n")
            out.flush()
    tmp.replace(a.out)
    print(f"wrote {a.out}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())

"""The fixed cost of an ``a5`` process (docs/SPEED.md): the whole ``a5`` on a small course scene against a bare
``python -c "import mitsuba as mi; mi.set_variant('llvm_ad_rgb')"``, paired (A B A B ...) in one run, medians of
wall and CPU seconds (user + sys of the child), the load average printed; then one in-process breakdown by
phase (CPU seconds: imports, parse + describe, Mitsuba + variant, plugin registration, build, render, write).

    .venv/bin/python benchmarks/startup.py [SCENE.txt] [REPEATS]

Default scene: ``$A5_DATA/scenes/scene11_cube.txt`` with ``-size 300 300 -shadows -bounces 4 -jitter -filter``
(BENCHMARKS.md's whole-process command). Kernels come from Dr.Jit's disk cache (one warm-up run first).
"""

from __future__ import annotations

import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time

PHASES = r"""
import json, sys, time
out, scene = sys.argv[1], sys.argv[2]
marks = []
c0 = time.process_time()
def mark(name):
    global c0
    c = time.process_time(); marks.append((name, c - c0)); c0 = c
import numpy; mark("numpy")
import a5mi.cli, a5mi.commands.render; mark("a5mi.cli")
from a5mi.converters.a5_parser import parse_file; from a5mi.converters.describe import describe; mark("converters")
d = describe(parse_file(scene)); mark("parse + describe (files read)")
import drjit, mitsuba as mi; mark("import drjit + mitsuba")
from a5mi.runtime import llvm; llvm.check(); mark("LLVM check")
from a5mi.plugins.syntax import cached_drjit_syntax
with cached_drjit_syntax(): mi.set_variant("llvm_ad_rgb")
drjit.llvm.Float(0.0); llvm.check_loaded(); mark("set_variant + LLVM backend")
from a5mi.plugins import register_all; register_all(); mark("plugin imports + registration")
from a5mi.render.session import build_scene; from a5mi.render.options import RenderOptions
o = RenderOptions(width=300, height=300, shadows=True, bounces=4, jitter=True, filter=True)
s = build_scene(d, o); mark("build (mi.load_dict)")
from a5mi.render.driver import render_scene
r = render_scene(s, d.camera, o); mark("render (+ jitter, filter)")
from a5mi.platform import imageio; imageio.write_images([(out, r.image)]); mark("write")
print(json.dumps(marks))
"""


def _child_cpu() -> float:
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def _timed(cmd: list[str], cwd: str) -> tuple[float, float]:
    c0, t0 = _child_cpu(), time.perf_counter()
    subprocess.run(cmd, cwd=cwd, check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - t0, _child_cpu() - c0


def main() -> None:
    data = os.environ.get("A5_DATA", os.path.join(os.path.dirname(__file__), "..", "..", "shared", "a5"))
    scene = os.path.abspath(sys.argv[1] if len(sys.argv) > 1 else os.path.join(data, "scenes", "scene11_cube.txt"))
    repeats = int(sys.argv[2]) if len(sys.argv) > 2 else 5
    a5 = os.path.join(os.path.dirname(sys.executable), "a5")
    cwd = os.path.dirname(scene)
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "out.png")
        cmd_a5 = [a5, "-input", scene, "-output", out, "-size", "300", "300", "-shadows", "-bounces", "4",
                  "-jitter", "-filter"]
        cmd_bare = [sys.executable, "-c", "import mitsuba as mi; mi.set_variant('llvm_ad_rgb')"]
        _timed(cmd_a5, cwd)                                   # warm-up: kernels into Dr.Jit's disk cache
        runs: dict[str, list[tuple[float, float]]] = {"a5": [], "bare": []}
        for _ in range(repeats):
            runs["a5"].append(_timed(cmd_a5, cwd))
            runs["bare"].append(_timed(cmd_bare, cwd))
        load = os.getloadavg()[0]
        phases = json.loads(subprocess.run([sys.executable, "-c", PHASES, out, scene], cwd=cwd, check=True,
                                           capture_output=True, text=True).stdout)
    med = {k: (statistics.median(w for w, _ in v), statistics.median(c for _, c in v)) for k, v in runs.items()}
    print(f"{os.path.basename(scene)} -size 300 300 -shadows -bounces 4 -jitter -filter; median of {repeats} "
          f"paired runs; load average (1 min) {load:.1f}; {os.cpu_count()} CPUs; "
          f"PYTHONDONTWRITEBYTECODE={os.environ.get('PYTHONDONTWRITEBYTECODE', '')}\n")
    print("| process | wall s | CPU s |")
    print("|---|---|---|")
    print(f"| `a5` | {med['a5'][0]:.3f} | {med['a5'][1]:.3f} |")
    print(f"| bare `import mitsuba; set_variant` | {med['bare'][0]:.3f} | {med['bare'][1]:.3f} |")
    print(f"\nratio a5 / bare: wall {med['a5'][0] / med['bare'][0]:.2f}, CPU {med['a5'][1] / med['bare'][1]:.2f}\n")
    print("| phase (one in-process run) | CPU s |")
    print("|---|---|")
    for name, cpu in phases:
        print(f"| {name} | {cpu:.3f} |")
    print(f"| total | {sum(c for _, c in phases):.3f} |")


if __name__ == "__main__":
    main()

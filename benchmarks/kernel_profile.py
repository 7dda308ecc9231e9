"""Where the a5_whitted render kernel spends its time: Embree's traversal against the kernel's own code.

For each scene a child process loads it (the handout command: 300 x 300, ``-shadows -bounces 4 -jitter
-filter``, so a 900 x 900 render of 810 000 camera rays), renders once to compile, then renders ``--renders``
times while ``perf record -e cpu-clock`` samples it. ``perf report --sort dso,sym`` then splits the samples:
Embree's ``intersect`` (nearest hit: camera, mirror and refracted rays) and ``occluded`` (shadow rays), the JIT
code (the kernel's own shading, plane and sphere tests, the triangle rule, the stack: Dr.Jit's LLVM output, which
perf shows as ``[JIT]``), and the rest (Dr.Jit, NumPy, Python: the jitter draw, the filter, copies). ``kernel``
is the best ``execute`` of the renders (Dr.Jit's kernel history). A second table gives the render kernel's IR
operation count (a 16 x 16 render of the same command: the same kernel), and without ``-shadows``, refraction
or reflection: what each block adds to every loop iteration, which every lane of a packet executes (masked). A
third table gives how busy the packets are: the lanes' ray-tree nodes (``counts`` AOV) against the iterations
their 16-lane packets loop (each packet loops until its largest tree is done).

Usage: ``.venv/bin/python benchmarks/kernel_profile.py [SCENE ...] [--renders N] [--threads N]`` (needs the
``perf`` tool; scenes default to the four test scenes, from ``$A5_DATA/scenes``). Prints a Markdown table.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

SCENES = ("scene06_bunny_1k.txt", "scene10_sphere.txt", "scene11_cube.txt", "scene12_vase.txt")

CHILD = r"""
import os, sys, time
from pathlib import Path
os.chdir(sys.argv[1])
from a5mi.runtime import variant
variant.activate()
from a5mi.render import driver
from a5mi.converters.a5_parser import parse_file
from a5mi.converters.describe import describe
from a5mi.render.options import RenderOptions
from a5mi.render.session import build_scene
threads = int(sys.argv[4]) or None
opts = RenderOptions(width=300, height=300, bounces=4, shadows=True, jitter=True, filter=True, threads=threads)
desc = describe(parse_file(Path(sys.argv[2])))
scene = build_scene(desc, opts)
driver.render_scene(scene, desc.camera, opts)
Path(sys.argv[3]).write_text("ready")
while Path(sys.argv[3]).read_text() != "go":
    time.sleep(0.01)
best = min(driver.render_scene(scene, desc.camera, opts).timings["execute"] for _ in range(int(sys.argv[5])))
print(f"KERNEL {best:.4f}", flush=True)
"""


OPS = r"""
import os, sys
from pathlib import Path
os.chdir(sys.argv[1])
from a5mi.runtime import variant
variant.activate()
import drjit as dr
import a5mi.render.render_pass as rp
from a5mi.render import driver
from a5mi.converters.a5_parser import parse_file
from a5mi.converters.describe import describe
from a5mi.render.options import RenderOptions
from a5mi.render.session import build_scene
seen = []
rp.account_kernels = lambda kernels, timings: seen.extend(dr.kernel_history())
desc = describe(parse_file(Path(sys.argv[2])))
for label, extra in (("full", {}), ("no -shadows", {"shadows": False}), ("no refraction", {"refraction": False}),
                     ("no reflection", {"reflection": False})):
    opts = RenderOptions(**{"width": 16, "height": 16, "bounces": 4, "shadows": True, "jitter": True,
                            "filter": True, **extra})
    seen.clear()
    driver.render_scene(build_scene(desc, opts), desc.camera, opts)
    print(label, max(e.get("operation_count", 0) for e in seen), flush=True)
"""


LANES = r"""
import os, sys
from pathlib import Path
import numpy as np
os.chdir(sys.argv[1])
from a5mi.runtime import variant
variant.activate()
import drjit as dr, mitsuba as mi
from a5mi.bench.floor import _camera_rays_for
from a5mi.converters.a5_parser import parse_file
from a5mi.converters.describe import describe
from a5mi.render.options import RenderOptions
from a5mi.render.session import build_scene
opts = RenderOptions(width=300, height=300, bounces=4, shadows=True, jitter=True, filter=True, count_rays=True)
desc = describe(parse_file(Path(sys.argv[2])))
scene = build_scene(desc, opts)
ray = _camera_rays_for(desc, 900, 900)
integrator = scene.integrator()
_, _, aovs = integrator.sample(scene, None, mi.RayDifferential3f(ray), None, mi.Bool(True))
named = dict(zip(integrator.aov_names(), aovs))
nodes = 1 + np.asarray(named["n_reflection"]) + np.asarray(named["n_refraction"])
busiest = nodes.reshape(-1, 16).max(axis=1)
print(int(nodes.sum()), int(16 * busiest.sum()), int(nodes.max()))
"""


def utilisation(scene_dir: Path, scene: str) -> tuple[int, int, int]:
    """``(nodes, lane iterations, largest tree)``: the ray-tree nodes of the 900 x 900 render's lanes, and the
    loop iterations its 16-lane packets run (16 x the packet's largest tree), from the ``counts`` AOV."""
    out = subprocess.run([sys.executable, "-c", LANES, str(scene_dir), scene], capture_output=True, text=True,
                         check=True).stdout.split()
    return int(out[0]), int(out[1]), int(out[2])


def operation_counts(scene_dir: Path, scene: str) -> dict[str, int]:
    """The render kernel's IR operation count (Dr.Jit's kernel history; vcall bodies are separate functions)
    for the command and with one block left out: -shadows, refraction, reflection."""
    out = subprocess.run([sys.executable, "-c", OPS, str(scene_dir), scene], capture_output=True, text=True,
                         check=True).stdout
    return {line.rsplit(" ", 1)[0]: int(line.rsplit(" ", 1)[1]) for line in out.splitlines() if line.strip()}


def classify(report: str) -> dict[str, float]:
    """Shares (%) of ``perf report --sort dso,sym -g none`` lines: embree intersect / occluded, JIT, other."""
    out = {"intersect": 0.0, "occluded": 0.0, "embree other": 0.0, "jit": 0.0, "other": 0.0}
    for line in report.splitlines():
        parts = line.split()
        if not parts or not parts[0].endswith("%") or line.lstrip().startswith("#"):
            continue
        share = float(parts[0].rstrip("%"))
        if "libembree" in line:
            key = "intersect" if "::intersect" in line else "occluded" if "::occluded" in line else "embree other"
        elif "[JIT]" in line:
            key = "jit"
        else:
            key = "other"
        out[key] += share
    total = sum(out.values()) or 1.0          # perf's column can add up to a little over 100: normalise
    return {k: 100.0 * v / total for k, v in out.items()}


def profile(scene_dir: Path, scene: str, renders: int, threads: int) -> tuple[float, dict[str, float]]:
    """``(best kernel execute s, shares)`` of ``renders`` renders of ``scene`` under perf (module docstring)."""
    with tempfile.TemporaryDirectory(prefix="a5prof-") as tmp:
        flag, data = Path(tmp) / "flag", Path(tmp) / "perf.data"
        flag.write_text("")
        child = subprocess.Popen([sys.executable, "-c", CHILD, str(scene_dir), scene, str(flag), str(threads),
                                  str(renders)], stdout=subprocess.PIPE, text=True)
        while flag.read_text() != "ready":
            if child.poll() is not None:
                raise RuntimeError(f"{scene}: the render process exited {child.returncode}")
            time.sleep(0.05)
        perf = subprocess.Popen(["perf", "record", "-q", "-e", "cpu-clock", "-p", str(child.pid), "-o", str(data)],
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        time.sleep(0.5)                       # perf attached before the first timed render
        flag.write_text("go")
        out, _ = child.communicate()
        perf.wait()
        kernel = float(next(line.split()[1] for line in out.splitlines() if line.startswith("KERNEL")))
        report = subprocess.run(["perf", "report", "-i", str(data), "--no-children", "--sort", "dso,sym", "-g", "none",
                                 "--stdio"], capture_output=True, text=True, check=True).stdout
        return kernel, classify(report)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenes", nargs="*", default=list(SCENES))
    ap.add_argument("--renders", type=int, default=6)
    ap.add_argument("--threads", type=int, default=0, help="Dr.Jit threads (0: all cores)")
    args = ap.parse_args()
    if shutil.which("perf") is None:
        print("kernel_profile: needs the perf tool (Debian: linux-perf)", file=sys.stderr)
        return 2
    scene_dir = Path(os.environ.get("A5_DATA", Path(__file__).resolve().parents[2] / "shared" / "a5")) / "scenes"
    print(f"load average before: {os.getloadavg()[0]:.2f}")
    print("| scene | kernel s | Embree intersect | Embree occluded | Embree other | JIT code | other |")
    print("| --- | ---: | ---: | ---: | ---: | ---: | ---: |")
    for scene in args.scenes:
        kernel, s = profile(scene_dir, scene, args.renders, args.threads)
        print(f"| {Path(scene).stem} | {kernel:.3f} | {s['intersect']:.1f}% | {s['occluded']:.1f}% | "
              f"{s['embree other']:.1f}% | {s['jit']:.1f}% | {s['other']:.1f}% |", flush=True)
    print(f"load average after: {os.getloadavg()[0]:.2f}")
    print()
    print("Render kernel IR operations (the command; and without one block)")
    print()
    print("| scene | ops | without -shadows | without refraction | without reflection |")
    print("| --- | ---: | ---: | ---: | ---: |")
    for scene in args.scenes:
        o = operation_counts(scene_dir, scene)
        print(f"| {Path(scene).stem} | {o['full']} | {o['no -shadows']} | {o['no refraction']} | "
              f"{o['no reflection']} |", flush=True)
    print()
    print("Packets: ray-tree nodes against the loop iterations of their 16-lane packets (a packet loops until its")
    print("largest tree is done; utilisation = nodes / lane iterations)")
    print()
    print("| scene | nodes | lane iterations | utilisation | mean tree | largest tree |")
    print("| --- | ---: | ---: | ---: | ---: | ---: |")
    for scene in args.scenes:
        nodes, lanes, largest = utilisation(scene_dir, scene)
        print(f"| {Path(scene).stem} | {nodes:,} | {lanes:,} | {nodes / lanes:.3f} | {nodes / 810000:.2f} | "
              f"{largest} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())

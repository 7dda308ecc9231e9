"""The a5_whitted kernel against the traversal of its own rays, in CPU seconds: a ratio that a busy machine moves
little, paired against another checkout in one run.

For each scene a child process renders the handout command's 900 x 900 camera rays (300 x 300, ``-shadows
-bounces 4 -jitter -filter``, the jitter of the render) with the integrator once to compile, then ``REPEAT`` more
times, and keeps the smallest CPU time (user + sys of the process, all Dr.Jit threads) and wall time of the
kernel's launch alone (the Python trace is left out); then the traversal floor of the same rays (the kernel's
ray log, a5mi/bench/floor.py ``ray_log``: camera and secondary rays by ``ray_intersect``, shadow rays by
``ray_test``, on the ``stock=True`` scene) timed the same way. On a machine whose other processes take its cores
the wall times grow with the load, the CPU times far less: ``kernel / floor`` in CPU seconds is the figure to
compare between runs there. ``--base DIR`` also runs each measurement with the a5mi packages of ``DIR`` (a folder
holding ``a5mi`` with ``plugins`` and ``converters`` inside, as installed), alternating base and this tree.

Usage: ``.venv/bin/python benchmarks/kernel_floor_cpu.py [SCENE ...] [--rounds N] [--repeat N] [--base DIR]``
(scenes default to scene10 and scene11 of ``$A5_DATA/scenes``). Prints one line per measurement and the medians.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

SCENES = ("scene10_sphere.txt", "scene11_cube.txt")

CHILD = r"""
import json, os, resource, sys, time
from dataclasses import replace
from pathlib import Path
os.chdir(sys.argv[1])
from a5mi.runtime import variant
variant.activate()
import drjit as dr, mitsuba as mi, numpy as np
from a5mi.bench import assignment_command
from a5mi.bench import floor as F
from a5mi.converters.a5_parser import parse_file
from a5mi.converters.describe import describe
from a5mi.converters.to_mitsuba import to_dict
from a5mi.render.session import build_scene

repeat = int(sys.argv[3])
opts = assignment_command()
model = parse_file(Path(sys.argv[2]))
desc = describe(model)

def cpu():
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime

def timed(trace):
    best = (float("inf"), float("inf"))
    for k in range(repeat + 1):
        out = trace()
        dr.sync_thread()
        c0, w0 = cpu(), time.perf_counter()
        dr.eval(out)
        dr.sync_thread()
        if k > 0:
            best = (min(best[0], cpu() - c0), min(best[1], time.perf_counter() - w0))
    return best

scene = build_scene(desc, opts)
ray = F._camera_rays_for(desc, 900, 900)
dr.eval(ray)
integ = scene.integrator()
kernel = timed(lambda: integ.sample(scene, None, mi.RayDifferential3f(ray), None, mi.Bool(True))[0])
del scene, integ
F._free()
counted = build_scene(desc, replace(opts, count_rays=True))
nodes, shadows = F.ray_log(counted, ray, F._count_pass(counted, ray, 900 * 900))
del counted
F._free()
stock = mi.load_dict(to_dict(describe(model, stock=True), opts, stock=True))

def cast(o, d, maxt, test):
    r = F._full_ray(mi.Point3f(o), mi.Vector3f(d), None if maxt is None else mi.Float(maxt))
    dr.eval(r)
    if test:
        return timed(lambda: stock.ray_test(r))
    return timed(lambda: (lambda s: (s.t, s.sh_frame.n))(stock.ray_intersect(r)))

start = nodes["o"] + nodes["tmin"] * nodes["d"]
cam = nodes["ordinal"] == 0
big = np.float32(np.finfo(np.float32).max)
maxt = np.where(shadows["far"], big, shadows["dist"] - shadows["tmin"]).astype(np.float32)
parts = [cast(start[:, cam], nodes["d"][:, cam], None, False), cast(start[:, ~cam], nodes["d"][:, ~cam], None, False),
         cast(shadows["p"] + shadows["tmin"] * shadows["d"], shadows["d"], maxt, True)]
floor = (sum(p[0] for p in parts), sum(p[1] for p in parts))
print("RESULT " + json.dumps({"kernel_cpu": kernel[0], "kernel_wall": kernel[1], "floor_cpu": floor[0],
                              "floor_wall": floor[1]}))
"""


def measure(scene_dir: Path, scene: str, repeat: int, base: str | None) -> dict[str, float]:
    """One child process's figures (module docstring); ``base``: the packages folder put first on its path."""
    env = dict(os.environ)
    if base is not None:
        env["PYTHONPATH"] = base
    out = subprocess.run([sys.executable, "-c", CHILD, str(scene_dir), scene, str(repeat)], capture_output=True,
                         text=True, check=True, env=env).stdout
    res = json.loads(next(line[7:] for line in out.splitlines() if line.startswith("RESULT ")))
    res["ratio_cpu"] = res["kernel_cpu"] / res["floor_cpu"]
    res["ratio_wall"] = res["kernel_wall"] / res["floor_wall"]
    return res


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenes", nargs="*", default=list(SCENES))
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--base", help="a5mi packages of the checkout to compare with (module docstring)")
    args = ap.parse_args()
    scene_dir = Path(os.environ.get("A5_DATA", Path(__file__).resolve().parents[2] / "shared" / "a5")) / "scenes"
    sides = ([("base", args.base)] if args.base else []) + [("this", None)]
    runs: dict[tuple[str, str], list[dict[str, float]]] = {}
    for r in range(args.rounds):
        for scene in args.scenes:
            for name, path in sides:
                res = measure(scene_dir, scene, args.repeat, path)
                runs.setdefault((scene, name), []).append(res)
                print(f"{Path(scene).stem} round {r + 1} {name}: load {os.getloadavg()[0]:.1f} "
                      + " ".join(f"{k} {v:.4f}" for k, v in res.items()), flush=True)
    print()
    print("| scene | code | kernel CPU s | floor CPU s | kernel / floor (CPU) | kernel wall s "
          "| kernel / floor (wall) |")
    print("| --- | --- | ---: | ---: | ---: | ---: | ---: |")
    for (scene, name), rs in runs.items():
        med = {k: statistics.median(r[k] for r in rs) for k in rs[0]}
        print(f"| {Path(scene).stem} | {name} | {med['kernel_cpu']:.3f} | {med['floor_cpu']:.3f} | "
              f"{med['ratio_cpu']:.2f} | {med['kernel_wall']:.3f} | {med['ratio_wall']:.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())

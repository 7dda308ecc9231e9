"""The octree replay's node table (plugins/emulation/octree_leaves.py, SPEC A.6; docs/FIDELITY.md): its size,
the build's CPU time and numpy peak, and the render it serves, on the project's own meshes (and the course's,
where ``../shared/a5/scenes`` is present).

Per mesh set: the nodes of :func:`octree_leaves.build` and their bytes in the kernel (4 per node), the build's
CPU time and its peak of Python/numpy memory (``tracemalloc``); then the CPU time of ``a5`` on
``scenes/octree_budget.txt`` (three different meshes, a light ``0 -1 0``) and the render process's peak
resident memory (``getrusage`` of the child), at ``-size 300 300 -shadows``, best of ``--repeat``.

    .venv/bin/python benchmarks/octree_table.py [--repeat 2]
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
COURSE = ROOT.parent / "shared" / "a5" / "scenes"
SETS = {
    "column + cylinder + icosphere (scenes/octree_budget.txt)": [ROOT / "scenes" / "meshes" / n
                                                                 for n in ("column.obj", "cylinder.obj",
                                                                           "icosphere.obj")],
    "bunny_1k (course)": [COURSE / "bunny_1k.obj"],
    "bunny_1k + bunny_200 (course)": [COURSE / "bunny_1k.obj", COURSE / "bunny_200.obj"],
    "vase (course)": [COURSE / "vase.obj"],
}


def _triangles(path: Path) -> np.ndarray:
    from a5mi.converters.obj import load_obj

    mesh = load_obj(path)
    return np.asarray(mesh.vertices, dtype=np.float32)[np.asarray(mesh.faces)]


def table_rows() -> list[str]:
    """One markdown row per mesh set whose files exist."""
    from a5mi.plugins.emulation import octree_leaves
    from a5mi.runtime.variant import activate

    activate()
    rows = []
    for name, files in SETS.items():
        if not all(f.is_file() for f in files):
            continue
        tris = [_triangles(f) for f in files]
        tracemalloc.start()
        cpu = time.process_time()
        table = octree_leaves.build(tris)
        cpu = time.process_time() - cpu
        _, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        nodes = len(np.asarray(table.child)) if table is not None else "over budget"
        size = f"{4 * nodes / 2**20:.2f}" if table is not None else "-"
        rows.append(f"| {name} | {nodes} | {size} | {cpu:.2f} | {peak / 2**20:.1f} |")
    return rows


def render_figures(repeat: int) -> tuple[float, float]:
    """(best CPU seconds, largest peak RSS in MiB) of ``a5`` on scenes/octree_budget.txt, 300 x 300."""
    best, rss = float("inf"), 0.0
    for _ in range(repeat):
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        with tempfile.TemporaryDirectory() as out:
            subprocess.run([str(Path(sys.executable).parent / "a5"), "-input", "octree_budget.txt", "-size", "300",
                            "300", "-shadows", "-output", str(Path(out) / "o.png")], cwd=ROOT / "scenes",
                           check=True, stdout=subprocess.DEVNULL)
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        best = min(best, (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime))
        rss = max(rss, after.ru_maxrss / 1024)
    return best, rss


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=2)
    args = parser.parse_args()
    print(f"load average {os.getloadavg()[0]:.1f}")
    print("| meshes | nodes | kernel MiB | build CPU s | build numpy peak MiB |")
    print("| --- | --- | --- | --- | --- |")
    print("\n".join(table_rows()))
    cpu, rss = render_figures(args.repeat)
    print(f"a5 scenes/octree_budget.txt -size 300 300 -shadows: {cpu:.2f} s CPU (best of {args.repeat}), "
          f"peak RSS {rss:.0f} MiB")


if __name__ == "__main__":
    main()

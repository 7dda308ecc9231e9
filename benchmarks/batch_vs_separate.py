"""Batch renders against separate processes, alternated (BENCHMARKS.md, the batch tables).

Per repetition, under the same contention: the four assignment test commands as four warm ``a5`` processes
(``-size 300 300 -shadows -bounces 4 -jitter -filter``, run from the scenes' folder), then one ``a5mi render``
process over the same four scenes (``--output-dir``). Prints each repetition's walls, the CPU share others
used just before (``busy``) and separate / batch. The Dr.Jit kernel cache is the user's (warm after the first
repetition).

    .venv/bin/python benchmarks/batch_vs_separate.py [REPETITIONS]   (default 3)
"""

from __future__ import annotations

import sys
import tempfile

from a5mi import data_dir
from a5mi.bench.batch import measure_batch_process
from a5mi.bench.process import a5_command, cpu_busy, render_flags, run_process

NAMES = ("scene06_bunny_1k.txt", "scene10_sphere.txt", "scene11_cube.txt", "scene12_vase.txt")


def main(repetitions: int = 3) -> None:
    scenes = data_dir() / "scenes"
    flags = render_flags(300, 300, 4)
    for rep in range(repetitions):
        with tempfile.TemporaryDirectory() as tmp:
            busy = cpu_busy()
            separate = sum(run_process(a5_command() + ["-input", n, "-output", f"{tmp}/{n}.png", *flags],
                                       cwd=scenes).wall for n in NAMES)
            batch, _ = measure_batch_process([scenes / n for n in NAMES], flags, None, 600.0)
            print(f"rep {rep}: busy {busy:.2f}, separate {separate:.3f} s, batch {batch.wall:.3f} s, "
                  f"separate/batch {separate / batch.wall:.2f}", flush=True)


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 3)

"""``make gpu-check``: the cuda variant against the llvm one, on the 12 reference images and the test commands.

For every image of ``reference/`` (its flags from reference/README.md, 300 x 300, rendered from ``scenes/``)
the real ``a5`` command renders it with ``-variant llvm`` and with ``-variant cuda`` in child processes; both are
compared with the reference and with each other (PSNR, 8-bit levels, :mod:`a5mi.compare`). Then the four
assignment test commands and a 3840 x 2160 ``-jitter -filter`` render of scene10 are timed with each variant
(wall time of the whole process, warm kernel cache: best of ``--repeat`` after one warm-up run).

Exit status 0 when every cuda image's PSNR against the reference is within 0.5 dB of the llvm image's; 1 when
one is not; 2 when there is no CUDA device (the check cannot run: it says so, and nothing is measured).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from a5mi import require_data_dir
from a5mi.compare import compare_arrays
from a5mi.fidelity import SIZE, cases
from a5mi.platform.imageio import read_levels
from a5mi.runtime.variant import cuda_available

TOLERANCE_DB = 0.5
TEST_SCENES = ("scene06_bunny_1k", "scene10_sphere", "scene11_cube", "scene12_vase")


def a5(variant: str, scene: Path, out: Path, flags: list[str], timeout: float = 900.0) -> float:
    """Run ``a5`` for ``scene`` with ``flags`` and ``-variant variant``; returns the wall time (s)."""
    cmd = [sys.executable, "-m", "a5mi", "-input", scene.name, "-output", str(out), "-variant", variant, *flags]
    t0 = time.perf_counter()
    p = subprocess.run(cmd, cwd=scene.parent, capture_output=True, text=True, timeout=timeout)
    wall = time.perf_counter() - t0
    if p.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} exited {p.returncode}: {p.stderr.strip()[-400:]}")
    return wall


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(prog="gpu_check", description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=2, help="timed runs per command and variant (best kept)")
    ap.add_argument("--no-4k", action="store_true", help="skip the 3840x2160 timing")
    args = ap.parse_args(argv)
    if not cuda_available():
        print("gpu_check: no CUDA device or driver on this machine: the GPU check was not run", file=sys.stderr)
        return 2
    root = require_data_dir()
    failed = False
    print("| image | llvm vs reference | cuda vs reference | cuda vs llvm | within 0.5 dB |")
    print("| --- | --- | --- | --- | --- |")
    with tempfile.TemporaryDirectory(prefix="a5mi-gpu-") as tmp:
        for case in cases():
            flags = case.flags.split()
            psnr: dict[str, float] = {}
            for variant in ("llvm", "cuda"):
                a5(variant, case.scene_file, Path(tmp) / f"{case}.{variant}.png", flags)
                psnr[variant] = compare_arrays(read_levels(Path(tmp) / f"{case}.{variant}.png"),
                                               read_levels(case.reference)).psnr
            between = compare_arrays(read_levels(Path(tmp) / f"{case}.cuda.png"),
                                     read_levels(Path(tmp) / f"{case}.llvm.png")).psnr
            ok = abs(psnr["cuda"] - psnr["llvm"]) <= TOLERANCE_DB
            failed |= not ok
            print(f"| {case} | {psnr['llvm']:.1f} dB | {psnr['cuda']:.1f} dB | {between:.1f} dB | "
                  f"{'yes' if ok else 'NO'} |")
        print("\n| command | llvm s | cuda s | llvm / cuda |\n| --- | --- | --- | --- |")
        jobs = [(name, root / "scenes" / f"{name}.txt", ["-size", str(SIZE), str(SIZE), "-shadows", "-bounces", "4",
                                                          "-jitter", "-filter"]) for name in TEST_SCENES]
        if not args.no_4k:
            jobs.append(("scene10 3840x2160", root / "scenes" / "scene10_sphere.txt",
                         ["-size", "3840", "2160", "-shadows", "-bounces", "4", "-jitter", "-filter"]))
        for name, scene, flags in jobs:
            best = {}
            for variant in ("llvm", "cuda"):
                a5(variant, scene, Path(tmp) / "t.png", flags)  # warm-up: fills the kernel cache
                best[variant] = min(a5(variant, scene, Path(tmp) / "t.png", flags) for _ in range(args.repeat))
            print(f"| {name} | {best['llvm']:.2f} | {best['cuda']:.2f} | {best['llvm'] / best['cuda']:.1f}x |")
    print(f"\ngpu_check: {'FAILED' if failed else 'passed'} (cuda within {TOLERANCE_DB} dB of llvm on every image)")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

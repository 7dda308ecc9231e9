"""``make gpu-check`` (benchmarks/gpu_check.py): on a machine without an NVIDIA GPU it says so and exits 2,
measuring nothing; on one with a GPU the check itself is ``make gpu-check`` (minutes), not a unit test."""

from __future__ import annotations

import subprocess
import sys

import pytest
from helpers import ROOT

from a5mi.runtime.variant import cuda_available

SCRIPT = ROOT / "benchmarks" / "gpu_check.py"


@pytest.mark.skipif(cuda_available(), reason="a GPU is present: run `make gpu-check` for the real check")
def test_gpu_check_without_a_gpu_says_so_and_exits_2() -> None:
    p = subprocess.run([sys.executable, str(SCRIPT)], capture_output=True, text=True, timeout=120)
    assert p.returncode == 2 and p.stdout == ""
    assert p.stderr.strip() == "gpu_check: no CUDA device or driver on this machine: the GPU check was not run"

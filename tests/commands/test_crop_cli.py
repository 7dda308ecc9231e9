"""``a5 -crop X0 X1 Y0 Y1`` through the real command line (docs/USAGE.md "Crop renders"): the image written is
the region alone, byte for byte the same pixels of the whole image's file, ``-normals`` likewise; every bad
region or mode is one line, exit 2, nothing written."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from helpers import TESTS

SCENE = TESTS.parent / "scenes" / "spec_glass.txt"


def a5(tmp_path: Path, *flags: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "a5mi", "-input", str(SCENE), *flags], cwd=tmp_path,
                          capture_output=True, text=True, timeout=600)


def test_crop_writes_the_regions_pixels_of_the_whole_file(tmp_path: Path) -> None:
    from a5mi.platform.imageio import read_image

    flags = ("-size", "20", "16", "-jitter", "-filter", "-shadows")
    whole = a5(tmp_path, "-output", "whole.png", "-normals", "wn.png", *flags)
    part = a5(tmp_path, "-output", "part.png", "-normals", "pn.png", "-crop", "13", "20", "0", "5", *flags)
    assert whole.returncode == 0 and part.returncode == 0, whole.stderr + part.stderr
    w, p = read_image(tmp_path / "whole.png"), read_image(tmp_path / "part.png")
    assert p.shape[:2] == (5, 7) and np.array_equal(p, w[0:5, 13:20])
    wn, pn = read_image(tmp_path / "wn.png"), read_image(tmp_path / "pn.png")
    assert pn.shape[:2] == (15, 21) and np.array_equal(pn, wn[0:15, 39:60])


@pytest.mark.parametrize("flags,message", [
    (("-crop", "0", "21", "0", "5"), "a5: error: -crop 0 21 0 5 is not a region of the 20x16 image"),
    (("-crop", "4", "4", "0", "5"), "a5: error: -crop 4 4 0 5 is not a region of the 20x16 image"),
    (("-crop", "0", "4", "6", "5"), "a5: error: -crop 0 4 6 5 is not a region"),
    (("-crop", "0", "4", "0"), "a5: error: -crop expects 4 values"),
    (("-crop", "0", "4", "0", "x"), "a5: error: -crop expects an integer, found 'x'"),
    (("-crop", "0", "4", "0", "5", "-integrator", "photon"), "a5: error: -crop renders -integrator whitted or path"),
    (("-crop", "0", "4", "0", "5", "-workers", "2"), "a5: error: -workers/-scheduler: -crop renders one region"),
    (("-crop", "0", "4", "0", "5", "-mistake", "upside_down"), "a5: error: -crop cannot make the mistake"),
    (("-crop", "0", "4", "0", "5", "-integrator", "irradiancecache"), "a5: error: -crop renders -integrator whitted"),
])
def test_bad_regions_are_one_line_exit_2(tmp_path: Path, flags: tuple[str, ...], message: str) -> None:
    p = a5(tmp_path, "-output", "o.png", "-size", "20", "16", *flags)
    assert p.returncode == 2
    assert p.stderr.count("\n") == 1 and p.stderr.startswith(message), p.stderr
    assert list(tmp_path.iterdir()) == []

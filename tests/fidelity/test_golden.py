"""Golden images of the project's own scenes: rendered by a5mi, checked by eye once, compared each run.

Each case renders ``scenes/NAME.txt`` at 150 x 150 with the assignment's flags and compares it with
``tests/golden/NAME.FLAGS.png`` using :mod:`a5mi.compare`: PSNR >= 60 dB and at most 0.1% of pixels off by more
than 2/255 (tighter than the sample-solution floors: the same renderer should agree with itself to the last
bits, apart from LLVM/CPU differences in float rounding at triangle edges).

After an intended change of the rendering, look at the new images and regenerate them with
``A5MI_UPDATE_GOLDEN=1 .venv/bin/python -m pytest tests/fidelity/test_golden.py``, then commit them with the change.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from helpers import ROOT, TESTS

from a5mi.compare import compare_arrays, write_diff
from a5mi.platform.imageio import read_levels

GOLDEN = TESTS / "golden"
SIZE = 150
CASES = {
    "b4-jitter-filter": {"shadows": True, "bounces": 4, "jitter": True, "filter": True},
    "b4": {"shadows": True, "bounces": 4},
}
SCENES = ("demo", "gallery")


@pytest.mark.parametrize("suffix", list(CASES))
@pytest.mark.parametrize("scene", SCENES)
def test_golden(scene: str, suffix: str, variant: str, tmp_path: Path) -> None:
    from a5mi.render.options import RenderOptions

    _check_golden(scene, f"{scene}.{suffix}", RenderOptions(width=SIZE, height=SIZE, **CASES[suffix]), tmp_path)


def _check_golden(scene: str, name: str, options, tmp_path: Path) -> None:
    """Render ``scenes/{scene}.txt`` with ``options`` and compare with ``tests/golden/{name}.png``: PSNR >= 60 dB
    and at most 0.1% of pixels off by more than 2/255 (``A5MI_UPDATE_GOLDEN=1`` rewrites the golden image)."""
    from a5mi.platform.imageio import quantize, write_image
    from a5mi.render.session import describe_file, render

    result = render(describe_file(str(ROOT / "scenes" / f"{scene}.txt"), bump=options.bump)[0], options)
    ours = quantize(result.image).astype(np.float64)
    golden = GOLDEN / f"{name}.png"
    if os.environ.get("A5MI_UPDATE_GOLDEN") == "1":
        write_image(golden, result.image)
    assert golden.is_file(), f"missing {golden}: run with A5MI_UPDATE_GOLDEN=1 and check the image by eye"
    ref = read_levels(golden)
    m = compare_arrays(ours, ref)
    if m.psnr < 60.0 or m.share_over > 0.001:
        write_diff(ours, ref, m, tmp_path / f"{name}.diff.png", ("now", "golden"))
    assert m.psnr >= 60.0, f"{name}: {m.summary()} (diff in {tmp_path})"
    assert m.share_over <= 0.001, f"{name}: {m.summary()} (diff in {tmp_path})"


#: The extension's demo scenes (docs/EXTENSIONS.md), seeded: -shadows -bounces 4 -spp 4 -seed 1.
EXT_SCENES = ("soft_shadows", "dof", "spot", "glossy", "prism")


@pytest.mark.parametrize("scene", EXT_SCENES)
def test_golden_extension(scene: str, variant: str, tmp_path: Path) -> None:
    from a5mi.render.options import RenderOptions

    options = RenderOptions(width=SIZE, height=SIZE, shadows=True, bounces=4, spp=4, seed=1)
    _check_golden(scene, f"{scene}.ext-spp4", options, tmp_path)


#: Extra credit part 2 demo scenes (docs/EXTENSIONS.md E.6, E.7) at 64 x 64, -shadows -bounces 4; bumps with -bump.
PART2 = {"solids": ("solids.b4", {}), "bumps": ("bumps.b4-bump", {"bump": True})}


@pytest.mark.parametrize("scene", list(PART2))
def test_golden_part2(scene: str, variant: str, tmp_path: Path) -> None:
    from a5mi.render.options import RenderOptions

    name, extra = PART2[scene]
    _check_golden(scene, name, RenderOptions(width=64, height=64, shadows=True, bounces=4, **extra), tmp_path)


def test_golden_fog(variant: str, tmp_path: Path) -> None:
    """The fog demo (docs/EXTENSIONS.md E.8): 64 x 64, -shadows -bounces 4 -spp 2 -seed 1."""
    from a5mi.render.options import RenderOptions

    options = RenderOptions(width=64, height=64, shadows=True, bounces=4, spp=2, seed=1)
    _check_golden("fog_shafts", "fog_shafts.fog-spp2", options, tmp_path)


def test_golden_volume(variant: str, tmp_path: Path) -> None:
    """The Volume demo (docs/EXTENSIONS.md E.9, grid ``scenes/volumes/cloud.vol``): 64 x 64, -shadows -bounces 2
    -spp 2 -seed 1."""
    from a5mi.render.options import RenderOptions

    options = RenderOptions(width=64, height=64, shadows=True, bounces=2, spp=2, seed=1)
    _check_golden("volume", "volume.vol-spp2", options, tmp_path)

"""Fidelity against the sample solution: re-render the reference images and measure (SPEC C, docs/FIDELITY.md).

``reference/README.md`` (beside SPEC.md) names the flags of each reference image by its suffix; every image is
300 x 300, rendered from inside ``scenes/``. :func:`render_reference` renders the same scene with the same flags
through the whole a5mi pipeline (parser, converter, plugins, driver, quantisation) and
:func:`a5mi.compare.compare_arrays` measures it. ``a5mi fidelity`` prints the table the README carries.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from a5mi import data_dir
from a5mi.compare import Metrics, compare_arrays
from a5mi.platform.imageio import read_levels

#: reference suffix -> driver flags (reference/README.md)
SUFFIX_FLAGS: dict[str, dict[str, object]] = {
    "b4-jitter-filter": {"shadows": True, "bounces": 4, "jitter": True, "filter": True},
    "b4": {"shadows": True, "bounces": 4},
    "b0-jitter-filter": {"shadows": True, "bounces": 0, "jitter": True, "filter": True},
}
SIZE = 300

#: PSNR between the two official sample-solution builds (reference/README.md), for context.
OFFICIAL_BUILDS_PSNR: dict[tuple[str, str], float] = {
    ("scene06_bunny_1k", "b4-jitter-filter"): 47.3,
    ("scene06_bunny_1k", "b4"): 45.9,
    ("scene10_sphere", "b4-jitter-filter"): 50.5,
    ("scene10_sphere", "b4"): 50.3,
    ("scene11_cube", "b4-jitter-filter"): 75.8,
    ("scene11_cube", "b4"): 64.5,
    ("scene12_vase", "b4-jitter-filter"): 39.4,
    ("scene12_vase", "b4"): 38.9,
}


@dataclass(frozen=True)
class ReferenceCase:
    scene: str  # e.g. "scene10_sphere"
    suffix: str  # e.g. "b4-jitter-filter"

    @property
    def reference(self) -> Path:
        return data_dir() / "reference" / f"{self.scene}.{self.suffix}.png"

    @property
    def scene_file(self) -> Path:
        return data_dir() / "scenes" / f"{self.scene}.txt"

    @property
    def flags(self) -> str:
        f = SUFFIX_FLAGS[self.suffix]
        out = f"-size {SIZE} {SIZE} -shadows -bounces {f['bounces']}"
        return out + (" -jitter -filter" if f.get("jitter") else "")

    def __str__(self) -> str:
        return f"{self.scene}.{self.suffix}"


def cases() -> Iterator[ReferenceCase]:
    """Every image in ``reference/``, in name order."""
    for png in sorted((data_dir() / "reference").glob("*.png")):
        scene, _, suffix = png.stem.partition(".")
        if suffix in SUFFIX_FLAGS:
            yield ReferenceCase(scene, suffix)


def render_reference(case: ReferenceCase) -> np.ndarray:
    """Our render of ``case`` in levels (H, W, 3), row 0 = top, quantised as the binary does (SPEC B.1)."""
    from a5mi.converters.a5_parser import parse_file
    from a5mi.converters.describe import describe
    from a5mi.platform.imageio import quantize
    from a5mi.render.options import RenderOptions
    from a5mi.render.session import render

    model = parse_file(case.scene_file)
    flags = SUFFIX_FLAGS[case.suffix]
    opts = RenderOptions(width=SIZE, height=SIZE, **flags)  # type: ignore[arg-type]
    result = render(describe(model, bump=opts.bump), opts)
    return quantize(result.image).astype(np.float64)


def measure(case: ReferenceCase) -> tuple[Metrics, np.ndarray, np.ndarray]:
    ours = render_reference(case)
    ref = read_levels(case.reference)
    return compare_arrays(ours, ref), ours, ref


def table(rows: list[tuple[ReferenceCase, Metrics]]) -> str:
    """The README's Markdown table."""
    lines = [
        "| scene | flags | PSNR | mean error | pixels > 2/255 | max | official builds' PSNR |",
        "| --- | --- | --- | --- | --- | --- | --- |",
    ]
    for case, m in rows:
        psnr = "identical" if m.psnr == float("inf") else f"{m.psnr:.1f} dB"
        official = OFFICIAL_BUILDS_PSNR.get((case.scene, case.suffix))
        lines.append(
            f"| {case.scene} | `{case.flags}` | {psnr} | {m.mean_error:.3f}/255 | {100 * m.share_over:.2f}% | "
            f"{m.max_error:g}/255 | {'n/a' if official is None else f'{official:.1f} dB'} |"
        )
    return "\n".join(lines)

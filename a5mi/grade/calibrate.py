"""Calibration of the verdict thresholds (the table of ``docs/GRADING.md``).

For each handout scene (``-shadows -bounces 4 -jitter -filter`` at ``size``), the reference and noise band of
:mod:`a5mi.grade.references` are built, then a5mi renders the case as students would get it:

* **correct, other jitter** (``-seed 1``, ``2``, ``3``): must all be ``match``;
* **defects**: shadows off; bounces off (0) and changed (1); refraction off; reflection off; the filter off
  (one ray per pixel, no jitter, no filter) and changed (a plain 3x3 box average instead of the blur); the
  marble off (its ``Noise`` replaced by the material's diffuse colour, scenes with marble only): must all be
  ``wrong``. A defect that leaves the quantised image identical (refraction in a scene without glass) cannot
  be seen by any grader and is reported as ``no effect``.

:func:`calibrate` returns the rows; ``benchmarks/grade_calibration.py`` prints them as Markdown and
``tests/grade/test_grade_calibration.py`` asserts the rule at 100 x 100.
"""

from __future__ import annotations

import contextlib
import dataclasses
import re
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from a5mi.grade.references import build_reference, render_levels
from a5mi.grade.verdict import ImageMetrics, Thresholds, judge, measure
from a5mi.render.options import RenderOptions

SCENES: tuple[str, ...] = ("scene06_bunny_1k.txt", "scene10_sphere.txt", "scene11_cube.txt", "scene12_vase.txt")
SEEDS: tuple[int, ...] = (1, 2, 3)


@dataclass(frozen=True)
class Row:
    """One calibration render: ``scene``, ``variant`` (e.g. ``seed 2``, ``shadows off``), ``expected``
    (``match`` or ``wrong``), the ``verdict`` given and its ``metrics`` (None for ``no effect``)."""

    scene: str
    variant: str
    expected: str
    verdict: str
    metrics: ImageMetrics | None

    @property
    def ok(self) -> bool:
        return self.verdict in (self.expected, "no effect")




def _box_not_blur(scene: Path, options: RenderOptions) -> np.ndarray:
    """The jittered 3W x 3H render averaged over 3 x 3 blocks, without the blur (a wrong filter)."""
    from a5mi.converters.a5_parser import parse_file
    from a5mi.converters.describe import describe
    from a5mi.platform.imageio import quantize
    from a5mi.render.filters import downsample3
    from a5mi.render.session import render
    from a5mi.runtime import variant

    variant.activate(None)
    big = render(describe(parse_file(str(scene)), bump=options.bump), dataclasses.replace(options, filter=False)).image
    return quantize(downsample3(big)).astype(np.float64)


def _no_marble(scene: Path, options: RenderOptions) -> np.ndarray | None:
    """The scene with every ``Noise { ... }`` block removed (the material keeps its diffuse colour)."""
    text = scene.read_text(encoding="utf-8")
    plain = re.sub(r"Noise\s*\{[^{}]*\}", "", text)
    if plain == text:
        return None
    with tempfile.TemporaryDirectory() as tmp:
        copy = Path(tmp) / scene.name
        copy.write_text(plain, encoding="utf-8")
        return render_levels(copy, options)  # relative names resolve against the working directory: scenes/


def defects(scene: Path, base: RenderOptions) -> list[tuple[str, Callable[[], np.ndarray | None]]]:
    """(name, render) of every defect of the module docstring."""
    r = dataclasses.replace

    def flags(**kw: object) -> Callable[[], np.ndarray]:
        return lambda: render_levels(scene, r(base, **kw))  # type: ignore[arg-type]

    return [("shadows off", flags(shadows=False)), ("bounces off (0)", flags(bounces=0)),
            ("bounces changed (1)", flags(bounces=1)), ("refraction off", flags(refraction=False)),
            ("reflection off", flags(reflection=False)),
            ("filter off (1 ray/pixel)", flags(jitter=False, filter=False)),
            ("filter changed (3x3 box)", lambda: _box_not_blur(scene, base)),
            ("marble off", lambda: _no_marble(scene, base))]


def calibrate(scenes_dir: str | Path, size: int, cache_dir: str | Path, *, scenes: tuple[str, ...] = SCENES,
              thresholds: Thresholds | None = None, flip: bool = True,
              log: Callable[[str], None] | None = None) -> list[Row]:
    """Every row of the calibration (module docstring) at ``size`` x ``size``."""
    folder = Path(scenes_dir)
    thresholds = thresholds or Thresholds()
    base = RenderOptions(width=size, height=size, shadows=True, bounces=4, jitter=True, filter=True)
    rows: list[Row] = []
    with contextlib.chdir(folder):
        for name in scenes:
            scene = folder / name
            ref_img, sigma = build_reference(scene, base, cache_dir).load()
            variants = [(f"seed {s}", "match", (lambda s=s, scene=scene: render_levels(
                scene, dataclasses.replace(base, seed=s)))) for s in SEEDS]
            variants += [(d, "wrong", fn) for d, fn in defects(scene, base)]
            for label, expected, fn in variants:
                img = fn()
                if img is None:
                    continue  # not applicable (no marble in the scene)
                if np.array_equal(img, ref_img):
                    rows.append(Row(name, label, expected, "no effect", None))
                else:
                    metrics, _ = measure(img, ref_img, sigma, flip=flip)
                    rows.append(Row(name, label, expected, judge(metrics, thresholds), metrics))
                if log is not None:
                    log(f"{name} {label}: {rows[-1].verdict}")
    return rows


def markdown(rows: list[Row], size: int) -> str:
    """The docs table: one row per render, the judged share and the reported metrics."""
    lines = [f"| scene ({size}x{size}) | render | expected | verdict | beyond noise | PSNR | mean | > 2/255 | FLIP |",
             "| --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for r in rows:
        m = r.metrics
        if m is None:
            lines.append(f"| {r.scene[:-4]} | {r.variant} | {r.expected} | no effect (identical) | 0 | inf | 0 | 0 "
                         "| 0 |")
            continue
        flip = "-" if m.flip is None else f"{m.flip:.4f}"
        lines.append(f"| {r.scene[:-4]} | {r.variant} | {r.expected} | **{r.verdict}** | {100 * m.beyond_noise:.2f}% "
                     f"| {m.psnr:.1f} | {m.mean_error:.2f} | {100 * m.share_over_2:.1f}% | {flip} |")
    return "\n".join(lines)


__all__ = ["Row", "SCENES", "SEEDS", "calibrate", "defects", "markdown"]

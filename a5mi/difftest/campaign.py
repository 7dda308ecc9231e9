"""A difftest campaign: N seeded random scenes compared, failures minimised, a table and a JSON report.

Scene ``i`` of seed ``s`` is :func:`.generate.random_scene` ``(s, i)`` at a square size drawn around the
requested one (``size - 10 .. size + 10``, the binary asserts on non-square images). A scene's PSNR for pass
or fail is the lowest of its main image and, unless ``aovs="none"``, its ``-normals`` and ``-depth`` images
(:attr:`.runner.Outcome.worst`); the tables and the summary give the main image's PSNR and each AOV's
beside it. A scene whose PSNR is below ``threshold`` dB, or where the other executable fails, is minimised
(:mod:`.minimise`) and both the scene and its smallest reproducer are written to ``out_dir``
(``scene_NNN.txt``, ``scene_NNN.min.txt``, each with a ``.cmd`` file holding the a5 command line), linked
course files beside them.

PSNR of two identical images is ``inf``: statistics take it as the largest value (the median of PSNRs of which
more than half are ``inf`` is ``inf``, :func:`median_psnr`), tables print ``inf`` and the JSON report the string
``"inf"`` (``float()`` reads it); ``null`` means that nothing was compared (a run failed). A campaign
*passes* (:func:`passed`) when every scene was compared and none is below ``threshold``.
"""

from __future__ import annotations

import json
import math
import os
import random
import statistics
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from a5mi.difftest.generate import GenScene, random_scene
from a5mi.difftest.minimise import Minimised, minimise
from a5mi.difftest.runner import DEFAULT_TIMEOUT, Outcome, compare_scene, stage


@dataclass(frozen=True)
class Row:
    """One scene's result; ``minimised`` only for failures."""

    index: int
    scene: GenScene
    outcome: Outcome
    minimised: Minimised | None = None


def scene_size(seed: int, index: int, size: int) -> int:
    """The square size of scene ``index``: ``size`` ± 10, seeded."""
    return size + random.Random(f"size:{seed}:{index}").randint(-10, 10)


def run_campaign(binary: Path, data: Path, *, count: int, seed: int = 0, size: int = 100,
                 threshold: float = 50.0, timeout: float = DEFAULT_TIMEOUT, out_dir: Path | None = None,
                 minimise_budget: int = 80, start: int = 0, aovs: str = "quadrant",
                 on_row: Callable[[Row], None] | None = None) -> list[Row]:
    """Compare scenes ``start .. start+count-1`` of ``seed`` (module docstring; ``aovs``: the rays of the
    compared AOV images, :data:`.runner.AOV_CHOICES`); ``on_row`` is called after each."""
    rows = []

    def check(s: GenScene) -> Outcome:
        return compare_scene(s, binary, data, timeout, aovs)

    for i in range(start, start + count):
        scene = random_scene(seed, i, scene_size(seed, i, size))
        out = check(scene)
        mini = None
        if out.worst < threshold and not out.status.startswith("a5mi failed"):
            mini = minimise(scene, check, threshold, first=out, budget=minimise_budget)
            if out_dir is not None:
                write_reproducer(out_dir, f"scene_{i:03d}", scene, data)
                write_reproducer(out_dir, f"scene_{i:03d}.min", mini.scene, data)
        row = Row(i, scene, out, mini)
        rows.append(row)
        if on_row is not None:
            on_row(row)
    return rows


def write_reproducer(out_dir: Path, stem: str, scene: GenScene, data: Path) -> Path:
    """``out_dir/STEM.txt`` (+ links to the course files it names) and ``STEM.cmd``, the a5 command line."""
    out_dir.mkdir(parents=True, exist_ok=True)
    path = stage(scene, out_dir, data)
    final = out_dir / f"{stem}.txt"
    os.replace(path, final)
    (out_dir / f"{stem}.cmd").write_text(" ".join(["a5", "-input", final.name, "-output", f"{stem}.bmp",
                                                   *scene.flags.argv()]) + "\n")
    return final


def median_psnr(psnrs: list[float]) -> float | None:
    """The median of PSNR values in dB, ``inf`` (identical images) ordered above every finite value: the middle
    value, or the mean of the two middle ones (``inf`` when either is), so never a stand-in number; None for
    no values."""
    if not psnrs:
        return None
    return float(statistics.median(sorted(psnrs)))


def psnr_text(psnr: float | None, digits: int = 1) -> str:
    """``inf`` for identical images, ``-`` for none, else the value with ``digits`` decimals."""
    if psnr is None:
        return "-"
    return "inf" if math.isinf(psnr) and psnr > 0 else f"{psnr:.{digits}f}"


def _json_psnr(psnr: float | None, digits: int = 2) -> float | str | None:
    return None if psnr is None else "inf" if math.isinf(psnr) and psnr > 0 else round(psnr, digits)


def below(row: Row, threshold: float) -> bool:
    """The scene fails: a side did not produce an image, or the PSNR of one of its images is below ``threshold``."""
    return row.outcome.metrics is None or row.outcome.worst < threshold


def passed(rows: list[Row], threshold: float) -> bool:
    """Every scene compared at or above ``threshold`` dB (the ``a5mi difftest`` exit status 0)."""
    return not any(below(r, threshold) for r in rows)


def summary(rows: list[Row], threshold: float) -> dict[str, float | int | None]:
    """Counts and PSNR statistics (``inf`` counts as above every threshold; module docstring)."""
    ok = [r.outcome.psnr for r in rows if r.outcome.metrics is not None]
    aov: dict[str, float | int | None] = {}
    for name in ("normals", "depth"):
        got = [p for r in rows if r.outcome.metrics is not None and (p := r.outcome.aov_psnr(name)) is not None]
        if got:
            aov[f"{name}_median_psnr"] = median_psnr(got)
            aov[f"{name}_identical"] = sum(math.isinf(p) for p in got)
            aov[f"{name}_share_at_least_50"] = sum(p >= 50 for p in got) / len(rows)
    return {
        "scenes": len(rows), "compared": len(ok), "failed_runs": len(rows) - len(ok),
        "median_psnr": median_psnr(ok),
        "share_at_least_50": sum(p >= 50 for p in ok) / len(rows) if rows else 0.0,
        "share_at_least_threshold": sum(p >= threshold for p in ok) / len(rows) if rows else 0.0,
        "identical": sum(math.isinf(p) for p in ok),
        "below_threshold": sum(below(r, threshold) for r in rows),
        **aov,
    }


def _metrics_json(o: Outcome) -> dict[str, object]:
    m = o.metrics
    return {"status": o.status, "binary_s": round(o.binary_s, 3), "a5mi_s": round(o.a5mi_s, 3),
            "psnr": None if m is None else _json_psnr(m.psnr),
            "share_over": None if m is None else m.share_over, "max_error": None if m is None else m.max_error,
            **{f"{name}_psnr": _json_psnr(a.psnr) for name, a in o.aovs},
            **{f"{name}_max_error": a.max_error for name, a in o.aovs}}


def report_json(rows: list[Row], threshold: float, seed: int) -> str:
    """The campaign as JSON: settings, :func:`summary`, one entry per scene (minimised scenes included)."""
    summ = summary(rows, threshold)
    for key in [k for k in summ if k.endswith("median_psnr")]:
        summ[key] = _json_psnr(summ[key])  # type: ignore[arg-type]
    out = {"seed": seed, "threshold": threshold, "summary": summ, "passed": passed(rows, threshold), "scenes": []}
    for r in rows:
        entry: dict[str, object] = {"index": r.index, "flags": r.scene.flags.argv(), "files": list(r.scene.files),
                                    **_metrics_json(r.outcome)}
        if r.minimised is not None:
            entry["minimised"] = {"text": r.minimised.scene.text(), "flags": r.minimised.scene.flags.argv(),
                                  "evaluations": r.minimised.evaluations, **_metrics_json(r.minimised.outcome)}
        out["scenes"].append(entry)  # type: ignore[attr-defined]
    return json.dumps(out, indent=1)


def _aov_cell(o: Outcome, name: str) -> str:
    p = o.aov_psnr(name)
    return "-" if p is None else psnr_text(p)


def table_line(r: Row) -> str:
    """One Markdown table row: index, size and flags, PSNR, share > 2/255, max, the AOV images' PSNR, status."""
    m = r.outcome.metrics
    flags = " ".join(r.scene.flags.argv()[3:])
    if m is None:
        return f"| {r.index} | {r.scene.flags.size} | `{flags}` | - | - | - | - | - | {r.outcome.status} |"
    psnr = psnr_text(m.psnr)
    mini = ""
    if r.minimised is not None:
        s = r.minimised.scene
        mini = (f"; minimised to {len(s.objects)} object(s), {len(s.lights)} light(s), "
                f"`{' '.join(s.flags.argv()[3:])}`, {psnr_text(r.minimised.outcome.worst)} dB")
    return (f"| {r.index} | {r.scene.flags.size} | `{flags}` | {psnr} | {100 * m.share_over:.2f}% | "
            f"{m.max_error:g} | {_aov_cell(r.outcome, 'normals')} | {_aov_cell(r.outcome, 'depth')} | "
            f"{r.outcome.status}{mini} |")


TABLE_HEAD = ("| scene | size | flags | PSNR (dB) | pixels > 2/255 | max | normals (dB) | depth (dB) | status |\n"
              "| --- | --- | --- | --- | --- | --- | --- | --- | --- |")

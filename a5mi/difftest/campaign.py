"""A difftest campaign: N seeded random scenes compared, failures minimised, a table and a JSON report.

Scene ``i`` of seed ``s`` is :func:`.generate.random_scene` ``(s, i)`` at a square size drawn around the
requested one (``size - 10 .. size + 10``, the binary asserts on non-square images). A scene whose PSNR is
below ``threshold`` dB, or where the other executable fails, is minimised (:mod:`.minimise`) and both the
scene and its smallest reproducer are written to ``out_dir`` (``scene_NNN.txt``, ``scene_NNN.min.txt``, each
with a ``.cmd`` file holding the a5 command line), linked course files beside them.
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

from .generate import GenScene, random_scene
from .minimise import Minimised, minimise
from .runner import DEFAULT_TIMEOUT, Outcome, compare_scene, stage


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
                 minimise_budget: int = 80, start: int = 0,
                 on_row: Callable[[Row], None] | None = None) -> list[Row]:
    """Compare scenes ``start .. start+count-1`` of ``seed`` (module docstring); ``on_row`` is called after each."""
    rows = []

    def check(s: GenScene) -> Outcome:
        return compare_scene(s, binary, data, timeout)

    for i in range(start, start + count):
        scene = random_scene(seed, i, scene_size(seed, i, size))
        out = check(scene)
        mini = None
        if out.psnr < threshold and not out.status.startswith("a5mi failed"):
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


def summary(rows: list[Row], threshold: float) -> dict[str, float | int]:
    """Counts and PSNR statistics (``inf`` counts as above every threshold)."""
    ok = [r.outcome.psnr for r in rows if r.outcome.metrics is not None]
    finite = [p if math.isfinite(p) else 1e9 for p in ok]
    return {
        "scenes": len(rows), "compared": len(ok), "failed_runs": len(rows) - len(ok),
        "median_psnr": statistics.median(finite) if finite else float("nan"),
        "share_at_least_50": sum(p >= 50 for p in finite) / len(rows) if rows else 0.0,
        "share_at_least_threshold": sum(p >= threshold for p in finite) / len(rows) if rows else 0.0,
        "identical": sum(math.isinf(p) for p in ok),
    }


def _metrics_json(o: Outcome) -> dict[str, object]:
    m = o.metrics
    return {"status": o.status, "binary_s": round(o.binary_s, 3), "a5mi_s": round(o.a5mi_s, 3),
            "psnr": None if m is None or math.isinf(m.psnr) else round(m.psnr, 2),
            "share_over": None if m is None else m.share_over, "max_error": None if m is None else m.max_error}


def report_json(rows: list[Row], threshold: float, seed: int) -> str:
    """The campaign as JSON: settings, :func:`summary`, one entry per scene (minimised scenes included)."""
    out = {"seed": seed, "threshold": threshold, "summary": summary(rows, threshold), "scenes": []}
    for r in rows:
        entry: dict[str, object] = {"index": r.index, "flags": r.scene.flags.argv(), "files": list(r.scene.files),
                                    **_metrics_json(r.outcome)}
        if r.minimised is not None:
            entry["minimised"] = {"text": r.minimised.scene.text(), "flags": r.minimised.scene.flags.argv(),
                                  "evaluations": r.minimised.evaluations, **_metrics_json(r.minimised.outcome)}
        out["scenes"].append(entry)  # type: ignore[attr-defined]
    return json.dumps(out, indent=1)


def table_line(r: Row) -> str:
    """One Markdown table row: index, size and flags, PSNR, share > 2/255, max, status."""
    m = r.outcome.metrics
    flags = " ".join(r.scene.flags.argv()[3:])
    if m is None:
        return f"| {r.index} | {r.scene.flags.size} | `{flags}` | - | - | - | {r.outcome.status} |"
    psnr = "inf" if math.isinf(m.psnr) else f"{m.psnr:.1f}"
    mini = ""
    if r.minimised is not None:
        s = r.minimised.scene
        mini = (f"; minimised to {len(s.objects)} object(s), {len(s.lights)} light(s), "
                f"`{' '.join(s.flags.argv()[3:])}`, {r.minimised.outcome.psnr:.1f} dB")
    return (f"| {r.index} | {r.scene.flags.size} | `{flags}` | {psnr} | {100 * m.share_over:.2f}% | "
            f"{m.max_error:g} | {r.outcome.status}{mini} |")


TABLE_HEAD = ("| scene | size | flags | PSNR (dB) | pixels > 2/255 | max | status |\n"
              "| --- | --- | --- | --- | --- | --- | --- |")

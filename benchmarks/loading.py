"""Benchmark of loading scenes in parallel and on one thread (BENCHMARKS.md "Loading", docs/MITSUBA.md).

For each scene, the seconds of ``mi.load_dict`` of a5mi's dict and of ``mi.load_file`` of the converted XML
(``a5mi convert``, a5 plugins, 200 x 200), with ``parallel=True`` (Mitsuba's default) and ``parallel=False``
(a5mi's, :mod:`a5mi.platform.loading`), alternated in one process, ``--repeat`` times each after one warm-up load
of each: min and median, one JSON line per scene. Scenes: the project's own ``scenes/gallery.txt`` and
``scenes/demo.txt``, then the course's scene10 and sibenik when the course data is present (``--scene``
replaces the list). The race that a parallel load once met is a test, not a figure:
tests/plugins/materials/test_a5_material.py.
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
SIZE = ["-size", "200", "200", "-shadows", "-bounces", "4"]


def _scenes() -> list[str]:
    from a5mi import data_dir

    own = [str(ROOT / "scenes" / "gallery.txt"), str(ROOT / "scenes" / "demo.txt")]
    course = [data_dir() / "scenes" / "scene10_sphere.txt", data_dir() / "extras" / "sibenik" / "s.txt"]
    return own + [str(p) for p in course if p.is_file()]


def _times(load: Callable[..., Any], arg: Any, repeat: int) -> dict[str, dict[str, float]]:
    out: dict[str, list[float]] = {"parallel": [], "serial": []}
    for parallel in (True, False):
        load(arg, parallel=parallel)  # warm-up: plugins, kernels, caches
    for _ in range(repeat):
        for parallel in (True, False):
            t0 = time.perf_counter()
            load(arg, parallel=parallel)
            out["parallel" if parallel else "serial"].append(time.perf_counter() - t0)
    return {k: {"min_s": round(min(v), 4), "median_s": round(statistics.median(v), 4)} for k, v in out.items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", action="append", help="scene file (repeatable); default: the list above")
    ap.add_argument("--repeat", type=int, default=5)
    a = ap.parse_args()
    from a5mi.cli import run_a5mi
    from a5mi.render.options import RenderOptions
    from a5mi.render.session import describe_file, scene_dict
    from a5mi.runtime.variant import activate

    activate()
    import mitsuba as mi

    options = RenderOptions(width=200, height=200, bounces=4, shadows=True)
    with tempfile.TemporaryDirectory(prefix="a5mi-loading-") as tmp:
        for scene in a.scene or _scenes():
            xml = Path(tmp) / f"{Path(scene).stem}.xml"
            assert run_a5mi(["convert", scene, "-o", str(xml), *SIZE]) == 0
            d = scene_dict(describe_file(scene)[0], options)
            print(json.dumps({"scene": scene, "size": "200x200",
                              "dict": _times(lambda e, parallel: mi.load_dict(e, parallel=parallel), d, a.repeat),
                              "xml": _times(lambda f, parallel: mi.load_file(str(f), parallel=parallel), xml,
                                            a.repeat)}))

if __name__ == "__main__":
    main()

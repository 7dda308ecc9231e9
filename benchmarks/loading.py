"""Benchmark of loading scenes on one thread (BENCHMARKS.md "Loading", docs/MITSUBA.md "Load on one thread").

Two parts, both printed as JSON:

* ``times``: for each scene, the seconds of ``mi.load_dict`` of a5mi's dict and of ``mi.load_file`` of the
  converted XML (``a5mi convert``, a5 plugins), with ``parallel=True`` (Mitsuba's default) and ``parallel=False``
  (a5mi's), alternated in one process, ``--repeat`` times each after one warm-up load: min and median;
* ``stress`` (``--stress N``): N fresh processes, each the plain script of tests/converters/test_interop.py
  loading the first scene's XML with Mitsuba's default and rendering it, ``--workers`` at a time; the failures
  are counted and their last lines printed (the native failure docs/MITSUBA.md describes).

Scenes: the project's own ``scenes/gallery.txt`` and ``scenes/demo.txt``, then the course's scene10 and sibenik when
the course data is present (``--scene`` replaces the list).
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SIZE = ["-size", "200", "200", "-shadows", "-bounces", "4"]
PLAIN = """
import sys
import mitsuba as mi
mi.set_variant("llvm_ad_rgb")
from a5mi.plugins import register_all
register_all()
mi.render(mi.load_file(sys.argv[1]))
"""


def _scenes() -> list[str]:
    from a5mi import data_dir

    own = [str(ROOT / "scenes" / "gallery.txt"), str(ROOT / "scenes" / "demo.txt")]
    course = [data_dir() / "scenes" / "scene10_sphere.txt", data_dir() / "extras" / "sibenik" / "s.txt"]
    return own + [str(p) for p in course if p.is_file()]


def _times(load: object, arg: object, repeat: int) -> dict[str, dict[str, float]]:
    out: dict[str, list[float]] = {"parallel": [], "serial": []}
    for parallel in (True, False):
        load(arg, parallel=parallel)  # type: ignore[operator]  # warm-up: plugins, kernels, caches
    for _ in range(repeat):
        for parallel in (True, False):
            t0 = time.perf_counter()
            load(arg, parallel=parallel)  # type: ignore[operator]
            out["parallel" if parallel else "serial"].append(time.perf_counter() - t0)
    return {k: {"min_s": round(min(v), 4), "median_s": round(statistics.median(v), 4)} for k, v in out.items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", action="append", help="scene file (repeatable); default: the list above")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--stress", type=int, default=0, help="fresh processes loading with Mitsuba's default")
    ap.add_argument("--workers", type=int, default=2)
    a = ap.parse_args()
    from a5mi.cli import run_a5mi
    from a5mi.render.options import RenderOptions
    from a5mi.render.session import describe_file, scene_dict
    from a5mi.runtime.variant import activate

    activate()
    import mitsuba as mi

    scenes = a.scene or _scenes()
    tmp = Path(tempfile.mkdtemp(prefix="a5mi-loading-"))
    options = RenderOptions(width=200, height=200, bounces=4, shadows=True)
    report: dict[str, object] = {"times": {}, "size": "200x200"}
    xmls = []
    for k, scene in enumerate(scenes):
        xml = tmp / f"s{k}.xml"
        assert run_a5mi(["convert", scene, "-o", str(xml), *SIZE]) == 0
        xmls.append(xml)
        desc = describe_file(scene)[0]
        report["times"][Path(scene).name if k < 2 else str(Path(scene).relative_to(Path(scene).parents[1]))] = {
            "dict": _times(lambda d, parallel: mi.load_dict(d, parallel=parallel), scene_dict(desc, options),
                           a.repeat),
            "xml": _times(lambda p, parallel: mi.load_file(str(p), parallel=parallel), xml, a.repeat)}
    if a.stress:
        def one(_: int) -> str:
            p = subprocess.run([sys.executable, "-c", PLAIN, str(xmls[0])], capture_output=True, text=True)
            return "" if p.returncode == 0 else (p.stderr.strip().splitlines() or ["(no output)"])[-1][-300:]

        t0 = time.perf_counter()
        with ThreadPoolExecutor(a.workers) as pool:
            fails = [f for f in pool.map(one, range(a.stress)) if f]
        report["stress"] = {"xml_of": scenes[0], "processes": a.stress, "workers": a.workers,
                            "failures": len(fails), "lines": fails[:5], "wall_s": round(time.perf_counter() - t0, 1)}
    print(json.dumps({k: v for k, v in report.items() if k != "times"}))
    for scene, figures in report["times"].items():  # type: ignore[attr-defined]
        print(json.dumps({"scene": scene, **figures}))


if __name__ == "__main__":
    main()

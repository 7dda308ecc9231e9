"""Error against time of the three indirect-light modes (docs/EXTENSIONS.md E.14-E.23), one process, one
machine: ``-integrator path -spp S``, ``-indirect N`` (a5_whitted) and ``-integrator irradiancecache``.

The scene is ``scenes/ic_sky.txt`` (a white floor and back wall between a red and a green panel, lit by the
background colour alone: colour bleeding), 32 x 32. Whitted's direct light is SPEC B.3's (``kd``, E.15), so only
light that arrives through the gather is comparable: lit by the background, ``-indirect N -bounces 2`` and
``-integrator path -bounces 1`` estimate the same image (E.15), and so does ``-integrator irradiancecache
-bounces 1`` (E.23). The reference is ``-integrator path -bounces 1`` at 4096 passes.
Error: the mean absolute difference over pixels and channels divided by the reference's mean (an RMSE is ruled
by the reference's own rare bright samples: the sky is seen through the box's opening only, and an RMSE
against a 2048-pass reference stalled near 0.14-0.19 for every mode). Time: the render's wall time after a
first render of the same options (Dr.Jit's compile excluded). ``python -m pytest -s -m slow
tests/test_irradiance_cache_bench.py`` prints the table that BENCHMARKS.md quotes.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from a5mi import session
from a5mi.converters.a5_parser import parse_file
from a5mi.converters.describe import describe
from a5mi.driver import render_scene
from a5mi.options import RenderOptions

SCENE = Path(__file__).resolve().parent.parent / "scenes" / "ic_sky.txt"
SIZE, REFERENCE_SPP = 32, 4096

#: (label, options) of each row
ROWS: list[tuple[str, dict[str, Any]]] = [
    *((f"path -spp {s}", {"integrator": "path", "spp": s, "bounces": 1}) for s in (4, 16, 64, 256)),
    *((f"-indirect {n}", {"integrator": "whitted", "shadows": True, "indirect": n, "bounces": 2})
      for n in (4, 16, 32)),
    *((f"irradiancecache -ic_samples {m} -ic_error {a}", {"integrator": "irradiancecache", "ic_samples": m,
                                                           "ic_error": a, "bounces": 1})
      for m, a in ((64, 0.5), (256, 0.3), (1024, 0.2))),
]


def _render(desc: Any, options: RenderOptions) -> tuple[np.ndarray, float]:
    scene = session.build_scene(desc, options)
    render_scene(scene, desc.camera, options)                       # compile
    result = render_scene(scene, desc.camera, options)
    return result.image, result.timings["render"]


def error_versus_time() -> list[tuple[str, float, float]]:
    """``(label, seconds, relative mean absolute error)`` of every row of :data:`ROWS` (module docstring)."""
    desc = describe(parse_file(str(SCENE)))
    base = RenderOptions(width=SIZE, height=SIZE)
    reference, _ = _render(desc, dataclasses.replace(base, integrator="path", spp=REFERENCE_SPP, bounces=1))
    rows = []
    for label, kw in ROWS:
        image, seconds = _render(desc, dataclasses.replace(base, **kw))
        rows.append((label, seconds, float(np.mean(np.abs(image - reference)) / reference.mean())))
    return rows


def time_at_error(points: list[tuple[float, float]], error: float) -> float:
    """Seconds a mode needs for ``error``: log-log interpolation between its ``(seconds, error)`` points
    (extrapolated with the last two beyond them)."""
    pts = sorted(points, key=lambda p: -p[1])
    for (t0, e0), (t1, e1) in zip(pts, pts[1:], strict=False):
        if e1 <= error or (t1, e1) == pts[-1]:
            slope = (math.log(t1) - math.log(t0)) / (math.log(e1) - math.log(e0))
            return math.exp(math.log(t0) + slope * (math.log(error) - math.log(e0)))
    return pts[0][0]


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="measured (BENCHMARKS.md): -indirect 16 reaches a lower error than the cache "
                   "in a sixth of its time at 32-48 pixels, and every mode stalls near 0.14 from the path reference")
def test01_irradiance_cache_beats_indirect_at_equal_error(mi: Any) -> None:
    """The point of the method: for the error the cache reaches, ``-indirect N`` needs more time."""
    rows = error_versus_time()
    print()
    for label, seconds, err in rows:
        print(f"| {label} | {seconds:.2f} | {err:.4f} |")
    indirect = [(t, e) for label, t, e in rows if label.startswith("-indirect")]
    for label, seconds, err in rows:
        if label.startswith("irradiancecache"):
            assert seconds < time_at_error(indirect, err), label

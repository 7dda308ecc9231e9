"""Convergence of the extension's sampling (docs/EXTENSIONS.md E.5): time and RMSE per spp.

:func:`convergence` renders a scene at ``spp`` in ``spps`` and at ``reference_spp`` (the reference, another
seed), and returns per spp the render time (wall seconds, after one warm-up render so compilation is not
counted) and ``RMSE = sqrt(mean((img - ref)²))`` over all pixels and channels, plus the least-squares slope of
``log RMSE`` against ``log spp`` (independent sampling: -1/2; stratified sampling of smooth integrands:
steeper). Returns data; ``a5mi converge`` prints it.
"""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any

import numpy as np


def convergence(scene: str | Path, *, size: int | tuple[int, int] = 300, spps: tuple[int, ...] = (1, 2, 4, 8, 16, 32),
                reference_spp: int = 512, shadows: bool = True, bounces: int = 4) -> dict[str, Any]:
    """``{'rows': [{'spp', 'seconds', 'rmse'}], 'slope', 'reference_spp', 'reference_seconds'}``; ``size``: the
    side of a square image or (width, height)."""
    from a5mi.converters.a5_parser import parse_file
    from a5mi.converters.describe import describe
    from a5mi.render.options import RenderOptions
    from a5mi.render.session import render

    desc = describe(parse_file(scene))
    width, height = (size, size) if isinstance(size, int) else size

    def run(spp: int, seed: int) -> tuple[np.ndarray, float]:
        options = RenderOptions(width=width, height=height, shadows=shadows, bounces=bounces, spp=spp, seed=seed)
        t0 = time.perf_counter()
        image = render(desc, options).image
        return image.astype(np.float64), time.perf_counter() - t0

    run(1, 0)  # warm-up: compile the kernel once
    ref, ref_s = run(reference_spp, 999)
    rows = []
    for spp in spps:
        img, secs = run(spp, 1)
        rows.append({"spp": spp, "seconds": secs, "rmse": float(np.sqrt(np.mean((img - ref) ** 2)))})
    x = np.log([r["spp"] for r in rows])
    y = np.log([max(r["rmse"], 1e-12) for r in rows])
    slope = float(np.polyfit(x, y, 1)[0]) if len(rows) > 1 else math.nan
    return {"rows": rows, "slope": slope, "reference_spp": reference_spp, "reference_seconds": ref_s}

"""``-ic_records IMG``: a picture of where the irradiance cache put its records (docs/EXTENSIONS.md E.23).

The rendered image, dimmed to 50%, with each record drawn where the a5 camera sees its point (SPEC B.2
inverted: ``x = f (d·u)/(d·w)``, ``y = f (d·v)/(d·w)`` for ``d = p_i − center``, pixel
``(x + 1)/2 · (W − 1)``, rows from the bottom): a red dot at its centre (one pixel; a cross of five from 320
pixels wide) and a green circle of its reach ``a R_i`` (where ``ε_i < a`` on its own plane), blended at 40%,
in pixels ``a R_i / s_i`` with ``s_i`` the pixel spacing at the record. A record made at a surface seen in a
mirror or through glass is drawn at its own position, not where it was seen. Records behind the camera are left
out. numpy only.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from a5mi.plugins.integrators.irradiance_cache.grid import RecordSet
from a5mi.vecmath32 import camera_basis

F32 = npt.NDArray[np.float32]

DOT = np.array([1.0, 0.1, 0.1], np.float32)
RING = np.array([0.2, 1.0, 0.3], np.float32)
#: opacity of the rings (overlapping rings stay readable)
RING_ALPHA = 0.4
#: images at least this wide draw each dot as a cross of five pixels
CROSS_WIDTH = 320


def project(points: np.ndarray, camera: Any, render_size: tuple[int, int]) -> tuple[np.ndarray, np.ndarray,
                                                                                    np.ndarray]:
    """``(x_pix, y_pix, depth)`` of world ``points`` (K, 3) in the render buffer ``render_size`` of the a5
    ``camera`` (``center``, ``direction``, ``up``, ``angle``; SPEC B.2, ``y_pix`` from the bottom row); depth
    ``d·w`` (<= 0: behind the camera)."""
    w, u, v = (np.asarray(a, np.float64) for a in camera_basis(camera.direction, camera.up))
    f = 1.0 / np.tan(np.radians(float(camera.angle)) * 0.5)
    d = np.asarray(points, np.float64) - np.asarray(camera.center, np.float64)
    depth = d @ w
    safe = np.where(depth > 0.0, depth, 1.0)
    x, y = f * (d @ u) / safe, f * (d @ v) / safe
    rw, rh = render_size
    return (x + 1.0) * 0.5 * max(rw - 1, 0), (y + 1.0) * 0.5 * max(rh - 1, 0), depth


def picture(image: np.ndarray, camera: Any, render_size: tuple[int, int], records: RecordSet) -> F32:
    """The records picture (module docstring) over ``image`` (H x W x 3, row 0 = top: the saved image, which
    is the render buffer ``render_size`` or its ``-filter`` downsample)."""
    out = np.ascontiguousarray(np.asarray(image, np.float32) * 0.5)
    h, w = out.shape[:2]
    if len(records) == 0:
        return out
    rw, rh = render_size
    sx, sy = w / rw, h / rh
    xb, yb, depth = project(records.p, camera, render_size)
    front = depth > 0.0
    cx = (xb + 0.5) * sx - 0.5
    cy = (h - 1) - ((yb + 0.5) * sy - 0.5)
    radius = records.a * records.R / np.maximum(records.spacing, 1e-30) * sx
    cx, cy, radius = cx[front], cy[front], radius[front]
    # rings: points every half pixel along each circle
    steps = np.maximum(8, np.ceil(4.0 * np.pi * radius)).astype(np.int64)
    owner = np.repeat(np.arange(cx.size), steps)
    angle = 2.0 * np.pi * (np.arange(steps.sum()) - np.repeat(np.cumsum(steps) - steps, steps)) / steps[owner]
    _plot(out, cx[owner] + radius[owner] * np.cos(angle), cy[owner] + radius[owner] * np.sin(angle), RING,
          RING_ALPHA)
    cross = ((0, 0), (1, 0), (-1, 0), (0, 1), (0, -1)) if w >= CROSS_WIDTH else ((0, 0),)
    for dx, dy in cross:
        _plot(out, cx + dx, cy + dy, DOT, 1.0)
    return out


def _plot(out: F32, x: np.ndarray, y: np.ndarray, color: np.ndarray, alpha: float) -> None:
    """Blend ``color`` at ``alpha`` into the pixels nearest to ``(x, y)`` (each pixel once per call)."""
    xi, yi = np.rint(x).astype(np.int64), np.rint(y).astype(np.int64)
    h, w = out.shape[:2]
    ok = (xi >= 0) & (xi < w) & (yi >= 0) & (yi < h)
    flat = np.unique(yi[ok] * w + xi[ok])
    rows, cols = flat // w, flat % w
    out[rows, cols] = (1.0 - alpha) * out[rows, cols] + alpha * color

"""Separable blur and 3x3 box downsample (SPEC B.5), in float32 numpy, in the binary's operation order.

Images are ``img[j, i, c]`` float32 arrays with ``j = 0`` the **bottom** row, as the sample solution stores
them (the downsample's 3x3 blocks start at the bottom-left pixel).

* Blur: ``K = (0.1201, 0.2339, 0.2921, 0.2339, 0.1201)`` as stored in the binary (sum 1.0001, not
  normalised); the handout prints the centre tap as 0.2931 (sum 1.0011), available as ``kernel="handout"``.
  First along y into a new buffer, ``t[j,i] = Σ_k K[k] · img[clamp(j+k-2, 0, H-1), i]``, then along x,
  ``out[j,i] = Σ_k K[k] · t[j, clamp(i+k-2, 0, W-1)]``; taps accumulate in k order in float32. Each axis
  clamps to its own size (the binary clamps both to W-1, which aborts on non-square images).
  A constant image c becomes ``(ΣK)² · c``.
* Downsample: ``out[y,x] = (Σ_{dx=0..2} Σ_{dy=0..2} img[3y+dy, 3x+dx]) / 9.0f`` (x outer, y inner), giving
  ``W//3 x H//3``.
* Flag combinations (:func:`postprocess`): ``-jitter -filter`` -> W x H from the 3W x 3H render;
  ``-jitter`` alone keeps 3W x 3H; ``-filter`` alone blurs and downsamples the W x H render to W/3 x H/3.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import numpy.typing as npt

#: The blur kernel the sample solution uses (SPEC B.5), and the handout's printed one (centre-tap typo).
KERNELS: dict[str, tuple[float, ...]] = {
    "binary": (0.1201, 0.2339, 0.2921, 0.2339, 0.1201),
    "handout": (0.1201, 0.2339, 0.2931, 0.2339, 0.1201),
}

FloatImage = npt.NDArray[np.float32]


def kernel_taps(kernel: str = "binary") -> npt.NDArray[np.float32]:
    """The five float32 taps of ``kernel`` (``"binary"``: centre 0.2921, ``"handout"``: centre 0.2931)."""
    try:
        return np.array(KERNELS[kernel], dtype=np.float32)
    except KeyError:
        raise ValueError(f"unknown blur kernel '{kernel}' (expected binary or handout)") from None


def _blur_axis(img: FloatImage, taps: npt.NDArray[np.float32], axis: int, size: int) -> FloatImage:
    """``out[n] = Σ_k taps[k] · img[n+k]`` for ``n < size`` along ``axis`` of an image already padded by 2
    (the clamped taps), accumulated in float32 in k order."""
    shape = list(img.shape)
    shape[axis] = size
    out = np.zeros(shape, np.float32)
    term = np.empty(shape, np.float32)
    for k, w in enumerate(taps):
        window = [slice(None)] * img.ndim
        window[axis] = slice(k, k + size)
        np.multiply(img[tuple(window)], w, out=term)
        out += term
    return out


def _blur_strip(plane: FloatImage, taps: npt.NDArray[np.float32], r0: int, r1: int, out: FloatImage) -> None:
    """Rows ``r0..r1-1`` of the blurred 2-D ``plane``: y pass over the clamped rows r0-2..r1+1, then x pass."""
    h, w = plane.shape
    rows = np.clip(np.arange(r0 - 2, r1 + 2), 0, h - 1)
    tmp = _blur_axis(plane[rows], taps, 0, r1 - r0)
    cols = np.clip(np.arange(-2, w + 2), 0, w - 1)
    out[r0:r1] = _blur_axis(tmp[:, cols], taps, 1, w)


def blur(img: npt.ArrayLike, kernel: str = "binary", strip_rows: int = 64) -> FloatImage:
    """The separable blur of SPEC B.5: along y (axis 0) into a new buffer, then along x (axis 1).

    Computed per channel in strips of ``strip_rows`` rows (cache-sized, spread over threads; numpy releases
    the GIL); every pixel sees the same float32 operations in the same order as the whole-image formula.
    """
    a = np.asarray(img, dtype=np.float32)
    if a.ndim < 2:
        raise ValueError(f"blur needs an image of at least 2 dimensions, got shape {a.shape}")
    taps = kernel_taps(kernel)
    result = np.empty_like(a)
    index = [(...,)] if a.ndim == 2 else [(slice(None), slice(None)) + c for c in np.ndindex(*a.shape[2:])]
    jobs = [(a[i], result[i], r0, min(a.shape[0], r0 + strip_rows))
            for i in index for r0 in range(0, a.shape[0], strip_rows)]
    workers = min(len(jobs), os.cpu_count() or 1)
    if workers <= 1:
        for plane, out, r0, r1 in jobs:
            _blur_strip(plane, taps, r0, r1, out)
    else:
        with ThreadPoolExecutor(max_workers=workers) as pool:
            list(pool.map(lambda job: _blur_strip(job[0], taps, job[2], job[3], job[1]), jobs))
    return result


def downsample3(img: npt.ArrayLike) -> FloatImage:
    """3x3 box downsample (SPEC B.5): sum 9 pixels x-outer, y-inner in float32, then divide by 9.0f."""
    a = np.asarray(img, dtype=np.float32)
    h, w = a.shape[0] // 3, a.shape[1] // 3
    if h == 0 or w == 0:
        raise ValueError(f"cannot downsample a {a.shape[1]}x{a.shape[0]} image by 3")
    s = np.zeros((h, w) + a.shape[2:], dtype=np.float32)
    for dx in range(3):
        for dy in range(3):
            s += a[dy : 3 * h : 3, dx : 3 * w : 3]
    return s / np.float32(9.0)


def output_size(width: int, height: int, *, jitter: bool, filter: bool) -> tuple[int, int]:
    """Size of the saved image for ``-size width height`` and the flags (SPEC B.5 table)."""
    if jitter and filter:
        return width, height
    if jitter:
        return 3 * width, 3 * height
    if filter:
        return width // 3, height // 3
    return width, height


def postprocess(img: npt.ArrayLike, *, filter: bool, kernel: str = "binary") -> FloatImage:
    """The image the binary saves from its render buffer: blur + downsample with ``-filter``, else as is.

    The render buffer is 3W x 3H with ``-jitter`` and W x H without; SPEC B.5's table follows from that.
    """
    a = np.asarray(img, dtype=np.float32)
    if not filter:
        return a
    return downsample3(blur(a, kernel))

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

import functools
import os
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import ParamSpec, TypeVar

import numpy as np
import numpy.typing as npt

P = ParamSpec("P")
R = TypeVar("R")

#: The blur kernel the sample solution uses (SPEC B.5), and the handout's printed one (centre-tap typo).
KERNELS: dict[str, tuple[float, ...]] = {
    "binary": (0.1201, 0.2339, 0.2921, 0.2339, 0.1201),
    "handout": (0.1201, 0.2339, 0.2931, 0.2339, 0.1201),
}

FloatImage = npt.NDArray[np.float32]


def _ieee(fn: Callable[P, R]) -> Callable[P, R]:
    """Run ``fn`` with numpy's floating-point warnings off: colours may be any finite float (SPEC A.5), and
    their float32 blur overflowing to inf (quantised to 255) is the sample solution's arithmetic too, not a
    message for the user (SPEC B.1: quantisation clamps)."""

    @functools.wraps(fn)
    def wrapped(*args: P.args, **kwargs: P.kwargs) -> R:
        with np.errstate(over="ignore", invalid="ignore", under="ignore"):
            return fn(*args, **kwargs)

    return wrapped


def kernel_taps(kernel: str = "binary") -> npt.NDArray[np.float32]:
    """The five float32 taps of ``kernel`` (``"binary"``: centre 0.2921, ``"handout"``: centre 0.2931)."""
    try:
        return np.array(KERNELS[kernel], dtype=np.float32)
    except KeyError:
        raise ValueError(f"unknown blur kernel '{kernel}' (expected binary or handout)") from None


@_ieee
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


@_ieee
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


@_ieee
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


class FilterStream:
    """Blur + 3x3 downsample (SPEC B.5) of a render buffer that arrives as bottom-up row bands.

    :meth:`push` takes the next rows ``j0..j1-1`` of the ``width x height`` buffer (``j0`` = the rows
    pushed so far); :attr:`image` fills in output rows as soon as they are determined. Output row ``y`` is
    ``Σ_{dx} Σ_{dy} blur[3y+dy, 3x+dx] / 9`` and blurred row ``r`` reads render rows ``clamp(r-2 .. r+2)``,
    so ``y`` is final once render row ``min(3y+4, height-1)`` has arrived. Only the rows still needed
    (at most the last band plus 6 rows) are kept, so memory is bounded by the band size, not by
    ``height``; every pixel sees the float32 operations of :func:`postprocess` in the same order (the y
    taps over the same clamped rows, then the x taps, then the downsample), so the result is bit-identical.
    """

    def __init__(self, width: int, height: int, kernel: str = "binary", channels: int = 3) -> None:
        if width // 3 == 0 or height // 3 == 0:
            raise ValueError(f"cannot downsample a {width}x{height} image by 3")
        self.width, self.height, self.channels = width, height, channels
        self.taps = kernel_taps(kernel)
        #: The output image, ``height//3 x width//3 x channels``, row 0 = the bottom row.
        self.image: FloatImage = np.empty((height // 3, width // 3, channels), np.float32)
        self.rows_in = 0  # render rows pushed so far
        self.rows_out = 0  # output rows finished
        self._window = np.empty((0, width, channels), np.float32)  # render rows [_base, rows_in)
        self._base = 0
        self.peak_window_rows = 0  # largest number of render rows held at once (tests, BENCHMARKS.md)

    def push(self, rows: npt.ArrayLike) -> None:
        """Append the next band of render rows (``n x width x channels`` float32, bottom-up)."""
        band = np.asarray(rows, dtype=np.float32)
        if band.shape[1:] != (self.width, self.channels):
            raise ValueError(f"expected rows of shape (n, {self.width}, {self.channels}), got {band.shape}")
        if self.rows_in + band.shape[0] > self.height:
            raise ValueError(f"more than {self.height} rows pushed")
        self._window = np.concatenate([self._window, band]) if self._window.shape[0] else band
        self.rows_in += band.shape[0]
        self.peak_window_rows = max(self.peak_window_rows, self._window.shape[0])
        complete = self.rows_in == self.height
        # output row y needs blurred rows 3y..3y+2, i.e. render rows up to 3y+4 (clamped to height-1)
        ready = self.image.shape[0] if complete else max(0, (self.rows_in - 5) // 3 + 1)
        ready = min(ready, self.image.shape[0])
        if ready > self.rows_out:
            self._filter_rows(3 * self.rows_out, 3 * ready)
            self.rows_out = ready
        # keep render rows from 3*rows_out - 2 on (the next output row's lowest y tap)
        keep = max(0, 3 * self.rows_out - 2) if not complete else self.rows_in
        if keep > self._base:
            self._window = self._window[keep - self._base :].copy()
            self._base = keep

    def _filter_rows(self, r0: int, r1: int, strip_rows: int = 48) -> None:
        """Output rows ``r0/3 .. r1/3 - 1`` from the window: per channel and per strip of ``strip_rows``
        blurred rows (a multiple of 3, cache-sized), spread over threads (numpy releases the GIL)."""
        cols = np.clip(np.arange(-2, self.width + 2), 0, self.width - 1)

        def job(c: int, s0: int, s1: int) -> None:
            rows = np.clip(np.arange(s0 - 2, s1 + 2), 0, self.height - 1) - self._base
            tmp = _blur_axis(self._window[rows, :, c], self.taps, 0, s1 - s0)
            blurred = _blur_axis(tmp[:, cols], self.taps, 1, self.width)
            self.image[s0 // 3 : s1 // 3, :, c] = downsample3(blurred)

        jobs = [(c, s0, min(r1, s0 + strip_rows)) for c in range(self.channels) for s0 in range(r0, r1, strip_rows)]
        workers = min(len(jobs), os.cpu_count() or 1)
        if workers <= 1:
            for j in jobs:
                job(*j)
        else:
            with ThreadPoolExecutor(max_workers=workers) as pool:
                list(pool.map(lambda j: job(*j), jobs))

    def result(self) -> FloatImage:
        """The filtered image once every row has been pushed (``ValueError`` before)."""
        if self.rows_in != self.height:
            raise ValueError(f"only {self.rows_in} of {self.height} rows pushed")
        return self.image


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


@_ieee
def mistaken_postprocess(img: npt.ArrayLike, mistakes: tuple[str, ...], kernel: str = "binary") -> FloatImage:
    """SPEC B.5's blur + downsample of a render buffer (``img[j, i, c]``, row 0 = bottom) as a student with the
    docs/MISTAKES.md ``mistakes`` of :data:`a5mi.render.options.FILTER_MISTAKES` computes it:

    * ``blur_not_normalised``: taps ``K / K[2]`` (the Gaussian's peak is 1; ΣK = 3.42 per pass);
    * ``blur_one_direction``: the y pass only;
    * ``blur_zero_border``: taps outside the image read 0 instead of the clamped edge pixel;
    * ``no_blur``: no blur, the 3x3 box downsample only;
    * ``downsample_one_sample``: ``out[y, x] = blurred[3y + 1, 3x + 1]`` (the centre sample, not the mean).
    """
    a = np.asarray(img, dtype=np.float32)
    taps = kernel_taps(kernel)
    if "blur_not_normalised" in mistakes:
        taps = (taps / taps[2]).astype(np.float32)
    h, w = a.shape[:2]
    if "no_blur" not in mistakes:
        zero = "blur_zero_border" in mistakes

        def padded(axis: int) -> FloatImage:
            n = a.shape[axis] if axis == 0 else w
            src = a if axis == 0 else out
            idx = np.clip(np.arange(-2, n + 2), 0, n - 1)
            p = np.take(src, idx, axis=axis)
            if zero:
                edge = [slice(None)] * p.ndim
                for s in (slice(0, 2), slice(n + 2, n + 4)):
                    edge[axis] = s
                    p[tuple(edge)] = 0.0
            return p

        out = _blur_axis(padded(0), taps, 0, h)
        if "blur_one_direction" not in mistakes:
            out = _blur_axis(padded(1), taps, 1, w)
        a = out
    if "downsample_one_sample" in mistakes:
        return np.ascontiguousarray(a[1 : 3 * (h // 3) : 3, 1 : 3 * (w // 3) : 3])
    return downsample3(a)


def srgb_encode(c: npt.ArrayLike) -> FloatImage:
    """The sRGB transfer function (IEC 61966-2-1): ``12.92 c`` for ``c <= 0.0031308``, else
    ``1.055 c^(1/2.4) - 0.055``, on ``c`` clamped to [0, 1]."""
    x = np.clip(np.asarray(c, dtype=np.float64), 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055).astype(np.float32)


def image_mistakes(img: npt.ArrayLike, mistakes: tuple[str, ...]) -> FloatImage:
    """The saved image (row 0 = **top**, float, quantised later by SPEC B.1's ``clamp(int(255 c), 0, 255)``) as a
    student with the docs/MISTAKES.md ``mistakes`` of :data:`a5mi.render.options.IMAGE_MISTAKES` writes it:

    * ``upside_down``: rows reversed (row 0 written as the bottom row); ``mirrored``: columns reversed;
    * ``red_blue_swapped``: channels (B, G, R);
    * ``srgb_gamma``: :func:`srgb_encode` applied before quantising;
    * ``colours_wrapped``: ``byte = int(255 c) mod 256`` (no clamp), returned as ``(byte + 0.5) / 255`` so SPEC
      B.1's quantisation writes that byte;
    * ``rounding``: ``byte = clamp(round(255 c), 0, 255)`` instead of truncation, returned likewise.
    """
    a = np.asarray(img, dtype=np.float32)
    if "upside_down" in mistakes:
        a = a[::-1]
    if "mirrored" in mistakes:
        a = a[:, ::-1]
    if "red_blue_swapped" in mistakes:
        a = a[..., ::-1]
    if "srgb_gamma" in mistakes:
        a = srgb_encode(a)
    with np.errstate(invalid="ignore", over="ignore"):
        if "colours_wrapped" in mistakes:
            byte = np.mod(np.trunc(np.nan_to_num(a.astype(np.float64) * 255.0, posinf=0.0, neginf=0.0)), 256.0)
            a = ((byte + 0.5) / 255.0).astype(np.float32)
        if "rounding" in mistakes:
            byte = np.clip(np.floor(a.astype(np.float64) * 255.0 + 0.5), 0.0, 255.0)
            a = ((byte + 0.5) / 255.0).astype(np.float32)
    return np.ascontiguousarray(a, dtype=np.float32)

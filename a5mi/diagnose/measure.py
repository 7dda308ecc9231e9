"""The measures of ``a5mi diagnose`` (docs/MISTAKES.md "The measure: explained share", "Evidence").

:func:`explained` is ``E(M) = 1 - ||I - M||² / ||I - R||²`` over the 8-bit images, :func:`explained_at` the larger
of it over pixels and over 4x4-pixel block means; :func:`sample_positions` and :func:`resample` put the image at a
small render's sample positions (SPEC B.2, B.5); :func:`evidence` says where a cause acts; :data:`REVERSIBLE`
undoes saved-image mistakes; :func:`log_likelihood` is the image's likelihood under a mutant with the mutant's
jitter noise counted (docs/MISTAKES.md "Closest causes: the likelihood with the noise"); :func:`crps` and
:func:`paired_z` weigh a partner (docs/MISTAKES.md "Partners: the paired score"). numpy only.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from a5mi.platform.imageio import quantize

Image = npt.NDArray[np.float64]

#: A pixel "differs" when some channel is more than this many levels away.
LEVELS = 2


def srgb_decode(c: Image) -> Image:
    """The inverse of :func:`a5mi.render.filters.srgb_encode` on [0, 1]."""
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


#: Saved-image mistakes and how to undo them (a pair's other mistake is then looked for in what is left).
REVERSIBLE: dict[str, Callable[[Image], Image]] = {
    "upside_down": lambda a: a[::-1], "mirrored": lambda a: a[:, ::-1], "red_blue_swapped": lambda a: a[..., ::-1],
    "srgb_gamma": srgb_decode,
}


@dataclass
class Evidence:
    """Where a cause acts: ``box`` (x0, y0, x1, y1, pixels, row 0 = top, end exclusive) of the pixels that differ
    from the reference, ``region`` (its place in words), ``differing`` (share of the image's pixels that differ),
    ``fixed`` (share of those the mutant reproduces within :data:`LEVELS` levels), ``psnr_before`` (image vs
    reference) and ``psnr_after`` (image vs mutant), dB."""

    box: tuple[int, int, int, int] | None
    region: str
    differing: float
    fixed: float
    psnr_before: float
    psnr_after: float


def psnr_of(mse: float) -> float:
    """PSNR in dB of a mean squared error of [0, 1] images (inf for 0)."""
    return math.inf if mse <= 0.0 else -10.0 * math.log10(mse)


def as_levels(img: npt.ArrayLike) -> Image:
    """A float render quantised as SPEC B.1 writes it, scaled to [0, 1] (float64, 3 channels)."""
    return quantize(np.asarray(img)[..., :3]).astype(np.float64) / 255.0


def mse(a: Image, b: Image) -> float:
    return float(np.mean((a - b) ** 2))


def explained(image: Image, reference: Image, mutant: Image) -> float:
    """``E = 1 - ||I - M||² / ||I - R||²`` (module docstring); 0 when ``I = R``."""
    base = float(np.sum((image - reference) ** 2))
    return 0.0 if base == 0.0 else 1.0 - float(np.sum((image - mutant) ** 2)) / base


#: Side of the blocks of the coarse scale (pixels).
BLOCK = 4


def blocks(img: Image, k: int = BLOCK) -> Image:
    """``img`` averaged over ``k x k`` blocks (cropped to whole blocks; unchanged when smaller than a block)."""
    h, w = img.shape[:2]
    if h < k or w < k:
        return img
    c = img[: h - h % k, : w - w % k]
    return c.reshape(h // k, k, w // k, k, -1).mean(axis=(1, 3))


def explained_at(image: Image, reference: Image, mutant: Image) -> tuple[float, str]:
    """``(E, scale)``: the larger of :func:`explained` over pixels and over :func:`blocks`, and which
    (``pixels`` or ``blocks``)."""
    fine = explained(image, reference, mutant)
    coarse = explained(blocks(image), blocks(reference), blocks(mutant))
    return (fine, "pixels") if fine >= coarse else (coarse, "blocks")


#: Side of the neighbourhood over which the per-pixel seed variance is averaged (pixels).
NEIGHBOURHOOD = 3
#: Variance of the difference of two images quantised by truncation to 8 bits (two uniform errors of one level):
#: ``2 · 1/12`` levels², in [0, 1] units.
QUANTISATION_VARIANCE = 2.0 / 12.0 / 255.0 ** 2


def box_mean(a: Image, k: int = NEIGHBOURHOOD) -> Image:
    """``a`` (H x W x C) averaged over the ``k x k`` pixels around each pixel (edges repeated)."""
    r = k // 2
    p = np.pad(a, ((r, r), (r, r), (0, 0)), mode="edge")
    h, w = a.shape[:2]
    return sum(p[i:i + h, j:j + w] for i in range(k) for j in range(k)) / float(k * k)


def log_likelihood(image: Image, mutant: Image, second: Image) -> float:
    """The mean log-likelihood per value of ``image`` under the hypothesis that it was rendered like ``mutant``
    with other jitter offsets (docs/MISTAKES.md "Closest causes"): ``second`` is the mutant with another seed.

    Each value is Gaussian about the mutant's, ``I - M ~ N(0, s²)`` with ``s² = 2 v + q``: ``v`` the mutant's seed
    variance at that pixel, ``(M - M₂)² / 2`` averaged over the :data:`NEIGHBOURHOOD` x :data:`NEIGHBOURHOOD` pixels
    around it (jitter noise sits on edges: one variance for the whole image would not do), doubled because the
    image and the mutant carry independent noise, ``q`` :data:`QUANTISATION_VARIANCE`. Result:
    ``mean(-(I - M)² / (2 s²) - ln(2π s²) / 2)``; a mutant free of jitter noise has ``s² = q``."""
    v = box_mean((mutant - second) ** 2 / 2.0)
    s2 = 2.0 * v + QUANTISATION_VARIANCE
    return float(np.mean(-((image - mutant) ** 2) / (2.0 * s2) - 0.5 * np.log(2.0 * math.pi * s2)))


def crps(image: Image, members: list[Image]) -> npt.NDArray[np.float64]:
    """The continuous ranked probability score of each pixel of ``image`` under the hypothesis whose renders with
    independent jitter seeds are ``members`` (docs/MISTAKES.md "Partners: the paired score"), summed over
    the channels; lower is better. The fair ensemble estimate with ``K = len(members)``:

        CRPS(I) = (1/K) Σ_k |I - M_k| - 1/(2 K (K - 1)) Σ_{k≠l} |M_k - M_l|

    unbiased for ``E|I - M| - E|M - M'| / 2`` (M, M' two renders of the hypothesis); ``K = 1`` for a hypothesis
    free of jitter noise: ``|I - M|``. CRPS is strictly proper: in expectation an image scores best under the
    hypothesis it was made by, its noise included, so a mistake that only changes the noise wins only on an image
    with that noise, and a noise-free mutant wins nothing on an image made with other jitter offsets."""
    k = len(members)
    near = sum(np.abs(image - m) for m in members) / k
    spread = (sum(np.abs(a - b) for i, a in enumerate(members) for b in members[i + 1:]) / (k * (k - 1))
              if k > 1 else 0.0)
    return np.asarray(np.sum(near - spread, axis=-1), np.float64)


def paired_z(gain: npt.NDArray[np.float64], k: int = BLOCK) -> float:
    """The paired z statistic of a per-pixel score difference ``gain`` (H x W): its sums over ``k x k`` blocks
    ``g_b``, ``z = mean(g_b) / (sd(g_b) / sqrt(n))`` over the n blocks (blocks, not pixels: the blur makes
    neighbouring pixels' noise correlated; blocks of 4 pixels a side are nearly independent). ``inf`` when every
    block gains the same positive amount, 0 for fewer than two blocks or no gain anywhere."""
    h, w = gain.shape
    if h < k or w < k:
        return 0.0
    g = gain[: h - h % k, : w - w % k].reshape(h // k, k, w // k, k).sum(axis=(1, 3)).ravel()
    mean = float(np.mean(g))
    sd = float(np.std(g, ddof=1)) if g.size > 1 else 0.0
    if sd == 0.0:
        return math.inf if mean > 0.0 and g.size > 1 else 0.0
    return mean / (sd / math.sqrt(g.size))


def sample_positions(n_small: int, n_full: int, supersampled: bool) -> npt.NDArray[np.float64]:
    """Continuous pixel positions in the full image of the ``n_small`` pixel centres of a small render along one
    axis (SPEC B.2: the small render's pixel ``k`` looks along ``x = 2k/(n-1) - 1``; the full image's pixel ``i``
    along ``2i/(N-1) - 1``, or, with ``-jitter -filter``, along its 3x3 block's centre sample
    ``2(3i+1)/(3N-1) - 1``)."""
    x = 2.0 * np.arange(n_small) / max(n_small - 1, 1) - 1.0
    if supersampled:
        return ((x + 1.0) * (3 * n_full - 1) / 2.0 - 1.0) / 3.0
    return (x + 1.0) * (n_full - 1) / 2.0


def resample(img: Image, xs: npt.NDArray[np.float64], ys: npt.NDArray[np.float64]) -> Image:
    """``img`` (row 0 = top) bilinearly interpolated at columns ``xs`` and rows ``ys`` counted from the bottom
    (positions clamped to the image)."""
    h, w = img.shape[:2]
    up = img[::-1]
    xs, ys = np.clip(xs, 0.0, w - 1.0), np.clip(ys, 0.0, h - 1.0)
    x0, y0 = np.minimum(xs.astype(int), w - 2 if w > 1 else 0), np.minimum(ys.astype(int), h - 2 if h > 1 else 0)
    x1, y1 = np.minimum(x0 + 1, w - 1), np.minimum(y0 + 1, h - 1)
    a, b = (xs - x0)[None, :, None], (ys - y0)[:, None, None]
    out = ((1 - a) * (1 - b) * up[np.ix_(y0, x0)] + a * (1 - b) * up[np.ix_(y0, x1)]
           + (1 - a) * b * up[np.ix_(y1, x0)] + a * b * up[np.ix_(y1, x1)])
    return out[::-1]


def region_words(box: tuple[int, int, int, int], w: int, h: int) -> str:
    """Where a box lies in the image, in words: ``whole image``, or e.g. ``top left``, ``centre``, ``bottom``."""
    x0, y0, x1, y1 = box
    if (x1 - x0) * (y1 - y0) >= 0.6 * w * h:
        return "whole image"
    cx, cy = (x0 + x1) / 2 / w, (y0 + y1) / 2 / h
    vert = "top" if cy < 1 / 3 else "bottom" if cy > 2 / 3 else ""
    horiz = "left" if cx < 1 / 3 else "right" if cx > 2 / 3 else ""
    return " ".join(p for p in (vert, horiz) if p) or "centre"


def evidence(image: Image, reference: Image, mutant: Image, noise: float = 0.0) -> Evidence:
    """The :class:`Evidence` of a mutant (module docstring); a pixel differs by more than :data:`LEVELS` levels
    and three times the RMS jitter noise ``sqrt(noise)``."""
    tol = max(LEVELS / 255.0, 3.0 * math.sqrt(noise)) + 1e-9
    differs = np.any(np.abs(image - reference) > tol, axis=-1)
    fixed = differs & np.all(np.abs(image - mutant) <= tol, axis=-1)
    h, w = differs.shape
    box = None
    region = "nowhere"
    if differs.any():
        ys, xs = np.nonzero(differs)
        box = (int(xs.min()), int(ys.min()), int(xs.max()) + 1, int(ys.max()) + 1)
        region = region_words(box, w, h)
    n = int(differs.sum())
    return Evidence(box, region, n / differs.size, (int(fixed.sum()) / n) if n else 0.0,
                    psnr_of(mse(image, reference)), psnr_of(mse(image, mutant)))

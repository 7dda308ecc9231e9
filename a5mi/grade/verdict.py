"""Verdicts of one submitted image against its reference (thresholds: ``docs/GRADING.md``).

Jittered renders of a correct ray tracer differ from the reference wherever the jitter samples matter (edges,
shadow boundaries, refraction): 2-24% of the pixels of a correct 100x100 ``-jitter -filter`` render drawn with
other samples are off by more than 2/255. So the verdict is not taken on the raw error but against the
**noise band** of the case: ``sigma`` = per-pixel, per-channel standard deviation of K renders of the case with
different jitter seeds (:mod:`a5mi.grade.references`). A pixel is *beyond noise* when

    max_c ( |s_c - r_c| - (NOISE_K * sigma_c + NOISE_FLOOR) ) > 0          (levels of 255)

and the verdict is ``match`` when the share of such pixels is <= ``match``, ``close`` when <= ``close``,
``wrong`` above (sizes must agree first: ``wrong size``). A pixel with a NaN or infinite channel (in either
image, or in ``sigma``) is beyond noise, and an image with any such pixel (``max_error`` not finite,
:func:`a5mi.compare.compare_arrays`) is ``wrong`` whatever the share: a non-finite value is never a match.
Without a noise band (``sigma`` None) sigma is 0 and the rule is the plain share of pixels over ``NOISE_FLOOR``.

The other metrics are reported, not judged on: PSNR, mean absolute error, share of pixels > 2/255
(:mod:`a5mi.compare`) and NVIDIA FLIP (LDR mean, heatmap; PyPI ``flip-evaluator``).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from a5mi.compare import compare_arrays
from a5mi.runtime.extras import require

#: Verdicts, best first; ``points`` are given for ``match`` (full) and ``close`` (CLOSE_CREDIT of them).
VERDICTS: tuple[str, ...] = ("match", "close", "wrong", "wrong size", "no output", "unreadable", "crash",
                             "timeout", "over memory")
CLOSE_CREDIT = 0.5
#: sigma multiple and floor (levels) of the noise band.
NOISE_K = 4.0
NOISE_FLOOR = 1.0


@dataclass(frozen=True)
class Thresholds:
    """Share of pixels beyond noise: ``match`` at most, ``close`` at most (calibrated, docs/GRADING.md)."""

    match: float = 0.01
    close: float = 0.015


@dataclass(frozen=True)
class ImageMetrics:
    """``beyond_noise`` (the judged share), ``psnr`` (dB, inf = identical), ``mean_error`` and ``max_error``
    (levels), ``share_over_2`` (pixels > 2/255), ``flip`` (mean LDR FLIP, None when not computed)."""

    beyond_noise: float
    psnr: float
    mean_error: float
    share_over_2: float
    max_error: float
    flip: float | None

    def as_dict(self) -> dict[str, Any]:
        d = {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in asdict(self).items()}
        d["psnr"] = None if not math.isfinite(self.psnr) else round(self.psnr, 3)
        return d

    def summary(self) -> str:
        psnr = f"{self.psnr:.1f}" if math.isfinite(self.psnr) else f"{self.psnr:g}"
        flip = "" if self.flip is None else f", FLIP {self.flip:.4f}"
        return (f"{100 * self.beyond_noise:.2f}% of pixels beyond noise, PSNR {psnr} dB, mean "
                f"{self.mean_error:.3f}/255, {100 * self.share_over_2:.2f}% > 2/255{flip}")


def beyond_noise(student: np.ndarray, reference: np.ndarray, sigma: np.ndarray | None) -> np.ndarray:
    """Boolean (H, W): pixels whose error exceeds the noise band (module docstring formula)."""
    band = NOISE_FLOOR + (0.0 if sigma is None else NOISE_K * np.asarray(sigma, dtype=np.float64))
    with np.errstate(invalid="ignore", over="ignore"):
        excess = np.abs(student.astype(np.float64) - reference.astype(np.float64)) - band
        return ~(excess.max(axis=2) <= 0)  # NaN (a non-finite value anywhere) counts as beyond noise


def flip_map(reference: np.ndarray, student: np.ndarray) -> tuple[np.ndarray, float]:
    """NVIDIA FLIP (LDR, default 67 pixels per degree) of two images in levels: (magma heatmap in levels
    (H, W, 3), mean FLIP in [0, 1])."""
    flip_evaluator = require("flip_evaluator", "grade")

    ref = np.ascontiguousarray(np.clip(reference / 255.0, 0, 1), dtype=np.float32)
    test = np.ascontiguousarray(np.clip(student / 255.0, 0, 1), dtype=np.float32)
    heat, mean, _ = flip_evaluator.evaluate(ref, test, "LDR")
    return np.asarray(heat, dtype=np.float64) * 255.0, float(mean)


def measure(student: np.ndarray, reference: np.ndarray, sigma: np.ndarray | None = None, *,
            flip: bool = True) -> tuple[ImageMetrics, np.ndarray | None]:
    """Metrics of two same-size images (levels) and the FLIP heatmap (None without ``flip``)."""
    m = compare_arrays(student, reference, 2.0)
    heat, flip_mean = flip_map(reference, student) if flip else (None, None)
    metrics = ImageMetrics(beyond_noise=float(beyond_noise(student, reference, sigma).mean()), psnr=m.psnr,
                           mean_error=m.mean_error, share_over_2=m.share_over, max_error=m.max_error,
                           flip=flip_mean)
    return metrics, heat


def judge(metrics: ImageMetrics, thresholds: Thresholds = Thresholds()) -> str:
    """``match`` / ``close`` / ``wrong`` from the share of pixels beyond noise; ``wrong`` when any pixel is not
    finite (``max_error`` inf or NaN)."""
    if not math.isfinite(metrics.max_error):
        return "wrong"
    if metrics.beyond_noise <= thresholds.match:
        return "match"
    return "close" if metrics.beyond_noise <= thresholds.close else "wrong"


def points_for(verdict: str, points: float) -> float:
    """Rubric: full points for ``match``, ``CLOSE_CREDIT`` of them for ``close``, none otherwise."""
    return points if verdict == "match" else points * CLOSE_CREDIT if verdict == "close" else 0.0


__all__ = ["CLOSE_CREDIT", "ImageMetrics", "NOISE_FLOOR", "NOISE_K", "Thresholds", "VERDICTS", "beyond_noise",
           "flip_map", "judge", "measure", "points_for"]

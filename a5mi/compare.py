"""Image comparison: the metrics every fidelity claim of a5mi is stated in, and a diff montage.

All metrics are on the 8-bit scale of the reference images (levels 0..255; float images such as EXR are
multiplied by 255 first, without quantising):

* ``psnr``        PSNR = 10 log10(255² / MSE), MSE over all pixels and channels (inf for identical images);
* ``mean_error``  mean absolute error, in levels (1/255 units);
* ``share_over``  share of pixels whose largest channel error exceeds ``threshold`` levels (default 2);
* ``max_error``   largest channel error, in levels;
* ``bbox``        (x0, y0, x1, y1), inclusive, of the pixels over the threshold, in file coordinates
  (row 0 = top row of the file), or None.

``a5mi compare A B [--diff OUT.png] [--json]`` prints them; ``--diff`` writes A, B and a false-colour heatmap of
the largest channel error side by side, with the metrics in a caption row.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from a5mi.errors import UserError
from a5mi.imageio import read_levels

DEFAULT_THRESHOLD = 2.0


class CompareError(UserError):
    """An image cannot be read, or the two images cannot be compared (user-fixable)."""


@dataclass(frozen=True)
class Metrics:
    psnr: float
    mean_error: float
    share_over: float
    max_error: float
    bbox: tuple[int, int, int, int] | None
    threshold: float
    width: int
    height: int

    def summary(self) -> str:
        """One line, e.g. ``PSNR 67.3 dB, mean 0.02/255, 0.01% of pixels > 2/255, max 14/255``."""
        psnr = "inf" if math.isinf(self.psnr) else f"{self.psnr:.1f}"
        return (
            f"PSNR {psnr} dB, mean {self.mean_error:.3f}/255, {100 * self.share_over:.2f}% of pixels "
            f"> {self.threshold:g}/255, max {self.max_error:g}/255"
        )

    def to_json(self) -> str:
        d = asdict(self)
        d["psnr"] = None if math.isinf(self.psnr) else self.psnr
        return json.dumps(d)


def compare_arrays(a: np.ndarray, b: np.ndarray, threshold: float = DEFAULT_THRESHOLD) -> Metrics:
    """Metrics of two (H, W, 3) arrays in levels (see module docstring for the formulas)."""
    if a.shape != b.shape:
        raise CompareError(f"image sizes differ: {a.shape[1]}x{a.shape[0]} vs {b.shape[1]}x{b.shape[0]}")
    diff = np.abs(a.astype(np.float64) - b.astype(np.float64))
    mse = float(np.mean(diff**2))
    psnr = math.inf if mse == 0 else 10.0 * math.log10(255.0**2 / mse)
    per_pixel = diff.max(axis=2)
    over = per_pixel > threshold
    bbox = None
    if over.any():
        ys, xs = np.nonzero(over)
        bbox = (int(xs.min()), int(ys.min()), int(xs.max()), int(ys.max()))
    return Metrics(
        psnr=psnr,
        mean_error=float(diff.mean()),
        share_over=float(over.mean()),
        max_error=float(diff.max()) if diff.size else 0.0,
        bbox=bbox,
        threshold=threshold,
        width=a.shape[1],
        height=a.shape[0],
    )


def compare_files(a: str | Path, b: str | Path, threshold: float = DEFAULT_THRESHOLD) -> Metrics:
    return compare_arrays(read_levels(a), read_levels(b), threshold)


def heatmap(a: np.ndarray, b: np.ndarray, full_scale: float = 16.0) -> np.ndarray:
    """False colour of the largest channel error: black 0, blue -> green -> yellow -> red at ``full_scale``."""
    err = np.clip(np.abs(a - b).max(axis=2) / full_scale, 0.0, 1.0)
    stops = np.array([[0, 0, 0], [0, 0, 1], [0, 1, 0], [1, 1, 0], [1, 0, 0]], dtype=np.float64)
    pos = err * (len(stops) - 1)
    i0 = np.minimum(pos.astype(int), len(stops) - 2)
    f = (pos - i0)[..., None]
    return (stops[i0] * (1 - f) + stops[i0 + 1] * f) * 255.0


def montage(a: np.ndarray, b: np.ndarray, caption: str) -> np.ndarray:
    """A | B | heatmap, 4-pixel gaps, with a caption row underneath (levels, uint8)."""
    import OpenImageIO as oiio

    h, w, _ = a.shape
    gap = 4
    caption_h = 28
    out = np.full((h + caption_h, 3 * w + 2 * gap, 3), 32.0)
    for k, img in enumerate((a, b, heatmap(a, b))):
        out[:h, k * (w + gap) : k * (w + gap) + w] = img
    buf = oiio.ImageBuf(out.astype(np.uint8))
    # render_text needs a font; without one the montage simply has no caption (the metrics are printed).
    oiio.ImageBufAlgo.render_text(buf, 4, h + caption_h - 8, caption, 14, "", [1.0, 1.0, 1.0])
    return np.asarray(buf.get_pixels(oiio.UINT8)).reshape(out.shape)


def write_diff(a: np.ndarray, b: np.ndarray, metrics: Metrics, path: str | Path, labels: tuple[str, str]) -> None:
    """Write the montage atomically (:func:`a5mi.imageio.write_image`)."""
    from a5mi.imageio import write_image

    caption = f"{labels[0]} | {labels[1]} | |A-B| (full scale 16/255): {metrics.summary()}"
    write_image(path, montage(a, b, caption))

"""Image comparison: the metrics every fidelity claim of a5mi is stated in, and a diff montage.

All metrics are on the 8-bit scale of the reference images (levels 0..255; float images such as EXR are
multiplied by 255 first, without quantising):

* ``psnr``        PSNR = 10 log10(255² / MSE), MSE over all pixels and channels (inf for identical images);
* ``mean_error``  mean absolute error, in levels (1/255 units);
* ``share_over``  share of pixels whose largest channel error exceeds ``threshold`` levels (default 2);
* ``max_error``   largest channel error, in levels;
* ``bbox``        (x0, y0, x1, y1), inclusive, of the pixels over the threshold, in file coordinates
  (row 0 = top row of the file), or None;
* ``nonfinite``   pixels with a NaN or infinite channel in either image. Such a channel's error is +inf (a value
  that is not a number is no match for any value, itself included), so the pixel is over every threshold,
  ``max_error`` and ``mean_error`` are inf and PSNR is -inf; JSON writes these non-finite figures as null.

``a5mi compare A B [--diff OUT.png [--scale N|auto]] [--json]`` prints them; ``--diff`` writes A, B and a
false-colour heatmap of the largest channel error side by side (:func:`colormap` of ``error / scale``: black 0,
blue, green, yellow, red at ``scale`` levels and beyond; ``scale`` 16 unless ``--scale``), a colour bar with its
labels in /255 units, and the names and metrics as a caption wrapped to the montage's width.
"""

from __future__ import annotations

import functools
import json
import math
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from a5mi import bitmapfont
from a5mi.platform.errors import UserError

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
    nonfinite: int = 0

    def summary(self) -> str:
        """One line, e.g. ``PSNR 67.3 dB, mean 0.02/255, 0.01% of pixels > 2/255, max 14/255``."""
        psnr = f"{self.psnr:.1f}" if math.isfinite(self.psnr) else f"{self.psnr:g}"
        odd = f", {self.nonfinite} pixels not finite" if self.nonfinite else ""
        return (
            f"PSNR {psnr} dB, mean {self.mean_error:.3f}/255, {100 * self.share_over:.2f}% of pixels "
            f"> {self.threshold:g}/255, max {self.max_error:g}/255{odd}"
        )

    def to_json(self) -> str:
        """Strict JSON: an infinite PSNR (identical images) and every non-finite figure (``nonfinite`` > 0)
        are null."""
        d = {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in asdict(self).items()}
        return json.dumps(d, allow_nan=False)


def compare_arrays(a: np.ndarray, b: np.ndarray, threshold: float = DEFAULT_THRESHOLD) -> Metrics:
    """Metrics of two (H, W, 3) arrays in levels (see module docstring for the formulas)."""
    if a.shape != b.shape:
        raise CompareError(f"image sizes differ: {a.shape[1]}x{a.shape[0]} vs {b.shape[1]}x{b.shape[0]}")
    a64, b64 = a.astype(np.float64), b.astype(np.float64)
    odd = ~(np.isfinite(a64) & np.isfinite(b64))
    with np.errstate(invalid="ignore", over="ignore"):
        diff = np.abs(a64 - b64)
        diff[odd] = math.inf
        mse = float(np.mean(diff**2))
    psnr = math.inf if mse == 0 else -math.inf if math.isinf(mse) else 10.0 * math.log10(255.0**2 / mse)
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
        nonfinite=int(odd.any(axis=2).sum()) if odd.ndim == 3 else int(odd.sum()),
    )


#: Full scale of the ``--diff`` heatmap, in levels (1/255 units), unless ``--scale`` says otherwise.
DEFAULT_SCALE = 16.0
#: ``--scale auto``: this percentile of the per-pixel largest channel error becomes the full scale.
AUTO_PERCENTILE = 99.9

#: Colour stops of the heatmap, at error 0, 1/4, 1/2, 3/4 and 1 of the full scale (levels 0..1).
STOPS = np.array([[0, 0, 0], [0, 0, 1], [0, 1, 0], [1, 1, 0], [1, 0, 0]], dtype=np.float64)


def auto_scale(a: np.ndarray, b: np.ndarray) -> float:
    """``--scale auto``: the :data:`AUTO_PERCENTILE` th percentile of the per-pixel largest channel error, in
    levels, rounded up to a whole level (at least 1), so single-pixel outliers saturate and the bulk shows."""
    err = _error(a, b)
    err = err[np.isfinite(err)]  # a non-finite pixel is red at any scale
    return max(1.0, float(np.ceil(np.percentile(err, AUTO_PERCENTILE)))) if err.size else 1.0


def _error(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Per pixel, the largest channel error in levels; +inf where either image is not finite."""
    a64, b64 = a.astype(np.float64), b.astype(np.float64)
    with np.errstate(invalid="ignore", over="ignore"):
        err = np.abs(a64 - b64)
    err[~(np.isfinite(a64) & np.isfinite(b64))] = np.inf
    return err.max(axis=2)


def colormap(t: np.ndarray) -> np.ndarray:
    """Levels 0..255 (float) of the colours at ``t`` in [0, 1] (clipped): black 0, then blue, green, yellow,
    red at 1, linear between the :data:`STOPS`."""
    t = np.clip(np.asarray(t, dtype=np.float64), 0.0, 1.0)
    pos = t * (len(STOPS) - 1)
    i0 = np.minimum(pos.astype(int), len(STOPS) - 2)
    f = (pos - i0)[..., None]
    return (STOPS[i0] * (1 - f) + STOPS[i0 + 1] * f) * 255.0


def heatmap(a: np.ndarray, b: np.ndarray, full_scale: float = DEFAULT_SCALE) -> np.ndarray:
    """False colour of the largest channel error ``e``: :func:`colormap` of ``e / full_scale`` (red at and
    beyond ``full_scale`` levels; a pixel that is not finite is red)."""
    return colormap(_error(a, b) / full_scale)


# --------------------------------------------------------------------------------------------------------
# Text: OpenImageIO's render_text with the font its wheel ships, else the embedded bitmap font
# --------------------------------------------------------------------------------------------------------

FONT_SIZE = 13
LINE_HEIGHT = 16
MARGIN = 4


@functools.cache
def font_path() -> str | None:
    """The font :func:`draw_text` uses: DroidSans of the OpenImageIO wheel (``OpenImageIO/share/fonts``),
    else ``""`` (OIIO's own search: ``$OPENIMAGEIO_FONTS``, the system's font folders) if that draws, else
    None: no font at all, and :mod:`a5mi.bitmapfont` draws instead."""
    import OpenImageIO as oiio

    wheel = Path(oiio.__file__).parent / "share" / "fonts" / "OpenImageIO" / "DroidSans.ttf"
    for font in ([str(wheel)] if wheel.is_file() else []) + [""]:
        probe = oiio.ImageBuf(np.zeros((24, 24, 3), np.uint8))
        if oiio.ImageBufAlgo.render_text(probe, 2, 20, "A", FONT_SIZE, font, [1.0, 1.0, 1.0]):
            return font
        oiio.geterror()  # clear the message of the failed try
    return None


def text_width(text: str, size: int = FONT_SIZE) -> int:
    """Width in pixels of ``text`` drawn by :func:`draw_text`, from the pen position to the ink's right end."""
    font = font_path()
    if font is None:
        return bitmapfont.text_width(text)
    import OpenImageIO as oiio

    roi = oiio.ImageBufAlgo.text_size(text, size, font)
    return int(roi.xend) if roi.defined else 0


def wrap(text: str, width: int, size: int = FONT_SIZE) -> list[str]:
    """Greedy word wrap of ``text`` into lines of at most ``width`` pixels (:func:`text_width`); a word wider
    than a line is split between characters. A newline starts a new line."""
    lines: list[str] = []
    for para in text.split("\n"):
        line = ""
        for word in para.split(" "):
            cand = f"{line} {word}" if line else word
            if text_width(cand, size) <= width:
                line = cand
                continue
            if line:
                lines.append(line)
            line = ""
            for ch in word:  # the word alone does not fit: split it
                if line and text_width(line + ch, size) > width:
                    lines.append(line)
                    line = ""
                line += ch
        lines.append(line)
    return lines


def draw_text(img: np.ndarray, items: list[tuple[int, int, str]], size: int = FONT_SIZE) -> np.ndarray:
    """``img`` (uint8 levels) with each ``(x, y, text)`` drawn in white, the line's top near row ``y``."""
    font = font_path()
    if font is None:
        out = img.astype(np.float64)
        for x, y, text in items:
            bitmapfont.draw(out, x, y + 1, text)
        return np.clip(np.rint(out), 0, 255).astype(np.uint8)
    import OpenImageIO as oiio

    buf = oiio.ImageBuf(np.ascontiguousarray(img))
    ascent = int(round(0.8 * size))  # the font's cap height above the baseline, about
    for x, y, text in items:
        if text and not oiio.ImageBufAlgo.render_text(buf, x, y + ascent, text, size, font, [1.0, 1.0, 1.0]):
            raise RuntimeError(f"OpenImageIO cannot draw text: {oiio.geterror()}")
    return np.asarray(buf.get_pixels(oiio.UINT8)).reshape(img.shape)


# --------------------------------------------------------------------------------------------------------
# The montage
# --------------------------------------------------------------------------------------------------------

BAR_HEIGHT = 10


@dataclass(frozen=True)
class Layout:
    """Where the parts of a montage lie (pixel rows/columns, end exclusive): the panels ``A | B | heatmap``
    in rows ``0..h``, the colour bar in rows ``bar_rows`` over columns ``bar_cols``, its labels below it, and
    the caption lines from row ``caption_top`` on."""

    width: int
    height: int
    bar_rows: tuple[int, int]
    bar_cols: tuple[int, int]
    labels_top: int
    caption_top: int
    caption_lines: tuple[str, ...]


#: Narrowest montage: smaller panels leave room on the right, so the caption stays a few readable lines.
MIN_WIDTH = 240


def layout(h: int, w: int, caption: str, gap: int = 4) -> Layout:
    """The :class:`Layout` of a montage of ``h x w`` panels (at least :data:`MIN_WIDTH` wide): the caption
    wrapped to the montage width."""
    width = max(3 * w + 2 * gap, MIN_WIDTH)
    lines = tuple(wrap(caption, width - 2 * MARGIN))
    bar_top = h + MARGIN
    labels_top = bar_top + BAR_HEIGHT + 2
    caption_top = labels_top + LINE_HEIGHT + MARGIN
    height = caption_top + LINE_HEIGHT * len(lines) + MARGIN
    return Layout(width, height, (bar_top, bar_top + BAR_HEIGHT), (MARGIN, width - MARGIN), labels_top, caption_top,
                  lines)


def bar_labels(scale: float, cols: tuple[int, int]) -> list[tuple[int, str]]:
    """``(x, text)`` of the colour bar's labels: 0 at the left end, the full scale ``N/255`` right-aligned at
    the right end, and the half scale in the middle when the three fit without touching."""
    x0, x1 = cols
    left, right = "0", f"{scale:g}/255"
    out = [(x0, left), (x1 - text_width(right), right)]
    mid = f"{scale / 2:g}"
    mw = text_width(mid)
    xm = (x0 + x1) // 2 - mw // 2
    if x0 + text_width(left) + 6 < xm and xm + mw + 6 < x1 - text_width(right):
        out.insert(1, (xm, mid))
    if text_width(left) + text_width(right) + 4 > x1 - x0:  # too narrow even for the ends: the caption says it
        return []
    return out


def montage(a: np.ndarray, b: np.ndarray, caption: str, scale: float = DEFAULT_SCALE) -> np.ndarray:
    """A | B | heatmap (full scale ``scale`` levels), 4-pixel gaps; below them the colour bar from 0 to
    ``scale`` with its labels, then ``caption`` wrapped to the montage's width (levels, uint8)."""
    h, w, _ = a.shape
    gap = 4
    lay = layout(h, w, caption, gap)
    out = np.full((lay.height, lay.width, 3), 32.0)
    for k, img in enumerate((a, b, heatmap(a, b, scale))):
        out[:h, k * (w + gap) : k * (w + gap) + w] = img
    (r0, r1), (c0, c1) = lay.bar_rows, lay.bar_cols
    out[r0:r1, c0:c1] = colormap(np.linspace(0.0, 1.0, c1 - c0))[None, :, :]
    items = [(x, lay.labels_top, label) for x, label in bar_labels(scale, lay.bar_cols)]
    items += [(MARGIN, lay.caption_top + i * LINE_HEIGHT, line) for i, line in enumerate(lay.caption_lines)]
    return draw_text(np.rint(np.nan_to_num(out, nan=0.0, posinf=255.0, neginf=0.0).clip(0, 255)).astype(np.uint8),
                     items)


def write_diff(a: np.ndarray, b: np.ndarray, metrics: Metrics, path: str | Path, labels: tuple[str, str],
               scale: float = DEFAULT_SCALE) -> None:
    """Write the montage atomically (:func:`a5mi.platform.imageio.write_image`), mode as the umask says."""
    from a5mi.platform.imageio import write_image

    caption = (f"{labels[0]} | {labels[1]} | |A-B|, largest channel, colour bar 0..{scale:g}/255\n"
               f"{metrics.summary()}")
    write_image(path, montage(a, b, caption, scale))

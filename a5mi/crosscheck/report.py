"""The cross-check as text, JSON and a montage image."""


from __future__ import annotations

import json
import math
import os
from collections.abc import Sequence
from dataclasses import asdict

import numpy as np
import numpy.typing as npt

from a5mi.compare import heatmap
from a5mi.crosscheck.core import BACKGROUND, FRESNEL_SCALE, LABELS, CrosscheckResult, levels
from a5mi.spec import FRESNEL_MODES

# --------------------------------------------------------------------------------------------------------
# Output: table, JSON, montage
# --------------------------------------------------------------------------------------------------------


def table(result: CrosscheckResult) -> str:
    """The pair table as text: one row per pair and region."""
    o = result.options
    n_glass = int(result.glass.sum())
    n_bg = int((result.classes == BACKGROUND).sum())
    lines = [
        f"{o.width}x{o.height}, bounces {o.bounces}, shadows {'on' if o.shadows else 'off'}; path: {o.spp} spp, "
        f"max_depth {o.path_max_depth}, no Russian roulette, mean standard error {result.path_stderr:.2f}/255",
        f"pixels: {n_glass} glass (ray tree touches a dielectric), {o.width * o.height - n_glass} other "
        f"({n_bg} background)",
        f"{'A':<8} {'B':<8} {'region':<6} {'pixels':>7} {'PSNR':>7} {'mean':>7} {'bias B-A':>9} {'>2/255':>8} "
        f"{'max':>5}",
    ]
    for r in result.pairs:
        if r.metrics is None:
            lines.append(f"{r.a:<8} {r.b:<8} {r.region:<6} {r.pixels:>7} {'-':>7}")
            continue
        m = r.metrics
        psnr = "inf" if math.isinf(m.psnr) else f"{m.psnr:.1f}"
        lines.append(f"{r.a:<8} {r.b:<8} {r.region:<6} {r.pixels:>7} {psnr:>7} {m.mean_error:>7.3f} "
                     f"{r.bias:>+9.3f} {100 * m.share_over:>7.2f}% {m.max_error:>5.0f}")
    lines.append("(levels of 1/255; PSNR in dB; bias = mean(B - A); '>2/255' = share of the region's pixels)")
    return "\n".join(lines)


def to_json(result: CrosscheckResult) -> str:
    o = result.options
    return json.dumps({
        "options": asdict(o), "path_max_depth": o.path_max_depth, "path_stderr": result.path_stderr,
        "pixels": {"glass": int(result.glass.sum()), "background": int((result.classes == BACKGROUND).sum()),
                   "total": o.width * o.height},
        "pairs": [r.to_dict() for r in result.pairs], "timings": result.timings,
    })


def _signed_map(a: npt.NDArray[np.float64], b: npt.NDArray[np.float64], full_scale: float) -> npt.NDArray[np.float64]:
    """Mean channel difference ``b − a``: red where B is brighter, blue where darker, black equal."""
    s = np.clip((b - a).mean(axis=2) / full_scale, -1.0, 1.0)
    out = np.zeros((*s.shape, 3))
    out[..., 0] = np.maximum(s, 0.0) * 255.0
    out[..., 2] = np.maximum(-s, 0.0) * 255.0
    return out


def error_scale(errors: Sequence[npt.NDArray[np.float64]], percentile: float = 99.0) -> float:
    """Full scale (levels) of a heatmap row: the ``percentile`` of the errors, rounded up to a power of two, in
    [4, 256] (so the typical error is a colour, not a saturated red, and 1-level specks stay visible)."""
    values = np.concatenate([np.ravel(e) for e in errors]) if errors else np.zeros(1)
    p = float(np.percentile(values, percentile)) if values.size else 0.0
    return float(min(256.0, max(4.0, 2.0 ** math.ceil(math.log2(max(p, 1.0))))))


def montage_image(result: CrosscheckResult) -> npt.NDArray[np.uint8]:
    """Three rows of four tiles, each labelled underneath (levels, uint8):

    1. ``a5 | schlick | exact | path``;
    2. ``|a5−schlick|``, ``|a5−exact|``, ``|schlick−exact|`` (full scale 16/255), and the pixel classes
       (glass white, other grey, background black);
    3. ``|a5−path|``, ``|schlick−path|``, ``|exact−path|`` and ``path − exact`` signed (red: path brighter,
       blue: darker), all at the full scale :func:`error_scale` picks from what the row shows (the 99th
       percentile of the errors against ``path``, rounded up to a power of two), printed in the labels.
    """
    import OpenImageIO as oiio

    lv = {k: levels(v) for k, v in result.images.items()}
    path_scale = error_scale([np.abs(lv[k] - lv["path"]).max(axis=2)[result.classes != BACKGROUND]
                              for k in FRESNEL_MODES])
    cls = np.choose(result.classes, [0.0, 96.0, 255.0])[..., None].repeat(3, axis=2)
    tiles = [
        [(lv[k], k) for k in LABELS],
        [(heatmap(lv["a5"], lv["schlick"], FRESNEL_SCALE), "|a5-schlick| x16"),
         (heatmap(lv["a5"], lv["exact"], FRESNEL_SCALE), "|a5-exact| x16"),
         (heatmap(lv["schlick"], lv["exact"], FRESNEL_SCALE), "|schlick-exact| x16"),
         (cls, "glass / other / bg")],
        [(heatmap(lv[k], lv["path"], path_scale), f"|{k}-path| 0..{path_scale:g}") for k in FRESNEL_MODES]
        + [(_signed_map(lv["exact"], lv["path"], path_scale), f"path-exact +-{path_scale:g}")],
    ]
    h, w = result.classes.shape
    gap, label_h = 4, 18
    rows, cols = len(tiles), len(tiles[0])
    out = np.full((rows * (h + label_h + gap), cols * (w + gap) - gap, 3), 32.0)
    for r, row in enumerate(tiles):
        for c, (img, _) in enumerate(row):
            y, x = r * (h + label_h + gap), c * (w + gap)
            out[y : y + h, x : x + w] = img
    buf = oiio.ImageBuf(np.ascontiguousarray(out.astype(np.uint8)))
    size = max(8, min(14, w // 12))
    for r, row in enumerate(tiles):
        for c, (_, label) in enumerate(row):
            # Without a font the montage just has no labels (the order is documented above).
            oiio.ImageBufAlgo.render_text(buf, c * (w + gap) + 2, r * (h + label_h + gap) + h + label_h - 4,
                                          label, size, "", [1.0, 1.0, 1.0])
    return np.asarray(buf.get_pixels(oiio.UINT8)).reshape(out.shape)


def write_montage(result: CrosscheckResult, path: str | os.PathLike[str]) -> None:
    """Write :func:`montage_image` atomically through :func:`a5mi.platform.imageio.write_image`."""
    from a5mi.platform.imageio import write_image

    write_image(path, montage_image(result).astype(np.float32) / np.float32(255.0) + np.float32(0.5 / 255))

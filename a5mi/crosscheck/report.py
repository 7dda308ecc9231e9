"""The cross-check as text, JSON and a montage image."""


from __future__ import annotations

import json
import math
import os
from dataclasses import asdict

import numpy as np
import numpy.typing as npt

from a5mi.compare import heatmap
from a5mi.crosscheck.core import BACKGROUND, FRESNEL_SCALE, LABELS, PATH_SCALE, CrosscheckResult, levels

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


def montage_image(result: CrosscheckResult) -> npt.NDArray[np.uint8]:
    """Three rows of four tiles, each labelled underneath (levels, uint8):

    1. ``a5 | schlick | exact | path``;
    2. ``|a5−schlick|``, ``|a5−exact|``, ``|schlick−exact|`` (full scale 16/255), and the pixel classes
       (glass white, other grey, background black);
    3. ``|a5−path|``, ``|schlick−path|``, ``|exact−path|`` (full scale 64/255), and ``path − exact``
       signed (red: path brighter, blue: darker, full scale 64/255).
    """
    import OpenImageIO as oiio

    lv = {k: levels(v) for k, v in result.images.items()}
    cls = np.choose(result.classes, [0.0, 96.0, 255.0])[..., None].repeat(3, axis=2)
    tiles = [
        [(lv[k], k) for k in LABELS],
        [(heatmap(lv["a5"], lv["schlick"], FRESNEL_SCALE), "|a5-schlick| x16"),
         (heatmap(lv["a5"], lv["exact"], FRESNEL_SCALE), "|a5-exact| x16"),
         (heatmap(lv["schlick"], lv["exact"], FRESNEL_SCALE), "|schlick-exact| x16"),
         (cls, "glass / other / bg")],
        [(heatmap(lv["a5"], lv["path"], PATH_SCALE), "|a5-path| x4"),
         (heatmap(lv["schlick"], lv["path"], PATH_SCALE), "|schlick-path| x4"),
         (heatmap(lv["exact"], lv["path"], PATH_SCALE), "|exact-path| x4"),
         (_signed_map(lv["exact"], lv["path"], PATH_SCALE), "path-exact (red +)")],
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
    """Write :func:`montage_image` atomically through :func:`a5mi.imageio.write_image`."""
    from a5mi.imageio import write_image

    write_image(path, montage_image(result).astype(np.float32) / np.float32(255.0) + np.float32(0.5 / 255))

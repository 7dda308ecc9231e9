"""``a5mi compare A B``: the metrics of :mod:`a5mi.compare` and the grading verdict of the pair (docs/GRADING.md).

The verdict is :func:`a5mi.grade.verdict.judge` on the share of pixels beyond the noise band: with
``--noise SIGMA.npy`` (the per-pixel jitter standard deviation ``a5mi grade`` caches beside each reference)
the band is ``4 sigma + 1`` levels, without it 1 level. Exit status (:class:`a5mi.platform.errors.ExitStatus`, as
``cmp``): 0 match, 1 differ (close, wrong, wrong size), 2 user error (unreadable image, bad flag), 70 internal
error, so the command can gate a script or CI job.

``--diff OUT.png`` writes :func:`a5mi.compare.montage`: A | B | heatmap of the largest channel error, full scale
``--scale`` levels (default 16; ``auto``: :func:`a5mi.compare.auto_scale`, the 99.9th percentile of the error,
at least 1), a colour bar labelled in /255 units and the metrics as a caption; ``--json`` then has ``diff_scale``.
"""

from __future__ import annotations

import json
import os

from a5mi.cli.app import Command, Console
from a5mi.cli.flags import Args, Flag, Positional, json_flag, number, real, real_in, text
from a5mi.platform.errors import ExitStatus, UsageError


def _scale(flag: str, values: list[str]) -> float | str:
    """``--scale``: ``auto`` or a positive number of levels (1/255 units)."""
    if values[0] == "auto":
        return "auto"
    value = number(flag, values[0])
    if value <= 0:
        raise UsageError(f"{flag} expects a positive number of levels or 'auto', found '{values[0]}'")
    return value


FLAGS: tuple[Flag, ...] = (
    Flag(("--diff",), "diff", "also write A | B | heatmap of the largest channel error", 1, text,
         metavar="OUT.png"),
    Flag(("--scale",), "scale", "--diff heatmap full scale in levels (red at N/255 and beyond), or auto: the "
         "99.9th percentile of the error", 1, _scale, 16.0, "N|auto"),
    json_flag("the metrics and the verdict"),
    Flag(("--threshold",), "threshold", "levels (of 255) a pixel may be off before it counts", 1, real_in(0.0), 2.0,
         "L"),
    Flag(("--flip",), "flip", "also compute NVIDIA FLIP (mean, LDR)",
         default=False, show_default=False),
    Flag(("--flip-map",), "flip_map", "write the FLIP heatmap (implies --flip)", 1, text, metavar="OUT.png"),
    Flag(("--noise",), "noise", "noise band: per-pixel jitter sigma (levels), an .npy of the image's shape", 1,
         text, metavar="SIGMA.npy"),
    Flag(("--match",), "match", "largest share of pixels beyond noise for 'match'", 1, real, 0.01, "SHARE"),
    Flag(("--close",), "close", "largest share of pixels beyond noise for 'close'", 1, real, 0.015, "SHARE"),
)


def _noise(path: str | None, shape: tuple[int, ...]):  # noqa: ANN202 - numpy array or None
    """The ``--noise`` sigma: a regular file (:func:`a5mi.platform.paths.read_regular`: a FIFO or device is refused,
    never waited on) holding an ``.npy`` array of the images' shape, every value finite and >= 0."""
    if path is None:
        return None
    import io

    import numpy as np

    from a5mi.platform.errors import FileReadError
    from a5mi.platform.paths import read_regular

    try:
        data = read_regular(path, int(np.prod(shape)) * 16 + (1 << 16), "--noise")
        sigma = np.load(io.BytesIO(data), allow_pickle=False)
    except FileReadError as exc:
        raise UsageError(f"--noise: cannot read '{path}': {exc.reason}") from None
    except (OSError, ValueError, EOFError) as exc:
        raise UsageError(f"--noise: cannot read '{path}': {exc}") from None
    if sigma.shape != shape:
        raise UsageError(f"--noise: '{path}' has shape {sigma.shape}, the images {shape}")
    if not np.issubdtype(sigma.dtype, np.number) or not np.all(np.isfinite(sigma)) or np.any(sigma < 0):
        raise UsageError(f"--noise: '{path}' holds values that are not finite numbers >= 0")
    return sigma


def run_compare(args: Args, console: Console) -> int:
    from a5mi import compare
    from a5mi.grade import verdict
    from a5mi.platform import clobber
    from a5mi.platform.imageio import check_output_path, read_levels, write_image

    a_path, b_path = args.images
    outs = [(flag, out) for flag, out in (("--diff", args.diff), ("--flip-map", args.flip_map)) if out is not None]
    for _, out in outs:
        check_output_path(out)
    clobber.check_outputs(outs, [a_path, b_path, *([args.noise] if args.noise else [])], of="")
    if not 0 <= args.match <= args.close <= 1:
        raise UsageError(f"--match and --close must satisfy 0 <= match <= close <= 1 (found {args.match:g}, "
                         f"{args.close:g})")
    a_img, b_img = read_levels(a_path), read_levels(b_path)
    if a_img.shape != b_img.shape:
        msg = f"image sizes differ: {a_img.shape[1]}x{a_img.shape[0]} vs {b_img.shape[1]}x{b_img.shape[0]}"
        console.result(json.dumps({"verdict": "wrong size", "detail": msg}) if args.json
                       else f"{a_path} vs {b_path}: {msg}\nverdict: wrong size")
        return ExitStatus.DIFFER
    metrics = compare.compare_arrays(a_img, b_img, args.threshold)
    want_flip = bool(args.flip) or args.flip_map is not None
    graded, heat = verdict.measure(b_img, a_img, _noise(args.noise, a_img.shape), flip=want_flip)
    decided = verdict.judge(graded, verdict.Thresholds(args.match, args.close))
    scale = None
    if args.diff is not None:
        scale = compare.auto_scale(a_img, b_img) if args.scale == "auto" else float(args.scale)
        compare.write_diff(a_img, b_img, metrics, args.diff, (os.path.basename(a_path), os.path.basename(b_path)),
                           scale)
    if args.flip_map is not None and heat is not None:
        write_image(args.flip_map, heat / 255.0 + 0.5 / 255.0)
    if args.json:
        doc = json.loads(metrics.to_json())
        doc.update(verdict=decided, beyond_noise=graded.beyond_noise, flip=graded.flip)
        if scale is not None:
            doc["diff_scale"] = scale
        console.result(json.dumps(doc))
    else:
        console.result(f"{a_path} vs {b_path} ({metrics.width}x{metrics.height}): {metrics.summary()}")
        if metrics.bbox is not None:
            x0, y0, x1, y1 = metrics.bbox
            console.result(f"pixels over {metrics.threshold:g}/255 lie in x {x0}..{x1}, y {y0}..{y1} (row 0 = top)")
        if scale is not None:
            console.result(f"{args.diff}: A | B | |A-B| heatmap, full scale {scale:g}/255")
        flip = "" if graded.flip is None else f", FLIP {graded.flip:.4f}"
        odd = "" if not metrics.nonfinite else f"; {metrics.nonfinite} pixels not finite (NaN or inf)"
        console.result(f"verdict: {decided} ({100 * graded.beyond_noise:.2f}% of pixels beyond "
                       f"{'the noise band' if args.noise else f'{verdict.NOISE_FLOOR:g}/255'}{flip}{odd})")
    return ExitStatus.OK if decided == "match" else ExitStatus.DIFFER


COMPARE = Command("compare", "Compare two images on the 8-bit scale (PSNR, mean error, share of pixels over the "
                  "threshold, max error, optionally FLIP) and give the grading verdict.",
                  FLAGS, run_compare, (Positional("images", "A B", "reference and test image", 2),),
                  exit_ok="the images match", exit_differ="they differ (verdict close, wrong or wrong size)")

"""``a5mi compare A B [--diff OUT.png] [--json] [--threshold L]``: the metrics of :mod:`a5mi.compare`."""

from __future__ import annotations

import os

from a5mi.cli.app import Command, Console
from a5mi.cli.flags import Args, Flag, Positional, real, text

FLAGS: tuple[Flag, ...] = (
    Flag(("--diff",), "diff", "also write A | B | heatmap of the largest channel error", 1, text,
         metavar="OUT.png"),
    Flag(("--json",), "json", "print the metrics as JSON", default=False, show_default=False),
    Flag(("--threshold",), "threshold", "levels (of 255) a pixel may be off before it counts", 1, real, 2.0, "L"),
)


def run_compare(args: Args, console: Console) -> int:
    from a5mi import compare
    from a5mi.imageio import check_output_path, read_levels

    a_path, b_path = args.images
    if args.diff is not None:
        check_output_path(args.diff)
    a_img, b_img = read_levels(a_path), read_levels(b_path)
    metrics = compare.compare_arrays(a_img, b_img, args.threshold)
    if args.diff is not None:
        compare.write_diff(a_img, b_img, metrics, args.diff, (os.path.basename(a_path), os.path.basename(b_path)))
    if args.json:
        console.result(metrics.to_json())
        return 0
    console.result(f"{a_path} vs {b_path} ({metrics.width}x{metrics.height}): {metrics.summary()}")
    if metrics.bbox is not None:
        x0, y0, x1, y1 = metrics.bbox
        console.result(f"pixels over {metrics.threshold:g}/255 lie in x {x0}..{x1}, y {y0}..{y1} (row 0 = top)")
    return 0


COMPARE = Command("compare", "Compare two images on the 8-bit scale: PSNR, mean error, share of pixels over the "
                  "threshold, max error.", FLAGS, run_compare, (Positional("images", "A B", "the two images", 2),))

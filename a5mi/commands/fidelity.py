"""``a5mi fidelity [--diff-dir DIR]``: re-render every reference image, print the fidelity table and judge it.

The verdict (SPEC C: a faithful implementation lands far above 40 dB; this project's regression floor is the
one of ``tests/fidelity/test_reference.py``): every image must reach ``--min-psnr`` (default :data:`PSNR_FLOOR`, 60 dB)
with fewer than ``--max-share`` of its pixels (default :data:`SHARE_CEILING`, 0.1%) off by more than 2/255.
Exit status 1 when an image does not, naming it on stderr.
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING, Any

from a5mi.cli.app import Command, Console, activate_variant
from a5mi.cli.flags import Args, Flag, real, text
from a5mi.platform.errors import ExitStatus, UsageError, UserError

if TYPE_CHECKING:
    from a5mi.compare import Metrics

#: Lowest PSNR (dB) of a reference image that passes (SPEC C; tests/fidelity/test_reference.py).
PSNR_FLOOR = 60.0
#: Share of an image's pixels off by more than 2/255 at which it fails (SPEC C; tests/fidelity/test_reference.py).
SHARE_CEILING = 0.001

FLAGS: tuple[Flag, ...] = (
    Flag(("--diff-dir",), "diff_dir", "write a diff montage per reference image into DIR", 1, text, metavar="DIR"),
    Flag(("--min-psnr",), "min_psnr", "an image below this PSNR fails", 1, real, PSNR_FLOOR, "DB"),
    Flag(("--max-share",), "max_share", "an image with this share of pixels (or more) off by > 2/255 fails", 1,
         real, SHARE_CEILING, "SHARE"),
)


def failures(rows: list[tuple[Any, Metrics]], min_psnr: float, max_share: float) -> list[str]:
    """One line per (case, metrics) row that fails the verdict (module docstring): PSNR below ``min_psnr`` or a
    share of pixels over 2/255 of ``max_share`` or more."""
    out = []
    for case, m in rows:
        if m.psnr < min_psnr or m.share_over >= max_share:
            out.append(f"{case}: {m.summary()}: below the floor (PSNR >= {min_psnr:g} dB and < "
                       f"{100 * max_share:g}% of pixels > 2/255)")
    return out


def run_fidelity(args: Args, console: Console) -> int:
    from a5mi import fidelity
    from a5mi.compare import write_diff

    if args.diff_dir is not None and not os.path.isdir(args.diff_dir):
        raise UsageError(f"--diff-dir: folder '{args.diff_dir}' does not exist")
    if not 0 <= args.max_share <= 1:
        raise UsageError(f"--max-share expects a share in [0, 1], found {args.max_share:g}")
    from a5mi import DATA_DOC, require_data_dir

    require_data_dir()
    cases = list(fidelity.cases())
    if not cases:
        raise UserError(f"no reference images under {fidelity.data_dir() / 'reference'} "
                        f"(set A5_DATA; see {DATA_DOC})")
    activate_variant(None)
    rows = []
    for case in cases:
        metrics, ours, ref = fidelity.measure(case)
        console.note(f"{case}: {metrics.summary()}")
        if args.diff_dir is not None:
            write_diff(ours, ref, metrics, os.path.join(args.diff_dir, f"{case}.diff.png"), ("a5mi", "a5soln"))
        rows.append((case, metrics))
    console.result(fidelity.table(rows))
    failed = failures(rows, args.min_psnr, args.max_share)
    for line in failed:
        console.error(line)
    return ExitStatus.DIFFER if failed else ExitStatus.OK


FIDELITY = Command("fidelity", "Re-render every sample-solution reference image and print the fidelity table.",
                   FLAGS, run_fidelity, exit_ok="every image at or above the floor (--min-psnr, --max-share)",
                   exit_differ="an image is below it (named on stderr)")

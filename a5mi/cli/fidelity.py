"""``a5mi fidelity [--diff-dir DIR]``: re-render every reference image and print the README table."""

from __future__ import annotations

import os

from a5mi.cli.app import Command, Console, activate_variant
from a5mi.cli.flags import Args, Flag, text
from a5mi.errors import UsageError, UserError

FLAGS: tuple[Flag, ...] = (
    Flag(("--diff-dir",), "diff_dir", "write a diff montage per reference image into DIR", 1, text, metavar="DIR"),
)


def run_fidelity(args: Args, console: Console) -> int:
    from a5mi import fidelity
    from a5mi.compare import write_diff

    if args.diff_dir is not None and not os.path.isdir(args.diff_dir):
        raise UsageError(f"--diff-dir: folder '{args.diff_dir}' does not exist")
    from a5mi import require_data_dir

    require_data_dir()
    cases = list(fidelity.cases())
    if not cases:
        raise UserError(f"no reference images under {fidelity.data_dir() / 'reference'} (set A5_DATA)")
    activate_variant(None)
    rows = []
    for case in cases:
        metrics, ours, ref = fidelity.measure(case)
        console.note(f"{case}: {metrics.summary()}")
        if args.diff_dir is not None:
            write_diff(ours, ref, metrics, os.path.join(args.diff_dir, f"{case}.diff.png"), ("a5mi", "a5soln"))
        rows.append((case, metrics))
    console.result(fidelity.table(rows))
    return 0


FIDELITY = Command("fidelity", "Re-render every sample-solution reference image and print the fidelity table.",
                   FLAGS, run_fidelity)

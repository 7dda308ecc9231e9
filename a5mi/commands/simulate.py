"""``a5mi simulate smoke -o DIR --frames N [--grid N] [--seed S]``: a simulation's frames as ``.vol`` grids.

The library is :mod:`a5mi.simulate` (stable fluids: docs/EXTENSIONS.md E.22). ``smoke`` writes the smoke
density after each of ``N`` steps of ``1/24`` s as ``DIR/smoke_000.vol`` ... (one channel, the format of
:mod:`a5mi.converters.volgrid`), the frames a ``Volume { grid "smoke_%03d.vol" ... }`` plays back.
"""

from __future__ import annotations

import time

from a5mi.cli.app import Command, Console
from a5mi.cli.flags import Args, Flag, Positional, integer, text
from a5mi.platform.errors import ExitStatus, UsageError, UserError

KINDS = ("smoke",)

FLAGS: tuple[Flag, ...] = (
    Flag(("-o", "--output"), "output", "folder of the frames (smoke_000.vol, smoke_001.vol, ...)", 1, text,
         metavar="DIR"),
    Flag(("--frames",), "frames", "number of frames (one step of 1/24 s each)", 1, integer(1, 100_000),
         metavar="N"),
    Flag(("--grid",), "grid", "grid cells along each axis (an N³ grid)", 1, integer(8, 256), default=48,
         metavar="N"),
    Flag(("--seed",), "seed", "seed of the source's random perturbation (same seed, same frames)", 1,
         integer(0, 2**63 - 1), default=0, metavar="S"),
)


def run_simulate(args: Args, console: Console) -> int:
    from pathlib import Path

    from a5mi.simulate import smoke

    if args.kind not in KINDS:
        raise UsageError(f"unknown simulation '{args.kind[:40]}' (expected one of {', '.join(KINDS)})")
    out = Path(args.output)
    if out.exists() and not out.is_dir():
        raise UserError(f"-o '{out}' is not a folder")
    if not out.parent.is_dir():
        raise UserError(f"-o '{out}': folder '{out.parent}' does not exist")
    params = smoke.SmokeParams(size=args.grid, seed=args.seed)
    t0 = time.perf_counter()
    paths = smoke.write_frames(out, params, args.frames)
    console.note(f"a5mi simulate: {len(paths)} smoke frames ({args.grid}³ cells) in {out} "
                 f"({time.perf_counter() - t0:.1f} s)")
    return ExitStatus.OK


SIMULATE = Command("simulate", "Run a simulation (smoke: stable fluids) and write its frames as Mitsuba .vol "
                   "grids for a keyframed Volume (docs/EXTENSIONS.md E.22).", FLAGS, run_simulate,
                   (Positional("kind", "smoke", "the simulation"),), required=("output", "frames"),
                   exit_ok="the frames written")

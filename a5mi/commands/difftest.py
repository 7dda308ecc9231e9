"""``a5mi difftest --binary PATH [--count N] [--seed S] [--mean-size N] [--threshold DB] [--out DIR]
[--json-file F] [--aovs quadrant|main|none]``.

Differential testing of a5mi against another executable with the a5 command line (:mod:`a5mi.difftest`):
prints one table row per scene as it is done, then the summary; failures are minimised and written to
``--out``.
"""

from __future__ import annotations

from pathlib import Path

from a5mi.cli.app import Command, Console, activate_variant
from a5mi.cli.flags import Args, Flag, choice, integer, json_file_flag, real, text
from a5mi.platform.errors import ExitStatus, UsageError

FLAGS: tuple[Flag, ...] = (
    Flag(("--binary", "-binary"), "binary", "the other renderer: an executable with the a5 command line "
         "(a5soln, a student's a5); run sandboxed in a temporary folder", 1, text, metavar="PATH"),
    Flag(("--count", "-count"), "count", "number of random scenes", 1, integer(1, 100_000), 20, "N"),
    Flag(("--seed", "-seed"), "seed", "series of scenes (scene i of seed s is always the same)", 1,
         integer(0, 2**31 - 1), 0, "S"),
    Flag(("--start",), "start", "first scene index", 1, integer(0, 10**9), 0, "I"),
    Flag(("--mean-size",), "size", "scenes are squares of a side drawn from N-10 .. N+10 (the binary asserts on "
         "non-square images)", 1, integer(16, 1000), 100, "N"),
    Flag(("--threshold",), "threshold", "PSNR (dB) below which a scene fails and is minimised", 1, real, 50.0,
         "DB"),
    Flag(("--timeout",), "timeout", "seconds one run of the binary may take", 1, real, 60.0, "S"),
    Flag(("--budget",), "budget", "comparisons the minimiser may spend per failing scene", 1,
         integer(1, 10_000), 80, "N"),
    Flag(("--out", "-o"), "out", "folder for failing scenes and their minimised reproducers", 1, text,
         metavar="DIR"),
    json_file_flag("the whole report"),
    Flag(("--allow-read",), "allow_read", "extra paths the sandboxed binary may read (':'-separated), e.g. its "
         "interpreter", 1, text, metavar="PATHS"),
    Flag(("--aovs",), "aovs", "compare the -normals and -depth images too, traced with the other renderer's rays: "
         "quadrant (a5soln's, SPEC B.6), main (the main image's), or none", 1,
         choice(("quadrant", "main", "none")), "quadrant", "RAYS"),
    Flag(("--no-sandbox",), "no_sandbox", "run the binary even without bubblewrap (rlimits and a user id only)",
         default=False, show_default=False),
)


def run_difftest(args: Args, console: Console) -> int:
    from a5mi import require_data_dir
    from a5mi.difftest import campaign
    from a5mi.difftest.runner import check_binary
    from a5mi.platform.imageio import atomic_file

    if args.binary is None:
        raise UsageError("--binary PATH is required")
    from a5mi.difftest.runner import Binary
    from a5mi.sandbox import bwrap as sandbox

    why = sandbox.refusal()
    if why and not args.no_sandbox:
        raise UsageError(why)
    if why:
        console.note(f"a5mi difftest: WARNING: --no-sandbox: {sandbox.sandbox_problem()}: the binary runs NOT "
                     "SANDBOXED (rlimits, its own user id and a temporary folder only)")
    allow = tuple(p for p in (args.allow_read or "").split(":") if p)
    binary = Binary(check_binary(args.binary), allow, not args.no_sandbox)  # run_campaign hands it to the runner
    if args.json_file:
        from a5mi.platform import clobber
        from a5mi.platform.paths import check_target

        check_target(args.json_file)
        clobber.check_outputs([("--json-file", args.json_file)], [args.binary], of="")
    if args.timeout <= 0:
        raise UsageError("--timeout must be positive")
    data = require_data_dir() / "scenes"
    activate_variant(None)
    console.result(campaign.TABLE_HEAD)
    rows = campaign.run_campaign(
        binary, data, count=args.count, seed=args.seed, size=args.size, threshold=args.threshold,
        timeout=args.timeout, out_dir=Path(args.out) if args.out else None, minimise_budget=args.budget,
        start=args.start, aovs=args.aovs, on_row=lambda r: console.result(campaign.table_line(r)))
    s = campaign.summary(rows, args.threshold)
    console.result(f"\n{s['scenes']} scenes (seed {args.seed}): median PSNR {campaign.psnr_text(s['median_psnr'])} "
                   f"dB, {100 * s['share_at_least_50']:.1f}% at >= 50 dB, {s['identical']} identical, "
                   f"{s['failed_runs']} failed runs, {s['below_threshold']} below {args.threshold:g} dB")
    for name in ("normals", "depth"):
        if f"{name}_median_psnr" in s:
            console.result(f"{name}: median PSNR {campaign.psnr_text(s[f'{name}_median_psnr'])} dB, "
                           f"{100 * s[f'{name}_share_at_least_50']:.1f}% at >= 50 dB, {s[f'{name}_identical']} "
                           "identical")
    if args.json_file:
        with atomic_file(args.json_file, "w") as f:
            f.write(campaign.report_json(rows, args.threshold, args.seed))
    return ExitStatus.OK if campaign.passed(rows, args.threshold) else ExitStatus.DIFFER


DIFFTEST = Command("difftest", "Differential testing against another a5 executable on seeded random scenes.",
                   FLAGS, run_difftest,
                   exit_ok="every scene at or above --threshold (identical scenes: inf dB)",
                   exit_differ="a scene below the threshold, or a failed run of the binary")

"""``a5mi bench [SCENE ...]``: how fast the real ``a5`` command is, and how far from what Mitsuba can do
(:mod:`a5mi.bench`; figures go to BENCHMARKS.md, never into timed tests)."""

from __future__ import annotations

from a5mi.cli.app import Command, Console, activate_variant
from a5mi.cli.flags import Args, Flag, Positional, integer, json_file_flag, json_flag, real, size_flag, text
from a5mi.platform.errors import ExitStatus, UsageError

FLAGS: tuple[Flag, ...] = (
    size_flag((300, 300), "image size of the test command"),
    Flag(("--bounces", "-bounces"), "bounces", "bounces of the test command", 1, integer(0, 64), 4, "N"),
    Flag(("--repeat",), "repeat", "timed repetitions of in-process passes (best kept)", 1, integer(1, 1000), 3, "N"),
    Flag(("--a5soln",), "a5soln", "time the sample-solution binary too", 1, text, metavar="PATH"),
    Flag(("--4k",), "k4", "also one 3840x2160 -jitter -filter process run", default=False, show_default=False),
    Flag(("--4k-scene",), "k4_scene", "scene of the --4k run", 1, text, "scene10", "NAME"),
    json_flag("the figures"),
    json_file_flag("the figures"),
    Flag(("--no-process",), "no_process", "skip the a5 child processes", default=False, show_default=False),
    Flag(("--no-inprocess",), "no_inprocess", "skip the floor and stock measurements", default=False,
         show_default=False),
    Flag(("--no-stock",), "no_stock", "skip the stock Mitsuba comparison", default=False, show_default=False),
    Flag(("--warm-runs",), "warm_runs", "warm process runs per scene (best kept)", 1, integer(1, 100), 2, "N"),
    Flag(("--verbose-runs",), "verbose_runs", "warm 'a5 -v' runs per scene for the stage table (0: none)", 1,
         integer(0, 100), 2, "N"),
    Flag(("--wait-idle",), "wait_idle", "before each scene, wait up to S s for other processes to leave the CPUs",
         1, real, 30.0, "S"),
    Flag(("--batch-renders",), "batch_renders", "extra renders per test scene in one session (0: no batch figures)",
         1, integer(0, 100), 3, "N"),
    Flag(("--timeout",), "timeout", "limit per child process (s)", 1, real, 600.0, "S"),
)


def run_bench(args: Args, console: Console) -> int:
    from a5mi import bench
    from a5mi.platform.imageio import atomic_file

    try:
        skipped = {"process": args.no_process, "inprocess": args.no_inprocess, "stock": args.no_stock}
        settings = bench.BenchSettings(
            test=bench.assignment_command(args.width, args.height, args.bounces), repeat=args.repeat,
            a5soln=bench.find_executable(args.a5soln) if args.a5soln else None,
            k4_scene=args.k4_scene if args.k4 else None, parts=bench.PARTS - {p for p, off in skipped.items() if off},
            warm_runs=args.warm_runs, verbose_runs=args.verbose_runs, wait_idle=args.wait_idle,
            timeout=args.timeout, batch_renders=args.batch_renders)
        paths = bench.resolve_scenes(args.scenes)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    if args.json_file is not None:
        from a5mi.platform import clobber
        from a5mi.platform.paths import check_target

        check_target(args.json_file)
        clobber.check_outputs([("--json-file", args.json_file)],
                              [*paths, *([settings.a5soln] if settings.a5soln else [])], of="")
    if "inprocess" in settings.parts:
        activate_variant(None)

    def log(msg: str) -> None:
        if not console.quiet:
            console.note(f"[bench] {msg}")

    run = bench.run_benchmark(paths, settings, log)
    if args.json_file is not None:
        with atomic_file(args.json_file, "w") as f:
            f.write(run.to_json() + "\n")
    console.result(run.to_json() if args.json else run.report())
    return ExitStatus.DIFFER if run.failed else ExitStatus.OK


BENCH = Command("bench", "Time the a5 command (cold and warm processes, stages, traversal floor, stock Mitsuba) on "
                "the benchmark scenes.", FLAGS, run_bench,
                (Positional("scenes", "SCENE", "scene files or names (default: the six benchmark scenes)", "*"),),
                exit_ok="every measurement ran", exit_differ="a measured command failed (named in the report)")

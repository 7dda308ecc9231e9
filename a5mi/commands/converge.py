"""``a5mi converge SCENE.txt``: time and RMSE per spp of the extension's sampling (docs/EXTENSIONS.md E.5)."""

from __future__ import annotations

from a5mi.cli.app import Command, Console, activate_variant, load_scene
from a5mi.cli.flags import Args, Flag, Positional, integer, size_flag
from a5mi.platform.errors import ExitStatus

FLAGS: tuple[Flag, ...] = (
    size_flag((300, 300)),
    Flag(("--max-spp",), "max_spp", "largest spp measured (powers of two from 1)", 1, integer(1, 65536), 32, "N"),
    Flag(("--reference-spp",), "reference_spp", "spp of the reference render (another seed)", 1,
         integer(1, 1 << 20), 512, "N"),
)


def run_converge(args: Args, console: Console) -> int:
    from a5mi.bench.convergence import convergence

    load_scene(args.scene, console)  # positioned errors before the JIT starts
    activate_variant(None)
    spps = tuple(1 << k for k in range(args.max_spp.bit_length()) if 1 << k <= args.max_spp)
    fig = convergence(args.scene, size=(args.width, args.height), spps=spps, reference_spp=args.reference_spp)
    console.result(f"{args.scene} at {args.width}x{args.height}, -shadows -bounces 4, reference "
                   f"{fig['reference_spp']} spp ({fig['reference_seconds']:.1f} s)")
    console.result("| spp | seconds | RMSE |\n|---:|---:|---:|")
    for r in fig["rows"]:
        console.result(f"| {r['spp']} | {r['seconds']:.2f} | {r['rmse']:.5f} |")
    console.result(f"slope of log RMSE against log spp: {fig['slope']:.3f} (independent sampling: -0.5)")
    return ExitStatus.OK


CONVERGE = Command("converge", "Time and RMSE against a high-spp render per spp (docs/EXTENSIONS.md E.5).",
                   FLAGS, run_converge, (Positional("scene", "SCENE.txt", "the scene"),),
                   exit_ok="the table printed")

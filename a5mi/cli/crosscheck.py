"""``a5mi crosscheck SCENE.txt``: the a5 dielectric against textbook Schlick, exact Fresnel and Mitsuba's
``path`` on the same camera rays (:mod:`a5mi.crosscheck`)."""

from __future__ import annotations

from pathlib import Path

from a5mi.cli.app import Command, Console, activate_variant, load_scene
from a5mi.cli.flags import Args, Flag, Positional, integer, text
from a5mi.spec import MAX_SIZE

FLAGS: tuple[Flag, ...] = (
    Flag(("--size", "-size"), ("width", "height"), "image size", 2, integer(1, MAX_SIZE), (300, 300), "W H"),
    Flag(("-o", "--output", "-output"), "output", "montage: renders, Fresnel-mode error maps, pixel classes, "
         "error maps against path (default: SCENE_crosscheck.png here)", 1, text, metavar="MONTAGE.png"),
    Flag(("--spp", "-spp"), "spp", "path samples per pixel", 1, integer(1, 1 << 20), 256, "N"),
    Flag(("--bounces", "-bounces"), "bounces", "Whitted bounce budget (path: max_depth = N + 2)", 1,
         integer(0, 64), 4, "N"),
    Flag(("--bump", "-bump"), "bump", "bump and normal maps on both sides (docs/EXTENSIONS.md E.7)", default=False,
         show_default=False),
    Flag(("--json",), "json", "print the table as JSON", default=False, show_default=False),
    Flag(("--explain",), "explain", "also split (stock path - exact Whitted) into terms, each isolated by a render "
         "(slow: three more path renders)", default=False, show_default=False),
)

SUMMARY = ("Render SCENE with the a5 dielectric, textbook Schlick and exact Fresnel (a5_whitted, shadows on) and "
           "with Mitsuba's path integrator on the --stock conversion (pixel centres, no Russian roulette); print "
           "per pair the metrics over glass pixels (the Whitted ray tree touches a dielectric) and over all other "
           "pixels, and write a montage.")


def run_crosscheck(args: Args, console: Console) -> int:
    from a5mi import crosscheck as xc
    from a5mi.imageio import check_output_path

    out = args.output or f"{Path(args.scene).stem}_crosscheck.png"
    check_output_path(out)
    desc = load_scene(args.scene, console, bump=bool(args.bump))
    activate_variant(None)
    options = xc.CrosscheckOptions(width=args.width, height=args.height, bounces=args.bounces, spp=args.spp,
                                   bump=bool(args.bump))
    result = xc.crosscheck(desc, options)
    xc.write_montage(result, out)
    console.result(xc.to_json(result) if args.json else f"{args.scene}\n{xc.table(result)}\nmontage: {out}")
    if args.explain:
        console.result(xc.explain_table(xc.explain(desc, options)))
    return 0


CROSSCHECK = Command("crosscheck", SUMMARY, FLAGS, run_crosscheck, (Positional("scene", "SCENE.txt", "the scene"),))

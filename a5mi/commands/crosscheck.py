"""``a5mi crosscheck SCENE.txt``: the a5 dielectric against textbook Schlick, exact Fresnel and Mitsuba's
``path`` on the same camera rays (:mod:`a5mi.crosscheck`, docs/CROSSCHECK.md).

Its verdict is the check the three Fresnel modes must pass (SPEC B.3: the Fresnel weight only scales the
mirror and refracted rays pushed at a dielectric): on every pixel whose ray tree touches no dielectric (region
``other``) the ``a5``, ``schlick`` and ``exact`` images agree bit for bit, ``max_error == 0``. Exit status 1
when they do not (:func:`fresnel_disagreements`); the ``path`` rows are measurements, never a verdict.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from a5mi.cli.app import Command, Console, activate_variant, load_scene
from a5mi.cli.flags import Args, Flag, Positional, integer, json_flag, size_flag, text
from a5mi.platform.errors import ExitStatus

FLAGS: tuple[Flag, ...] = (
    size_flag((300, 300)),
    Flag(("-o", "--output", "-output"), "output", "montage: renders, Fresnel-mode error maps, pixel classes, "
         "error maps against path (default: SCENE_crosscheck.png here)", 1, text, metavar="MONTAGE.png"),
    Flag(("--spp", "-spp"), "spp", "path samples per pixel", 1, integer(1, 1 << 20), 256, "N"),
    Flag(("--bounces", "-bounces"), "bounces", "Whitted bounce budget (path: max_depth = N + 2)", 1,
         integer(0, 64), 4, "N"),
    Flag(("--bump", "-bump"), "bump", "bump and normal maps on both sides (docs/EXTENSIONS.md E.7)", default=False,
         show_default=False),
    Flag(("--media-bounces", "-media_bounces"), "media_bounces", "the a5 side's -media_bounces (1: light "
         "attenuated through Fog/Volume as in volpath; 0: the course-era medium, docs/EXTENSIONS.md E.8)", 1,
         integer(0, 64), 1, "N"),
    json_flag("the table"),
    Flag(("--explain",), "explain", "also split (stock path - exact Whitted) into terms, each isolated by a render "
         "(slow: three more path renders)", default=False, show_default=False),
)

SUMMARY = ("Render SCENE with the a5 dielectric, textbook Schlick and exact Fresnel (a5_whitted, shadows on) and "
           "with Mitsuba's path integrator on the --stock conversion (pixel centres, no Russian roulette); print "
           "per pair the metrics over glass pixels (the Whitted ray tree touches a dielectric) and over all other "
           "pixels, and write a montage.")


def fresnel_disagreements(pairs: list[Any]) -> list[Any]:
    """The pair reports (:class:`a5mi.crosscheck.PairReport`) of two Fresnel modes over the non-glass pixels
    that are not bit for bit equal (module docstring): empty when the check holds."""
    return [r for r in pairs if r.region == "other" and "path" not in (r.a, r.b) and r.metrics is not None
            and r.metrics.max_error != 0]


def run_crosscheck(args: Args, console: Console) -> int:
    from a5mi import crosscheck as xc
    from a5mi.platform.imageio import check_output_path

    out = args.output or f"{Path(args.scene).stem}_crosscheck.png"
    from a5mi.platform import clobber

    inputs: list[Any] = []
    desc = load_scene(args.scene, console, bump=bool(args.bump), inputs=inputs)  # the scene's errors come first
    check_output_path(out)
    clobber.check_outputs([("-o", out)], inputs)
    activate_variant(None)
    options = xc.CrosscheckOptions(width=args.width, height=args.height, bounces=args.bounces, spp=args.spp,
                                   bump=bool(args.bump), media_bounces=args.media_bounces)
    result = xc.crosscheck(desc, options)
    xc.write_montage(result, out)
    console.result(xc.to_json(result) if args.json else f"{args.scene}\n{xc.table(result)}\nmontage: {out}")
    if args.explain:
        console.result(xc.explain_table(xc.explain(desc, options)))
    bad = fresnel_disagreements(result.pairs)
    for r in bad:
        console.error(f"check failed: {r.a} and {r.b} differ where the ray tree touches no dielectric (max "
                      f"{r.metrics.max_error:g}/255 over those {r.pixels} pixels; the Fresnel modes must agree there "
                      "bit for bit)")
    return ExitStatus.DIFFER if bad else ExitStatus.OK


CROSSCHECK = Command("crosscheck", SUMMARY, FLAGS, run_crosscheck, (Positional("scene", "SCENE.txt", "the scene"),),
                     exit_ok="the table printed and the Fresnel modes agree bit for bit off glass",
                     exit_differ="they differ on a pixel whose ray tree touches no dielectric (a check that "
                                 "must hold)")

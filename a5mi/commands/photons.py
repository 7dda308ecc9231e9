"""``a5mi photons SCENE.txt -o map.png``: the photon maps drawn over the image, photon counts per surface
(docs/EXTENSIONS.md E.16); ``--ppm OUT --passes N``: progressive photon mapping here or on Dask (E.17).

The libraries are :mod:`a5mi.photons.report` (counts, projection, the overlay) and :mod:`a5mi.photons.passes`
(the ppm passes, here, on ``--workers N`` local Dask worker processes or on the cluster of ``--scheduler``).
"""

from __future__ import annotations

import dataclasses
import json

from a5mi.cli.app import Command, Console, activate_variant, load_scene
from a5mi.cli.flags import Args, Flag, Positional, integer, text
from a5mi.cli.scheduler import SCHEDULER_FLAGS, scheduler_security
from a5mi.commands.render import IMAGE_OUTPUT_DESTS, check_render_args, render_flags_except, render_options
from a5mi.platform.errors import ExitStatus, UsageError

FLAGS: tuple[Flag, ...] = (
    Flag(("-o", "--output"), "output", "the image with the photons drawn over it (global blue, caustic orange)",
         1, text, metavar="MAP.png"),
    Flag(("--json",), "json", "print the counts per surface as JSON", default=False, show_default=False),
    Flag(("--ppm",), "ppm", "render progressive photon mapping (-integrator ppm) to this image instead", 1, text,
         metavar="IMG"),
    Flag(("--passes",), "passes", "ppm passes (each an independent photon map and image)", 1,
         integer(1, 1 << 20), 16, "N"),
    Flag(("--workers",), "workers", "run the ppm passes on N local Dask worker processes", 1, integer(1, 512),
         metavar="N"),
    Flag(("--scheduler",), "scheduler", "run the ppm passes on an existing Dask cluster", 1, text,
         metavar="tls://HOST:PORT"),
    *SCHEDULER_FLAGS,
    *render_flags_except(IMAGE_OUTPUT_DESTS | {"input"}),
)


def check_photons_args(args: Args) -> None:
    if (args.output is None) == (args.ppm is None):
        raise UsageError("give -o MAP.png (the photon map) or --ppm IMG (a progressive render), one of them")
    if args.workers is not None and args.scheduler is not None:
        raise UsageError("give --workers or --scheduler, not both")
    if (args.workers is not None or args.scheduler is not None) and args.ppm is None:
        raise UsageError("--workers and --scheduler split the --ppm passes; give --ppm IMG")
    check_render_args(args)


def _table(report: object) -> str:
    rows = [f"{'surface':<22} {'direct':>8} {'indirect':>9} {'caustic':>8} {'global power':>13} "
            f"{'caustic power':>14}"]
    for s in report.surfaces:   # type: ignore[attr-defined]
        rows.append(f"{s.name:<22} {s.direct:>8} {s.indirect:>9} {s.caustic:>8} {s.global_power:>13.4g} "
                    f"{s.caustic_power:>14.4g}")
    return "\n".join(rows)


def run_photons(args: Args, console: Console) -> int:
    from pathlib import Path

    from a5mi.platform import clobber, imageio
    from a5mi.platform.paths import check_target

    inputs: list[Path] = []
    desc = load_scene(args.scene, console, inputs=inputs, bump=bool(args.bump))
    target = args.output if args.ppm is None else args.ppm
    check_target(target)
    clobber.check_outputs([("-o" if args.ppm is None else "--ppm", target)], inputs)
    if args.ppm is not None:
        from a5mi.photons.passes import render_ppm

        options = dataclasses.replace(render_options(args, count_rays=False), integrator="ppm")
        security = scheduler_security(args)  # tcp:// only with --insecure-scheduler, as grade
        if args.workers is None and args.scheduler is None:
            activate_variant(args.variant)
        image, info = render_ppm(args.scene, options, args.passes, workers=args.workers,
                                 scheduler=args.scheduler, security=security, variant=args.variant)
        imageio.write_images([(args.ppm, image)])
        console.note(f"a5mi photons: {args.passes} ppm passes in {info['wall_s']:.1f} s on {len(info['pids'])} "
                     f"process(es), mean {sum(info['seconds']) / len(info['seconds']):.2f} s per pass")
        return ExitStatus.OK
    from a5mi.photons.report import overlay, photon_report
    from a5mi.render.session import render

    options = render_options(args, count_rays=False)
    activate_variant(args.variant)
    result = render(desc, options)
    h, w = result.image.shape[:2]
    report = photon_report(desc, options, (w, h))
    imageio.write_images([(args.output, overlay(result.image, report))])
    console.result(json.dumps(report.as_json(), indent=1) if args.json else _table(report))
    console.note(f"a5mi photons: {report.emitted['global']} global + {report.emitted['caustic']} caustic photons "
                 f"traced in {report.seconds:.1f} s; drawn: {len(report.global_px)} global, "
                 f"{len(report.caustic_px)} caustic (visible from the camera)")
    return ExitStatus.OK


PHOTONS = Command("photons", "Trace the photon maps of a scene (docs/EXTENSIONS.md E.16) and draw them over its "
                  "image with the photon counts per surface; or, with --ppm, render progressive photon mapping "
                  "(E.17) here or on Dask workers.",
                  FLAGS, run_photons, (Positional("scene", "SCENE.txt", "scene file"),), check=check_photons_args,
                  exit_ok="the photon-map picture (or with --ppm the image) written")

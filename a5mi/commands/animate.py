"""``a5mi animate SCENE.txt -o FRAMES_DIR``: the frames of an animated scene, optionally a video (EXTENSIONS E.11).

The library is :mod:`a5mi.animate` (keyframes: docs/EXTENSIONS.md E.11, motion blur: E.12). This module turns
the flags into :class:`~a5mi.render.options.RenderOptions` (the ``a5`` render flags, less the AOV outputs), checks
the outputs before anything renders, shows a progress bar with frames/s and ETA (tqdm) and prints a summary.
"""

from __future__ import annotations

import time

from a5mi.cli.app import Command, Console, activate_variant
from a5mi.cli.flags import Args, Flag, Positional, integer, text
from a5mi.cli.scheduler import SCHEDULER_FLAGS, scheduler_security
from a5mi.commands.render import IMAGE_OUTPUT_DESTS, check_render_args, render_flags_except, render_options
from a5mi.platform.errors import ExitStatus, UsageError, UserError
from a5mi.runtime.extras import require


def frame_span(flag: str, values: list[str]) -> tuple[int, int]:
    """``A:B``: frames A to B - 1 (a Python slice), ``0 <= A < B``."""
    a, sep, b = values[0].partition(":")
    if not sep or not a.isdigit() or not b.isdigit() or int(a) >= int(b):
        raise UsageError(f"{flag} expects A:B with 0 <= A < B (frames A to B-1), found '{values[0][:40]}'")
    return int(a), int(b)


FLAGS: tuple[Flag, ...] = (
    Flag(("-o", "--output"), "output", "folder of the frames (frame_00000.png + .sha256 beside each)", 1, text,
         metavar="FRAMES_DIR"),
    Flag(("--video",), "video", "also encode the frames as a video (.mp4 H.264 or .gif)", 1, text,
         metavar="OUT.mp4"),
    Flag(("--frames",), "frames", "render frames A to B-1 only (default: all of the Animation block)", 1,
         frame_span, metavar="A:B"),
    Flag(("--workers",), "workers", "render on N local Dask worker processes (default: in this process)", 1,
         integer(1, 512), metavar="N"),
    Flag(("--scheduler",), "scheduler", "render on an existing Dask cluster", 1, text, metavar="tls://HOST:PORT"),
    *SCHEDULER_FLAGS,
    Flag(("--resume",), "resume", "render only the frames that are missing or fail their checksum",
         default=False, show_default=False),
    *render_flags_except(IMAGE_OUTPUT_DESTS | {"input"}),  # the scene is the positional SCENE.txt
)


def check_animate_args(args: Args) -> None:
    if args.workers is not None and args.scheduler is not None:
        raise UsageError("give --workers or --scheduler, not both")
    check_render_args(args)


def run_animate(args: Args, console: Console) -> int:
    from pathlib import Path

    from a5mi.animate import batch, video
    from a5mi.animate import frames as framefiles
    from a5mi.cli.app import load_scene
    from a5mi.converters.a5_parser import parse_file
    from a5mi.platform import clobber
    from a5mi.platform.paths import check_target

    require("tqdm", "animate")  # the optional modules this run uses, checked before anything renders
    if args.workers is not None or args.scheduler is not None:
        require("distributed", "animate")
    security = scheduler_security(args)  # tcp:// only with --insecure-scheduler, as grade
    if args.video is not None:
        require("imageio_ffmpeg", "animate")
        video.check_video_path(args.video)
        check_target(args.video)
    out = Path(args.output)
    if out.exists() and not out.is_dir():
        raise UserError(f"-o '{out}' is not a folder")
    inputs: list[Path] = []
    load_scene(args.scene, console, inputs=inputs)  # warnings, and every file the scene names, before rendering
    anim = parse_file(args.scene).animation
    if anim is None:
        raise UserError(f"'{args.scene}' has no Animation block (docs/EXTENSIONS.md E.11)")
    a, b = args.frames if args.frames is not None else (0, anim.frames)
    if b > anim.frames:
        raise UsageError(f"--frames {a}:{b}: the animation has {anim.frames} frames (0 to {anim.frames - 1})")
    if args.video is not None:
        clobber.check_outputs([("--video", args.video)], inputs)
    if out.is_dir():  # a frame or its checksum over an input (frames are distinct by name: one check each)
        for f in range(a, b):
            image = framefiles.frame_path(out, f)
            for path in (image, framefiles.checksum_path(image)):
                clobber.check_outputs([("-o", path)], inputs)
    options = render_options(args, count_rays=False)
    security = scheduler_security(args)
    if args.workers is None and args.scheduler is None:
        activate_variant(args.variant)
    bar = None

    def progress(done: int, total: int) -> None:
        nonlocal bar
        if bar is None:
            tqdm = require("tqdm", "animate").tqdm

            bar = tqdm(total=total, initial=done, unit="frame", file=console.err, dynamic_ncols=True,
                       disable=console.quiet or not console.err.isatty(), desc="frames", smoothing=0.1)
        else:
            bar.update(done - bar.n)

    t0 = time.perf_counter()
    try:
        outcome = batch.render_animation(args.scene, out, options, range(a, b), workers=args.workers,
                                         scheduler=args.scheduler, security=security, resume=args.resume,
                                         variant=args.variant,
                                         progress=progress)
    finally:
        if bar is not None:
            bar.close()
    for e in outcome.errors[:5]:
        console.error(f"frames {e}")
    n = len(outcome.rendered)
    rate = n / outcome.wall_s if outcome.wall_s > 0 else 0.0
    console.note(f"a5mi animate: {n} frames rendered ({rate:.2f} frames/s), {outcome.skipped} already done, "
                 f"in {out}")
    if args.verbose:
        for r in outcome.records:
            frames = len(r["frames"])
            console.note(f"a5mi animate: pid {r['pid']}: {frames} frames, build {r['build_s']:.2f} s, update "
                         f"{r['update_s']:.2f} s, render {r['render_s']:.2f} s (kernels {r['kernel_s']:.2f} s), "
                         f"kernels {r['kernels']}, peak {r['peak_mb']:.0f} MB")
    missing = framefiles.missing_frames(out, range(a, b))
    if missing:
        console.error(f"{len(missing)} frames are missing (first {missing[0]}); run again with --resume")
        return ExitStatus.DIFFER
    if args.video is not None:
        video.encode(args.video, [framefiles.frame_path(out, f) for f in range(a, b)], anim.fps)
        console.note(f"a5mi animate: video {args.video} ({time.perf_counter() - t0:.1f} s in all)")
    return ExitStatus.OK


ANIMATE = Command("animate", "Render the frames of a scene's Animation block (docs/EXTENSIONS.md E.11, E.12), here "
                  "or on Dask workers, each frame written atomically with its checksum; optionally a video.",
                  FLAGS, run_animate, (Positional("scene", "SCENE.txt", "scene file with an Animation block"),),
                  required=("output",), check=check_animate_args, exit_ok="every frame written",
                  exit_differ="some frames are missing after the run (a worker failed; see --resume)")

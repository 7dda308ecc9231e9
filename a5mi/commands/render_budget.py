"""What a render may cost, checked before it starts: its peak memory against what the machine has, and its
work (rays, seconds) against an hour (docs/USAGE.md "Work estimate and progress"); with ``-v``, the rays it
traced against the estimate afterwards. Used by ``a5`` / ``a5mi render`` and the commands that render."""

from __future__ import annotations

from typing import Any

from a5mi.cli.app import Console
from a5mi.cli.flags import Args
from a5mi.render.options import RenderOptions


def check_memory(args: Args, options: RenderOptions) -> None:
    """Refuse, before anything is read, a render whose estimated peak memory (:func:`a5mi.render.limits.
    memory_need`: the render buffers, the integrator's photon maps, kd-trees, statistics or records, and the
    bands of ``-workers`` / ``-scheduler``) exceeds the memory available (a user error: a smaller ``-size``)."""
    from a5mi.render import limits

    aovs = bool(args.get("normals_output") or args.get("depth_output"))
    workers = args.get("workers") if args.get("workers") is not None else (
        0 if args.get("scheduler") is not None else None)
    hint = " (-jitter -filter streams the render buffer)" if args.jitter and not args.filter else ""
    limits.check_memory(options, aovs=aovs, workers=workers, hint=hint)


def check_work(desc: Any, options: RenderOptions, console: Console, *, force: bool, verbose: bool) -> Any:
    """The work estimate of a render (:func:`a5mi.render.estimate.estimate`), before the JIT starts: over
    :data:`~a5mi.render.estimate.REFUSE_SECONDS` a positioned scene error (exit 2) naming the flags that
    reduce it, unless ``force``; over :data:`~a5mi.render.estimate.WARN_SECONDS` a positioned warning; with
    ``-v`` a note. Returns the estimate."""
    from a5mi.converters.errors import SceneError
    from a5mi.render import estimate as est

    work = est.estimate(desc, options)
    if work.seconds > est.REFUSE_SECONDS and not force:
        raise SceneError(est.refusal(work), work.loc)
    if work.seconds > est.WARN_SECONDS:
        console.warnings([(work.loc if work.loc is not None else desc.path, est.warning(work))])
    elif verbose:
        console.note(f"{console.prog}: estimate {est.summary(work)}")
    return work


def report_work(console: Console, work: Any, options: RenderOptions, result: Any, timings: dict[str, float]) -> None:
    """``-v``: the rays the render traced against the estimate's bound, and this machine's ray rate kept for
    the next estimate (:func:`a5mi.render.estimate.record_rate`, from the plain render's kernel time)."""
    from a5mi.render import estimate as est
    from a5mi.render.crop import traced_samples

    traced = traced_samples(options) * options.spp + sum(result.ray_counts.values())
    console.note(f"{console.prog}: traced {traced} rays of the estimate's {work.rays:.3g} "
                 f"({work.rays / max(traced, 1):.1f} x)")
    if not work.extra_rays:  # photons and cache records are not in the counts: their rate would be wrong
        est.record_rate(traced, timings.get("execute", 0.0))

"""``a5mi trace``: why one pixel has its colour: the SPEC B.3 ray tree as ``a5_whitted`` computes it.

``a5mi trace -input S.txt -size W H -pixel X Y [a5 render flags] [--origin bottom-left] [--sample K] [--json]
[--svg OUT.svg]`` (the a5 flags less those naming images: trace writes none)
prints every node of the pixel's ray tree (the render kernel in record mode, :mod:`a5mi.trace`)
and checks that the contributions sum to the pixel of the real render. ``--diff STUDENT.png [--worst N]``
renders the reference, picks the N pixels where the student's image is furthest off and names, for each,
the term of the reference tree that best accounts for the difference; pixels within the noise threshold
(:data:`a5mi.trace.report.DIFF_NOISE` levels) are not named, so an identical image prints "nothing differs";
otherwise it ends with the ``a5mi diagnose`` command that names the mistake behind the whole image
(docs/MISTAKES.md). ``-pixel X Y --diff STUDENT.png`` explains that pixel instead, saying so when it is within
the noise threshold.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from a5mi.cli.app import Command, Console, activate_variant, load_scene
from a5mi.cli.flags import Args, Flag, choice, integer, json_flag, text
from a5mi.commands.render import IMAGE_OUTPUT_DESTS, check_render_args, render_flags_except, render_options
from a5mi.platform.errors import ExitStatus, ImageWriteError
from a5mi.spec import MAX_SIZE

FLAGS: tuple[Flag, ...] = (
    *render_flags_except(IMAGE_OUTPUT_DESTS),
    Flag(("--pixel", "-pixel"), ("px", "py"), "the pixel to trace (x right, y down from the top-left; see "
         "--origin)", 2, integer(0, MAX_SIZE), (None, None), "X Y"),
    Flag(("--origin",), "origin", "where -pixel counts from: top-left (image viewers) or bottom-left (a5soln's j)",
         1, choice(("top-left", "bottom-left")), "top-left", "O"),
    Flag(("--sample",), "sample", "with -jitter: only sub-sample K (0..8, row-major from the pixel's top-left)",
         1, integer(0, 8), metavar="K"),
    json_flag("the trace"),
    Flag(("--svg",), "svg", "also write a diagram of the (first shown) ray tree", 1, text, metavar="OUT.svg"),
    Flag(("--diff",), "diff", "find the pixels where this student image is furthest from the reference and name "
         "the term to look at (pixels off by at most 2/255 are noise: none named); with -pixel: that pixel",
         1, text, metavar="STUDENT.png"),
    Flag(("--worst",), "worst", "with --diff: how many pixels (default 3; not with -pixel)", 1, integer(1, 1000),
         metavar="N"),
)


def check_trace_args(args: Args) -> None:
    from a5mi.trace.core import TraceError

    check_render_args(args)
    if args.get("integrator", "whitted") not in ("whitted", "path"):  # recorders: a5_whitted's tree, a5_path's samples
        raise TraceError(f"a5mi trace follows -integrator whitted (its ray tree, -indirect's samples) and path (its "
                         f"samples), not {args.integrator}")
    if args.sample is not None and not args.jitter:
        raise TraceError("--sample needs -jitter (without it a pixel has one camera ray)")
    if args.diff is None and args.px is None:
        raise TraceError("give -pixel X Y (or --diff STUDENT.png)")
    if args.worst is not None and (args.diff is None or args.px is not None):
        raise TraceError("--worst goes with --diff alone (with -pixel X Y, --diff explains that pixel)")
    if args.diff is not None and args.jitter and not args.filter:
        raise TraceError("--diff with -jitter alone: the saved image is the 3W x 3H buffer; use -jitter -filter")
    if args.svg is not None:
        folder = os.path.dirname(os.path.abspath(args.svg))
        if not args.svg.lower().endswith(".svg"):
            raise TraceError(f"--svg '{args.svg}' must end in .svg")
        if not os.path.isdir(folder) or not os.access(folder, os.W_OK):
            raise ImageWriteError(f"--svg '{args.svg}': folder '{folder}' does not exist or is not writable")
        from a5mi.platform import clobber
        from a5mi.platform.paths import check_target

        check_target(args.svg)
        clobber.check_outputs([("--svg", args.svg)], [args.input, *([args.diff] if args.diff else [])])


def run_trace(args: Args, console: Console) -> int:
    from a5mi.platform import clobber
    from a5mi.trace import report
    from a5mi.trace.core import Tracer, to_top_left

    inputs: list[Any] = []
    desc = load_scene(args.input, console, inputs=inputs)
    if args.svg is not None:  # nor any file the scene reads
        clobber.check_outputs([("--svg", args.svg)], inputs)
    activate_variant(args.variant)
    options = render_options(args, normals=False, depth=None, count_rays=False)
    tracer = Tracer(desc, options)
    from a5mi.trace import paths

    if paths.stochastic_mode(options) is not None:  # docs/EXTENSIONS.md E.14, E.15: samples and contributions
        return _run_samples(args, console, tracer, options)
    if args.diff is not None:
        return _run_diff(args, console, tracer, desc)
    x, y = to_top_left(options, args.px, args.py, args.origin)
    (pt,) = tracer.pixels([(x, y)])
    if args.json:
        console.result(report.dumps(report.trace_json(pt)))
    else:
        console.result(report.format_trace(pt, desc.ambient, args.sample))
    if args.svg is not None:
        from a5mi.trace.svg import write_svg

        k = args.sample if args.sample is not None else 0
        write_svg(args.svg, pt.trees[k], f"{args.input} pixel ({x}, {y}) sample {k}")
    return ExitStatus.OK


#: ``--diff`` without ``-pixel``: how many of the worst pixels are explained unless ``--worst`` says.
DIFF_WORST = 3


def _run_diff(args: Args, console: Console, tracer: Any, desc: Any) -> int:
    """``--diff STUDENT.png``: the ``--worst`` pixels furthest from the reference, or the ``-pixel`` asked for,
    each with the reference term that best accounts for the difference (docs/TRACE.md)."""
    from a5mi.platform.imageio import quantize, read_levels
    from a5mi.trace import report
    from a5mi.trace.core import TraceError, to_top_left

    student = read_levels(args.diff)
    ref = tracer.image()
    if student.shape[:2] != ref.shape[:2]:
        raise TraceError(f"--diff '{args.diff}' is {student.shape[1]}x{student.shape[0]}; the reference render is "
                         f"{ref.shape[1]}x{ref.shape[0]}")
    ref_bytes = quantize(ref)[..., :3].astype(np.float64)
    err = np.abs(student - ref_bytes).max(axis=-1)
    if args.px is not None:  # the pixel asked for, whether or not it differs
        pixels = [to_top_left(tracer.options, args.px, args.py, args.origin)]
    else:
        order = np.argsort(-err, axis=None, kind="stable")[: args.worst or DIFF_WORST]
        pixels = [(int(k % err.shape[1]), int(k // err.shape[1])) for k in order if report.differs(err.flat[k])]
    if not pixels:
        console.result("[]" if args.json else f"nothing differs: no pixel is off by more than {report.DIFF_NOISE}/255 "
                       f"(the noise threshold; largest difference {int(err.max())}/255)")
        return 0
    traces = tracer.pixels(pixels)
    out_json = []
    blocks = []
    for pt in traces:
        stud = student[pt.y, pt.x] / 255.0
        ranked = report.explain(pt, stud)
        centre = 4 if len(pt.block) > 1 else 0
        if args.json:
            out_json.append({"pixel": [pt.x, pt.y], "student_byte": [int(v) for v in student[pt.y, pt.x]],
                             "reference_byte": list(pt.image_byte), "reference": list(pt.value),
                             "terms": [{"label": t.label, "kind": t.kind, "value": list(t.value), "sign": t.sign,
                                        "residual": r} for t, r in ranked[:5]],
                             "trace": report.trace_json(pt)})
            continue
        lines = [f"pixel ({pt.x}, {pt.y}) (top-left): student {tuple(int(v) for v in student[pt.y, pt.x])}, "
                 f"reference {pt.image_byte} (off by {int(err[pt.y, pt.x])}/255)"]
        if not report.differs(err[pt.y, pt.x]):
            lines.append(f"  within the noise threshold ({report.DIFF_NOISE}/255): nothing to explain")
        elif not ranked:
            lines.append("  no single term of the reference tree accounts for the difference")
        else:
            best, resid = ranked[0]
            lines.append(f"  look at: {best.label}: {report.v3(best.value, 4)} "
                         f"({'the student adds it' if best.sign > 0 else 'the student lacks it'}; leaves "
                         f"{resid * 255:.1f}/255 unexplained)")
            for t, r in ranked[1:3]:
                lines.append(f"  then: {t.label}: {report.v3(t.value, 4)} (leaves {r * 255:.1f}/255)")
        lines.append(f"  reference tree{' of the centre sample' if centre else ''}:")
        lines.extend("    " + s for s in report.tree_lines(pt.trees[centre], tracer.options.fresnel, desc.ambient))
        blocks.append("\n".join(lines))
    console.result(report.dumps(out_json) if args.json else "\n\n".join(blocks))
    if not args.json:   # docs/MISTAKES.md: the whole image's cause, not one pixel's term
        from a5mi.commands.diagnose import hint

        console.result("\n" + hint(args.diff, args.input, tracer.options))
    if args.svg is not None and traces:
        from a5mi.trace.svg import write_svg

        pt = traces[0]
        write_svg(args.svg, pt.trees[4 if len(pt.block) > 1 else 0], f"{args.input} pixel ({pt.x}, {pt.y})")
    return ExitStatus.OK


TRACE = Command("trace", "Print the SPEC B.3 ray tree of one pixel exactly as a5_whitted computes it, with every "
                "term, checked against the real render; or (--diff) name the term a student image gets wrong.",
                FLAGS, run_trace, required=("input",), check=check_trace_args, exit_ok="the trace printed")


def _run_samples(args: Args, console: Console, tracer: Any, options: Any) -> int:
    """``-integrator path`` / ``-indirect N``: the pixel's samples and what each contributes (a5mi/trace/paths.py)."""
    from a5mi.trace import paths, report
    from a5mi.trace.core import TraceError, to_top_left

    if args.diff is not None or args.svg is not None:
        raise TraceError("--diff and --svg trace Whitted ray trees; -integrator path and -indirect print samples")
    x, y = to_top_left(options, args.px, args.py, args.origin)
    pp = paths.trace_pixel(tracer, x, y)
    console.result(report.dumps(pp.to_json()) if args.json else paths.format_pixel(pp))
    return ExitStatus.OK

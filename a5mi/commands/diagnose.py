"""``a5mi diagnose IMG -input SCENE [a5 flags]``: name the mistake that explains how IMG differs (docs/MISTAKES.md).

Renders the reference and the catalogued mistakes' mutants in one warm session and ranks them by the share of the
difference each explains (:func:`a5mi.diagnose.rank.diagnose`); prints the best causes with their evidence (where,
how much), or ``unexplained`` with the remaining error. ``--list`` prints the catalogue. ``--binary PATH`` runs
another a5 program in the sandbox on the probe scenes instead (:mod:`a5mi.diagnose.probes`). Exit status: 0 the
image matches (no mistake found), 1 a diagnosis or an unexplained difference (``--binary``: also a probe the program
gave no image for), 2 a usage error.
"""

from __future__ import annotations

import json
import math
from typing import Any

from a5mi.cli.app import Command, Console, activate_variant, load_scene
from a5mi.cli.flags import Args, Flag, Positional, json_flag, text
from a5mi.commands.render import IMAGE_OUTPUT_DESTS, check_render_args, render_flags_except, render_options
from a5mi.platform.errors import ExitStatus, UsageError

FLAGS: tuple[Flag, ...] = (
    *render_flags_except(IMAGE_OUTPUT_DESTS | {"mistakes"}),
    Flag(("--list",), "list", "print the catalogue of mistakes (docs/MISTAKES.md) and exit", default=False,
         show_default=False),
    Flag(("--only",), "only", "consider only these mistakes (comma-separated names)", 1, text, metavar="NAMES"),
    Flag(("--binary",), "binary", "diagnose another a5 program: run it (sandboxed) on the probe scenes", 1, text,
         metavar="PATH"),
    json_flag("the diagnosis"),
)


def check_diagnose_args(args: Args) -> None:
    if args.list:
        return
    if args.binary is not None:
        if args.image is not None:
            raise UsageError("--binary renders its own images: give no IMG")
        return
    if args.image is None or args.input is None:
        raise UsageError("give IMG and -input SCENE.txt (or --binary PATH, or --list)")
    check_render_args(args)
    if args.jitter and not args.filter:
        raise UsageError("-jitter without -filter saves the 3W x 3H buffer: diagnose it with -jitter -filter")
    if args.get("integrator", "whitted") != "whitted":
        raise UsageError("a5mi diagnose follows the sample solution's renderer (-integrator whitted)")


def _pct(x: float | None) -> str:
    return "-" if x is None else f"{100 * x:.1f}%"


def _db(x: float) -> str:
    return "inf" if x == float("inf") else f"{x:.1f}"


def _other(pair: tuple[str, ...], one: str) -> str:
    return next(m for m in pair if m != one)


def format_diagnosis(d: Any, image: str, scene: str) -> str:
    """The diagnosis as text: verdict, causes with the catalogue's change and symptom and the evidence."""
    lines = [f"{image} vs the reference of {scene}: PSNR {_db(d.psnr)} dB"
             + (f" (two jitter seeds differ by {_db(-10 * math.log10(2 * d.noise))} dB)"
                if d.noise > 0 else "")]
    if d.verdict == "match":
        lines.append("verdict: match (within the noise; no mistake found)")
        return "\n".join(lines)
    if d.verdict == "unexplained":
        lines.append(f"verdict: unexplained: no catalogued mistake explains the difference; remaining error PSNR "
                     f"{_db(d.psnr)} dB")
        if d.causes:   # ranked by the likelihood with each mistake's jitter noise (docs/MISTAKES.md "Closest causes")
            lines.append("closest: " + "; ".join(
                f"{' + '.join(c.mistakes)} (explains {_pct(c.explained)}"
                + (f", likelihood ratio {c.likelihood:+.3f} nats per value" if c.likelihood is not None else "")
                + ")" for c in d.causes))
        return "\n".join(lines)
    lines.append("verdict: diagnosis")
    for k, c in enumerate(d.causes, 1):
        lines.append(f"{k}. {' + '.join(c.mistakes)}: explains {_pct(c.explained)} of the difference"
                     + (" (in 4x4 block means)" if c.scale == "blocks" else "")
                     + (f"; the paired score prefers it to {_other(c.mistakes, c.partner)} alone, "
                        f"z = {c.partner_z:.1f}" if c.partner else ""))
        for m in c.catalogue:
            lines.append(f"   {m.name} (SPEC {m.section}): {m.change}")
            lines.append(f"   symptom: {m.symptom}")
        e = c.evidence
        if e is not None and e.box is not None:
            x0, y0, x1, y1 = e.box
            lines.append(f"   where: x {x0}..{x1 - 1}, y {y0}..{y1 - 1} ({e.region}, row 0 = top); "
                         f"{_pct(e.differing)} of pixels differ, {_pct(e.fixed)} of them reproduced; "
                         f"PSNR {_db(e.psnr_before)} -> {_db(e.psnr_after)} dB")
    return "\n".join(lines)


def hint(image: str, scene: str, options: Any) -> str:
    """The ``a5mi diagnose`` command line for ``image`` made from ``scene`` with ``options``' SPEC B.1 flags (the
    hint other commands print after a difference)."""
    flags = [f"-size {options.width} {options.height}", f"-bounces {options.bounces}"]
    flags += [f for f, on in (("-shadows", options.shadows), ("-jitter", options.jitter), ("-filter", options.filter))
              if on]
    return f"to name the mistake behind the difference: a5mi diagnose {image} -input {scene} {' '.join(flags)}"


def run_diagnose(args: Args, console: Console) -> int:
    from a5mi.diagnose.catalogue import CATALOGUE

    if args.list:
        if args.json:
            console.result(json.dumps([{"name": m.name, "section": m.section, "change": m.change,
                                        "symptom": m.symptom, "needs": list(m.needs), "layer": m.layer}
                                       for m in CATALOGUE]))
        else:
            console.result("\n".join(f"{m.name:28s} SPEC {m.section}: {m.change}" for m in CATALOGUE))
        return ExitStatus.OK
    if args.binary is not None:
        return _run_binary(args, console)
    from a5mi.diagnose.rank import diagnose
    from a5mi.platform.imageio import read_uint8
    from a5mi.render.session import RenderSession

    only = None
    if args.only is not None:
        known = {m.name for m in CATALOGUE}
        only = [n.strip() for n in args.only.split(",") if n.strip()]
        bad = [n for n in only if n not in known]
        if bad or not only:
            raise UsageError(f"--only expects names of docs/MISTAKES.md, found '{bad[0] if bad else args.only}'")
    image = read_uint8(args.image)
    desc = load_scene(args.input, console)
    activate_variant(args.variant)
    options = render_options(args, normals=False, depth=None, count_rays=False)
    result = diagnose(image, desc, options, session=RenderSession(args.variant), candidates=only,
                      progress=console.note if args.verbose else None)
    if args.json:
        console.result(json.dumps(result.to_dict()))
    else:
        console.result(format_diagnosis(result, args.image, args.input))
    return ExitStatus.OK if result.verdict == "match" else ExitStatus.DIFFER


def _run_binary(args: Args, console: Console) -> int:
    from a5mi.diagnose.probes import diagnose_binary, format_binary

    activate_variant(args.variant)
    report = diagnose_binary(args.binary, progress=console.note if args.verbose else None)
    console.result(json.dumps(report.to_dict()) if args.json else format_binary(report))
    clean = not report.found and not report.unexplained and all(p.diagnosis is not None for p in report.probes)
    return ExitStatus.OK if clean else ExitStatus.DIFFER   # a probe the program failed on is a difference too


DIAGNOSE = Command("diagnose", "Name the catalogued mistake (docs/MISTAKES.md) that explains how an image differs "
                   "from the reference: the mutants of every applicable mistake are rendered and ranked by the share "
                   "of the difference each explains.", FLAGS, run_diagnose,
                   (Positional("image", "IMG", "the image to diagnose (made from -input with these flags)", "?"),),
                   check=check_diagnose_args, exit_ok="the image matches the reference",
                   exit_differ="a diagnosis, or a difference no catalogued mistake explains")

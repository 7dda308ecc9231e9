"""The ``a5`` and ``a5mi`` commands (SPEC B.1): flags -> scene -> render -> images. The only module that prints.

``a5`` takes the assignment's arguments, in any order (SPEC B.1)::

    a5 -input F.txt -size W H -output IMG [-shadows] [-bounces N] [-jitter|-jittered] [-filter]
       [-normals IMG] [-depth DMIN DMAX IMG] [-reflection_off] [-refraction_off]

plus the extras ``-seed N``, ``-variant llvm|cuda|auto``, ``-threads N``, ``-phong``,
``-fresnel a5|schlick|exact``, ``-kernel binary|handout``, ``-normals_mode main|quadrant``, ``-v``,
``--debug``, ``-h``. A flag given twice keeps its last value, as the binary's loop does. ``a5mi`` is the
toolbox: ``a5mi render <a5 flags>``,
``a5mi convert SCENE.txt -o OUT.xml [--stock]``; further sub-commands are one line in :data:`SUBCOMMANDS`.

Errors (issue 8): a user error prints one line on stderr, ``FILE:LINE:COL: error: ...`` for the scene or
``a5: error: ...`` otherwise, and returns 2; anything else is a bug and returns 1 with a hint to re-run with
``--debug``, which prints tracebacks. Outputs are checked (extension, folder) before rendering and written,
each atomically, only after everything has rendered, so a failure never leaves or clobbers a file.
Mitsuba is imported only after the flags and the scene have been parsed.
"""

from __future__ import annotations

import importlib
import os
import re
import sys
import time
import traceback
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, TextIO

from a5mi.errors import UsageError, UserError

PROG = "a5"
MAX_SIZE = 16384  # per side
MAX_SAMPLES = 1 << 28  # render-buffer samples (3W x 3H with -jitter): 3 GB of float32 colour

A5_USAGE = """\
usage: a5 -input SCENE.txt -output IMG [-size W H] [-shadows] [-bounces N] [-jitter] [-filter]
          [-normals IMG] [-depth DMIN DMAX IMG] [-reflection_off] [-refraction_off]
          [-seed N] [-variant llvm|cuda|auto] [-threads N] [-phong] [-fresnel a5|schlick|exact]
          [-kernel binary|handout] [-normals_mode main|quadrant] [-v] [--debug] [-h]

Render a 6.837 assignment-5 scene as the course's sample solution a5soln does.

assignment flags (SPEC B.1; any order):
  -input SCENE.txt       scene file (relative paths: the scene's folder first, then the working directory)
  -output IMG            image to write: .png .bmp .tga .ppm .tif .tiff (8-bit) or .exr (float)
  -size W H              image size (default 100 100); non-square sizes work
  -shadows               cast shadow rays
  -bounces N             reflection/refraction depth (default 4; 0: ambient + diffuse only)
  -jitter, -jittered     3W x 3H samples with glibc rand() offsets (alone: saves the 3W x 3H image)
  -filter                blur + 3x3 downsample (with -jitter: W x H; alone: W/3 x H/3, as a5soln)
  -normals IMG           also write |N| of the first hit (render resolution, unfiltered)
  -depth DMIN DMAX IMG   also write the depth image (1 at DMIN, 0 at DMAX)
  -reflection_off        no mirror rays
  -refraction_off        no refracted rays

extras:
  -seed N                jitter from numpy's PCG64 with seed N instead of glibc rand() (seed 1)
  -variant V             llvm (default), cuda or auto
  -threads N             Dr.Jit worker threads
  -phong                 add the handout's Phong highlight (a5soln has none)
  -fresnel MODE          a5 (the binary's R0, default), schlick or exact
  -kernel K              blur kernel: binary (centre tap 0.2921, default) or handout (0.2931, a typo)
  -normals_mode M        main (default: -normals/-depth use the image's rays) or quadrant (a5soln's
                         top-right-quadrant rays, SPEC B.6)
  -v                     print stage timings, ray counts and peak memory on stderr
  --debug                show tracebacks
  -h, -help, --help      show this help
"""

A5MI_USAGE = """\
usage: a5mi COMMAND [ARGS]

commands:
{commands}
run 'a5mi COMMAND -h' for a command's flags.
"""


# --------------------------------------------------------------------------------------------------------
# Output
# --------------------------------------------------------------------------------------------------------


def print_error(msg: str, stream: TextIO | None = None) -> None:
    """Print one user-facing error line; ``msg`` is either ``FILE:LINE:COL: error: ...`` or a bare message
    that gets the ``a5: error:`` prefix."""
    assert not msg.startswith("error:"), "callers pass the message without the 'error:' prefix"
    line = msg if ": error: " in msg else f"{PROG}: error: {msg}"
    print(line.splitlines()[0] if line else line, file=stream or sys.stderr)


def _note(msg: str) -> None:
    print(msg, file=sys.stderr)


class _ProgressBar:
    """A one-line bar on stderr, shown once a render has taken more than ``delay`` seconds."""

    def __init__(self, enabled: bool, delay: float = 2.0, width: int = 30) -> None:
        self.enabled, self.delay, self.width = enabled, delay, width
        self.start = time.perf_counter()
        self.shown = False

    def __call__(self, done: int, total: int) -> None:
        elapsed = time.perf_counter() - self.start
        if not self.enabled or (elapsed < self.delay and done < total) or (not self.shown and done >= total):
            return
        frac = done / total if total else 1.0
        fill = int(frac * self.width)
        eta = elapsed / frac - elapsed if frac > 0 else 0.0
        sys.stderr.write(f"\r[{'#' * fill}{'.' * (self.width - fill)}] {frac:4.0%}  {elapsed:6.1f} s  eta {eta:5.1f} s")
        sys.stderr.flush()
        self.shown = True
        if done >= total:
            sys.stderr.write("\n")


# --------------------------------------------------------------------------------------------------------
# Argument parsing (single-dash long flags in any order: hand-written)
# --------------------------------------------------------------------------------------------------------


@dataclass
class A5Args:
    """The parsed ``a5`` command line."""

    input: str | None = None
    output: str | None = None
    width: int = 100
    height: int = 100
    bounces: int = 4
    shadows: bool = False
    jitter: bool = False
    filter: bool = False
    normals: str | None = None
    depth: tuple[float, float, str] | None = None
    reflection: bool = True
    refraction: bool = True
    seed: int | None = None
    variant: str | None = None
    threads: int | None = None
    phong: bool = False
    fresnel: str = "a5"
    kernel: str = "binary"
    normals_mode: str = "main"
    verbose: bool = False
    debug: bool = False
    help: bool = False
    seen: list[str] = field(default_factory=list)


def _int(flag: str, text: str, lo: int, hi: int) -> int:
    try:
        value = int(text)
    except ValueError:
        raise UsageError(f"{flag} expects an integer, found '{text}'") from None
    if not lo <= value <= hi:
        raise UsageError(f"{flag} expects an integer in [{lo}, {hi}], found {value}")
    return value


def _float(flag: str, text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise UsageError(f"{flag} expects a number, found '{text}'") from None
    if value != value or value in (float("inf"), float("-inf")):
        raise UsageError(f"{flag} expects a finite number, found '{text}'")
    return value


def _choice(flag: str, text: str, choices: Sequence[str]) -> str:
    if text not in choices:
        raise UsageError(f"{flag} expects one of {', '.join(choices)}, found '{text}'")
    return text


def _set(field_name: str, value: object) -> Callable[[A5Args, list[str]], None]:
    def apply(a: A5Args, _vals: list[str]) -> None:
        setattr(a, field_name, value)

    return apply


def _size(a: A5Args, v: list[str]) -> None:
    a.width, a.height = _int("-size", v[0], 1, MAX_SIZE), _int("-size", v[1], 1, MAX_SIZE)


def _depth(a: A5Args, v: list[str]) -> None:
    a.depth = (_float("-depth", v[0]), _float("-depth", v[1]), v[2])


# flag -> (number of values, action)
_A5_FLAGS: dict[str, tuple[int, Callable[[A5Args, list[str]], None]]] = {
    "-input": (1, lambda a, v: setattr(a, "input", v[0])),
    "-output": (1, lambda a, v: setattr(a, "output", v[0])),
    "-size": (2, _size),
    "-shadows": (0, _set("shadows", True)),
    "-bounces": (1, lambda a, v: setattr(a, "bounces", _int("-bounces", v[0], 0, 64))),
    "-jitter": (0, _set("jitter", True)),
    "-jittered": (0, _set("jitter", True)),
    "-filter": (0, _set("filter", True)),
    "-normals": (1, lambda a, v: setattr(a, "normals", v[0])),
    "-depth": (3, _depth),
    "-reflection_off": (0, _set("reflection", False)),
    "-refraction_off": (0, _set("refraction", False)),
    "-seed": (1, lambda a, v: setattr(a, "seed", _int("-seed", v[0], 0, 2**63 - 1))),
    "-variant": (1, lambda a, v: setattr(a, "variant", _choice("-variant", v[0], ("llvm", "cuda", "auto")))),
    "-threads": (1, lambda a, v: setattr(a, "threads", _int("-threads", v[0], 1, 1024))),
    "-phong": (0, _set("phong", True)),
    "-fresnel": (1, lambda a, v: setattr(a, "fresnel", _choice("-fresnel", v[0], ("a5", "schlick", "exact")))),
    "-kernel": (1, lambda a, v: setattr(a, "kernel", _choice("-kernel", v[0], ("binary", "handout")))),
    "-normals_mode": (
        1, lambda a, v: setattr(a, "normals_mode", _choice("-normals_mode", v[0], ("main", "quadrant")))
    ),
    "-v": (0, _set("verbose", True)),
    "--debug": (0, _set("debug", True)),
    "-debug": (0, _set("debug", True)),
    "-h": (0, _set("help", True)),
    "-help": (0, _set("help", True)),
    "--help": (0, _set("help", True)),
}


def parse_a5_args(argv: Sequence[str]) -> A5Args:
    """Parse ``a5`` flags in any order; raise :class:`UsageError` with a one-line message."""
    args = A5Args()
    k = 0
    while k < len(argv):
        flag = argv[k]
        if flag not in _A5_FLAGS:
            if flag.startswith("-"):
                raise UsageError(f"unknown flag '{flag}' (see a5 -h)")
            raise UsageError(f"unexpected argument '{flag}' (flags take the form -input F.txt; see a5 -h)")
        nvals, action = _A5_FLAGS[flag]
        values = list(argv[k + 1 : k + 1 + nvals])
        if len(values) < nvals:
            raise UsageError(f"{flag} expects {nvals} value{'s' if nvals > 1 else ''}, found end of arguments")
        action(args, values)
        args.seen.append(flag)
        k += 1 + nvals
    if args.help:
        return args
    if args.input is None:
        raise UsageError("missing -input SCENE.txt")
    if args.output is None:
        raise UsageError("missing -output IMG")
    samples = args.width * args.height * (9 if args.jitter else 1)
    if samples > MAX_SAMPLES:
        raise UsageError(
            f"-size {args.width} {args.height}{' with -jitter' if args.jitter else ''} is {samples} samples; "
            f"the limit is {MAX_SAMPLES}"
        )
    if args.filter and not args.jitter and (args.width < 3 or args.height < 3):
        raise UsageError(
            f"-filter without -jitter saves a W/3 x H/3 image; -size {args.width} {args.height} is too small"
        )
    return args


# --------------------------------------------------------------------------------------------------------
# a5 / a5mi render
# --------------------------------------------------------------------------------------------------------


def _render_command(args: A5Args) -> int:
    """Check outputs, parse the scene, activate the variant, render, then write every image atomically."""
    from a5mi import imageio

    timings: dict[str, float] = {}
    outputs = [args.output] + ([args.normals] if args.normals else []) + ([args.depth[2]] if args.depth else [])
    for path in outputs:
        assert path is not None
        imageio.check_output_path(path)
    if len(set(map(os.path.abspath, outputs))) != len(outputs):  # type: ignore[arg-type]
        raise UsageError("-output, -normals and -depth must name different files")

    t0 = time.perf_counter()
    from a5mi.converters.a5_parser import parse_file

    assert args.input is not None
    try:
        scene = parse_file(args.input)
    except OSError as exc:
        raise UserError(f"cannot read '{args.input}': {exc.strerror or exc}") from None
    for loc, msg in getattr(scene, "warnings", ()):
        _note(f"{loc}: warning: {msg}")
    desc = _describe(scene, stock=False)
    timings["parse"] = time.perf_counter() - t0

    from a5mi import driver
    from a5mi.variant import VariantError, activate

    t0 = time.perf_counter()
    try:
        variant = activate(args.variant)
    except VariantError as exc:
        raise UserError(str(exc)) from None
    timings["variant"] = time.perf_counter() - t0

    options = driver.RenderOptions(
        width=args.width,
        height=args.height,
        bounces=args.bounces,
        shadows=args.shadows,
        jitter=args.jitter,
        filter=args.filter,
        seed=args.seed,
        phong=args.phong,
        fresnel=args.fresnel,
        reflection=args.reflection,
        refraction=args.refraction,
        kernel=args.kernel,
        normals=args.normals is not None,
        depth=args.depth[:2] if args.depth else None,
        aov_mode=args.normals_mode,
        threads=args.threads,
        count_rays=args.verbose,
    )
    bar = _ProgressBar(enabled=args.verbose or sys.stderr.isatty())
    result = driver.render(desc, options, progress=bar)
    timings.update(result.timings)

    t0 = time.perf_counter()
    writes: list[tuple[str, object]] = [(args.output, result.image)]  # type: ignore[list-item]
    if args.normals:
        writes.append((args.normals, result.normals))
    if args.depth:
        writes.append((args.depth[2], result.depth))
    imageio.write_images(writes)  # type: ignore[arg-type]
    timings["write"] = time.perf_counter() - t0

    if args.verbose:
        import resource

        peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
        rw, rh = result.render_size
        h, w = result.image.shape[:2]
        _note(f"a5: {variant}, render {rw}x{rh} ({result.camera_rays} camera rays, {result.tiles} tiles), "
              f"saved {w}x{h}")
        if result.ray_counts:
            _note("a5: secondary rays " + ", ".join(f"{k} {v}" for k, v in result.ray_counts.items()))
        order = ("parse", "variant", "build", "compile", "execute", "render", "jitter", "filter", "write")
        _note("a5: times " + ", ".join(f"{k} {timings[k]:.3f} s" for k in order if k in timings))
        _note(f"a5: peak memory {peak_mb:.0f} MB")
    return 0


def _describe(scene: object, stock: bool) -> Any:
    """The scene description (every mesh, texture and cube-map face read once, before Mitsuba is imported: a
    bad file is a ``FILE:LINE:COL`` error in a fraction of a second); prints the conversion warnings."""
    from a5mi.converters.describe import describe

    desc = describe(scene, stock=stock)  # type: ignore[arg-type]
    for loc, msg in desc.warnings:
        _note(f"{loc}: warning: {msg}")
    return desc


def _guarded(debug: bool, body: Callable[[], int]) -> int:
    """Run ``body`` with the error policy: user errors -> one line, 2; bugs -> short message, 1."""
    from a5mi.converters.errors import SceneError

    try:
        return body()
    except SceneError as exc:
        if debug:
            traceback.print_exc()
        print_error(str(exc) if exc.loc is not None else exc.msg)
        return 2
    except UserError as exc:
        if debug:
            traceback.print_exc()
        print_error(str(exc))
        return 2
    except KeyboardInterrupt:
        print_error("interrupted")
        return 130
    except Exception as exc:  # noqa: BLE001 - the last line of defence: report a bug, not a traceback
        if debug:
            traceback.print_exc()
        else:
            # First line only, and never the text of a traceback embedded in the message (Mitsuba's
            # load_dict wraps a plugin's Python exception that way).
            detail = _exception_summary(exc)
            _note(f"{PROG}: internal error: {type(exc).__name__}{': ' + detail if detail else ''} "
                  "(re-run with --debug for the traceback)")
        return 1


def _exception_summary(exc: BaseException) -> str:
    """One line for an unexpected exception: its first line, plus the innermost cause when Mitsuba's
    ``load_dict`` has wrapped a plugin's Python exception (with its traceback text) into its message."""
    head, *embedded = str(exc).split("Traceback")
    first = (head.strip().splitlines() or [""])[0]
    if embedded:
        lines = [ln.strip() for ln in embedded[-1].strip().splitlines() if ln.strip()]
        if lines and re.match(r"[A-Za-z_][\w.]*(Error|Exception|Exit|Interrupt)\b", lines[-1]):
            return f"{first} ({lines[-1]})" if first else lines[-1]
    return first


def run(argv: Sequence[str]) -> int:
    """``a5 ARGS``: render a scene (SPEC B.1). Returns the exit status (0, 1 internal error, 2 user error)."""
    debug = "--debug" in argv or "-debug" in argv

    def body() -> int:
        args = parse_a5_args(argv)
        if args.help:
            print(A5_USAGE, end="")
            return 0
        return _render_command(args)

    return _guarded(debug, body)


# --------------------------------------------------------------------------------------------------------
# a5mi sub-commands
# --------------------------------------------------------------------------------------------------------


def _parse_sub(
    argv: Sequence[str], command: str, *, valued: dict[str, str], switches: dict[str, str]
) -> tuple[list[str], dict[str, str | bool]] | None:
    """Flags of an ``a5mi`` sub-command, in any order: ``(positionals, {key: value})``, or None for ``-h``.

    ``valued`` / ``switches`` map each accepted spelling to its key (``{"-o": "out", "--output": "out"}``);
    ``--debug`` is always accepted. Unknown flags and missing values raise :class:`UsageError`.
    """
    positionals: list[str] = []
    found: dict[str, str | bool] = {}
    k = 0
    while k < len(argv):
        a = argv[k]
        if a in ("-h", "--help", "-help"):
            return None
        if a in valued:
            if k + 1 >= len(argv):
                raise UsageError(f"{a} expects a value, found end of arguments")
            found[valued[a]] = argv[k + 1]
            k += 2
            continue
        if a in switches:
            found[switches[a]] = True
        elif a != "--debug":
            if a.startswith("-") and len(a) > 1:
                raise UsageError(f"unknown flag '{a}' (see a5mi {command} -h)")
            positionals.append(a)
        k += 1
    return positionals, found


def run_convert(argv: Sequence[str]) -> int:
    """``a5mi convert SCENE.txt -o OUT.xml [--stock]``: write the scene as Mitsuba XML (+ PLY meshes)."""
    usage = "usage: a5mi convert SCENE.txt -o OUT.xml [--stock] [--debug]\n"
    debug = "--debug" in argv

    def body() -> int:
        parsed = _parse_sub(argv, "convert", valued=dict.fromkeys(("-o", "--output", "-output"), "out"),
                            switches={"--stock": "stock"})
        if parsed is None:
            print(usage, end="")
            return 0
        positionals, opts = parsed
        if len(positionals) > 1:
            raise UsageError(f"unexpected argument '{positionals[1]}' (one scene file per call)")
        if not positionals:
            raise UsageError("convert: missing SCENE.txt")
        scene_path = positionals[0]
        stock = bool(opts.get("stock", False))
        out = opts.get("out")
        if not isinstance(out, str):
            raise UsageError("convert: missing -o OUT.xml")
        if not out.endswith(".xml"):
            raise UsageError(f"convert: the output must end in .xml, found '{out}'")
        folder = os.path.dirname(out) or "."
        if not os.path.isdir(folder):
            raise UsageError(f"{out}: output folder '{folder}' does not exist")
        from a5mi.converters.a5_parser import parse_file

        try:
            scene = parse_file(scene_path)
        except OSError as exc:
            raise UserError(f"cannot read '{scene_path}': {exc.strerror or exc}") from None
        for loc, msg in getattr(scene, "warnings", ()):
            _note(f"{loc}: warning: {msg}")
        desc = _describe(scene, stock=stock)
        from a5mi.variant import VariantError, activate

        try:
            activate(None)  # the XML writer builds meshes (PLY) through Mitsuba
        except VariantError as exc:
            raise UserError(str(exc)) from None
        from a5mi.converters.to_xml import write_xml

        write_xml(desc, out, stock=stock)
        return 0

    return _guarded(debug, body)


def run_compare(argv: Sequence[str]) -> int:
    """``a5mi compare A B [--diff OUT.png] [--json] [--threshold L]``: the metrics of :mod:`a5mi.compare`."""
    usage = "usage: a5mi compare A B [--diff OUT.png] [--json] [--threshold LEVELS] [--debug]\n"
    debug = "--debug" in argv

    def body() -> int:
        from a5mi import compare
        from a5mi.imageio import check_output_path

        parsed = _parse_sub(argv, "compare", valued={"--diff": "diff", "--threshold": "threshold"},
                            switches={"--json": "json"})
        if parsed is None:
            print(usage, end="")
            return 0
        images, opts = parsed
        diff = opts.get("diff")
        diff = diff if isinstance(diff, str) else None
        as_json = bool(opts.get("json", False))
        threshold = _float("--threshold", str(opts["threshold"])) if "threshold" in opts else compare.DEFAULT_THRESHOLD
        if len(images) != 2:
            raise UsageError(f"compare takes two images, found {len(images)}")
        if diff is not None:
            check_output_path(diff)
        a_img, b_img = compare.read_levels(images[0]), compare.read_levels(images[1])
        metrics = compare.compare_arrays(a_img, b_img, threshold)
        if diff is not None:
            compare.write_diff(a_img, b_img, metrics, diff, (os.path.basename(images[0]), os.path.basename(images[1])))
        if as_json:
            print(metrics.to_json())
        else:
            print(f"{images[0]} vs {images[1]} ({metrics.width}x{metrics.height}): {metrics.summary()}")
            if metrics.bbox is not None:
                x0, y0, x1, y1 = metrics.bbox
                print(f"pixels over {metrics.threshold:g}/255 lie in x {x0}..{x1}, y {y0}..{y1} (row 0 = top)")
        return 0

    return _guarded(debug, body)


def run_fidelity(argv: Sequence[str]) -> int:
    """``a5mi fidelity [--diff-dir DIR]``: re-render every reference image and print the README table."""
    usage = "usage: a5mi fidelity [--diff-dir DIR] [--debug]\n"
    debug = "--debug" in argv

    def body() -> int:
        from a5mi import fidelity
        from a5mi.compare import write_diff
        from a5mi.variant import VariantError, activate

        parsed = _parse_sub(argv, "fidelity", valued={"--diff-dir": "diff_dir"}, switches={})
        if parsed is None:
            print(usage, end="")
            return 0
        positionals, opts = parsed
        if positionals:
            raise UsageError(f"unknown argument '{positionals[0]}' (see a5mi fidelity -h)")
        diff_dir = opts.get("diff_dir")
        diff_dir = diff_dir if isinstance(diff_dir, str) else None
        if diff_dir is not None and not os.path.isdir(diff_dir):
            raise UsageError(f"--diff-dir: folder '{diff_dir}' does not exist")
        cases = list(fidelity.cases())
        if not cases:
            raise UserError(f"no reference images under {fidelity.data_dir() / 'reference'} (set A5_DATA)")
        try:
            activate(None)
        except VariantError as exc:
            raise UserError(str(exc)) from None
        rows = []
        for case in cases:
            metrics, ours, ref = fidelity.measure(case)
            _note(f"{case}: {metrics.summary()}")
            if diff_dir is not None:
                write_diff(ours, ref, metrics, os.path.join(diff_dir, f"{case}.diff.png"), ("a5mi", "a5soln"))
            rows.append((case, metrics))
        print(fidelity.table(rows))
        return 0

    return _guarded(debug, body)


def run_render(argv: Sequence[str]) -> int:
    """``a5mi render <a5 flags>``: the same as ``a5``."""
    return run(argv)


#: Sub-command -> "module:function" taking ``argv`` and returning an exit status (imported on use).
SUBCOMMANDS: dict[str, tuple[str, str]] = {
    "render": ("a5mi.cli:run_render", "render a scene (the a5 flags)"),
    "convert": ("a5mi.cli:run_convert", "convert a scene to Mitsuba XML"),
    "compare": ("a5mi.cli:run_compare", "PSNR, mean error, share of pixels > 2/255 of two images (+ diff)"),
    "fidelity": ("a5mi.cli:run_fidelity", "re-render the reference images and print the fidelity table"),
    "crosscheck": ("a5mi.crosscheck:run", "a5 Whitted vs Mitsuba's path tracer on the same rays"),
    "bench": ("a5mi.bench:run", "time the stages (cold/warm), optionally against a5soln"),
}


def run_a5mi(argv: Sequence[str]) -> int:
    """``a5mi COMMAND ARGS``: dispatch through :data:`SUBCOMMANDS`."""
    commands = "\n".join(f"  {name:<12}{help_}" for name, (_, help_) in SUBCOMMANDS.items())
    if not argv or argv[0] in ("-h", "--help", "-help", "help"):
        print(A5MI_USAGE.format(commands=commands), end="")
        return 0 if argv else 2
    name, rest = argv[0], argv[1:]
    if name not in SUBCOMMANDS:
        print_error(f"unknown command '{name}' (expected one of {', '.join(SUBCOMMANDS)})")
        return 2
    module, func = SUBCOMMANDS[name][0].split(":")
    return int(getattr(importlib.import_module(module), func)(list(rest)))


def main_a5() -> None:
    """Console script ``a5``."""
    sys.exit(run(sys.argv[1:]))


def main_a5mi() -> None:
    """Console script ``a5mi``."""
    sys.exit(run_a5mi(sys.argv[1:]))


__all__ = ["run", "run_a5mi", "run_convert", "run_render", "parse_a5_args", "main_a5", "main_a5mi"]

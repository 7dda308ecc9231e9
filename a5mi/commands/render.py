"""``a5`` / ``a5mi render``: flags -> scene description -> render -> images (SPEC B.1, B.5, B.6).

The render flags are one table (:data:`RENDER_FLAGS`) used by ``a5`` in the sample solution's strict grammar
and by ``a5mi render`` (and the sub-commands that render) in GNU style. Their dests are the field names of
:class:`a5mi.render.options.RenderOptions`, so :func:`render_options` builds the one options object without copying
fields by hand. Outputs are checked (extension, folder, distinct files) before the scene is parsed and
written, each atomically and all or nothing, only after everything has rendered.
"""

from __future__ import annotations

import dataclasses
import time
from typing import Any

from a5mi.cli.app import Command, Console, activate_variant, load_scene
from a5mi.cli.flags import Args, Flag, Positional, choice, integer, number, real, size_flag, text
from a5mi.commands.render_budget import check_memory, check_work, report_work
from a5mi.platform import clobber
from a5mi.platform.errors import ExitStatus, UsageError
from a5mi.render.options import (
    AOV_MODES,
    INTEGRATORS,
    KERNELS,
    MISTAKES,
    PHOTON_FILTERS,
    QUIRKS,
    SUBSURFACE_METHODS,
    RenderOptions,
)
from a5mi.spec import DEFAULT_BOUNCES, DEFAULT_SIZE, FRESNEL_MODES, MAX_SIZE

#: The largest finite float32 (SPEC B.6's depths are float32).
FLOAT32_MAX = 3.4028234663852886e38


def _depth(flag: str, values: list[str]) -> tuple[tuple[float, float], str]:
    """``-depth DMIN DMAX IMG`` (SPEC B.6): the bounds are compared with float32 depths, so each must be a
    finite float32 (beyond 3.4e38 it is inf there and every pixel is 1, in a5soln too)."""
    bounds = (number(flag, values[0]), number(flag, values[1]))
    for value, raw in zip(bounds, values, strict=False):
        if abs(value) > FLOAT32_MAX:
            raise UsageError(f"{flag} expects depths within float32 (|d| <= 3.4e38, the sample solution's "
                             f"precision), found '{raw}'")
    return bounds, text(flag, values[2:])


def _nonneg(flag: str, value: str) -> float:
    x = number(flag, value)
    if x < 0.0:
        raise UsageError(f"{flag} expects a number >= 0, found {value}")
    return x


def _unit(flag: str, value: str) -> float:
    x = number(flag, value)
    if not 0.0 < x < 1.0:
        raise UsageError(f"{flag} expects a number in (0, 1), found {value}")
    return x


def _mistakes(flag: str, values: list[str]) -> tuple[str, ...]:
    """``-mistake NAME[,NAME]``: names of :data:`a5mi.render.options.MISTAKES` (docs/MISTAKES.md), each once."""
    names = tuple(dict.fromkeys(n.strip() for n in values[0].split(",") if n.strip()))
    unknown = [n for n in names if n not in MISTAKES]
    if not names or unknown:
        raise UsageError(f"{flag} expects names of docs/MISTAKES.md separated by commas, found "
                         f"'{unknown[0] if unknown else values[0]}' (a5mi diagnose --list prints them)")
    return names


#: SPEC B.1 flags, then the extras; dests are RenderOptions fields (plus the output paths).
RENDER_FLAGS: tuple[Flag, ...] = (
    Flag(("-input", "--input"), "input", "scene file (relative paths: its folder first, then the working "
         "directory)", 1, text, metavar="SCENE.txt"),
    Flag(("-output", "--output"), "output", "image to write: .png .bmp .tga .ppm .tif .tiff (8-bit) or .exr",
         1, text, metavar="IMG"),
    size_flag(DEFAULT_SIZE, "image size; non-square sizes work", names=("-size", "--size")),
    Flag(("-shadows", "--shadows"), "shadows", "cast shadow rays", default=False, show_default=False),
    Flag(("-bounces", "--bounces"), "bounces", "reflection/refraction depth (0: ambient + diffuse only)", 1,
         integer(0, 64), DEFAULT_BOUNCES, "N"),
    Flag(("-jitter", "-jittered", "--jitter"), "jitter", "3W x 3H samples with glibc rand() offsets (alone: saves "
         "the 3W x 3H image)", default=False, show_default=False),
    Flag(("-filter", "--filter"), "filter", "blur + 3x3 downsample (with -jitter: W x H; alone: W/3 x H/3)",
         default=False, show_default=False),
    Flag(("-crop", "--crop"), "crop", "render only the saved image's pixels X0 <= x < X1, Y0 <= y < Y1 (row 0 the "
         "top; pbrt's --pixelbounds), bit for bit as in the whole image, and save that region alone (-normals, "
         "-depth: its own samples; docs/USAGE.md \"Crop renders\")", 4,
         integer(0, 3 * MAX_SIZE), metavar="X0 X1 Y0 Y1"),
    Flag(("-normals", "--normals"), "normals_output", "also write |N| of the first hit (render size, unfiltered)",
         1, text, metavar="IMG"),
    Flag(("-depth", "--depth"), ("depth", "depth_output"), "also write the depth image (1 at DMIN, 0 at DMAX)", 3,
         _depth, (None, None), "DMIN DMAX IMG"),
    Flag(("-reflection_off", "--reflection-off"), "reflection", "no mirror rays", const=False, default=True,
         show_default=False),
    Flag(("-refraction_off", "--refraction-off"), "refraction", "no refracted rays", const=False, default=True,
         show_default=False),
    Flag(("-seed", "--seed"), "seed", "jitter from numpy's PCG64 with seed N instead of glibc rand() (seed 1); also "
         "seeds the -spp sampling (default 0)", 1,
         integer(0, 2**63 - 1), metavar="N"),
    Flag(("-spp", "--spp"), "spp", "samples per pixel of area lights, lens and gloss (docs/EXTENSIONS.md E.5)",
         1, integer(1, 65536), 1, "N"),
    Flag(("-integrator", "--integrator"), "integrator", "whitted (the sample solution's, SPEC B.3) or a physically "
         "based mode of docs/EXTENSIONS.md", 1, choice(tuple(INTEGRATORS)), "whitted", "NAME"),
    Flag(("-rr_depth", "--rr-depth"), "rr_depth", "-integrator path: Russian roulette from N scatterings on "
         "(docs/EXTENSIONS.md E.14)", 1, integer(0, 1 << 16), 5, "N"),
    Flag(("-indirect", "--indirect"), "indirect", "whitted: N cosine-weighted rays gather indirect light at each "
         "diffuse hit (docs/EXTENSIONS.md E.15)", 1, integer(0, 4096), 0, "N"),
    Flag(("-two_sided", "--two-sided"), "two_sided", "whitted: the light loop lights both faces of a surface, N "
         "turned toward the ray (the physical reading for -indirect; SPEC B.3 lights the front only; "
         "docs/EXTENSIONS.md E.15)", default=False, show_default=False),
    Flag(("-photons", "--photons"), "photons", "photons emitted for the global map (per pass with ppm; E.16)", 1,
         integer(0, 1 << 26), 100000, "N"),
    Flag(("-caustic_photons", "--caustic-photons"), "caustic_photons", "photons emitted for the caustic map "
         "(E.16)", 1, integer(0, 1 << 26), 100000, "N"),
    Flag(("-photon_depth", "--photon-depth"), "photon_depth", "photon hits before a photon path is cut, 0: no "
         "cut, Russian roulette alone (unbiased; E.16)", 1, integer(0, 1 << 16), 0, "N"),
    Flag(("-k", "--k"), "photon_k", "nearest photons of a photon-map estimate (E.16)", 1, integer(1, 4096), 50, "K"),
    Flag(("-photon_max_radius", "--photon-max-radius"), "photon_max_radius", "largest radius of a k-nearest "
         "photon disc, 0: none (bounds the estimate's leak from a bright neighbour; E.16)", 1,
         lambda f, v: _nonneg(f, v[0]), 0.0, "R"),
    Flag(("-photon_filter", "--photon-filter"), "photon_filter", "photon estimate filter: none, cone or "
         "epanechnikov (E.16)", 1, choice(PHOTON_FILTERS), "none", "F"),
    Flag(("-final_gather", "--final-gather"), "final_gather", "final-gather rays per diffuse point, 0: off (E.16)",
         1, integer(0, 4096), 0, "M"),
    Flag(("-ppm_radius", "--ppm-radius"), "ppm_radius", "first ppm radius, 0: 1/50 of the scene's bounding "
         "sphere (E.17)", 1, lambda f, v: _nonneg(f, v[0]), 0.0, "R"),
    Flag(("-ppm_alpha", "--ppm-alpha"), "ppm_alpha", "ppm radius schedule alpha in (0, 1) (E.17)", 1,
         lambda f, v: _unit(f, v[0]), 2.0 / 3.0, "A"),
    Flag(("-ic_error", "--ic-error"), "ic_error", "-integrator irradiancecache: Ward's error bound a (records serve "
         "where ε < a; docs/EXTENSIONS.md E.23)", 1, real, 0.3, "A"),
    Flag(("-ic_samples", "--ic-samples"), "ic_samples", "-integrator irradiancecache: hemisphere rays per record "
         "(M x N strata, N ≈ πM)", 1, integer(6, 1 << 16), 256, "N"),
    Flag(("-ic_records", "--ic-records"), "ic_records_output", "-integrator irradiancecache: also write a picture "
         "of the cache's records (dots, reach circles)", 1, text, metavar="IMG"),
    Flag(("-variant", "--variant"), "variant", "llvm (default; or $A5MI_VARIANT), cuda or auto", 1,
         choice(("llvm", "cuda", "auto")), metavar="V"),
    Flag(("-threads", "--threads"), "threads", "Dr.Jit worker threads", 1, integer(1, 1024), metavar="N"),
    Flag(("-bump", "--bump"), "bump", "bump and normal maps perturb the shading normal (docs/EXTENSIONS.md E.7; "
         "a5soln ignores 'bump')", default=False, show_default=False),
    Flag(("-media_bounces", "--media-bounces"), "media_bounces", "Fog/Volume: 0 light arrives unattenuated (E.8); "
         "N >= 1 shadow rays carry the medium's transmittance, up to N scatterings (docs/EXTENSIONS.md E.8)", 1,
         integer(0, 64), 0, "N"),
    Flag(("-subsurface", "--subsurface"), "subsurface", "materials' subsurface blocks: none, dipole (Jensen 2001) "
         "or walk (volumetric random walk) (docs/EXTENSIONS.md E.18)", 1, choice(SUBSURFACE_METHODS), "none", "M"),
    Flag(("-phong", "--phong"), "phong", "add the handout's Phong highlight (a5soln has none)", default=False,
         show_default=False),
    Flag(("-fresnel", "--fresnel"), "fresnel", "a5 (the binary's R0), schlick or exact", 1, choice(FRESNEL_MODES),
         "a5", "MODE"),
    Flag(("-kernel", "--kernel"), "kernel", "blur kernel: binary (centre tap 0.2921) or handout (0.2931, a typo)",
         1, choice(KERNELS), "binary", "K"),
    Flag(("-quirks", "--quirks"), "quirks", "none, or binary: a textured sphere or plane in front of a textured mesh "
         "tested before it takes that mesh's uv, as a5soln (docs/FIDELITY.md)", 1, choice(QUIRKS), "none", "Q"),
    Flag(("-normals_mode", "--normals-mode"), "aov_mode", "main (-normals/-depth use the image's rays) or "
         "quadrant (a5soln's top-right-quadrant rays, SPEC B.6)", 1, choice(AOV_MODES), "main", "M"),
    Flag(("-mistake", "--mistake"), "mistakes", "render as a student with these mistakes would (comma-separated "
         "names of docs/MISTAKES.md; a5mi diagnose ranks them)", 1, _mistakes, metavar="NAME[,NAME]"),
    Flag(("-v", "--verbose"), "verbose", "print the work estimate, progress lines, stage timings, ray counts and "
         "peak memory on stderr", default=False, show_default=False),
)


#: ``-force``: the commands that check the work estimate (``a5``, ``a5mi render``, ``a5mi view``) take it.
FORCE_FLAG = Flag(("-force", "--force"), "force", "render even when the work estimate is over an hour (docs/USAGE.md "
                  "\"Work estimate and progress\")", default=False, show_default=False)


def render_options(args: Args, **overrides: Any) -> RenderOptions:
    """The one :class:`RenderOptions` of parsed render flags: every flag whose dest is a field, plus the AOV
    images asked for by ``-normals`` / ``-depth`` and ``count_rays`` = ``-v``; ``overrides`` win."""
    names = {f.name for f in dataclasses.fields(RenderOptions)}
    values = {k: v for k, v in args.items() if k in names and v is not None}
    values["normals"] = args.get("normals_output") is not None
    values["count_rays"] = bool(args.get("verbose"))
    values.update(overrides)
    return RenderOptions(**values)


def check_render_args(args: Args) -> None:
    """Limits that depend on several flags, the same for the command line and the page
    (:mod:`a5mi.render.limits`: the sample budget, ``-indirect``, ``-filter``'s minimum size, the memory), and
    the ``-ic_records`` / ``-ic_error`` rules."""
    from a5mi.render import limits

    if args.get("ic_records_output") and args.get("integrator") != "irradiancecache":
        raise UsageError("-ic_records needs -integrator irradiancecache")
    ic_error = args.get("ic_error")
    if ic_error is not None and not 0.0 < ic_error <= 1.0:
        raise UsageError(f"-ic_error must be in (0, 1], got {ic_error}")
    options = render_options(args, count_rays=False)
    limits.check_combination(options)
    check_memory(args, options)


def outputs_of(args: Args) -> list[tuple[str, str]]:
    """(role, path) of every image the command writes, checked before rendering."""
    from a5mi.platform import imageio

    outs = [("-output", args.output)]
    if args.get("normals_output"):
        outs.append(("-normals", args.normals_output))
    if args.get("depth_output"):
        outs.append(("-depth", args.depth_output))
    if args.get("ic_records_output"):
        outs.append(("-ic_records", args.ic_records_output))
    for _, path in outs:
        imageio.check_output_path(path)
    clobber.check_outputs(outs, [args.input])  # the same file twice, or the scene itself
    return outs


#: docs/EXTENSIONS.md E.24: one render's row bands on Dask workers (a5mi/render/bands.py)
SPLIT_FLAGS: tuple[Flag, ...] = (
    Flag(("-workers", "--workers"), "workers", "split the render into row bands on N local Dask worker processes",
         1, integer(1, 512), metavar="N"),
    Flag(("-scheduler", "--scheduler"), "scheduler", "split the render into row bands on an existing Dask "
         "cluster", 1, text, metavar="tls://HOST:PORT"),
    Flag(("-tls_ca", "--tls-ca"), "tls_ca", "with -scheduler tls://: the CA certificate of the cluster (PEM)", 1,
         text, metavar="CA.pem"),
    Flag(("-tls_cert", "--tls-cert"), "tls_cert", "with -scheduler tls://: this client's certificate (PEM)", 1,
         text, metavar="CERT.pem"),
    Flag(("-tls_key", "--tls-key"), "tls_key", "with -scheduler tls://: this client's private key (PEM)", 1, text,
         metavar="KEY.pem"),
    Flag(("-insecure_scheduler", "--insecure-scheduler"), "insecure_scheduler", "allow a plain tcp:// -scheduler "
         "(anyone who reaches it can run code on its workers)", default=False, show_default=False),
)


def _split(args: Args) -> Any:
    """The render function of ``-workers`` / ``-scheduler`` (:func:`a5mi.render.bands.render_split`), or None."""
    workers, scheduler = args.get("workers"), args.get("scheduler")
    tls = [args.get(d) for d in ("tls_ca", "tls_cert", "tls_key")]
    if (any(tls) or args.get("insecure_scheduler")) and scheduler is None:
        raise UsageError("-tls_ca/-tls_cert/-tls_key/-insecure_scheduler need -scheduler")
    if workers is None and scheduler is None:
        return None
    if workers is not None and scheduler is not None:
        raise UsageError("give -workers or -scheduler, not both")
    if any(tls) and not all(tls):
        raise UsageError("give -tls_ca, -tls_cert and -tls_key together")
    from a5mi.render import bands
    from a5mi.runtime import cluster

    why = bands.splittable(render_options(args))
    if why is not None:
        raise UsageError(f"-workers/-scheduler: {why}")
    security = None if scheduler is None else cluster.check_scheduler(
        scheduler, tuple(tls) if all(tls) else None, bool(args.get("insecure_scheduler")), flag="-scheduler")

    def render(desc: Any, options: RenderOptions, progress: Any = None) -> Any:
        return bands.render_split(args.input, options, workers=workers, scheduler=scheduler, security=security,
                                  variant=args.variant, progress=progress)[0]

    return render


def run_render(args: Args, console: Console, kept: Any = None) -> int:
    """One scene (``a5``, ``a5mi render -input -output``), or the jobs of ``a5mi render`` with several scenes or
    ``--jobs`` (:mod:`a5mi.cli.batch`: one process, one :class:`a5mi.render.session.RenderSession`). ``kept``: the
    images and meshes ``a5mi serve`` keeps from one command to the next (:class:`a5mi.converters.files.KeptFiles`)."""
    from a5mi.cli import batch

    if batch.is_batch(args):
        if args.get("workers") is not None or args.get("scheduler") is not None:
            raise UsageError("-workers/-scheduler split one render; not with scenes as arguments or --jobs")
        return batch.run_batch(batch.make_jobs(args, (*RENDER_FLAGS, FORCE_FLAG), check_render_args), console,
                               render_job)
    from a5mi.render import session

    return _render_and_write(args, console, lambda: activate_variant(args.variant), _split(args) or session.render,
                             lambda: _load(args.input, console, bool(args.get("bump")), kept))


def render_job(args: Args, console: Console, session: Any, scenes: dict[Any, Any]) -> int:
    """One job of a batch: as :func:`run_render` for one scene, through ``session`` (built scenes and
    integrators reused), with the scene's description taken from ``scenes`` when an earlier job loaded it
    (its warnings were printed then). At most :data:`SCENES_KEPT` descriptions are kept."""
    import os

    key = (os.path.abspath(args.input), os.getcwd(), bool(args.get("bump")))

    def load() -> tuple[Any, list[Any]]:
        if key not in scenes:
            scenes[key] = _load(args.input, console, bool(args.get("bump")))
            while len(scenes) > SCENES_KEPT:
                dropped = scenes.pop(next(iter(scenes)))
                session.forget(dropped[0])
        return scenes[key]

    return _render_and_write(args, console, lambda: session.variant, session.render, load)


#: Tiles at most of a render warned for its estimate (each a progress step; each launch re-traces the
#: integrator, ~50-90 ms)
PROGRESS_TILES = 16
#: Scene descriptions a batch keeps loaded (parsed, files checked); the session keeps one built scene.
SCENES_KEPT = 4


def _load(path: str, console: Console, bump: bool, kept: Any = None) -> tuple[Any, list[Any]]:
    inputs: list[Any] = []
    return load_scene(path, console, inputs=inputs, bump=bump, kept=kept), inputs


def _render_and_write(args: Args, console: Console, activate: Any, render: Any, load: Any) -> int:
    """Check outputs, load the scene once, activate the variant, render, then write every image atomically."""
    from a5mi.platform import imageio
    from a5mi.render import estimate as est

    outputs = outputs_of(args)
    timings: dict[str, float] = {}
    t0 = time.perf_counter()
    desc, inputs = load()
    clobber.check_outputs(outputs, inputs)  # no output may overwrite a mesh, texture or cube-map face
    timings["parse"] = time.perf_counter() - t0
    # -v times the plain render kernel; the ray counts (a different kernel: three more outputs) come from a
    # second pass afterwards, timed on its own ("counts": not part of the command without -v).
    options = render_options(args, count_rays=False)
    work = check_work(desc, options, console, force=bool(args.get("force")), verbose=bool(args.verbose))
    t0 = time.perf_counter()
    variant = activate()
    timings["variant"] = time.perf_counter() - t0

    interactive = console.err.isatty()  # never a \r bar in a log file
    # progress steps cost a trace each: only when shown; a warned render (over a minute by the estimate) is cut
    # into up to PROGRESS_TILES tiles so that the bar or the -v lines follow it (the image is the same)
    long = work.seconds > est.WARN_SECONDS
    shown = interactive or (bool(args.verbose) and long)
    run = dataclasses.replace(options, tile_rays=est.progress_tile_rays(
        work, options, tile_seconds=1.0, max_tiles=PROGRESS_TILES)) if long else options
    split = args.get("workers") is not None or args.get("scheduler") is not None
    with console.progress(enabled=interactive, log=bool(args.verbose) and not interactive, rays=work.rays,
                          seconds=work.seconds, unit="bands" if split else "samples") as bar:
        result = render(desc, run, progress=bar if shown else None)
    timings.update(result.timings)
    if args.verbose:
        t0 = time.perf_counter()
        # (a crop keeps -filter: its region is in the saved image's pixels, and -filter traces the blur's margin)
        counting = dataclasses.replace(options, count_rays=True, normals=False, depth=None,
                                       filter=options.filter and options.crop is not None)
        result.ray_counts = render(desc, counting).ray_counts
        timings["counts"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    images = {"-output": result.image, "-normals": result.normals, "-depth": result.depth}
    if args.get("ic_records_output"):  # docs/EXTENSIONS.md E.23
        from a5mi.render.ic_records import picture

        images["-ic_records"] = picture(result.image, desc.camera, result.render_size,
                                        result.extras["irradiance_cache"])
    imageio.write_images([(path, images[role]) for role, path in outputs])
    timings["write"] = time.perf_counter() - t0
    if args.verbose:
        _report(console, variant, result, timings)
        report_work(console, work, options, result, timings)
    return ExitStatus.OK


def _report(console: Console, variant: str, result: Any, timings: dict[str, float]) -> None:
    import resource

    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    rw, rh = result.render_size
    h, w = result.image.shape[:2]
    p = console.prog
    console.note(f"{p}: {variant}, render {rw}x{rh} ({result.camera_rays} camera rays, {result.tiles} tiles), "
                 f"saved {w}x{h}")
    if result.ray_counts:
        console.note(f"{p}: secondary rays " + ", ".join(f"{k} {v}" for k, v in result.ray_counts.items()))
    order = ("parse", "variant", "build", "compile", "execute", "render", "jitter", "filter", "write", "counts")
    console.note(f"{p}: times " + ", ".join(f"{k} {timings[k]:.3f} s" for k in order if k in timings))
    console.note(f"{p}: peak memory {peak_mb:.0f} MB")


_SUMMARY = "Render a 6.837 assignment-5 scene as the course's sample solution a5soln does (SPEC B.1)."

#: ``a5``: the sample solution's command line, strict single-dash grammar.
A5 = Command("a5", _SUMMARY, (*RENDER_FLAGS, FORCE_FLAG, *SPLIT_FLAGS), run_render, grammar="a5",
             required=("input", "output"),
             check=check_render_args, epilog="Flags in any order; a flag given twice keeps its last value.",
             exit_ok="every image written")

#: Render flags that name an image to write, say how its AOV rays are cast or which of its pixels it holds
#: (``-crop``): not offered by the commands that write no a5 image (trace) or write their own (animate, view).
IMAGE_OUTPUT_DESTS = frozenset({"output", "normals_output", "depth", "depth_output", "aov_mode",
                                "ic_records_output", "crop"})


def render_flags_except(dests: frozenset[str] | set[str]) -> tuple[Flag, ...]:
    """:data:`RENDER_FLAGS` without the flags that set any of ``dests``."""
    return tuple(f for f in RENDER_FLAGS if not set(f.dests) & dests)


def check_render_command(args: Args) -> None:
    """``a5mi render``: one scene needs ``-input`` and ``-output`` and the a5 checks; a batch's jobs are
    checked one by one (:func:`a5mi.cli.batch.make_jobs`)."""
    from a5mi.cli import batch

    if batch.is_batch(args):
        return
    for dest, name in (("input", "-input SCENE.txt"), ("output", "-output IMG")):
        if args.get(dest) is None:
            raise UsageError(f"missing {name}")
    check_render_args(args)


def _render_command() -> Command:
    from a5mi.cli.batch import BATCH_FLAGS, EPILOG, EXIT_NOTE

    return Command("render", "render a scene, or several in one process (the a5 flags; see 'a5 -h')",
                   (*RENDER_FLAGS, FORCE_FLAG, *SPLIT_FLAGS, *BATCH_FLAGS), run_render,
                   (Positional("scenes", "SCENE.txt", "scenes to render with the same flags (with --output-dir)",
                               "*"),),
                   epilog=A5.epilog + " " + EPILOG, check=check_render_command, exit_ok="every image written",
                   exit_note=EXIT_NOTE)


#: ``a5mi render``: the same flags, GNU style (the a5 spellings are aliases), plus batches (a5mi.cli.batch).
RENDER = _render_command()

"""``a5mi render-xml SCENE.xml -o IMG [-D NAME=VALUE ...] [--spp N]`` (also ``python -m a5mi.mitsuba``): render
any Mitsuba 3 XML scene with the a5mi plugins registered.

The ``mitsuba`` executable cannot load Python plugins (``Plugin "a5_whitted" not found``); this command
activates the variant, registers the plugins (:func:`a5mi.plugins.register_all`), loads the file with
``mi.load_file(path, parallel=False, **defaults)`` (:func:`a5mi.platform.loading.load_file`: on one thread) and
renders it with ``mi.render``. The image is written linear, as the a5 images are (8-bit:
``byte = clamp(int(c·255))``, SPEC B.1; ``.exr``: float), never sRGB-encoded; the AOV channels an integrator
adds are dropped.

Before Mitsuba reads the file, every ``<string name="filename" value="..."/>`` (``$NAME`` replaced by the
``-D`` values and the file's ``<default>`` values) must name a regular file or a folder (a cube map), beside
the XML or in the working directory (Mitsuba's file resolver), and every image among them (a folder's images
included) must fit in memory by its header
(:func:`a5mi.platform.imageio.check_image_fits`); the film's ``W·H·spp`` rays must fit too
(:func:`a5mi.platform.resources.render_bytes` with the whole image as one wavefront). Each is one line,
``SCENE.xml:LINE:COL: error: ...``, exit 2; Mitsuba's own errors are shortened to the same form (its
``[parser.cpp]`` tag and a plugin's Python traceback dropped, the exception's last line kept).
"""

from __future__ import annotations

import os
import re
from pathlib import Path

from a5mi.cli.app import Command, Console, activate_variant
from a5mi.cli.flags import Args, Flag, Positional, choice, integer, text
from a5mi.platform.errors import ExitStatus, UsageError, UserError
from a5mi.platform.loading import load_file


def _define(flag: str, values: list[str]) -> tuple[str, str]:
    name, eq, value = values[0].partition("=")
    if not eq or not name.isidentifier():
        raise UsageError(f"{flag} expects NAME=VALUE, found '{values[0][:40]}'")
    return name, value


FLAGS: tuple[Flag, ...] = (
    Flag(("-o", "--output", "-output"), "output", "image to write: .png .bmp .tga .ppm .tif .tiff (8-bit) or .exr",
         1, text, metavar="IMG"),
    Flag(("-D", "--define"), "define", "set an XML <default> parameter (repeatable, as mitsuba -D)", 1, _define,
         metavar="NAME=VALUE", append=True),
    Flag(("--spp",), "spp", "samples per pixel (default: the scene's sampler)", 1, integer(1, 1 << 20), metavar="N"),
    Flag(("--variant", "-variant"), "variant", "llvm (default; or $A5MI_VARIANT), cuda or auto", 1,
         choice(("llvm", "cuda", "auto")), metavar="V"),
)


#: Extensions of the files Mitsuba decodes as images (Mitsuba's ``bitmap``, the a5mi ``a5_bitmap``).
_IMAGE_SUFFIXES = frozenset({".bmp", ".png", ".jpg", ".jpeg", ".tga", ".ppm", ".pfm", ".tif", ".tiff", ".exr", ".hdr",
                             ".rgbe"})
#: Bytes per sample of Mitsuba's float32 copy of a decoded bitmap (and its colour-space conversion).
_BITMAP_COPY_BYTES = 8


def referenced_files(scene: str, defines: dict[str, str]) -> list[tuple[str, int, int]]:
    """(value, line, column) of every ``<string name="filename">`` of the XML ``scene``, ``$NAME`` substituted
    by ``defines`` (``-D``) and the file's ``<default>`` elements, as Mitsuba does. A file that is not
    well-formed XML gives [] (Mitsuba reports it with its position)."""
    import xml.parsers.expat

    from a5mi.platform.errors import FileReadError
    from a5mi.platform.paths import read_regular

    defaults: dict[str, str] = {}
    found: list[tuple[str, int, int]] = []
    parser = xml.parsers.expat.ParserCreate()

    def start(tag: str, attrs: dict[str, str]) -> None:
        if tag == "default" and "name" in attrs:
            defaults.setdefault(attrs["name"], attrs.get("value", ""))
        elif tag == "string" and attrs.get("name") == "filename" and "value" in attrs:
            found.append((attrs["value"], parser.CurrentLineNumber, parser.CurrentColumnNumber + 1))

    parser.StartElementHandler = start
    try:
        parser.Parse(read_regular(scene, 1 << 28, "scene"), True)  # never open a FIFO or a device
    except FileReadError as exc:
        raise UserError(str(exc)) from None
    except (xml.parsers.expat.ExpatError, ValueError):
        return []
    values = {**defaults, **defines}

    def substitute(text: str) -> str:
        return re.sub(r"\$([A-Za-z_]\w*)", lambda m: values.get(m.group(1), m.group(0)), text)

    return [(substitute(v), line, col) for v, line, col in found]


def check_files(scene: str, defines: dict[str, str]) -> list[Path]:
    """Every file the XML names exists as a regular file (a FIFO or a device would block ``mi.load_file``) or a
    folder, and every image fits in memory (module docstring); raises :class:`UserError` with the XML position.
    Returns the files and folders found, as resolved (the inputs an output must not replace)."""
    from a5mi.platform import imageio, paths
    from a5mi.platform.errors import ImageReadError

    base = Path(scene).parent
    found: list[Path] = []
    for value, line, col in referenced_files(scene, defines):
        where = f"{scene}:{line}:{col}: error:"
        candidates = [Path(value)] if os.path.isabs(value) else [base / value, Path(value)]
        path = next((c for c in candidates if c.exists()), None)
        if path is None:
            looked = "" if os.path.isabs(value) else f" (looked beside the XML in '{base}' and in the working " \
                                                     "directory)"
            raise UserError(f"{where} file '{value[:200]}' not found{looked}")
        if path.is_dir():  # a cube-map folder (a5_cubemap): its face images
            images = sorted(f for f in path.iterdir() if f.suffix.lower() in _IMAGE_SUFFIXES and f.is_file())
        elif path.is_file():
            images = [path] if path.suffix.lower() in _IMAGE_SUFFIXES else []
        else:
            raise UserError(f"{where} '{value[:200]}' is not a regular file ({paths.file_kind(path)})")
        found.append(path)
        for image in images[:64]:
            try:
                imageio.check_image_fits(image, _BITMAP_COPY_BYTES)
            except ImageReadError as exc:
                shown = value if image == path else f"{value}/{image.name}"
                raise UserError(f"{where} image '{shown[:200]}': {exc.reason}") from None
    return found


def mitsuba_error(scene: str, exc: BaseException) -> str:
    """Mitsuba's load error as one line: ``SCENE:LINE:COL: error: what (the plugin's exception)``."""
    from a5mi.cli.app import exception_summary

    text = exception_summary(exc)
    text = re.sub(r"\[[A-Za-z][\w.]*(?::\d+)?\]\s*", "", text)  # [parser.cpp:1718], [PluginManager]
    text = re.sub(r":\s*\((\w+(?:Error|Exception): .*)\)$", r": \1", text)  # the plugin's exception
    m = re.match(r"At (.+?) \(line (\d+), col (\d+)\):\s*(.*)", text)
    if m:
        return f"{m.group(1)}:{m.group(2)}:{m.group(3)}: error: {m.group(4)}"[:400]
    return f"{scene}: {text}"[:400]


def check_film(scene: object, spp: int) -> None:
    """The render's rays fit in memory: the film's W x H at ``spp`` samples (0: the sampler's) as one
    wavefront, ``resources.render_bytes`` (module docstring); raises :class:`UserError`."""
    from a5mi.platform import resources

    sensors = scene.sensors()  # type: ignore[attr-defined]
    if not sensors:
        return
    w, h = (int(x) for x in sensors[0].film().crop_size())
    n = spp or int(sensors[0].sampler().sample_count())
    need = resources.render_bytes(w, h * n, width=w, height=h, aovs=False, jitter=False, filtered=False,
                                  tile_rays=w * h * n)
    enough, have = resources.fits(need)
    if not enough:
        raise UserError(f"a {w}x{h} film at {n} samples per pixel needs about {resources.gb(need)} of memory; "
                        f"{resources.gb(have or 0)} is available")


def run_render_xml(args: Args, console: Console) -> int:
    from a5mi.platform import clobber, imageio

    imageio.check_output_path(args.output)
    if not os.path.isfile(args.scene):
        raise UserError(f"cannot read '{args.scene}': no such file")
    defines = dict(args.define or ())
    named = check_files(args.scene, defines)
    clobber.check_outputs([("-o", args.output)], [args.scene, *named], of=f" of '{args.scene}'")
    activate_variant(args.variant)
    import mitsuba as mi
    import numpy as np

    try:
        scene = load_file(args.scene, **defines)
    except RuntimeError as exc:  # Mitsuba's XML errors: one line, with its own position in the file
        raise UserError(mitsuba_error(args.scene, exc)) from None
    check_film(scene, args.spp or 0)
    image = mi.render(scene, spp=args.spp or 0)
    pixels = np.asarray(image, dtype=np.float32)
    if pixels.ndim == 3 and pixels.shape[2] > 3:
        pixels = pixels[:, :, :3]  # RGB; an integrator's AOV channels follow
    imageio.write_image(args.output, pixels)
    return ExitStatus.OK


RENDER_XML = Command("render-xml", "Render any Mitsuba 3 XML scene with the a5mi plugins registered (linear output).",
                     FLAGS, run_render_xml, (Positional("scene", "SCENE.xml", "the Mitsuba XML file"),),
                     required=("output",), exit_ok="the image written")

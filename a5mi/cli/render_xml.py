"""``a5mi render-xml SCENE.xml -o IMG [-D NAME=VALUE ...] [--spp N]`` (also ``python -m a5mi.mitsuba``): render
any Mitsuba 3 XML scene with the a5mi plugins registered.

The ``mitsuba`` executable cannot load Python plugins (``Plugin "a5_whitted" not found``); this command
activates the variant, registers the plugins (:func:`a5mi.plugins.register_all`), loads the file with
``mi.load_file(path, **defaults)`` and renders it with ``mi.render``. The image is written linear, as the a5
images are (8-bit: ``byte = clamp(int(c·255))``, SPEC B.1; ``.exr``: float), never sRGB-encoded; the AOV
channels an integrator adds are dropped.
"""

from __future__ import annotations

import os

from a5mi.cli.app import Command, Console, activate_variant
from a5mi.cli.flags import Args, Flag, Positional, choice, integer, text
from a5mi.errors import ExitStatus, UsageError, UserError


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


def referenced_files(scene: str, defines: dict[str, str]) -> list[str]:
    """The files an XML scene names (every ``filename`` attribute or ``<string name="filename">`` value, its
    ``$NAME`` parameters replaced by ``-D`` values, else the file's ``<default>`` ones), each resolved as
    Mitsuba does: beside the XML first, then the working directory. Raises :class:`UserError` when one exists but
    is not a regular file or folder (a FIFO or device would block ``mi.load_file``; read only regular files,
    as :func:`a5mi.imageio.read_regular`), or when the XML cannot be read."""
    import re
    import xml.etree.ElementTree as ET

    from a5mi.errors import FileReadError
    from a5mi.imageio import file_kind, read_regular

    try:
        root = ET.fromstring(read_regular(scene, 1 << 28, "scene"))
    except FileReadError as exc:
        raise UserError(str(exc)) from None
    except ET.ParseError:
        return [scene]  # Mitsuba reports the syntax error with its position
    params = {e.get("name", ""): e.get("value", "") for e in root.iter("default")}
    params.update(defines)
    names = [e.get("filename") for e in root.iter() if e.get("filename")]
    names += [e.get("value") for e in root.iter("string") if e.get("name") == "filename" and e.get("value")]
    base = os.path.dirname(os.path.abspath(scene))
    found = [scene]
    for name in names:
        name = re.sub(r"\$(\w+)", lambda m: params.get(m.group(1), m.group(0)), str(name))
        for path in (os.path.join(base, name), os.path.abspath(name)):
            if os.path.lexists(path):
                if file_kind(path) not in ("regular file", "folder"):
                    raise UserError(f"{scene}: '{name}' is not a regular file ({file_kind(path)})")
                found.append(path)
                break
    return found


def run_render_xml(args: Args, console: Console) -> int:
    from a5mi import clobber, imageio

    imageio.check_output_path(args.output)
    if not os.path.isfile(args.scene):
        raise UserError(f"cannot read '{args.scene}': no such file")
    clobber.check_outputs([("-o", args.output)], referenced_files(args.scene, dict(args.define or ())),
                          of=f" of '{args.scene}'")
    activate_variant(args.variant)
    import mitsuba as mi
    import numpy as np

    try:
        scene = mi.load_file(args.scene, **dict(args.define))
    except RuntimeError as exc:  # Mitsuba's XML errors: one line, with its own position in the file
        raise UserError(f"{args.scene}: {' '.join(str(exc).split())[:300]}") from None
    image = mi.render(scene, spp=args.spp or 0)
    pixels = np.asarray(image, dtype=np.float32)
    if pixels.ndim == 3 and pixels.shape[2] > 3:
        pixels = pixels[:, :, :3]  # RGB; an integrator's AOV channels follow
    imageio.write_image(args.output, pixels)
    return ExitStatus.OK


RENDER_XML = Command("render-xml", "Render any Mitsuba 3 XML scene with the a5mi plugins registered (linear output).",
                     FLAGS, run_render_xml, (Positional("scene", "SCENE.xml", "the Mitsuba XML file"),),
                     required=("output",), exit_ok="the image written")

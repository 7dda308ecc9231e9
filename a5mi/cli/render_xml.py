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


def run_render_xml(args: Args, console: Console) -> int:
    from a5mi import imageio

    imageio.check_output_path(args.output)
    if not os.path.isfile(args.scene):
        raise UserError(f"cannot read '{args.scene}': no such file")
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

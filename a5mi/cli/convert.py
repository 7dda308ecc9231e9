"""``a5mi convert SCENE.txt -o OUT.xml [--stock] [render flags]``: the scene as Mitsuba XML (+ PLY meshes).

The XML is written from the same scene description the renderer uses (:func:`a5mi.cli.app.load_scene`) and
the same :class:`~a5mi.options.RenderOptions` (film size, integrator parameters), by
:func:`a5mi.converters.to_xml.write_xml`.
"""

from __future__ import annotations

import os

from a5mi.cli.app import Command, Console, activate_variant, load_scene
from a5mi.cli.flags import Args, Flag, Positional, text
from a5mi.cli.render import RENDER_FLAGS, render_options
from a5mi.errors import UsageError

_SHARED = ("width", "bounces", "shadows", "phong", "fresnel", "reflection", "refraction")
FLAGS: tuple[Flag, ...] = (
    Flag(("-o", "--output", "-output"), "output", "the XML file to write (meshes go to OUT_meshes/ beside it)", 1,
         text, metavar="OUT.xml"),
    Flag(("--stock",), "stock", "stock Mitsuba plugins only (path integrator; approximations are warned)",
         default=False, show_default=False),
    *(f for f in RENDER_FLAGS if f.dests[0] in _SHARED),
)


def run_convert(args: Args, console: Console) -> int:
    if not args.output.endswith(".xml"):
        raise UsageError(f"the output must end in .xml, found '{args.output}'")
    folder = os.path.dirname(args.output) or "."
    if not os.path.isdir(folder):
        raise UsageError(f"{args.output}: output folder '{folder}' does not exist")
    desc = load_scene(args.scene, console, stock=bool(args.stock))
    activate_variant(None)  # the XML writer builds meshes (PLY) through Mitsuba
    from a5mi.converters.to_xml import write_xml

    write_xml(desc, args.output, render_options(args), stock=bool(args.stock))
    return 0


CONVERT = Command("convert", "Write a scene as Mitsuba 3 XML, meshes as PLY beside it.", FLAGS, run_convert,
                  (Positional("scene", "SCENE.txt", "the scene file"),), required=("output",))

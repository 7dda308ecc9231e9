"""``a5mi convert SCENE.txt -o OUT.xml [--stock] [render flags]``: the scene as Mitsuba XML (+ PLY meshes, PNG
textures and cube-map faces beside it, named relative to the XML: the folder can be moved).

The XML is written from the same scene description the renderer uses (:func:`a5mi.cli.app.load_scene`) and
the same :class:`~a5mi.render.options.RenderOptions` (film size, integrator parameters), by
:func:`a5mi.converters.to_xml.write_xml`, which stages the whole set and moves it into place (nothing is
written through a symlink; a second conversion replaces the first exactly). Outputs are checked before the
scene is read (:func:`check_convert_outputs`) and against its input files after (:mod:`a5mi.platform.clobber`).
"""

from __future__ import annotations

import os
from typing import Any

from a5mi.cli.app import Command, Console, activate_variant, load_scene
from a5mi.cli.flags import Args, Flag, Positional, integer, text
from a5mi.commands.render import RENDER_FLAGS, render_options
from a5mi.platform import clobber
from a5mi.platform.errors import ExitStatus, UsageError

_SHARED = ("width", "bounces", "shadows", "phong", "fresnel", "reflection", "refraction", "bump", "media_bounces",
           "subsurface")
FLAGS: tuple[Flag, ...] = (
    Flag(("-o", "--output", "-output"), "output", "the XML file to write (meshes go to OUT_meshes/, images to "
         "OUT_images/ beside it)", 1, text, metavar="OUT.xml"),
    Flag(("--stock",), "stock", "stock Mitsuba plugins only (path integrator; approximations are warned)",
         default=False, show_default=False),
    Flag(("--spp",), "spp", "the sampler's samples per pixel, the XML default $spp (mitsuba -Dspp=N overrides it)",
         1, integer(1, 1 << 20), metavar="N"),
    *(f for f in RENDER_FLAGS if f.dests[0] in _SHARED),
    Flag(("-jitter", "-jittered", "--jitter"), "jitter", "refused: not part of a Mitsuba scene (see -filter)",
         default=False, show_default=False),
    Flag(("-filter", "--filter"), "filter", "refused: SPEC B.5's glibc jitter and blur are steps of a5's driver; "
         "the XML's sampler takes pixel centres, the image of a5 without -jitter/-filter", default=False,
         show_default=False),
)

#: Why ``convert`` refuses ``-jitter`` and ``-filter`` (docs/USAGE.md "a5mi compare and a5mi convert").
NO_SUPERSAMPLING = ("-jitter and -filter are not part of a Mitsuba scene: SPEC B.5's glibc jitter and the binary's "
                    "blur and downsample are steps of a5's own driver; the XML renders one ray through each pixel "
                    "centre, the image of the same a5 command without them (docs/USAGE.md, 'a5mi compare and "
                    "a5mi convert')")


def check_convert_outputs(xml: str) -> tuple[str, str, str, str]:
    """Before the scene is read: the XML's folder exists and is writable, the XML is not a folder or special
    file, ``{stem}_meshes`` and ``{stem}_images`` are not files and ``{stem}_envmap.exr`` not a folder (a symlink
    there is replaced, never followed). Returns the paths of the XML, the meshes folder, the envmap and the
    images folder."""
    from a5mi.platform.paths import check_target, file_kind

    if not xml.endswith(".xml"):
        raise UsageError(f"the output must end in .xml, found '{xml}'")
    folder = os.path.dirname(xml) or "."
    if not os.path.isdir(folder):
        what = "is not a folder" if os.path.exists(folder) else "does not exist"
        raise UsageError(f"{xml}: output folder '{folder}' {what}")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise UsageError(f"{xml}: output folder '{folder}' is not writable")
    stem = os.path.splitext(os.path.basename(xml))[0]
    meshes, envmap = os.path.join(folder, f"{stem}_meshes"), os.path.join(folder, f"{stem}_envmap.exr")
    images = os.path.join(folder, f"{stem}_images")
    for path, want in ((xml, "regular file"), (meshes, "folder"), (envmap, "regular file"), (images, "folder")):
        if os.path.exists(path) and not os.path.islink(path) and file_kind(path) != want:
            raise UsageError(f"{path}: exists and is a {file_kind(path)}, not a {want}: remove or rename it")
    from a5mi.converters.to_xml import check_replaceable

    for path in (meshes, images):  # a folder the user made is never replaced
        check_replaceable(path)
    check_target(xml)
    return xml, meshes, envmap, images


def run_convert(args: Args, console: Console) -> int:
    if args.jitter or args.filter:
        raise UsageError(NO_SUPERSAMPLING)
    xml, meshes, envmap, images = check_convert_outputs(args.output)
    inputs: list[Any] = []
    desc = load_scene(args.scene, console, stock=bool(args.stock), inputs=inputs, bump=bool(args.get("bump")))
    clobber.check_outputs([("-o", xml), ("the envmap", envmap)], inputs)
    clobber.check_folder_holds_no_input("the meshes folder", meshes, inputs)
    clobber.check_folder_holds_no_input("the images folder", images, inputs)
    activate_variant(None)  # the XML writer builds meshes (PLY) through Mitsuba
    from a5mi.converters.to_xml import write_xml

    write_xml(desc, xml, render_options(args), stock=bool(args.stock), spp=args.spp)
    return ExitStatus.OK


CONVERT = Command("convert", "Write a scene as Mitsuba 3 XML, meshes (PLY) and images (PNG) beside it, by "
                  "relative path (the folder can be moved).", FLAGS, run_convert,
                  (Positional("scene", "SCENE.txt", "the scene file"),), required=("output",),
                  exit_ok="the XML and its files written")

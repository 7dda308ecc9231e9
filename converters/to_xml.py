"""Scene description -> Mitsuba 3 XML, meshes beside it as PLY (the layout of :func:`.to_mitsuba.scene_entries`).

``write_xml(desc, "out/scene.xml")`` writes ``out/scene.xml``, ``out/scene_meshes/mesh_NNN.ply``, the textures
as ``out/scene_images/texture_NNN_{name}.png`` and a cube map's six faces as ``out/scene_images/cubemap/{face}.png``
(and, with ``stock=True``, a cube map as ``out/scene_envmap.exr`` and each procedural solid's baked RGB grid as
``out/scene_images/solid_NNN.vol``, docs/EXTENSIONS.md E.6). The XML loads with ``mi.load_file``: with
``stock=False`` once the a5mi plugins are registered (``a5mi.plugins.register_all()``), with ``stock=True``
in plain Mitsuba (see :mod:`.to_mitsuba` and :mod:`.materials` for every stock approximation). Every file is
named relative to the XML (Mitsuba's file resolver looks beside the XML first; the a5 plugins resolve through
it too), so the folder can be moved or copied elsewhere and renders the same. Images are written from the
pixels :func:`.describe.describe` decoded (8-bit PNG, lossless: the plugin reads back the very bytes of the
original, which is not opened again), so a texture named ``maps/old wood.bmp`` becomes
``scene_images/texture_000_old wood.png``.

Serialisation of the scene entries: a dict with ``type`` becomes an element whose tag is its plugin kind
(``bsdf``, ``shape``, ``emitter``, ...; see :data:`PLUGIN_TAGS`), with ``id`` = its top-level key or
``name`` = its parameter name; ``{'type': 'rgb'}`` -> ``<rgb>``; bool, int, float, str -> ``<boolean>``,
``<integer>``, ``<float>``, ``<string>``; three numbers -> ``<point>`` (or ``<vector>`` for ``direction`` /
``up``); a 4x4 array -> ``<transform><matrix value="16 numbers, row-major"/>``. BSDFs are top-level
elements (``mat_NNN``, ``mat_NNN_nouv`` for a textured material's untextured variant on shapes without uv),
written before the first shape that references them. Flat meshes get ``face_normals=true`` (the PLY has no
normals; without the flag Mitsuba would compute smooth ones).

Writing is all or nothing and never outside the set: the XML, ``{stem}_meshes/``, ``{stem}_images/``
and ``{stem}_envmap.exr`` are written into a fresh hidden staging folder beside the XML
(``.{name}.a5mi-{pid}-...``) and then moved into place entry by entry with ``rename``, which replaces a
symlink already there instead of writing through it; an earlier ``{stem}_meshes/`` or ``{stem}_images/`` is
replaced whole (no stale file stays) only when a conversion made it: each folder a conversion writes holds the
marker file :data:`MARKER`, and a folder without it that is not empty is the user's and is never replaced
(:func:`check_replaceable` raises :class:`~a5mi.platform.errors.UsageError`, before anything is written); and an
earlier ``{stem}_envmap.exr`` that this conversion does not write
is removed. The XML is renamed last. Any failure before the moves leaves every existing file as it was and
removes the staging folder; signals wait for the moves (:func:`a5mi.platform.interrupts.protected`).
"""

from __future__ import annotations

import os
import shutil
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import numpy as np

from a5mi.converters import materials
from a5mi.converters.describe import CubeMapBackground, MeshShape, SceneDescription, VolumeDescription
from a5mi.converters.files import Image
from a5mi.converters.to_mitsuba import Backend, bake_cubemap_envmap, make_mesh, scene_entries
from a5mi.platform import interrupts
from a5mi.platform.paths import remove_stale, temp_prefix
from a5mi.render.options import INTEGRATORS, RenderOptions
from a5mi.spec import CUBE_FACES

PLUGIN_TAGS: dict[str, str] = {
    **dict.fromkeys(("a5_whitted", "path", "direct", "volpath", *INTEGRATORS.values()), "integrator"),
    **dict.fromkeys(("a5_camera", "perspective", "thinlens"), "sensor"),
    "hdrfilm": "film",
    **dict.fromkeys(("stratified", "independent"), "sampler"),
    **dict.fromkeys(("box", "gaussian"), "rfilter"),
    **dict.fromkeys(("directional", "a5_point", "point", "a5_cubemap", "constant", "envmap", "a5_spot", "spot",
                     "a5_area", "area"), "emitter"),
    **dict.fromkeys(("a5_material", "diffuse", "conductor", "dielectric", "blendbsdf", "roughconductor",
                     "roughdielectric", "bumpmap", "normalmap", "a5_milled"), "bsdf"),
    **dict.fromkeys(("a5_marble", "a5_solid", "a5_bitmap", "bitmap", "srgb", "volume", "a5_btf"), "texture"),
    **dict.fromkeys(("sphere", "rectangle", "instance", "shapegroup", "ply"), "shape"),
    **dict.fromkeys(("homogeneous", "heterogeneous"), "medium"),
    **dict.fromkeys(("isotropic", "hg"), "phase"),
    "gridvolume": "volume",
}
VECTOR_NAMES = frozenset(("direction", "up"))


def _num(x: float) -> str:
    return repr(float(x))


class _XmlBackend(Backend):
    """Files instead of objects: BSDFs as top-level entries referenced by id, meshes as PLY files beside the
    XML, textures and cube maps by their paths, the stock envmap as an EXR file."""

    def __init__(self, desc: SceneDescription, xml_path: Path, *, stock: bool) -> None:
        super().__init__(desc, stock=stock)
        self.xml_path = xml_path
        self.mesh_dir = xml_path.parent / set_names(xml_path)[1]
        self.image_dir = xml_path.parent / set_names(xml_path)[3]
        self.textures: dict[Path, str] = {}  # source path -> its copy, relative to the XML

    def _write_png(self, relative: str, image: Image) -> None:
        from a5mi.platform.imageio import write_image

        target = self.xml_path.parent / relative
        target.parent.mkdir(parents=True, exist_ok=True)
        write_image(target, np.ascontiguousarray(image.pixels, dtype=np.uint8))

    def texture(self, image: Image) -> dict[str, Any]:
        """``{'filename': '{stem}_images/texture_NNN_{name}.png'}``: the decoded pixels written as PNG, once
        per source file (the same bytes reach the plugin as from the original; the file is not read again)."""
        if image.path not in self.textures:
            rel = f"{self.image_dir.name}/texture_{len(self.textures):03d}_{image.path.stem}.png"
            self._write_png(rel, image)
            self.textures[image.path] = rel
        return {"filename": self.textures[image.path]}

    def bsdf(self, entries: dict[str, Any], material: int, with_uv: bool) -> Any:
        mat = self.desc.materials[material]
        key = f"mat_{material:03d}" + ("_nouv" if materials.without_texture(mat, with_uv) else "")
        if key not in entries:
            entries[key] = materials.bsdf(mat, with_uv, stock=self.stock, image=self.texture)
            if self.stock:
                entries[key] = self.stock_solids(entries[key], material)
        return {"type": "ref", "id": key}

    def mesh(self, key: str, shape: MeshShape, bsdf: Any) -> Any:
        self.mesh_dir.mkdir(parents=True, exist_ok=True)
        ply = self.mesh_dir / f"{key}.ply"
        make_mesh(key, shape.mesh).write_ply(str(ply))
        out: dict[str, Any] = {"type": "ply", "filename": f"{self.mesh_dir.name}/{ply.name}"}
        if shape.mesh.normals is None:
            out["face_normals"] = True
        out["bsdf"] = bsdf
        return out

    def cubemap(self, bg: CubeMapBackground) -> Any:
        """``{stem}_images/cubemap/{face}.png``, the six decoded faces (SPEC A.4 names), and the folder by
        its path relative to the XML."""
        rel = f"{self.image_dir.name}/cubemap"
        for face, image in zip(CUBE_FACES, bg.faces, strict=True):
            self._write_png(f"{rel}/{face}.png", image)
        return {"type": "a5_cubemap", "filename": rel}

    def envmap(self, bg: CubeMapBackground) -> Any:
        import mitsuba as mi

        exr = self.xml_path.parent / set_names(self.xml_path)[2]
        mi.Bitmap(np.ascontiguousarray(bake_cubemap_envmap(bg), dtype=np.float32)).write(str(exr))
        return {"type": "envmap", "filename": exr.name}

    def grid_source(self, vol: VolumeDescription) -> dict[str, Any]:
        """``{'filename': '{stem}_images/grid_{name}.vol'}``: the decoded grid written back as a Mitsuba ``.vol``
        (E.9; the source file is not read again), relative to the XML like every other file."""
        from a5mi.converters.volgrid import write_vol

        rel = f"{self.image_dir.name}/grid_{vol.path.stem}.vol"
        target = self.xml_path.parent / rel
        target.parent.mkdir(parents=True, exist_ok=True)
        write_vol(target, vol.grid)
        return {"filename": rel}


    def solid_grid(self, grid: np.ndarray, material: int) -> dict[str, Any]:
        """``{'filename': '{stem}_images/solid_NNN.vol'}``: a baked solid's RGB grid (E.6, ``--stock``)."""
        from a5mi.converters.volgrid import write_vol

        rel = f"{self.image_dir.name}/solid_{material:03d}.vol"
        target = self.xml_path.parent / rel
        target.parent.mkdir(parents=True, exist_ok=True)
        write_vol(target, grid)
        return {"filename": rel}


def _element(parent: ET.Element, key: str, value: Any, top: bool) -> None:
    """Append the element for parameter/entry ``key`` = ``value`` to ``parent`` (module docstring)."""
    attr = "id" if top else "name"
    if isinstance(value, bool):
        ET.SubElement(parent, "boolean", name=key, value=str(value).lower())
    elif isinstance(value, int):
        ET.SubElement(parent, "integer", name=key, value=str(value))
    elif isinstance(value, float):
        ET.SubElement(parent, "float", name=key, value=_num(value))
    elif isinstance(value, str):
        ET.SubElement(parent, "string", name=key, value=value)
    elif isinstance(value, np.ndarray):
        t = ET.SubElement(parent, "transform", name=key)
        ET.SubElement(t, "matrix", value=" ".join(_num(x) for x in value.ravel()))
    elif isinstance(value, (list, tuple)) and len(value) == 3:
        tag = "vector" if key in VECTOR_NAMES else "point"
        ET.SubElement(parent, tag, name=key, value=", ".join(_num(x) for x in value))
    elif isinstance(value, dict):
        kind = value["type"]
        if kind == "rgb":
            ET.SubElement(parent, "rgb", name=key, value=", ".join(_num(x) for x in value["value"]))
        elif kind == "ref":
            el = ET.SubElement(parent, "ref", id=value["id"])
            if not top and key != "shapegroup":
                el.set("name", key)
        else:
            el = ET.SubElement(parent, PLUGIN_TAGS[kind], type=kind, **{attr: key})
            for k, v in value.items():
                if k != "type":
                    _element(el, k, v, top=False)
    else:
        raise TypeError(f"cannot write parameter {key!r} of type {type(value).__name__} to XML")


#: XML ``<default>`` parameters (``mitsuba -Dname=value``, ``mi.load_file(path, name=value)``) and where they go:
#: (element tag, its ``type`` or None for any, parameter name).
DEFAULTS: dict[str, tuple[str, str | None, str]] = {
    "spp": ("sampler", None, "sample_count"),
    "width": ("film", None, "width"),
    "height": ("film", None, "height"),
    "max_depth": ("integrator", None, "max_depth"),
}


def parametrise(root: ET.Element, spp: int | None = None) -> None:
    """Turn the sampler's ``sample_count``, the film's ``width``/``height`` and the integrator's ``max_depth``
    into ``<default>`` parameters (``$spp``, ``$width``, ``$height``, ``$max_depth``) whose values are the
    converted ones (``spp`` overrides the sample count), so ``mitsuba -Dspp=256 scene.xml`` works."""
    defaults = []
    for name, (tag, _, param) in DEFAULTS.items():
        for parent in root.iter(tag):
            el = next((e for e in parent if e.get("name") == param), None)
            if el is not None:
                value = str(spp) if name == "spp" and spp is not None else el.get("value", "")
                el.set("value", f"${name}")
                defaults.append(ET.Element("default", name=name, value=value))
                break
    for k, el in enumerate(defaults):
        root.insert(k, el)


def write_xml(desc: SceneDescription, path: str | Path, options: RenderOptions | None = None, *,
              stock: bool = False, spp: int | None = None) -> Path:
    """Write the scene ``desc`` as Mitsuba XML at ``path`` (meshes as PLY beside it); returns the XML path.
    ``options`` (default ``RenderOptions()``): film size and integrator parameters, written as ``<default>``
    parameters (:func:`parametrise`; ``spp``: the sampler's sample count, for ``--stock`` path tracing).
    Every scene error was raised by :func:`.describe.describe` already. Needs an active Mitsuba variant (PLY
    writing; the stock cube-map bake also needs the a5 plugins registered)."""
    xml_path = Path(path)
    options = options if options is not None else RenderOptions()
    folder = xml_path.parent if str(xml_path.parent) else Path(".")
    remove_stale(folder, xml_path.name)
    staging = Path(tempfile.mkdtemp(prefix=temp_prefix(xml_path.name), dir=folder))
    try:
        staged_xml = staging / xml_path.name
        entries = scene_entries(desc, options, _XmlBackend(desc, staged_xml, stock=stock))
        root = ET.Element("scene", version="3.0.0")
        for key, value in entries.items():
            if key != "type":
                _element(root, key, value, top=True)
        parametrise(root, spp)
        ET.indent(root, space="    ")
        with open(staged_xml, "w", encoding="utf-8") as f:
            ET.ElementTree(root).write(f, encoding="unicode", xml_declaration=True)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(staged_xml, 0o666 & ~_umask())
        with interrupts.protected():
            _commit(staging, folder, xml_path)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return xml_path


#: The marker file in every folder a conversion writes (``{stem}_meshes/``, ``{stem}_images/``).
MARKER = ".a5mi-convert"


def check_replaceable(folder: str | os.PathLike[str]) -> None:
    """Raise :class:`~a5mi.platform.errors.UsageError` when ``folder`` is a folder (not a symlink) a conversion did not
    write (no :data:`MARKER`) and holds anything: replacing it would delete the user's files."""
    from a5mi.platform.errors import UsageError

    p = Path(folder)
    if p.is_symlink() or not p.is_dir() or (p / MARKER).is_file():
        return
    try:
        empty = next(os.scandir(p), None) is None
    except OSError:
        empty = False
    if not empty:
        raise UsageError(f"{p}: this folder was not written by a5mi convert (no {MARKER} in it) and a conversion "
                         "would replace it: remove or rename it, or write the XML elsewhere")


def set_names(xml_path: Path) -> tuple[str, str, str, str]:
    """The entries a conversion to ``xml_path`` owns beside it: the XML, ``{stem}_meshes``, ``{stem}_envmap.exr``,
    ``{stem}_images``."""
    return xml_path.name, f"{xml_path.stem}_meshes", f"{xml_path.stem}_envmap.exr", f"{xml_path.stem}_images"


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def _commit(staging: Path, folder: Path, xml_path: Path) -> None:
    """Move the staged set into ``folder`` (module docstring): the meshes folder and the envmap first, each old
    entry moved aside into ``staging`` (so it is removed with it, without following links), the XML last."""
    xml_name, mesh_name, env_name, image_name = set_names(xml_path)
    for name in (mesh_name, image_name):
        check_replaceable(folder / name)
        if (staging / name).is_dir():
            (staging / name / MARKER).write_text("written by a5mi convert: the next conversion replaces this folder\n")
    aside = staging / ".replaced"
    aside.mkdir()
    for name in (mesh_name, env_name, image_name):
        new, old = staging / name, folder / name
        if os.path.lexists(old):
            os.rename(old, aside / name)  # renames the entry itself: a symlink is moved, its target untouched
        if os.path.lexists(new):
            os.rename(new, old)
    os.replace(staging / xml_name, folder / xml_name)

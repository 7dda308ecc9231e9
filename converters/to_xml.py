"""Scene model -> Mitsuba 3 XML, meshes beside it as PLY (the same description as :func:`.to_mitsuba.to_dict`).

``write_xml(scene, "out/scene.xml")`` writes ``out/scene.xml`` and ``out/scene_meshes/mesh_NNN.ply`` (and,
with ``stock=True`` and a cube map, ``out/scene_envmap.exr``). The XML loads with ``mi.load_file``: with
``stock=False`` once the a5mi plugins are registered (``a5mi.plugins.register_all()``), with ``stock=True``
in plain Mitsuba (see :mod:`.to_mitsuba` for every stock approximation). Textures and cube-map folders are
written as absolute paths (the a5 plugins open them directly); PLY and EXR files relative to the XML.

Serialisation of the plain description (:class:`.to_mitsuba.Built`): a dict with ``type`` becomes an element
whose tag is its plugin kind (``bsdf``, ``shape``, ``emitter``, ...; see :data:`PLUGIN_TAGS`), with
``id`` = its top-level key or ``name`` = its parameter name; ``{'type': 'rgb'}`` -> ``<rgb>``; bool, int,
float, str -> ``<boolean>``, ``<integer>``, ``<float>``, ``<string>``; three numbers -> ``<point>`` (or
``<vector>`` for ``direction`` / ``up``); a 4x4 array -> ``<transform><matrix value="16 numbers, row-major"/>``.
Flat meshes get ``face_normals=true`` (the PLY has no normals; without the flag Mitsuba would compute
smooth ones).
"""

from __future__ import annotations

import os
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import numpy as np

from .model import Scene
from .to_mitsuba import MeshData, RenderSettings, bake_cubemap_envmap, build, make_mesh, write_float_image

PLUGIN_TAGS: dict[str, str] = {
    **dict.fromkeys(("a5_whitted", "path", "direct"), "integrator"),
    **dict.fromkeys(("a5_camera", "perspective"), "sensor"),
    "hdrfilm": "film",
    **dict.fromkeys(("stratified", "independent"), "sampler"),
    **dict.fromkeys(("box", "gaussian"), "rfilter"),
    **dict.fromkeys(("directional", "a5_point", "point", "a5_cubemap", "constant", "envmap"), "emitter"),
    **dict.fromkeys(("a5_material", "diffuse", "conductor", "dielectric", "blendbsdf"), "bsdf"),
    **dict.fromkeys(("a5_marble", "a5_bitmap", "bitmap"), "texture"),
    **dict.fromkeys(("sphere", "rectangle", "instance", "shapegroup", "ply", "_mesh"), "shape"),
}
VECTOR_NAMES = frozenset(("direction", "up"))


def _num(x: float) -> str:
    return repr(float(x))


class _Writer:
    def __init__(self, xml_path: Path, settings: RenderSettings | None) -> None:
        self.xml_path = xml_path
        self.mesh_dir = xml_path.parent / f"{xml_path.stem}_meshes"
        self.settings = settings

    def element(self, parent: ET.Element, key: str, value: Any, top: bool) -> None:
        """Append the element for parameter/entry ``key`` = ``value`` to ``parent``."""
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
            elif kind == "_mesh":
                self.mesh(parent, key, value, attr)
            elif "_bake_cubemap" in value:
                exr = self.xml_path.parent / f"{self.xml_path.stem}_envmap.exr"
                write_float_image(bake_cubemap_envmap(value["_bake_cubemap"]), exr)
                el = ET.SubElement(parent, "emitter", type="envmap", **{attr: key})
                ET.SubElement(el, "string", name="filename", value=exr.name)
            else:
                el = ET.SubElement(parent, PLUGIN_TAGS[kind], type=kind, **{attr: key})
                for k, v in value.items():
                    if k != "type":
                        self.element(el, k, v, top=False)
        else:
            raise TypeError(f"cannot write parameter {key!r} of type {type(value).__name__} to XML")

    def mesh(self, parent: ET.Element, key: str, value: dict[str, Any], attr: str) -> None:
        data: MeshData = value["data"]
        self.mesh_dir.mkdir(parents=True, exist_ok=True)
        ply = self.mesh_dir / f"{data.name}.ply"
        make_mesh(data).write_ply(str(ply))
        el = ET.SubElement(parent, "shape", type="ply", **{attr: key})
        ET.SubElement(el, "string", name="filename", value=f"{self.mesh_dir.name}/{ply.name}")
        if data.normals is None:
            ET.SubElement(el, "boolean", name="face_normals", value="true")
        self.element(el, "bsdf", value["bsdf"], top=False)


def write_xml(scene: Scene, path: str | Path, *, stock: bool = False,
              settings: RenderSettings | None = None, normals: str = "auto") -> Path:
    """Write ``scene`` as Mitsuba XML at ``path`` (meshes as PLY beside it); returns the XML path.
    Raises :class:`~a5mi.converters.errors.SceneSemanticError` for missing meshes/textures/cube maps, before
    anything is written. Needs an active Mitsuba variant (PLY writing; the stock cube-map bake also needs
    the a5 plugins registered)."""
    xml_path = Path(path)
    built = build(scene, settings, stock=stock, normals=normals)  # type: ignore[arg-type]
    writer = _Writer(xml_path, settings)
    root = ET.Element("scene", version="3.0.0")
    for key, value in built.scene.items():
        if key != "type":
            writer.element(root, key, value, top=True)
    ET.indent(root, space="    ")
    # The XML last and atomically (a unique temporary beside it, then a rename): it is the file that refers
    # to the meshes, so a reader never sees an XML whose PLY files are not written yet.
    fd, tmp = tempfile.mkstemp(prefix=f".{xml_path.name}.", suffix=".tmp", dir=xml_path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            ET.ElementTree(root).write(f, encoding="unicode", xml_declaration=True)
        os.replace(tmp, xml_path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return xml_path

"""Mitsuba XML export: every shipped scene loads (a5 plugins, and stock without them); same images as the dict."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from a5mi import data_dir
from a5mi.converters.a5_parser import parse_file, parse_text
from a5mi.converters.describe import describe
from a5mi.converters.errors import SceneSemanticError
from a5mi.converters.to_mitsuba import to_dict
from a5mi.converters.to_xml import write_xml
from a5mi.options import RenderOptions


def _scene_files() -> list[Path]:
    root = data_dir()
    return sorted((root / "scenes").glob("*.txt")) + [root / "extras" / "sibenik" / "s.txt"]


SCENE_FILES = _scene_files()
SCENE_IDS = [p.stem if p.stem != "s" else "sibenik" for p in SCENE_FILES]


def _load_file(path: Path, **kw):
    """``mi.load_file``: every a5 plugin is registered by the ``variant`` fixture, so an unknown plugin (a
    regression in ``register_all``) fails here like any other error."""
    import mitsuba as mi

    return mi.load_file(str(path), **kw)


def test_xml_structure(variant: str, scenes_dir: Path, tmp_path: Path) -> None:
    out = write_xml(describe(parse_file(scenes_dir / "scene11_cube.txt")), tmp_path / "s11.xml",
                    RenderOptions(40, 30, shadows=True))
    root = ET.parse(out).getroot()
    assert root.tag == "scene" and root.get("version") == "3.0.0"
    integ = root.find("integrator")
    assert integ is not None and integ.get("type") == "a5_whitted"
    assert integ.find("boolean[@name='shadows']").get("value") == "true"  # type: ignore[union-attr]
    film = root.find("sensor/film")
    assert film is not None and film.find("integer[@name='width']").get("value") == "$width"  # type: ignore[union-attr]
    assert root.find("default[@name='width']").get("value") == "40"  # type: ignore[union-attr]
    mesh = root.find("shape[@id='mesh_001']")
    assert mesh is not None and mesh.get("type") == "ply"
    assert mesh.find("string[@name='filename']").get("value") == "s11_meshes/mesh_001.ply"  # type: ignore[union-attr]
    assert mesh.find("boolean[@name='face_normals']").get("value") == "true"  # type: ignore[union-attr]
    assert (tmp_path / "s11_meshes" / "mesh_001.ply").is_file()
    point = root.find("emitter[@id='light_001']")
    assert point is not None and point.get("type") == "a5_point"
    assert point.find("point[@name='position']").get("value") == "-2.0, 0.8, -2.0"  # type: ignore[union-attr]


def test_xml_errors_before_writing(variant: str, tmp_path: Path) -> None:
    text = ("PerspectiveCamera { center 0 0 5 direction 0 0 -1 up 0 1 0 angle 30 }\n"
            "Materials { numMaterials 1 Material { } }\n"
            "Group { numObjects 1 MaterialIndex 0 TriangleMesh { obj_file missing.obj } }\n")
    with pytest.raises(SceneSemanticError, match=r"m.txt:3:62: error: obj_file file 'missing.obj' not found"):
        write_xml(describe(parse_text(text, str(tmp_path / "m.txt"))), tmp_path / "m.xml")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow
@pytest.mark.parametrize("path", SCENE_FILES, ids=SCENE_IDS)
def test_shipped_scene_stock_xml_loads_in_plain_mitsuba(variant: str, path: Path, tmp_path: Path) -> None:
    import mitsuba as mi

    model = parse_file(path)
    out = write_xml(describe(model, stock=True), tmp_path / "stock.xml", RenderOptions(8, 8), stock=True)
    assert 'type="a5_' not in out.read_text()
    scene = mi.load_file(str(out), optimize=False)
    assert len(scene.shapes()) == len(model.objects)


@pytest.mark.slow
@pytest.mark.parametrize("path", SCENE_FILES, ids=SCENE_IDS)
def test_shipped_scene_xml_loads_with_a5_plugins(variant: str, path: Path, tmp_path: Path) -> None:
    model = parse_file(path)
    out = write_xml(describe(model), tmp_path / "a5.xml", RenderOptions(8, 8))
    scene = _load_file(out, optimize=False)
    # Planes and spheres travel as a5_whitted parameters (intersected as the binary does, SPEC A.6,
    # plugins/planes.py), not as shapes.
    n_planes = sum(type(p.primitive).__name__ in ("Plane", "Sphere") for p in model.objects)
    assert len(scene.shapes()) == len(model.objects) - n_planes
    assert len(scene.integrator().planes) == n_planes


@pytest.mark.parametrize("name", ["scene08_c", "scene12_vase", "scene03_sphere", "scene10_sphere"])
def test_xml_renders_like_the_dict(variant: str, scenes_dir: Path, tmp_path: Path, name: str) -> None:
    """Textured (uv through PLY), smooth-normal, and instanced-sphere scenes: XML image == dict image."""
    import mitsuba as mi

    model = parse_file(scenes_dir / f"{name}.txt")
    options = RenderOptions(24, 24, shadows=True)
    desc = describe(model)
    a = mi.load_dict(to_dict(desc, options))
    b = _load_file(write_xml(desc, tmp_path / f"{name}.xml", options))
    img_a = np.asarray(mi.render(a, spp=1))[..., :3]
    img_b = np.asarray(mi.render(b, spp=1))[..., :3]
    assert np.abs(img_a - img_b).max() < 1e-4

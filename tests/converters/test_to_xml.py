"""Mitsuba XML export: every shipped scene loads (a5 plugins, and stock without them); same images as the dict."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from helpers import ROOT

from a5mi import data_dir
from a5mi.converters.a5_parser import parse_file, parse_text
from a5mi.converters.describe import describe
from a5mi.converters.errors import SceneSemanticError
from a5mi.converters.to_mitsuba import to_dict
from a5mi.converters.to_xml import write_xml
from a5mi.render.options import RenderOptions


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
@pytest.mark.course_data
@pytest.mark.parametrize("path", SCENE_FILES, ids=SCENE_IDS)
def test_shipped_scene_stock_xml_loads_in_plain_mitsuba(variant: str, path: Path, tmp_path: Path) -> None:
    import mitsuba as mi

    model = parse_file(path)
    out = write_xml(describe(model, stock=True), tmp_path / "stock.xml", RenderOptions(8, 8), stock=True)
    assert 'type="a5_' not in out.read_text()
    scene = mi.load_file(str(out), optimize=False)
    assert len(scene.shapes()) == len(model.objects)


@pytest.mark.slow
@pytest.mark.course_data
@pytest.mark.parametrize("path", SCENE_FILES, ids=SCENE_IDS)
def test_shipped_scene_xml_loads_with_a5_plugins(variant: str, path: Path, tmp_path: Path) -> None:
    model = parse_file(path)
    out = write_xml(describe(model), tmp_path / "a5.xml", RenderOptions(8, 8))
    scene = _load_file(out, optimize=False)
    # Planes and spheres travel as a5_whitted parameters (intersected as the binary does, SPEC A.6,
    # plugins/emulation/planes.py), not as shapes.
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


# ------------------------------------------------------------------------- E.6 solids and E.7 maps, --stock

PLAIN_STOCK = """
import sys
import mitsuba as mi
import numpy as np
mi.set_variant("scalar_rgb")
assert not any(m.startswith("a5mi") for m in sys.modules)
image = np.asarray(mi.render(mi.load_file(sys.argv[1]), spp=1))
np.save(sys.argv[2], image)
"""


def test_stock_xml_of_solids_loads_in_plain_mitsuba(variant: str, tmp_path: Path) -> None:
    """scenes/solids.txt (Wood, Turbulence, Veins; E.6) converted with --stock: no a5 plugin in the XML, one
    warning per solid at its block, and a process that imports Mitsuba only (no a5mi plugin registered)
    loads and renders it. The baked grid holds the a5_solid colour at its cell centres (float32), and the
    stock texture looked up there returns it."""
    import subprocess
    import sys

    import mitsuba as mi

    from a5mi.converters import ext_mitsuba
    from a5mi.converters.to_mitsuba import bake_solid

    model = parse_file(ROOT / "scenes" / "solids.txt")
    desc = describe(model, stock=True)
    warned = [msg for _, msg in desc.warnings if "baked into an RGB grid" in msg]
    assert sorted(w.split()[2] for w in warned) == ["Turbulence", "Veins", "Wood", "Wood"]
    out = write_xml(desc, tmp_path / "stock.xml", RenderOptions(24, 24), stock=True)
    text = out.read_text()
    assert 'type="a5_' not in text and text.count('type="gridvolume"') == 4
    subprocess.run([sys.executable, "-c", PLAIN_STOCK, str(out), str(tmp_path / "img.npy")], check=True,
                   timeout=300, cwd=tmp_path)
    image = np.load(tmp_path / "img.npy")
    assert image.shape == (24, 24, 3) and float(image.std()) > 0.01
    # the bake: the grid at its cell centres is the a5_solid colour there
    m = next(i for i, mat in enumerate(model.materials) if mat.solid is not None)
    solid = {"type": "a5_solid", "kind": model.materials[m].solid.kind,
             "color1": {"type": "rgb", "value": list(model.materials[m].solid.color1)},
             "color2": {"type": "rgb", "value": list(model.materials[m].solid.color2)},
             "frequency": model.materials[m].solid.frequency, "amplitude": model.materials[m].solid.amplitude,
             "scale": model.materials[m].solid.scale, "axis": list(model.materials[m].solid.axis),
             "center": list(model.materials[m].solid.center), "octaves": model.materials[m].solid.octaves}
    lo, hi = ext_mitsuba.solid_box(desc, m)
    grid = bake_solid(solid, lo, hi)
    nx, ny, nz = ext_mitsuba.solid_resolution(lo, hi)
    assert grid.shape == (nz, ny, nx, 3) and nx * ny * nz <= ext_mitsuba.SOLID_CELLS
    rng = np.random.default_rng(1)
    idx = rng.integers(0, [nx, ny, nz], size=(50, 3))
    pts = lo + (idx + 0.5) / [nx, ny, nz] * (hi - lo)
    import drjit as dr

    si = dr.zeros(mi.SurfaceInteraction3f, 50)
    si.p = mi.Point3f(*pts.T.astype(np.float32))
    want = np.asarray(mi.load_dict(solid).eval(si))
    assert np.allclose(grid[idx[:, 2], idx[:, 1], idx[:, 0]], want.T, atol=1e-6)
    baked = ext_mitsuba.baked_solid({"data": mi.TensorXf(grid)}, lo, hi)
    baked["volume"]["to_world"] = mi.ScalarTransform4f(baked["volume"]["to_world"].tolist())
    got = np.asarray(mi.load_dict(baked).eval(si))
    assert np.allclose(got, want, atol=1e-5)


@pytest.mark.parametrize("shape", ["Sphere { center 0 0 0 radius 1 }", "TriangleMesh { obj_file QUAD }"],
                         ids=["sphere", "obj-without-uv"])
def test_bump_and_normal_map_without_uv_warn_at_the_shape(shape: str, tmp_path: Path) -> None:
    """E.7: with -bump, a bump or normal map on a shape without texture coordinates cannot show (as a texture
    there): a warning at the shape, as for the texture; without -bump the maps are not read and nothing is said."""
    from a5mi.platform.imageio import write_image

    write_image(tmp_path / "h.png", np.full((4, 4, 3), 128, dtype=np.uint8))
    (tmp_path / "q.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    text = ("PerspectiveCamera { center 0 0 5 direction 0 0 -1 up 0 1 0 angle 30 }\n"
            "Background { color 0 0 0 }\n"
            "Materials { numMaterials 1 Material { diffuseColor 1 1 1 bump h.png normalMap h.png } }\n"
            f"Group {{ numObjects 1 MaterialIndex 0 {shape.replace('QUAD', 'q.obj')} }}\n")
    (tmp_path / "s.txt").write_text(text)
    model = parse_file(tmp_path / "s.txt")
    col = text.splitlines()[3].index(shape.split()[0]) + 1
    kind = shape.split()[0]
    got = [(str(loc), msg) for loc, msg in describe(model, bump=True).warnings if "cannot show" in msg]
    assert got == [(f"{tmp_path / 's.txt'}:4:{col}", f"{which} 'h.png' cannot show on this {kind}: it has no "
                    "texture coordinates (EXTENSIONS E.7)") for which in ("bump", "normalMap")]
    assert not [msg for _, msg in describe(model).warnings if "cannot show" in msg]

"""Model -> scene description -> Mitsuba dict (SPEC A.3-A.6, B.2, B.3): structure, geometry facts, loading, and the
plane horizon."""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from a5mi import data_dir
from a5mi.converters import transforms as tf
from a5mi.converters.a5_parser import parse_file, parse_text
from a5mi.converters.describe import (
    ColorBackground,
    CubeMapBackground,
    MeshShape,
    PlaneShape,
    SceneDescription,
    SphereShape,
    describe,
)
from a5mi.converters.errors import SceneSemanticError
from a5mi.converters.files import Image, cube_map_folder
from a5mi.converters.geometry import PLANE_HALF_SIZE, MeshData, plane_rectangle_to_world, world_plane
from a5mi.converters.materials import a5_bsdf, without_texture
from a5mi.converters.model import Noise
from a5mi.converters.names import object_bsdf, scene_ids
from a5mi.converters.to_mitsuba import (
    Backend,
    background_dict,
    integrator_dict,
    light_dict,
    scene_entries,
    sensor_dict,
    to_dict,
)
from a5mi.platform.imageio import read_uint8
from a5mi.render.options import RenderOptions

CAM = "PerspectiveCamera { center 0 0 10 direction 0 0 -1 up 0 1 0 angle 30 }\n"


def _scene_files() -> list[Path]:
    root = data_dir()
    return sorted((root / "scenes").glob("*.txt")) + [root / "extras" / "sibenik" / "s.txt"]


SCENE_FILES = _scene_files()
SCENE_IDS = [p.stem if p.stem != "s" else "sibenik" for p in SCENE_FILES]


def _load(d: dict):
    """``mi.load_dict``: every a5 plugin is registered by the ``variant`` fixture, so an unknown plugin (a
    regression in ``register_all``) fails here like any other error."""
    import mitsuba as mi

    return mi.load_dict(d)


def _mesh(desc: SceneDescription, i: int) -> MeshData:
    shape = desc.shapes[i]
    assert isinstance(shape, MeshShape)
    return shape.mesh


# --------------------------------------------------------------------------------- structure (no Mitsuba)
def test_b3_integrator_and_a1_ambient(scenes_dir: Path) -> None:
    desc = describe(parse_file(scenes_dir / "scene11_cube.txt"))
    options = RenderOptions(width=30, height=20, bounces=2, shadows=True, fresnel="exact")
    assert integrator_dict(desc, options, stock=False) == {
        "type": "a5_whitted", "max_depth": 2, "shadows": True, "ambient": {"type": "rgb", "value": [0.1, 0.1, 0.1]},
        "phong": False, "fresnel": "exact", "reflection": True, "refraction": True, "aovs": "", "glossy": False}
    s = sensor_dict(desc, options, stock=False)
    assert (s["type"], s["center"], s["direction"], s["up"], s["angle"]) == (
        "a5_camera", [-5.3, 7.0, 8.3], [0.4, -0.5, -0.75], [0.0, 1.0, 0.0], 25.0)
    assert (s["film"]["width"], s["film"]["height"]) == (30, 20)
    text = CAM + "Materials { numMaterials 1 Material { } } Background { ambientLight 0.3 0.3 0.3 }\n" \
                 "Group { numObjects 1 MaterialIndex 0 Sphere { center 0 0 0 radius 1 } }"
    no_lights = describe(parse_text(text, "n.txt"))
    assert integrator_dict(no_lights, RenderOptions(), stock=False)["ambient"]["value"] == [1.0, 1.0, 1.0]
    assert no_lights.lights == ()


def test_a3_a4_lights_and_background(scenes_dir: Path) -> None:
    desc = describe(parse_file(scenes_dir / "scene11_cube.txt"))
    assert light_dict(desc.lights[0], desc.centre, stock=False) == {
        "type": "directional", "direction": [-0.3, -0.5, -0.5], "irradiance": {"type": "rgb", "value": [0.3, 0.3, 0.3]}}
    assert light_dict(desc.lights[1], desc.centre, stock=False) == {
        "type": "a5_point", "position": [-2.0, 0.8, -2.0], "color": {"type": "rgb", "value": [0.9, 0.9, 0.9]},
        "falloff": 0.1}
    bg = desc.background
    assert isinstance(bg, CubeMapBackground)
    assert bg.folder == (scenes_dir / "tex" / "church2").resolve()
    assert [f.path for f in bg.faces] == [(scenes_dir / "tex" / "church2" / f"{face}.bmp").resolve()
                                          for face in ("left", "right", "up", "down", "front", "back")]
    bg = describe(parse_file(scenes_dir / "scene02_cube.txt")).background
    assert isinstance(bg, ColorBackground)
    assert background_dict(bg) == {"type": "constant", "radiance": {"type": "rgb", "value": [0.2, 0.0, 0.6]}}


def test_b3_texture_only_where_the_shape_has_uv(scenes_dir: Path) -> None:
    """scene08: textured materials on OBJ meshes with vt; a textured material on the Plane (no uv)
    gets a second, untextured BSDF whose kd is the diffuse colour."""
    text = (scenes_dir / "scene08_c.txt").read_text()
    text = text.replace("MaterialIndex 3\n    Plane", "MaterialIndex 0\n    Plane")
    desc = describe(parse_text(text, str(scenes_dir / "scene08_x.txt")))
    mat = desc.materials[0]
    head = (scenes_dir / "tex" / "head.bmp").resolve()
    assert isinstance(mat.kd, Image) and mat.kd.path == head
    np.testing.assert_array_equal(mat.kd.pixels, read_uint8(head))
    assert a5_bsdf(mat, True)["kd"] == {"type": "a5_bitmap", "filename": str(head)}
    nouv = a5_bsdf(mat, False)
    assert "kd" not in nouv and nouv["diffuse_color"]["value"] == [0.2, 0.8, 0.2]
    assert without_texture(mat, False) and not without_texture(mat, True)
    plane, mesh = desc.shapes[3], desc.shapes[0]
    assert isinstance(plane, PlaneShape) and plane.material == 0 and not plane.has_uv
    assert isinstance(mesh, MeshShape) and mesh.material == 0 and mesh.has_uv


def test_b4_noise_is_the_kd_texture(scenes_dir: Path) -> None:
    desc = describe(parse_file(scenes_dir / "scene10_sphere.txt"))
    assert isinstance(desc.materials[2].kd, Noise)
    for with_uv in (False, True):  # Noise overrides any texture, with or without uv (B.3)
        assert a5_bsdf(desc.materials[2], with_uv)["kd"] == {
            "type": "a5_marble", "color1": {"type": "rgb", "value": [0.1, 0.2, 0.3]},
            "color2": {"type": "rgb", "value": [0.3, 0.4, 0.5]}, "octaves": 4, "frequency": 2.0, "amplitude": 4.0}
    glass = a5_bsdf(desc.materials[0], False)
    assert glass["refraction_index"] == 1.3 and glass["specular_color"]["value"] == [1, 1, 1]


def test_a6_sphere_similarity_vs_shapegroup(variant: str, scenes_dir: Path) -> None:
    desc = describe(parse_file(scenes_dir / "scene10_sphere.txt"))
    sph = desc.shapes[0]
    assert isinstance(sph, SphereShape) and sph.to_world is None and list(sph.center) == [0.3, 0.0, -1.0]
    d = to_dict(desc, stock=True)
    assert d["sphere_000"]["type"] == "sphere" and d["sphere_000"]["center"] == [0.3, 0.0, -1.0]
    d = to_dict(desc)   # a5: the binary's sphere test in a5_whitted, untransformed (identity)
    assert d["integrator"]["plane_000_center"] == [0.3, 0.0, -1.0]
    assert np.array_equal(np.array(d["integrator"]["plane_000_to_world"].matrix), np.eye(4))
    desc = describe(parse_file(scenes_dir / "scene03_sphere.txt"))  # ZRotate 45 * Scale 1 .2 1
    sph = desc.shapes[0]
    assert isinstance(sph, SphereShape) and sph.to_world is not None
    assert np.allclose(sph.to_world, tf.z_rotate(45) @ tf.scale(1, 0.2, 1))
    d = to_dict(desc, stock=True)
    assert d["sphere_000"]["type"] == "instance"
    assert d["sphere_000"]["shapegroup"] == {"type": "ref", "id": "sphere_000_group"}
    group = d["sphere_000_group"]
    assert group["type"] == "shapegroup" and group["sphere_000_shape"]["type"] == "sphere"
    assert np.allclose(np.array(d["sphere_000"]["to_world"].matrix), tf.z_rotate(45) @ tf.scale(1, 0.2, 1))
    d = to_dict(desc)   # a5 renders: the binary's object-space test inside a5_whitted (plugins/emulation/planes.py)
    assert "sphere_000" not in d and d["integrator"]["plane_000_radius"] == sph.radius
    assert np.allclose(np.array(d["integrator"]["plane_000_to_world"].matrix), tf.z_rotate(45) @ tf.scale(1, 0.2, 1))
    text = CAM + "Materials { numMaterials 1 Material { } }\nGroup { numObjects 1 MaterialIndex 0 Transform {" \
                 " Translate 1 2 3 ZRotate 30 UniformScale 2 Sphere { center 1 0 0 radius 0.5 } } }"
    sph = describe(parse_text(text, "s.txt")).shapes[0]
    c = [1 + 2 * math.cos(math.radians(30)), 2 + 2 * math.sin(math.radians(30)), 3]
    assert isinstance(sph, SphereShape) and sph.to_world is None
    assert np.allclose(sph.center, c) and sph.radius == pytest.approx(1.0)


#: One object of each kind (a plain and an instanced sphere, a plane, a triangle, a mesh) and one light of each.
EVERY_KIND = CAM + """Lights { numLights 5
  DirectionalLight { direction 0 -1 0 color 1 1 1 }
  PointLight { position 0 5 0 color 1 1 1 }
  SpotLight { position 0 5 0 direction 0 -1 0 color 1 1 1 angle 30 }
  AreaLight { corner -1 5 -1 edge1 2 0 0 edge2 0 0 2 color 1 1 1 }
  SphereLight { center 3 5 0 radius 0.5 color 1 1 1 }
}
Materials { numMaterials 1 Material { diffuseColor 1 0 0 } }
Group { numObjects 5 MaterialIndex 0
  Sphere { center 0 0 0 radius 1 }
  Transform { Scale 1 2 1 Sphere { center 0 0 0 radius 1 } }
  Plane { normal 0 1 0 offset -1 }
  Triangle { vertex0 0 0 0 vertex1 1 0 0 vertex2 0 1 0 }
  TriangleMesh { obj_file cube.obj }
}
"""


class _NamesOnly(Backend):
    """A back end that builds no Mitsuba object: the entries' names and layout only."""

    def bsdf(self, entries, material, with_uv):
        return {"type": "stub_bsdf", "material": material}

    def mesh(self, key, shape, bsdf):
        return {"type": "stub_mesh", "bsdf": bsdf}

    def cubemap(self, bg):
        raise AssertionError("no cube map here")

    envmap = cubemap

    def grid_source(self, vol):
        raise AssertionError("no volume here")


@pytest.mark.parametrize("stock", [False, True], ids=["a5", "stock"])
def test_scene_ids_name_every_entry_of_every_kind(scenes_dir: Path, stock: bool) -> None:
    """The table of names is the dict's layout: every entry it names exists with the right type, and every
    shape, light and plane parameter of the dict is named by it (nothing else is)."""
    desc = describe(parse_text(EVERY_KIND, str(scenes_dir / "every_kind.txt")), stock=stock)
    ids = scene_ids(desc, stock=stock)
    d = scene_entries(desc, RenderOptions(), _NamesOnly(desc, stock=stock))
    assert [o.kind for o in ids.objects] == ["sphere", "sphere", "plane", "triangle", "mesh"]
    assert [o.index for o in ids.objects] == [0, 1, 2, 3, 4]
    plain, moved, plane, tri, mesh = ids.objects
    if stock:
        assert d[plain.entry]["type"] == "sphere" and plain.shape_ids == (plain.entry,)
        assert d[moved.entry]["type"] == "instance" and d[moved.entry]["shapegroup"]["id"] == moved.group
        assert d[moved.group][moved.inner]["type"] == "sphere" and moved.shape_ids == (moved.entry, moved.inner)
    else:   # the binary's sphere test, in a5_whitted's plane set
        for sphere in (plain, moved):
            assert sphere.key is None and sphere.shape_ids == ()
            for name in ("center", "radius", "to_world", "bsdf"):
                assert sphere.plane_param(name) in d["integrator"]
    assert d[tri.entry]["type"] == d[mesh.entry]["type"] == "stub_mesh"
    if stock:
        assert plane.plane is None and d[plane.entry]["type"] == "rectangle"
    else:
        assert plane.key is None and plane.shape_ids == ()
        for name in ("normal", "offset", "mirror_normal", "bsdf"):
            assert plane.plane_param(name) in d["integrator"]
        with pytest.raises(ValueError):
            _ = plane.entry
    for o in ids.objects:
        assert object_bsdf(d, o) == {"type": "stub_bsdf", "material": 0}
        for sid in o.shape_ids:
            assert ids.object_of_shape(sid) == o.index
        if o.plane is not None:
            assert ids.object_of_plane(o.plane) == o.index
    assert [lt.shape for lt in ids.lights] == [False, False, False, True, True]
    light_types = [d[lt.key]["type"] for lt in ids.lights]
    assert light_types[3:] == ["rectangle", "sphere"] and "emitter" in d[ids.lights[3].key]
    named = {o.key for o in ids.objects} | {o.group for o in ids.objects} | {lt.key for lt in ids.lights}
    assert set(d) - {"type", "integrator", "sensor", "background"} == named - {None}
    plane_params = {k for k in d["integrator"] if k.startswith("plane_")}
    kinds = {"plane": ("normal", "offset", "mirror_normal", "bsdf"), "sphere": ("center", "radius", "to_world", "bsdf")}
    assert plane_params == {o.plane_param(n) for o in ids.objects if o.plane is not None for n in kinds[o.kind]}
    assert ids.object_of_shape(ids.lights[3].key) is None and ids.object_of_plane("nope") is None


def test_scene_ids_are_the_loaded_scene_ids(variant: str, scenes_dir: Path) -> None:
    """In the loaded scene: every shape's Mitsuba id is an object's (or an area light's) name from the table, the
    lights' and shapes' ``mi.traverse`` parameters sit under their names, and each object's BSDF is found."""
    import mitsuba as mi

    desc = describe(parse_text(EVERY_KIND, str(scenes_dir / "every_kind.txt")))
    ids = scene_ids(desc)
    d = to_dict(desc)
    scene = _load(d)
    light_shapes = {lt.key for lt in ids.lights if lt.shape}
    loaded = {s.id() for s in scene.shapes()}
    assert loaded - light_shapes == {o.entry for o in ids.objects if o.key is not None}
    params = mi.traverse(scene)
    plain, moved, _, tri, mesh = ids.objects
    assert plain.key is None and plain.plane_param("center") in d["integrator"]
    for key in (f"{ids.lights[1].key}.position", f"{ids.lights[2].key}.position",
                f"{tri.entry}.vertex_positions", f"{mesh.entry}.vertex_positions"):
        assert key in params, key
    assert moved.key is None and moved.plane_param("to_world") in d["integrator"]   # exact: a5_whitted's
    for o in ids.objects:
        assert isinstance(object_bsdf(d, o), mi.BSDF)


def test_a6_mesh_vertices_are_baked_into_world_space(scenes_dir: Path) -> None:
    """scene11 red post: Translate(-.8,0,-2) Scale(.25,1,.25) YRotate(45) Translate(0,1,0); corner (1,1,1)
    -> (-0.8 + 0.25*sqrt2, 2, -2)."""
    mesh = _mesh(describe(parse_file(scenes_dir / "scene11_cube.txt")), 1)
    corner = np.array([-0.8 + 0.25 * math.sqrt(2), 2.0, -2.0])
    assert np.min(np.linalg.norm(mesh.positions - corner, axis=1)) < 1e-12
    assert mesh.normals is None and mesh.texcoords is None and mesh.faces.shape == (12, 3)


def test_a6_smooth_normals_are_transformed_by_inverse_transpose_without_renormalising(scenes_dir: Path) -> None:
    text = CAM + "Materials { numMaterials 1 Material { } }\nGroup { numObjects 1 MaterialIndex 0 Transform {" \
                 f" Scale 2 1 1 TriangleMesh {{ obj_file {scenes_dir / 'bunny_1k.obj'} }} }} }}"
    mesh = _mesh(describe(parse_text(text, "b.txt")), 0)
    assert mesh.normals is not None and len(mesh.normals) == 502
    plain = _mesh(describe(parse_text(text.replace("Scale 2 1 1", "Scale 1 1 1"), "b.txt")), 0)
    assert plain.normals is not None
    assert np.allclose(np.linalg.norm(plain.normals, axis=1), 1.0)
    assert np.allclose(mesh.normals, plain.normals * [0.5, 1, 1])
    assert np.allclose(mesh.positions, plain.positions * [2, 1, 1])


def test_a6_flat_winding_reversed_under_a_mirror() -> None:
    """Triangle (0,0,0) (1,0,0) (0,1,0) has normal +z; under Scale -1 1 1 the binary's normal is
    (M⁻¹)ᵀ(0,0,1) = (0,0,1): the world winding must keep +z."""
    text = CAM + "Materials { numMaterials 1 Material { } }\nGroup { numObjects 1 MaterialIndex 0 Transform {" \
                 " Scale -1 1 1 Triangle { vertex0 0 0 0 vertex1 1 0 0 vertex2 0 1 0 } } }"
    mesh = _mesh(describe(parse_text(text, "t.txt")), 0)
    p = mesh.positions[mesh.faces[0]]
    assert np.cross(p[1] - p[0], p[2] - p[0]).tolist() == [0.0, 0.0, 1.0]


def test_a6_plane_rectangle(scenes_dir: Path) -> None:
    """``normal 0 2 0 offset -1`` is y = -0.5 (normal not normalised); the rectangle's z axis is +y."""
    text = CAM + "Materials { numMaterials 1 Material { } }\nGroup { numObjects 1 MaterialIndex 0 " \
                 "Plane { normal 0 2 0 offset -1 } }"
    plane = describe(parse_text(text, "p.txt")).shapes[0]
    assert isinstance(plane, PlaneShape)
    assert np.allclose(plane.n_w, [0, 2, 0]) and plane.offset_w == pytest.approx(-1.0)
    m = plane.rectangle
    assert np.allclose(m[:3, 3], [0, -0.5, 10]) and np.allclose(m[:3, 2], [0, 1, 0])
    assert np.isclose(np.linalg.norm(m[:3, 0]), PLANE_HALF_SIZE)  # the --stock stand-in
    # Under a Transform the plane maps by M^-T: Translate 0 3 0 lifts y = -0.5 to y = 2.5.
    n_w, off = world_plane(parse_text(text, "p.txt").objects[0].primitive, tf.translate(0, 3, 0))
    assert np.allclose(n_w, [0, 2, 0]) and off == pytest.approx(5.0)
    assert np.allclose(plane_rectangle_to_world(n_w, off, np.zeros(3))[:3, 3], [0, 2.5, 0])


def test_paths_resolve_against_the_scene_folder_and_missing_files_are_errors(scenes_dir: Path,
                                                                              tmp_path: Path) -> None:
    src = (scenes_dir / "scene02_cube.txt").read_text()
    (tmp_path / "s.txt").write_text(src)
    with pytest.raises(SceneSemanticError) as e:
        describe(parse_file(tmp_path / "s.txt"))
    assert str(e.value).startswith(f"{tmp_path / 's.txt'}:31:18: error: obj_file file 'cube.obj' not found")
    shutil.copy(scenes_dir / "cube.obj", tmp_path / "cube.obj")
    assert _mesh(describe(parse_file(tmp_path / "s.txt")), 0).faces.shape == (12, 3)
    (tmp_path / "t.txt").write_text(src.replace("Material { diffuseColor 1 0 0 }",
                                                "Material { diffuseColor 1 0 0 texture nope.bmp }")
                                    .replace("Background {", "Background {\n    cubeMap cm"))
    with pytest.raises(SceneSemanticError, match=r"t.txt:18:13: error: cubeMap folder 'cm' not found"):
        describe(parse_file(tmp_path / "t.txt"))
    (tmp_path / "cm").mkdir()
    with pytest.raises(SceneSemanticError, match=r"t.txt:18:13: error: cubeMap folder '.*cm' has no 'left' face"):
        describe(parse_file(tmp_path / "t.txt"))
    for face in ("left", "right", "up", "down", "front", "back"):
        (tmp_path / "cm" / f"{face}.bmp").write_bytes(b"BM")
    with pytest.raises(SceneSemanticError, match=r"t.txt:18:13: error: cubeMap face '.*left.bmp' is not a readable"):
        describe(parse_file(tmp_path / "t.txt"))  # faces are read whole when resolved
    for face in ("left", "right", "up", "down", "front", "back"):
        shutil.copy(scenes_dir / "tex" / "head.bmp", tmp_path / "cm" / f"{face}.bmp")
    # A referenced texture is checked wherever it is used, even on cube.obj (no uv) where it
    # cannot show: missing -> error at the file name; readable -> a warning at the shape.
    text = (tmp_path / "t.txt").read_text()
    line = text[:text.index("nope.bmp")].count("\n") + 1
    col = text.index("nope.bmp") - text.rfind("\n", 0, text.index("nope.bmp"))
    with pytest.raises(SceneSemanticError, match=rf"t.txt:{line}:{col}: error: texture file 'nope.bmp' not found"):
        describe(parse_file(tmp_path / "t.txt"))
    (tmp_path / "nope.bmp").write_bytes(b"BM garbage")
    with pytest.raises(SceneSemanticError, match=rf"t.txt:{line}:{col}: error: texture .*nope.bmp.* not a readable"):
        describe(parse_file(tmp_path / "t.txt"))
    shutil.copy(scenes_dir / "tex" / "head.bmp", tmp_path / "nope.bmp")
    desc = describe(parse_file(tmp_path / "t.txt"))
    mesh_loc = next(s.loc for s in desc.shapes if isinstance(s, MeshShape))
    assert [(str(loc), msg) for loc, msg in desc.warnings if "texture" in msg] == [
        (str(mesh_loc), "texture 'nope.bmp' cannot show on this TriangleMesh: it has no texture coordinates "
                        "(SPEC B.3)")]
    assert "kd" not in a5_bsdf(desc.materials[0], False)  # on shapes without uv: the diffuse colour


def _cube_scene(folder: Path) -> Path:
    """``folder/s.txt``: one sphere in front of the cube map ``tex/church`` (its name on line 3, column 34)."""
    (folder / "s.txt").write_text(CAM + "Lights { numLights 0 }\nBackground { color 0 0 0 cubeMap tex/church }\n"
                                  "Materials { numMaterials 1 Material { } }\n"
                                  "Group { numObjects 1 MaterialIndex 0 Sphere { center 0 0 0 radius 1 } }\n")
    (folder / "tex").mkdir()
    return folder / "s.txt"


def test_a4_cubemap_link_file_is_followed_with_a_warning(tmp_path: Path) -> None:
    """A cube-map folder reached through a real symlink needs nothing; a small text file holding a relative
    path to a folder (a git symlink checked out as text, like the course's extras/sibenik/tex/church) is
    followed with a warning at the cubeMap keyword."""
    from a5mi.platform import imageio

    faces = tmp_path / "faces"
    faces.mkdir()
    for k, face in enumerate(("left", "right", "up", "down", "front", "back")):
        imageio.write_image(faces / f"{face}.png", np.full((2, 2, 3), (10 * k + 0.5) / 255.0))

    (tmp_path / "a").mkdir()
    linked = _cube_scene(tmp_path / "a")
    (linked.parent / "tex" / "church").symlink_to(Path("..") / ".." / "faces", target_is_directory=True)
    warnings: list = []
    assert cube_map_folder(parse_file(linked), warnings).resolve() == faces.resolve() and warnings == []
    desc = describe(parse_file(linked))
    assert isinstance(desc.background, CubeMapBackground) and desc.background.folder == faces.resolve()
    assert desc.warnings == ()
    assert [int(f.pixels[0, 0, 0]) for f in desc.background.faces] == [0, 10, 20, 30, 40, 50]

    (tmp_path / "b").mkdir()
    text = _cube_scene(tmp_path / "b")
    (text.parent / "tex" / "church").write_text("../../faces\n")
    warnings = []
    assert cube_map_folder(parse_file(text), warnings).resolve() == faces.resolve()
    assert len(warnings) == 1 and "symlink checked out as a file" in warnings[0][1]
    assert (warnings[0][0].line, warnings[0][0].col) == (3, 34)  # the folder name
    desc = describe(parse_file(text))
    assert isinstance(desc.background, CubeMapBackground) and desc.background.folder == faces.resolve()
    assert [msg for _, msg in desc.warnings] == [warnings[0][1]]


# --------------------------------------------------------------------------------- loading
@pytest.mark.course_data
@pytest.mark.parametrize("path", SCENE_FILES, ids=SCENE_IDS)
def test_shipped_scene_loads_stock(variant: str, path: Path) -> None:
    import mitsuba as mi

    model = parse_file(path)
    scene = mi.load_dict(to_dict(describe(model), RenderOptions(8, 8), stock=True))
    assert len(scene.shapes()) == len(model.objects)
    assert len(scene.emitters()) == len(model.lights) + 1  # + the background


@pytest.mark.course_data
@pytest.mark.parametrize("path", SCENE_FILES, ids=SCENE_IDS)
def test_shipped_scene_loads_with_a5_plugins(variant: str, path: Path) -> None:
    model = parse_file(path)
    scene = _load(to_dict(describe(model), RenderOptions(8, 8)))
    # Planes and spheres are not Mitsuba shapes here: a5_whitted intersects them analytically (SPEC A.6,
    # plugins/emulation/planes.py).
    n_planes = sum(type(p.primitive).__name__ in ("Plane", "Sphere") for p in model.objects)
    assert len(scene.shapes()) == len(model.objects) - n_planes
    assert len(scene.integrator().planes) == n_planes
    assert len(scene.emitters()) == len(model.lights) + 1  # + the background


def test_stock_sensor_puts_pixel_centres_where_b2_does(variant: str, scenes_dir: Path) -> None:
    """fov = 2 atan(tan(a/2) W/(W-1)): the stock perspective camera's pixel-centre rays equal B.2's."""
    import mitsuba as mi

    from a5mi.plugins.sensors.camera import camera_rays

    model = parse_file(scenes_dir / "scene11_cube.txt")
    w = 9
    sensor = mi.load_dict(to_dict(describe(model), RenderOptions(w, w), stock=True)["sensor"])
    c = model.camera
    for i, j in [(0, 0), (4, 4), (8, 2), (3, 8)]:
        ray, _ = sensor.sample_ray(0.0, 0.0, mi.Point2f((i + 0.5) / w, 1 - (j + 0.5) / w), mi.Point2f(0.5))
        ref = camera_rays(c.center, c.direction, c.up, c.angle, mi.Float(i), mi.Float(j), w, w)
        assert np.allclose(np.array(ray.d).ravel(), np.array(ref.d).ravel(), atol=2e-6), (i, j)


def test_stock_envmap_bakes_the_cube_map(variant: str, scenes_dir: Path) -> None:
    import drjit as dr
    import mitsuba as mi

    desc = describe(parse_file(scenes_dir / "scene11_cube.txt"))
    env = mi.load_dict(to_dict(desc, stock=True)["background"])
    cube = mi.load_dict(to_dict(desc)["background"])
    from_folder = _load({"type": "a5_cubemap", "filename": str(scenes_dir / "tex" / "church2")})
    rng = np.random.default_rng(1)
    d = rng.normal(size=(2000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    si = dr.zeros(mi.SurfaceInteraction3f, len(d))
    si.wi = -mi.Vector3f(d.astype(np.float32).T)
    a = np.array(env.eval(si))
    b = np.array(cube.eval(si))
    assert np.mean(np.abs(a - b)) < 0.03
    np.testing.assert_array_equal(b, np.array(from_folder.eval(si)))  # decoded faces == the files


# --------------------------------------------------------------------------------- the plane horizon
TILTED = ("PerspectiveCamera { center 0 2 8 direction 0 -0.3 -1 up 0 1 0 angle 40 }\n"
          "Lights { numLights 0 }\nMaterials { numMaterials 1 Material { diffuseColor 1 1 1 } }\n"
          "Group { numObjects 1 MaterialIndex 0 Plane { normal 0 1 0.05 offset -1 } }\n")


@pytest.mark.parametrize("name", ["scene01_plane", "scene06_bunny_1k", "scene10_sphere", "scene11_cube",
                                  "scene12_vase", "scene13_diamond", "tilted"])
def test_a6_stock_plane_stand_in_is_exact_to_far_below_tmin(variant: str, scenes_dir: Path, name: str) -> None:
    """The ``--stock`` stand-in (a rectangle of half-size PLANE_HALF_SIZE centred below the camera): every B.2
    pixel ray (300 x 300) that meets the infinite plane at 0 < t < PLANE_HALF_SIZE/2 hits the rectangle, no
    other ray does, and each hit point lies within 1e-5 (tmin/100) of the plane, tilted planes included (a
    1e7 rectangle is off by 1e-2 on the tilted one)."""
    import mitsuba as mi

    from a5mi.plugins.sensors.camera import camera_rays

    model = parse_text(TILTED, "t.txt") if name == "tilted" else parse_file(scenes_dir / f"{name}.txt")
    planes = [s for s in describe(model, stock=True).shapes if isinstance(s, PlaneShape)]
    n = 300
    jj, ii = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    c = model.camera
    ray = camera_rays(c.center, c.direction, c.up, c.angle, mi.Float(ii.ravel()), mi.Float(jj.ravel()), n, n)
    o = np.array(ray.o, dtype=np.float64).T
    dirs = np.array(ray.d, dtype=np.float64).T
    for s in planes:
        rect = mi.load_dict({"type": "scene", "p": {"type": "rectangle",
                                                    "to_world": mi.ScalarTransform4f(s.rectangle.tolist())}})
        si = rect.ray_intersect(ray)
        hit = np.array(si.is_valid())
        nd = dirs @ s.n_w
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (s.offset_w - o @ s.n_w) / nd
        near = (nd != 0) & (t > 0) & (t < PLANE_HALF_SIZE / 2)
        assert near.sum() > 1000
        assert hit[near].all() and not hit[~((nd != 0) & (t > 0))].any()
        p = o[hit] + np.array(si.t, dtype=np.float64)[hit, None] * dirs[hit]
        err = np.abs(p @ s.n_w - s.offset_w) / np.linalg.norm(s.n_w)
        assert err.max() < 1e-5


@pytest.mark.parametrize("name", ["scene10_sphere", "scene12_vase"])
def test_a6_horizon_row_matches_the_reference_image(variant: str, a5_data: Path, name: str) -> None:
    """Where the converted scene is missed just above the plane's last hit row, the reference render shows the
    cube-map background for that ray (so a5soln missed it too); on the last hit row it shows something else."""
    import drjit as dr
    import mitsuba as mi

    from a5mi.plugins.sensors.camera import camera_rays

    model = parse_file(a5_data / "scenes" / f"{name}.txt")
    scene = _load(to_dict(describe(model), RenderOptions(300, 300)))
    n = 300
    jj, ii = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    c = model.camera
    ray = camera_rays(c.center, c.direction, c.up, c.angle, mi.Float(ii.ravel()), mi.Float(jj.ravel()), n, n)
    t_first = np.array(scene.integrator().trace(scene, ray)[2]).reshape(n, n)  # analytic planes (SPEC A.6)
    hit = np.isfinite(t_first)  # [j, i], j = 0 the bottom row
    plane = next(p for p in model.objects if type(p.primitive).__name__ == "Plane")
    nw, off = world_plane(plane.primitive, plane.to_world)
    o = np.array(ray.o, dtype=np.float64).T
    dirs = np.array(ray.d, dtype=np.float64).T
    with np.errstate(divide="ignore", invalid="ignore"):
        t_plane = ((off - o @ nw) / (dirs @ nw)).reshape(n, n)
    plane_hit = t_plane > 0
    si = dr.zeros(mi.SurfaceInteraction3f, n * n)
    si.wi = -ray.d
    bg = np.array(scene.environment().eval(si)).T.reshape(n, n, 3)
    bg8 = np.clip((bg * 255).astype(int), 0, 255)

    import OpenImageIO as oiio

    ref = oiio.ImageBuf(str(a5_data / "reference" / f"{name}.b4.png")).get_pixels(oiio.UINT8)[::-1, :, :3]
    top = int(np.nonzero(plane_hit.any(axis=1))[0].max())  # the plane's last row from the bottom: the horizon
    assert plane_hit[top].all() and not plane_hit[top + 1].any()
    free_above = ~hit[top + 1]  # columns where nothing else covers the sky just above the horizon
    plane_first = np.isclose(t_first[top], t_plane[top], rtol=1e-4)
    assert free_above.sum() > 150 and plane_first.sum() > 150
    above = np.abs(ref[top + 1].astype(int) - bg8[top + 1]).max(axis=1)[free_above]
    below = np.abs(ref[top].astype(int) - bg8[top]).max(axis=1)[plane_first]
    assert np.mean(above <= 1) > 0.97
    assert np.mean(below > 2) > 0.5


def test_a_kept_decoded_image_is_one_bitmap(variant: str) -> None:
    """``bitmap`` of the same decoded image (a served request's kept image) returns the Bitmap made before; an
    equal image decoded again is its own; the pixels are the image's."""
    import gc
    import weakref

    import mitsuba as mi

    from a5mi.converters import to_mitsuba

    px = np.arange(4 * 5 * 3, dtype=np.uint8).reshape(4, 5, 3)
    px.flags.writeable = False                       # as decoded images are
    img = Image(Path("/x/a.bmp"), px)
    first = to_mitsuba.bitmap(img)
    assert to_mitsuba.bitmap(img) is first and isinstance(first, mi.Bitmap)
    other = Image(Path("/x/a.bmp"), px.copy())
    assert to_mitsuba.bitmap(other) is not first
    np.testing.assert_array_equal(np.asarray(first), px)
    alive = weakref.ref(img)
    del img, first
    gc.collect()
    assert alive() is None and other in to_mitsuba._BITMAPS   # the cache does not keep an image alive

"""SPEC A.1-A.6: the parser on the tomli-style corpus (tests/data) and on every shipped scene.

``tests/data/valid/NAME.txt`` must parse to the summary in ``NAME.json`` (see :func:`summary`);
``tests/data/invalid/NAME.txt`` must raise exactly the ``line:col: error: message`` in ``NAME.err``.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from helpers import TESTS

from a5mi.converters import model as m
from a5mi.converters.a5_parser import parse_file, parse_text
from a5mi.converters.errors import FileLoc, SceneError, SceneSemanticError, SceneSyntaxError
from a5mi.converters.transforms import transform_points

pytestmark = pytest.mark.unit  # the fast tier (`make check`): no Mitsuba, no child process

DATA = TESTS / "data"
VALID = sorted((DATA / "valid").glob("*.txt"))
INVALID = sorted((DATA / "invalid").glob("*.txt"))


def _r(x: Any) -> Any:
    """Round floats (recursively) so JSON expectations are stable."""
    if isinstance(x, float):
        return round(x, 9) + 0.0
    if isinstance(x, (tuple, list)):
        return [_r(v) for v in x]
    return x


def summary(scene: m.Scene) -> dict[str, Any]:
    """The facts a corpus file pins: every block's values, each primitive with material and to_world."""
    def prim(p: m.Placed) -> dict[str, Any]:
        obj = p.primitive
        d: dict[str, Any] = {"type": type(obj).__name__, "material": obj.material, "line": obj.loc.line}
        for k in ("center", "radius", "normal", "offset", "vertex0", "vertex1", "vertex2", "obj_file"):
            if hasattr(obj, k):
                d[k] = _r(getattr(obj, k))
        d["to_world"] = _r(p.to_world.tolist())
        return d

    def light(li: m.Light) -> dict[str, Any]:
        if isinstance(li, m.DirectionalLight):
            return {"type": "directional", "direction": _r(li.direction), "color": _r(li.color)}
        return {"type": "point", "position": _r(li.position), "color": _r(li.color), "falloff": _r(li.falloff)}

    def material(mt: m.Material) -> dict[str, Any]:
        d = {k: _r(getattr(mt, k)) for k in ("diffuse_color", "specular_color", "shininess", "refraction_index",
                                            "texture", "bump")}
        if mt.noise is not None:
            n = mt.noise
            d["noise"] = {k: _r(getattr(n, k)) for k in ("color1", "color2", "octaves", "frequency", "amplitude")}
        return d

    cam, bg = scene.camera, scene.background
    return {
        "camera": {k: _r(getattr(cam, k)) for k in ("center", "direction", "up", "angle")},
        "lights": [light(li) for li in scene.lights],
        "background": {"color": _r(bg.color), "ambient_light": _r(bg.ambient_light), "cube_map": bg.cube_map},
        "ambient": _r(scene.ambient),
        "materials": [material(mt) for mt in scene.materials],
        "objects": [prim(p) for p in scene.objects],
        "warnings": [f"{loc.line}:{loc.col}: {msg}" for loc, msg in scene.warnings],
    }


def test_corpus_globs_found_files() -> None:
    assert len(VALID) >= 5 and len(INVALID) >= 40


@pytest.mark.parametrize("path", VALID, ids=[p.stem for p in VALID])
def test_a_valid_corpus(path: Path) -> None:
    expected = json.loads(path.with_suffix(".json").read_text())
    assert summary(parse_file(path)) == expected


@pytest.mark.parametrize("path", INVALID, ids=[p.stem for p in INVALID])
def test_a_invalid_corpus(path: Path) -> None:
    expected = path.with_suffix(".err").read_text().strip()
    with pytest.raises(SceneError) as e:
        parse_file(path)
    assert str(e.value) == f"{path}:{expected}"
    assert e.value.loc is not None and e.value.loc.path == str(path)


# ----------------------------------------------------------------------------------- targeted rules
def test_a6_material_index_is_sequential_through_nested_groups() -> None:
    scene = parse_file(DATA / "valid" / "repeated_block_and_material_scoping.txt")
    # MaterialIndex 0 inside the nested group still holds for the Plane after the group closes.
    assert [p.primitive.material for p in scene.objects] == [0, 0, 1]


def test_a6_translate_then_scale_applies_the_scale_first() -> None:
    scene = parse_file(DATA / "valid" / "repeated_block_and_material_scoping.txt")
    sphere = scene.objects[0]
    # Translate(1,0,0) * Scale(2): the sphere's centre (1,0,0) lands on 2*1 + 1 = 3.
    assert transform_points(sphere.to_world, np.array([1.0, 0, 0])).tolist() == [3.0, 0.0, 0.0]


def test_a1_repeated_block_replaces_and_warns() -> None:
    scene = parse_file(DATA / "valid" / "repeated_block_and_material_scoping.txt")
    assert scene.camera.angle == 45.0
    assert any("second PerspectiveCamera block replaces the one at line 1" in w for _, w in scene.warnings)


def test_a1_no_lights_forces_ambient_to_one() -> None:
    scene = parse_file(DATA / "valid" / "no_lights.txt")
    assert scene.background.ambient_light == (0.2, 0.2, 0.2)
    assert scene.ambient == (1.0, 1.0, 1.0)
    assert scene.warnings[0][1].startswith("no Lights block")


def test_a0_file_name_not_ending_in_txt_is_accepted_with_a_warning(tmp_path: Path) -> None:
    p = tmp_path / "scene.scn"
    p.write_text((DATA / "valid" / "minimal.txt").read_text())
    scene = parse_file(p)
    assert scene.warnings[0] == (FileLoc(str(p), 1, 1),
                                 "scene file name does not end in '.txt' (the sample solution refuses it)")


def test_a5_defaults() -> None:
    text = (DATA / "valid" / "minimal.txt").read_text().replace(
        "Material { diffuseColor 1 0 0 }", "Material { }").replace("Lights", "Background { } Lights", 1)
    scene = parse_text(text, "t.txt")
    mt = scene.materials[0]
    assert (mt.diffuse_color, mt.specular_color, mt.shininess, mt.refraction_index) == ((1, 1, 1), (0, 0, 0), 0, 0)
    assert (scene.background.color, scene.background.ambient_light) == ((0.5, 0.5, 0.5), (0.0, 0.0, 0.0))
    assert mt.loc == FileLoc("t.txt", 16, 5)


def test_parse_text_rejects_bytes() -> None:
    with pytest.raises(TypeError, match="expects str, not bytes"):
        parse_text(b"Group { }")  # type: ignore[arg-type]


def test_error_types_split_syntax_and_semantics() -> None:
    with pytest.raises(SceneSyntaxError):
        parse_file(DATA / "invalid" / "word_for_number.txt")
    with pytest.raises(SceneSemanticError) as e:
        parse_file(DATA / "invalid" / "material_index_off_by_one.txt")
    assert e.value.source_line == "    MaterialIndex 2"


# ------------------------------------------------------------------------------------ shipped scenes
SCENE_FACTS = {
    # name: (lights, materials, objects, primitive types)
    "scene01_plane": (1, 4, 6, ["Sphere"] * 5 + ["Plane"]),
    "scene02_cube": (1, 1, 1, ["TriangleMesh"]),
    "scene03_sphere": (1, 1, 1, ["Sphere"]),
    "scene04_axes": (1, 4, 4, ["TriangleMesh"] * 4),
    "scene05_bunny_200": (2, 1, 1, ["TriangleMesh"]),
    "scene06_bunny_1k": (1, 1, 2, ["TriangleMesh", "Plane"]),
    "scene07_shine": (1, 9, 9, ["Sphere"] * 9),
    "scene08_c": (2, 4, 4, ["TriangleMesh"] * 3 + ["Plane"]),
    "scene09_s": (2, 3, 3, ["TriangleMesh", "TriangleMesh", "Plane"]),
    "scene10_sphere": (2, 3, 4, ["Sphere", "Sphere", "TriangleMesh", "Plane"]),
    "scene11_cube": (2, 4, 4, ["Plane"] + ["TriangleMesh"] * 3),
    "scene12_vase": (2, 2, 2, ["TriangleMesh", "Plane"]),
    "scene13_diamond": (3, 2, 2, ["TriangleMesh", "Plane"]),
}


@pytest.mark.parametrize("name", sorted(SCENE_FACTS))
def test_a_shipped_scene_counts(scenes_dir: Path, name: str) -> None:
    scene = parse_file(scenes_dir / f"{name}.txt")
    n_lights, n_mats, n_objs, types = SCENE_FACTS[name]
    assert (len(scene.lights), len(scene.materials), len(scene.objects)) == (n_lights, n_mats, n_objs)
    assert [type(p.primitive).__name__ for p in scene.objects] == types


def test_a_shipped_scene01_values_and_glued_brace(scenes_dir: Path) -> None:
    scene = parse_file(scenes_dir / "scene01_plane.txt")
    assert scene.materials[3].shininess == 20.0 and scene.materials[3].specular_color == (1.0, 1.0, 1.0)
    assert [p.primitive.material for p in scene.objects] == [0, 1, 1, 2, 2, 3]
    assert len(scene.warnings) == 1 and scene.warnings[0][0].line == 32


def test_a_shipped_scene03_transform(scenes_dir: Path) -> None:
    """ZRotate 45 then Scale 1 0.2 1: (1,0,0) -> scale (1,0,0) -> rotate (cos45, sin45, 0)."""
    scene = parse_file(scenes_dir / "scene03_sphere.txt")
    p = transform_points(scene.objects[0].to_world, np.array([1.0, 0, 0]))
    assert np.allclose(p, [math.sqrt(0.5), math.sqrt(0.5), 0.0], atol=1e-15)
    q = transform_points(scene.objects[0].to_world, np.array([0.0, 1, 0]))
    assert np.allclose(q, [-0.2 * math.sqrt(0.5), 0.2 * math.sqrt(0.5), 0.0], atol=1e-15)


def test_a_shipped_scene10_noise_and_lights(scenes_dir: Path) -> None:
    scene = parse_file(scenes_dir / "scene10_sphere.txt")
    noise = scene.materials[2].noise
    assert noise is not None
    assert (noise.color1, noise.color2, noise.octaves, noise.frequency, noise.amplitude) == (
        (0.1, 0.2, 0.3), (0.3, 0.4, 0.5), 4, 2.0, 4.0)
    assert isinstance(scene.lights[1], m.PointLight) and scene.lights[1].falloff == 0.0
    assert scene.background.cube_map == "tex/church"
    plane = scene.objects[3].primitive
    assert isinstance(plane, m.Plane) and (plane.normal, plane.offset) == ((0.0, 1.0, 0.0), -1.0)
    # cube: Translate(1, .5, -3.5) * Scale(.8): corner (1,1,1) -> (1.8, 1.3, -2.7)
    assert np.allclose(transform_points(scene.objects[2].to_world, np.array([1.0, 1, 1])), [1.8, 1.3, -2.7])


def test_a_shipped_scene11_transform_chain(scenes_dir: Path) -> None:
    """Translate(-0.8,0,-2) * Scale(.25,1,.25) * YRotate(45) * Translate(0,1,0) on the cube corner (1,1,1)."""
    scene = parse_file(scenes_dir / "scene11_cube.txt")
    p = transform_points(scene.objects[1].to_world, np.array([1.0, 1, 1]))
    # Translate: (1,2,1); YRotate 45: x = c*1 + s*1 = sqrt2, z = -s + c = 0; Scale: (.25 sqrt2, 2, 0); shift.
    assert np.allclose(p, [-0.8 + 0.25 * math.sqrt(2), 2.0, -2.0], atol=1e-12)
    assert scene.lights[1] == m.PointLight((-2.0, 0.8, -2.0), (0.9, 0.9, 0.9), 0.1, scene.lights[1].loc)


def test_a_shipped_sibenik(a5_data: Path) -> None:
    scene = parse_file(a5_data / "extras" / "sibenik" / "s.txt")
    assert (len(scene.lights), len(scene.materials), len(scene.objects)) == (2, 15, 15)
    assert scene.materials[2].texture == "tex/kamen.bmp" and scene.materials[2].bump == "bump/kamen.bmp"
    assert [p.primitive.material for p in scene.objects] == list(range(15))
    assert scene.warnings == ()


# ------------------------------------------------------------------------------------ fuzzing
def _fuzz_sources() -> list[tuple[str, list[str]]]:
    from a5mi import data_dir

    root = data_dir()
    files = sorted((root / "scenes").glob("*.txt")) + sorted(VALID)
    return [(p.name, p.read_text().split()) for p in files]


FUZZ_SOURCES = _fuzz_sources()
FUZZ_WORDS = ["{", "}", "0", "-1", "1e999", "nan", "inf", "abc", "#", "1}", "{x", "Group", "Sphere", "Transform",
              "MaterialIndex", "numObjects", "Noise", "color", "Matrix4f", "Rotate", "99999999999", "\x00", "é"]


def test_fuzz_mutated_scenes_raise_only_scene_errors_with_positions() -> None:
    """2,000+ mutations (delete, duplicate, swap, replace, truncate tokens) of the real scenes: the parser
    either succeeds or raises SceneError with a position inside the text; never any other exception."""
    from conftest import examples
    from hypothesis import given, settings
    from hypothesis import strategies as st

    @st.composite
    def mutated(draw: st.DrawFn) -> str:
        _, words = draw(st.sampled_from(FUZZ_SOURCES))
        words = list(words)
        for _ in range(draw(st.integers(1, 3))):
            if not words:
                break
            i = draw(st.integers(0, len(words) - 1))
            op = draw(st.sampled_from(["delete", "duplicate", "swap", "replace", "truncate"]))
            if op == "delete":
                del words[i]
            elif op == "duplicate":
                words.insert(i, words[i])
            elif op == "swap":
                j = draw(st.integers(0, len(words) - 1))
                words[i], words[j] = words[j], words[i]
            elif op == "replace":
                words[i] = draw(st.sampled_from(FUZZ_WORDS))
            else:
                words = words[:i]
        return "\n".join(" ".join(words[k:k + 7]) for k in range(0, len(words), 7))

    count = 0

    @settings(max_examples=examples(2000))
    @given(mutated())
    def check(text: str) -> None:
        nonlocal count
        count += 1
        try:
            parse_text(text, "fuzz.txt")
        except SceneError as e:
            assert e.loc is not None and e.loc.path == "fuzz.txt"
            assert 1 <= e.loc.line <= text.count("\n") + 1 and e.loc.col >= 1
            assert str(e).startswith(f"{e.loc}: error: ")

    check()
    assert count >= examples(2000)


_CAMERA = "PerspectiveCamera { center 0 0 10 direction 0 0 -1 up 0 1 0 angle 30 }\n"
_TWO_MATERIALS = "Materials { numMaterials 2 Material { diffuseColor 1 0 0 } Material { diffuseColor 0 1 0 } }\n"


def test_a1_materials_after_the_group_keep_the_groups_materials() -> None:
    """The binary's primitives point at the materials they were parsed with: a later Materials block does
    not change the rendered group (warned)."""
    text = (_CAMERA + _TWO_MATERIALS + "Group { numObjects 1 MaterialIndex 1 Sphere { center 0 0 0 radius 1 } }\n"
            "Materials { numMaterials 1 Material { diffuseColor 0 0 1 } }\n")
    scene = parse_text(text, "s.txt")
    assert len(scene.materials) == 2 and scene.materials[1].diffuse_color == (0.0, 1.0, 0.0)
    assert any("keeps the materials it was parsed with" in msg for _, msg in scene.warnings)


def test_a6_current_material_persists_into_a_later_group_block() -> None:
    """A.6: one global current material; a second Group block (which replaces the first) still has it."""
    text = (_CAMERA + _TWO_MATERIALS + "Group { numObjects 1 MaterialIndex 1 Sphere { center 0 0 0 radius 1 } }\n"
            "Group { numObjects 1 Sphere { center 1 0 0 radius 1 } }\n")
    scene = parse_text(text, "s.txt")
    (sphere,) = scene.root.children
    assert sphere.center == (1.0, 0.0, 0.0) and sphere.material == 1


# ----------------------------------------------------------------------------------- rules and builders
def test_a5_a6_builders_start_from_the_model_defaults() -> None:
    """A block's builder starts from the SPEC defaults its frozen entity has (an empty block builds exactly
    the default entity), and the material builder carries every field of the model's Material and no other."""
    import dataclasses

    from a5mi.converters import builders as b

    loc = FileLoc("s.txt", 1, 1)
    assert b.MaterialBuilder(loc).build() == m.Material(loc=loc)
    full = b.MaterialBuilder(loc)
    for i, f in enumerate(dataclasses.fields(m.Material)):
        setattr(full, f.name, i)  # a value of its own per field: build() passes every one
    assert dataclasses.astuple(full.build()) == tuple(range(len(dataclasses.fields(m.Material))))
    with pytest.raises(AttributeError):
        full.colour = (1.0, 0.0, 0.0)  # type: ignore[attr-defined]  # not a field of Material
    assert b.BackgroundBuilder().build(loc) == m.Background(loc=loc)
    assert b.NoiseBuilder().build(loc) == m.Noise(loc=loc)
    two = [(1.0, 0.0, 0.0), (0.0, 0.0, 1.0)]
    assert b.SolidBuilder("Wood", "wood", colors=list(two)).build(loc) == m.Solid("wood", *two, loc=loc)
    assert b.PointLightBuilder().build(loc) == m.PointLight((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 0.0, loc)
    assert b.SceneBuilder().background == m.Scene("s.txt", m.Camera((0, 0, 0), (0, 0, -1), (0, 1, 0), 30.0,
                                                                       loc)).background


def test_a5_every_material_keyword_has_a_rule_and_is_listed() -> None:
    """The Material rule table is what the error message lists, the course's keywords (A.5) first, then the
    extensions' (docs/EXTENSIONS.md E.4, E.6, E.7), and each keyword reaches its rule."""
    from a5mi.converters.a5_parser import MATERIAL_RULES

    course = ("diffuseColor", "specularColor", "shininess", "refractionIndex", "texture", "bump", "Noise")
    assert tuple(MATERIAL_RULES)[:7] == course
    text = (_CAMERA + "Materials { numMaterials 1 Material { diffuseColor 0.1 0.2 0.3 specularColor 1 1 1 "
            "shininess 5 refractionIndex 1.5 texture t.png bump b.png roughness 0.25 glossySamples 4 "
            "bumpScale 0.5 normalMap n.png Wood { color 1 0 0 color 0 1 0 } } }\n"
            "Group { numObjects 0 }")
    mat = parse_text(text).materials[0]
    assert (mat.diffuse_color, mat.specular_color, mat.shininess, mat.refraction_index) == (
        (0.1, 0.2, 0.3), (1.0, 1.0, 1.0), 5.0, 1.5)
    assert (mat.texture, mat.bump, mat.normal_map, mat.bump_scale) == ("t.png", "b.png", "n.png", 0.5)
    assert (mat.roughness, mat.glossy_samples, mat.solid.kind if mat.solid else None) == (0.25, 4, "wood")
    with pytest.raises(SceneSyntaxError) as err:
        parse_text(_CAMERA + "Materials { numMaterials 1 Material { shine 1 } }")
    assert err.value.msg == ("unknown Material keyword 'shine' (expected " + ", ".join(MATERIAL_RULES)
                             + " or '}')")

"""The error policy through the real command line (docs/CLI.md "Exit status"): every class of bad input is one
line, exit 2, and nothing is lost; an internal error is one line and exit 70.

Each case is its own ``python -m a5mi ...`` process (cwd = the test's tmp folder), so the real exit path is
tested: the exit status, ``stderr`` being exactly one line (``FILE:LINE:COL: error: ...`` for scene and OBJ
errors, ``a5: error: ...`` for the command line), no ``Traceback``, and the folder afterwards holding exactly
what it held before, byte for byte: no output and no temporary file appears, and pre-existing ``-output``,
``-normals`` and ``-depth`` images are untouched. Scene cases alternate between a folder without outputs and
one where all three outputs already exist.

Expected positions are computed from the scene text (:func:`loc_of`), not copied from the program's output;
the invalid corpus (tests/data/invalid, 52 scenes) is checked against its ``.err`` files line for line.
Errors found before rendering never import Mitsuba (checked in :func:`test_errors_before_rendering_do_not_
import_mitsuba`), which keeps each process near 0.1 s.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest
from helpers import TESTS

INVALID = TESTS / "data" / "invalid"
OUTPUTS = ("out.png", "n.png", "d.png")
AOV_FLAGS = ("-normals", "n.png", "-depth", "9", "10", "d.png")

HEAD = """PerspectiveCamera {
    center 0 0 10
    direction 0 0 -1
    up 0 1 0
    angle 30
}
Lights {
    numLights 1
    DirectionalLight { direction 0 0 -1 color 1 1 1 }
}
"""
ONE_MATERIAL = "Materials { numMaterials 1 Material { diffuseColor 1 0 0 } }\n"
SPHERE = "Group { numObjects 1 MaterialIndex 0 Sphere { center 0 0 0 radius 1 } }\n"
TRIANGLE_OBJ = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"
UV_OBJ = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nf 1/1 2/2 3/3\n"
FACES = ("left", "right", "up", "down", "front", "back")


def loc_of(text: str, needle: str, nth: int = 1) -> str:
    """``LINE:COL`` (1-based) of the ``nth`` occurrence of ``needle`` in ``text``."""
    pos = -1
    for _ in range(nth):
        pos = text.index(needle, pos + 1)
    line = text.count("\n", 0, pos) + 1
    return f"{line}:{pos - (text.rfind(chr(10), 0, pos) + 1) + 1}"


def mesh_scene(obj: str, material: str = ONE_MATERIAL) -> str:
    return HEAD + material + f"Group {{ numObjects 1 MaterialIndex 0 TriangleMesh {{ obj_file {obj} }} }}\n"


def textured_scene(texture: str) -> str:
    return mesh_scene("uv.obj", f"Materials {{ numMaterials 1 Material {{ texture {texture} }} }}\n")


def cubemap_scene(folder: str) -> str:
    return HEAD + f"Background {{ cubeMap {folder} }}\n" + ONE_MATERIAL + SPHERE


def bmp_bytes(size: int = 8) -> bytes:
    """A valid 24-bit BMP (``size`` x ``size``, grey) written by the project's own writer."""
    import tempfile

    from a5mi.platform.imageio import write_image

    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "t.bmp"
        write_image(p, np.full((size, size, 3), 0.5, np.float32))
        return p.read_bytes()


BMP = bmp_bytes()


@dataclass
class Case:
    """Files to create (name -> text or bytes), the argument list, and the one expected stderr line.

    ``expect`` is the exact line, or, ending in ``...``, its exact beginning."""

    id: str
    files: dict[str, str | bytes]
    args: list[str]
    expect: str
    setup: Callable[[Path], None] | None = None
    aovs: bool = field(default=True)  # pass -normals n.png -depth 9 10 d.png


def scene_case(id_: str, text: str, expect: str, extra: dict[str, str | bytes] | None = None,
               setup: Callable[[Path], None] | None = None) -> Case:
    """A scene ``s.txt`` rendered to out.png (+ AOVs); ``expect`` is ``"s.txt:" + expect`` unless it names
    another file (``"m.obj:..."``)."""
    line = expect if re.match(r"^[\w.]+\.(obj|txt):", expect) else f"s.txt:{expect}"
    return Case(id_, {"s.txt": text, **(extra or {})}, ["-input", "s.txt", "-output", "out.png", "-size", "8", "8"],
                line, setup)


def _cube_folder(name: str, faces: dict[str, bytes]) -> Callable[[Path], None]:
    def make(root: Path) -> None:
        (root / name).mkdir()
        for face, data in faces.items():
            (root / name / f"{face}.bmp").write_bytes(data)

    return make


def _file_cases() -> list[Case]:
    """Classes the parser cannot see: meshes, OBJ content, textures, cube maps, degenerate camera."""
    cases: list[Case] = []
    t = mesh_scene("nope.obj")
    cases.append(scene_case("mesh_missing", t, f"{loc_of(t, 'nope.obj')}: error: obj_file file 'nope.obj' not "
                            "found ..."))
    t = mesh_scene("dir.obj")
    cases.append(scene_case("mesh_is_a_folder", t, f"{loc_of(t, 'dir.obj')}: error: obj_file 'dir.obj' is a folder, "
                            "not a file ...", setup=lambda root: (root / "dir.obj").mkdir()))
    t = mesh_scene("m.obj")
    garbage = bytes(range(256)) * 8
    cases.append(scene_case("mesh_binary_garbage", t, f"{loc_of(t, 'm.obj')}: error: expected at least one 'f' face "
                            "in mesh file ...", {"m.obj": garbage}))
    cases.append(scene_case("obj_face_index_out_of_range", t, "m.obj:4:7: error: face index 4 out of range: expected 1 "
                            "to 3 (3 vertices)", {"m.obj": "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n"}))
    cases.append(scene_case("obj_face_index_zero", t, "m.obj:4:3: error: face index 0 out of range: expected 1 to 3 "
                            "(3 vertices)", {"m.obj": "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n"}))
    huge = "99999999999999999999"
    cases.append(scene_case("obj_face_index_huge", t, f"m.obj:4:7: error: face index out of range: '{huge}'",
                            {"m.obj": f"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 {huge}\n"}))
    cases.append(scene_case("obj_nan_vertex", t, "m.obj:2:5: error: expected a finite number in a vertex coordinate, "
                            "found 'nan'", {"m.obj": "v 0 0 0\nv 1 nan 0\nv 0 1 0\nf 1 2 3\n"}))
    cases.append(scene_case("obj_vertex_beyond_float32", t, "m.obj:3:3: error: vertex coordinate out of range: "
                            "'1e39'", {"m.obj": "v 0 0 0\nv 1 0 0\nv 1e39 1 0\nf 1 2 3\n"}))
    cases.append(scene_case("obj_word_for_index", t, "m.obj:4:5: error: expected a face index, found 'b'",
                            {"m.obj": "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 b 3\n"}))

    for name, data, reason in [
        ("garbage.bmp", b"this is not a bitmap " * 20, "'garbage.bmp' is not a readable image: ..."),
        ("truncated.bmp", BMP[: len(BMP) - 100], "'truncated.bmp' is not a readable image: ..."),
        ("empty.bmp", b"", "'empty.bmp' is not a readable image: the file is empty"),
    ]:
        t = textured_scene(name)
        cases.append(scene_case(f"texture_{name.split('.')[0]}", t, f"{loc_of(t, name)}: error: texture {reason}",
                                {"uv.obj": UV_OBJ, name: data}))
    t = textured_scene("nope.bmp")
    cases.append(scene_case("texture_missing", t, f"{loc_of(t, 'nope.bmp')}: error: texture file 'nope.bmp' not "
                            "found ...", {"uv.obj": UV_OBJ}))

    t = cubemap_scene("cm")
    at = loc_of(t, "cm")
    good = dict.fromkeys(FACES, BMP)
    cases.append(scene_case("cubemap_missing", t, f"{at}: error: cubeMap folder 'cm' not found ..."))
    cases.append(scene_case("cubemap_is_a_file", t, f"{at}: error: cubeMap 'cm' is a file, not a folder ...",
                            {"cm": "not a folder"}))
    cases.append(scene_case("cubemap_missing_one_face", t, f"{at}: error: cubeMap folder 'cm' has no 'down' face "
                            "(expected down.bmp or down.png)",
                            setup=_cube_folder("cm", {k: v for k, v in good.items() if k != "down"})))
    cases.append(scene_case("cubemap_garbage_face", t, f"{at}: error: cubeMap face 'cm/up.bmp' is not a readable "
                            "image: ...", setup=_cube_folder("cm", {**good, "up": b"BM" + b"\x00" * 80})))
    cases.append(scene_case("cubemap_truncated_face", t, f"{at}: error: cubeMap face 'cm/back.bmp' is not a "
                            "readable image: ...", setup=_cube_folder("cm", {**good, "back": BMP[:100]})))

    t = HEAD.replace("direction 0 0 -1\n    up", "direction 0 0 0\n    up") + ONE_MATERIAL + SPHERE
    cases.append(scene_case("camera_zero_direction", t, f"{loc_of(t, 'direction')}: error: camera direction must "
                            "not be the zero vector"))
    t = HEAD + ONE_MATERIAL + "Group { numObjects 1 MaterialIndex 0 Plane { normal 0 0 0 offset 1 } }\n"
    cases.append(scene_case("plane_zero_normal_inline", t, f"{loc_of(t, 'normal')}: error: Plane normal must not be "
                            "the zero vector"))
    t = HEAD + "Materials { numMaterials 1 Material { Noise { color 1 0 0 color 0 1 0 color 0 0 1 } } }\n" + SPHERE
    cases.append(scene_case("noise_third_color_inline", t, f"{loc_of(t, 'color', 4)}: error: Noise takes two "
                            "colors, found a third 'color'"))
    t = HEAD + "Materials { numMaterials 3000000000 }\n" + SPHERE
    cases.append(scene_case("num_materials_beyond_int", t, f"{loc_of(t, '3000000000')}: error: integer out of range "
                            "after 'numMaterials': '3000000000'"))
    t = HEAD.replace("numLights 1", "numLights 2000000000") + ONE_MATERIAL + SPHERE
    cases.append(scene_case("num_lights_huge", t, f"{loc_of(t, '}', 3)}: error: Lights declares numLights "
                            "2000000000 but has 1 light, found '}'"))
    t = HEAD + ONE_MATERIAL + ("Group { numObjects 1 MaterialIndex 0 Transform { Scale 1e30 1e30 1e30\n"
                               "  Triangle { vertex0 0 0 0 vertex1 1e10 0 0 vertex2 0 1 0 } } }\n")
    cases.append(scene_case("absurd_after_transform", t, f"{loc_of(t, 'Triangle')}: error: Triangle is out of "
                            "float32 range in world space (the enclosing Transforms scale it beyond 3.4e38)"))
    nest = "Transform { UniformScale 1e-20 " * 3
    t = HEAD + ONE_MATERIAL + f"Group {{ numObjects 1 MaterialIndex 0 {nest}Sphere {{ center 0 0 0 radius 1 }}" + (
        " }" * 3) + " }\n"
    cases.append(scene_case("nested_transforms_singular", t, f"{loc_of(t, 'Sphere')}: error: Sphere is placed by "
                            "nested Transforms whose product is singular"))
    bom = b"\xef\xbb\xbf" + (HEAD + ONE_MATERIAL + SPHERE).encode()
    cases.append(scene_case("utf8_byte_order_mark", "", "1:1: error: expected scene text, found a UTF-8 byte-order "
                            "mark (save the file without BOM)", {"s.txt": bom}))
    return cases


def _corpus_cases() -> list[Case]:
    """Every scene of tests/data/invalid with its exact message (the ``.err`` file: ``LINE:COL: error: ...``)."""
    cases = []
    for txt in sorted(INVALID.glob("*.txt")):
        expect = (txt.with_suffix(".err")).read_text().strip()
        cases.append(Case(txt.stem, {txt.name: txt.read_bytes()},
                          ["-input", txt.name, "-output", "out.png", "-size", "8", "8"], f"{txt.name}:{expect}"))
    return cases


def _usage_cases() -> list[Case]:
    """Command-line misuse: ``a5: error: ...`` (the scene is valid, so only the flags can fail)."""
    ok = {"s.txt": HEAD + ONE_MATERIAL + SPHERE}
    base = ["-input", "s.txt", "-output", "out.png"]

    def c(id_: str, args: list[str], expect: str, setup: Callable[[Path], None] | None = None,
          aovs: bool = True) -> Case:
        return Case(id_, dict(ok), args, expect, setup, aovs)

    return [
        c("missing_input", ["-output", "out.png"], "a5: error: missing -input SCENE.txt", aovs=False),
        c("missing_output", ["-input", "s.txt"], "a5: error: missing -output IMG", aovs=False),
        c("no_arguments", [], "a5: error: missing -input SCENE.txt", aovs=False),
        c("size_zero", base + ["-size", "0", "8"], "a5: error: -size expects an integer in [1, 16384], found 0"),
        c("size_negative", base + ["-size", "8", "-3"], "a5: error: -size expects an integer in [1, 16384], found -3"),
        c("size_too_large", base + ["-size", "100000", "8"],
          "a5: error: -size expects an integer in [1, 16384], found 100000"),
        c("size_too_many_samples", base + ["-size", "16384", "16384", "-jitter"], "a5: error: -size 16384 16384 with "
          "-jitter is 2415919104 samples; the limit is 268435456"),
        c("size_not_a_number", base + ["-size", "ten", "8"], "a5: error: -size expects an integer, found 'ten'"),
        c("size_missing_value", base + ["-size", "8"], "a5: error: -size expects 2 values, found end of arguments",
          aovs=False),
        c("bounces_negative", base + ["-bounces", "-1"], "a5: error: -bounces expects an integer in [0, 64], found -1"),
        c("unknown_flag", base + ["-frobnicate"], "a5: error: unknown flag '-frobnicate' (see a5 -h)"),
        c("stray_argument", base + ["extra.txt"], "a5: error: unexpected argument 'extra.txt' (flags take the form "
          "-input F.txt; see a5 -h)"),
        c("depth_not_a_number", base + ["-depth", "1", "far", "d.png"], "a5: error: -depth expects a number, found "
          "'far'", aovs=False),
        c("output_folder_missing", ["-input", "s.txt", "-output", "nodir/out.png"],
          "a5: error: nodir/out.png: output folder 'nodir' does not exist"),
        c("output_folder_is_a_file", ["-input", "s.txt", "-output", "plain/out.png"],
          "a5: error: plain/out.png: output folder 'plain' is not a folder: 'plain' is a file",
          setup=lambda root: (root / "plain").write_text("a regular file")),
        c("output_under_a_file_deeper", ["-input", "s.txt", "-output", "plain/sub/out.png"],
          "a5: error: plain/sub/out.png: output folder 'plain/sub' is not a folder: 'plain' is a file",
          setup=lambda root: (root / "plain").write_text("a regular file")),
        c("output_is_a_folder", ["-input", "s.txt", "-output", "img.png"], "a5: error: img.png: is a directory",
          setup=lambda root: (root / "img.png").mkdir()),
        c("output_unknown_extension", ["-input", "s.txt", "-output", "out.jpg"], "a5: error: out.jpg: unknown image "
          "extension '.jpg' (expected one of .bmp .exr .png .ppm .tga .tif .tiff)"),
        c("output_no_extension", ["-input", "s.txt", "-output", "out"], "a5: error: out: no image extension "
          "(expected one of .bmp .exr .png .ppm .tga .tif .tiff)"),
        c("normals_unknown_extension", ["-input", "s.txt", "-output", "out.png", "-normals", "n.gif"],
          "a5: error: n.gif: unknown image extension '.gif' (expected one of .bmp .exr .png .ppm .tga .tif .tiff)",
          aovs=False),
        c("depth_folder_missing", ["-input", "s.txt", "-output", "out.png", "-depth", "1", "2", "no/d.png"],
          "a5: error: no/d.png: output folder 'no' does not exist", aovs=False),
        c("same_output_twice", ["-input", "s.txt", "-output", "out.png", "-normals", "./out.png"],
          "a5: error: -output 'out.png' and -normals './out.png' are the same file", aovs=False),
        Case("input_missing", {}, ["-input", "nope.txt", "-output", "out.png"],
             "nope.txt:1:1: error: cannot read scene file: No such file or directory"),
        Case("input_is_a_folder", {}, ["-input", "sub", "-output", "out.png"],
             "sub:1:1: error: cannot read scene file: not a regular file (folder)",
             lambda root: (root / "sub").mkdir()),
    ]


ERROR_CASES = _corpus_cases() + _file_cases() + _usage_cases()


def run_a5(cwd: Path, args: list[str]) -> subprocess.CompletedProcess[str]:
    """``python -m a5mi ARGS`` in ``cwd`` (the real ``__main__``, a fresh process)."""
    env = {**os.environ, "PYTHONWARNINGS": "default"}  # a stray Python warning would show as a second line
    return subprocess.run([sys.executable, "-m", "a5mi", *args], cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=120)


def snapshot(root: Path) -> dict[str, bytes | None]:
    """Every path under ``root`` -> its bytes (None for a folder)."""
    return {str(p.relative_to(root)): (None if p.is_dir() else p.read_bytes()) for p in sorted(root.rglob("*"))}


def one_error_line(proc: subprocess.CompletedProcess[str]) -> str:
    """The single stderr line of a failed run (asserting there is exactly one and no traceback anywhere)."""
    assert "Traceback" not in proc.stderr + proc.stdout, proc.stderr
    lines = proc.stderr.splitlines()
    assert len(lines) == 1, proc.stderr
    assert proc.stdout == "", proc.stdout
    return lines[0]


def check_line(line: str, expect: str) -> None:
    if expect.endswith("..."):
        assert line.startswith(expect[:-3]), f"{line!r} does not start with {expect[:-3]!r}"
    else:
        assert line == expect


def test_cases_cover_every_class() -> None:
    """The classes of user error (SPEC A.0-A.6, B.1), each present among the case ids (a guard against a case
    list shrinking)."""
    ids = {c.id for c in ERROR_CASES}
    required = {
        "unknown_top_level", "unknown_light", "unknown_background_keyword", "unknown_material_keyword",
        "unknown_object", "unknown_transform_keyword", "missing_closing_brace", "stray_closing_brace",
        "stray_token_after_last_block", "word_for_number", "nan_number", "inf_number", "absurd_number",
        "truncated_mid_block", "truncated_mid_number", "empty_file", "binary_file", "latin1_file",
        "num_objects_too_few", "num_lights_mismatch", "num_materials_mismatch", "num_objects_huge",
        "num_lights_huge", "material_index_off_by_one", "material_index_missing", "noise_third_color",
        "matrix4f_too_few_numbers", "mesh_missing", "mesh_binary_garbage", "texture_missing", "texture_garbage",
        "texture_truncated", "cubemap_missing_one_face", "cubemap_garbage_face", "cubemap_truncated_face",
        "obj_face_index_out_of_range", "obj_nan_vertex", "triangle_zero_area", "sphere_zero_radius",
        "plane_zero_normal", "camera_zero_direction", "camera_zero_up", "camera_up_parallel", "missing_input",
        "missing_output", "size_zero", "size_too_large", "bounces_negative", "unknown_flag",
        "output_folder_missing", "output_folder_is_a_file", "output_unknown_extension", "absurd_after_transform",
    }
    assert required <= ids, sorted(required - ids)
    assert len(ids) == len(ERROR_CASES)


@pytest.mark.parametrize(
    "case,preexisting",
    [(c, k % 2 == 1) for k, c in enumerate(ERROR_CASES)],
    ids=[c.id + ("+outputs" if k % 2 == 1 else "") for k, c in enumerate(ERROR_CASES)],
)
def test_user_error_is_one_line_exit_2_and_nothing_is_written(case: Case, preexisting: bool,
                                                                      tmp_path: Path) -> None:
    """Odd-numbered cases start with out.png, n.png and d.png present (sentinel bytes), even ones without."""
    for name, data in case.files.items():
        (tmp_path / name).write_bytes(data if isinstance(data, bytes) else data.encode())
    if case.setup is not None:
        case.setup(tmp_path)
    if preexisting:
        for k, name in enumerate(OUTPUTS):
            (tmp_path / name).write_bytes(BMP[:60] + bytes([k]) * 7)  # distinct sentinel bytes per file
    before = snapshot(tmp_path)
    args = case.args + (list(AOV_FLAGS) if case.aovs and "-output" in case.args else [])
    proc = run_a5(tmp_path, args)
    assert proc.returncode == 2, proc.stderr
    check_line(one_error_line(proc), case.expect)
    assert snapshot(tmp_path) == before  # no output, no temporary file, existing images byte-for-byte unchanged


# ------------------------------------------------------------------------------- no Mitsuba before rendering
_PROBE = """
import runpy, sys
sys.argv = ["a5mi", *sys.argv[1:]]
try:
    runpy.run_module("a5mi", run_name="__main__", alter_sys=True)
except SystemExit as exc:
    code = exc.code
print(" ".join(m for m in ("mitsuba", "drjit") if m in sys.modules) or "-")
sys.exit(code)
"""


@pytest.mark.parametrize("case_id", ["word_for_number", "mesh_missing", "obj_nan_vertex", "texture_truncated",
                                     "cubemap_missing_one_face", "unknown_flag", "output_folder_is_a_file"])
def test_errors_before_rendering_do_not_import_mitsuba(case_id: str, tmp_path: Path) -> None:
    """The ``__main__`` of ``python -m a5mi`` run in a probe process that reports the loaded modules: syntax,
    file and flag errors are found before Mitsuba / Dr.Jit are imported (the JIT costs ~0.4 s to start)."""
    case = next(c for c in ERROR_CASES if c.id == case_id)
    for name, data in case.files.items():
        (tmp_path / name).write_bytes(data if isinstance(data, bytes) else data.encode())
    if case.setup is not None:
        case.setup(tmp_path)
    proc = subprocess.run([sys.executable, "-c", _PROBE, *case.args], cwd=tmp_path, capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode == 2, proc.stderr
    assert proc.stdout.strip() == "-", proc.stdout  # stdout holds the probe's report of loaded modules
    assert "Traceback" not in proc.stderr and len(proc.stderr.splitlines()) == 1, proc.stderr
    check_line(proc.stderr.strip(), case.expect)


# ------------------------------------------------------------------------------- accepted, with warnings
def test_quirks_accepted_as_the_sample_solution_did_warn_and_exit_0(tmp_path: Path) -> None:
    """``numObjects`` counts objects, not ``MaterialIndex`` lines, and ``shininess 20}`` (scene01) is read as
    ``20 }``: both render (exit 0); the glued brace is the one warning, at the brace."""
    text = (HEAD + "Materials { numMaterials 2\n  Material { diffuseColor 1 0 0 shininess 20}\n"
            "  Material { diffuseColor 0 1 0 }\n}\n"
            "Group { numObjects 2\n  MaterialIndex 0\n  Sphere { center -1 0 0 radius 1 }\n"
            "  MaterialIndex 1\n  Sphere { center 1 0 0 radius 1 }\n}\n")
    (tmp_path / "s.txt").write_text(text)
    proc = run_a5(tmp_path, ["-input", "s.txt", "-output", "out.png", "-size", "6", "4"])
    assert proc.returncode == 0, proc.stderr
    brace = loc_of(text, "20}")
    brace = f"{brace.split(':')[0]}:{int(brace.split(':')[1]) + 2}"
    assert proc.stderr.splitlines() == [f"s.txt:{brace}: warning: '}}' glued to the number before it: read as two "
                                        "tokens, as the sample solution's %f does (SPEC A.0 asks for whitespace)"]
    from a5mi.platform.imageio import read_image

    assert read_image(tmp_path / "out.png").shape == (4, 6, 3)


def test_zero_area_obj_faces_warn_at_the_first_and_still_render(tmp_path: Path) -> None:
    """Zero-area OBJ faces are never hit (as in a5soln): one warning at the first such face, exit 0."""
    (tmp_path / "m.obj").write_text("v 0 0 0\nv 1 0 0\nv 2 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 4\nf 2 3 1\n")
    (tmp_path / "s.txt").write_text(mesh_scene("m.obj"))
    proc = run_a5(tmp_path, ["-input", "s.txt", "-output", "out.png", "-size", "4", "4"])
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.splitlines() == ["m.obj:5:3: warning: 2 zero-area faces (first here): never hit, as in the "
                                        "sample solution"]
    assert (tmp_path / "out.png").is_file()


# ------------------------------------------------------------------------------- internal errors
def test_internal_error_exit_70_short_message_and_debug_traceback(tmp_path: Path, monkeypatch, capsys) -> None:
    """A bug (here: the parser raising ZeroDivisionError) is exit 70 (EX_SOFTWARE) with one line and a --debug hint; an
    embedded traceback in the message (as Mitsuba's load_dict reports plugin failures) is cut; ``--debug``
    prints the traceback. A pre-existing output stays as it was."""
    from a5mi import cli
    from a5mi.converters import a5_parser
    from a5mi.platform.errors import ExitStatus

    def buggy(path: object) -> None:
        raise ZeroDivisionError("float division by zero\nTraceback (most recent call last):\n  File ...")

    monkeypatch.setattr(a5_parser, "parse_file", buggy)
    (tmp_path / "out.png").write_bytes(b"previous image")
    args = ["-input", "s.txt", "-output", str(tmp_path / "out.png")]
    assert cli.run(args) == ExitStatus.SOFTWARE == 70
    err = capsys.readouterr().err
    assert err.splitlines() == ["a5: internal error: ZeroDivisionError: float division by zero (re-run with --debug "
                                "for the traceback)"]
    assert cli.run(args + ["--debug"]) == ExitStatus.SOFTWARE
    err = capsys.readouterr().err
    assert err.startswith("Traceback (most recent call last):") and "ZeroDivisionError" in err
    assert (tmp_path / "out.png").read_bytes() == b"previous image"


# ------------------------------------------------------------------------------- fuzz past the parser
def test_fuzz_converter_stage_raises_only_positioned_scene_errors_and_no_warnings(scenes_dir: Path) -> None:
    """500 mutated course scenes (delete, duplicate, swap tokens; numbers replaced by extremes such as 0, -0,
    1e-45, 3.4e38; file names swapped) through the parser *and* :func:`describe` (OBJ loading, image
    validation, world-space geometry of every primitive): each either passes or raises SceneError with a
    position, and no Python/numpy warning is emitted (it would be a second stderr line in the CLI). The
    parser-only fuzz with 2,000 scenes is in tests/converters/test_parser.py."""
    import warnings

    from hypothesis import HealthCheck, given, settings
    from hypothesis import strategies as st

    from a5mi.converters.a5_parser import parse_text
    from a5mi.converters.describe import describe
    from a5mi.converters.errors import SceneError

    sources = [p.read_text().split() for p in sorted(scenes_dir.glob("*.txt"))]
    numbers = ["0", "-0", "1e-45", "1e-30", "3.4e38", "-3.4e38", "1e30", "-1", "0.5", "2"]
    words = ["cube.obj", "vase.obj", "tex/head.bmp", "tex/church", "tex", "nope.obj", "{", "}", "texture",
             "cubeMap", "Scale", "Matrix4f", "MaterialIndex", "Plane", "Sphere"]
    number_re = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")
    fuzz_path = str(scenes_dir / "fuzz.txt")

    @st.composite
    def mutated(draw: st.DrawFn) -> str:
        toks = list(draw(st.sampled_from(sources)))
        for _ in range(draw(st.integers(1, 3))):
            i = draw(st.integers(0, len(toks) - 1))
            op = draw(st.sampled_from(["number", "number", "number", "word", "delete", "duplicate", "swap"]))
            if op == "number":
                nums = [k for k, w in enumerate(toks) if number_re.fullmatch(w)]
                toks[draw(st.sampled_from(nums))] = draw(st.sampled_from(numbers))
            elif op == "word":
                toks[i] = draw(st.sampled_from(words))
            elif op == "delete" and len(toks) > 1:
                del toks[i]
            elif op == "duplicate":
                toks.insert(i, toks[i])
            else:
                j = draw(st.integers(0, len(toks) - 1))
                toks[i], toks[j] = toks[j], toks[i]
        return "\n".join(" ".join(toks[k:k + 7]) for k in range(0, len(toks), 7))

    count = {"examples": 0, "converted": 0}

    @settings(max_examples=500, deadline=None, derandomize=True, database=None,
              suppress_health_check=list(HealthCheck))
    @given(mutated())
    def check(text: str) -> None:
        count["examples"] += 1
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            try:
                describe(parse_text(text, fuzz_path))
                count["converted"] += 1
            except SceneError as e:
                assert e.loc is not None and e.loc.line >= 1 and e.loc.col >= 1
                assert e.loc.path == fuzz_path or e.loc.path.startswith(str(scenes_dir))
                assert str(e).startswith(f"{e.loc}: error: ") and "\n" not in str(e)

    check()
    assert count["examples"] >= 500 and count["converted"] >= 100  # the converter stage is really reached


def test_internal_error_summary_names_the_innermost_cause() -> None:
    """Mitsuba wraps a plugin's Python exception (with traceback text) into its own message: the one-line
    summary keeps the first line and the innermost cause, never the traceback."""
    from a5mi.cli import exception_summary

    wrapped = RuntimeError('[parser.cpp:1718] At dictionary node "l": failed to instantiate plugin: Traceback '
                           '(most recent call last):\n  File "x.py", line 5, in f\nValueError: bad falloff')
    assert exception_summary(wrapped) == ('[parser.cpp:1718] At dictionary node "l": failed to instantiate '
                                           "plugin: (ValueError: bad falloff)")
    assert exception_summary(KeyError("k")) == "'k'"
    assert exception_summary(ValueError("")) == ""

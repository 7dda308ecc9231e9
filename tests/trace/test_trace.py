"""``a5mi trace`` (docs/TRACE.md): the recorded ray tree is the render's (sums equal the rendered pixels on every
course scene), each printed term equals the hand-worked value on three small scenes, ``--diff`` names the
term a broken render gets wrong, and bad input is one line with exit 2.

Metric for "equal": ``max |Σ contributions - rendered sample|`` over the three channels, float32, must be
``<= 1e-6`` (in practice 0: record mode runs the render kernel's own arithmetic). Hand values below are
derived in the comments from SPEC B.2/B.3 for camera rays along -z through the centre of a 5x5 image.
"""

from __future__ import annotations

import json
import os
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from helpers import ROOT

from a5mi.cli import run_a5mi
from a5mi.render.options import RenderOptions

COURSE_SCENES = [f"scene{n:02d}_{s}.txt" for n, s in (
    (1, "plane"), (2, "cube"), (3, "sphere"), (4, "axes"), (5, "bunny_200"), (6, "bunny_1k"), (7, "shine"),
    (8, "c"), (9, "s"), (10, "sphere"), (11, "cube"), (12, "vase"), (13, "diamond"))]


def tracer_for(path: Path, **opts: object):  # type: ignore[no-untyped-def]
    from a5mi.converters.a5_parser import parse_file
    from a5mi.converters.describe import describe
    from a5mi.trace.core import Tracer

    cwd = os.getcwd()
    os.chdir(path.parent)
    try:
        desc = describe(parse_file(str(path)))
    finally:
        os.chdir(cwd)
    return Tracer(desc, RenderOptions(**opts))  # type: ignore[arg-type]


def categories(tracer, traces) -> set[str]:  # type: ignore[no-untyped-def]
    from a5mi.converters.describe import CubeMapBackground

    seen: set[str] = set()
    desc = tracer.desc
    for pt in traces:
        for tree in pt.trees:
            for node in tree.nodes:
                if not node.is_hit:
                    seen.add("cube map" if isinstance(desc.background, CubeMapBackground) else "miss")
                    continue
                seen.add("hit")
                if node.ior > 0:
                    seen.add("glass")
                if node.push_refl > 0.5:
                    seen.add("mirror")
                if any(lt.tested and not lt.visible for lt in node.lights):
                    seen.add("shadowed")
                shape = desc.shapes[node.obj.index]
                kd = desc.materials[shape.material].kd_on(shape.has_uv)
                if kd is not None:
                    seen.add("marble" if type(kd).__name__ == "Noise" else "textured")
    return seen


TEXTURED = """PerspectiveCamera { center 0 0.7 3 direction 0 0 -1 up 0 1 0 angle 30 }
Lights { numLights 1 DirectionalLight { direction -0.3 -0.5 -1 color 0.9 0.9 0.9 } }
Background { color 0 0 0 ambientLight 0.2 0.2 0.2 cubeMap {tex}/church }
Materials { numMaterials 1 Material { diffuseColor 1 1 1 texture {tex}/char.bmp } }
Group { numObjects 1 MaterialIndex 0 Transform { YRotate 30 TriangleMesh { obj_file {tex}/c1.obj } } }
"""


@pytest.mark.slow
def test_sums_equal_the_render_on_every_course_scene(variant: str, scenes_dir: Path, tmp_path: Path) -> None:
    """24 pixels (a 6x4 grid) of every course scene at 24x24 -shadows -bounces 4, plus a textured cube in a
    cube map: Σ contributions == rendered sample to 1e-6, 8-bit equal, and every category was traced."""
    textured = tmp_path / "textured.txt"
    textured.write_text(TEXTURED.replace("{tex}", str(scenes_dir / "tex")))
    seen: set[str] = set()
    for path in [scenes_dir / name for name in COURSE_SCENES] + [textured]:
        tracer = tracer_for(path, width=24, height=24, shadows=True)
        pixels = [(x, y) for x in range(1, 24, 4) for y in range(2, 24, 6)]
        traces = tracer.pixels(pixels)
        assert len(traces) == 24
        for pt in traces:
            assert pt.max_error <= 1e-6, (path.name, pt.x, pt.y, pt.max_error)
            assert pt.value_byte == pt.image_byte, (path.name, pt.x, pt.y)
            tree = pt.trees[0]
            # the kernel's colour is the float32 running sum the tree shows
            assert np.array_equal(tree.contribution_sum(), np.array(tree.color, np.float32))
            for node in tree.nodes[1:]:   # a child's weight is the one its parent handed down
                parent = tree.nodes[node.parent]
                handed = parent.w_refl if node.kind == "reflection" else parent.w_refr
                assert node.weight == handed
        seen |= categories(tracer, traces)
    assert {"hit", "miss", "glass", "mirror", "shadowed", "marble", "textured", "cube map"} <= seen


def test_jitter_filter_samples_and_weights(variant: str, scenes_dir: Path) -> None:
    """-jitter -filter: the 3x3 sub-samples are the glibc-jittered rays of the block, the feeding samples' SPEC
    B.5 weights sum to (ΣK)² (K the float32 taps, ΣK ≈ 1.0001), and Σ w·c equals the filtered image's pixel to
    float32 precision."""
    from a5mi.render.filters import kernel_taps
    from a5mi.trace.core import filter_weights

    tracer = tracer_for(scenes_dir / "scene10_sphere.txt", width=12, height=12, shadows=True, jitter=True,
                        filter=True)
    (pt,) = tracer.pixels([(6, 5)])
    assert len(pt.block) == 9 and pt.samples[:9] == [(18 + dx, 18 + dy) for dy in (2, 1, 0) for dx in range(3)]
    assert all(abs(xp - round(xp)) > 0 for xp in pt.x_pix[:9])   # jittered
    assert len(pt.weights) == 49 and sum(pt.weights.values()) == pytest.approx(
        float(kernel_taps().astype(np.float64).sum()) ** 2, abs=1e-12)
    assert pt.max_error <= 1e-6 and pt.value_error <= 1e-6
    corner = filter_weights(tracer.options, 0, 11)    # bottom-left pixel: clamped taps pile onto the border
    assert max(corner, key=corner.get) == (0, 0) and len(corner) == 25


def _scene(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "s.txt"
    path.write_text(text)
    return path


CAM = "PerspectiveCamera { center 0 0 5 direction 0 0 -1 up 0 1 0 angle 30 }\n"


def test_hand_lit_sphere(variant: str, tmp_path: Path) -> None:
    """Unit sphere, centre pixel of 5x5 (x = 2·2/4 - 1 = 0: d = (0,0,-1)): t = 4, p = N = (0,0,1).
    Directional light travelling (0,0,-1): L = (0,0,1), N·L = 1, term = 1 · (0.8,0.6,0.4) ⊙ (0.5,0.25,1).
    Point light at (0,0,3), falloff 0.5: |p - x| = 2, arriving (1,1,1)/(1 + 0.5·4) = 1/3, L = (0,0,1).
    Ambient (0.1,0.2,0.3) ⊙ diffuse (0.5,0.25,1) = (0.05,0.05,0.3)."""
    path = _scene(tmp_path, CAM + """Lights { numLights 2 DirectionalLight { direction 0 0 -1 color 0.8 0.6 0.4 }
        PointLight { position 0 0 3 color 1 1 1 falloff 0.5 } }
        Background { color 0 0 0 ambientLight 0.1 0.2 0.3 }
        Materials { numMaterials 1 Material { diffuseColor 0.5 0.25 1 } }
        Group { numObjects 1 MaterialIndex 0 Sphere { center 0 0 0 radius 1 } }""")
    tracer = tracer_for(path, width=5, height=5, shadows=True)
    (pt,) = tracer.pixels([(2, 2)])
    (node,) = pt.trees[0].nodes
    assert node.kind == "camera" and node.d == pytest.approx((0, 0, -1), abs=1e-7)
    assert node.t == pytest.approx(4.0, abs=1e-6) and node.p == pytest.approx((0, 0, 1), abs=1e-6)
    assert node.n == pytest.approx((0, 0, 1), abs=1e-6) and not node.inside
    assert node.obj.kind == "Sphere" and node.obj.line == 6 and node.obj.material_line == 5
    assert node.ambient_term == pytest.approx((0.05, 0.05, 0.3), abs=1e-7)
    sun, lamp = node.lights
    assert sun.L == pytest.approx((0, 0, 1)) and sun.n_dot_l == pytest.approx(1.0, abs=1e-6) and sun.visible
    assert sun.term == pytest.approx((0.4, 0.15, 0.4), abs=1e-6)
    assert lamp.light_color == pytest.approx((1 / 3,) * 3, abs=1e-7) and lamp.dist == pytest.approx(2.0, abs=1e-6)
    assert lamp.term == pytest.approx((0.5 / 3, 0.25 / 3, 1 / 3), abs=1e-6)
    expect = np.array([0.05, 0.05, 0.3]) + np.array([0.4, 0.15, 0.4]) + np.array([0.5, 0.25, 1]) / 3
    assert node.contribution == pytest.approx(tuple(expect), abs=1e-6)
    assert pt.max_error == 0.0


def test_hand_mirror_and_shadow(variant: str, tmp_path: Path) -> None:
    """A mirror sphere (specular 0.5, diffuse 0) at the centre pixel: the mirror ray leaves p = (0,0,1) along
    reflect((0,0,-1), N) = (0,0,1) with tmin 0.001 and weight specular · R = 0.5 · 1 (no refraction: R = 1), and
    misses: contribution 0.5 · background (0.2,0.4,0.6). The light travels (0,-1,-1): L = (0,1,1)/√2,
    N·L = 1/√2; a sphere of radius 0.1 centred 2 along the shadow ray, p + 2L = (0, √2, 1 + √2), blocks it at
    t = 2 - 0.1 = 1.9, off the camera and mirror rays."""
    path = _scene(tmp_path, CAM + """Lights { numLights 1 DirectionalLight { direction 0 -1 -1 color 1 1 1 } }
        Background { color 0.2 0.4 0.6 ambientLight 0 0 0 }
        Materials { numMaterials 2 Material { diffuseColor 0 0 0 specularColor 0.5 0.5 0.5 }
          Material { diffuseColor 1 1 1 } }
        Group { numObjects 2 MaterialIndex 0 Sphere { center 0 0 0 radius 1 }
          MaterialIndex 1 Sphere { center 0 1.41421356 2.41421356 radius 0.1 } }""")
    tracer = tracer_for(path, width=5, height=5, shadows=True, bounces=1)
    (pt,) = tracer.pixels([(2, 2)])
    root, child = pt.trees[0].nodes
    (sun,) = root.lights
    assert not sun.visible and sun.occluder.kind == "Sphere" and sun.occluder.line == 7
    assert sun.occluder_t == pytest.approx(1.9, abs=1e-5) and sun.n_dot_l == pytest.approx(0.5 ** 0.5, abs=1e-6)
    assert root.r_fresnel == 1.0 and root.w_refl == pytest.approx((0.5,) * 3)
    assert child.kind == "reflection" and child.parent == 0 and child.tmin == pytest.approx(0.001)
    assert child.d == pytest.approx((0, 0, 1), abs=1e-6) and child.o == pytest.approx((0, 0, 1), abs=1e-6)
    assert not child.is_hit and child.contribution == pytest.approx((0.1, 0.2, 0.3), abs=1e-7)
    assert pt.max_error == 0.0


def test_hand_glass_pane_normal_incidence(variant: str, tmp_path: Path) -> None:
    """A pane: plane z = 0 (normal +z) and z = -0.1 (normal -z, offset 0.1), refractionIndex 1.5, specular 1.
    Entering at normal incidence: R0 = ((1.5-1)/(1.5+1))² = 0.04, c = |d·N| = 1, R = 0.04; T = -N = (0,0,-1);
    children: mirror weight 0.04, refracted weight 0.96 in medium 1.5. Leaving through z = -0.1: d·N = 1 > 0,
    nt = 1, R0 = 0 (the binary's (nt-1)/(nt+1)), c = |T·N| = 1, R = 0: transmitted weight 0.96 · 1."""
    path = _scene(tmp_path, CAM + """Lights { numLights 0 }
        Background { color 0.2 0.4 0.6 ambientLight 0 0 0 }
        Materials { numMaterials 1 Material { diffuseColor 0 0 0 specularColor 1 1 1 refractionIndex 1.5 } }
        Group { numObjects 2 MaterialIndex 0 Plane { normal 0 0 1 offset 0 } Plane { normal 0 0 -1 offset 0.1 } }""")
    tracer = tracer_for(path, width=5, height=5, bounces=3)
    (pt,) = tracer.pixels([(2, 2)])
    nodes = pt.trees[0].nodes
    root = nodes[0]
    assert root.obj.kind == "Plane" and root.t == pytest.approx(5.0) and not root.inside
    assert root.r_fresnel == pytest.approx(0.04, abs=1e-7)
    assert root.w_refl == pytest.approx((0.04,) * 3, abs=1e-7) and root.w_refr == pytest.approx((0.96,) * 3, abs=1e-7)
    assert root.t_dir == pytest.approx((0, 0, -1), abs=1e-7) and root.nt == pytest.approx(1.5)
    refr = next(n for n in nodes if n.kind == "refraction" and n.parent == 0)
    assert refr.n_medium == pytest.approx(1.5) and refr.inside and refr.t == pytest.approx(0.1, abs=1e-6)
    assert refr.r_fresnel == pytest.approx(0.0, abs=1e-7) and refr.w_refr == pytest.approx((0.96,) * 3, abs=1e-7)
    refl = next(n for n in nodes if n.kind == "reflection" and n.parent == 0)
    assert not refl.is_hit and refl.contribution == pytest.approx((0.008, 0.016, 0.024), abs=1e-7)
    assert sum(np.array(n.contribution) for n in nodes) == pytest.approx((0.2, 0.4, 0.6), abs=1e-6)
    from a5mi.trace.tree import fresnel_text

    assert "((1.5-1)/(1.5+1))² = 0.04" in fresnel_text(root, "a5") and "|d·N| = 1" in fresnel_text(root, "a5")


def _a5mi(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    rc = run_a5mi(argv)
    cap = capsys.readouterr()
    return rc, cap.out, cap.err


def test_cli_trace_text_json_svg(variant: str, scenes_dir: Path, tmp_path: Path,
                                 capsys: pytest.CaptureFixture[str]) -> None:
    scene = str(scenes_dir / "scene10_sphere.txt")
    svg = tmp_path / "tree.svg"
    rc, out, _ = _a5mi(["trace", "-input", scene, "-size", "20", "20", "-shadows", "-pixel", "10", "10",
                        "--svg", str(svg)], capsys)
    assert rc == 0 and "#0 camera ray" in out and "Sphere at line 59" in out and ": equal" in out
    assert "Fresnel: R = R0 + (1-R0)(1-c)^5" in out and "DIFFER" not in out
    root = ET.parse(svg).getroot()
    boxes = [r for r in root.iter("{http://www.w3.org/2000/svg}rect") if r.get("rx")]
    n_nodes = out.count(" ray  o (")
    assert len(boxes) == n_nodes > 1
    rc, out2, _ = _a5mi(["trace", "-input", scene, "-size", "20", "20", "-shadows", "-pixel", "10", "9",
                         "--origin", "bottom-left", "--json"], capsys)
    data = json.loads(out2)
    assert rc == 0 and data["pixel"] == [10, 10] and data["pixel_bottom_left"] == [10, 9]
    (sample,) = data["samples"]
    assert sample["sum"] == sample["rendered"] and len(sample["nodes"]) == n_nodes
    rc, out3, _ = _a5mi(["trace", "-input", scene, "-size", "8", "8", "-jitter", "-filter", "-pixel", "3", "3",
                         "--sample", "4"], capsys)
    assert rc == 0 and out3.count("render-buffer sample") == 1 and "49 samples feed this pixel" in out3


@pytest.mark.parametrize("flags, kind", [((), "shadow"), (("-shadows", "-bounces", "0"), "reflection|refraction")])
def test_diff_names_the_broken_term(variant: str, scenes_dir: Path, tmp_path: Path, flags: tuple[str, ...],
                                    kind: str, capsys: pytest.CaptureFixture[str]) -> None:
    """A student render without shadows / with -bounces 0 against the -shadows -bounces 4 reference: the
    first pixel's named term is a shadow term / a reflection or refraction term."""
    scene = str(scenes_dir / "scene10_sphere.txt")
    student = tmp_path / "student.png"
    assert run_a5mi(["render", "-input", scene, "-size", "30", "30", *flags, "-output", str(student)]) == 0
    rc, out, _ = _a5mi(["trace", "-input", scene, "-size", "30", "30", "-shadows", "--diff", str(student),
                        "--worst", "3", "--json"], capsys)
    assert rc == 0
    worst = json.loads(out)
    assert len(worst) == 3 and worst[0]["student_byte"] != worst[0]["reference_byte"]
    top = worst[0]["terms"][0]
    assert top["kind"] in kind.split("|"), top
    if kind == "shadow":
        assert "shadow term of light" in top["label"] and "reference blocked by" in top["label"]
    rc, text, _ = _a5mi(["trace", "-input", scene, "-size", "30", "30", "-shadows", "--diff", str(student),
                         "--worst", "1"], capsys)
    assert rc == 0 and text.splitlines()[1].startswith("  look at: ")
    assert text.splitlines()[-1] == (f"to name the mistake behind the difference: a5mi diagnose {student} -input "
                                     f"{scene} -size 30 30 -bounces 4 -shadows")   # docs/MISTAKES.md


@pytest.mark.parametrize("extra, message", [
    (["-pixel", "20", "3"], "outside the 20x20 image"),
    (["-pixel", "3", "3", "--sample", "2"], "--sample needs -jitter"),
    (["--diff", "{small}"], "is 5x5; the reference render is 20x20"),
    ([], "give -pixel X Y"),
    (["-pixel", "1", "1", "--svg", "/no/such/dir/t.svg"], "does not exist"),
])
def test_bad_input_one_line(variant: str, scenes_dir: Path, tmp_path: Path, extra: list[str], message: str,
                            capsys: pytest.CaptureFixture[str]) -> None:
    from a5mi.platform.imageio import write_image

    small = tmp_path / "small.png"
    write_image(small, np.zeros((5, 5, 3), np.float32))
    argv = ["trace", "-input", str(scenes_dir / "scene03_sphere.txt"), "-size", "20", "20"]
    rc, out, err = _a5mi(argv + [e.replace("{small}", str(small)) for e in extra], capsys)
    lines = err.strip().splitlines()
    assert rc == 2 and out == "" and len(lines) == 1, err
    assert lines[0].startswith("a5mi trace: error: ") and message in lines[0]


def test_readme_example_is_what_trace_prints(variant: str, scenes_dir: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    """docs/TRACE.md's scene10 trace, run as written (from the scenes folder), prints exactly the page's text."""
    import re

    readme = (ROOT / "docs" / "TRACE.md").read_text()
    block = re.search(r"```\n\$ cd \.\./shared/a5/scenes && a5mi trace (.*?)\n(.*?)```", readme, re.S)
    assert block is not None
    cwd = os.getcwd()
    os.chdir(scenes_dir)
    try:
        rc, out, _ = _a5mi(["trace", *block.group(1).split()], capsys)
    finally:
        os.chdir(cwd)
    assert rc == 0 and out == block.group(2)


@pytest.mark.parametrize("opts, grid, n_samples", [
    ({"filter": True}, (4, 4), 49),                 # -filter alone: the saved image is W/3 x H/3
    ({"jitter": True}, (12, 12), 9),                # -jitter alone: nine saved pixels of the 3W x 3H image
])
def test_filter_alone_and_jitter_alone(variant: str, scenes_dir: Path, opts: dict[str, bool],
                                       grid: tuple[int, int], n_samples: int) -> None:
    from a5mi.trace.core import TraceError, pixel_grid

    tracer = tracer_for(scenes_dir / "scene07_shine.txt", width=12, height=12, shadows=True, **opts)
    assert pixel_grid(tracer.options) == grid
    (pt,) = tracer.pixels([(1, 2)])
    assert len(pt.samples) == n_samples and pt.max_error <= 1e-6 and pt.value_error <= 1e-6
    with pytest.raises(TraceError, match="outside"):
        tracer.pixels([(grid[0], 0)])


def test_many_samples_are_traced_in_chunks(variant: str, scenes_dir: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Record buffers are bounded: with room for a few lanes per launch the 49 samples of a -jitter -filter
    pixel take several launches and give the same trees as one launch."""
    from a5mi.plugins.kernel.record import LIGHT_STRIDE, NODE_STRIDE
    from a5mi.trace import core

    tracer = tracer_for(scenes_dir / "scene10_sphere.txt", width=6, height=6, shadows=True, jitter=True,
                        filter=True, bounces=2)
    (one,) = tracer.pixels([(2, 3)])
    monkeypatch.setattr(core, "RECORD_FLOATS", 7 * 7 * (NODE_STRIDE + 2 * LIGHT_STRIDE))   # 7 lanes a launch
    (chunked,) = tracer.pixels([(2, 3)])
    assert [t.nodes[-1].color for t in chunked.trees] == [t.nodes[-1].color for t in one.trees]
    assert chunked.max_error == 0.0 and chunked.value == one.value


@pytest.mark.parametrize("off", [0, 2])
def test_diff_names_nothing_within_the_noise(variant: str, scenes_dir: Path, tmp_path: Path, off: int,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    """The reference image itself (``off`` 0), and the same image with every channel moved by a random
    -off..off levels (a correct jittered render, <= 2/255 off): nothing differs, no term is named; one pixel
    moved by 40 levels is then named (it is beyond the noise threshold)."""
    from a5mi.platform.imageio import read_levels, write_image
    from a5mi.trace.report import DIFF_NOISE

    assert off <= DIFF_NOISE
    scene = str(scenes_dir / "scene10_sphere.txt")
    flags = ["-size", "24", "24", "-shadows", "-jitter", "-filter"]
    student = tmp_path / "student.png"
    assert run_a5mi(["render", "-input", scene, *flags, "-output", str(student)]) == 0
    img = read_levels(student)
    noise = np.random.default_rng(3).integers(-off, off + 1, img.shape)
    img = np.clip(img + noise, 0, 255)
    assert np.abs(img - read_levels(student)).max() == off
    write_image(student, (img + 0.5) / 255)
    rc, out, _ = _a5mi(["trace", "-input", scene, *flags, "--diff", str(student)], capsys)
    assert rc == 0 and out.strip() == (f"nothing differs: no pixel is off by more than 2/255 (the noise threshold; "
                                       f"largest difference {off}/255)")
    assert "look at" not in out
    rc, out, _ = _a5mi(["trace", "-input", scene, *flags, "--diff", str(student), "--json"], capsys)
    assert rc == 0 and json.loads(out) == []
    img[12, 5] = np.where(img[12, 5] > 127, img[12, 5] - 40, img[12, 5] + 40)
    write_image(student, (img + 0.5) / 255)
    rc, out, _ = _a5mi(["trace", "-input", scene, *flags, "--diff", str(student), "--worst", "3"], capsys)
    assert rc == 0 and out.startswith("pixel (5, 12) (top-left)") and out.count("(top-left)") == 1


def test_explain_names_no_term_for_an_identical_pixel(variant: str, scenes_dir: Path) -> None:
    """:func:`explain` against the reference pixel itself lists no term (every term moves away from it)."""
    from a5mi.trace.report import explain

    tracer = tracer_for(scenes_dir / "scene10_sphere.txt", width=20, height=20, shadows=True)
    (pt,) = tracer.pixels([(10, 10)])
    assert explain(pt, np.asarray(pt.value)) == []
    assert explain(pt, np.zeros(3))  # a black pixel: the reference's terms explain it

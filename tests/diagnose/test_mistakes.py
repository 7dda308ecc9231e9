"""Each docs/MISTAKES.md mistake made by ``-mistake`` on a scene where its effect is known in closed form.

* kernel and marble mistakes: renders of plane/triangle scenes against tests/diagnose/oracle.py, an independent
  float64 statement of SPEC B.3 with each catalogued change (metric: share of pixels within 2e-3 of the oracle
  in every channel, >= 97 %; the rest are float32-vs-float64 pixels on edges), and the mutant must differ from
  the correct render (the mistake shows);
* mistakes equal to another render by definition (``no_shadows`` = no ``-shadows``, ``no_recursion`` =
  ``-bounces 0``, the bounce budget, ``phong_highlight`` = ``-phong``, ``marble_no_octaves`` = ``octaves 0``,
  ``no_supersampling`` = no ``-jitter -filter``, ``no_jitter`` = the 3W x 3H grid filtered): bit for bit;
* the random ones (acne): a share of darkened pixels strictly between 0 and 1, where the correct render has none;
* camera, jitter, filter and image mistakes: their formulas on arrays, and one render each through ``a5``.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from oracle import Mat, Oracle, Scene

from a5mi.render.options import MISTAKES, RenderOptions

SIZE = 17


def _scene_lit() -> Scene:
    return Scene(
        camera=((0, 0, 5), (0, 0, -1), (0, 1, 0), 50),
        materials=[Mat((0.5, 0.5, 0.5), marble=((0.9, 0.3, 0.1), (0.1, 0.3, 0.8), 4.0, 2.0)),
                   Mat((0.2, 0.7, 0.3), (0.3, 0.3, 0.3), 8.0)],
        planes=[((0, 0, 1), 0.0, 0)],
        triangles=[(((-0.8, -0.6, 1.5), (0.0, 0.9, 1.5), (0.7, -0.5, 1.5)), 1)],
        directional=[((0.3, -0.2, -1), (0.5, 0.5, 0.5)), ((0.1, 0.2, 1), (0.3, 0.3, 0.3))],
        point=[((0.5, 0.3, 1.0), (0.6, 0.5, 0.4))],
        ambient=(0.15, 0.15, 0.15), background=(0.1, 0.1, 0.1))


def _scene_corridor() -> Scene:
    return Scene(
        camera=((0, 0, 5), (0.2, 0.1, -1), (0, 1, 0), 40),
        materials=[Mat((0.3, 0.3, 0.3), (0.5, 0.4, 0.3), marble=((0.9, 0.8, 0.2), (0.1, 0.2, 0.6), 1.5, 1.0)),
                   Mat((0.2, 0.5, 0.2), (0.6, 0.6, 0.6))],
        planes=[((0, 0, 1), 0.0, 0), ((0, 0, -1), -10.0, 1)],
        directional=[((0.2, 0.3, -1), (0.7, 0.7, 0.7))],
        ambient=(0.1, 0.1, 0.1), background=(0.3, 0.2, 0.1))


def _scene_glass() -> Scene:
    return Scene(
        camera=((0, 0, 5), (0, 0, -1), (0, 1, 0), 110),
        materials=[Mat((0, 0, 0), (0.9, 0.9, 0.9), ior=1.5),
                   Mat((0.5, 0.5, 0.5), marble=((0.9, 0.2, 0.2), (0.2, 0.9, 0.2), 2.0, 1.0)),
                   Mat((0.5, 0.5, 0.5), marble=((0.2, 0.2, 0.9), (0.9, 0.9, 0.2), 1.3, 1.0))],
        planes=[((0, 0, 1), 0.0, 0), ((0.6, 0, -0.8), 0.8, 0), ((0, 0, 1), -6.0, 1), ((0, 0, -1), -12.0, 2)],
        directional=[((0, 0, -1), (0.8, 0.8, 0.8))],
        ambient=(0.2, 0.2, 0.2), background=(0.05, 0.05, 0.05))


def _scene_placed() -> Scene:
    """A sphere stretched along a tilted axis, a mirror triangle and a wall, each under a non-uniform
    ``Transform``, a world floor: docs/MISTAKES.md's normal-transform mistakes on every primitive kind."""
    return Scene(
        camera=((0, 0, 5), (0, 0, -1), (0, 1, 0), 55),
        materials=[Mat((0.8, 0.5, 0.3)), Mat((0.3, 0.6, 0.8), (0.5, 0.5, 0.5)), Mat((0.6, 0.6, 0.6))],
        planes=[((0, 1, 0), -1.5, 2)],
        placed=[("sphere", ((0, 0, 0), 0.6), [("Translate", (-0.8, 0.3, 0.5)), ("ZRotate", 30),
                                               ("Scale", (1.8, 0.7, 0.9))], 0),
                ("triangle", ((-0.5, -0.4, 0.2), (0.5, -0.3, -0.2), (0.0, 0.5, 0.1)),
                 [("Translate", (0.9, -0.2, 1.0)), ("UniformScale", 1.3), ("Scale", (1, 2.5, 1)), ("YRotate", 35)], 1),
                ("plane", ((0, 0, 1), -3.0), [("Scale", (2, 1, 1)), ("YRotate", 30)], 2)],
        directional=[((-0.3, -0.4, -1), (0.7, 0.7, 0.7))],
        point=[((1.5, 1.5, 3.0), (0.4, 0.4, 0.4))],
        ambient=(0.1, 0.1, 0.1), background=(0.2, 0.1, 0.1))


#: scene, flags (bounces, shadows), the mistakes checked on it against the oracle
ORACLE_CASES: dict[str, tuple[Scene, int, bool, tuple[str, ...]]] = {
    "lit": (_scene_lit(), 0, True, (
        "no_shadows", "shadow_beyond_light", "shadow_first_light_only", "no_ambient", "ambient_uses_kd",
        "ndotl_unclamped", "light_dir_flipped", "normal_faces_viewer", "light_color_ignored", "kd_ignores_texture",
        "phong_highlight", "marble_sine_unmapped", "marble_freq_amp_swapped")),
    "corridor": (_scene_corridor(), 3, False, (
        "mirror_sign", "reflection_unweighted", "bounces_plus_one", "bounces_minus_one", "no_recursion")),
    "glass": (_scene_glass(), 4, False, (
        "refraction_unweighted", "refl_refr_added", "eta_inverted", "eta_inside_inverted",
        "normal_not_flipped_inside", "tir_ignored", "schlick_wrong_c")),
    "placed": (_scene_placed(), 1, True, ("normal_by_m", "normal_not_normalised")),
}


@pytest.fixture(scope="module")
def session(variant: str):  # noqa: ANN201 - a RenderSession
    from a5mi.render.session import RenderSession

    return RenderSession()


def _desc(text: str, tmp: Path, name: str = "s.txt"):  # noqa: ANN202 - a SceneDescription
    from a5mi.render.session import describe_file

    path = tmp / name
    path.write_text(text)
    return describe_file(str(path))[0]


def _render(session, desc, **kw) -> np.ndarray:  # noqa: ANN001
    return session.render(desc, RenderOptions(**{"width": SIZE, "height": SIZE, **kw})).image


def _agree(a: np.ndarray, b: np.ndarray, tol: float = 2e-3) -> float:
    """Share of pixels whose channels all lie within ``tol``."""
    return float(np.mean(np.all(np.abs(a - b) <= tol, axis=-1)))


@pytest.mark.parametrize("case,mistake", [(c, m) for c, (_, _, _, ms) in ORACLE_CASES.items() for m in ms])
def test_kernel_mistake_matches_oracle(session, tmp_path: Path, case: str, mistake: str) -> None:
    scene, bounces, shadows, _ = ORACLE_CASES[case]
    desc = _desc(scene.text(), tmp_path)
    correct = _render(session, desc, bounces=bounces, shadows=shadows)
    mutant = _render(session, desc, bounces=bounces, shadows=shadows, mistakes=(mistake,))
    assert _agree(correct, Oracle(scene, bounces, shadows).image(SIZE)) >= 0.97   # the oracle is SPEC B.3
    expected = Oracle(scene, bounces, shadows, (mistake,)).image(SIZE)
    assert _agree(mutant, expected) >= 0.97, mistake
    assert _agree(mutant, correct, 1e-3) <= 0.95, f"{mistake} does not show on scene {case}"


def test_normal_mistakes_together_match_oracle(session, tmp_path: Path) -> None:
    """Both normal-transform mistakes at once: N = M n_o, not normalised (docs/MISTAKES.md)."""
    scene, both = _scene_placed(), ("normal_by_m", "normal_not_normalised")
    mutant = _render(session, _desc(scene.text(), tmp_path), bounces=1, shadows=True, mistakes=both)
    assert _agree(mutant, Oracle(scene, 1, True, both).image(SIZE)) >= 0.97
    for one in both:
        assert _agree(mutant, Oracle(scene, 1, True, (one,)).image(SIZE)) <= 0.9


UNIFORM_SPHERE = """PerspectiveCamera { center 0 0 5 direction 0 0 -1 up 0 1 0 angle 30 }
Lights { numLights 1 DirectionalLight { direction 0 0 -1 color 0.8 0.8 0.8 } }
Background { color 0 0 0 ambientLight 0 0 0 }
Materials { numMaterials 1 Material { diffuseColor 1 1 1 } }
Group { numObjects 1 MaterialIndex 0 Transform { ZRotate 25 UniformScale 2 Sphere { center 0 0 0 radius 0.5 } } }
"""


def test_normal_mistakes_under_a_similarity(session, tmp_path: Path) -> None:
    """M = 2 R (a similarity): ``normal_by_m`` changes nothing (normalize(M Mᵀ n_w) = n_w; up to float32 rounding);
    ``normal_not_normalised`` halves N (|Mᵀ n_w| = 2): the Lambert colour clamp(L·N) and the ``-normals`` image
    |N| (SPEC B.6: the hit record's normal, the one the student's Transform wrote) are half the correct ones."""
    desc = _desc(UNIFORM_SPHERE, tmp_path)

    def both(mistakes: tuple[str, ...]) -> tuple[np.ndarray, np.ndarray]:
        r = session.render(desc, RenderOptions(width=SIZE, height=SIZE, normals=True, mistakes=mistakes))
        return r.image, r.normals

    image, normals = both(())
    np.testing.assert_allclose(np.stack(both(("normal_by_m",))), np.stack((image, normals)), atol=1e-5)
    half_image, half_normals = both(("normal_not_normalised",))
    on = image.max(axis=-1) > 0.05                     # the sphere's lit pixels (the rest is black)
    assert on.mean() > 0.2
    np.testing.assert_allclose(half_image[on], image[on] / 2, atol=1e-5)
    np.testing.assert_allclose(half_normals, normals / 2, atol=1e-5)


def test_oracle_cases_cover_the_kernel(tmp_path: Path) -> None:
    """Every kernel / marble mistake is checked somewhere in this file (oracle, equality or acne test)."""
    from a5mi.render.options import KERNEL_MISTAKES, MARBLE_MISTAKES

    elsewhere = {"shadow_acne", "secondary_acne", "marble_no_octaves", "background_wrong_direction"}
    covered = {m for _, _, _, ms in ORACLE_CASES.values() for m in ms} | elsewhere
    assert set(KERNEL_MISTAKES + MARBLE_MISTAKES) <= covered


@pytest.mark.parametrize("mistake,same", [
    ("no_shadows", {"shadows": False}), ("no_recursion", {"bounces": 0}), ("bounces_plus_one", {"bounces": 4}),
    ("bounces_minus_one", {"bounces": 2}), ("phong_highlight", {"phong": True}),
])
def test_mistake_equals_a_flag(session, tmp_path: Path, mistake: str, same: dict) -> None:
    """Bit for bit: these mistakes are another flag by definition (docs/MISTAKES.md)."""
    scene = dataclasses.replace(_scene_lit(), materials=[Mat((0.5, 0.5, 0.5), (0.4, 0.4, 0.4), 6.0),
                                                         Mat((0.2, 0.7, 0.3), (0.3, 0.3, 0.3), 8.0)])
    if "bounces" in same or mistake == "no_recursion":   # the corridor's mirrors reflect without end
        scene = _scene_corridor()
    desc = _desc(scene.text(), tmp_path)
    base = {"bounces": 3, "shadows": True}
    mutant = _render(session, desc, **base, mistakes=(mistake,))
    assert np.array_equal(mutant, _render(session, desc, **{**base, **same}))
    assert not np.array_equal(mutant, _render(session, desc, **base))


def test_marble_no_octaves_is_octaves_0(session, tmp_path: Path) -> None:
    text = _scene_lit().text()
    with_octaves = _desc(text.replace("octaves 0", "octaves 3"), tmp_path, "a.txt")
    mutant = _render(session, with_octaves, mistakes=("marble_no_octaves",))
    assert np.array_equal(mutant, _render(session, _desc(text, tmp_path, "b.txt")))
    assert not np.array_equal(mutant, _render(session, with_octaves))


def test_acne_darkens_some_pixels(session, tmp_path: Path) -> None:
    """shadow_acne: some lit pixels of a plane lit from straight above lose the light (the shadow ray meets
    the plane at t ~ 0); secondary_acne: mirror rays meet their own plane, some pixels change. Never all."""
    scene = Scene(camera=((0, 0, 5), (0, 0, -1), (0, 1, 0), 50), materials=[Mat((0.6, 0.6, 0.6), (0.5, 0.5, 0.5))],
                  planes=[((0.3, 0.2, 1), 0.1, 0)], point=[((0.2, 0.1, 3.0), (0.8, 0.8, 0.8))],
                  ambient=(0.1, 0.1, 0.1), background=(0.9, 0.2, 0.2))
    desc = _desc(scene.text(), tmp_path)
    for mistake, flags in (("shadow_acne", {"shadows": True, "bounces": 0}), ("secondary_acne", {"bounces": 1})):
        correct = _render(session, desc, width=40, height=40, **flags)
        mutant = _render(session, desc, width=40, height=40, mistakes=(mistake,), **flags)
        changed = float(np.mean(np.any(np.abs(mutant - correct) > 1e-3, axis=-1)))
        assert 0.0 < changed < 1.0, (mistake, changed)


def test_background_wrong_direction(session, tmp_path: Path) -> None:
    """A cube map of six uniform faces: looking along -z the camera sees ``back``; background(-d) is ``front``."""
    from a5mi.platform.imageio import write_image

    faces = {"left": (1, 0, 0), "right": (0, 1, 0), "up": (0, 0, 1), "down": (1, 1, 0), "front": (0, 1, 1),
             "back": (1, 0, 1)}
    cube = tmp_path / "cube"
    cube.mkdir()
    for name, c in faces.items():
        write_image(cube / f"{name}.bmp", np.broadcast_to(np.array(c, np.float32) * 0.8, (4, 4, 3)).copy())
    text = Scene(camera=((0, 0, 5), (0, 0, -1), (0, 1, 0), 30), materials=[Mat()]).text()
    text = text.replace("Background {", f"Background {{ cubeMap {cube}")
    desc = _desc(text, tmp_path)
    level = np.float32(204 / 255)   # 0.8 stored as a byte
    assert np.allclose(_render(session, desc), np.array(faces["back"]) * level, atol=1e-6)
    assert np.allclose(_render(session, desc, mistakes=("background_wrong_direction",)),
                       np.array(faces["front"]) * level, atol=1e-6)


# ---------------------------------------------------------------- camera, jitter, filter, image

def test_camera_mistakes_closed_form(variant: str) -> None:
    """fov_full_angle: the ray through x = 1 has tan = tan(angle) (not tan(angle/2)); camera_divides_by_w: the
    last pixel column is at x = 2(W-1)/W - 1."""
    import mitsuba as mi

    from a5mi.converters.errors import FileLoc
    from a5mi.converters.model import Camera
    from a5mi.render.driver import _default_camera_rays, mistaken

    cam = Camera((0.0, 0.0, 0.0), (0.0, 0.0, -1.0), (0.0, 1.0, 0.0), 40.0, FileLoc("<t>", 1, 1))
    w = 11
    for names, expect in ((("fov_full_angle",), math.tan(math.radians(40))), (("camera_divides_by_w",),
                          (2 * (w - 1) / w - 1) * math.tan(math.radians(20))), ((), math.tan(math.radians(20)))):
        c, rays, _ = mistaken(cam, _default_camera_rays(), RenderOptions(width=w, height=w, mistakes=names))
        ray = rays(c.center, c.direction, c.up, c.angle, mi.Float([w - 1.0]), mi.Float([(w - 1) / 2]), w, w)
        d = np.array([ray.d.x[0], ray.d.y[0], ray.d.z[0]])
        assert d[0] / -d[2] == pytest.approx(expect, rel=1e-5), names


def test_jitter_mistakes_offsets() -> None:
    from a5mi.render.tiles import main_tiles

    rows = [(0, 3)]
    spec = next(main_tiles(6, rows, 5, True, {}))
    unit = next(main_tiles(6, rows, 5, True, {}, ("jitter_0_1",)))
    none = next(main_tiles(6, rows, 5, True, {}, ("no_jitter",)))
    i = np.tile(np.arange(6, dtype=np.float32), 3)
    assert np.all((spec.x_pix - i >= -0.5) & (spec.x_pix - i < 0.5))
    assert np.allclose(unit.x_pix - spec.x_pix, 0.5) and np.allclose(unit.y_pix - spec.y_pix, 0.5)
    assert np.array_equal(none.x_pix, i)


def test_filter_mistakes_closed_form() -> None:
    from a5mi.render.filters import KERNELS, downsample3, mistaken_postprocess, postprocess

    k = np.array(KERNELS["binary"], np.float64)
    c = np.full((9, 9, 3), 0.2, np.float32)
    # not normalised: a constant image times (ΣK / K[2])² (interior and, with the clamped border, everywhere)
    assert np.allclose(mistaken_postprocess(c, ("blur_not_normalised",)), 0.2 * (k.sum() / k[2]) ** 2, rtol=1e-5)
    # zero border: the blur of a constant is c · a(j) · a(i), a(n) = Σ of the taps that land inside
    a = np.array([sum(k[t] for t in range(5) if 0 <= n + t - 2 < 9) for n in range(9)])
    blurred = 0.2 * a[:, None] * a[None, :]
    got = mistaken_postprocess(c, ("blur_zero_border",))[..., 0]
    assert np.allclose(got, downsample3(blurred[..., None])[..., 0], rtol=1e-5)
    rng = np.random.default_rng(3)
    img = rng.random((9, 12, 3), dtype=np.float32)
    assert np.array_equal(mistaken_postprocess(img, ("no_blur",)), downsample3(img))
    assert np.array_equal(mistaken_postprocess(img, ("no_blur", "downsample_one_sample")), img[1::3, 1::3])
    # one direction: an impulse spreads along y (axis 0) only
    imp = np.zeros((9, 9, 1), np.float32)
    imp[4, 4] = 1.0
    assert np.array_equal(mistaken_postprocess(imp, ("blur_one_direction", "no_blur")), downsample3(imp))
    one = mistaken_postprocess(np.repeat(np.repeat(imp, 1, 0), 1, 1), ("blur_one_direction",))
    assert one[:, 0].max() == 0 and one[:, 2].max() == 0 and one[:, 1].sum() > 0
    assert not np.array_equal(one, postprocess(imp, filter=True))


def test_image_mistakes_closed_form() -> None:
    from a5mi.platform.imageio import quantize
    from a5mi.render.filters import image_mistakes, srgb_encode

    img = np.array([[[0.1, 0.5, 0.9], [1.5, -0.2, 0.002]], [[0.25, 0.75, 1.0], [0.3, 0.6, 2.1]]], np.float32)
    assert np.array_equal(image_mistakes(img, ("upside_down",)), img[::-1])
    assert np.array_equal(image_mistakes(img, ("mirrored",)), img[:, ::-1])
    assert np.array_equal(image_mistakes(img, ("red_blue_swapped",)), img[..., ::-1])
    assert srgb_encode(np.float32(0.5)) == pytest.approx(1.055 * 0.5 ** (1 / 2.4) - 0.055, rel=1e-6)
    assert srgb_encode(np.float32(0.002)) == pytest.approx(12.92 * 0.002, rel=1e-6)
    wrapped = quantize(image_mistakes(img, ("colours_wrapped",)))
    assert wrapped[0, 1, 0] == int(1.5 * 255) % 256 and wrapped[1, 1, 2] == int(np.float32(2.1) * 255) % 256
    assert wrapped[0, 1, 1] == (-int(0.2 * 255)) % 256
    rounded = quantize(image_mistakes(img, ("rounding",)))
    assert np.array_equal(rounded, np.clip(np.floor(img.astype(np.float64) * 255 + 0.5), 0, 255).astype(np.uint8))


def test_driver_mistakes_through_a_render(session, tmp_path: Path) -> None:
    """The driver's mistakes in a real render: equal to what their definition says, bit for bit."""
    from a5mi.render.filters import image_mistakes, mistaken_postprocess

    desc = _desc(_scene_lit().text(), tmp_path)
    opts = {"width": 12, "height": 12, "shadows": True}
    full = session.render(desc, RenderOptions(**opts, jitter=True, filter=True)).image
    plain = session.render(desc, RenderOptions(**opts)).image
    assert np.array_equal(session.render(desc, RenderOptions(**opts, jitter=True, filter=True,
                                                             mistakes=("no_supersampling",))).image, plain)
    grid = session.render(desc, RenderOptions(**{**opts, "width": 36, "height": 36})).image[::-1]
    for names in (("no_jitter",), ("no_jitter", "blur_zero_border")):
        got = session.render(desc, RenderOptions(**opts, jitter=True, filter=True, mistakes=names)).image
        filt = tuple(n for n in names if n != "no_jitter")
        expect = mistaken_postprocess(grid, filt) if filt else mistaken_postprocess(grid, ("__none__",))
        assert np.allclose(got, expect[::-1], atol=1e-6), names
    for name in ("upside_down", "red_blue_swapped", "srgb_gamma"):
        got = session.render(desc, RenderOptions(**opts, jitter=True, filter=True, mistakes=(name,))).image
        assert np.array_equal(got, image_mistakes(full, (name,))), name


def test_every_mistake_is_tested_here() -> None:
    """The catalogue's names are the option's names, and each is exercised by a test of this file."""
    from a5mi.diagnose.catalogue import BY_NAME

    assert set(BY_NAME) == set(MISTAKES)
    source = Path(__file__).read_text()
    assert all(f'"{m}"' in source for m in MISTAKES), [m for m in MISTAKES if f'"{m}"' not in source]

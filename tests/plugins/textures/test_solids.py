"""Procedural solids (docs/EXTENSIONS.md E.6): a5_solid against a direct evaluation at random points, the scene
keywords and their positioned errors."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from test_perlin import ref_noise, ref_octave_noise

C1 = [0.9, 0.7, 0.3]
C2 = [0.2, 0.1, 0.05]


def _solid(kind: str, **kw: object):
    import mitsuba as mi

    return mi.load_dict({"type": "a5_solid", "kind": kind, "color1": {"type": "rgb", "value": C1},
                         "color2": {"type": "rgb", "value": C2}, **kw})


def _eval(tex, pts: np.ndarray) -> np.ndarray:
    import drjit as dr
    import mitsuba as mi

    si = dr.zeros(mi.SurfaceInteraction3f, len(pts))
    si.p = mi.Point3f(*(pts[:, k].astype(np.float32) for k in range(3)))
    return np.asarray(tex.eval(si)).T


def ref_turbulence(p: np.ndarray, octaves: int) -> float:
    """Σ |noise(2^i p)| / 2^i with the octave points of the marble (float32 products, double sum)."""
    t = 0.0
    for i in range(octaves):
        scale = np.float32(2.0**i)
        q = (p.astype(np.float32) * scale).astype(np.float64)
        t += abs(ref_noise(float(q[0]), float(q[1]), float(q[2]))) / float(scale)
    return t


def _mix(t: float) -> np.ndarray:
    t32 = np.float32(t)
    return t32 * np.float32(C1) + (np.float32(1) - t32) * np.float32(C2)


def _ref(kind: str, p: np.ndarray, octaves: int, frequency: float, amplitude: float, scale: float,
         axis: np.ndarray, center: np.ndarray) -> np.ndarray:
    """The E.6 formulas evaluated directly, in double (the plugin's float32 steps give ~1e-6 differences)."""
    p64 = p.astype(np.float64)
    sp = p64 * scale
    a = axis / np.linalg.norm(axis)
    if kind == "turbulence":
        return _mix(min(max(amplitude * ref_turbulence(sp, octaves), 0.0), 1.0))
    if kind == "wood":
        q = p64 - center
        x = float(np.linalg.norm(q - np.dot(q, a) * a))
        n = ref_octave_noise(sp, octaves)
    else:
        x = float(np.dot(p64, a))
        n = ref_turbulence(sp, octaves)
    return _mix(min(max(0.5 * math.sin(frequency * x + amplitude * n) + 0.5, 0.0), 1.0))


@pytest.mark.parametrize("kind", ["wood", "turbulence", "veins"])
def test_solid_matches_direct_evaluation(variant: str, kind: str) -> None:
    """Every kind at 300 random points against its formula (E.6), for a few parameter sets."""
    rng = np.random.default_rng({"wood": 1, "turbulence": 2, "veins": 3}[kind])
    pts = rng.uniform(-4.0, 4.0, size=(300, 3)).astype(np.float32)
    for octaves, frequency, amplitude, scale in ((0, 3.0, 1.0, 1.0), (4, 7.5, 2.0, 1.7), (6, 1.0, 0.6, 0.4)):
        axis = rng.normal(size=3)
        center = rng.uniform(-1.0, 1.0, size=3)
        tex = _solid(kind, octaves=octaves, frequency=frequency, amplitude=amplitude, scale=scale,
                     axis=axis.tolist(), center=center.tolist())
        got = _eval(tex, pts)
        want = np.array([_ref(kind, p, octaves, frequency, amplitude, scale, axis, center) for p in pts])
        # float32 radius / dot product: the sine's argument is off by ~1e-6 relative; the blend by less.
        assert np.max(np.abs(got - want)) < 5e-5, (kind, octaves)


def test_wood_rings_are_cylinders_about_the_axis(variant: str) -> None:
    """Without noise, wood depends only on the distance to the axis: rotating a point about it keeps kd, and
    sin(ω r) = 1 at r = π/(2ω) gives color1 exactly."""
    w = 4.0
    tex = _solid("wood", octaves=0, frequency=w, axis=[0.0, 0.0, 2.0], center=[1.0, -1.0, 0.0])
    r = math.pi / (2 * w)
    angles = np.linspace(0, 2 * math.pi, 7)
    pts = np.stack([1.0 + r * np.cos(angles), -1.0 + r * np.sin(angles), np.linspace(-3, 3, 7)], axis=1)
    got = _eval(tex, pts.astype(np.float32))
    assert np.allclose(got, C1, atol=1e-5)


def test_turbulence_is_zero_on_the_lattice_and_nonnegative(variant: str) -> None:
    """T = 0 at integer points (every octave's noise vanishes): kd = color2; T ≥ 0 elsewhere."""
    tex = _solid("turbulence", octaves=5, amplitude=3.0)
    lattice = np.array([[0, 0, 0], [3, -2, 7], [-5, 1, 1]], dtype=np.float32)
    assert np.allclose(_eval(tex, lattice), C2, atol=1e-7)
    rng = np.random.default_rng(7)
    pts = rng.uniform(-3, 3, size=(200, 3)).astype(np.float32)
    t = np.array([ref_turbulence(p, 5) for p in pts])
    assert (t >= 0).all() and t.max() > 0.1


def test_marble_kernel_is_unchanged(variant: str) -> None:
    """The marble still evaluates the SPEC B.4 sum bit for bit after the solids were added (the same noise)."""
    import mitsuba as mi

    marble = mi.load_dict({"type": "a5_marble", "color1": {"type": "rgb", "value": C1},
                           "color2": {"type": "rgb", "value": C2}, "octaves": 4, "frequency": 5.0,
                           "amplitude": 2.0})
    rng = np.random.default_rng(11)
    pts = rng.uniform(-2, 2, size=(64, 3)).astype(np.float32)
    got = _eval(marble, pts)
    want = []
    for p in pts:
        arg = float(np.float32(p[0]) * np.float32(5.0)) + 2.0 * ref_octave_noise(p, 4)
        want.append(_mix(min(max(0.5 * math.sin(arg) + 0.5, 0.0), 1.0)))
    assert np.array_equal(got, np.array(want, dtype=np.float32))


# ------------------------------------------------------------------------------------------ scene language
SCENE = """PerspectiveCamera {{ center 0 0 10 direction 0 0 -1 up 0 1 0 angle 30 }}
Lights {{ numLights 1 DirectionalLight {{ direction 0 0 -1 color 1 1 1 }} }}
Background {{ color 0 0 0 ambientLight 0.1 0.1 0.1 }}
Materials {{ numMaterials 1
Material {{ diffuseColor 1 1 1
{block}
}} }}
Group {{ numObjects 1 MaterialIndex 0 Sphere {{ center 0 0 0 radius 1 }} }}
"""


def _parse(tmp_path: Path, block: str):
    from a5mi.converters.a5_parser import parse_file

    f = tmp_path / "s.txt"
    f.write_text(SCENE.format(block=block))
    return parse_file(str(f))


def test_solid_blocks_parse_with_defaults(tmp_path: Path) -> None:
    from a5mi.converters.model import Solid

    wood = _parse(tmp_path, "Wood { color 1 0 0 color 0 1 0 frequency 12 axis 0 0 1 center 1 2 3 }").materials[0].solid
    assert wood == Solid("wood", (1, 0, 0), (0, 1, 0), 4, 12.0, 1.0, 1.0, (0, 0, 1), (1, 2, 3), wood.loc)
    turb = _parse(tmp_path, "Turbulence { octaves 6 color 1 1 1 color 0 0 0 amplitude 2 }").materials[0].solid
    assert (turb.kind, turb.octaves, turb.amplitude) == ("turbulence", 6, 2.0)
    veins = _parse(tmp_path, "Veins { color 1 1 1 color 0 0 0 scale 0.5 }").materials[0].solid
    assert (veins.kind, veins.scale, veins.axis) == ("veins", 0.5, (0.0, 1.0, 0.0))


@pytest.mark.parametrize(("block", "at", "message"), [
    ("Wood { color 1 0 0 }", "Wood", "Wood needs two colors, found 1"),
    ("Wood { color 1 0 0 color 0 0 0 axis 0 0 0 }", "axis", "Wood axis must not be the zero vector"),
    ("Turbulence { color 1 0 0 color 0 0 0 frequency 2 }", "frequency", "expected color, octaves, amplitude, scale"),
    ("Veins { color 1 0 0 color 0 0 0 octaves 40 }", "40", "Veins octaves must be between 0 and 31"),
    ("Veins { color 1 0 0 color 0 0 0 scale -1 }", "scale", "Veins scale must be positive"),
    ("Wood { color 1 0 0 color 0 0 0 scale 2 scale 3 }", "scale", "Wood gives 'scale' twice"),
    ("Noise { color 1 0 0 color 0 0 0 } Wood { color 1 0 0 color 0 0 0 }", "Wood", "a Material takes one of"),
    ("Wood { color 1 0 0 color 0 0 0 } Noise { color 1 0 0 color 0 0 0 }", "Noise", "a Material takes one of"),
])
def test_solid_errors_are_positioned(tmp_path: Path, block: str, at: str, message: str) -> None:
    """Each error names the file, line 6 (the block's line) and the column of the offending word (its last
    occurrence in the block)."""
    from a5mi.converters.errors import SceneError

    with pytest.raises(SceneError) as exc:
        _parse(tmp_path, block)
    text = str(exc.value)
    assert f"s.txt:6:{block.rindex(at) + 1}:" in text and message in text, text


def test_solid_scene_renders_the_texture(tmp_path: Path, variant: str) -> None:
    """A Wood sphere through parse -> describe -> to_dict -> render: the a5_solid texture is the kd (the
    centre pixel equals ambient + kd·cos at the hit point); the stock conversion bakes it into a grid."""
    import mitsuba as mi

    from a5mi.converters.describe import describe
    from a5mi.converters.to_mitsuba import to_dict
    from a5mi.render.options import RenderOptions

    desc = describe(_parse(tmp_path, "Wood { color 1 0.5 0 color 0 0 1 frequency 9 octaves 2 }"))
    scene = mi.load_dict(to_dict(desc, RenderOptions(width=21, height=21)))
    img = np.asarray(mi.render(scene))
    kd = _eval(_solid_from(desc), np.array([[0.0, 0.0, 1.0]], dtype=np.float32))[0]
    assert np.allclose(img[10, 10], 0.1 + kd, atol=1e-5)
    stock = mi.load_dict(to_dict(desc, RenderOptions(width=21, height=21), stock=True))
    assert "A5Solid" not in str(stock.shapes()[0].bsdf())  # baked: the stock volume texture (EXTENSIONS E.6)
    assert "GridVolume" in str(stock.shapes()[0].bsdf())


def _solid_from(desc):
    import mitsuba as mi

    from a5mi.converters.materials import solid_texture

    return mi.load_dict(solid_texture(desc.materials[0].kd))

"""Fog and volumes (docs/EXTENSIONS.md E.8, E.9): analytic checks with stated tolerances.

Transmittance through a fog slab of depth ``d`` is ``exp(-σ d)`` (black fog, 1e-5 relative); the in-scattered
light of a uniform slab under a directional light is ``albedo · P · (1 − exp(−σ d)) · L`` with ``P = 1/4``
(1e-5: the fog estimator is exact for constant light); a ray in the umbra of an occluder gains no light; zero
density renders the course scenes bit for bit; the ``.vol`` reader reads what Mitsuba's writer writes and
round-trips; a constant-density Volume equals the Fog inside its box (exactly for constant light, within the
marching error otherwise).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import positioned_error_test

from a5mi.converters import volgrid
from a5mi.converters.a5_parser import parse_text
from a5mi.converters.errors import SceneError

PHASE = 0.25

#: A wall z = 0 (white or black) lit head-on by a directional light; the camera looks down -z.
WALL = """PerspectiveCamera {{ center 0 0 5 direction 0 0 -1 up 0 1 0 angle 20 }}
Lights {{ numLights 1 DirectionalLight {{ direction {light} color 1 1 1 }} }}
Background {{ color 0.3 0.6 0.9 ambientLight 0 0 0 }}
{medium}
Materials {{ numMaterials 1 Material {{ diffuseColor {wall} }} }}
Group {{ numObjects {n} MaterialIndex 0 Plane {{ normal 0 0 1 offset 0 }} {extra} }}
"""


def _scene(text: str, path: str = "<string>", **opts: Any) -> Any:
    from a5mi.converters.describe import describe
    from a5mi.render.options import RenderOptions
    from a5mi.render.session import build_scene

    return build_scene(describe(parse_text(text, path)), RenderOptions(**{"shadows": True, **opts}))


def _trace(mi: Any, scene: Any, o: np.ndarray, d: np.ndarray, passes: int = 1, seed: int = 3) -> np.ndarray:
    """Mean colour (N, 3) of rays ``o + t d`` over ``passes`` E.5 passes."""
    import drjit as dr

    from a5mi.plugins.sampling import SamplePass

    integ = scene.integrator()
    total = np.zeros((len(o), 3))
    for k in range(passes):
        ray = mi.Ray3f(mi.Point3f(*o.T.astype(np.float32)), mi.Vector3f(*d.T.astype(np.float32)))
        c = integ.trace(scene, ray, sample_pass=SamplePass(0, k, passes, seed))[0]
        dr.eval(c)                                                    # one kernel for the three channels
        total += np.stack([np.asarray(c.x), np.asarray(c.y), np.asarray(c.z)], axis=-1)
    return total / passes


def _rays(depths: list[float]) -> tuple[np.ndarray, np.ndarray]:
    o = np.array([[0.1 * (i + 1), -0.05 * (i + 1), z] for i, z in enumerate(depths)])
    return o, np.tile([0.0, 0.0, -1.0], (len(depths), 1))


# --------------------------------------------------------------------------------------------------- grammar
test_medium_errors_are_positioned = positioned_error_test(
    lambda block: WALL.format(light="0 0 -1", medium=block, wall="1 1 1", n=1, extra=""), [
        ("Fog { color 1 1 1 ^density -0.5 }", "density must not be negative"),
        ("Fog { ^color 1 2 1 density 0.5 }", "single-scattering albedo"),
        ("Fog { color 1 1 1 density 0.5 ^steps 0 }", "steps must be between 1 and 1024"),
        ("Volume { grid g.vol density 1 min 0 0 0 ^max 1 0 1 }", "max must exceed min"),
    ])


def test_one_medium_and_missing_grid(tmp_path: Path) -> None:
    from a5mi.converters.describe import describe

    two = WALL.format(light="0 0 -1", medium="Fog { color 1 1 1 density 1 }\nFog { color 1 1 1 density 2 }",
                      wall="1 1 1", n=1, extra="")
    with pytest.raises(SceneError, match="at most one medium") as err:
        parse_text(two)
    assert (err.value.loc.line, err.value.loc.col) == (5, 1)
    with pytest.raises(SceneError, match="expected 'grid', 'density'|expected grid, density") as err:
        parse_text(WALL.format(light="0 0 -1", medium="Volume { grid g.vol density 1 min 0 0 0 max 1 1 1 size 2 }",
                               wall="1 1 1", n=1, extra=""))
    scene = tmp_path / "s.txt"
    scene.write_text(WALL.format(light="0 0 -1", medium="Volume { grid nothere.vol density 1 min 0 0 0 max 1 1 1 }",
                                 wall="1 1 1", n=1, extra=""))
    from a5mi.converters.a5_parser import parse_file

    with pytest.raises(SceneError, match="Volume grid file 'nothere.vol' not found") as err:
        describe(parse_file(scene))
    assert (err.value.loc.line, err.value.loc.col) == (4, 15)
    (tmp_path / "bad.vol").write_bytes(b"VOL\x03" + b"\0" * 44)
    scene.write_text(scene.read_text().replace("nothere.vol", "bad.vol"))
    with pytest.raises(SceneError, match="is not a .vol grid: encoding 0"):
        describe(parse_file(scene))


# ----------------------------------------------------------------------------------------------- .vol format
def test_vol_round_trip_and_mitsuba_writer(mi: Any, tmp_path: Path) -> None:
    rng = np.random.default_rng(5)
    grid = rng.random((3, 4, 5, 1), dtype=np.float32)
    volgrid.write_vol(tmp_path / "a.vol", grid)
    back = volgrid.read_vol(tmp_path / "a.vol")
    assert back.shape == (3, 4, 5, 1) and back.dtype == np.float32 and np.array_equal(back, grid)
    mi.VolumeGrid(grid).write(str(tmp_path / "m.vol"))           # Mitsuba's own writer, same bytes
    assert (tmp_path / "m.vol").read_bytes() == (tmp_path / "a.vol").read_bytes()
    assert np.array_equal(volgrid.read_vol(tmp_path / "m.vol"), grid)
    data = (tmp_path / "a.vol").read_bytes()
    for bad, reason in ((b"XOL" + data[3:], "does not start with 'VOL'"), (data[:-4], "bytes, expected"),
                        (data[:3] + b"\x02" + data[4:], "version 2")):
        with pytest.raises(volgrid.VolFormatError, match=reason):
            volgrid.decode(bad)


# ------------------------------------------------------------------------------------------------------- fog
@pytest.mark.parametrize("sigma", [0.05, 0.3, 1.2])
def test_fog_slab_transmittance_is_exponential(mi: Any, sigma: float) -> None:
    """Black fog (no in-scatter) before a white wall lit head-on (local colour 1): ``exp(-σ d)``."""
    scene = _scene(WALL.format(light="0 0 -1", medium=f"Fog {{ color 0 0 0 density {sigma} }}", wall="1 1 1",
                               n=1, extra=""))
    depths = [0.5, 2.0, 5.0, 9.0]
    got = _trace(mi, scene, *_rays(depths))
    expected = np.exp(-sigma * np.array(depths))[:, None].repeat(3, axis=1)
    np.testing.assert_allclose(got, expected, rtol=1e-5)


@pytest.mark.parametrize(("sigma", "albedo"), [(0.1, (1.0, 0.5, 0.25)), (0.8, (0.9, 0.9, 0.9))])
def test_fog_inscatter_matches_closed_form(mi: Any, sigma: float, albedo: tuple[float, ...]) -> None:
    """A black wall behind a uniform slab under a directional light from the side: ``albedo P (1 − e^{−σd}) L``;
    a miss (no wall, infinite fog) gives ``albedo P L`` and hides the background."""
    medium = f"Fog {{ color {' '.join(map(str, albedo))} density {sigma} steps 4 }}"
    scene = _scene(WALL.format(light="0.3 -1 -0.2", medium=medium, wall="0 0 0", n=1, extra=""))
    depths = [0.5, 2.0, 6.0]
    got = _trace(mi, scene, *_rays(depths))
    expected = np.outer(1.0 - np.exp(-sigma * np.array(depths)), albedo) * PHASE
    np.testing.assert_allclose(got, expected, rtol=1e-5)
    o, d = _rays([1.0])
    np.testing.assert_allclose(_trace(mi, scene, o, -d)[0], np.array(albedo) * PHASE, rtol=1e-5)


def test_umbra_gains_no_light(mi: Any) -> None:
    """A ray under a ceiling plane (y = 1) that blocks a light from above: no in-scatter with shadows, the full
    closed form without (so a light makes shafts only past occluders, and only with shadow rays)."""
    text = WALL.format(light="0 -1 0", medium="Fog { color 1 1 1 density 0.5 }", wall="0 0 0", n=2,
                       extra="Plane { normal 0 1 0 offset 1 }")
    o, d = _rays([3.0])
    assert _trace(mi, _scene(text), o, d)[0, 0] == 0.0
    np.testing.assert_allclose(_trace(mi, _scene(text, shadows=False), o, d)[0, 0],
                               PHASE * (1.0 - np.exp(-1.5)), rtol=1e-5)


@pytest.mark.parametrize("name", ["scene07_shine.txt", "scene10_sphere.txt", "scene13_diamond.txt"])
def test_zero_density_is_the_course_image(mi: Any, scenes_dir: Path, name: str) -> None:
    """``Fog { density 0 }`` compiles the medium code and still renders the course scene bit for bit."""
    from a5mi.converters.describe import describe
    from a5mi.render.options import RenderOptions
    from a5mi.render.session import render

    text = (scenes_dir / name).read_text()
    opts = RenderOptions(width=24, height=24, shadows=True, bounces=4)
    plain = render(describe(parse_text(text, str(scenes_dir / name))), opts).image
    foggy = render(describe(parse_text(text + "\nFog { color 0.7 0.8 0.9 density 0 }\n", str(scenes_dir / name))),
                   opts).image
    assert np.array_equal(plain, foggy)


# ----------------------------------------------------------------------------------------------------- volume
def _box_scenes(tmp_path: Path, light: str, extra: str, n: int, steps: int) -> tuple[Any, Any]:
    volgrid.write_vol(tmp_path / "one.vol", np.ones((3, 3, 3), dtype=np.float32))
    base = """PerspectiveCamera {{ center 0 0 5 direction 0 0 -1 up 0 1 0 angle 20 }}
Lights {{ numLights 1 {light} }}
Background {{ color 0 0 0 ambientLight 0 0 0 }}
{medium}
Materials {{ numMaterials 1 Material {{ diffuseColor 0.5 0.5 0.5 }} }}
Group {{ numObjects {n} MaterialIndex 0 Plane {{ normal 0 0 1 offset 0 }} {extra} }}
"""
    fog = base.format(light=light, medium=f"Fog {{ color 0.8 0.8 0.8 density 0.4 steps {steps} }}", n=n, extra=extra)
    vol = base.format(light=light, n=n, extra=extra, medium="Volume { grid one.vol density 0.4 min -20 -20 -1 "
                      f"max 20 20 8 color 0.8 0.8 0.8 steps {steps} }}")
    (tmp_path / "fog.txt").write_text(fog)
    (tmp_path / "vol.txt").write_text(vol)
    return _scene(fog, str(tmp_path / "fog.txt")), _scene(vol, str(tmp_path / "vol.txt"))


def test_constant_volume_equals_fog_in_its_box(mi: Any, tmp_path: Path) -> None:
    """A point light with falloff behind a sphere (a shadow across the rays), camera and wall inside the box:
    both estimators are unbiased for the same integral (exact for a constant light: E.9); 32 steps x 16 passes
    agree to 2 % of the brightest pixel, and the lanes that cross the shadow differ from the others."""
    o = np.array([[x, y, 4.0] for x in (-0.6, 0.0, 0.7) for y in (-0.5, 0.4)])
    d = np.tile([0.0, 0.0, -1.0], (len(o), 1))
    light = "PointLight { position 0 3 2 color 2 2 2 falloff 0.05 }"
    fog, vol = _box_scenes(tmp_path, light, "Sphere { center 0 1.5 2 radius 0.6 }", 2, 32)
    a, b = _trace(mi, fog, o, d, passes=16), _trace(mi, vol, o, d, passes=16)
    assert a.max() - a.min() > 0.05 and a.min() > 0.0
    np.testing.assert_allclose(b, a, atol=0.02 * float(a.max()))


# ------------------------------------------------------------------------------------------------ stock mapping
def test_stock_mapping_uses_volpath_media(mi: Any, tmp_path: Path) -> None:
    from a5mi.converters.describe import describe
    from a5mi.converters.to_mitsuba import to_dict

    fog = describe(parse_text(WALL.format(light="0 0 -1", medium="Fog { color 0.5 0.6 0.7 density 0.3 }",
                                          wall="1 1 1", n=1, extra="")))
    d = to_dict(fog, stock=True)
    assert d["integrator"]["type"] == "volpath"
    med = d["sensor"]["medium"]
    assert med["type"] == "homogeneous" and med["sigma_t"] == 0.3 and med["albedo"]["value"] == [0.5, 0.6, 0.7]
    assert med["phase"] == {"type": "isotropic"}
    a5 = to_dict(fog)["integrator"]
    assert (a5["medium"], a5["medium_density"], a5["medium_steps"]) == ("fog", 0.3, 16)
    volgrid.write_vol(tmp_path / "g.vol", np.ones((2, 2, 2), dtype=np.float32))
    (tmp_path / "v.txt").write_text(WALL.format(light="0 0 -1", wall="1 1 1", n=1, extra="",
                                                medium="Volume { grid g.vol density 2 min 0 0 0 max 1 2 3 }"))
    from a5mi.converters.a5_parser import parse_file

    d = to_dict(describe(parse_file(tmp_path / "v.txt")), stock=True)
    med = d["sensor"]["medium"]
    assert med["type"] == "heterogeneous" and med["scale"] == 2.0 and med["sigma_t"]["type"] == "gridvolume"
    assert mi.load_dict(d) is not None


def test_xml_carries_the_medium(mi: Any, tmp_path: Path) -> None:
    """a5 XML: the integrator's ``medium_grid`` is a ``gridvolume`` on the grid written beside it;
    stock XML: the sensor's ``heterogeneous`` medium and ``volpath``; both load in Mitsuba."""
    from a5mi.converters.a5_parser import parse_file
    from a5mi.converters.describe import describe
    from a5mi.converters.to_xml import write_xml

    volgrid.write_vol(tmp_path / "g.vol", np.ones((2, 2, 2), dtype=np.float32))
    (tmp_path / "v.txt").write_text(WALL.format(light="0 0 -1", wall="1 1 1", n=1, extra="",
                                                medium="Volume { grid g.vol density 2 min 0 0 0 max 1 2 3 }"))
    desc = describe(parse_file(tmp_path / "v.txt"))
    a5 = write_xml(desc, tmp_path / "a5.xml")
    stock = write_xml(desc, tmp_path / "stock.xml", stock=True)
    text = a5.read_text()
    assert '<volume type="gridvolume" name="medium_grid">' in text
    assert '<string name="filename" value="a5_images/grid_g.vol" />' in text   # relative: the folder can move
    np.testing.assert_array_equal(volgrid.read_vol(tmp_path / "a5_images" / "grid_g.vol"),
                                  volgrid.read_vol(tmp_path / "g.vol"))
    assert '<string name="medium" value="volume" />' in text
    text = stock.read_text()
    assert '<integrator type="volpath"' in text and '<medium type="heterogeneous" name="medium">' in text
    assert mi.load_file(str(a5)).integrator()._medium.kind == "volume"
    assert mi.load_file(str(stock)).sensors()[0].get_medium() is not None


def test_volume_grid_orientation_and_march(mi: Any, tmp_path: Path) -> None:
    """A black Volume before a white wall lit head-on (local colour 1), box [0, 4] x [0, 1] x [1, 3]:
    ``grid[z, y, x] = 0.5 + x + 2 z/(nz − 1)`` (x fastest in the file). Rays along −z through the cell centres
    of column ``x`` see ``σ(z) = density (0.5 + x + 2 z_frac)``, whose interpolated (cell-centred, clamped)
    integral over the depth 2 is ``density · 2 (0.5 + x + 1)``: the march gives ``exp(−that)`` within 1 %."""
    nz, nx = 6, 4
    z = np.arange(nz, dtype=np.float32)[:, None, None]
    x = np.arange(nx, dtype=np.float32)[None, None, :]
    volgrid.write_vol(tmp_path / "ramp.vol", (0.5 + x + 2.0 * z / (nz - 1) + np.zeros((nz, 1, nx))).astype(np.float32))
    text = WALL.format(light="0 0 -1", wall="1 1 1", n=1, extra="",
                       medium="Volume { grid ramp.vol density 0.2 min 0 0 1 max 4 1 3 color 0 0 0 steps 64 }")
    (tmp_path / "r.txt").write_text(text)
    scene = _scene(text, str(tmp_path / "r.txt"))
    o = np.array([[i + 0.5, 0.5, 4.0] for i in range(nx)])
    d = np.tile([0.0, 0.0, -1.0], (nx, 1))
    got = _trace(mi, scene, o, d)[:, 0]
    expected = np.exp(-0.2 * 2.0 * (0.5 + np.arange(nx) + 1.0))
    np.testing.assert_allclose(got, expected, rtol=0.01)

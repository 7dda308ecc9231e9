"""The a5_point emitter (SPEC A.3): L = normalize(pos - p), d = |pos - p|, colour / (1 + falloff d^2)."""

from __future__ import annotations

import math

import numpy as np
import pytest


def _light(position=(1.0, 2.0, 3.0), color=(0.9, 0.6, 0.3), falloff=None):
    import mitsuba as mi

    d = {"type": "a5_point", "position": list(position), "color": {"type": "rgb", "value": list(color)}}
    if falloff is not None:
        d["falloff"] = falloff
    return mi.load_dict(d)


def _it(points: list[tuple[float, float, float]]):
    import drjit as dr
    import mitsuba as mi

    it = dr.zeros(mi.Interaction3f, len(points))
    it.p = mi.Point3f(*(np.array([p[k] for p in points], dtype=np.float32) for k in range(3)))
    return it


def test_a3_point_sample_direction_by_hand(variant: str) -> None:
    import mitsuba as mi

    light = _light(falloff=0.5)
    # p = (1, 2, 0): pos - p = (0, 0, 3), d = 3; p = (4, 6, 3): pos - p = (-3, -4, 0), d = 5
    ds, value = light.sample_direction(_it([(1, 2, 0), (4, 6, 3)]), mi.Point2f(0.3, 0.7))
    assert np.allclose(np.asarray(ds.d).T, [[0, 0, 1], [-0.6, -0.8, 0]], atol=1e-7)
    assert np.allclose(np.asarray(ds.dist), [3, 5])
    assert np.allclose(np.asarray(ds.pdf), 1.0)
    assert np.all(np.asarray(ds.delta))
    assert np.allclose(np.asarray(ds.p).T, [[1, 2, 3], [1, 2, 3]])
    color = np.array([0.9, 0.6, 0.3])
    want = [color / (1 + 0.5 * 9), color / (1 + 0.5 * 25)]
    assert np.allclose(np.asarray(value).T, want, atol=1e-7)


def test_a3_point_no_falloff_no_inverse_square(variant: str) -> None:
    """falloff defaults to 0: the colour arrives unchanged at any distance."""
    import mitsuba as mi

    _, value = _light().sample_direction(_it([(1, 2, 2.5), (100, -50, 7)]), mi.Point2f(0.5, 0.5))
    assert np.allclose(np.asarray(value).T, [[0.9, 0.6, 0.3]] * 2, atol=1e-7)


def test_a3_point_is_delta_and_never_hit(variant: str) -> None:
    import drjit as dr
    import mitsuba as mi

    light = _light(falloff=1.0)
    assert mi.has_flag(light.flags(), mi.EmitterFlags.DeltaPosition)
    assert not light.is_environment()
    si = dr.zeros(mi.SurfaceInteraction3f, 2)
    assert np.all(np.asarray(light.eval(si)) == 0)
    ds, _ = light.sample_direction(_it([(0, 0, 0)]), mi.Point2f(0.5, 0.5))
    assert np.all(np.asarray(light.pdf_direction(_it([(0, 0, 0)]), ds)) == 0)


def test_a3_point_traverse_update(variant: str) -> None:
    import mitsuba as mi

    light = _light()
    params = mi.traverse(light)
    assert {"position", "color", "falloff"} <= set(params.keys())
    params["falloff"] = mi.Float(2.0)
    params["position"] = mi.Point3f(0, 0, 1)
    params.update()
    ds, value = light.sample_direction(_it([(0, 0, 0)]), mi.Point2f(0.5, 0.5))
    assert np.allclose(np.asarray(ds.dist), 1.0)
    assert np.allclose(np.asarray(value).T, [[0.3, 0.2, 0.1]], atol=1e-7)


def test_a3_point_in_scene_emitters(variant: str) -> None:
    """Usable from a scene dict: the scene lists it among its emitters, with its flags."""
    import mitsuba as mi

    scene = mi.load_dict(
        {
            "type": "scene",
            "light": {"type": "a5_point", "position": [0, 1, 0], "color": {"type": "rgb", "value": [1, 1, 1]}},
        }
    )
    (em,) = scene.emitters()
    assert mi.has_flag(em.flags(), mi.EmitterFlags.DeltaPosition)
    assert scene.environment() is None


@pytest.mark.parametrize(
    ("params", "match"),
    [({}, "position"), ({"position": [0, 0, 0], "falloff": -1.0}, "falloff"), ({"position": "x"}, "position")],
)
def test_a3_point_validation(variant: str, params: dict, match: str) -> None:
    import mitsuba as mi

    with pytest.raises(Exception, match=match):
        mi.load_dict({"type": "a5_point", **params})


def test_a3_stock_directional_contract(variant: str) -> None:
    """What the integrator gets for a DirectionalLight (stock `directional`, Mitsuba 3.9.1): ds.d =
    -direction, a DeltaDirection flag, the irradiance as the value (no distance term), and a FINITE
    ds.dist = 2 max(R, |p - c|) for the scene's bounding sphere (c, R): not inf, but always past every
    object, so a shadow ray up to ds.dist is equivalent to the binary's FLT_MAX."""
    import mitsuba as mi

    light = mi.load_dict(
        {
            "type": "directional",
            "direction": [0.5, -1.0, 0.0],
            "irradiance": {"type": "rgb", "value": [0.3, 0.2, 0.1]},
        }
    )
    assert mi.has_flag(light.flags(), mi.EmitterFlags.DeltaDirection)
    # the stock plugin takes the scene's bounding sphere in set_scene: sample it from inside a scene
    scene = mi.load_dict({"type": "scene", "light": light, "s": {"type": "sphere", "radius": 0.1}})
    (em,) = scene.emitters()
    pts = [(0, 0, 0), (3, 4, 5)]
    ds, value = em.sample_direction(_it(pts), mi.Point2f(0.5, 0.5))
    n = math.sqrt(1.25)
    assert np.allclose(np.asarray(ds.d).T, [[-0.5 / n, 1 / n, 0]] * 2, atol=1e-6)
    assert np.allclose(np.asarray(value).T, [[0.3, 0.2, 0.1]] * 2, atol=1e-6)
    radius = 0.1 * math.sqrt(3)  # bounding sphere of the sphere's bbox
    dist = np.asarray(ds.dist)
    assert np.all(np.isfinite(dist))
    assert np.allclose(dist, [2 * max(radius, math.dist(p, (0, 0, 0))) for p in pts], rtol=1e-4)
    assert np.all(dist >= np.array([math.dist(p, (0, 0, 0)) for p in pts]) + radius)


def test_a3_point_through_vcall(variant: str) -> None:
    """Reached through an EmitterPtr array (how an integrator loops over lights), alongside a stock light."""
    import drjit as dr
    import mitsuba as mi

    scene = mi.load_dict(
        {
            "type": "scene",
            "a": {"type": "a5_point", "position": [0, 0, 2], "color": {"type": "rgb", "value": [1, 0.5, 0.25]}},
            "b": {"type": "directional", "direction": [0, -1, 0], "irradiance": {"type": "rgb", "value": [1, 1, 1]}},
        }
    )
    kinds = [mi.has_flag(e.flags(), mi.EmitterFlags.DeltaPosition) for e in scene.emitters()]
    k_point, k_dir = kinds.index(True), kinds.index(False)
    idx = mi.UInt32([k_point, k_dir, k_point])
    ptr = dr.gather(mi.EmitterPtr, scene.emitters_dr(), idx)
    ds, value = ptr.sample_direction(_it([(0, 0, 0)] * 3), mi.Point2f(0.5, 0.5))
    got = np.asarray(value).T
    assert np.allclose(got[[0, 2]], [1, 0.5, 0.25])
    assert np.allclose(got[1], [1, 1, 1])
    assert np.allclose(np.asarray(ds.dist)[[0, 2]], 2.0)
    assert np.allclose(np.asarray(ds.d).T[1], [0, 1, 0])

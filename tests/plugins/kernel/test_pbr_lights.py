"""The E.13 light loop (plugins/kernel/pbr_lights.py) with shapes a light does not sit on: a non-uniformly
scaled sphere is a Mitsuba ``instance``, which has no ``sample_position`` / ``pdf_direction``; the lights on a
shape are called through ``dr.switch`` over those shapes alone, so such a scene renders, and an instance that
no ray or shadow ray can reach changes no pixel."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

SCENE = """PerspectiveCamera {{ center 0 4 9 direction 0 -0.45 -1 up 0 1 0 angle 40 }}
Lights {{ numLights 2
  AreaLight {{ corner -1.5 4 -1.5 edge1 3 0 0 edge2 0 0 1.5 color 0.7 0.7 0.65 samples 4 }}
  PointLight {{ position 2 3 2 color 0.4 0.4 0.4 }} }}
Background {{ color 0.1 0.1 0.15 ambientLight 0.1 0.1 0.1 }}
Materials {{ numMaterials 2 Material {{ diffuseColor 0.8 0.8 0.8 }} Material {{ diffuseColor 0.9 0.3 0.2 }} }}
Group {{ numObjects {n}
  MaterialIndex 0 Plane {{ normal 0 1 0 offset 0 }}
  MaterialIndex 1 Sphere {{ center -0.8 1 0 radius 1 }}
  {extra} }}
"""
#: An ellipsoid (an ``instance`` in Mitsuba) far behind the camera, above nothing the camera sees: no camera ray,
#: bounce or shadow ray toward a light can reach it at -bounces 1 (the lights are in front, below it).
HIDDEN = "Transform { Translate 0 60 400 Scale 1 0.3 2 Sphere { center 0 0 0 radius 1 } }"


@pytest.mark.parametrize("integrator", ["path", "irradiancecache", "photon"])
def test_an_instance_in_the_scene_changes_nothing_it_cannot_reach(render_text: Callable[..., np.ndarray],
                                                                  integrator: str) -> None:
    """Bit-identical images with and without the unreachable ellipsoid (before, the scene with it ended in an
    internal error: ``Shape::sample_position(): not implemented``). Photon mapping emits photons in every
    direction from the point light, and the few that reach the ellipsoid change the map's random stream: its
    images agree in the mean (within 2% of the mean level) instead."""
    opts = {"width": 16, "height": 16, "integrator": integrator, "bounces": 1, "spp": 2}
    plain = render_text(SCENE.format(n=2, extra=""), **opts)
    with_instance = render_text(SCENE.format(n=3, extra=HIDDEN), **opts)
    assert np.isfinite(plain).all() and plain.max() > 0.05
    if integrator == "photon":
        assert np.abs(plain - with_instance).mean() < 0.02 * plain.mean()
    else:
        assert np.array_equal(plain, with_instance)


def test_a_visible_ellipsoid_lit_by_an_area_light(render_text: Callable[..., np.ndarray]) -> None:
    """The ellipsoid in view, under the area light (-integrator path): it renders, and its pixels are lit
    (the light's shape sampled through the switch, not the instance)."""
    ellipsoid = "Transform { Translate 1.5 0.6 0 Scale 1 0.6 0.6 Sphere { center 0 0 0 radius 1 } }"
    img = render_text(SCENE.format(n=3, extra=ellipsoid), width=24, height=24, integrator="path", spp=4)
    bare = render_text(SCENE.format(n=2, extra=""), width=24, height=24, integrator="path", spp=4)
    assert np.isfinite(img).all()
    changed = np.abs(img - bare).max(axis=-1) > 0.02
    assert changed.sum() >= 10  # the ellipsoid (and its shadow) are in the picture
    assert img[changed].max() > 0.2  # and lit

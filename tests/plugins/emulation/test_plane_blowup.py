"""A plane with a non-unit normal in front of glass: the Schlick blow-up, followed to the byte (docs/FIDELITY.md).

A mirror ray off ``Plane { normal 0 -12.6 0 ... }`` is ``|n|²`` long (SPEC A.6: the reflection uses the normal
as written), so Schlick's ``c = |d·N|`` on the glass ball it meets is far above 1 and ``R = R0 + (1 − R0)(1 −
c)⁵`` reaches −1e10 .. −1e15 (SPEC B.3). The pixel's colour is then ±1e7 .. ±1e15; the sample solution's
``int(c * 255)`` of a product beyond the int32 range is x86's ``INT_MIN``, which the clamp makes 0: every such
pixel is black, the negative ones and the positive ones alike.

Golden: tests/data/plane_blowup_a5soln.png is ``a5soln -input plane_blowup.txt -size 48 48 -output pb.tga``
of :data:`SCENE` (default 4 bounces), converted to PNG losslessly; 85 of its pixels are black. Before the
quantisation followed the conversion, a5mi drew the positive ones white (17.5 dB at 100 x 100).

The ``-normals`` image shows the hit record's normal, which for a plane is its normal as written: ``|n_y| =
12.6``, 255 (SPEC B.6; a5mi showed the unit normal there before). tests/data/plane_blowup_a5soln_normals.png
and ``_depth.png`` are ``a5soln -input plane_blowup.txt -size 48 48 -output x.bmp -normals n.bmp -depth 3 16
d.bmp`` (its main image is the golden above), traced with the binary's quadrant rays (``aov_mode quadrant``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from a5mi.converters.a5_parser import parse_text
from a5mi.converters.describe import describe
from a5mi.platform.imageio import quantize, read_uint8
from a5mi.render.options import RenderOptions
from a5mi.render.session import render

SCENE = """PerspectiveCamera { center 0 2 6 direction 0 -0.3 -1 up 0 1 0 angle 40 }
Lights { numLights 1 DirectionalLight { direction -0.3 -1 -0.5 color 0.9 0.9 0.9 } }
Background { color 0.2 0.3 0.5 ambientLight 0.1 0.1 0.1 }
Materials { numMaterials 3
  Material { diffuseColor 0.3 0.3 0.3 specularColor 0.7 0.7 0.7 }
  Material { diffuseColor 0.1 0.1 0.1 specularColor 0.9 0.9 0.9 refractionIndex 1.5 }
  Material { diffuseColor 0.8 0.2 0.2 }
}
Group { numObjects 3
  MaterialIndex 0 Plane { normal 0 -12.6 0 offset 12.6 }
  MaterialIndex 1 Sphere { center 0 0 0 radius 0.8 }
  MaterialIndex 2 Sphere { center 1.5 0.3 -1 radius 0.5 }
}
"""


def test_blown_up_pixels_are_black_as_in_the_sample_solution(variant: str) -> None:
    """The whole 48 x 48 image equals a5soln's byte for byte; the blow-up is really there (float colours
    beyond 8.4e6, both signs)."""
    result = render(describe(parse_text(SCENE, "plane_blowup.txt")), RenderOptions(width=48, height=48))
    golden = read_uint8(Path(__file__).parents[2] / "data" / "plane_blowup_a5soln.png")
    np.testing.assert_array_equal(quantize(result.image)[..., :3], golden)
    rgb = np.asarray(result.image, dtype=np.float64)[..., :3]
    assert (rgb > 8.5e6).any() and (rgb < -8.5e6).any()


def test_aov_images_are_the_sample_solutions(variant: str) -> None:
    """The quadrant-ray ``-normals`` and ``-depth 3 16`` images equal a5soln's byte for byte; the plane shows
    ``(0, 255, 0)`` in the normals image (1513 of its pixels)."""
    opts = RenderOptions(width=48, height=48, normals=True, depth=(3.0, 16.0), aov_mode="quadrant")
    result = render(describe(parse_text(SCENE, "plane_blowup.txt")), opts)
    data = Path(__file__).parents[2] / "data"
    normals = quantize(result.normals)[..., :3]
    np.testing.assert_array_equal(normals, read_uint8(data / "plane_blowup_a5soln_normals.png"))
    np.testing.assert_array_equal(quantize(result.depth)[..., :3], read_uint8(data / "plane_blowup_a5soln_depth.png"))
    assert int((normals == (0, 255, 0)).all(axis=2).sum()) == 1513


def test_normals_image_of_a_tilted_plane_shows_the_normal_as_written(variant: str) -> None:
    """``Plane { normal -0.305 0.333 -0.42 }`` fills the quadrant rays' view: every pixel of the ``-normals``
    image is ``trunc(255 |n_i|)`` of the normal as written, (77, 84, 107), not of the unit normal
    (126, 137, 173). (a5soln ``-size 32 32 -normals`` of this scene: all 1024 pixels (77, 84, 107).)"""
    text = SCENE.replace("Plane { normal 0 -12.6 0 offset 12.6 }", "Plane { normal -0.305 0.333 -0.42 offset -0.955 }")
    opts = RenderOptions(width=32, height=32, normals=True, aov_mode="quadrant")
    normals = quantize(render(describe(parse_text(text, "tilted.txt")), opts).normals)[..., :3]
    want = np.trunc(np.float32(255.0) * np.abs(np.array([-0.305, 0.333, -0.42], dtype=np.float32)))
    assert want.tolist() == [77, 84, 107]
    assert (normals == want).all(axis=2).sum() == 32 * 32

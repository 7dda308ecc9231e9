"""``-two_sided``: the light loop lights the face a ray sees (docs/EXTENSIONS.md E.15), tested on the inside of a
closed sphere.

A camera and an a5 ``PointLight`` (colour ``c``, no falloff) at the centre of a sphere of Lambert colour
``kd``, no ambient light. SPEC B.3's light loop uses the outward normal, ``clamp(L·N) = 0`` inside: the wall is
black, with or without ``-indirect``. With ``-two_sided`` the normal faces the ray, ``L·N = 1`` at every wall
point, so every wall point shows ``kd c`` directly; ``-indirect N`` adds ``kd`` times the mean of what its rays
see, which is again the same wall, one bounce fewer. The camera hit has ``B`` bounces left, the last level
none, so every pixel is exactly (no variance: every gathered ray sees the same value)

    L_B = c Σ_(m=1..B+1) kd^m          (kd = 0.7, c = 0.3, B = 3: 0.3 · 1.7731 = 0.53193)

and ``L_0 = kd c`` without gathering. The integrating sphere's limit ``kd c/(1 − kd) = 0.7`` is approached as
``B`` grows.
"""

from __future__ import annotations

import numpy as np
import pytest

from a5mi.converters.a5_parser import parse_text
from a5mi.converters.describe import describe
from a5mi.render.options import RenderOptions
from a5mi.render.session import render

KD, C = 0.7, 0.3
SPHERE = f"""PerspectiveCamera {{ center 0 0 0 direction 0.2 -0.1 -1 up 0 1 0 angle 60 }}
Lights {{ numLights 1 PointLight {{ position 0 0 0 color {C} {C} {C} }} }}
Background {{ color 0 0 0 ambientLight 0 0 0 }}
Materials {{ numMaterials 1 Material {{ diffuseColor {KD} {KD} {KD} }} }}
Group {{ numObjects 1 MaterialIndex 0 Sphere {{ center 0 0 0 radius 2 }} }}
"""


def _image(**opts: object) -> np.ndarray:
    o = RenderOptions(width=8, height=8, **opts)  # type: ignore[arg-type]
    return np.asarray(render(describe(parse_text(SPHERE, "inside.txt")), o).image, dtype=np.float64)[..., :3]


@pytest.mark.parametrize("shadows", [False, True])
def test_spec_light_loop_leaves_the_inside_black(variant: str, shadows: bool) -> None:
    assert np.all(_image(shadows=shadows, bounces=3, indirect=1) == 0.0)


@pytest.mark.parametrize(("bounces", "indirect", "shadows"), [(0, 0, False), (3, 1, False), (3, 4, True),
                                                              (5, 1, True)])
def test_two_sided_inside_the_sphere_is_the_bounce_series(variant: str, bounces: int, indirect: int,
                                                          shadows: bool) -> None:
    """Every pixel ``c Σ_(m=1..B'+1) kd^m`` (module docstring; ``B' = B`` with ``-indirect``, 0 without), to
    float32 rounding (1e-5 relative)."""
    levels = bounces if indirect else 0
    want = C * sum(KD ** m for m in range(1, levels + 2))
    got = _image(two_sided=True, shadows=shadows, bounces=bounces, indirect=indirect)
    np.testing.assert_allclose(got, want, rtol=1e-5)


def test_flag_and_its_limits() -> None:
    """``-two_sided`` sets the option, reaches ``a5_whitted`` only when on (course dicts unchanged) and is
    refused with the physically based integrators (they light both faces already)."""
    from a5mi import cli
    from a5mi.commands.render import render_options
    from a5mi.platform.errors import UsageError

    args = cli.parse_a5_args(["-input", "s.txt", "-output", "o.png", "-two_sided", "-indirect", "2"])
    assert render_options(args).two_sided
    assert RenderOptions(two_sided=True).integrator_params()["two_sided"] is True
    assert "two_sided" not in RenderOptions().integrator_params()
    with pytest.raises(UsageError, match="-two_sided is a mode of the whitted integrator"):
        cli.parse_a5_args(["-input", "s.txt", "-output", "o.png", "-two_sided", "-integrator", "path"])

"""Every numeric keyword of docs/EXTENSIONS.md E.1-E.24 at its documented bounds and at float32's edges: the scene
is refused at the value's line (a positioned :class:`SceneError`) or renders a finite image (no NaN, no inf), for
the integrator and flags the keyword is used with. Each keyword sits on its own line of the scene, so a refusal
must name that line. The fast tier runs the values that once gave NaN images from accepted input (milled
``alphaU 1e-38``, ``dispersion 1e30 1e30``, ``1e20 0``, ``3e38 0``) and each keyword's documented bounds; the
``slow`` tier adds float32's edges for every keyword (``pytest -m slow``)."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import pytest

#: float32's edges and beyond: zero of both signs, the smallest subnormal and normal, the largest finite values,
#: a huge value whose square overflows, and 3.5e38 (beyond float32: stored as inf unless refused).
EDGES = ("0", "-0", "1e-45", "1e-38", "-1e-38", "1e30", "-1e30", "3.4e38", "-3.4e38", "3.5e38")

SCENE = """PerspectiveCamera {
    center 0 0 5
    direction 0 0 -1
    up 0 1 0
    angle 30
CAMERA
}
Lights {
    numLights 2
    PointLight { position 1 2 3 color 0.6 0.6 0.6 }
LIGHT
}
Background { color 0.2 0.3 0.4 ambientLight 0.1 0.1 0.1 }
TOP
Materials {
    numMaterials 2
    Material {
        diffuseColor 0.5 0.5 0.5
        specularColor 0.5 0.5 0.5
MATERIAL
    }
    Material { diffuseColor 0.8 0.8 0.8 }
}
Group {
    numObjects 2
    MaterialIndex 0
    Sphere { center 0 0 0 radius 1 }
    MaterialIndex 1
    Plane { normal 0 1 0 offset -1 }
}
"""
DEFAULT_LIGHT = "    DirectionalLight { direction 0 -1 -1 color 0.3 0.3 0.3 }"


class Keyword(NamedTuple):
    """``slot`` (CAMERA, LIGHT, MATERIAL, TOP) holds ``text`` with ``{v}`` on the line of the keyword under test;
    ``bounds`` are the documented limits and values just past them; ``flags`` the a5 flags it is used with."""

    section: str
    name: str
    slot: str
    text: str
    bounds: tuple[str, ...]
    flags: tuple[str, ...] = ()


SPOT = "    SpotLight {{ position 0 3 0 direction 0 -1 0 color 1 1 1\n        {line}\n    }}"
AREA = "    AreaLight {{ corner -0.5 3 -0.5 edge1 1 0 0 edge2 0 0 1 color 1 1 1\n        {line}\n    }}"
SPHERE_LIGHT = "    SphereLight {{ center 0 3 0 color 1 1 1\n        {line}\n    }}"
WOOD = "        Wood {{ color 1 0 0 color 0 0 1\n        {line}\n        }}"
FOG = "Fog {{ color 0.9 0.9 0.9\n    {line}\n}}"
FOG_DENSITY = "Fog {{ color 0.9 0.9 0.9 density 0.1\n    {line}\n}}"
SSS = "        subsurface {{ preset marble\n        {line}\n        }}"
MILLED = "        milled {{ pattern straight axis 1 0 0\n        {line}\n        }}"
PHOTONS = ("-integrator", "photon", "-photons", "300", "-caustic_photons", "300")

KEYWORDS: tuple[Keyword, ...] = (
    Keyword("E.1", "falloff", "LIGHT", SPOT.format(line="angle 30 falloff {v}"), ("0", "-1e-30", "1e30")),
    Keyword("E.1", "angle", "LIGHT", SPOT.format(line="angle {v}"), ("0", "1e-30", "89.999", "90")),
    Keyword("E.1", "beamWidth", "LIGHT", SPOT.format(line="angle 30 beamWidth {v}"), ("0", "1e-30", "30", "31")),
    Keyword("E.2", "samples", "LIGHT", AREA.format(line="samples {v}"), ("0", "1", "64", "65"), ("-shadows",)),
    Keyword("E.2", "falloff", "LIGHT", AREA.format(line="falloff {v}"), ("0", "-1", "1e30"), ("-shadows",)),
    Keyword("E.2", "edge1", "LIGHT", "    AreaLight { corner -0.5 3 -0.5 color 1 1 1\n"
            "        edge2 0 0 1 edge1 {v} 0 0\n    }", ("0", "1e-30", "1e30"), ("-shadows",)),
    Keyword("E.2", "radius", "LIGHT", SPHERE_LIGHT.format(line="radius {v}"), ("0", "1e-30", "1e30"),
            ("-shadows",)),
    Keyword("E.3", "aperture", "CAMERA", "    aperture {v}", ("0", "-1", "1e30"), ("-spp", "2")),
    Keyword("E.3", "focusDistance", "CAMERA", "    aperture 0.1\n    focusDistance {v}", ("0", "1e-30", "1e30"),
            ("-spp", "2")),
    Keyword("E.4", "roughness", "MATERIAL", "        roughness {v}", ("0", "-1e-30", "1", "1.001"), ("-spp", "2")),
    Keyword("E.4", "glossySamples", "MATERIAL", "        roughness 0.2\n        glossySamples {v}",
            ("0", "1", "64", "65")),
    Keyword("E.5", "-spp", "MATERIAL", "", ("1", "4")),
    Keyword("E.6", "octaves", "MATERIAL", WOOD.format(line="octaves {v}"), ("-1", "0", "31", "32")),
    Keyword("E.6", "frequency", "MATERIAL", WOOD.format(line="frequency {v}"), ("0", "-1e30", "1e30")),
    Keyword("E.6", "amplitude", "MATERIAL", WOOD.format(line="amplitude {v}"), ("0", "-1e30", "1e30")),
    Keyword("E.6", "scale", "MATERIAL", WOOD.format(line="scale {v}"), ("0", "1e-30", "1e30")),
    Keyword("E.8", "density", "TOP", FOG.format(line="density {v}"), ("0", "-1e-30", "1e30")),
    Keyword("E.8", "steps", "TOP", FOG_DENSITY.format(line="steps {v}"), ("0", "1", "1024", "1025")),
    Keyword("E.8", "g", "TOP", FOG_DENSITY.format(line="g {v}"), ("-1", "-0.999", "0.999", "1"),
            ("-shadows", "-media_bounces", "2")),
    Keyword("E.10", "dispersion A", "MATERIAL", "        refractionIndex dispersion {v} 0.0042",
            ("0", "1e-30", "1.8e19", "1e20")),
    Keyword("E.10", "dispersion B", "MATERIAL", "        refractionIndex dispersion 1.5 {v}",
            ("-0.24", "-0.2", "1e18", "1e30")),
    Keyword("E.18", "eta", "MATERIAL", SSS.format(line="eta {v}"), ("0", "1e-30", "1e30"), ("-subsurface", "dipole")),
    Keyword("E.18", "scale", "MATERIAL", SSS.format(line="scale {v}"), ("0", "1e-30", "1e30"),
            ("-subsurface", "walk")),
    Keyword("E.18", "g", "MATERIAL", SSS.format(line="g {v}"), ("-1", "-0.999", "0.999", "1"),
            ("-subsurface", "walk")),
    Keyword("E.18", "samples", "MATERIAL", SSS.format(line="samples {v}"), ("0", "1", "256", "257"),
            ("-subsurface", "dipole")),
    Keyword("E.18", "sigma_a", "MATERIAL", SSS.format(line="sigma_a {v} 0.1 0.1"), ("0", "-1e-30", "1e30"),
            ("-subsurface", "dipole")),
    Keyword("E.20", "alphaU", "MATERIAL", MILLED.format(line="alphaV 0.5 alphaU {v}"), ("0", "1e-38", "1", "1.001")),
    Keyword("E.20", "alphaV", "MATERIAL", MILLED.format(line="alphaU 0.04 alphaV {v}"), ("0", "1e-38", "1", "1.5")),
    Keyword("E.14", "-rr_depth", "MATERIAL", "", ("0", "1"), ("-integrator", "path")),
    Keyword("E.15", "-indirect", "MATERIAL", "", ("1", "127"), ("-bounces", "1")),
    Keyword("E.16", "-photon_k", "MATERIAL", "", ("1", "300"), PHOTONS),
    Keyword("E.16", "-final_gather", "MATERIAL", "", ("0", "4"), PHOTONS),
    Keyword("E.17", "-ppm_radius", "MATERIAL", "", ("0", "1e-30", "1e30"),
            ("-integrator", "ppm", "-photons", "300", "-caustic_photons", "300")),
    Keyword("E.17", "-ppm_alpha", "MATERIAL", "", ("1e-30", "0.5", "1"),
            ("-integrator", "ppm", "-photons", "300", "-caustic_photons", "300", "-spp", "2")),
    Keyword("E.23", "-ic_error", "MATERIAL", "", ("1e-30", "1"),
            ("-integrator", "irradiancecache", "-ic_samples", "6")),
    Keyword("E.23", "-ic_samples", "MATERIAL", "", ("6", "64"), ("-integrator", "irradiancecache")),
)

#: The values that once gave NaN images from accepted input (issue report of a hostile campaign).
ONCE_NAN = {("E.20", "alphaU"): ("1e-38",), ("E.10", "dispersion A"): ("1e20", "3e38"),
            ("E.10", "dispersion B"): ("1e30",)}


def _scene(k: Keyword, value: str) -> tuple[str, list[str], int | None]:
    """The scene text, the a5 flags and the 1-based line of the keyword under test (None: a flag)."""
    if k.name.startswith("-"):
        return _fill(""), [*k.flags, k.name, value], None
    template = _fill(k.text, k.slot)
    line = next(n for n, ln in enumerate(template.splitlines(), 1) if "{v}" in ln)
    return template.replace("{v}", value), list(k.flags), line


def _fill(block: str, slot: str = "") -> str:
    text = SCENE
    for name in ("CAMERA", "LIGHT", "MATERIAL", "TOP"):
        text = text.replace(name + "\n", (block + "\n") if slot == name else ("" if name != "LIGHT" else
                                                                              DEFAULT_LIGHT + "\n"))
    return text


def _cases(slow: bool) -> list[object]:
    out: list[object] = []
    for k in KEYWORDS:
        values = [*k.bounds, *ONCE_NAN.get((k.section, k.name), ())]
        for v in dict.fromkeys(values):
            out.append(pytest.param(k, v, id=f"{k.section}-{k.name}-{v}"))
        if slow:
            for v in EDGES:
                if v not in values:
                    out.append(pytest.param(k, v, id=f"{k.section}-{k.name}-{v}", marks=pytest.mark.slow))
    return out


def _check(tmp_path, k: Keyword, value: str) -> None:  # noqa: ANN001
    from a5mi.cli import parse_a5_args
    from a5mi.cli.render import check_render_args, render_options
    from a5mi.converters.a5_parser import parse_file
    from a5mi.converters.describe import describe
    from a5mi.converters.errors import SceneError
    from a5mi.errors import UserError
    from a5mi.session import render

    text, flags, line = _scene(k, value)
    path = tmp_path / "s.txt"
    path.write_text(text)
    try:
        args = parse_a5_args(["-input", str(path), "-output", str(tmp_path / "o.png"), "-size", "8", "8", *flags])
        check_render_args(args)
    except UserError as exc:  # a flag's value refused by its range: one line naming the flag
        assert line is None and k.name in str(exc), str(exc)
        return
    try:
        desc = describe(parse_file(path))
    except SceneError as exc:
        assert line is not None and exc.loc is not None and exc.loc.line == line, (str(exc), line)
        return
    image = render(desc, render_options(args, count_rays=False)).image
    bad = int((~np.isfinite(image)).any(axis=-1).sum())
    assert bad == 0, f"{bad} of {image.shape[0] * image.shape[1]} pixels are not finite"


@pytest.mark.parametrize("k, value", _cases(slow=True))
def test_a_keyword_at_its_bounds_is_refused_at_its_line_or_renders_finite(tmp_path, variant, k: Keyword,  # noqa: ANN001
                                                                          value: str) -> None:
    _check(tmp_path, k, value)

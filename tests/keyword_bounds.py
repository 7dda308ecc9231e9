"""Every numeric keyword of docs/EXTENSIONS.md E.1-E.24 with its documented bounds (values at and just past
them) and float32's edges, and the scene that holds one of them on its own line: shared by the keyword sweep
(tests/converters/test_keyword_sweep.py) and the ``keyword`` mutants of ``make fuzz`` (tests/fuzzing.py)."""

from __future__ import annotations

from typing import NamedTuple

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

#: The values that once gave NaN images from accepted input (found by a hostile campaign).
ONCE_NAN = {("E.20", "alphaU"): ("1e-38",), ("E.10", "dispersion A"): ("1e20", "3e38"),
            ("E.10", "dispersion B"): ("1e30",)}


def scene_of(k: Keyword, value: str) -> tuple[str, list[str], int | None]:
    """The scene text, the a5 flags and the 1-based line of the keyword under test (None: a flag)."""
    if k.name.startswith("-"):
        return fill(""), [*k.flags, k.name, value], None
    template = fill(k.text, k.slot)
    line = next(n for n, ln in enumerate(template.splitlines(), 1) if "{v}" in ln)
    return template.replace("{v}", value), list(k.flags), line


def fill(block: str, slot: str = "") -> str:
    text = SCENE
    for name in ("CAMERA", "LIGHT", "MATERIAL", "TOP"):
        text = text.replace(name + "\n", (block + "\n") if slot == name else ("" if name != "LIGHT" else
                                                                              DEFAULT_LIGHT + "\n"))
    return text

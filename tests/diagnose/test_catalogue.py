"""The catalogue's data (a5mi/diagnose/mistakes.tsv, docs/MISTAKES.md "The catalogue") read by
:func:`a5mi.diagnose.catalogue.read_catalogue`."""

from __future__ import annotations

import pytest

from a5mi.diagnose.catalogue import CATALOGUE, NEEDS, read_catalogue
from a5mi.render.options import MISTAKES

pytestmark = pytest.mark.unit  # the fast tier (`make check`): no Mitsuba, no child process

HEADER = "# a comment\nname\tsection\tchange\tsymptom\tneeds\n"


def test_every_mistake_once_in_the_documented_order() -> None:
    assert tuple(m.name for m in CATALOGUE) == MISTAKES
    assert all(m.section and m.change and m.symptom and set(m.needs) <= set(NEEDS) for m in CATALOGUE)


def test_a_line_reads_into_a_mistake() -> None:
    (m,) = read_catalogue(HEADER + "no_shadows\tB.3 S\tS = 1\tno shadows\tshadows,lights2\n")
    assert (m.name, m.section, m.change, m.symptom, m.needs) == ("no_shadows", "B.3 S", "S = 1", "no shadows",
                                                                 ("shadows", "lights2"))
    (any_scene,) = read_catalogue(HEADER + "rounding\tB.1\tround\thalf a level\t\n")
    assert any_scene.needs == ()


@pytest.mark.parametrize("body", ["a\tB.1\tc\ts\n", "a\tB.1\tc\ts\t\na\tB.1\tc\ts\t\n", "a\tB.1\tc\ts\twings\n"])
def test_malformed_lines_are_refused(body: str) -> None:
    """Four fields, a name twice, a need :data:`NEEDS` does not list."""
    with pytest.raises(ValueError):
        read_catalogue(HEADER + body)
    with pytest.raises(ValueError):
        read_catalogue("name\tsection\n" + body)


PLACED = """PerspectiveCamera {{ center 0 0 5 direction 0 0 -1 up 0 1 0 angle 50 }}
Lights {{ numLights 1 DirectionalLight {{ direction 0 0 -1 color 1 1 1 }} }}
Background {{ color 0 0 0 ambientLight 0 0 0 }}
Materials {{ numMaterials 1 Material {{ diffuseColor 1 1 1 }} }}
Group {{ numObjects 2 MaterialIndex 0 Plane {{ normal 0 1 0 offset -1 }}
  Transform {{ {steps} {obj} }} }}
"""
SPHERE = "Sphere { center 0 0 0 radius 1 }"
PLANE = "Plane { normal 0 0 1 offset -2 }"
TRIANGLE = "Triangle { vertex0 0 0 0 vertex1 1 0 0 vertex2 0 1 0 }"


@pytest.mark.parametrize("obj", [SPHERE, PLANE, TRIANGLE])
@pytest.mark.parametrize("steps,traits", [
    ("Translate 1 2 3", set()),
    ("XRotate 30 Rotate { 1 1 0 25 } Translate 1 0 0", set()),          # orthonormal: neither mistake shows
    ("UniformScale 0.5 ZRotate 40", {"scaled"}),                        # a similarity: normal_by_m does not show
    ("YRotate 20 Scale 2 1 1", {"scaled", "nonuniform"}),
    ("Matrix4f { 1 0 0 0  0.5 1 0 0  0 0 1 0  0 0 0 1 }", {"scaled", "nonuniform"}),   # a shear
])
def test_placing_traits_of_each_primitive(obj: str, steps: str, traits: set[str]) -> None:
    """docs/MISTAKES.md's ``scaled`` / ``nonuniform`` needs: from a sphere's or plane's matrix, or a triangle's
    world-to-object rows; the world plane outside any Transform adds none."""
    from a5mi.converters.a5_parser import parse_text
    from a5mi.converters.describe import describe
    from a5mi.diagnose.catalogue import placing_traits

    assert placing_traits(describe(parse_text(PLACED.format(steps=steps, obj=obj)))) == traits

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

"""README.md, a newcomer's first page: at most 250 lines; its quick start begins with what works without the
course data (the project's own scenes) and marks the block of commands that need it (docs/INSTALL.md "The
course data")."""

from __future__ import annotations

from pathlib import Path

import pytest

pytestmark = pytest.mark.unit  # the fast tier (`make check`): no Mitsuba, no child process

README = Path(__file__).resolve().parent.parent / "README.md"


def test_readme_fits_and_its_quick_start_begins_without_the_course_data() -> None:
    text = README.read_text()
    assert len(text.splitlines()) <= 250
    quick = text[text.index("## Quick start"):text.index("## The live page")]
    first, mark, rest = quick.partition("**With the course data**")
    assert mark and "A5_DATA" in rest and "docs/INSTALL.md#the-course-data" in rest
    for course in ("../shared", "scene06", "scene10", "scene11", "scene12", "reference/", "a5mi fidelity"):
        assert course not in first, course
    assert "a5 -input demo.txt" in first

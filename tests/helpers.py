"""Helpers shared by the test folders (importable from any of them: tests/ is on ``sys.path`` through its
conftest): the project's folders, and a5 scene text rendered in-process."""

from __future__ import annotations

from pathlib import Path

#: tests/
TESTS = Path(__file__).resolve().parent
#: the project root
ROOT = TESTS.parent
#: the project's own scenes (scenes/)
SCENES = ROOT / "scenes"

"""SPEC constants and the cube-face search shared by the converter's file check and the ``a5_cubemap`` plugin."""

from __future__ import annotations

from pathlib import Path

import pytest

from a5mi import spec

pytestmark = pytest.mark.unit  # the fast tier (`make check`): no Mitsuba, no child process


def test_a4_cube_face_search_prefers_the_listed_extensions_then_any_other(tmp_path: Path) -> None:
    """Moved from the old shared-constants test: the converter and the plugin both call this one function."""
    (tmp_path / "left.PNG").write_bytes(b"x")
    (tmp_path / "right.bmp").write_bytes(b"x")
    (tmp_path / "right.zzz").write_bytes(b"x")
    (tmp_path / "front.zzz").write_bytes(b"x")
    assert spec.find_cube_face(tmp_path, "left") == tmp_path / "left.PNG"
    assert spec.find_cube_face(tmp_path, "right") == tmp_path / "right.bmp"
    assert spec.find_cube_face(tmp_path, "front") == tmp_path / "front.zzz"
    assert spec.find_cube_face(tmp_path, "up") is None


def test_spec_values() -> None:
    assert spec.TMIN == spec.MIRROR_THRESHOLD == 0.001
    assert spec.FRESNEL_MODES == ("a5", "schlick", "exact")
    assert spec.CUBE_FACES == ("left", "right", "up", "down", "front", "back")

"""Constants that must agree across the layers that cannot import each other (ARCHITECTURE.md: converters and
plugins are independent; a5mi avoids importing Mitsuba before parsing)."""

from __future__ import annotations

import pytest


def test_cube_face_search_agrees_between_converter_check_and_plugin(variant, tmp_path) -> None:
    """check_files promises to find cube faces exactly as a5_cubemap does."""
    from a5mi.converters import to_mitsuba
    from a5mi.plugins import cubemap

    assert tuple(to_mitsuba.IMAGE_EXTENSIONS) == tuple(cubemap.EXTENSIONS)
    (tmp_path / "left.PNG").write_bytes(b"x")
    (tmp_path / "right.bmp").write_bytes(b"x")
    for face in ("left", "right"):
        assert to_mitsuba.find_cube_face(tmp_path, face) == cubemap.find_face(tmp_path, face)
    assert to_mitsuba.find_cube_face(tmp_path, "up") is None
    with pytest.raises(ValueError, match="face 'up' not found"):
        cubemap.find_face(tmp_path, "up")

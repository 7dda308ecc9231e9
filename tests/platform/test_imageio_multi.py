"""SPEC B.1 outputs: a5mi.platform.imageio.write_images is all-or-nothing for several images (-output, -normals,
-depth): every temporary is written before any target is replaced."""

from __future__ import annotations

import os

import numpy as np
import pytest

from a5mi.platform import imageio
from a5mi.platform.errors import ImageWriteError

pytestmark = pytest.mark.unit  # the fast tier (`make check`): no Mitsuba, no child process


def _failing_create_for(monkeypatch, marker: str) -> list[str]:
    """Make OpenImageIO fail to create a writer for temporaries whose name contains ``marker``; returns the
    list of temporary names that were created (for the test's checks)."""
    import OpenImageIO as oiio

    real_create = oiio.ImageOutput.create
    created: list[str] = []

    def create(name: str):
        created.append(name)
        return None if marker in os.path.basename(name) else real_create(name)

    monkeypatch.setattr(oiio.ImageOutput, "create", staticmethod(create))
    return created


def test_b1_write_images_is_all_or_nothing_when_the_second_write_fails(tmp_path, monkeypatch) -> None:
    """-output then -normals: the second temporary cannot be written -> the first target keeps its old
    bytes, the second is not created, and no temporary is left (the first one was already written)."""
    first, second = tmp_path / "out.png", tmp_path / "normals.png"
    first.write_bytes(b"old image")
    created = _failing_create_for(monkeypatch, ".normals.")
    with pytest.raises(ImageWriteError, match="normals.png: cannot create a writer"):
        imageio.write_images([(first, np.ones((2, 2, 3))), (second, np.zeros((2, 2, 3)))])
    assert len(created) == 2  # the first temporary was really written before the failure
    assert first.read_bytes() == b"old image"
    assert sorted(os.listdir(tmp_path)) == ["out.png"]


def test_b1_write_images_malformed_third_image_replaces_nothing(tmp_path) -> None:
    paths = [tmp_path / "a.png", tmp_path / "b.exr", tmp_path / "c.png"]
    for p in paths[:2]:
        p.write_bytes(b"old " + p.name.encode())
    with pytest.raises(ValueError, match="HxWx3"):
        imageio.write_images([(paths[0], np.ones((2, 2, 3))), (paths[1], np.ones((2, 2))),
                              (paths[2], np.ones((2, 2, 7)))])
    assert [p.read_bytes() for p in paths[:2]] == [b"old a.png", b"old b.exr"]
    assert sorted(os.listdir(tmp_path)) == ["a.png", "b.exr"]


def test_b1_write_images_all_succeed(tmp_path) -> None:
    img = np.full((3, 4, 3), 0.5, np.float32)
    paths = [tmp_path / "a.png", tmp_path / "b.exr"]
    paths[0].write_bytes(b"old")
    imageio.write_images([(paths[0], img), (paths[1], img)])
    assert imageio.read_image(paths[0]).tolist() == np.full((3, 4, 3), 127 / 255, np.float32).tolist()
    np.testing.assert_array_equal(imageio.read_image(paths[1]), img)
    assert sorted(os.listdir(tmp_path)) == ["a.png", "b.exr"]

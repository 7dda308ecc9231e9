"""SPEC A.6 meshes with uv: vertices split per distinct (v, vt) pair in lexicographic order, computed once
for check_files + build; A.4 images prefetched in parallel without changing which error is reported."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from a5mi import data_dir
from a5mi.converters import to_mitsuba as tm
from a5mi.converters.obj import load_obj

UV_OBJS = [p for p in sorted(data_dir().rglob("*.obj")) if b"\nvt " in p.read_bytes()]


@pytest.mark.skipif(not UV_OBJS, reason="course data not found (set A5_DATA)")
@pytest.mark.parametrize("path", UV_OBJS, ids=lambda p: p.name)
def test_a6_uv_split_is_the_lexicographic_pair_order(path: Path) -> None:
    obj = load_obj(path)
    assert obj.face_texcoords is not None and obj.texcoords is not None
    pairs = np.stack([obj.faces.ravel(), obj.face_texcoords.ravel()], axis=1)
    uniq, inverse = np.unique(pairs, axis=0, return_inverse=True)  # the reference: rows sorted by (v, vt)
    m = np.diag([2.0, 1.0, 1.0, 1.0])
    data = tm.mesh_from_obj("mesh_000", obj, m)
    np.testing.assert_array_equal(data.faces, inverse.reshape(-1, 3).astype(np.uint32))
    np.testing.assert_array_equal(data.texcoords, obj.texcoords[uniq[:, 1]])
    np.testing.assert_array_equal(data.positions, obj.vertices[uniq[:, 0]] * [2.0, 1.0, 1.0])
    assert tm.mesh_from_obj("mesh_000", obj, m) is data  # check_files then build: computed once
    assert tm.mesh_from_obj("mesh_000", obj, np.eye(4)) is not data


def test_a4_prefetch_fills_the_cache_and_drops_errors(tmp_path: Path) -> None:
    from a5mi import imageio

    good = [tmp_path / f"g{i}.png" for i in range(3)]
    for i, p in enumerate(good):
        imageio.write_image(p, np.full((2, 3, 3), (i + 0.5) / 255.0))
    bad = tmp_path / "bad.png"
    bad.write_bytes(b"not a png at all")
    tm._prefetch_images([*good, bad, tmp_path / "missing.png"])
    for i, p in enumerate(good):
        cached = tm.decoded_image(p)
        assert cached is not None and cached.tolist() == np.full((2, 3, 3), i).tolist()
    assert tm.decoded_image(bad) is None

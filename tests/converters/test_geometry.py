"""SPEC A.6 meshes with uv (converters/geometry.py): vertices split per distinct (v, vt) pair in lexicographic
order, positions baked into world space."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from a5mi import data_dir
from a5mi.converters.geometry import mesh_from_obj
from a5mi.converters.obj import load_obj

pytestmark = pytest.mark.unit  # the fast tier (`make check`): no Mitsuba, no child process

UV_OBJS = [p for p in sorted(data_dir().rglob("*.obj")) if b"\nvt " in p.read_bytes()]


@pytest.mark.course_data
@pytest.mark.parametrize("path", UV_OBJS, ids=lambda p: p.name)
def test_a6_uv_split_is_the_lexicographic_pair_order(path: Path) -> None:
    obj = load_obj(path)
    assert obj.face_texcoords is not None and obj.texcoords is not None
    pairs = np.stack([obj.faces.ravel(), obj.face_texcoords.ravel()], axis=1)
    uniq, inverse = np.unique(pairs, axis=0, return_inverse=True)  # the reference: rows sorted by (v, vt)
    m = np.diag([2.0, 1.0, 1.0, 1.0])
    data = mesh_from_obj(obj, m)
    np.testing.assert_array_equal(data.faces, inverse.reshape(-1, 3).astype(np.uint32))
    np.testing.assert_array_equal(data.texcoords, obj.texcoords[uniq[:, 1]])
    np.testing.assert_array_equal(data.positions, obj.vertices[uniq[:, 0]] * [2.0, 1.0, 1.0])
    assert data.has_uv and not data.positions.flags.writeable  # shared read-only by every back end

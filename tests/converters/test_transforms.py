"""SPEC A.6: every transform keyword against hand-computed matrices, composition order, the Matrix4f quirk."""

from __future__ import annotations

import math

import numpy as np
import pytest

from a5mi.converters import transforms as t
from a5mi.converters.a5_parser import parse_text

pytestmark = pytest.mark.unit  # the fast tier (`make check`): no Mitsuba, no child process

S = math.sqrt(0.5)  # sin 45 = cos 45


def test_a6_translate_scale_uniform_scale() -> None:
    assert t.translate(1, 2, 3).tolist() == [[1, 0, 0, 1], [0, 1, 0, 2], [0, 0, 1, 3], [0, 0, 0, 1]]
    assert t.scale(2, 3, 4).tolist() == [[2, 0, 0, 0], [0, 3, 0, 0], [0, 0, 4, 0], [0, 0, 0, 1]]
    assert t.uniform_scale(5).tolist() == t.scale(5, 5, 5).tolist()


def test_a6_axis_rotations_are_right_handed() -> None:
    # XRotate 90: y -> z; YRotate 90: z -> x; ZRotate 90: x -> y.
    assert np.allclose(t.x_rotate(90), [[1, 0, 0, 0], [0, 0, -1, 0], [0, 1, 0, 0], [0, 0, 0, 1]], atol=1e-15)
    assert np.allclose(t.y_rotate(90), [[0, 0, 1, 0], [0, 1, 0, 0], [-1, 0, 0, 0], [0, 0, 0, 1]], atol=1e-15)
    assert np.allclose(t.z_rotate(90), [[0, -1, 0, 0], [1, 0, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]], atol=1e-15)
    assert np.allclose(t.z_rotate(45)[:3, :3], [[S, -S, 0], [S, S, 0], [0, 0, 1]])


def test_a6_rotate_normalises_its_axis_and_matches_the_axis_rotations() -> None:
    assert np.allclose(t.rotate((0, 0, 7), 30), t.z_rotate(30))
    assert np.allclose(t.rotate((2, 0, 0), -60), t.x_rotate(-60))
    # 120 degrees about (1,1,1) permutes the axes: x -> y -> z -> x.
    r = t.rotate((1, 1, 1), 120)
    assert np.allclose(r[:3, :3], [[0, 0, 1], [1, 0, 0], [0, 1, 0]], atol=1e-15)
    with pytest.raises(ValueError):
        t.rotate((0, 0, 0), 10)


def test_a6_post_multiplication_last_listed_applies_first() -> None:
    m = t.compose([("Translate", (1, 0, 0)), ("Scale", (2, 2, 2))])
    assert t.transform_points(m, np.array([1.0, 0, 0])).tolist() == [3.0, 0.0, 0.0]
    m2 = t.compose([("Scale", (2, 2, 2)), ("Translate", (1, 0, 0))])
    assert t.transform_points(m2, np.array([1.0, 0, 0])).tolist() == [4.0, 0.0, 0.0]


def test_a6_matrix4f_reads_columns_and_pre_multiplies() -> None:
    g = t.matrix4f_columns([1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 5, 6, 7, 1])
    assert g.tolist() == [[1, 0, 0, 5], [0, 1, 0, 6], [0, 0, 1, 7], [0, 0, 0, 1]]
    # Scale 2 then Matrix4f(translate 5 6 7): pre-multiplied, so M = G * S: (1,0,0) -> (2+5, 6, 7).
    m = t.compose([("Scale", (2, 2, 2)), ("Matrix4f", tuple(g.T.ravel()))])
    assert m.tolist() == [[2, 0, 0, 5], [0, 2, 0, 6], [0, 0, 2, 7], [0, 0, 0, 1]]
    # Had it been post-multiplied like the others, S * G would move (0,0,0) to (10, 12, 14).
    assert t.transform_points(m, np.zeros(3)).tolist() == [5.0, 6.0, 7.0]
    # Matrix4f then Translate: M = (G * I) * T.
    m = t.compose([("Matrix4f", tuple(t.scale(2, 2, 2).T.ravel())), ("Translate", (1, 0, 0))])
    assert t.transform_points(m, np.zeros(3)).tolist() == [2.0, 0.0, 0.0]


def test_a6_matrix4f_quirk_through_the_parser() -> None:
    text = """PerspectiveCamera { center 0 0 5 direction 0 0 -1 up 0 1 0 angle 30 }
Materials { numMaterials 1 Material { } }
Group { numObjects 1 MaterialIndex 0
  Transform {
    Translate 1 0 0
    Matrix4f { 0 1 0 0  -1 0 0 0  0 0 1 0  0 0 0 1 }
    Scale 3 3 3
    Sphere { center 0 0 0 radius 1 }
  }
}"""
    scene = parse_text(text, "q.txt")
    # Columns (0,1,0), (-1,0,0), (0,0,1): G = ZRotate 90. M = G * T(1,0,0) * S(3).
    expected = t.z_rotate(90) @ t.translate(1, 0, 0) @ t.scale(3, 3, 3)
    assert np.allclose(scene.objects[0].to_world, expected, atol=1e-15)
    assert np.allclose(t.transform_points(expected, np.array([1.0, 0, 0])), [0, 4, 0], atol=1e-15)


def test_b3_normal_matrix_is_inverse_transpose() -> None:
    m = t.scale(2, 1, 1)
    n = t.normal_matrix(m)
    assert n.tolist() == [[0.5, 0, 0], [0, 1, 0], [0, 0, 1]]
    # The plane x + y = const: normal (1,1,0) -> (0.5, 1, 0), still perpendicular to mapped tangents.
    tangent = np.array([1.0, -1, 0]) @ m[:3, :3].T  # a direction: the upper 3x3 only
    assert float(n @ np.array([1.0, 1, 0]) @ tangent) == 0.0


def test_similarity_detection() -> None:
    assert t.similarity_scale(t.z_rotate(30) @ t.uniform_scale(2.5) @ t.translate(1, 2, 3)) == pytest.approx(2.5)
    assert t.similarity_scale(t.z_rotate(45) @ t.scale(1, 0.2, 1)) is None
    assert t.similarity_scale(t.scale(-1, -1, -1)) == pytest.approx(1.0)

"""Mesh hits evaluated with the sample solution's own triangle test (plugins/emulation/triangle_rule.py).

The binary solves ``[a−b | a−c | d] (β, γ, t) = a − o`` in float32 with vecmath's cofactor inverse and
accepts ``t >= tmin`` (not strictly greater). For a ray that leaves a triangle at a grazing angle its ``t``
for that same triangle is rounding noise, which can land above tmin: the binary then re-hits the triangle
the ray starts on (scene06's bunny: 4 of its 5 differing pixels; the fifth is the converse). The
expectations below are hand-computed (exact small numbers) or come from an independent numpy float32
evaluation of the formula, written out here.
"""

from __future__ import annotations

import numpy as np

from a5mi.converters import octree
from a5mi.converters.geometry import mesh_from_obj
from a5mi.converters.obj import ObjMesh, binary_corner_normals

F = np.float32
TMIN = F(0.001)


def _scene(vertices, faces, m=None, normals="auto", transformed=False):
    import mitsuba as mi

    from a5mi.converters.to_mitsuba import make_mesh

    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    obj = ObjMesh("probe.obj", v, f)
    data = mesh_from_obj(obj, np.eye(4) if m is None else m, normals, octree.reach_masks(v, f), transformed)
    return mi.load_dict({"type": "scene", "m": make_mesh("m", data)})


def _intersect(scene, o, d, t_min, origin=None):
    """``(valid, t, N)`` of ``octree_rule.intersect`` with the scene's rule table; ``origin``: the table row of
    the face the ray leaves (None: every ray starts behind its origin, the rule's first form)."""
    import mitsuba as mi

    from a5mi.plugins.emulation import octree_rule, triangle_rule

    table = triangle_rule.rule_table(scene)
    si, offset, _ = octree_rule.intersect(scene, mi.Point3f(*[float(x) for x in o]),
                                          mi.Vector3f(*[float(x) for x in d]), mi.Float(float(t_min)),
                                          mi.Bool(True), table, None if origin is None else mi.UInt32(origin))
    valid = bool(si.is_valid()[0])
    t = F(np.array(si.t + offset)[0])
    n = np.array(si.sh_frame.n, dtype=np.float32).ravel()
    return valid, t, n


def _binary_solve(a, b, c, o, d):
    """(β, γ, t) of the binary's Triangle::intersect in numpy float32 (SPEC formula, cofactor inverse)."""
    a, b, c, o, d = (np.asarray(x, dtype=F) for x in (a, b, c, o, d))
    m = np.array([[a[0] - b[0], a[0] - c[0], d[0]], [a[1] - b[1], a[1] - c[1], d[1]],
                  [a[2] - b[2], a[2] - c[2], d[2]]], dtype=F)

    def det2(p, q, r, s):
        return F(F(p * s) - F(q * r))

    (m00, m01, m02), (m10, m11, m12), (m20, m21, m22) = m
    c00, c01, c02 = det2(m11, m12, m21, m22), -det2(m10, m12, m20, m22), det2(m10, m11, m20, m21)
    c10, c11, c12 = -det2(m01, m02, m21, m22), det2(m00, m02, m20, m22), -det2(m00, m01, m20, m21)
    c20, c21, c22 = det2(m01, m02, m11, m12), -det2(m00, m02, m10, m12), det2(m00, m01, m10, m11)
    r = F(F(1) / F(F(F(m00 * c00) + F(m01 * c01)) + F(m02 * c02)))
    rhs = (a - o).astype(F)

    def row(x, y, z):
        return F(F(F(F(x * r) * rhs[0]) + F(F(y * r) * rhs[1])) + F(F(z * r) * rhs[2]))

    return row(c00, c10, c20), row(c01, c11, c21), row(c02, c12, c22)


TRI = [[0, 0, 0], [2, 0, 0], [0, 2, 0]]


def test_hit_distance_and_flat_normal_inside_a_transform(variant: str) -> None:
    """Exact numbers: the triangle z = 0 scaled by 2 and moved by (1, 0, 0); a ray down from (2, 1, 3)."""
    m = np.diag([2.0, 2.0, 2.0, 1.0])
    m[0, 3] = 1.0
    valid, t, n = _intersect(_scene(TRI, [[0, 1, 2]], m, transformed=True), (2, 1, 3), (0, 0, -1), 0.0)
    assert valid and t == F(3.0)
    assert n.tolist() == [0.0, 0.0, 1.0]


def test_tmin_test_is_not_strict(variant: str) -> None:
    """From z = 0.001f straight down: the binary's t is exactly 0.001f (det = -4, r = -1/4), a hit since
    its test is ``t >= tmin``; from z = 2^-10 < 0.001 the only hit lies below tmin: a miss."""
    scene = _scene(TRI, [[0, 1, 2]])
    o = (0.5, 0.5, float(TMIN))
    assert _binary_solve(*TRI, o, (0, 0, -1))[2] == TMIN
    valid, t, _ = _intersect(scene, o, (0, 0, -1), TMIN)
    assert valid and t == TMIN
    valid, _, _ = _intersect(scene, (0.5, 0.5, 2.0**-10), (0, 0, -1), TMIN)
    assert not valid


def test_grazing_ray_re_hits_the_triangle_it_leaves(variant: str) -> None:
    """A ray starting on a triangle and leaving it at 1e-5 rad: the exact intersection lies behind the origin
    (t ≈ -0.0071), but the binary's float32 t for that triangle is 0.0234375 >= tmin, so it re-hits it
    there. a5mi reports the same hit at the same t (Mitsuba alone reports nothing)."""
    tri = np.array([[0.3, -0.2, 0.1], [1.7, 0.4, -0.3], [0.2, 1.1, 0.6]], dtype=F)
    o = np.array([0.6956666111946106, 0.3893588185310364, 0.1343245804309845], dtype=F)
    d = np.array([0.8890007138252258, 0.3810005187988281, -0.2540006637573242], dtype=F)
    t64 = tri.astype(np.float64)
    n = np.cross(t64[1] - t64[0], t64[2] - t64[0])
    assert -0.01 < np.dot(t64[0] - o, n) / np.dot(d.astype(np.float64), n) < -0.005
    beta, gamma, t_binary = _binary_solve(*tri, o, d)
    assert t_binary == F(0.0234375) and beta >= 0 and gamma >= 0 and beta + gamma <= 1
    valid, t, _ = _intersect(_scene(tri.astype(np.float64), [[0, 1, 2]]), o, d, TMIN)
    assert valid and t == t_binary
    # The render kernel's form: the ray names the face it leaves (table row 1), which is tested directly.
    valid, t, _ = _intersect(_scene(tri.astype(np.float64), [[0, 1, 2]]), o, d, TMIN, origin=1)
    assert valid and t == t_binary


def test_origin_face_that_is_not_re_hit_leaves_the_ray_to_mitsuba(variant: str) -> None:
    """A ray leaving face 1 of two parallel triangles (z = 0 and z = -1) straight down: the binary's t for
    the face it leaves is 0 < tmin, so the ray starts at tmin and finds the lower face at t = 1 (its row, 2)."""
    import mitsuba as mi

    from a5mi.plugins.emulation import octree_rule, triangle_rule

    v = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, -1], [1, 0, -1], [0, 1, -1]]
    scene = _scene(v, [[0, 1, 2], [3, 4, 5]])
    table = triangle_rule.rule_table(scene)
    o, d = mi.Point3f(0.25, 0.25, 0.0), mi.Vector3f(0.0, 0.0, -1.0)
    rehit, t0, _ = triangle_rule.evaluate(table, mi.UInt32(1), o, d, mi.Float(TMIN), mi.Bool(True))
    assert not rehit[0] and t0[0] == 0.0
    si, offset, row = octree_rule.intersect(scene, o, d, mi.Float(TMIN), mi.Bool(True), table, mi.UInt32(1))
    assert row[0] == 2 and (si.t + offset)[0] == 1.0
    assert _intersect(scene, (0.25, 0.25, 0.0), (0, 0, -1), TMIN, origin=1)[:2] == (True, F(1.0))


def test_rule_table_rows_are_the_face_attributes(variant: str) -> None:
    """Row r of the table holds face r-1's eleven attribute vectors; shapes without them map to row 0."""
    import mitsuba as mi

    from a5mi.converters.to_mitsuba import make_mesh
    from a5mi.plugins.emulation import triangle_rule

    v = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, -1], [1, 0, -1], [0, 1, -1]]
    mesh = _scene(v, [[0, 1, 2], [3, 4, 5]]).shapes()[0]
    shifted = np.asarray(v, float) + [3.0, 0.0, 0.0]
    plain = make_mesh("plain", mesh_from_obj(ObjMesh("p.obj", shifted, np.array([[0, 1, 2]])),
                                             np.eye(4), "auto", None, False))
    scene = mi.load_dict({"type": "scene", "a": plain, "m": mesh, "s": {"type": "sphere", "center": [10, 0, 0]}})
    table = triangle_rule.rule_table(scene)
    rows = np.asarray(table.rows).reshape(-1, triangle_rule.ROW_FLOATS)
    params = mi.traverse(mesh)
    for k, name in enumerate(triangle_rule.ROW_ATTRIBUTES):
        assert rows[:, 3 * k:3 * k + 3].ravel().tolist() == np.asarray(params[name]).tolist()
    pad = rows[:, 3 * len(triangle_rule.ROW_ATTRIBUTES):]      # the mesh's number (row order), the face, 0
    assert pad.tolist() == [[0.0, 0.0, 0.0], [0.0, 1.0, 0.0]]
    assert triangle_rule.rule_table(scene, table) is table
    hits = scene.ray_intersect(mi.Ray3f(mi.Point3f([3.2, 0.2, 0.2, 10, 0.2], [0.2, 0.2, 0.2, 0, 0.2],
                                                   [5, 0.5, -0.5, 5, -5]),
                                        mi.Vector3f([0] * 5, [0] * 5, [-1, -1, -1, -1, -1])))
    rows = np.asarray(triangle_rule.row_of(table, hits, mi.Bool(True))).tolist()
    assert rows == [0, 1, 2, 0, 0] and np.asarray(hits.is_valid()).tolist() == [True, True, True, True, False]


def test_smooth_normal_is_the_binarys_interpolation(variant: str) -> None:
    """Two triangles sharing an edge, smooth normals: the corner normals are normalize(c1 + c2) on the
    shared edge (c_f the face cross products), and the hit's normal is normalize((α n0 + β n1) + γ n2)
    with the binary's (β, γ), all in float32."""
    v = np.array([[0, 0, 0], [2, 0, 0], [0, 2, 0], [2, 2, 1]], dtype=np.float64)
    f = np.array([[0, 1, 2], [1, 3, 2]])
    corners = binary_corner_normals(v, f, "smooth")
    shared = np.array([0, 0, 4], F) + np.cross(np.array([2, 2, 1], F) - np.array([2, 0, 0], F),
                                                np.array([0, 2, 0], F) - np.array([2, 0, 0], F)).astype(F)
    expect = (shared / np.sqrt(F(F(shared[0] ** 2 + shared[1] ** 2) + shared[2] ** 2))).astype(F)
    assert corners[0, 1].tolist() == expect.tolist() and corners[1, 0].tolist() == expect.tolist()
    o, d = (0.3, 0.5, 3.0), (0.0, 0.0, -1.0)
    beta, gamma, _ = _binary_solve(*v[f[0]], o, d)
    alpha = F(F(F(1) - beta) - gamma)
    n = (F(alpha) * corners[0, 0] + F(beta) * corners[0, 1]).astype(F) + (F(gamma) * corners[0, 2]).astype(F)
    n = (n / np.sqrt(F(F(n[0] * n[0] + n[1] * n[1]) + n[2] * n[2]))).astype(F)
    valid, _, got = _intersect(_scene(v, f, normals="smooth"), o, d, 0.0)
    assert valid and got.tolist() == n.tolist()

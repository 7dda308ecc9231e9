"""World-space geometry of the scene's primitives (SPEC A.6), as Mitsuba needs it (float32, exact unless stated).

* **Meshes** (``TriangleMesh``, A.6) get their vertices baked into world space, ``p_w = M p``. Smooth meshes
  (:func:`.obj.vertex_normals`: more than 120 vertices by default) carry vertex normals ``A n`` with
  ``A = (M⁻¹)ᵀ`` (upper 3x3) and *no* renormalisation: interpolating then normalising commutes with the linear
  map, which is exactly the binary's interpolate / transform / normalise. Flat meshes carry no normals
  (Mitsuba shades with the face normal); as ``(Mp1−Mp0)×(Mp2−Mp0) = det(M)·A n``, the winding is reversed
  when ``det M < 0`` so the face normal keeps the binary's direction ``A n``. Texture coordinates only when
  the OBJ has ``vt`` (vertices are split per distinct (v, vt) pair).
* **Spheres**: a world sphere with centre ``M c`` and radius ``s r`` when ``M`` is a similarity
  (``AᵀA = s² I``, :func:`.transforms.similarity_scale`); otherwise the object-space sphere placed by
  ``to_world = M`` (a sphere with a non-uniform ``to_world`` gives wrong hits in Mitsuba 3.9.1, so the back
  ends instance it).
* **Triangles**: a one-face mesh, as flat meshes above, with the binary's triangle-test rows.
* **Planes** (infinite in the assignment: ``P·n = offset``, n not normalised): the world plane is
  ``π_w = M⁻ᵀ (n, −offset)`` (:func:`world_plane`). a5 renders intersect it exactly, analytically, inside
  ``a5_whitted`` (``plugins/emulation/planes.py``): no geometry stands in for it. Plain Mitsuba (``--stock``) needs a
  finite stand-in: a ``rectangle`` of half-size :data:`PLANE_HALF_SIZE` = 4096 scene units
  (:func:`plane_rectangle_to_world`), centred on the foot of the perpendicular from the camera centre, with
  its frame's z axis along the plane's unit normal. Mitsuba inverts its ``to_world`` in float32, so the hit
  point's error grows with the half-size (measured on a plane tilted by 0.05: 1.3e-2 at 1e7, 2.8e-5 at 1e4,
  3e-6 at 1e3); at 4096 it stays below 1e-5 = tmin/100 (tests/converters/test_to_mitsuba.py). What it cannot do: a
  camera ray that would meet the infinite plane more than ~4096 units away misses the stand-in, i.e. the
  last rows below the horizon (scene10's farthest plane row is hit at t ≈ 16,000) show the background.

Every world-space number handed to Mitsuba (float32) must be finite there (:func:`check_float32`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from a5mi.converters import transforms as tf
from a5mi.converters.errors import SceneSemanticError
from a5mi.converters.model import Placed, Plane, Sphere, Triangle
from a5mi.converters.obj import FLOAT32_MAX, NormalMode, ObjMesh, binary_corner_normals, vertex_normals

#: Half-size of the ``--stock`` rectangle standing in for an infinite plane (scene units; module docstring).
PLANE_HALF_SIZE = 4096.0


def _frozen(a: np.ndarray | None) -> Any:
    if a is not None:
        a.flags.writeable = False
    return a


@dataclass(frozen=True, eq=False)
class MeshData:
    """A triangle mesh in world space: ``positions`` (N, 3) float64, ``faces`` (F, 3) uint32, optional
    ``normals`` (N, 3) and ``texcoords`` (N, 2); the arrays are read-only."""

    positions: np.ndarray
    faces: np.ndarray
    normals: np.ndarray | None = None
    texcoords: np.ndarray | None = None
    #: (F, 12) float32 per face for the binary's octree rule (:mod:`.octree`): the rows of the world-to-object
    #: matrix A = M⁻¹ (upper 3x3, 9 numbers), the two reach-mask words, and 1.0 if some ``Transform``
    #: encloses the mesh, else 0.0 (a ``Triangle``: every pattern reached, 2.0 outside any Transform,
    #: :func:`mesh_from_triangle`).
    octree: np.ndarray | None = None
    #: (F, 21) float32 per face for the binary's triangle test and shading normal (:func:`triangle_rows`,
    #: plugins/emulation/triangle_rule.py); None where :attr:`octree` is None.
    triangles: np.ndarray | None = None

    def __post_init__(self) -> None:
        for a in (self.positions, self.faces, self.normals, self.texcoords, self.octree, self.triangles):
            _frozen(a)

    @property
    def has_uv(self) -> bool:
        """True when the mesh carries texture coordinates (SPEC B.3: only such hits are textured)."""
        return self.texcoords is not None


def _face_normals_flip(faces: np.ndarray, m: np.ndarray) -> np.ndarray:
    """Reverse the winding when det(M) < 0 so the world face normal is ``(M⁻¹)ᵀ n`` (see module doc)."""
    return faces[:, ::-1].copy() if np.linalg.det(m[:3, :3]) < 0 else faces


def octree_rows(reach: np.ndarray, m: np.ndarray, transformed: bool) -> np.ndarray:
    """The (F, 12) :attr:`MeshData.octree` rows for an OBJ with per-face reach masks ``reach`` (F, 2) placed
    with ``M`` (``transformed``: inside some ``Transform``)."""
    a = np.linalg.inv(m[:3, :3]).astype(np.float32).ravel()
    out = np.empty((len(reach), 12), dtype=np.float32)
    out[:, :9], out[:, 9:11], out[:, 11] = a, reach, 1.0 if transformed else 0.0
    return out


def triangle_rows(obj: ObjMesh, m: np.ndarray, normals: NormalMode = "auto") -> np.ndarray:
    """The (F, 21) :attr:`MeshData.triangles` rows of an OBJ placed with ``M``, in the binary's object space:
    the translation column of ``M⁻¹`` (3; its upper 3x3 are the :attr:`MeshData.octree` rows), the face's
    float32 vertices ``v0, v1, v2`` (9) and its corner normals ``n0, n1, n2`` (9,
    :func:`.obj.binary_corner_normals`). ``M⁻¹`` is the float64 inverse rounded once to float32 (the binary
    inverts in float32 with cofactors; equal on scene06's ``Translate``/``Scale``, checked with gdb)."""
    f = np.asarray(obj.faces, dtype=np.int64)
    v = np.asarray(obj.vertices, dtype=np.float32)[f].reshape(len(f), 9)
    n = binary_corner_normals(obj.vertices, f, normals).reshape(len(f), 9)
    out = np.empty((len(f), 21), dtype=np.float32)
    out[:, :3] = np.linalg.inv(m)[:3, 3].astype(np.float32)
    out[:, 3:12], out[:, 12:] = v, n
    return out


def mesh_from_obj(obj: ObjMesh, m: np.ndarray, normals: NormalMode = "auto",
                  reach: np.ndarray | None = None, transformed: bool = True) -> MeshData:
    """World-space :class:`MeshData` for an OBJ placed with ``M`` (module docstring: normals, winding, uv);
    ``reach``: the OBJ's :func:`.octree.reach_masks` (face order is kept), for :attr:`MeshData.octree`."""
    vn = vertex_normals(obj.vertices, obj.faces, normals)
    faces = obj.faces
    positions = obj.vertices
    texcoords = None
    if obj.texcoords is not None and obj.face_texcoords is not None:
        # Split vertices per distinct (v, vt) pair: Mitsuba stores one uv per vertex. The pairs, in
        # lexicographic order, are the sorted keys v·T + vt (0 <= vt < T, checked by load_obj).
        nt = len(obj.texcoords)
        pair_key = faces.ravel().astype(np.int64) * nt + obj.face_texcoords.ravel()
        uniq, inverse = np.unique(pair_key, return_inverse=True)
        faces = inverse.reshape(-1, 3)
        uniq_v, uniq_t = uniq // nt, uniq % nt
        positions = obj.vertices[uniq_v]
        texcoords = obj.texcoords[uniq_t]
        if vn is not None:
            vn = vn[uniq_v]
    world = tf.transform_points(m, positions)
    world_n = None
    if vn is not None:
        world_n = vn @ tf.normal_matrix(m).T  # A n, deliberately not renormalised
    else:
        faces = _face_normals_flip(faces, m)
    rows = None if reach is None else octree_rows(reach, m, transformed)
    tris = None if reach is None else triangle_rows(obj, m, normals)
    return MeshData(world, faces.astype(np.uint32), world_n, texcoords, rows, tris)


#: The reach-mask words of a face every ray pattern reaches (24 bits each, :mod:`.octree`).
ALL_REACHED = float((1 << 24) - 1)


def mesh_from_triangle(tri: Triangle, m: np.ndarray) -> MeshData:
    """One-face world-space mesh with a flat normal (winding reversed when det M < 0), carrying the binary's
    triangle-test rows (plugins/emulation/triangle_rule.py: ``Triangle::intersect`` is the test meshes use) and octree
    rows that every ray reaches (a ``Triangle`` has no octree); the octree row's last number is 2.0 for a
    triangle outside any ``Transform`` (``M`` = I: its rays are not mapped, and a ``-0.0`` direction component
    does not hide it), else 1.0."""
    corners = np.array([tri.vertex0, tri.vertex1, tri.vertex2], dtype=np.float64)
    v = tf.transform_points(m, corners)
    faces = _face_normals_flip(np.array([[0, 1, 2]]), m)
    rows = np.empty((1, 12), dtype=np.float32)
    rows[0, :9] = np.linalg.inv(m[:3, :3]).astype(np.float32).ravel()
    rows[0, 9:11], rows[0, 11] = ALL_REACHED, 2.0 if np.array_equal(m, np.eye(4)) else 1.0
    tris = np.empty((1, 21), dtype=np.float32)
    tris[0, :3] = np.linalg.inv(m)[:3, 3].astype(np.float32)
    tris[0, 3:12] = corners.astype(np.float32).ravel()
    tris[0, 12:] = binary_corner_normals(corners, np.array([[0, 1, 2]]), "flat").reshape(9)
    return MeshData(v, faces.astype(np.uint32), octree=rows, triangles=tris)


def world_plane(plane: Plane, m: np.ndarray) -> tuple[np.ndarray, float]:
    """``(n_w, offset_w)`` with ``P·n_w = offset_w`` the image of ``P·n = offset`` under ``M``
    (planes map by ``M⁻ᵀ``: ``(n_w, −offset_w) = M⁻ᵀ (n, −offset)``)."""
    pi = np.linalg.inv(m).T @ np.array([*plane.normal, -plane.offset], dtype=np.float64)
    return pi[:3], float(-pi[3])


def plane_rectangle_to_world(n: np.ndarray, offset: float, near: np.ndarray,
                             half_size: float = PLANE_HALF_SIZE) -> np.ndarray:
    """``to_world`` of a ``rectangle`` ([-1,1]², z = 0, normal +z) covering the plane ``P·n = offset`` within
    ``half_size`` of the foot of the perpendicular from ``near``; its z axis is ``n/|n|``."""
    nn = float(np.dot(n, n))
    z = n / math.sqrt(nn)
    foot = near - (float(np.dot(n, near)) - offset) / nn * n
    helper = np.array([1.0, 0, 0]) if abs(z[0]) < 0.9 else np.array([0, 1.0, 0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    out = np.eye(4)
    out[:3, 0], out[:3, 1], out[:3, 2], out[:3, 3] = x * half_size, y * half_size, z, foot
    return out


def check_placement(p: Placed) -> None:
    """The object-to-world matrix of ``p`` in float32 must be finite and invertible: nested ``Transform`` s
    whose product is singular or out of float32 range are a :class:`SceneSemanticError` at the primitive."""
    m32 = p.to_world.astype(np.float32)
    det = float(np.linalg.det(m32[:3, :3].astype(np.float64)))
    if not (np.all(np.isfinite(m32)) and math.isfinite(det) and det != 0.0):
        raise SceneSemanticError(f"{type(p.primitive).__name__} is placed by nested Transforms whose product is "
                                 f"{'singular' if det == 0.0 else 'out of float32 range'}", p.primitive.loc)


def check_float32(prim: Any, *values: Any) -> None:
    """Every world-space number handed to Mitsuba (float32) must be finite there: ``|x| <= 3.4028235e38``.
    The parser bounds each number as written; an enclosing ``Transform`` can still scale them past float32
    (``Scale 1e30`` on a vertex at 1e10), which is a :class:`SceneSemanticError` at the primitive."""
    for v in values:
        a = np.asarray(v, dtype=np.float64)
        if not (np.all(np.isfinite(a)) and np.all(np.abs(a) <= FLOAT32_MAX)):
            raise SceneSemanticError(f"{type(prim).__name__} is out of float32 range in world space (the enclosing "
                                     "Transforms scale it beyond 3.4e38)", prim.loc)


def geometry_centre(placed: tuple[Placed, ...], meshes: dict[str, ObjMesh]) -> np.ndarray | None:
    """Centre ``(min + max)/2`` of the world bounding box of the finite geometry (spheres' centres, triangles,
    mesh vertices; planes are infinite), or None when there is none. ``meshes``: OBJ file name -> mesh."""
    pts = []
    for p in placed:
        prim = p.primitive
        if isinstance(prim, Sphere):
            pts.append(tf.transform_points(p.to_world, np.asarray(prim.center))[None])
        elif isinstance(prim, Triangle):
            pts.append(tf.transform_points(p.to_world, np.array([prim.vertex0, prim.vertex1, prim.vertex2])))
        elif not isinstance(prim, Plane):
            pts.append(tf.transform_points(p.to_world, meshes[prim.obj_file].vertices))
    if not pts:
        return None
    allp = np.concatenate(pts)
    return (allp.min(0) + allp.max(0)) / 2

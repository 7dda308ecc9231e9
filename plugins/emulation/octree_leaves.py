"""The sample solution's octree traversal, per ray, for shadow rays with a zero direction component (SPEC A.6).

``a5soln`` intersects a mesh through an octree (Revelles et al.'s parametric traversal; the structure and its
breakdown for zero components: ``a5mi.converters.octree``). The per-face reach masks of plugins/emulation/octree_rule.py
say whether *some* ray with a zero/sign pattern reaches a leaf holding a face; which leaves *one* ray reaches
depends on its finite comparisons, so the masks see faces the binary's traversal for that ray never tests
(a directional light along an axis, a mesh under ``ZRotate 30``: a shadow patch a5soln leaves lit). Here the
traversal is replayed per ray, for the leaves that hold the face a shadow ray meets:

* :func:`build` (numpy, once per scene): the binary's octree on the object-space float32 vertices (root: their
  bounding box; a node splits into 8 when it holds more than 7 triangles and its level is at most 8; a
  triangle goes into every child its bounding box touches, closed intervals; child ``i`` takes the upper half
  of x, y, z for bits 4, 2, 1; midpoints ``(mn + mx)/2`` in float32) and, per face, the leaves holding it as
  paths (3 bits per level from the root);
* :func:`sees` (kernel): the ray in object space (``d' = ((0 + a_0 d_x) + a_1 d_y) + a_2 d_z``: a zero is
  ``+0`` after a Transform), normalised, axes with ``d_k < 0`` mirrored (``o_k = mn_k + mx_k − o_k``, ``a``
  gets bit 4, 2, 1), ``t_k0 = (mn_k − o_k)(1/d_k)``, ``t_k1 = (mx_k − o_k)(1/d_k)``; a ``−0`` component (an
  untransformed mesh) or an origin outside a zero axis's slab misses the root; then, down each leaf path,
  Revelles' ``first_node`` / ``new_node`` sequence of the node (at most 4 children) must contain the path's
  child (index ``digit ^ a``), and no child with an exit ``t_k1 < 0`` is entered. The face is seen when one
  of its leaves is reached.

A zero axis's t values are ``−inf`` / ``+inf`` at the root and NaN from the first midpoint on, and every
comparison with NaN is false. Dr.Jit compiles with fast math, so these values are not computed: each t is a
pair (float, code) with the codes :data:`FIN`, :data:`NEG`, :data:`POS`, :data:`NAN` and the comparisons and
midpoints are written out for them (:func:`_lt`, :func:`_mid`). Checked against a5soln on a bunny under
``ZRotate 30`` lit straight from above: the replay gives the binary's shadow verdict on all 9,777 plane pixels.
"""

from __future__ import annotations

from dataclasses import dataclass

import drjit as dr
import mitsuba as mi
import numpy as np

from a5mi.plugins.syntax import syntax

MAX_TRIG = 7
MAX_LEVEL = 8
#: Triangle references held by leaves, at most, over a scene's distinct rule meshes (meshes with the same
#: object-space triangles, instances of one OBJ under different transforms, share their leaves: their octrees
#: are the same); beyond it no leaf table is built and the reach masks decide (plugins/emulation/octree_rule.py).
MAX_REFS = 2_000_000
FIN, NEG, POS, NAN = 0, 1, 2, 3


@dataclass
class LeafTable:
    """Per table row (face; index ``row − 1``): ``first``, ``count`` into ``codes`` / ``depths`` (its leaves'
    paths); per rule mesh (number in row order): the root box ``mn``, ``mx`` (3 Float arrays each)."""

    first: mi.UInt32
    count: mi.UInt32
    codes: mi.UInt32
    depths: mi.UInt32
    mn: tuple[mi.Float, mi.Float, mi.Float]
    mx: tuple[mi.Float, mi.Float, mi.Float]


def mesh_leaves(tri: np.ndarray, budget: int) -> tuple[np.ndarray, np.ndarray, list[tuple[np.ndarray, int, int]]]:
    """``(mn, mx, leaves)`` of one mesh's octree (module docstring) from its (F, 3, 3) float32 object-space
    triangles: ``leaves`` holds ``(faces, codes, depth)`` per level (the leaves' (face, path) pairs). Built a
    level at a time over (node, face) pairs. ``OverflowError`` past ``budget`` references."""
    tmn, tmx = tri.min(axis=1), tri.max(axis=1)
    mn, mx = tmn.min(axis=0).astype(np.float32), tmx.max(axis=0).astype(np.float32)
    lo, hi = mn[None], mx[None]
    code = np.zeros(1, dtype=np.int64)
    node, face = np.zeros(len(tri), dtype=np.int64), np.arange(len(tri), dtype=np.int64)
    leaves, refs = [], 0
    for level in range(MAX_LEVEL + 2):
        count = np.bincount(node, minlength=len(code))
        leaf = (count <= MAX_TRIG) | (level > MAX_LEVEL)
        done = leaf[node]
        leaves.append((face[done], code[node[done]], level))
        refs += int(done.sum())
        node, face = node[~done], face[~done]
        if refs + 8 * len(face) > budget:
            raise OverflowError
        if not len(face):
            break
        split = np.flatnonzero(~leaf)
        slot = np.full(len(code), -1, dtype=np.int64)
        slot[split] = np.arange(len(split))
        lo, hi, code = lo[split], hi[split], code[split]
        mid = ((lo + hi) / np.float32(2)).astype(np.float32)
        node = slot[node]
        kids_lo, kids_hi, kids_code, pairs_node, pairs_face = [], [], [], [], []
        for i in range(8):
            up = np.array([(i >> 2) & 1, (i >> 1) & 1, i & 1], dtype=bool)
            cmn, cmx = np.where(up, mid, lo).astype(np.float32), np.where(up, hi, mid).astype(np.float32)
            touch = np.all((tmn[face] <= cmx[node]) & (cmn[node] <= tmx[face]), axis=1)
            kids_lo.append(cmn)
            kids_hi.append(cmx)
            kids_code.append(code | (i << (3 * level)))
            pairs_node.append(node[touch] + i * len(split))
            pairs_face.append(face[touch])
        lo, hi, code = np.concatenate(kids_lo), np.concatenate(kids_hi), np.concatenate(kids_code)
        node, face = np.concatenate(pairs_node), np.concatenate(pairs_face)
    return mn, mx, leaves


def build(meshes: list[np.ndarray]) -> LeafTable | None:
    """The :class:`LeafTable` of the rule meshes' (F, 3, 3) object-space triangles, in row order; None past
    :data:`MAX_REFS` references. A mesh whose float32 triangles equal an earlier one's (byte for byte: the same
    octree) gets that one's ``first`` / ``count`` and adds no references."""
    firsts, counts, codes, depths, boxes = [], [], [], [], []
    base = 0
    seen: dict[bytes, tuple[np.ndarray, np.ndarray, tuple[np.ndarray, np.ndarray]]] = {}
    try:
        for tri in meshes:
            tri32 = np.ascontiguousarray(tri, dtype=np.float32)
            key = tri32.tobytes()
            if key in seen:                                   # an instance: its octree is the earlier one's
                first, count, box = seen[key]
                firsts.append(first)
                counts.append(count)
                boxes.append(box)
                continue
            mn, mx, leaves = mesh_leaves(tri32, MAX_REFS)
            boxes.append((mn, mx))
            faces = np.concatenate([f for f, _, _ in leaves]).astype(np.int64)
            code = np.concatenate([c for _, c, _ in leaves])
            depth = np.concatenate([np.full(len(f), d, dtype=np.int64) for f, _, d in leaves])
            order = np.argsort(faces, kind="stable")
            count = np.bincount(faces, minlength=len(tri))
            firsts.append(base + np.concatenate([[0], np.cumsum(count)[:-1]]))
            counts.append(count)
            seen[key] = (firsts[-1], count, (mn, mx))
            codes.append(code[order])
            depths.append(depth[order])
            base += len(faces)
            if base > MAX_REFS:
                return None
    except OverflowError:
        return None
    box = np.array(boxes, dtype=np.float32)               # (meshes, 2, 3)
    out = LeafTable(mi.UInt32(np.concatenate(firsts).tolist()), mi.UInt32(np.concatenate(counts).tolist()),
                    mi.UInt32(np.concatenate(codes).tolist()), mi.UInt32(np.concatenate(depths).tolist()),
                    tuple(mi.Float(box[:, 0, k].tolist()) for k in range(3)),   # type: ignore[arg-type]
                    tuple(mi.Float(box[:, 1, k].tolist()) for k in range(3)))   # type: ignore[arg-type]
    dr.make_opaque(out.first, out.count, out.codes, out.depths, *out.mn, *out.mx)
    return out


def _rank(c: mi.UInt32) -> mi.Int32:
    return dr.select(c == NEG, mi.Int32(-1), dr.select(c == POS, mi.Int32(1), mi.Int32(0)))


def _lt(a: tuple[mi.Float, mi.UInt32], b: tuple[mi.Float, mi.UInt32]) -> mi.Bool:
    """``a < b`` of IEEE floats given as (value, code): false with a NaN, else by value or by infinity."""
    (av, ac), (bv, bc) = a, b
    finite = (ac == FIN) & (bc == FIN)
    return (ac != NAN) & (bc != NAN) & dr.select(finite, av < bv, _rank(ac) < _rank(bc))


def _mid(a: tuple[mi.Float, mi.UInt32], b: tuple[mi.Float, mi.UInt32]) -> tuple[mi.Float, mi.UInt32]:
    """``0.5 (a + b)`` as (value, code): NaN with a NaN or ``−inf + inf``, an infinity wins over a finite."""
    (av, ac), (bv, bc) = a, b
    code = dr.select(ac == FIN, bc, dr.select((bc == FIN) | (bc == ac), ac, mi.UInt32(NAN)))
    return 0.5 * (av + bv), code


def _first_node(t0: list, tm: list) -> mi.UInt32:
    """Revelles' ``first_node`` (the binary's): the entry child of a node from its ``t0`` and midpoints."""
    tx0, ty0, tz0 = t0
    txm, tym, tzm = tm
    yz = _lt(ty0, tx0) & _lt(tz0, tx0)
    xz = ~_lt(ty0, tx0) & _lt(tz0, ty0)
    bits_yz = dr.select(_lt(tym, tx0), 2, 0) | dr.select(_lt(tzm, tx0), 1, 0)
    bits_xz = dr.select(_lt(txm, ty0), 4, 0) | dr.select(_lt(tzm, ty0), 1, 0)
    bits_xy = dr.select(_lt(txm, tz0), 4, 0) | dr.select(_lt(tym, tz0), 2, 0)
    return mi.UInt32(dr.select(yz, bits_yz, dr.select(xz, bits_xz, bits_xy)))


def _new_node(cur: mi.UInt32, tm: list, t1: list) -> mi.UInt32:
    """Revelles' ``new_node`` after child ``cur``: its exit on each axis (``t1`` past the midpoint, else the
    midpoint), the smallest one's neighbour (8: the node is left)."""
    exits, nexts = [], []
    for k, bit in enumerate((4, 2, 1)):
        up = (cur & bit) != 0
        exits.append((dr.select(up, t1[k][0], tm[k][0]), dr.select(up, t1[k][1], tm[k][1])))
        nexts.append(dr.select(up, mi.UInt32(8), cur | bit))
    x, y, z = exits
    go_x = _lt(x, y) & _lt(x, z)
    go_y = ~_lt(x, y) & _lt(y, z)
    return dr.select(go_x, nexts[0], dr.select(go_y, nexts[1], nexts[2]))


def sees(leaves: LeafTable, row: mi.UInt32, mesh: mi.UInt32, a: list[mi.Vector3f], tr: mi.Vector3f,
         transformed: mi.Bool, o: mi.Point3f, d: mi.Vector3f, active: mi.Bool) -> mi.Bool:
    """Whether the binary's traversal of the world ray ``(o, d)`` reaches a leaf holding face ``row`` of rule
    mesh ``mesh`` (``a``: rows of its world-to-object ``A``, ``tr``: ``T``; module docstring). Lanes outside
    ``active`` give False."""
    m = mi.Bool(active) & (row > 0)
    first = dr.gather(mi.UInt32, leaves.first, row - 1, m)
    count = dr.gather(mi.UInt32, leaves.count, row - 1, m)
    mn = [dr.gather(mi.Float, leaves.mn[k], mesh, m) for k in range(3)]
    mx = [dr.gather(mi.Float, leaves.mx[k], mesh, m) for k in range(3)]
    dw = [((0.0 + a[k].x * d.x) + a[k].y * d.y) + a[k].z * d.z for k in range(3)]
    ow = [(((0.0 + a[k].x * o.x) + a[k].y * o.y) + a[k].z * o.z) + tr[k] for k in range(3)]
    dv = [dr.select(transformed, dw[k], d[k]) for k in range(3)]
    ov = [dr.select(transformed, ow[k], o[k]) for k in range(3)]
    length = dr.sqrt((dv[0] * dv[0] + dv[1] * dv[1]) + dv[2] * dv[2])
    dv = [x / length for x in dv]
    mirror = 0
    t0, t1 = [], []
    ok = mi.Bool(m)
    for k, bit in enumerate((4, 2, 1)):
        zero = dv[k] == 0.0
        # After a Transform every zero is +0 (vecmath sums from +0; fast math may drop that +0 here, so the
        # sign of a transformed zero is not read); an untransformed mesh sees d's own signed zeros.
        neg_zero = zero & ~transformed & ((dr.reinterpret_array(mi.UInt32, dv[k]) >> 31) == 1)
        flip = ~zero & (dv[k] < 0.0)
        ok &= ~neg_zero & (~zero | ((mn[k] - ov[k] < 0.0) & (mx[k] - ov[k] > 0.0)))
        ok_k = dr.select(flip, (mn[k] + mx[k]) - ov[k], ov[k])
        inv = 1.0 / dr.select(zero, 1.0, dr.abs(dv[k]))
        mirror = mirror | dr.select(flip, mi.UInt32(bit), 0)
        t0.append(((mn[k] - ok_k) * inv, dr.select(zero, mi.UInt32(NEG), FIN)))
        t1.append(((mx[k] - ok_k) * inv, dr.select(zero, mi.UInt32(POS), FIN)))
    ok &= _lt(_max3(t0), _min3(t1))
    zero_f = (mi.Float(0.0), mi.UInt32(FIN))
    ok &= ~(_lt(t1[0], zero_f) | _lt(t1[1], zero_f) | _lt(t1[2], zero_f))
    return _walk(leaves, first, count, mirror, t0, t1, ok)


def _max3(t: list) -> tuple[mi.Float, mi.UInt32]:
    """max of the root's t0 (zero axes are −inf there and never win)."""
    v = dr.maximum(dr.maximum(dr.select(t[0][1] == FIN, t[0][0], -3e38), dr.select(t[1][1] == FIN, t[1][0], -3e38)),
                   dr.select(t[2][1] == FIN, t[2][0], -3e38))
    return v, mi.UInt32(FIN)


def _min3(t: list) -> tuple[mi.Float, mi.UInt32]:
    """min of the root's t1 (zero axes are +inf there and never win)."""
    v = dr.minimum(dr.minimum(dr.select(t[0][1] == FIN, t[0][0], 3e38), dr.select(t[1][1] == FIN, t[1][0], 3e38)),
                   dr.select(t[2][1] == FIN, t[2][0], 3e38))
    return v, mi.UInt32(FIN)


@syntax
def _walk(leaves: LeafTable, first: mi.UInt32, count: mi.UInt32, mirror: mi.UInt32, t0: list, t1: list,
          ok: mi.Bool) -> mi.Bool:
    """True where some leaf path of the face (``first``, ``count``) is reached from the root ``(t0, t1)``."""
    zero_f = (mi.Float(0.0), mi.UInt32(FIN))
    seen = dr.zeros(mi.Bool, dr.width(first))
    j = mi.UInt32(0)
    r0v, r0c = [t[0] for t in t0], [t[1] for t in t0]
    r1v, r1c = [t[0] for t in t1], [t[1] for t in t1]
    while ok & ~seen & (j < count):
        code = dr.gather(mi.UInt32, leaves.codes, first + j, ok)
        depth = dr.gather(mi.UInt32, leaves.depths, first + j, ok)
        a0v, a0c, a1v, a1c = list(r0v), list(r0c), list(r1v), list(r1c)
        live = mi.Bool(ok)
        level = mi.UInt32(0)
        while live & (level < depth):
            lo = [(a0v[k], a0c[k]) for k in range(3)]
            hi = [(a1v[k], a1c[k]) for k in range(3)]
            tm = [_mid(lo[k], hi[k]) for k in range(3)]
            target = ((code >> (3 * level)) & 7) ^ mirror
            cur = _first_node(lo, tm)
            found = cur == target
            for _ in range(3):
                cur = dr.select(cur < 8, _new_node(cur, tm, hi), cur)
                found |= cur == target
            for k, bit in enumerate((4, 2, 1)):
                up = (target & bit) != 0
                a0v[k], a0c[k] = dr.select(up, tm[k][0], a0v[k]), dr.select(up, tm[k][1], a0c[k])
                a1v[k], a1c[k] = dr.select(up, a1v[k], tm[k][0]), dr.select(up, a1c[k], tm[k][1])
            behind = _lt((a1v[0], a1c[0]), zero_f) | _lt((a1v[1], a1c[1]), zero_f) | _lt((a1v[2], a1c[2]), zero_f)
            live &= found & ~behind
            level += 1
        seen |= live
        j += 1
    return seen

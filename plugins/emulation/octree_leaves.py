"""The sample solution's octree traversal, per ray, for shadow rays with a zero direction component (SPEC A.6).

``a5soln`` intersects a mesh through an octree (Revelles et al.'s parametric traversal; the structure and its
breakdown for zero components: ``a5mi.converters.octree``). The per-face reach masks of plugins/emulation/octree_rule.py
say whether *some* ray with a zero/sign pattern reaches a leaf holding a face; which leaves *one* ray reaches
depends on its finite comparisons, so the masks see faces the binary's traversal for that ray never tests
(a directional light along an axis, a mesh under ``ZRotate 30``: a shadow patch a5soln leaves lit). Here the
traversal is replayed per ray, down to the leaves that hold the face a shadow ray meets:

* :func:`build` (numpy, once per scene): the binary's octree on the object-space float32 vertices (root: their
  bounding box; a node splits into 8 when it holds more than 7 triangles and its level is at most 8; a
  triangle goes into every child its bounding box touches, closed intervals; child ``i`` takes the upper half
  of x, y, z for bits 4, 2, 1; midpoints ``(mn + mx)/2`` in float32), kept as a *node table*: per node, the
  index of its first child (its 8 children are consecutive), 0 for a leaf. Which faces a leaf holds is not
  stored: a node holds face ``f`` exactly when ``f``'s bounding box touches the boxes of the node and of all
  its ancestors, which the search recomputes from the midpoints. The table grows with the nodes, not with the
  (leaf, face) references: the level-9 leaves, which hold most references (bunny_1k: 1,081,591 of 1,179,163),
  are never listed;
* :func:`sees` (kernel): the ray in object space (``d' = ((0 + a_0 d_x) + a_1 d_y) + a_2 d_z``: a zero is
  ``+0`` after a Transform), normalised, axes with ``d_k < 0`` mirrored (``o_k = mn_k + mx_k − o_k``, ``a``
  gets bit 4, 2, 1), ``t_k0 = (mn_k − o_k)(1/d_k)``, ``t_k1 = (mx_k − o_k)(1/d_k)``; a ``−0`` component (an
  untransformed mesh) or an origin outside a zero axis's slab misses the root; then a depth-first search from
  the root enters child ``i`` of a node when Revelles' ``first_node`` / ``new_node`` sequence of the node (at
  most 4 children) contains ``i ^ a``, its exit ``t_k1`` is not ``< 0`` on any axis, and its box touches the
  face's bounding box. The face is seen when the search reaches a leaf. The search keeps only the path (3 bits
  a level) and walks it again from the root at each step, so it needs no stack.

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

from a5mi.platform.arrays import aligned_uint32
from a5mi.plugins.syntax import syntax

MAX_TRIG = 7
MAX_LEVEL = 8
#: Nodes of the table over a scene's distinct rule meshes, at most (4 bytes each in the kernel: 16 MB; bunny_1k
#: makes 177,697, scenes/octree_budget.txt's three meshes 570,075). Meshes
#: with the same object-space triangles (instances of one OBJ under different transforms) share their nodes.
#: Beyond it no table is built and the reach masks decide (plugins/emulation/octree_rule.py).
MAX_NODES = 4_000_000
#: (node, face) pairs of one level while a mesh's table is built, at most. With both budgets the build's
#: numpy peak stays under 170 MiB (measured on the degenerate meshes of tests/converters/test_degenerate_meshes.py,
#: which pass them).
MAX_PAIRS = 4_000_000
FIN, NEG, POS, NAN = 0, 1, 2, 3
#: Child ``i``'s upper halves on x, y, z (bits 4, 2, 1).
_UP = np.array([[(i >> 2) & 1, (i >> 1) & 1, i & 1] for i in range(8)], dtype=bool)


@dataclass
class NodeTable:
    """``child``: per node, its first child's index (the 8 children are consecutive), 0 for a leaf; per rule
    mesh (number in row order): its root's index ``root`` and root box ``mn``, ``mx`` (3 Float arrays each)."""

    child: mi.UInt32
    root: mi.UInt32
    mn: tuple[mi.Float, mi.Float, mi.Float]
    mx: tuple[mi.Float, mi.Float, mi.Float]


def mesh_nodes(tri: np.ndarray, base: int = 0, max_nodes: int = MAX_NODES,
               max_pairs: int = MAX_PAIRS) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(mn, mx, child)`` of one mesh's octree (module docstring) from its (F, 3, 3) float32 object-space
    triangles: ``child`` per node in level order, the first child's index plus ``base`` (0 for a leaf), the
    root first. Built a level at a time over (node, face) pairs down to level 8 (level 9 is all leaves).
    ``OverflowError`` past ``max_nodes`` nodes (``base`` included) or ``max_pairs`` pairs in one level."""
    tmn, tmx = tri.min(axis=1), tri.max(axis=1)
    mn, mx = tmn.min(axis=0).astype(np.float32), tmx.max(axis=0).astype(np.float32)
    lo, hi = mn[None], mx[None]
    node, face = np.zeros(len(tri), dtype=np.int32), np.arange(len(tri), dtype=np.int32)
    levels, nodes = [], base + 1
    for level in range(MAX_LEVEL + 1):
        split = np.flatnonzero(np.bincount(node, minlength=len(lo)) > MAX_TRIG)
        first = np.zeros(len(lo), dtype=np.uint32)
        first[split] = nodes + 8 * np.arange(len(split), dtype=np.uint32)
        levels.append(first)
        nodes += 8 * len(split)
        if nodes > max_nodes:
            raise OverflowError
        if not len(split):
            break
        if level == MAX_LEVEL:                     # the children are level 9: leaves
            levels.append(np.zeros(8 * len(split), dtype=np.uint32))
            break
        rank = np.full(len(lo), -1, dtype=np.int32)
        rank[split] = np.arange(len(split), dtype=np.int32)
        keep = rank[node] >= 0
        node, face = rank[node[keep]], face[keep]
        lo, hi = lo[split], hi[split]
        mid = ((lo + hi) / np.float32(2)).astype(np.float32)
        lo = np.where(_UP[None], mid[:, None], lo[:, None]).reshape(-1, 3)   # child i of split r: 8 r + i
        hi = np.where(_UP[None], hi[:, None], mid[:, None]).reshape(-1, 3)
        fmn, fmx = tmn[face], tmx[face]
        kids, faces, pairs = [], [], 0
        for i in range(8):
            c = node * 8 + i
            touch = np.all((fmn <= hi[c]) & (lo[c] <= fmx), axis=1)
            pairs += int(np.count_nonzero(touch))
            if pairs > max_pairs:
                raise OverflowError
            kids.append(c[touch])
            faces.append(face[touch])
        node, face = np.concatenate(kids), np.concatenate(faces)
    return mn, mx, np.concatenate(levels)


def build(meshes: list[np.ndarray]) -> NodeTable | None:
    """The :class:`NodeTable` of the rule meshes' (F, 3, 3) object-space triangles, in row order; None past
    :data:`MAX_NODES` nodes or :data:`MAX_PAIRS` pairs. A mesh whose float32 triangles equal an earlier one's
    (byte for byte: the same octree) gets that one's root and adds no nodes."""
    roots, boxes, tables = [], [], []
    nodes = 0
    seen: dict[bytes, tuple[int, tuple[np.ndarray, np.ndarray]]] = {}
    try:
        for tri in meshes:
            tri32 = np.ascontiguousarray(tri, dtype=np.float32)
            key = tri32.tobytes()
            if key not in seen:
                mn, mx, child = mesh_nodes(tri32, nodes, MAX_NODES, MAX_PAIRS)
                seen[key] = (nodes, (mn, mx))
                tables.append(child)
                nodes += len(child)
            root, box = seen[key]
            roots.append(root)
            boxes.append(box)
    except OverflowError:
        return None
    box = np.array(boxes, dtype=np.float32)               # (meshes, 2, 3)
    out = NodeTable(mi.UInt32(aligned_uint32(np.concatenate(tables))), mi.UInt32(roots),
                    tuple(mi.Float(box[:, 0, k].tolist()) for k in range(3)),   # type: ignore[arg-type]
                    tuple(mi.Float(box[:, 1, k].tolist()) for k in range(3)))   # type: ignore[arg-type]
    dr.make_opaque(out.child, out.root, *out.mn, *out.mx)
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


def sees(nodes: NodeTable, mesh: mi.UInt32, face: tuple[mi.Vector3f, mi.Vector3f], a: list[mi.Vector3f],
         tr: mi.Vector3f, transformed: mi.Bool, o: mi.Point3f, d: mi.Vector3f, active: mi.Bool) -> mi.Bool:
    """Whether the binary's traversal of the world ray ``(o, d)`` reaches a leaf holding the face of rule mesh
    ``mesh`` whose object-space bounding box is ``face`` (min, max) (``a``: rows of its world-to-object ``A``,
    ``tr``: ``T``; module docstring). Lanes outside ``active`` give False."""
    m = mi.Bool(active)
    root = dr.gather(mi.UInt32, nodes.root, mesh, m)
    mn = [dr.gather(mi.Float, nodes.mn[k], mesh, m) for k in range(3)]
    mx = [dr.gather(mi.Float, nodes.mx[k], mesh, m) for k in range(3)]
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
    return _search(nodes, root, (mn, mx), [face[0][k] for k in range(3)], [face[1][k] for k in range(3)],
                   mirror, t0, t1, ok)

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


def _sequence(t0: list, tm: list, t1: list) -> mi.UInt32:
    """The children (bit ``c`` for mirrored child ``c``) Revelles' traversal enters in a node: ``first_node``,
    then ``new_node`` until the node is left (at most 4 children)."""
    cur = _first_node(t0, tm)
    seq = mi.UInt32(1) << cur
    for _ in range(3):
        cur = dr.select(cur < 8, _new_node(cur, tm, t1), cur)
        seq |= dr.select(cur < 8, mi.UInt32(1) << dr.minimum(cur, 7), 0)
    return seq


def _children(t0: list, t1: list, lo: list, hi: list, fmn: list, fmx: list, mirror: mi.UInt32,
              start: mi.UInt32) -> mi.UInt32:
    """Bit ``i`` for each child ``i >= start`` of the node with t values ``(t0, t1)`` (mirrored frame) and box
    ``(lo, hi)`` that the traversal enters (:func:`_sequence`), whose exit is not behind the origin, and whose
    box touches the face's bounding box ``(fmn, fmx)``."""
    zero_f = (mi.Float(0.0), mi.UInt32(FIN))
    tm = [_mid(t0[k], t1[k]) for k in range(3)]
    seq = _sequence(t0, tm, t1)
    mid = [(lo[k] + hi[k]) * 0.5 for k in range(3)]
    out = mi.UInt32(0)
    for i in range(8):
        c = mirror ^ i
        ok = (((seq >> c) & 1) == 1) & (start <= i)
        for k, bit in enumerate((4, 2, 1)):
            up = (c & bit) != 0
            ok &= ~_lt((dr.select(up, t1[k][0], tm[k][0]), dr.select(up, t1[k][1], tm[k][1])), zero_f)
            cmn, cmx = (mid[k], hi[k]) if i & bit else (lo[k], mid[k])
            ok &= (fmn[k] <= cmx) & (cmn <= fmx[k])
        out |= dr.select(ok, mi.UInt32(1 << i), 0)
    return out


@syntax
def _search(nodes: NodeTable, root: mi.UInt32, box: tuple[list, list], fmn: list, fmx: list, mirror: mi.UInt32,
            t0: list, t1: list, ok: mi.Bool) -> mi.Bool:
    """True where the depth-first search from the root ``(t0, t1)`` (module docstring) reaches a leaf: state
    ``path`` (the child index at level ``l`` in bits ``3l..3l+2``), its ``depth``, and the first child of the
    node at ``path`` still to try (``start``); each step walks the path from the root again."""
    seen = dr.zeros(mi.Bool, dr.width(ok))
    done = ~ok
    path, depth, start = mi.UInt32(0), mi.UInt32(0), mi.UInt32(0)
    r0v, r0c = [t[0] for t in t0], [t[1] for t in t0]
    r1v, r1c = [t[0] for t in t1], [t[1] for t in t1]
    while ~done:
        a0v, a0c, a1v, a1c = list(r0v), list(r0c), list(r1v), list(r1c)
        lo, hi = list(box[0]), list(box[1])
        node = mi.UInt32(root)
        level = mi.UInt32(0)
        while ~done & (level < depth):
            digit = (path >> (3 * level)) & 7
            c = digit ^ mirror
            for k, bit in enumerate((4, 2, 1)):
                tmv, tmc = _mid((a0v[k], a0c[k]), (a1v[k], a1c[k]))
                up = (c & bit) != 0
                a0v[k], a0c[k] = dr.select(up, tmv, a0v[k]), dr.select(up, tmc, a0c[k])
                a1v[k], a1c[k] = dr.select(up, a1v[k], tmv), dr.select(up, a1c[k], tmc)
                mid = (lo[k] + hi[k]) * 0.5
                up_box = (digit & bit) != 0
                lo[k], hi[k] = dr.select(up_box, mid, lo[k]), dr.select(up_box, hi[k], mid)
            node = dr.gather(mi.UInt32, nodes.child, node, ~done) + digit
            level += 1
        leaf = ~done & (dr.gather(mi.UInt32, nodes.child, node, ~done) == 0)
        seen |= leaf
        done |= leaf
        valid = _children([(a0v[k], a0c[k]) for k in range(3)], [(a1v[k], a1c[k]) for k in range(3)], lo, hi,
                          fmn, fmx, mirror, start)
        down = ~done & (valid != 0)
        up = ~done & (valid == 0)
        done |= up & (depth == 0)
        up &= depth > 0
        back = dr.select(up, depth - 1, depth)
        last = (path >> (3 * back)) & 7
        path = dr.select(down, path | (dr.tzcnt(valid) << (3 * depth)), path)
        path = dr.select(up, path & ~(mi.UInt32(7) << (3 * back)), path)
        start = dr.select(down, 0, dr.select(up, last + 1, start))
        depth = dr.select(down, depth + 1, back)
    return seen

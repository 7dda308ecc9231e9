"""The sample solution's mesh octree, and which triangles it reaches for rays with a zero direction component.

``a5soln`` intersects a ``TriangleMesh`` through an octree (Revelles et al.'s parametric traversal; the
course's ``octree.cpp``): built on the object-space vertices (float32), a node splits into 8 when it holds
more than 7 triangles and its level is at most 8; a triangle goes into every child whose box its bounding
box touches (closed intervals). The traversal normalises the object-space direction, mirrors every axis
with ``d_k < 0`` and computes ``t_k0 = (mn_k - o_k) / d_k``, ``t_k1 = (mx_k - o_k) / d_k`` (``1/d_k`` first).
For every ray whose direction has no zero component it visits every leaf the ray crosses, so the result is
the exact nearest hit. A zero component breaks it (measured against the binary, SPEC A.6, C):

* ``d_k = -0.0`` (not mirrored, ``1/d_k = -inf``) makes the root slab test fail: **the mesh is invisible**
  to that ray. Only an untransformed mesh can see a ``-0.0``: vecmath's ``Matrix4f * Vector4f`` sums from
  ``+0``, so after any ``Transform`` every zero component is ``+0``;
* ``d_k = +0.0`` gives ``t_k0 = -inf``, ``t_k1 = +inf`` and NaN midpoints, and every comparison with NaN is
  false, so the traversal never steps along that axis (and, with two zero axes, steps in odd patterns): it
  reaches only some leaves. :func:`reach_masks` runs the traversal's own decision code with the zero axes'
  actual values (``-inf``, ``+inf``, NaN) and every possible outcome of the comparisons between finite axes,
  and marks each triangle that lies in a reachable leaf.

The result per triangle is a bit mask over *patterns*: slot ``(zmask - 1) * 8 + neg`` with ``zmask`` the
zero axes (x=1, y=2, z=4; 1..6) and ``neg`` the finite axes with a negative component (same bits). A hit
on a triangle whose slot bit is 0 is one the binary does not see.

**Bounds.** The binary builds its whole octree up front and has no other leaf rule, so a mesh with more than
:data:`MAX_TRIG` triangles sharing one region (8 coincident faces, thin faces crossing at a point) makes
every node there split down to level 9, about 8^9 nodes: ``a5soln`` itself runs out of memory or time on it
(8 copies of one triangle: 1.7 GB and still building at 60 s; the two over-budget meshes of
tests/converters/test_degenerate_meshes.py, 300 slivers and 30 copies of an 800-face grid: 1.1-1.2 GB and not done at
60 s). Here nodes split only when the traversal visits them, a node whose triangles are all reached already
is not entered (the reach set is the union of the reachable leaves' triangles, and a leaf holds a subset of
its ancestors'), and the work has a budget: :data:`MAX_REFS` triangle references held by split nodes,
:data:`MAX_STATES` traversal states and :data:`MAX_NODES` nodes. Over budget every face is marked as reached
by every pattern (the mesh is intersected exactly, except that a ``-0.0`` component still hides it,
plugins/emulation/octree_rule.py) and :func:`reach_masks` reports the fallback, which the converter turns into one
warning at the mesh's ``obj_file`` (SPEC A.6, TriangleMesh).
"""

from __future__ import annotations

import hashlib
import math
import os
import stat
import zlib
from collections.abc import Callable
from pathlib import Path

import numpy as np

from a5mi import cache_dir
from a5mi.converters.errors import FileLoc

MAX_TRIG = 7
MAX_LEVEL = 8
#: Budget (module docstring): triangle references held by split nodes' children and traversal states visited
#: over the 27 patterns. The course meshes need at most 0.29 M and 12 k (sibenik2.obj, 33,344 faces; vase:
#: 98 k, 6.5 k); the budget costs ~10 s at most. Over it, :func:`reach_masks` falls back to "every face
#: reached".
MAX_REFS = 2_000_000
MAX_STATES = 100_000
#: Budget on the nodes made by splits (~500 bytes each; the course meshes make at most 25 k: sibenik2.obj).
MAX_NODES = 200_000
#: Pattern slots: zmask 1..6 times the 8 sign combinations.
N_SLOTS = 48
_F = "F"  # a finite t value of unknown order


class OverBudget(Exception):
    """The octree emulation needs more than :data:`MAX_REFS` references, :data:`MAX_STATES` states or
    :data:`MAX_NODES` nodes."""


class _Node:
    """An octree node, split on first visit (the traversals of :func:`reach_masks` reach few nodes)."""

    __slots__ = ("_children", "level", "mn", "mx", "tree", "trigs")

    def __init__(self, tree: _Tree, mn: np.ndarray, mx: np.ndarray, trigs: np.ndarray, level: int) -> None:
        self.tree, self.mn, self.mx, self.trigs, self.level = tree, mn, mx, trigs, level
        self._children: list[_Node] | None = None

    @property
    def is_leaf(self) -> bool:
        return len(self.trigs) <= MAX_TRIG or self.level > MAX_LEVEL

    @property
    def children(self) -> list[_Node]:
        """The 8 children (``buildNode``): child ``i`` takes the upper half of x, y, z for bits 4, 2, 1."""
        if self._children is None:
            mid = ((self.mn + self.mx) / np.float32(2)).astype(np.float32)
            tree = self.tree
            tree.nodes += 8
            if tree.nodes > tree.max_nodes:
                raise OverBudget
            a_mn, a_mx = tree.tmn[self.trigs], tree.tmx[self.trigs]
            kids = []
            for i in range(8):
                hi = np.array([(i >> 2) & 1, (i >> 1) & 1, i & 1], dtype=bool)
                cmn = np.where(hi, mid, self.mn).astype(np.float32)
                cmx = np.where(hi, self.mx, mid).astype(np.float32)
                touch = np.all((a_mn <= cmx) & (cmn <= a_mx), axis=1)
                tree.refs += int(np.count_nonzero(touch))
                if tree.refs > tree.max_refs:  # checked before the child's index array is made
                    raise OverBudget
                kids.append(_Node(tree, cmn, cmx, self.trigs[touch], self.level + 1))
            self._children = kids
        return self._children


class _Tree:
    def __init__(self, vertices: np.ndarray, faces: np.ndarray, max_refs: int, max_states: int,
                 max_nodes: int) -> None:
        v = np.asarray(vertices, dtype=np.float32)
        tri = v[np.asarray(faces, dtype=np.int64)]
        self.tmn, self.tmx = tri.min(axis=1), tri.max(axis=1)
        self.refs, self.states, self.nodes = 0, 0, 1
        self.max_refs, self.max_states, self.max_nodes = max_refs, max_states, max_nodes
        self.root = _Node(self, v.min(axis=0), v.max(axis=0), np.arange(len(faces), dtype=np.int32), 0)


def build(vertices: np.ndarray, faces: np.ndarray, max_refs: int = MAX_REFS, max_states: int = MAX_STATES,
          max_nodes: int = MAX_NODES) -> _Node:
    """The root of the binary's octree (module docstring) on float32 object-space ``vertices`` (N, 3) and
    ``faces`` (F, 3); nodes split when first visited, within the budget (:class:`OverBudget` beyond it)."""
    return _Tree(vertices, faces, max_refs, max_states, max_nodes).root


def _lt(a: object, b: object) -> tuple[bool, ...]:
    """Possible outcomes of ``a < b`` for concrete floats (the zero axes) and :data:`_F` (finite axes)."""
    if a == _F and b == _F:
        return (True, False)
    if a == _F:
        return (False,) if math.isnan(b) else ((b == math.inf),)  # type: ignore[arg-type]
    if b == _F:
        return (False,) if math.isnan(a) else ((a == -math.inf),)  # type: ignore[arg-type]
    return (a < b,)  # type: ignore[operator]


def _outcomes(fn: Callable[[Callable[[object, object], bool]], int]) -> set[int]:
    """Every result of ``fn(lt)`` over all choices of the comparisons that can go either way."""
    results: set[int] = set()
    pending: list[list[bool]] = [[]]
    while pending:
        prefix = pending.pop()
        pos = 0

        def lt(a: object, b: object, prefix: list[bool] = prefix) -> bool:
            nonlocal pos
            opts = _lt(a, b)
            if len(opts) == 1:
                return opts[0]
            if pos == len(prefix):
                pending.append(prefix + [False])
                prefix.append(True)
            pos += 1
            return prefix[pos - 1]

        results.add(fn(lt))
    return results


def _first_node(t0: tuple, tm: tuple) -> Callable:
    def fn(lt: Callable[[object, object], bool]) -> int:
        (tx0, ty0, tz0), (txm, tym, tzm) = t0, tm
        bits = 0
        if lt(ty0, tx0):
            if lt(tz0, tx0):
                bits |= 2 if lt(tym, tx0) else 0
                bits |= 1 if lt(tzm, tx0) else 0
                return bits
        elif lt(tz0, ty0):
            bits |= 4 if lt(txm, ty0) else 0
            bits |= 1 if lt(tzm, ty0) else 0
            return bits
        bits |= 4 if lt(txm, tz0) else 0
        bits |= 2 if lt(tym, tz0) else 0
        return bits
    return fn


def _new_node(exits: tuple, succ: tuple) -> Callable:
    def fn(lt: Callable[[object, object], bool]) -> int:
        (tx, ty, tz), (x, y, z) = exits, succ
        if lt(tx, ty):
            if lt(tx, tz):
                return x
        elif lt(ty, tz):
            return y
        return z
    return fn


def _mid(a: object, b: object) -> object:
    return _F if _F in (a, b) else 0.5 * (a + b)  # type: ignore[operator]


def _key(v: object) -> str:
    return v if isinstance(v, str) else repr(v)


def reachable_trigs(root: _Node, zmask: int, neg: int) -> set[int]:
    """Triangles in the leaves the traversal can reach for a direction with zero axes ``zmask`` (+0.0
    each) and negative finite axes ``neg`` (bits x=1, y=2, z=4), over every ray origin inside the box.
    Raises :class:`OverBudget` when the tree's budget (:func:`build`) runs out."""
    aa = (4 if neg & 1 else 0) | (2 if neg & 2 else 0) | (1 if neg & 4 else 0)
    t0 = tuple(-math.inf if zmask & (1 << k) else _F for k in range(3))
    t1 = tuple(math.inf if zmask & (1 << k) else _F for k in range(3))
    tree = root.tree
    reached = np.zeros(len(tree.tmn), dtype=bool)
    seen: set[tuple] = set()
    stack = [(root, t0, t1)]
    while stack:
        node, a0, a1 = stack.pop()
        if reached[node.trigs].all():  # its leaves can add no triangle (module docstring, Bounds)
            continue
        key = (id(node), *map(_key, a0), *map(_key, a1))
        if key in seen:
            continue
        seen.add(key)
        tree.states += 1
        if tree.states > tree.max_states:
            raise OverBudget
        if node.is_leaf:
            reached[node.trigs] = True
            continue
        tm = tuple(_mid(a, b) for a, b in zip(a0, a1, strict=True))
        todo = list(_outcomes(_first_node(a0, tm)))
        done: set[int] = set()
        while todo:
            cur = todo.pop()
            if cur >= 8 or cur in done:
                continue
            done.add(cur)
            bits = ((cur >> 2) & 1, (cur >> 1) & 1, cur & 1)
            c0 = tuple(tm[k] if bits[k] else a0[k] for k in range(3))
            c1 = tuple(a1[k] if bits[k] else tm[k] for k in range(3))
            stack.append((node.children[cur ^ aa], c0, c1))
            succ = tuple(8 if bits[k] else cur | (4 >> k) for k in range(3))
            todo.extend(_outcomes(_new_node(c1, succ)))
    return {int(t) for t in np.flatnonzero(reached)}


def reach_masks(vertices: np.ndarray, faces: np.ndarray, folder: Path | None | bool = None, *,
                warnings: list[tuple[FileLoc, str]] | None = None, loc: FileLoc | None = None) -> np.ndarray:
    """(F, 2) float32: per triangle, bit ``s`` of ``lo + hi·2^24`` says the traversal reaches it in pattern
    slot ``s`` (module docstring); both words are integers below 2^24, exact in float32.

    The masks depend on the mesh alone and cost ~1 s for the vase (5,762 lines) and ~2 s for sibenik2, so
    they are kept on disk: ``folder`` (default :func:`a5mi.cache_dir`; ``False``: no cache) holds one file
    per mesh named by the SHA-256 of :data:`CACHE_VERSION`, the float64 vertices and the int64 faces, with a
    CRC of its words; a missing, unreadable or mismatching file is recomputed and rewritten atomically, and
    a folder that cannot be written just means the masks are computed. Over the budget (module docstring,
    Bounds) every bit is set, and ``(loc, message)`` is appended to ``warnings`` when it is given (a cached
    fallback is reported too)."""
    path = None
    cached = None
    if folder is not False:
        path = _cache_path(Path(cache_dir()) if folder is None or folder is True else Path(folder), vertices, faces)
        cached = _load_masks(path, len(faces))
    if cached is not None:
        masks, exact = cached
    else:
        masks, exact = _compute_masks(vertices, faces)
        if path is not None:
            _save_masks(path, masks, exact)
    if not exact and warnings is not None and loc is not None:
        warnings.append((loc, f"mesh of {len(faces)} faces is too degenerate for the sample solution's octree "
                              f"(more than {MAX_TRIG} faces share a region down to level {MAX_LEVEL + 1}); "
                              "every face is taken as reached by rays with a +0.0 direction component (SPEC A.6)"))
    return masks


#: Part of every cache key: bump it when the traversal model above changes.
CACHE_VERSION = "a5mi-octree-reach-2"


def _cache_path(folder: Path, vertices: np.ndarray, faces: np.ndarray) -> Path:
    h = hashlib.sha256(CACHE_VERSION.encode())
    for a in (np.ascontiguousarray(vertices, dtype=np.float64), np.ascontiguousarray(faces, dtype=np.int64)):
        h.update(repr(a.shape).encode())
        h.update(a.tobytes())
    return folder / "octree" / f"{h.hexdigest()}.npy"


def _load_masks(path: Path, n_faces: int) -> tuple[np.ndarray, bool] | None:
    """The cached ``(masks, exact)``, or None when the file is missing or fails a check (never raises).
    The file holds the 2F mask words, an exact flag (1 or 0) and the CRC-32 of those words."""
    try:
        if not stat.S_ISREG(os.stat(path).st_mode):  # np.load of a FIFO would block
            return None
        words = np.load(path, allow_pickle=False)
        if words.dtype != np.uint32 or words.shape != (2 * n_faces + 2,):
            return None
        body = words[:-1]
        if int(words[-1]) != zlib.crc32(body.tobytes()) or int(body.max(initial=0)) >= 1 << 24:
            return None
        if int(body[-1]) not in (0, 1):
            return None
    except Exception:  # noqa: BLE001 - a cache must never be fatal (empty, truncated, garbage files)
        return None
    return body[:-1].reshape(n_faces, 2).astype(np.float32), bool(body[-1])


def _save_masks(path: Path, masks: np.ndarray, exact: bool) -> None:
    from a5mi.platform.imageio import atomic_file

    body = np.concatenate([masks.astype(np.uint32).ravel(), np.array([int(exact)], dtype=np.uint32)])
    words = np.concatenate([body, np.array([zlib.crc32(body.tobytes())], dtype=np.uint32)])
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with atomic_file(path, "wb") as f:
            np.save(f, words)
    except OSError:
        pass


#: Both mask words with every pattern bit set (24 slots each).
_ALL = float((1 << 24) - 1)


def _compute_masks(vertices: np.ndarray, faces: np.ndarray, max_refs: int = MAX_REFS,
                   max_states: int = MAX_STATES, max_nodes: int = MAX_NODES) -> tuple[np.ndarray, bool]:
    """:func:`reach_masks` without the cache: ``(masks, exact)``; ``exact`` is False when the budget ran out
    and every bit is set."""
    root = build(vertices, faces, max_refs, max_states, max_nodes)
    words = np.zeros((len(faces), 2), dtype=np.int64)
    try:
        for zmask in range(1, 7):
            for neg in range(8):
                if neg & zmask:
                    continue
                slot = (zmask - 1) * 8 + neg
                idx = np.fromiter(reachable_trigs(root, zmask, neg), dtype=np.int64)
                if len(idx):
                    words[idx, slot // 24] |= 1 << (slot % 24)
    except OverBudget:
        return np.full((len(faces), 2), _ALL, dtype=np.float32), False
    return words.astype(np.float32), True

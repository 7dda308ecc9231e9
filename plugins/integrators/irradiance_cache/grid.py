"""The irradiance cache's records and their spatial index: a loose octree as a multi-level hash grid, in numpy
(docs/EXTENSIONS.md E.23).

A record reaches no farther than ``a R_i`` (beyond it ``ε_i ≥ a``, :mod:`.irradiance_cache_math`). It is
filed at level ``ℓ_i = ⌈log2(a R_i)⌉ − 1`` (cells of side ``2^ℓ`` in ``[a R_i / 2, a R_i)``), in every cell
of that level's grid that its box ``p_i ± a R_i`` overlaps (at most 5 per axis), as an octree files a
record in the nodes its box overlaps. A query visits, per level in use, its own cell: the cell keys of each
level are sorted once (``np.searchsorted`` finds a cell's records), and the candidate pairs (query, record)
are expanded and weighed all at once. Keys are the three cell coordinates modulo 2^21 packed in 63 bits;
when the queries span more cells than that, pairs are made unique (two cells sharing a key only add
candidates, which the exact weight rejects). Records are appended, never moved: the index is rebuilt lazily
after an append.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from a5mi.plugins.integrators.irradiance_cache.formulas import EPS_MIN, epsilon, extrapolate, in_front

F = npt.NDArray[np.float64]
I = npt.NDArray[np.int64]  # noqa: E741 - the index-array alias

_BITS = 21
_MASK = (1 << _BITS) - 1
#: query points weighed per block (bounds the pair arrays)
_BLOCK = 8192


def cell_keys(cells: I) -> I:
    """One int64 key per integer cell ``(..., 3)`` (coordinates modulo 2^21)."""
    c = cells & _MASK
    return (c[..., 0] << (2 * _BITS)) | (c[..., 1] << _BITS) | c[..., 2]


def level_of(reach: F) -> I:
    """The grid level ``⌈log2(reach)⌉`` of records reaching ``reach``."""
    return np.ceil(np.log2(np.maximum(reach, 1e-30))).astype(np.int64)


@dataclass
class Lookup:
    """Interpolation at query points: ``E`` (Q, 3; 0 where uncovered), ``covered`` (Q,), ``weight`` (Q,: Σ
    w_i) and, when asked for, the pairs used (``pair_query``, ``pair_record``, ``pair_weight``)."""

    E: F
    covered: npt.NDArray[np.bool_]
    weight: F
    pair_query: I | None = None
    pair_record: I | None = None
    pair_weight: F | None = None


@dataclass
class RecordSet:
    """The cache: records as parallel arrays (``p``, ``n`` unit, ``E``, ``R``, ``grad_r``, ``grad_t``,
    ``spacing`` the pixel spacing where it was made) and the error bound ``a``."""

    a: float
    p: F = field(default_factory=lambda: np.zeros((0, 3)))
    n: F = field(default_factory=lambda: np.zeros((0, 3)))
    E: F = field(default_factory=lambda: np.zeros((0, 3)))
    R: F = field(default_factory=lambda: np.zeros(0))
    grad_r: F = field(default_factory=lambda: np.zeros((0, 3, 3)))
    grad_t: F = field(default_factory=lambda: np.zeros((0, 3, 3)))
    spacing: F = field(default_factory=lambda: np.zeros(0))
    _index: dict[int, tuple[I, I, I, I]] | None = None

    def __len__(self) -> int:
        return int(self.R.shape[0])

    def add(self, p: F, n: F, E: F, R: F, grad_r: F, grad_t: F, spacing: F) -> None:
        """Append records (arrays with a leading record axis)."""
        self.p = np.concatenate([self.p, p])
        self.n = np.concatenate([self.n, n])
        self.E = np.concatenate([self.E, E])
        self.R = np.concatenate([self.R, R])
        self.grad_r = np.concatenate([self.grad_r, grad_r])
        self.grad_t = np.concatenate([self.grad_t, grad_t])
        self.spacing = np.concatenate([self.spacing, spacing])
        self._index = None

    def index(self) -> dict[int, tuple[I, I, I, I]]:
        """Level -> (sorted cell keys, record numbers in that order, lowest and highest cell): every cell of side
        ``2^ℓ`` that a record's box ``p_i ± a R_i`` overlaps (module docstring)."""
        if self._index is None:
            reach = self.a * self.R
            levels = level_of(reach) - 1
            self._index = {}
            for lv in np.unique(levels):
                ids = np.nonzero(levels == lv)[0]
                size = 2.0 ** int(lv)
                lo = np.floor((self.p[ids] - reach[ids, None]) / size).astype(np.int64)
                span = np.floor((self.p[ids] + reach[ids, None]) / size).astype(np.int64) - lo     # 0 .. 4
                ext = span + 1                      # cells per axis; each record's cells expanded at once
                cnt = ext.prod(axis=1)
                owner = np.repeat(ids, cnt)
                local = np.arange(int(cnt.sum())) - np.repeat(np.cumsum(cnt) - cnt, cnt)
                e = np.repeat(ext, cnt, axis=0)
                off = np.stack([local // (e[:, 1] * e[:, 2]), (local // e[:, 2]) % e[:, 1], local % e[:, 2]], axis=1)
                key = cell_keys(np.repeat(lo, cnt, axis=0) + off)
                order = np.argsort(key, kind="stable")
                self._index[int(lv)] = (key[order], owner[order], lo.min(axis=0), (lo + span).max(axis=0))
        return self._index

    def candidates(self, p: F) -> tuple[I, I]:
        """Pairs ``(query, record)`` whose record's box holds the query's cell (module docstring)."""
        qs, rs = [], []
        exact = True
        for lv, (keys, ids, low, high) in self.index().items():
            cell = np.floor(p / 2.0 ** lv).astype(np.int64)
            span = np.maximum(cell.max(axis=0), high) - np.minimum(cell.min(axis=0), low)
            exact &= bool(np.all(span < _MASK))     # else two cells in use may share a key
            qkeys = cell_keys(cell)
            lo = np.searchsorted(keys, qkeys, side="left")
            count = np.searchsorted(keys, qkeys, side="right") - lo
            total = int(count.sum())
            if total == 0:
                continue
            starts = np.repeat(lo - (np.cumsum(count) - count), count)
            rs.append(ids[starts + np.arange(total)])
            qs.append(np.repeat(np.arange(p.shape[0]), count))
        if not qs:
            return np.zeros(0, np.int64), np.zeros(0, np.int64)
        q_all, r_all = np.concatenate(qs), np.concatenate(rs)
        if exact:           # a record is filed once per cell, and distinct cells have distinct keys
            return q_all, r_all
        pair = np.unique(q_all * len(self) + r_all)
        return pair // len(self), pair % len(self)

    def lookup(self, p: F, n: F, gradients: bool = True, pairs: bool = False) -> Lookup:
        """Interpolate at points ``p`` with unit normals ``n`` (module docstring of
        :mod:`.irradiance_cache_math`); ``gradients=False``: the records' ``E_i`` alone; ``pairs``: keep
        the (query, record, weight) triples used."""
        count = p.shape[0]
        E = np.zeros((count, 3))
        wsum = np.zeros(count)
        kept: list[tuple[I, I, F]] = []
        if len(self) and count:
            for start in range(0, count, _BLOCK):
                block = slice(start, min(start + _BLOCK, count))
                q, r = self.candidates(p[block])
                if q.size == 0:
                    continue
                pq, nq = p[block][q], n[block][q]
                eps = epsilon(pq, nq, self.p[r], self.n[r], self.R[r])
                ok = (eps < self.a) & ~in_front(pq, nq, self.p[r], self.n[r], self.R[r])
                q, r, eps, pq, nq = q[ok], r[ok], eps[ok], pq[ok], nq[ok]
                w = 1.0 / np.maximum(eps, EPS_MIN)
                if gradients:
                    value = extrapolate(pq, nq, self.p[r], self.n[r], self.E[r], self.grad_r[r], self.grad_t[r])
                else:
                    value = self.E[r]
                size = block.stop - block.start
                wsum[block] += np.bincount(q, w, minlength=size)
                for c in range(3):
                    E[block, c] += np.bincount(q, w * value[:, c], minlength=size)
                if pairs:
                    kept.append((start + q, r, w))
        covered = wsum > 0.0
        E[covered] /= wsum[covered, None]
        out = Lookup(E, covered, wsum)
        if pairs:
            out.pair_query = np.concatenate([k[0] for k in kept]) if kept else np.zeros(0, np.int64)
            out.pair_record = np.concatenate([k[1] for k in kept]) if kept else np.zeros(0, np.int64)
            out.pair_weight = np.concatenate([k[2] for k in kept]) if kept else np.zeros(0)
        return out

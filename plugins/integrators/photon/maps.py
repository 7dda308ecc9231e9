"""Photon maps and their radiance estimates (Jensen 2001, ch. 7; docs/EXTENSIONS.md E.16, E.17).

A :class:`PhotonMap` holds stored photons in a kd-tree (SciPy's ``cKDTree``, built once per map). At a diffuse
point ``x`` with the normal ``n`` facing the viewer and Lambert colour ``kd``, the reflected radiance is

    L(x) = (kd / π) Σ_p w_p Φ_p,      over the photons p near x arriving on the front (``dir_p · n < 0``)

with the density weights ``w_p`` of a disc of radius ``r``:

* ``none`` (box):         ``w = 1 / (π r²)``
* ``cone`` (Jensen, k=1): ``w = (1 − d_p / r) / ((1 − 2/3) π r²) = 3 (1 − d_p/r) / (π r²)``
* ``epanechnikov``:       ``w = 2 (1 − d_p²/r²) / (π r²)``

each integrating to 1 over the disc. :meth:`PhotonMap.knn` takes ``r`` = the distance of the ``k``-th nearest
photon and sums the ``k − 1`` nearer ones (for a Poisson density ``ρ``, ``E[(k − 1)/(π r²)] = ρ``, while
``k/(π r²)`` is ``k/(k − 1)`` too high) (E.16); with ``max_radius = R`` it takes ``r = min(r_k, R)`` and the
photons within it (all of them lie among the ``k − 1`` nearer ones when ``r_k > R``: the fixed-radius estimate
of E.17 there), so no disc reaches farther than ``R`` into a bright neighbour. :meth:`PhotonMap.radius` takes
every photon within a given ``r`` per point (E.17), through ``cKDTree.sparse_distance_matrix`` between the
points' tree and the map's (no Python loop).
"""

from __future__ import annotations

import numpy as np

FILTERS: tuple[str, ...] = ("none", "cone", "epanechnikov")


def weights(filter_name: str, dist: np.ndarray, r: np.ndarray) -> np.ndarray:
    """The density weights ``w_p`` of the module docstring for distances ``dist`` within radii ``r``."""
    r = np.maximum(r, 1e-30)
    q = np.clip(dist / r, 0.0, 1.0)
    area = np.pi * r * r
    if filter_name == "none":
        return np.where(dist <= r, 1.0 / area, 0.0)
    if filter_name == "cone":
        return 3.0 * (1.0 - q) / area
    if filter_name == "epanechnikov":
        return 2.0 * (1.0 - q * q) / area
    raise ValueError(f"photon filter must be one of {', '.join(FILTERS)}, got {filter_name!r}")


class PhotonMap:
    """Photons ``pos``, ``dir``, ``power`` (``(n, 3)`` arrays) in a ``cKDTree``."""

    def __init__(self, pos: np.ndarray, dir: np.ndarray, power: np.ndarray) -> None:
        self.pos = np.ascontiguousarray(pos, dtype=np.float64)
        self.dir = np.ascontiguousarray(dir, dtype=np.float64)
        self.power = np.ascontiguousarray(power, dtype=np.float64)
        from scipy.spatial import cKDTree  # on first use: 0.2-0.6 CPU-s of every a5 start otherwise

        self.tree = cKDTree(self.pos) if len(self.pos) else None

    def __len__(self) -> int:
        return len(self.pos)

    def knn(self, x: np.ndarray, n: np.ndarray, kd: np.ndarray, k: int, filter_name: str = "none",
            workers: int = 1, max_radius: float = 0.0) -> np.ndarray:
        """``L(x)`` (rgb, ``(m, 3)``) from the ``k`` nearest photons of each point, their disc at most
        ``max_radius`` wide when it is > 0 (module docstring)."""
        out = np.zeros((len(x), 3))
        if self.tree is None or len(x) == 0:
            return out
        k = min(k, len(self.pos))
        dist, idx = self.tree.query(x, k=k, workers=workers)
        if k == 1:
            dist, idx = dist[:, None], idx[:, None]
        r = dist[:, -1:]
        if max_radius > 0.0:
            r = np.minimum(r, max_radius)               # a bound: the photons within it (module docstring)
        dist, idx = dist[:, :-1], idx[:, :-1]         # the k-th photon sets r and is not counted
        front = np.einsum("mkc,mc->mk", self.dir[idx], n) < 0.0
        w = weights(filter_name, dist, r) * front
        flux = np.einsum("mk,mkc->mc", w, self.power[idx])
        return kd / np.pi * flux

    def radius(self, x: np.ndarray, n: np.ndarray, kd: np.ndarray, r: float | np.ndarray,
               filter_name: str = "none") -> np.ndarray:
        """``L(x)`` from every photon within ``r`` of each point (module docstring)."""
        out = np.zeros((len(x), 3))
        if self.tree is None or len(x) == 0:
            return out
        r_max = float(np.max(r))
        from scipy.spatial import cKDTree

        pairs = cKDTree(x).sparse_distance_matrix(self.tree, r_max, output_type="ndarray")
        i, j, dist = pairs["i"], pairs["j"], pairs["v"]
        r_i = np.broadcast_to(np.asarray(r, dtype=np.float64), (len(x),))[i]
        keep = (dist <= r_i) & (np.einsum("pc,pc->p", self.dir[j], n[i]) < 0.0)
        i, j, dist, r_i = i[keep], j[keep], dist[keep], r_i[keep]
        w = weights(filter_name, dist, r_i)
        flux = np.zeros((len(x), 3))
        for c in range(3):
            flux[:, c] = np.bincount(i, weights=w * self.power[j, c], minlength=len(x))
        return kd / np.pi * flux

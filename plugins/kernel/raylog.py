"""Ray-log mode of ``a5_whitted``: every ray the SPEC B.3 kernel traverses, written where the kernel casts it.

``a5mi bench`` measures the kernel against a *traversal floor*: the time Mitsuba takes to traverse exactly the
rays the kernel traverses. :class:`RayLog` is handed to :func:`~.raytree.trace_tree` (``A5WhittedIntegrator.trace``'s
``ray_log=``) with :attr:`~.features.Features.ray_log` set; without it the flag is false and the kernel contains
none of the calls below (every one sits under ``if dr.hint(f.ray_log, mode='scalar'):``).

* :meth:`RayLog.node`: each popped node of the ray tree (camera, reflection, refraction and E.15 gathered rays:
  one per loop iteration and active lane): ``(o, d, t_min)``, the ray ``o + t d, t > t_min``.
* :meth:`RayLog.shadow`: each shadow ray the light loop casts (the lanes ``tested`` of
  :func:`~.lights.sample`): ``(p, L, tmin, dist, far)``, the segment ``tmin < t < dist`` of ``p + t L``
  (``far``: a directional light, whose planes the kernel tests up to +inf).

Slots come from one atomic counter per kind (``dr.scatter_inc``, which reduces within a SIMD packet first and
adds once per packet), so the log holds the rays in the order the kernel's packets cast them: the rays that
shared a packet in the kernel share one in a wavefront replay. That order depends on thread scheduling; the
entries themselves do not: each carries its lane and ordinal (node: the depth-first number
``n_reflection + n_refraction - top``; shadow ray: the lane's shadow count before it), a unique key.
Buffers are preallocated (the ``counts`` AOV's totals give the sizes); entries past a buffer's end are counted
but not written, so ``nodes``/``shadows`` (the counters) tell whether the buffers sufficed.
"""

from __future__ import annotations

import drjit as dr
import mitsuba as mi
import numpy as np

#: Fields of a node entry and of a shadow entry (3-vectors first), as :meth:`RayLog.read` returns them.
NODE_FIELDS = ("o", "d", "tmin", "lane", "ordinal")
SHADOW_FIELDS = ("p", "d", "tmin", "dist", "far", "lane", "ordinal")


class RayLog:
    """Preallocated buffers for ``max_nodes`` node rays and ``max_shadows`` shadow rays (module docstring)."""

    def __init__(self, max_nodes: int, max_shadows: int) -> None:
        self.max_nodes, self.max_shadows = int(max_nodes), int(max_shadows)
        nn, ns = max(1, self.max_nodes), max(1, self.max_shadows)
        self.node_count = dr.zeros(mi.UInt32, 1)
        self.shadow_count = dr.zeros(mi.UInt32, 1)
        self.node_cap = dr.opaque(mi.UInt32, self.max_nodes)
        self.shadow_cap = dr.opaque(mi.UInt32, self.max_shadows)
        # one flat array per component (``dr.scatter`` writes 1D targets): vectors are three
        self.node_buf = _buffers(nn, o=(mi.Float, 3), d=(mi.Float, 3), tmin=(mi.Float, 1), lane=(mi.UInt32, 1),
                                 ordinal=(mi.UInt32, 1))
        self.shadow_buf = _buffers(ns, p=(mi.Float, 3), d=(mi.Float, 3), tmin=(mi.Float, 1), dist=(mi.Float, 1),
                                   far=(mi.Bool, 1), lane=(mi.UInt32, 1), ordinal=(mi.UInt32, 1))
        dr.make_opaque(self.node_count, self.shadow_count)

    # ------------------------------------------------------------------ called from the kernel
    def node(self, o: mi.Point3f, d: mi.Vector3f, t_min: mi.Float, ordinal: mi.UInt32) -> None:
        """Log the node ray ``(o, d, t_min)`` of every lane the loop runs (depth-first number ``ordinal``)."""
        slot = dr.scatter_inc(self.node_count, mi.UInt32(0))
        ok = slot < self.node_cap
        lane = dr.arange(mi.UInt32, dr.width(d))
        _write(self.node_buf, slot, ok, o=o, d=d, tmin=t_min, lane=lane, ordinal=ordinal)

    def shadow(self, tested: mi.Bool, p: mi.Point3f, d: mi.Vector3f, tmin: mi.Float, dist: mi.Float, far: mi.Bool,
               ordinal: mi.Float) -> None:
        """Log the shadow ray ``p + t d, tmin < t < dist`` (``far``: a directional light) of the lanes
        ``tested``; ``ordinal``: the lane's shadow rays before this one."""
        slot = dr.scatter_inc(self.shadow_count, mi.UInt32(0), tested)
        ok = tested & (slot < self.shadow_cap)
        lane = dr.arange(mi.UInt32, dr.width(d))
        _write(self.shadow_buf, slot, ok, p=p, d=d, tmin=tmin, dist=dist, far=far, lane=lane,
               ordinal=mi.UInt32(ordinal))

    # ------------------------------------------------------------------ after the launch
    @property
    def nodes(self) -> int:
        """Node rays the kernel cast (may exceed ``max_nodes``: then the log is short)."""
        return int(self.node_count[0])

    @property
    def shadows(self) -> int:
        """Shadow rays the kernel cast (may exceed ``max_shadows``)."""
        return int(self.shadow_count[0])

    def read(self) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
        """``(nodes, shadows)``: numpy arrays by field (:data:`NODE_FIELDS`, :data:`SHADOW_FIELDS`; vectors
        ``(3, n)``), in slot order, the written entries only."""
        n, s = min(self.nodes, self.max_nodes), min(self.shadows, self.max_shadows)
        return _read(self.node_buf, n), _read(self.shadow_buf, s)


def _buffers(size: int, **fields: tuple[type, int]) -> dict[str, list[dr.ArrayBase]]:
    """Per field a list of ``width`` evaluated 1D arrays of ``size`` entries."""
    out = {name: [dr.zeros(t, size) for _ in range(w)] for name, (t, w) in fields.items()}
    for arrays in out.values():
        dr.make_opaque(*arrays)
    return out


def _write(buf: dict[str, list[dr.ArrayBase]], slot: mi.UInt32, ok: mi.Bool, **values: object) -> None:
    for name, value in values.items():
        arrays = buf[name]
        if len(arrays) == 1:
            dr.scatter(arrays[0], value, slot, ok)
        else:
            for c, target in enumerate(arrays):
                dr.scatter(target, value[c], slot, ok)  # type: ignore[index]


def _read(buf: dict[str, list[dr.ArrayBase]], n: int) -> dict[str, np.ndarray]:
    out = {}
    for name, arrays in buf.items():
        cols = [np.asarray(a)[:n] for a in arrays]
        out[name] = cols[0] if len(cols) == 1 else np.stack(cols)
    return out

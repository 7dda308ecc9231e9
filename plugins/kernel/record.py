"""Record mode of ``a5_whitted``: the SPEC B.3 ray tree of a few camera rays, node by node, from the render kernel.

:class:`TreeRecorder` is handed to the kernel :func:`plugins.kernel.raytree.trace_tree`
(``A5WhittedIntegrator.trace``'s ``record=``) only by ``a5mi trace``; a render passes ``None`` and its
:class:`~.kernel.features.Features` have ``record = False``, so its kernel contains none of the recording calls.
Inside the one ``@dr.syntax`` loop the kernel calls the recorder at fixed points of each popped node; every
call scatters the values the kernel itself computed into flat per-lane buffers (no arithmetic of its own except
the occluder query below), so a trace is exactly the render's arithmetic.

Node numbering needs no extra loop state: every push increments both the stack pointer ``top`` and one of the
counts ``n_reflection`` / ``n_refraction``, so after a pop the node's depth-first number is
``n_reflection + n_refraction - top`` (0 for the camera ray). Children are pushed refraction first, then
reflection, so the reflection child is popped first; :func:`a5mi.trace.tree` replays that stack order to link
nodes to parents.

Shadow occluders: the render's ``ray_test`` only says "blocked"; the recorder additionally runs the nearest-hit
query (the same octree rule and plane test) from ``p`` towards the light and stores the first shape or plane
with ``t < dist`` and its ``t``, for naming only. The verdict printed is always the kernel's own.
"""

from __future__ import annotations

import drjit as dr
import mitsuba as mi

from a5mi.plugins.emulation import octree_rule
from a5mi.plugins.emulation.plane_hits import intersect_planes
from a5mi.plugins.emulation.planes import PlaneSet

#: Per-node fields and their widths, in buffer order.
NODE_FIELDS: tuple[tuple[str, int], ...] = (
    ("valid", 1), ("o", 3), ("d", 3), ("tmin", 1), ("n_medium", 1), ("weight", 3), ("bounces", 1),
    ("hit", 1), ("on_plane", 1), ("plane", 1), ("shape", 1), ("t", 1), ("p", 3), ("n", 3), ("uv", 2),
    ("a5", 1), ("diffuse_color", 3), ("kd", 3), ("specular", 3), ("ior", 1), ("shininess", 1),
    ("local", 3), ("background", 3), ("contribution", 3), ("color", 3),
    ("refractive", 1), ("leaving", 1), ("nt", 1), ("refr_exists", 1), ("t_dir", 3), ("r_fresnel", 1),
    ("push_refr", 1), ("w_refr", 3), ("push_refl", 1), ("r_dir", 3), ("w_refl", 3),
)
#: Per-(node, light) fields.
LIGHT_FIELDS: tuple[tuple[str, int], ...] = (
    ("valid", 1), ("L", 3), ("n_dot_l", 1), ("light_color", 3), ("dist", 1), ("visible", 1), ("tested", 1),
    ("far", 1), ("occ_shape", 1), ("occ_plane", 1), ("occ_on_plane", 1), ("occ_t", 1), ("highlight", 1),
    ("term", 3),
)


def _layout(fields: tuple[tuple[str, int], ...]) -> tuple[dict[str, tuple[int, int]], int]:
    out, k = {}, 0
    for name, w in fields:
        out[name] = (k, w)
        k += w
    return out, k


NODE_LAYOUT, NODE_STRIDE = _layout(NODE_FIELDS)
LIGHT_LAYOUT, LIGHT_STRIDE = _layout(LIGHT_FIELDS)


def _f(v: object) -> mi.Float:
    """Bools as 0/1, integers and pointers as their value, floats unchanged (all small or exact in float32)."""
    if isinstance(v, mi.Bool):
        return dr.select(v, mi.Float(1.0), mi.Float(0.0))
    return mi.Float(v)


def shape_id(shape: mi.ShapePtr) -> mi.UInt32:
    """The registry id of a shape pointer (0 = none); :func:`shape_of` turns it back into the shape."""
    return dr.reinterpret_array(mi.UInt32, shape)


def shape_of(rid: int) -> mi.Shape | None:
    """The shape object of registry id ``rid`` (None for 0)."""
    if rid <= 0:
        return None
    return dr.reinterpret_array(mi.ShapePtr, mi.UInt32([rid]))[0]


class TreeRecorder:
    """Per-lane buffers for at most ``max_nodes`` nodes and ``max_lights`` lights per node (``width`` lanes).

    ``nodes[lane, node, :]`` and ``lights[lane, node, light, :]`` after :meth:`read`, laid out by
    :data:`NODE_LAYOUT` / :data:`LIGHT_LAYOUT`; nodes past ``max_nodes`` are dropped (``overflow``).
    """

    def __init__(self, width: int, max_nodes: int, max_lights: int) -> None:
        self.width, self.max_nodes, self.max_lights = width, max_nodes, max(1, max_lights)
        self.lane = dr.arange(mi.UInt32, width)
        self.node_buf = dr.zeros(mi.Float, width * max_nodes * NODE_STRIDE)
        self.light_buf = dr.zeros(mi.Float, width * max_nodes * self.max_lights * LIGHT_STRIDE)
        self.count = dr.zeros(mi.UInt32, width)
        dr.make_opaque(self.node_buf, self.light_buf, self.count)

    # ------------------------------------------------------------------ called from the kernel
    @staticmethod
    def index(n_refl: mi.Float, n_refr: mi.Float, top: mi.UInt32) -> mi.UInt32:
        """Depth-first number of the node just popped (module docstring): the ``at`` of the calls below."""
        return mi.UInt32(n_refl + n_refr) - top

    def _put(self, buf: str, base: mi.UInt32, layout: dict[str, tuple[int, int]], ok: mi.Bool,
             values: dict[str, object]) -> None:
        target = getattr(self, buf)
        for name, value in values.items():
            off, w = layout[name]
            if w == 1:
                dr.scatter(target, _f(value), base + off, ok)
            else:
                for c in range(w):
                    dr.scatter(target, _f(value[c]), base + off + c, ok)  # type: ignore[index]
        setattr(self, buf, target)

    def node(self, idx: mi.UInt32, **values: object) -> None:
        """Store node fields (names of :data:`NODE_FIELDS`) of node ``idx``."""
        ok = idx < self.max_nodes
        base = (self.lane * self.max_nodes + idx) * NODE_STRIDE
        self._put("node_buf", base, NODE_LAYOUT, ok, values)
        dr.scatter_reduce(dr.ReduceOp.Max, self.count, idx + 1, self.lane)

    def light(self, idx: mi.UInt32, k: mi.UInt32, **values: object) -> None:
        """Store light-``k`` fields (names of :data:`LIGHT_FIELDS`) of node ``idx``."""
        ok = (idx < self.max_nodes) & (k < self.max_lights)
        base = ((self.lane * self.max_nodes + idx) * self.max_lights + k) * LIGHT_STRIDE
        self._put("light_buf", base, LIGHT_LAYOUT, ok, values)

    def occluder(self, scene: mi.Scene, planes: PlaneSet, idx: mi.UInt32, k: mi.UInt32, p: mi.Point3f,
                 d_light: mi.Vector3f, tmin: mi.Float, dist: mi.Float, far: mi.Bool, active: mi.Bool) -> None:
        """The first shape or plane between ``p`` and the light (``tmin < t < dist``; planes up to +inf for a
        directional light, as the kernel's shadow test): its id and ``t``, for naming the occluder."""
        si, offset, _ = octree_rule.intersect(scene, p, d_light, tmin, active)
        t_shape = dr.select(si.is_valid() & (si.t + offset < dist), si.t + offset, dr.inf)
        on_plane, t_plane, plane_idx = intersect_planes(planes, p, d_light, tmin,
                                                        dr.select(far, dr.inf, dist), active)
        plane_first = on_plane & (t_plane < t_shape)
        shape = dr.select(si.is_valid() & (si.t + offset < dist), shape_id(si.shape), 0)
        self.light(idx, k, occ_shape=dr.select(plane_first, 0, shape), occ_plane=plane_idx,
                   occ_on_plane=plane_first, occ_t=dr.select(plane_first, t_plane, t_shape))

    # ------------------------------------------------------------------ read back
    def read(self) -> tuple[object, object, object]:
        """``(nodes, lights, count)`` as numpy arrays: ``(W, N, NODE_STRIDE)``, ``(W, N, L, LIGHT_STRIDE)``,
        ``(W,)`` nodes per lane (``count > max_nodes``: the tree was cut)."""
        import numpy as np

        dr.eval(self.node_buf, self.light_buf, self.count)
        nodes = np.asarray(self.node_buf).reshape(self.width, self.max_nodes, NODE_STRIDE)
        lights = np.asarray(self.light_buf).reshape(self.width, self.max_nodes, self.max_lights, LIGHT_STRIDE)
        return nodes, lights, np.asarray(self.count)

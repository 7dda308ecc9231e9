"""The SPEC B.3 ray tree of one camera ray, rebuilt from what ``a5_whitted`` recorded in its own kernel.

:class:`RayNode` is one popped ray: its ray (kind, origin, direction, tmin, medium index, path weight), its hit
(t, point, object and its scene line, inside/outside, shading normal, material and its line), its local terms
(``ambient ⊙ diffuseColor``, then per light ``S · max(L·N, 0) · lightColor ⊙ kd``), its Fresnel weight ``R``
and the weights handed to its children (``w ⊙ specularColor ⊙ R`` to the mirror ray, ``w ⊙ specularColor ⊙
(1 - R)`` to the refracted one), and its contribution ``w ⊙ local`` (``w ⊙ background`` on a miss). All numbers
are the kernel's (plugins/kernel/record.py); this module only links nodes to parents and names objects.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from a5mi.converters.names import scene_ids, shape_kind
from a5mi.plugins.kernel.record import LIGHT_LAYOUT, NODE_LAYOUT

#: The scene-language keyword of each kind of object (:func:`a5mi.converters.names.shape_kind`).
KEYWORDS = {"sphere": "Sphere", "plane": "Plane", "triangle": "Triangle", "mesh": "TriangleMesh"}


def _fields(row: np.ndarray, layout: dict[str, tuple[int, int]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for name, (off, w) in layout.items():
        out[name] = float(row[off]) if w == 1 else tuple(float(x) for x in row[off:off + w])
    return out


@dataclass(frozen=True)
class SceneObject:
    """An object of the scene file: its kind (``Sphere``, ``Plane``, ``Triangle``, ``TriangleMesh``), its
    index in the Group, its line, its material index and the material's line."""

    kind: str
    index: int
    line: int
    material: int
    material_line: int | None

    def __str__(self) -> str:
        return f"{self.kind} at line {self.line}"


@dataclass
class LightTerm:
    """One light at one hit (SPEC B.3): direction ``L`` to the light, ``N·L``, the colour arriving (falloff
    applied), the shadow verdict (``visible``; ``tested`` = shadow rays on) and, when blocked, the occluder and
    its ``t``; ``term`` = ``max(L·N, 0) lightColor ⊙ kd`` (+ Phong), added to the local colour iff visible."""

    index: int
    name: str
    L: tuple[float, float, float]
    n_dot_l: float
    light_color: tuple[float, float, float]
    dist: float
    visible: bool
    tested: bool
    term: tuple[float, float, float]
    highlight: float
    occluder: SceneObject | None = None
    occluder_t: float | None = None

    @property
    def added(self) -> tuple[float, float, float]:
        """What this light adds to the node's local colour (before the path weight)."""
        return self.term if self.visible else (0.0, 0.0, 0.0)


@dataclass
class RayNode:
    """One node of the ray tree (module docstring). ``index`` is the kernel's depth-first number."""

    index: int
    kind: str                      # camera, reflection, refraction
    parent: int | None
    depth: int
    values: dict[str, Any]
    obj: SceneObject | None
    lights: list[LightTerm] = field(default_factory=list)
    children: list[int] = field(default_factory=list)

    def __getattr__(self, name: str) -> Any:
        try:
            return self.__dict__["values"][name]
        except KeyError:
            raise AttributeError(name) from None

    @property
    def is_hit(self) -> bool:
        return self.values["hit"] > 0.5

    @property
    def inside(self) -> bool:
        """The ray leaves the object (``d·N > 0``, SPEC B.3): it travels inside it."""
        d, n = np.array(self.values["d"]), np.array(self.values["n"])
        return bool(self.is_hit and float(np.dot(d, n)) > 0.0)

    @property
    def ambient_term(self) -> tuple[float, float, float]:
        """``ambient ⊙ diffuseColor`` (the kernel's local colour minus the added light terms)."""
        local = np.array(self.values["local"], np.float64)
        for light in self.lights:
            local -= np.array(light.added)
        return tuple(float(x) for x in local)  # type: ignore[return-value]


@dataclass
class RayTree:
    """The nodes of one camera ray, in the kernel's depth-first order (node 0 = the camera ray); ``color``
    is the kernel's colour for the ray; ``cut``: the tree had more nodes than were recorded."""

    nodes: list[RayNode]
    color: tuple[float, float, float]
    cut: bool = False

    def contribution_sum(self) -> np.ndarray:
        """Σ of node contributions, summed in float32 in the kernel's order (the kernel's own sum)."""
        acc = np.zeros(3, np.float32)
        for node in self.nodes:
            acc = acc + np.array(node.contribution, np.float32)
        return acc

    def subtree(self, index: int) -> np.ndarray:
        """Σ of the contributions of node ``index`` and everything below it (float64)."""
        node = self.nodes[index]
        total = np.array(node.contribution, np.float64)
        for child in node.children:
            total += self.subtree(child)
        return total


def scene_object(desc: Any, i: int) -> SceneObject:
    """Object ``i`` of the scene description's Group, with its kind, line and material."""
    shape = desc.shapes[i]
    mat = desc.materials[shape.material]
    return SceneObject(KEYWORDS[shape_kind(shape)], i, shape.loc.line, shape.material,
                       mat.loc.line if mat.loc else None)


def object_names(desc: Any, scene: Any, integrator: Any, rids: set[int]) -> tuple[dict[int, SceneObject],
                                                                                 list[SceneObject]]:
    """``({shape registry id: object}, [object of plane k])`` for a scene built by
    :func:`a5mi.converters.to_mitsuba.to_dict`: each shape's Mitsuba id and each plane's parameter id looked up
    in :func:`~a5mi.converters.names.scene_ids` (a shape that is no object, an area light's, is left
    out). ``rids``: the registry ids met in the record."""
    from a5mi.plugins.kernel.record import shape_of

    ids = scene_ids(desc)
    shapes: dict[int, SceneObject] = {}
    for rid in rids - {0}:
        s = shape_of(rid)
        index = ids.object_of_shape(s.id()) if s is not None else None
        if index is not None:
            shapes[rid] = scene_object(desc, index)
    planes = []
    for pid, *_ in integrator.planes:
        index = ids.object_of_plane(pid)
        if index is None:
            raise ValueError(f"a5_whitted has a plane '{pid}' that the scene description does not name")
        planes.append(scene_object(desc, index))
    return shapes, planes


def _named(row: dict[str, Any], shapes: dict[int, SceneObject], planes: list[SceneObject],
           on: str, plane: str, shape: str) -> SceneObject | None:
    if row[on] > 0.5:
        return planes[int(row[plane])] if planes else None
    return shapes.get(int(row[shape]))


def build_trees(nodes: np.ndarray, lights: np.ndarray, counts: np.ndarray, colors: np.ndarray, desc: Any,
                scene: Any, integrator: Any) -> list[RayTree]:
    """One :class:`RayTree` per lane from a :class:`~a5mi.plugins.kernel.record.TreeRecorder`'s buffers.

    Parents: the kernel pushes the refracted child, then the mirror child, and pops the last push first, so
    replaying that stack over the depth-first numbers links every node to its parent."""
    off_shape = NODE_LAYOUT["shape"][0]
    off_occ = LIGHT_LAYOUT["occ_shape"][0]
    rids = {int(x) for x in np.unique(nodes[..., off_shape])} | {int(x) for x in np.unique(lights[..., off_occ])}
    shapes, planes = object_names(desc, scene, integrator, rids)
    light_names = [f"{type(light).__name__} at line {light.loc.line}" for light in desc.lights]
    trees = []
    max_nodes = nodes.shape[1]
    for lane in range(nodes.shape[0]):
        n = min(int(counts[lane]), max_nodes)
        pending: list[tuple[str, int | None, int]] = [("camera", None, 0)]
        out: list[RayNode] = []
        for idx in range(n):
            row = _fields(nodes[lane, idx], NODE_LAYOUT)
            kind, parent, depth = pending.pop() if pending else ("?", None, 0)
            node = RayNode(idx, kind, parent, depth, row,
                           _named(row, shapes, planes, "on_plane", "plane", "shape") if row["hit"] > 0.5 else None)
            if row["hit"] > 0.5:
                for k in range(lights.shape[2]):
                    lr = _fields(lights[lane, idx, k], LIGHT_LAYOUT)
                    if lr["valid"] < 0.5:
                        continue
                    blocked = lr["tested"] > 0.5 and lr["visible"] < 0.5
                    occ = _named(lr, shapes, planes, "occ_on_plane", "occ_plane", "occ_shape") if blocked else None
                    node.lights.append(LightTerm(
                        k, light_names[k] if k < len(light_names) else f"light {k}", lr["L"], lr["n_dot_l"],
                        lr["light_color"], lr["dist"], lr["visible"] > 0.5, lr["tested"] > 0.5, lr["term"],
                        lr["highlight"], occ, lr["occ_t"] if blocked else None))
            if parent is not None:
                out[parent].children.append(idx)
            out.append(node)
            if row["push_refr"] > 0.5:
                pending.append(("refraction", idx, depth + 1))
            if row["push_refl"] > 0.5:
                pending.append(("reflection", idx, depth + 1))
        color = tuple(float(x) for x in colors[lane])
        trees.append(RayTree(out, color, cut=int(counts[lane]) > max_nodes))  # type: ignore[arg-type]
    return trees


def fresnel_text(node: RayNode, mode: str) -> str:
    """The SPEC B.3 Fresnel formula of ``-fresnel MODE`` with this node's numbers; the value of ``R`` shown
    is the kernel's (the inputs are recomputed here in float64 for display only)."""
    r = node.r_fresnel
    if node.refractive < 0.5:
        return f"R = {r:.6g} (no refracted ray: not a refracting material or no bounces left)"
    if node.refr_exists < 0.5:
        return f"R = {r:.6g} (total internal reflection: Snell has no solution)"
    d = np.array(node.d)
    n = np.array(node.n) * (-1.0 if node.leaving > 0.5 else 1.0)
    t = np.array(node.t_dir)
    n1, nt = node.n_medium, node.nt
    if mode == "exact":
        return f"R = fresnel(|d·N| = {abs(d @ n):.6g}, nt/n = {nt / n1:.6g}) = {r:.6g} (exact dielectric)"
    r0 = ((nt - 1) / (nt + 1)) ** 2 if mode == "a5" else ((nt - n1) / (nt + n1)) ** 2
    r0_txt = f"((nt-1)/(nt+1))² = (({nt:g}-1)/({nt:g}+1))²" if mode == "a5" else \
        f"((nt-n)/(nt+n))² = (({nt:g}-{n1:g})/({nt:g}+{n1:g}))²"
    c_txt, c = (f"|d·N| = {abs(d @ n):.6g}", abs(d @ n)) if nt > n1 else (f"|T·N| = {abs(t @ n):.6g}", abs(t @ n))
    return (f"R = R0 + (1-R0)(1-c)^5 with R0 = {r0_txt} = {r0:.6g}, c = {c_txt} (n {n1:g} -> nt {nt:g}): "
            f"R = {r:.6g} (-fresnel {mode})")

"""The Mitsuba names of a scene's objects and lights: the table the scene dict is named by (SPEC A.3, A.6).

:func:`scene_ids` gives, for a :class:`~.describe.SceneDescription`, each object's and light's entries in the
dict of :func:`.to_mitsuba.to_dict` (and the XML of :mod:`.to_xml`), which are also the ids of the loaded
Mitsuba objects and the prefixes of their ``mi.traverse`` parameters. :func:`.to_mitsuba.scene_entries` names
its entries by it, and code that finds an object in the dict, the loaded scene or a hit record reads it
(``a5mi.trace``: which object a ray hit; ``a5mi.animate``: which parameters to update) instead of parsing
names. No Mitsuba import.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Any

from a5mi.converters.describe import MeshShape, PlaneShape, SceneDescription, SphereShape
from a5mi.converters.model import AreaLight, SphereLight


@dataclass(frozen=True)
class ObjectIds:
    """The Mitsuba names of object ``index`` of the scene (SPEC A.6 file order, as
    :attr:`.describe.SceneDescription.shapes`); ``kind`` is ``sphere``, ``plane``, ``triangle`` or ``mesh``.

    * ``key``: its top-level entry of the scene dict, which is also the Mitsuba id of that shape and the prefix
      of its ``mi.traverse`` parameters (``sphere_003.to_world``, ``mesh_003.vertex_positions``); None for an
      exact plane, which is no shape (ARCHITECTURE.md, "Planes");
    * ``group``, ``inner``: for a sphere under a non-similarity transform, the ``shapegroup`` entry and the key
      (and id) of the sphere inside it, which ``key``'s ``instance`` places;
    * ``plane``: for an exact plane, the ``<id>`` of its ``plane_<id>_*`` parameters of ``a5_whitted``;
    * ``bsdf``: the keys leading to its BSDF in the dict of :func:`.to_mitsuba.to_dict` (:func:`object_bsdf`).
    """

    index: int
    kind: str
    key: str | None
    group: str | None = None
    inner: str | None = None
    plane: str | None = None

    @property
    def entry(self) -> str:
        """``key`` of an object that has a shape entry (every object but an exact plane)."""
        if self.key is None:
            raise ValueError(f"object {self.index} ({self.kind}) is an exact plane: it has no shape entry")
        return self.key

    @property
    def shape_ids(self) -> tuple[str, ...]:
        """The ids of the Mitsuba shapes that are this object (a hit on any of them is a hit on it)."""
        return tuple(i for i in (self.key, self.inner) if i is not None)

    def plane_param(self, name: str) -> str:
        """``plane_<id>_<name>``: an exact plane's ``a5_whitted`` parameter (``normal``, ``offset``, ``bsdf``,
        ``mirror_normal``)."""
        if self.plane is None:
            raise ValueError(f"object {self.index} ({self.kind}) has no plane parameters")
        return f"plane_{self.plane}_{name}"

    @property
    def bsdf(self) -> tuple[str, ...]:
        """The keys of its BSDF in the scene dict, ending in ``bsdf`` (a mesh entry holds it as ``.bsdf()``)."""
        if self.plane is not None:
            return ("integrator", self.plane_param("bsdf"))
        if self.group is not None and self.inner is not None:
            return (self.group, self.inner, "bsdf")
        return (self.entry, "bsdf")


@dataclass(frozen=True)
class LightIds:
    """The Mitsuba name of light ``index`` (SPEC A.3 order): ``key`` is its scene-dict entry, Mitsuba id and
    ``mi.traverse`` prefix (``light_000.position``); ``shape``: the entry is a shape carrying an area emitter
    (``AreaLight``, ``SphereLight``, EXTENSIONS E.2), not an emitter."""

    index: int
    key: str
    shape: bool = False


@dataclass(frozen=True)
class SceneIds:
    """Every Mitsuba name :func:`.to_mitsuba.scene_entries` gives a scene: one :class:`ObjectIds` per object and
    one :class:`LightIds` per light, in scene order. Code that finds an object in the dict, in ``mi.traverse`` or in
    a hit record reads this table (:func:`scene_ids`) instead of parsing names."""

    objects: tuple[ObjectIds, ...]
    lights: tuple[LightIds, ...]

    @cached_property
    def _by_shape(self) -> dict[str, int]:
        return {sid: o.index for o in self.objects for sid in o.shape_ids}

    @cached_property
    def _by_plane(self) -> dict[str, int]:
        return {o.plane: o.index for o in self.objects if o.plane is not None}

    def object_of_shape(self, shape_id: str) -> int | None:
        """The object whose Mitsuba shape has id ``shape_id`` (None: not an object, e.g. an area light)."""
        return self._by_shape.get(shape_id)

    def object_of_plane(self, plane_id: str) -> int | None:
        """The exact plane whose ``a5_whitted`` parameters are ``plane_<plane_id>_*``."""
        return self._by_plane.get(plane_id)


def scene_ids(desc: SceneDescription, *, stock: bool = False, binary_spheres: bool = True) -> SceneIds:
    """The names of ``desc``'s objects and lights in the dict of :func:`.to_mitsuba.to_dict` (and the XML of
    :mod:`.to_xml`) made with the same ``stock``: the parameter id ``NNN`` for a sphere (intersected by
    ``a5_whitted`` as the binary does, plugins/emulation/planes.py; with ``stock`` ``sphere_NNN``, and
    ``sphere_NNN_group`` holding ``sphere_NNN_shape`` when its transform is no similarity), ``plane_NNN``
    (``--stock`` rectangle) or the parameter id ``NNN`` (exact plane), ``triangle_NNN``, ``mesh_NNN``,
    ``light_NNN``; ``NNN`` the index, three digits at least. ``binary_spheres = False`` (the physically based
    integrators and ``-subsurface``, which trace Mitsuba's own shapes: :func:`binary_spheres`): spheres are
    ``sphere_NNN`` Mitsuba shapes, as with ``stock``."""
    objects = []
    for i, shape in enumerate(desc.shapes):
        key = f"{shape_kind(shape)}_{i:03d}"
        if isinstance(shape, SphereShape) and not stock and binary_spheres:
            objects.append(ObjectIds(i, "sphere", None, plane=f"{i:03d}"))   # the binary's test, a5_whitted's
        elif isinstance(shape, SphereShape) and shape.to_world is not None:
            objects.append(ObjectIds(i, "sphere", key, group=key + "_group", inner=key + "_shape"))
        elif isinstance(shape, PlaneShape) and not stock:
            objects.append(ObjectIds(i, "plane", None, plane=f"{i:03d}"))
        else:
            objects.append(ObjectIds(i, shape_kind(shape), key))
    lights = tuple(LightIds(i, f"light_{i:03d}", isinstance(light, AreaLight | SphereLight))
                   for i, light in enumerate(desc.lights))
    return SceneIds(tuple(objects), lights)


def binary_spheres(integrator: str, subsurface: str) -> bool:
    """Whether spheres are intersected by the binary's test inside ``a5_whitted`` (SPEC B.3,
    plugins/emulation/planes.py):
    for the sample solution's tracing (``-integrator whitted``) without ``-subsurface``; the physically based
    integrators (docs/EXTENSIONS.md E.13-E.17) and the E.18 probes and walks trace Mitsuba's sphere shape."""
    return integrator == "whitted" and subsurface == "none"


def shape_kind(shape: SphereShape | PlaneShape | MeshShape) -> str:
    """``sphere``, ``plane``, ``mesh`` (a ``TriangleMesh``) or ``triangle``."""
    if isinstance(shape, SphereShape):
        return "sphere"
    if isinstance(shape, PlaneShape):
        return "plane"
    return "mesh" if shape.obj_file is not None else "triangle"


def object_bsdf(scene_dict: dict[str, Any], obj: ObjectIds) -> Any:
    """The BSDF of ``obj`` in a dict of :func:`.to_mitsuba.to_dict`: a loaded BSDF object
    (:attr:`ObjectIds.bsdf`)."""
    *path, last = obj.bsdf
    entry: Any = scene_dict
    for key in path:
        entry = entry[key]
    return entry[last] if isinstance(entry, dict) else entry.bsdf()

"""The live page's scene builds: Mitsuba objects kept from one save to the next (docs/VIEW.md "Live reload").

A save re-parses and re-describes the scene (SPEC A), and a plain :class:`a5mi.render.session.RenderSession` then builds
every Mitsuba object again (``mi.load_dict`` of :func:`a5mi.converters.to_mitsuba.to_dict`): on the course scenes
that is 0.15-0.25 s, most of it the ``a5_cubemap`` emitter (six faces into its atlas), for an edit that changed
one number. :class:`ViewSession` builds the same dict through :class:`KeyedBackend`, whose every object (image
bitmap, BSDF, mesh, and each top-level entry but the integrator) is first a :class:`Pending` key, the exact
content it is made from:

* an image: the decoded :class:`~a5mi.converters.files.Image` object (the engine keeps decoded images while
  their file's ``(mtime_ns, size, inode)`` stays, so an unchanged file is the same object);
* a BSDF: ``(material number, untextured variant, the a5_material dict)`` (as ``to_dict`` makes one BSDF per
  material and uv variant);
* a mesh: ``(entry name, its BSDF's key, BLAKE2b of every array of its world-space MeshData)``;
* a top-level entry (camera, lights, background): ``(name, the dict)``.

Dict contents become keys by :func:`freeze`: floats by ``float.hex`` (``0.0`` and ``-0.0`` differ), arrays by
dtype, shape and bytes, objects it does not know by identity (never shared). Then the objects whose key the
new build does not use are dropped *before* the missing ones are made (as the session frees the old scene before
a build: a made object takes the registry ID its predecessor left, and the render kernel, which names the
instances by ID, is found in Dr.Jit's cache instead of compiled again), and the scene is loaded from the kept
and the new objects. When nothing but the integrator entry changed (``ambientLight``, the exact planes'
parameters, the flags), the Mitsuba scene itself is kept and only the integrator is loaded.

A kept object was made from equal input by the same code, so the render is the one a fresh build gives, bit
for bit (tests/view/test_view_build.py compares with ``a5`` after geometry, material and number edits).
"""

from __future__ import annotations

import hashlib
import weakref
from collections.abc import Callable, Hashable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from a5mi.converters import materials
from a5mi.converters.to_mitsuba import Backend, bitmap, cubemap_faces, make_mesh, scene_entries
from a5mi.platform.loading import load_dict
from a5mi.render.options import RenderOptions
from a5mi.render.session import RenderSession

if TYPE_CHECKING:
    import mitsuba as mi

    from a5mi.converters.describe import CubeMapBackground, MeshShape, SceneDescription, VolumeDescription
    from a5mi.converters.files import Image

#: Top-level entry types never made on their own: an instance names its shape group by ``ref``, resolved only
#: inside one ``mi.load_dict``.
LINKED_TYPES = frozenset({"shapegroup", "instance"})


@dataclass(frozen=True, eq=False)
class Pending:
    """An object of the scene dict not made yet: ``key`` (what it is made from, :func:`freeze`d) and
    ``make(resolve)``, which makes it (``resolve`` turns the :class:`Pending` values it holds into objects)."""

    key: Hashable
    make: Callable[[Callable[[Any], Any]], Any]


def freeze(value: Any, keep: list[Any]) -> Hashable:
    """A hashable key equal for equal dict contents (module docstring); objects keyed by identity are appended to
    ``keep`` (kept alive with the key, so their ``id`` is not reused)."""
    if isinstance(value, Pending):
        return ("pending", value.key)
    if isinstance(value, dict):
        return ("dict", tuple((k, freeze(v, keep)) for k, v in value.items()))
    if isinstance(value, list | tuple):
        return (type(value).__name__, tuple(freeze(v, keep) for v in value))
    if isinstance(value, np.ndarray):
        return ("array", value.dtype.str, value.shape, value.tobytes())
    if isinstance(value, np.generic):
        return ("scalar", value.dtype.str, value.tobytes())
    if isinstance(value, float):
        return ("float", value.hex())
    if value is None or isinstance(value, bool | int | str):
        return (type(value).__name__, value)
    keep.append(value)
    return ("object", id(value))


#: :func:`mesh_digest` of each live MeshData (its arrays are read-only: a placement kept across descriptions,
#: :func:`a5mi.converters.describe.placed_mesh`, is hashed once).
_DIGESTS: weakref.WeakKeyDictionary[Any, str] = weakref.WeakKeyDictionary()


def mesh_digest(shape: MeshShape) -> str:
    """BLAKE2b of every array of the shape's world-space :class:`~a5mi.converters.geometry.MeshData` (dtype,
    shape and bytes; a missing array counts as such), computed once per MeshData object."""
    data = shape.mesh
    known = _DIGESTS.get(data)
    if known is None:
        known = _DIGESTS[data] = _digest(data)
    return known


def _digest(data: Any) -> str:
    h = hashlib.blake2b(digest_size=20)
    for a in (data.positions, data.faces, data.normals, data.texcoords, data.octree, data.triangles):
        if a is None:
            h.update(b"-")
        else:
            h.update(f"{a.dtype.str}{a.shape}".encode())
            h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


def as_load_value(value: Any, resolve: Callable[[Any], Any]) -> Any:
    """``value`` with its :class:`Pending` objects made (``resolve``) and, in dicts, every ``np.ndarray`` turned
    into ``mi.ScalarTransform4f`` (the conversion :func:`a5mi.converters.to_mitsuba.to_dict` ends with)."""
    import mitsuba as mi

    if isinstance(value, Pending):
        return resolve(value)
    if isinstance(value, np.ndarray):
        return mi.ScalarTransform4f(value.tolist())
    if isinstance(value, dict):
        return {k: as_load_value(v, resolve) for k, v in value.items()}
    return value


class KeyedBackend(Backend):
    """The dict back end of :func:`a5mi.converters.to_mitsuba.to_dict` (a5 plugins) whose bitmaps, BSDFs and
    meshes are :class:`Pending` (module docstring); ``keep`` collects the identity-keyed objects."""

    def __init__(self, desc: SceneDescription) -> None:
        super().__init__(desc, stock=False)
        self.keep: list[Any] = []

    def image(self, image: Image) -> Pending:
        self.keep.append(image)
        return Pending(("image", id(image)), lambda resolve: bitmap(image))

    def bsdf(self, entries: dict[str, Any], material: int, with_uv: bool) -> Pending:
        mat = self.desc.materials[material]
        d = materials.bsdf(mat, with_uv, stock=False, image=lambda img: {"bitmap": self.image(img)})
        key = ("bsdf", material, materials.without_texture(mat, with_uv), freeze(d, self.keep))
        return Pending(key, lambda resolve: load_dict(as_load_value(d, resolve)))

    def mesh(self, key: str, shape: MeshShape, bsdf: Any) -> Pending:
        return Pending(("mesh", key, freeze(bsdf, self.keep), mesh_digest(shape)),
                       lambda resolve: make_mesh(key, shape.mesh, resolve(bsdf)))

    def cubemap(self, bg: CubeMapBackground) -> Any:
        return {"type": "a5_cubemap", **cubemap_faces(bg, self.image)}

    def envmap(self, bg: CubeMapBackground) -> Any:
        raise NotImplementedError("the live page renders with the a5 plugins (no stock envmap)")

    def grid_source(self, vol: VolumeDescription) -> dict[str, Any]:
        import mitsuba as mi

        return {"data": mi.TensorXf(np.ascontiguousarray(vol.grid, dtype=np.float32))}


def pending_entries(desc: SceneDescription, options: RenderOptions) -> tuple[dict[str, Any], list[Any]]:
    """The scene dict of ``desc`` with :class:`Pending` objects: those of :class:`KeyedBackend`, and each top-level
    entry but ``type``, ``integrator`` and the :data:`LINKED_TYPES` (and entries that reference them); with the
    identity-keyed objects to keep alive."""
    backend = KeyedBackend(desc)
    entries = scene_entries(desc, options, backend)
    linked = any(isinstance(v, dict) and v.get("type") in LINKED_TYPES for v in entries.values())
    for name, value in list(entries.items()):
        if name not in ("type", "integrator") and isinstance(value, dict) and not linked:
            entries[name] = Pending(("entry", name, freeze(value, backend.keep)),
                                    lambda resolve, value=value: load_dict(as_load_value(value, resolve)))
    return entries, backend.keep


class ViewSession(RenderSession):
    """A :class:`~a5mi.render.session.RenderSession` whose builds keep the objects of the last build that the next one
    can use (module docstring). ``made`` counts the objects made, ``reused`` those taken from the last build,
    ``scenes_kept`` the builds that kept the Mitsuba scene (tests read them)."""

    def __init__(self, variant: str | None = None) -> None:
        super().__init__(variant, max_scenes=1)
        self._objects: dict[Hashable, Any] = {}
        self._keep: list[Any] = []
        self._scene: tuple[Hashable, mi.Scene] | None = None
        self.made = self.reused = self.scenes_kept = 0

    def build(self, desc: SceneDescription, options: RenderOptions
              ) -> tuple[mi.Scene, dict[str, Any], mi.SamplingIntegrator]:
        entries, keep = pending_entries(desc, options)
        keys = _pending_keys(entries)
        # the scene is kept only with the same objects in its integrator too: the one it was loaded with holds them
        scene_key = (tuple(freeze(v, keep) for k, v in entries.items() if k != "integrator"),
                     frozenset(_pending_keys(entries["integrator"])))
        dropped = [k for k in self._objects if k not in keys]
        for k in dropped:
            del self._objects[k]
        kept_scene = self._scene is not None and self._scene[0] == scene_key
        if not kept_scene:
            self._scene = None  # freed now (reference counts), with the dropped objects: the new ones reuse their IDs
        self._keep = keep
        reused = set(self._objects)

        def resolve(p: Pending) -> Any:
            obj = self._objects.get(p.key)
            if obj is None:
                obj = self._objects[p.key] = p.make(resolve)
                self.made += 1
            return obj

        template = as_load_value(entries["integrator"], resolve)
        if kept_scene:
            assert self._scene is not None
            scene = self._scene[1]
            integrator = load_dict(dict(template))
            self.scenes_kept += 1
        else:
            scene = load_dict({k: (template if k == "integrator" else as_load_value(v, resolve))
                          for k, v in entries.items()})
            integrator = scene.integrator()
            self._scene = (scene_key, scene)
        self.reused += len(reused & keys)
        # the template keeps the scene's part only, as RenderSession.build's: an integrator of other options is
        # loaded from it plus their own parameters, and one they leave out (an empty -mistake) must not stay
        own = options.integrator_params()
        return scene, {k: v for k, v in template.items() if k not in own}, integrator


def _pending_keys(value: Any) -> set[Hashable]:
    """The keys of every :class:`Pending` in ``value``, and of those their ``make`` resolves (a mesh's BSDF, a
    BSDF's or cube map's bitmaps): found through the keys themselves, which hold theirs as ``("pending", key)``."""
    out: set[Hashable] = set()

    def walk(v: Any) -> None:
        if isinstance(v, Pending):
            out.add(v.key)
            inner(v.key)
        elif isinstance(v, dict):
            for x in v.values():
                walk(x)
        elif isinstance(v, list | tuple):
            for x in v:
                walk(x)

    def inner(key: Any) -> None:
        if isinstance(key, tuple):
            if len(key) == 2 and key[0] == "pending":
                out.add(key[1])
            for x in key:
                inner(x)

    walk(value)
    return out


__all__ = ["KeyedBackend", "Pending", "ViewSession", "as_load_value", "freeze", "mesh_digest", "pending_entries"]

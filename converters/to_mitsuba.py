"""Scene description -> Mitsuba 3 scene dict (SPEC A.3-A.6 lights, background, shapes; B.2 camera; B.3 integrator).

:func:`to_dict` returns a dict for ``mi.load_dict`` made from a :class:`.describe.SceneDescription` (every file
already read: images arrive as ``mi.Bitmap`` objects built from the decoded pixels, meshes as ``mi.Mesh``
objects, BSDFs as loaded objects). With ``stock=False`` it uses the a5mi plugins of the contract in
ARCHITECTURE.md (``a5_whitted``, ``a5_camera``, ``a5_material``, ``a5_marble``, ``a5_bitmap``, ``a5_point``,
``a5_cubemap``), which must be registered (``a5mi.plugins.register_all()``); with ``stock=True`` it uses stock
Mitsuba plugins only. :func:`scene_entries` is the layout shared with the XML writer (:mod:`.to_xml`); what
differs between the two (BSDFs, meshes, images) goes through a :class:`Backend`. This module and
:mod:`.to_xml` are the only ones of ``converters`` that import Mitsuba, and only inside the functions that
need it. Geometry: :mod:`.geometry`; materials: :mod:`.materials`; names: :func:`.names.scene_ids`, the
table (object or light -> its Mitsuba ids) that :func:`scene_entries` names the entries by.

Camera, integrator, lights and background:

* integrator ``a5_whitted`` with ``ambient`` (the description's ambient term) and
  :meth:`a5mi.render.options.RenderOptions.integrator_params`; sensor ``a5_camera`` (B.2) with an ``hdrfilm`` of
  :attr:`~a5mi.render.options.RenderOptions.render_size`, a ``box`` filter, the jittered ``stratified`` sampler and
  ``pixel_centres`` (every sample through its pixel's centre, as ``a5 -spp N``: the sampler's positions only
  choose the pixel), and the E.3 ``aperture`` / ``focus_distance`` of a thin-lens camera;
* ``directional`` (stock; ``irradiance`` = colour, the direction it travels); ``a5_point``;
* the background is ``a5_cubemap`` (its six faces) if ``cubeMap`` is set, else a stock ``constant`` with
  ``radiance`` = colour.

``stock=True`` approximations (for use outside a5mi; none is needed for a5 renders):

* integrator ``path`` with ``max_depth = bounces + 2``; there is no ambient term (``describe(stock=True)``
  warns if it is not 0);
* sensor ``perspective`` at ``to_world = look_at(center, center + direction, up)`` with
  ``fov = 2·atan(tan(angle/2)·W/(W−1))`` on the x axis. B.2 puts the first and last pixel *centres* on ±1
  (spacing ``2/(W−1)``); Mitsuba puts the film *edges* there (spacing ``2/W``); this fov makes the pixel
  centres coincide exactly for square images. Non-square images: y keeps Mitsuba's aspect-correct spacing
  ``2/(W−1)·tan(angle/2)`` instead of B.2's ``2/(H−1)``. With the ``stratified`` sampler (1 spp, no jitter)
  the ray goes through the pixel centre as in a5soln;
* a ``Fog`` / ``Volume`` (docs/EXTENSIONS.md E.8, E.9): a ``homogeneous`` / ``heterogeneous`` medium on the
  sensor and ``volpath`` instead of ``path`` (:mod:`.ext_mitsuba`);
* materials: :mod:`.materials`;
* ``a5_point`` -> ``point`` with ``intensity = color·d²/(1 + falloff·d²)``, ``d`` the distance from the light
  to the centre of the scene's finite geometry: exact at that distance, inverse-square elsewhere;
* ``Wood`` / ``Turbulence`` / ``Veins`` (E.6) -> the stock ``volume`` texture of an RGB grid baked from
  ``a5_solid`` (:func:`bake_solid`; loaded by name, so the a5 plugins must be registered for this step, as for
  the cube map);
* cube map -> ``envmap`` from a 2048 x 1024 latitude-longitude image baked by evaluating the ``a5_cubemap``
  plugin (loaded by name, so the a5 plugins must be registered for this step) at the pixel-centre directions
  ``d = (sin θ sin φ, cos θ, −sin θ cos φ)``, ``θ = π (j + ½)/1024``, ``φ = 2π (i + ½)/2048`` (Mitsuba's
  envmap parametrisation); the envmap then filters it bilinearly.
"""

from __future__ import annotations

import math
import weakref
from abc import ABC, abstractmethod
from collections.abc import Callable
from typing import Any

import numpy as np

from a5mi.converters import materials
from a5mi.converters import transforms as tf
from a5mi.converters.describe import (
    ColorBackground,
    CubeMapBackground,
    Light,
    MeshShape,
    PlaneShape,
    SceneDescription,
    SphereShape,
    VolumeDescription,
)
from a5mi.converters.errors import SceneSemanticError
from a5mi.converters.ext_mitsuba import (
    baked_solid,
    grid_volume,
    light_entry,
    medium_params,
    solid_box,
    solid_resolution,
    stock_medium,
    thinlens_params,
)
from a5mi.converters.files import Image
from a5mi.converters.geometry import MeshData
from a5mi.converters.materials import rgb
from a5mi.converters.model import AreaLight, DirectionalLight, SphereLight, SpotLight
from a5mi.converters.names import binary_spheres, scene_ids
from a5mi.platform.loading import load_dict
from a5mi.render.options import MARBLE_MISTAKES, RenderOptions
from a5mi.spec import CUBE_FACES

#: Face attributes carrying :attr:`.geometry.MeshData.octree` (name -> its columns).
OCTREE_ATTRIBUTES = {"face_a5_inv0": [0, 1, 2], "face_a5_inv1": [3, 4, 5], "face_a5_inv2": [6, 7, 8],
                     "face_a5_octree": [9, 10, 11]}
#: Face attributes carrying :attr:`.geometry.MeshData.triangles` (name -> its columns).
TRIANGLE_ATTRIBUTES = {"face_a5_inv_t": [0, 1, 2], "face_a5_v0": [3, 4, 5], "face_a5_v1": [6, 7, 8],
                       "face_a5_v2": [9, 10, 11], "face_a5_n0": [12, 13, 14], "face_a5_n1": [15, 16, 17],
                       "face_a5_n2": [18, 19, 20]}

#: Size of the baked latitude-longitude environment in stock mode.
ENVMAP_SIZE = (2048, 1024)


def integrator_dict(desc: SceneDescription, options: RenderOptions, *, stock: bool) -> dict[str, Any]:
    """SPEC B.3: ``options.plugin`` (``a5_whitted`` unless ``-integrator`` says otherwise; ambient + the options'
    parameters + the scene's material flags), or stock ``path`` (``bounces + 2``)."""
    if stock:
        return {"type": "path", "max_depth": int(options.bounces) + 2}
    d = {"type": options.plugin, "ambient": rgb(desc.ambient), **options.integrator_params()}
    glossy = max((m.glossy_samples for m in desc.materials if m.roughness > 0.0), default=1)
    if glossy > 1:  # docs/EXTENSIONS.md E.4: the stack holds 2 G children of a glossy camera hit
        d["glossy_samples"] = int(glossy)
    if any(m.dispersion is not None for m in desc.materials):  # docs/EXTENSIONS.md E.10: wavelength per ray
        d["dispersion"] = True
    if not any(m.roughness > 0.0 for m in desc.materials):
        d["glossy"] = False  # no glossy material: the kernel leaves the E.4 lobe sampling out (EXTENSIONS E.4)
    return d


def sensor_dict(desc: SceneDescription, options: RenderOptions, *, stock: bool) -> dict[str, Any]:
    """SPEC B.2: ``a5_camera`` (or the stock ``perspective`` of the module docstring) with the render buffer's
    film, a box filter and one unjittered sample per pixel."""
    cam = desc.camera
    width, height = options.render_size
    film = {"type": "hdrfilm", "width": int(width), "height": int(height), "rfilter": {"type": "box"},
            "pixel_format": "rgb"}
    sampler = {"type": "stratified", "sample_count": 1, "jitter": False}
    if not stock:  # every sample through its pixel's centre, as a5 -spp N; the E.3 lens in the sensor
        lens = ({"aperture": float(cam.aperture), "focus_distance": float(cam.focus_distance)}
                if cam.aperture > 0.0 else {})
        return {"type": "a5_camera", "center": list(cam.center), "direction": list(cam.direction),
                "up": list(cam.up), "angle": float(cam.angle), **lens, "pixel_centres": True, "film": film,
                "sampler": {**sampler, "jitter": True}}
    w = max(int(width), 2)
    fov = math.degrees(2.0 * math.atan(math.tan(math.radians(cam.angle) / 2.0) * w / (w - 1)))
    c = np.asarray(cam.center, dtype=np.float64)
    if cam.aperture > 0.0:  # docs/EXTENSIONS.md E.3
        sampler = {"type": "stratified", "sample_count": int(options.spp), "jitter": True}
        return {"type": "thinlens", "fov": fov, "fov_axis": "x", **thinlens_params(cam.aperture, cam.focus_distance),
                "to_world": tf.look_at(c, c + np.asarray(cam.direction), np.asarray(cam.up)),
                "film": film, "sampler": sampler}
    return {"type": "perspective", "fov": fov, "fov_axis": "x",
            "to_world": tf.look_at(c, c + np.asarray(cam.direction), np.asarray(cam.up)),
            "film": film, "sampler": sampler}


def light_dict(light: Light, centre: np.ndarray | None, *, stock: bool) -> dict[str, Any]:
    """SPEC A.3: stock ``directional``; ``a5_point`` (or the stock ``point`` of the module docstring, scaled
    to be exact at the distance to ``centre``)."""
    if isinstance(light, DirectionalLight):
        return {"type": "directional", "direction": list(light.direction), "irradiance": rgb(light.color)}
    if isinstance(light, SpotLight | AreaLight | SphereLight):  # docs/EXTENSIONS.md E.1, E.2
        return light_entry(light, centre, stock=stock)
    if not stock:
        return {"type": "a5_point", "position": list(light.position), "color": rgb(light.color),
                "falloff": float(light.falloff)}
    dist2 = 1.0 if centre is None else float(np.sum((centre - np.asarray(light.position)) ** 2))
    scale = dist2 / (1.0 + light.falloff * dist2)
    return {"type": "point", "position": list(light.position), "intensity": rgb(np.asarray(light.color) * scale)}


def background_dict(bg: ColorBackground) -> dict[str, Any]:
    """SPEC A.4 without a cube map: the stock ``constant`` emitter with ``radiance`` = the colour."""
    return {"type": "constant", "radiance": rgb(bg.color)}


class Backend(ABC):
    """What differs between the ``mi.load_dict`` dict and the XML: how BSDFs, meshes and cube maps become
    values. ``entries`` is the scene dict being built (a back end may add entries to it, in order)."""

    def __init__(self, desc: SceneDescription, *, stock: bool) -> None:
        self.desc = desc
        self.stock = stock
        self.solids: dict[int, dict[str, Any]] = {}  # material -> its baked stock texture (E.6)

    def stock_solids(self, value: Any, material: int) -> Any:
        """``value`` (a stock BSDF dict) with every ``a5_solid`` texture replaced by the stock ``volume``
        texture of its grid (:func:`bake_solid`, once per material; docs/EXTENSIONS.md E.6, stock mapping)."""
        if isinstance(value, dict):
            if value.get("type") == "a5_solid":
                if material not in self.solids:
                    lo, hi = solid_box(self.desc, material)
                    self.solids[material] = baked_solid(self.solid_grid(bake_solid(value, lo, hi), material), lo, hi)
                return self.solids[material]
            return {k: self.stock_solids(v, material) for k, v in value.items()}
        return value

    def solid_grid(self, grid: np.ndarray, material: int) -> dict[str, Any]:
        """Where the ``gridvolume`` of a baked solid gets its (z, y, x, 3) grid: here the tensor itself (the XML
        back end writes a file)."""
        import mitsuba as mi

        return {"data": mi.TensorXf(np.ascontiguousarray(grid, dtype=np.float32))}

    @abstractmethod
    def bsdf(self, entries: dict[str, Any], material: int, with_uv: bool) -> Any:
        """The value of a shape's ``bsdf`` for material number ``material`` on a shape with/without uv."""

    @abstractmethod
    def mesh(self, key: str, shape: MeshShape, bsdf: Any) -> Any:
        """The entry of a world-space mesh."""

    @abstractmethod
    def cubemap(self, bg: CubeMapBackground) -> Any:
        """The ``a5_cubemap`` emitter entry (a5 plugins)."""

    @abstractmethod
    def envmap(self, bg: CubeMapBackground) -> Any:
        """The stock ``envmap`` entry baked from the cube map."""

    @abstractmethod
    def grid_source(self, vol: VolumeDescription) -> dict[str, Any]:
        """Where a ``gridvolume`` gets a Volume's grid: ``{'data': tensor}`` or ``{'filename': path}``."""


def scene_entries(desc: SceneDescription, options: RenderOptions, backend: Backend) -> dict[str, Any]:
    """The scene dict's layout (module docstring): ``integrator``, ``sensor``, one entry per light,
    ``background``, then one entry per shape (exact planes: ``a5_whitted`` parameters), each named by
    :func:`scene_ids`, with 4x4 transforms as ``np.ndarray``."""
    stock = backend.stock
    ids = scene_ids(desc, stock=stock, binary_spheres=binary_spheres(options.integrator, options.subsurface))
    d: dict[str, Any] = {"type": "scene", "integrator": integrator_dict(desc, options, stock=stock),
                         "sensor": sensor_dict(desc, options, stock=stock)}
    for light, lid in zip(desc.lights, ids.lights, strict=True):
        d[lid.key] = light_dict(light, desc.centre, stock=stock)
    if desc.medium is not None:  # docs/EXTENSIONS.md E.8, E.9
        med = desc.medium
        if not stock and options.integrator != "whitted":  # the media code lives in a5_whitted's loop only
            kind = "Volume" if isinstance(med, VolumeDescription) else "Fog"
            raise SceneSemanticError(f"{kind} is rendered by -integrator whitted only (docs/EXTENSIONS.md E.8, "
                                     f"E.9); -integrator {options.integrator} has no participating media",
                                     med.loc)
        grid = grid_volume(med, backend.grid_source(med)) if isinstance(med, VolumeDescription) else None
        if stock:
            d["integrator"]["type"] = "volpath"
            d["sensor"]["medium"] = stock_medium(med, grid)
        else:
            d["integrator"].update(medium_params(med, grid))
    bg = desc.background
    if isinstance(bg, CubeMapBackground):
        d["background"] = backend.envmap(bg) if stock else backend.cubemap(bg)
    else:
        d["background"] = background_dict(bg)
    for shape, o in zip(desc.shapes, ids.objects, strict=True):
        bsdf = backend.bsdf(d, shape.material, shape.has_uv)
        if options.quirks == "binary" and o.plane is not None and not shape.has_uv and \
                isinstance(desc.materials[shape.material].kd, Image):
            # the textured BSDF, looked up at a mesh's stale uv (plugins/emulation/planes.py, docs/FIDELITY.md)
            d["integrator"][o.plane_param("bsdf_uv")] = backend.bsdf(d, shape.material, True)
        if isinstance(shape, SphereShape):
            sphere = {"type": "sphere", "center": list(shape.center), "radius": float(shape.radius), "bsdf": bsdf}
            if o.plane is not None:   # a5: the binary's sphere test inside a5_whitted (plugins/emulation/planes.py)
                to_world, centre, radius = shape.binary or (np.eye(4), shape.center, shape.radius)
                d["integrator"].update({o.plane_param("center"): [float(x) for x in centre],
                                        o.plane_param("radius"): float(radius),
                                        o.plane_param("to_world"): to_world, o.plane_param("bsdf"): bsdf})
            elif o.group is None or o.inner is None:
                d[o.entry] = sphere
            else:
                d[o.group] = {"type": "shapegroup", o.inner: sphere}  # the inner id names the object
                d[o.entry] = {"type": "instance", "shapegroup": {"type": "ref", "id": o.group},
                                 "to_world": shape.to_world}
        elif isinstance(shape, PlaneShape):
            if o.plane is None:  # --stock: plain Mitsuba has no infinite plane, the finite stand-in of .geometry
                d[o.entry] = {"type": "rectangle", "to_world": shape.rectangle, "bsdf": bsdf}
            else:      # exact: intersected analytically by a5_whitted (plugins/emulation/planes.py)
                mirror = shape.n_w if shape.mirror_normal is None else shape.mirror_normal
                n, off = (shape.n_w, shape.offset_w) if shape.binary is None else shape.binary[1:]
                if shape.binary is not None:   # in object space, as the binary's Transform does
                    d["integrator"][o.plane_param("to_world")] = shape.binary[0]
                d["integrator"].update({o.plane_param("normal"): [float(x) for x in n],
                                        o.plane_param("offset"): float(off),
                                        o.plane_param("mirror_normal"): [float(x) for x in mirror],
                                        o.plane_param("bsdf"): bsdf})
        else:
            d[o.entry] = backend.mesh(o.entry, shape, bsdf)
    return d


# ------------------------------------------------------------------------------------------------- Mitsuba
def make_mesh(name: str, data: MeshData, bsdf: Any = None) -> Any:
    """An ``mi.Mesh`` named ``name`` from :class:`.geometry.MeshData` (``bsdf``: a loaded BSDF object or None)."""
    import mitsuba as mi

    props = mi.Properties()
    if bsdf is not None:
        props["bsdf"] = bsdf
    mesh = mi.Mesh(name, vertex_count=len(data.positions), face_count=len(data.faces),
                   has_vertex_normals=data.normals is not None, has_vertex_texcoords=data.texcoords is not None,
                   props=props)
    params = mi.traverse(mesh)
    params["vertex_positions"] = mi.Float(np.ascontiguousarray(data.positions, dtype=np.float32).ravel())
    params["faces"] = mi.UInt32(np.ascontiguousarray(data.faces, dtype=np.uint32).ravel())
    if data.normals is not None:
        params["vertex_normals"] = mi.Float(np.ascontiguousarray(data.normals, dtype=np.float32).ravel())
    if data.texcoords is not None:
        params["vertex_texcoords"] = mi.Float(np.ascontiguousarray(data.texcoords, dtype=np.float32).ravel())
    params.update()
    if data.octree is not None:  # the binary's octree rule, read by a5_whitted (plugins/emulation/octree_rule.py)
        for name, cols in OCTREE_ATTRIBUTES.items():
            mesh.add_attribute(name, len(cols), np.ascontiguousarray(data.octree[:, cols]).ravel().tolist())
    if data.triangles is not None:  # the binary's triangle test (plugins/emulation/triangle_rule.py)
        for name, cols in TRIANGLE_ATTRIBUTES.items():
            mesh.add_attribute(name, len(cols), np.ascontiguousarray(data.triangles[:, cols]).ravel().tolist())
    return mesh


def bitmap(image: Image) -> Any:
    """An ``mi.Bitmap`` holding the decoded pixels of ``image`` (a copy: Mitsuba wants a writable array), made
    once per image and variant while the image lives: a decoded image kept from one build to the next (``a5mi
    serve``'s :class:`~a5mi.converters.files.KeptFiles`) is not copied again; the plugins only read bitmaps."""
    import mitsuba as mi

    made = _BITMAPS.get(image)
    if made is None or made[0] != mi.variant():
        made = _BITMAPS[image] = (mi.variant(), mi.Bitmap(np.array(image.pixels, dtype=np.uint8, order="C", copy=True)))
    return made[1]


#: :func:`bitmap`'s ``(variant, mi.Bitmap)`` of each decoded image still alive
_BITMAPS: weakref.WeakKeyDictionary[Image, tuple[str, Any]] = weakref.WeakKeyDictionary()


def cubemap_faces(bg: CubeMapBackground, make: Callable[[Image], Any] = bitmap) -> dict[str, Any]:
    """``{'left': mi.Bitmap, ..., 'back': mi.Bitmap}``: the ``a5_cubemap`` parameters for its decoded faces."""
    return {face: make(img) for face, img in zip(CUBE_FACES, bg.faces, strict=True)}


def bake_solid(texture: dict[str, Any], lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """(nz, ny, nx, 3) float32: the ``a5_solid`` ``texture`` (loaded by name: the a5 plugins must be registered)
    at the cell centres ``lo + (i + ½)/n (hi − lo)`` of :func:`.ext_mitsuba.solid_resolution`'s grid."""
    import drjit as dr
    import mitsuba as mi

    nx, ny, nz = solid_resolution(lo, hi)
    tex = load_dict(texture)
    axes = [lo[a] + (np.arange(n) + 0.5) / n * (hi[a] - lo[a]) for a, n in enumerate((nx, ny, nz))]
    zz, yy, xx = np.meshgrid(axes[2], axes[1], axes[0], indexing="ij")
    si = dr.zeros(mi.SurfaceInteraction3f, xx.size)
    si.p = mi.Point3f(xx.ravel(), yy.ravel(), zz.ravel())
    color = tex.eval(si)
    return np.stack([np.asarray(c, dtype=np.float32) for c in color], axis=-1).reshape(nz, ny, nx, 3)


def bake_cubemap_envmap(bg: CubeMapBackground, size: tuple[int, int] = ENVMAP_SIZE) -> np.ndarray:
    """(H, W, 3) float32 latitude-longitude image of the ``a5_cubemap`` of ``bg``'s faces, sampled at
    pixel-centre directions in Mitsuba's envmap parametrisation (module docstring)."""
    import drjit as dr
    import mitsuba as mi

    w, h = size
    emitter = load_dict({"type": "a5_cubemap", **cubemap_faces(bg)})
    jj, ii = np.meshgrid(np.arange(h), np.arange(w), indexing="ij")
    theta = (jj.ravel() + 0.5) / h * math.pi
    phi = (ii.ravel() + 0.5) / w * 2 * math.pi
    dirs = mi.Vector3f(np.sin(theta) * np.sin(phi), np.cos(theta), -np.sin(theta) * np.cos(phi))
    si = dr.zeros(mi.SurfaceInteraction3f, dr.width(dirs))
    si.wi = -dirs
    color = emitter.eval(si)
    return np.stack([np.asarray(c, dtype=np.float32) for c in color], axis=-1).reshape(h, w, 3)


class _DictBackend(Backend):
    """Loaded objects: BSDFs (one per material and uv variant), meshes, bitmaps (one per image)."""

    def __init__(self, desc: SceneDescription, *, stock: bool, marble_mistake: str = "") -> None:
        super().__init__(desc, stock=stock)
        self.bsdfs: dict[tuple[int, bool], Any] = {}
        self.bitmaps: dict[Image, Any] = {}
        self.marble_mistake = marble_mistake   # docs/MISTAKES.md: a5_marble's ``mistake`` parameter ("" none)

    def image(self, image: Image) -> Any:
        if image not in self.bitmaps:
            self.bitmaps[image] = bitmap(image)
        return self.bitmaps[image]

    def bsdf(self, entries: dict[str, Any], material: int, with_uv: bool) -> Any:

        mat = self.desc.materials[material]
        key = (material, materials.without_texture(mat, with_uv))
        if key not in self.bsdfs:
            d = materials.bsdf(mat, with_uv, stock=self.stock, image=lambda img: {"bitmap": self.image(img)})
            if self.marble_mistake:
                d = materials.with_marble_mistake(d, self.marble_mistake)
            if self.stock:
                d = self.stock_solids(d, material)
            self.bsdfs[key] = load_dict(_transforms(d))  # the stock bitmaps' to_uv (materials.FLIP_V)
        return self.bsdfs[key]

    def mesh(self, key: str, shape: MeshShape, bsdf: Any) -> Any:
        return make_mesh(key, shape.mesh, bsdf)

    def cubemap(self, bg: CubeMapBackground) -> Any:
        return {"type": "a5_cubemap", **cubemap_faces(bg, self.image)}

    def envmap(self, bg: CubeMapBackground) -> Any:
        import mitsuba as mi

        return {"type": "envmap", "bitmap": mi.Bitmap(bake_cubemap_envmap(bg))}

    def grid_source(self, vol: VolumeDescription) -> dict[str, Any]:
        import mitsuba as mi

        return {"data": mi.TensorXf(np.ascontiguousarray(vol.grid, dtype=np.float32))}


def _transforms(value: Any) -> Any:
    """Plain value -> ``mi.load_dict`` value: (4, 4) arrays become ``mi.ScalarTransform4f``, in nested dicts."""
    import mitsuba as mi

    if isinstance(value, np.ndarray):
        return mi.ScalarTransform4f(value.tolist())
    if isinstance(value, dict):
        return {k: _transforms(v) for k, v in value.items()}
    return value


def to_dict(desc: SceneDescription, options: RenderOptions | None = None, *, stock: bool = False) -> dict[str, Any]:
    """A dict for ``mi.load_dict`` (module docstring), made from ``desc`` without reading any file. BSDFs are
    loaded objects (``mi.load_dict``) because the meshes built from numpy take their BSDF object at
    construction. ``options`` (default ``RenderOptions()``): film size and the integrator's parameters, and
    docs/MISTAKES.md's marble mistake (given to every ``a5_marble``)."""
    options = options if options is not None else RenderOptions()
    marble = options.of_layer(MARBLE_MISTAKES)
    backend = _DictBackend(desc, stock=stock, marble_mistake=marble[0] if marble else "")
    return _transforms(scene_entries(desc, options, backend))

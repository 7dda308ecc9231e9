"""The scene description: a parsed scene with every file read and every world-space quantity computed, once.

:func:`describe` turns the typed model (:mod:`.model`, SPEC A.1-A.6) into a :class:`SceneDescription`:
paths resolved and files checked (:mod:`.files`: OBJ meshes, the textures of every material a shape uses,
the six cube-map faces), each image decoded once (its pixels travel in the description), geometry in world
space (:mod:`.geometry`), and the conversion warnings. It never imports Mitsuba, so the command line reports
a bad file as ``FILE:LINE:COL: error`` before the JIT starts; :func:`.to_mitsuba.to_dict` and
:func:`.to_xml.write_xml` build the Mitsuba scene from the description without reading any file again.

Materials (A.5, B.3): the Lambert colour ``kd`` is the ``Noise`` (marble, B.4), else the ``texture`` on
shapes with uv, else the diffuse colour: SPEC B.3's "texture(uv) only if the hit has uv". A textured
material's image is read (and a missing or unreadable one is an error at its ``texture`` keyword) whenever a
shape uses the material; on a shape without uv it cannot show, which is a warning at the shape. ``bump`` is parsed
and ignored unless ``describe(bump=True)`` (``-bump``, docs/EXTENSIONS.md E.7): then the ``bump`` height field and the
``normalMap`` of materials used on shapes with uv are read too. A procedural solid (``Wood``, ``Turbulence``,
``Veins``, E.6) is kd like the ``Noise``. The ambient term is ``Background.ambientLight``, (1,1,1) without lights
(A.1). A ``Volume``'s ``.vol`` grid (docs/EXTENSIONS.md E.9) is read here once (:mod:`.volgrid`); a ``Fog`` passes
as it is (E.8).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from a5mi.converters import files, octree, volgrid
from a5mi.converters import transforms as tf
from a5mi.converters.errors import FileLoc, SceneSemanticError
from a5mi.converters.files import Image
from a5mi.converters.geometry import (
    MeshData,
    check_float32,
    check_placement,
    geometry_centre,
    mesh_from_obj,
    mesh_from_triangle,
    plane_rectangle_to_world,
    world_plane,
)
from a5mi.converters.material_use import MaterialUse
from a5mi.converters.model import (
    Camera,
    Fog,
    Light,
    Material,
    Noise,
    Placed,
    Plane,
    Scene,
    Solid,
    Sphere,
    Triangle,
    TriangleMesh,
    Vec3,
    Volume,
    VolumeBox,
)
from a5mi.converters.obj import NormalMode, ObjMesh
from a5mi.converters.subsurface import Subsurface
from a5mi.converters.surface_ext import BtfImages, Milled

SceneWarning = tuple[FileLoc, str]


@dataclass(frozen=True)
class ColorBackground:
    """A constant background ``color`` (SPEC A.4)."""

    color: Vec3
    loc: FileLoc | None = None


@dataclass(frozen=True, eq=False)
class CubeMapBackground:
    """A cube-map background (SPEC A.4): the resolved ``folder`` and its six decoded ``faces`` in
    :data:`a5mi.spec.CUBE_FACES` order (left right up down front back)."""

    folder: Path
    faces: tuple[Image, ...]
    loc: FileLoc | None = None


Background = ColorBackground | CubeMapBackground


@dataclass(frozen=True)
class MaterialDescription:
    """One ``Material`` (SPEC A.5) with its Lambert colour source ``kd`` on shapes with uv: the ``Noise``
    (marble, B.4), the decoded ``texture`` :class:`~.files.Image`, or None for ``diffuse_color``. On shapes
    without uv a texture is not looked up (B.3): see :meth:`kd_on`."""

    diffuse_color: Vec3
    specular_color: Vec3
    shininess: float
    refraction_index: float
    kd: Noise | Solid | Image | BtfImages | None
    loc: FileLoc | None = None
    #: docs/EXTENSIONS.md E.4: GGX alpha (0 = mirror) and glossy children per camera hit
    roughness: float = 0.0
    glossy_samples: int = 1
    #: docs/EXTENSIONS.md E.10: Cauchy's B (µm²) of a dispersive material (``refraction_index`` is A), else None
    dispersion: float | None = None
    #: docs/EXTENSIONS.md E.7 (``describe(bump=True)`` only; used on shapes with uv): the height field, the
    #: height of grey 1 in world units, and the tangent-space normal map
    bump: Image | None = None
    bump_scale: float = 1.0
    normal_map: Image | None = None
    #: docs/EXTENSIONS.md E.18: the ``subsurface`` block (converters/subsurface.py), None without one
    subsurface: Subsurface | None = None
    #: docs/EXTENSIONS.md E.20: Ward's anisotropic lobe on a milling tangent field
    milled: Milled | None = None

    def kd_on(self, with_uv: bool) -> Noise | Solid | Image | BtfImages | None:
        """The kd source on a shape with (``with_uv``) or without texture coordinates (a texture or an E.19
        btf is looked up at uv only)."""
        return None if isinstance(self.kd, (Image, BtfImages)) and not with_uv else self.kd

    @property
    def has_maps(self) -> bool:
        """A bump height field or a normal map (E.7): looked up on shapes with uv only, like a texture."""
        return self.bump is not None or self.normal_map is not None


@dataclass(frozen=True, eq=False)
class MeshShape:
    """A triangle mesh in world space (an OBJ ``TriangleMesh``, or a ``Triangle`` as a one-face mesh; SPEC
    A.6). ``obj_file``: the resolved OBJ path, None for a ``Triangle``."""

    mesh: MeshData
    material: int
    loc: FileLoc
    obj_file: Path | None = None

    @property
    def has_uv(self) -> bool:
        return self.mesh.has_uv


@dataclass(frozen=True, eq=False)
class SphereShape:
    """A sphere (SPEC A.6): with ``to_world`` None, ``center`` / ``radius`` are in world space (the placing
    matrix is a similarity); otherwise they are in object space and ``to_world`` (4, 4) places it."""

    center: Vec3
    radius: float
    material: int
    loc: FileLoc
    to_world: np.ndarray | None = None
    has_uv: bool = False
    #: Inside a ``Transform``: ``(M, centre, radius)`` as the binary holds them (``M`` its float32 matrix,
    #: :func:`.transforms.binary_chain`; the object-space sphere as written), for a5_whitted's sphere test.
    binary: tuple[np.ndarray, Vec3, float] | None = None


@dataclass(frozen=True, eq=False)
class PlaneShape:
    """An infinite plane ``P·n_w = offset_w`` in world space (SPEC A.6; ``n_w`` not normalised) and the
    ``rectangle`` standing in for it: the (4, 4) ``to_world`` of Mitsuba's ``rectangle`` (:mod:`.geometry`).
    ``mirror_normal``: the normal the binary mirrors rays with, ``n`` as written for a plane outside any
    ``Transform``, else the normalised world normal (the binary's Transform normalises the normals it maps;
    measured against a5soln, SPEC A.6, C)."""

    n_w: np.ndarray
    offset_w: float
    rectangle: np.ndarray
    material: int
    loc: FileLoc
    has_uv: bool = False
    mirror_normal: np.ndarray | None = None
    #: Inside a ``Transform``: ``(M, normal, offset)`` as the binary holds them (its float32 matrix and the
    #: object-space plane as written), for a5_whitted's object-space plane test.
    binary: tuple[np.ndarray, Vec3, float] | None = None


Shape = MeshShape | SphereShape | PlaneShape


@dataclass(frozen=True, eq=False)
class VolumeDescription(VolumeBox):
    """A ``Volume`` (docs/EXTENSIONS.md E.9) with its grid read: ``grid`` the ``(z, y, x, 1)`` float32 array of
    the resolved ``.vol`` file ``path``, stretched over the box ``[box_min, box_max]``."""

    grid: np.ndarray
    path: Path
    #: Henyey-Greenstein asymmetry (docs/EXTENSIONS.md E.8, E.9)
    g: float = 0.0


MediumDescription = Fog | VolumeDescription


def describe_volume(scene: Scene, vol: Volume) -> VolumeDescription:
    """Resolve and read the ``.vol`` grid of ``vol`` (E.9); a missing, unreadable, malformed or multi-channel
    file is a :class:`SceneSemanticError` at its name."""
    name = volgrid.frame_name(vol.grid, 0)  # E.11: frame 0's grid
    path = files.resolve_path(name, scene.base_dir, vol.grid_loc, "Volume grid")
    try:
        grid = volgrid.read_vol(path)
    except OSError as exc:
        raise SceneSemanticError(f"Volume grid '{path}': {exc.strerror or exc}", vol.grid_loc) from None
    except volgrid.VolFormatError as exc:
        raise SceneSemanticError(f"Volume grid '{path}' is not a .vol grid: {exc.reason}", vol.grid_loc) from None
    if grid.shape[3] != 1:
        raise SceneSemanticError(f"Volume grid '{path}' has {grid.shape[3]} channels; a density grid has 1",
                                 vol.grid_loc)
    if not np.all(np.isfinite(grid)) or float(grid.min()) < 0.0:
        raise SceneSemanticError(f"Volume grid '{path}' holds negative or non-finite densities", vol.grid_loc)
    return VolumeDescription(vol.density, vol.box_min, vol.box_max, vol.color, vol.steps, vol.loc, grid=grid,
                             path=path.resolve(), g=vol.g)


@dataclass(frozen=True, eq=False)
class SceneDescription:
    """Everything a renderer needs from a scene, files already read (module docstring).

    ``shapes`` are in the scene's object order, each with the index of its material in ``materials`` (the
    scene's ``MaterialIndex``); ``ambient`` is the ambient term the integrator uses (A.1); ``centre`` is
    the centre of the finite geometry's world bounding box (None without finite geometry; used by the stock
    point-light approximation); ``warnings`` are ``(loc, message)`` pairs (OBJ quirks, zero-area faces,
    followed cube-map links, stock approximations when described with ``stock=True``)."""

    path: str
    camera: Camera
    ambient: Vec3
    background: Background
    materials: tuple[MaterialDescription, ...]
    shapes: tuple[Shape, ...]
    lights: tuple[Light, ...]
    centre: np.ndarray | None = None
    warnings: tuple[SceneWarning, ...] = ()
    #: the participating medium (docs/EXTENSIONS.md E.8, E.9), None without one
    medium: MediumDescription | None = None


def describe(scene: Scene, *, stock: bool = False, normals: NormalMode = "auto", bump: bool = False,
             decoded: files.Decoded | None = None, meshes: files.Meshes | None = None) -> SceneDescription:
    """The :class:`SceneDescription` of ``scene``: every file read once, geometry in world space.

    Raises :class:`SceneSemanticError` for missing or unreadable meshes, textures or cube-map faces, at the
    keyword that named them (or at the OBJ line at fault), and for geometry that nested ``Transform`` s push
    out of float32 range or make singular, at the primitive. ``stock=True`` adds the warnings of the stock
    conversion's approximations (:mod:`.to_mitsuba`). ``normals``: :func:`.obj.vertex_normals`' rule. numpy's
    floating-point warnings are silenced here: such overflows are checked and reported as errors instead.
    ``decoded``: images already decoded by the caller, by resolved path (a caller that re-describes an edited
    scene, ``a5mi view``, keeps the decoded images whose files did not change); new decodes are added to it.
    ``meshes``: the same for OBJ meshes, their octree reach masks and world-space placements
    (:func:`.files.load_mesh`: kept while the file's identity stays; the masks' warnings are given again at this
    description's ``obj_file``)."""
    with np.errstate(all="ignore"):
        return _describe(scene, stock=stock, normals=normals, bump=bump, decoded=decoded, kept=meshes)


def mesh_reach(mesh: ObjMesh, entry: files.KeptMesh | None, warnings: list[SceneWarning],
               loc: FileLoc | None) -> np.ndarray:
    """:func:`.octree.reach_masks` of ``mesh`` (its warnings appended at ``loc``), taken from ``entry`` when it
    kept them for this mesh, else computed and kept there."""
    if entry is not None and entry.mesh is mesh and entry.reach is not None:
        masks, notes = entry.reach
    else:
        found: list[SceneWarning] = []
        masks = octree.reach_masks(mesh.vertices, mesh.faces, warnings=found, loc=loc)
        notes = tuple(msg for _, msg in found)
        if entry is not None and entry.mesh is mesh:
            masks.flags.writeable = False
            entry.reach = (masks, notes)
    if loc is not None:
        warnings.extend((loc, msg) for msg in notes)
    return masks


#: World-space placements kept per mesh (:func:`placed_mesh`); more are dropped all at once.
MAX_PLACED = 8


def placed_mesh(obj: ObjMesh, entry: files.KeptMesh | None, m: np.ndarray, normals: NormalMode,
                reach: np.ndarray | None, transformed: bool) -> MeshData:
    """:func:`.geometry.mesh_from_obj` of ``obj`` placed with ``m``, taken from ``entry`` when it kept this
    placement (the same ``m`` bit for bit, normal rule, reach masks or none, and ``transformed``), else made and
    kept there (a pure function of those: its arrays are read-only, so one object serves every description)."""
    if entry is None or entry.mesh is not obj:
        return mesh_from_obj(obj, m, normals, reach, transformed)
    key = (np.asarray(m, dtype=np.float64).tobytes(), normals, reach is None, transformed)
    data = entry.placed.get(key)
    if data is None:
        if len(entry.placed) >= MAX_PLACED:
            entry.placed.clear()
        data = entry.placed[key] = mesh_from_obj(obj, m, normals, reach, transformed)
    return data


def _describe(scene: Scene, *, stock: bool, normals: NormalMode, bump: bool = False,
              decoded: files.Decoded | None = None, kept: files.Meshes | None = None) -> SceneDescription:
    """:func:`describe`, step by step: OBJ files, background, shapes (using their materials), materials, medium."""
    warnings: list[SceneWarning] = []
    if stock and any(scene.ambient):
        warnings.append((scene.background.loc or scene.camera.loc,  # type: ignore[arg-type]
                         "stock conversion: the ambient term has no equivalent in 'path' and is dropped"))
    placed = scene.objects
    for p in placed:
        check_placement(p)
    objs = _read_meshes(scene, placed, stock, kept, warnings)
    centre = geometry_centre(placed, objs.meshes)
    decoded = {} if decoded is None else decoded  # each image file decoded once, even when several materials name it
    background = _background(scene, warnings, decoded)
    # Materials on first use, in shape order (so errors and warnings come in the order of the objects).
    uses = MaterialUse(scene, stock, bump, decoded, warnings)
    cam_c = np.asarray(scene.camera.center, dtype=np.float64)
    shapes = tuple(_shape(p, objs, normals, uses, cam_c) for p in placed)
    materials = tuple(_material(i, mat, uses) for i, mat in enumerate(scene.materials))
    medium = describe_volume(scene, scene.medium) if isinstance(scene.medium, Volume) else scene.medium
    return SceneDescription(scene.path, scene.camera, scene.ambient, background, materials, shapes,
                            tuple(scene.lights), centre, tuple(warnings), medium)


@dataclass
class _ObjFiles:
    """The OBJ files of a scene (A.6), each read once in order of first use, by ``obj_file`` as written: the
    mesh, its resolved path, the binary's octree reach masks (object space, so once per file; None with
    ``stock``), and the caller's kept meshes (:data:`.files.Meshes`)."""

    meshes: dict[str, ObjMesh]
    paths: dict[str, Path]
    reach: dict[str, np.ndarray | None]
    kept: files.Meshes | None

    def entry(self, name: str) -> files.KeptMesh | None:
        """The kept entry of OBJ file ``name``, if the caller keeps meshes."""
        return (self.kept or {}).get(self.paths[name])


def _read_meshes(scene: Scene, placed: tuple[Placed, ...], stock: bool, kept: files.Meshes | None,
                 warnings: list[SceneWarning]) -> _ObjFiles:
    """Read every OBJ file the placed objects name (:func:`.files.load_mesh`), its warnings appended."""
    objs = _ObjFiles({}, {}, {}, kept)
    for p in placed:
        prim = p.primitive
        if isinstance(prim, TriangleMesh) and prim.obj_file not in objs.meshes:
            name = prim.obj_file
            objs.paths[name], objs.meshes[name] = files.load_mesh(scene, name, prim.obj_file_loc, kept)
            warnings.extend(objs.meshes[name].warnings)
            objs.reach[name] = None if stock else mesh_reach(  # stock: no a5 rule attributes
                objs.meshes[name], objs.entry(name), warnings, prim.obj_file_loc)
    return objs


def _background(scene: Scene, warnings: list[SceneWarning], decoded: files.Decoded) -> Background:
    """The Background (A.1): its colour, or the six faces of its ``cubeMap`` read (:func:`.files.cube_map`)."""
    bg = scene.background
    if bg.cube_map is None:
        return ColorBackground(bg.color, bg.loc)
    folder, faces = files.cube_map(scene, warnings, decoded)
    return CubeMapBackground(folder, faces, bg.cube_map_loc or bg.loc)


def _shape(p: Placed, objs: _ObjFiles, normals: NormalMode, uses: MaterialUse, cam_c: np.ndarray) -> Shape:
    """The world-space shape of placed object ``p``, its material used (:meth:`.MaterialUse.use`)."""
    prim = p.primitive
    if isinstance(prim, TriangleMesh):
        return _mesh_shape(p, prim, objs, normals, uses)
    uses.use(prim.material, False, prim)
    chain = tf.binary_chain(p.levels)
    if isinstance(prim, Sphere):
        return _sphere_shape(p, prim, chain)
    if isinstance(prim, Plane):
        return _plane_shape(p, prim, chain, cam_c)
    if isinstance(prim, Triangle):
        data = mesh_from_triangle(prim, p.to_world)
        check_float32(prim, data.positions)
        return MeshShape(data, prim.material, prim.loc)
    raise SceneSemanticError(f"unknown primitive {type(prim).__name__}", prim.loc)  # pragma: no cover


def _mesh_shape(p: Placed, prim: TriangleMesh, objs: _ObjFiles, normals: NormalMode,
                uses: MaterialUse) -> MeshShape:
    """A ``TriangleMesh`` (A.6) placed in world space (:func:`placed_mesh`); its material sees its uv."""
    name = prim.obj_file
    data = placed_mesh(objs.meshes[name], objs.entry(name), p.to_world, normals, objs.reach[name], p.transformed)
    uses.use(prim.material, data.has_uv, prim)
    check_float32(prim, data.positions, 0.0 if data.normals is None else data.normals)
    return MeshShape(data, prim.material, prim.loc, objs.paths[name])


def _sphere_shape(p: Placed, prim: Sphere, chain: np.ndarray | None) -> SphereShape:
    """A Sphere (A.6): in world space under a similarity ``m`` (centre ``m c``, radius ``s r``), else in
    object space with ``m`` kept."""
    m = p.to_world
    binary = None if chain is None else (chain, prim.center, float(prim.radius))
    scale = tf.similarity_scale(m)
    if scale is None:
        check_float32(prim, m)
        return SphereShape(prim.center, float(prim.radius), prim.material, prim.loc, m.copy(), binary=binary)
    center = tf.transform_points(m, np.asarray(prim.center))
    check_float32(prim, center, prim.radius * scale)
    return SphereShape(tuple(float(x) for x in center), float(prim.radius * scale),  # type: ignore[arg-type]
                       prim.material, prim.loc, binary=binary)


def _plane_shape(p: Placed, prim: Plane, chain: np.ndarray | None, cam_c: np.ndarray) -> PlaneShape:
    """A Plane (A.6) in world space, as a rectangle around the camera centre ``cam_c``."""
    n_w, off_w = world_plane(prim, p.to_world)
    rect = plane_rectangle_to_world(n_w, off_w, cam_c)
    check_float32(prim, rect)
    mirror = n_w / np.linalg.norm(n_w) if p.transformed else n_w
    return PlaneShape(n_w, off_w, rect, prim.material, prim.loc, mirror_normal=mirror,
                      binary=None if chain is None else (chain, prim.normal, float(prim.offset)))


def _material(i: int, mat: Material, uses: MaterialUse) -> MaterialDescription:
    """Material ``i`` (A.5) with its images: kd's source is the Noise, else the solid, else the btf images, else
    the texture (SPEC B.3 order; None for a solid diffuse colour)."""
    return MaterialDescription(
        mat.diffuse_color, mat.specular_color, float(mat.shininess), float(mat.refraction_index),
        mat.noise if mat.noise is not None else mat.solid if mat.solid is not None
        else uses.btfs.get(i, uses.textures.get(i)),
        mat.loc, float(mat.roughness), int(mat.glossy_samples),
        None if mat.dispersion is None else float(mat.dispersion),
        bump=uses.maps.get((i, "bump")), bump_scale=float(mat.bump_scale),
        normal_map=uses.maps.get((i, "normal_map")), subsurface=mat.subsurface, milled=mat.milled)

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
from a5mi.converters.model import (
    Camera,
    Fog,
    Light,
    Noise,
    Plane,
    Scene,
    Solid,
    Sphere,
    Triangle,
    TriangleMesh,
    Vec3,
    Volume,
)
from a5mi.converters.obj import NormalMode, ObjMesh
from a5mi.converters.subsurface import Subsurface
from a5mi.converters.surface_ext import STOCK_BTF_WARNING, STOCK_WARNING, BtfImages, Milled, describe_btf
from a5mi.spec import CENTRE_WAVELENGTH_NM

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
class VolumeDescription:
    """A ``Volume`` (docs/EXTENSIONS.md E.9) with its grid read: ``grid`` the ``(z, y, x, 1)`` float32 array of
    the resolved ``.vol`` file ``path``, stretched over the box ``[box_min, box_max]``."""

    grid: np.ndarray
    path: Path
    density: float
    box_min: Vec3
    box_max: Vec3
    color: Vec3
    steps: int
    loc: FileLoc
    #: Henyey-Greenstein asymmetry (docs/EXTENSIONS.md E.8, E.9)
    g: float = 0.0


MediumDescription = Fog | VolumeDescription


def describe_volume(scene: Scene, vol: Volume) -> VolumeDescription:
    """Resolve and read the ``.vol`` grid of ``vol`` (E.9); a missing, unreadable, malformed or multi-channel
    file is a :class:`SceneSemanticError` at its name."""
    path = scene.resolve(volgrid.frame_name(vol.grid, 0), vol.grid_loc, "Volume grid")  # E.11: frame 0's grid
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
    return VolumeDescription(grid, path.resolve(), vol.density, vol.box_min, vol.box_max, vol.color, vol.steps,
                             vol.loc, vol.g)


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
    warnings: list[SceneWarning] = []
    if stock and any(scene.ambient):
        warnings.append((scene.background.loc or scene.camera.loc,  # type: ignore[arg-type]
                         "stock conversion: the ambient term has no equivalent in 'path' and is dropped"))

    placed = scene.objects
    for p in placed:
        check_placement(p)
    meshes: dict[str, ObjMesh] = {}  # each OBJ file read once, in order of first use
    obj_paths: dict[str, Path] = {}
    reach: dict[str, np.ndarray | None] = {}  # the binary's octree rule per OBJ (object space, so once per file)
    for p in placed:
        prim = p.primitive
        if isinstance(prim, TriangleMesh) and prim.obj_file not in meshes:
            obj_paths[prim.obj_file], meshes[prim.obj_file] = files.load_mesh(scene, prim.obj_file,
                                                                               prim.obj_file_loc, kept)
            warnings.extend(meshes[prim.obj_file].warnings)
            reach[prim.obj_file] = None if stock else mesh_reach(  # stock: no a5 rule attributes
                meshes[prim.obj_file], (kept or {}).get(obj_paths[prim.obj_file]), warnings, prim.obj_file_loc)
    centre = geometry_centre(placed, meshes)

    decoded = {} if decoded is None else decoded  # each image file decoded once, even when several materials name it
    bg = scene.background
    background: Background
    if bg.cube_map is not None:
        folder, faces = files.cube_map(scene, warnings, decoded)
        background = CubeMapBackground(folder, faces, bg.cube_map_loc or bg.loc)
    else:
        background = ColorBackground(bg.color, bg.loc)

    # Materials on first use, in shape order (so errors and warnings come in the order of the objects).
    used: set[int] = set()
    textures: dict[int, Image] = {}
    maps: dict[tuple[int, str], Image] = {}  # E.7: (material, 'bump' | 'normal_map') -> image, with -bump
    btfs: dict[int, BtfImages] = {}  # E.19: material -> its images

    def use_material(index: int, with_uv: bool, shape: object) -> None:
        mat = scene.materials[index]
        if index not in used:
            used.add(index)
            if stock and mat.noise is not None:
                warnings.append((mat.noise.loc or mat.loc,  # type: ignore[arg-type]
                                 "stock conversion: Noise (marble) replaced by its mean colour"))
            if stock and mat.solid is not None:  # docs/EXTENSIONS.md E.6, stock mapping
                warnings.append((mat.solid.loc or mat.loc,  # type: ignore[arg-type]
                                 f"stock conversion: {mat.solid.kind.capitalize()} baked into an RGB grid over "
                                 "its shapes' box (stock 'volume' texture, trilinear)"))
            if stock and mat.dispersion is not None:  # docs/EXTENSIONS.md E.10
                n_c = mat.refraction_index + mat.dispersion / (CENTRE_WAVELENGTH_NM * 1e-3) ** 2
                warnings.append((mat.loc,  # type: ignore[arg-type]
                                 "stock conversion: dispersion replaced by the index at the centre wavelength, "
                                 f"n({CENTRE_WAVELENGTH_NM:g} nm) = {n_c:.6g}"))
            if stock and (mat.milled is not None or mat.btf is not None):  # docs/EXTENSIONS.md E.19, E.20
                warnings.extend((mat.loc, w) for w, on in ((STOCK_WARNING, mat.milled), (STOCK_BTF_WARNING, mat.btf))  # type: ignore[misc]
                                if on is not None)
        if mat.btf is not None:  # E.19: the images, read once; no texture coordinates, no lookup
            if index not in btfs:
                btfs[index] = describe_btf(scene, mat, decoded)
            if not with_uv:
                warnings.append((shape.loc, f"btf cannot show on this {type(shape).__name__}: it has no "  # type: ignore[attr-defined]
                                 "texture coordinates (SPEC B.3)"))
        for which in ("bump", "normal_map") if bump and with_uv else ():
            if getattr(mat, which) is not None and (index, which) not in maps:
                maps[(index, which)], warning = files.map_image(scene, mat, which, decoded)
                if warning is not None:
                    warnings.append((mat.bump_loc or mat.loc, warning))  # type: ignore[arg-type]
        if bump and not with_uv:  # E.7: like a texture, a map cannot show without uv
            for which, name in (("bump", mat.bump), ("normalMap", mat.normal_map)):
                if name is not None:
                    warnings.append((shape.loc, f"{which} '{name}' cannot show on this "  # type: ignore[attr-defined]
                                     f"{type(shape).__name__}: it has no texture coordinates (EXTENSIONS E.7)"))
        if mat.texture is None:
            return
        # A referenced file is checked wherever it is used, even where Noise hides it (SPEC B.3 kd order).
        image = files.texture_image(scene, mat, decoded)
        if mat.noise is None and mat.solid is None:
            textures.setdefault(index, image)
            if not with_uv:
                kind = type(shape).__name__
                # docs/FIDELITY.md "Stale texture coordinates": a5soln may show it at a mesh's uv (-quirks binary)
                stale = "; a5soln may show it at a textured mesh's stale uv (-quirks binary)" \
                    if kind in ("Sphere", "Plane") else ""
                warnings.append((shape.loc, f"texture '{mat.texture}' cannot show on this "  # type: ignore[attr-defined]
                                 f"{kind}: it has no texture coordinates (SPEC B.3){stale}"))

    cam_c = np.asarray(scene.camera.center, dtype=np.float64)
    shapes: list[Shape] = []
    for p in placed:
        prim, m = p.primitive, p.to_world
        if isinstance(prim, TriangleMesh):
            data = placed_mesh(meshes[prim.obj_file], (kept or {}).get(obj_paths[prim.obj_file]), m, normals,
                               reach[prim.obj_file], p.transformed)
            use_material(prim.material, data.has_uv, prim)
            check_float32(prim, data.positions, 0.0 if data.normals is None else data.normals)
            shapes.append(MeshShape(data, prim.material, prim.loc, obj_paths[prim.obj_file]))
            continue
        use_material(prim.material, False, prim)
        chain = tf.binary_chain(p.levels)
        if isinstance(prim, Sphere):
            binary = None if chain is None else (chain, prim.center, float(prim.radius))
            scale = tf.similarity_scale(m)
            if scale is not None:
                center = tf.transform_points(m, np.asarray(prim.center))
                check_float32(prim, center, prim.radius * scale)
                shapes.append(SphereShape(tuple(float(x) for x in center), float(prim.radius * scale),  # type: ignore[arg-type]
                                          prim.material, prim.loc, binary=binary))
            else:
                check_float32(prim, m)
                shapes.append(SphereShape(prim.center, float(prim.radius), prim.material, prim.loc, m.copy(),
                                          binary=binary))
        elif isinstance(prim, Plane):
            n_w, off_w = world_plane(prim, m)
            rect = plane_rectangle_to_world(n_w, off_w, cam_c)
            check_float32(prim, rect)
            mirror = n_w / np.linalg.norm(n_w) if p.transformed else n_w
            shapes.append(PlaneShape(n_w, off_w, rect, prim.material, prim.loc, mirror_normal=mirror,
                                     binary=None if chain is None else (chain, prim.normal, float(prim.offset))))
        elif isinstance(prim, Triangle):
            data = mesh_from_triangle(prim, m)
            check_float32(prim, data.positions)
            shapes.append(MeshShape(data, prim.material, prim.loc))
        else:  # pragma: no cover - the model has no other primitive
            raise SceneSemanticError(f"unknown primitive {type(prim).__name__}", prim.loc)

    materials = tuple(
        MaterialDescription(mat.diffuse_color, mat.specular_color, float(mat.shininess),
                            float(mat.refraction_index),
                            mat.noise if mat.noise is not None else mat.solid if mat.solid is not None
                            else btfs.get(i, textures.get(i)),
                            mat.loc, float(mat.roughness), int(mat.glossy_samples),
                            None if mat.dispersion is None else float(mat.dispersion),
                            bump=maps.get((i, "bump")), bump_scale=float(mat.bump_scale),
                            normal_map=maps.get((i, "normal_map")), subsurface=mat.subsurface,
                            milled=mat.milled)
        for i, mat in enumerate(scene.materials))
    medium = describe_volume(scene, scene.medium) if isinstance(scene.medium, Volume) else scene.medium
    return SceneDescription(scene.path, scene.camera, scene.ambient, background, materials, tuple(shapes),
                            tuple(scene.lights), centre, tuple(warnings), medium)

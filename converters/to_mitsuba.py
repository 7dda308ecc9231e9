"""Scene model -> Mitsuba 3 scene dict (SPEC A.1-A.6 geometry and materials, B.2 camera, B.3 integrator).

:func:`to_dict` returns a dict for ``mi.load_dict``; with ``stock=False`` it uses the a5mi plugins of the
contract in ARCHITECTURE.md (``a5_whitted``, ``a5_camera``, ``a5_material``, ``a5_marble``, ``a5_bitmap``,
``a5_point``, ``a5_cubemap``), which must be registered (``a5mi.plugins.register_all()``); with
``stock=True`` it uses stock Mitsuba plugins only. The same plain description (:func:`build`) feeds the XML
writer (:mod:`.to_xml`). This is the only module of ``converters`` that imports Mitsuba, and only inside the
functions that need it (parsing never waits for a JIT backend).

Geometry (exact unless stated):

* **Meshes** (``TriangleMesh``, A.6) become ``mi.Mesh`` objects with vertices baked into world space,
  ``p_w = M p``. Smooth meshes (:func:`.obj.vertex_normals`: more than 120 vertices by default) carry vertex
  normals ``A n`` with ``A = (M⁻¹)ᵀ`` (upper 3x3) and *no* renormalisation: interpolating then normalising
  commutes with the linear map, which is exactly the binary's interpolate / transform / normalise. Flat
  meshes carry no normals (Mitsuba shades with the face normal); as ``(Mp1−Mp0)×(Mp2−Mp0) = det(M)·A n``,
  the winding is reversed when ``det M < 0`` so the face normal keeps the binary's direction ``A n``.
  Texture coordinates only when the OBJ has ``vt`` (vertices are split per distinct (v, vt) pair).
* **Spheres**: a ``sphere`` with world centre ``M c`` and radius ``s r`` when ``M`` is a similarity
  (``AᵀA = s² I``); otherwise a ``shapegroup`` holding the object-space sphere plus an ``instance`` with
  ``to_world = M`` (a sphere with a non-uniform ``to_world`` gives wrong hits in Mitsuba 3.9.1).
* **Triangles**: a one-face mesh, as flat meshes above.
* **Planes** (infinite in the assignment: ``P·n = offset``, n not normalised): the world plane is
  ``π_w = M⁻ᵀ (n, −offset)``; it becomes a ``rectangle`` of half-size :data:`PLANE_HALF_SIZE` = 1e7 scene
  units, centred on the foot of the perpendicular from the camera centre, with its frame's z axis along the
  plane's unit normal (the a5 shading normal). A camera ray misses it only when it would hit the infinite
  plane at t > 1e7, i.e. within ``h/1e7`` radians of the horizon for a camera at height h, far below one
  pixel (scene10's last plane row is hit at t ≈ 16,000: tests/test_to_mitsuba.py checks that every B.2
  pixel ray hits the rectangle exactly when it hits the plane, for every shipped scene with a plane).
  The plane keeps only its z extent in float32, so the hit distance is as precise as an analytic plane.

Materials (A.5, B.3): ``a5_material`` with ``kd`` = ``a5_marble`` (Noise), else ``a5_bitmap`` (texture) on
shapes with uv, else the diffuse colour. A textured material used on a shape without uv (sphere, plane,
triangle, OBJ without ``vt``) gets a second BSDF without the texture: SPEC B.3's "texture(uv) only if the hit
has uv". ``bump`` is parsed and ignored.

Lights and background: ``directional`` (stock; ``irradiance`` = colour, the direction it travels);
``a5_point``; the background is ``a5_cubemap`` (folder) if ``cubeMap`` is set, else a stock ``constant``
with ``radiance`` = colour. The ambient term (``Background.ambientLight``; (1,1,1) without lights, A.1) goes
to the integrator.

``stock=True`` approximations (for use outside a5mi; none is needed for a5 renders):

* integrator ``path`` with ``max_depth = bounces + 2``; there is no ambient term (a warning if it is not 0);
* sensor ``perspective`` at ``to_world = look_at(center, center + direction, up)`` with
  ``fov = 2·atan(tan(angle/2)·W/(W−1))`` on the x axis. B.2 puts the first and last pixel *centres* on ±1
  (spacing ``2/(W−1)``); Mitsuba puts the film *edges* there (spacing ``2/W``); this fov makes the pixel
  centres coincide exactly for square images. Non-square images: y keeps Mitsuba's aspect-correct spacing
  ``2/(W−1)·tan(angle/2)`` instead of B.2's ``2/(H−1)``. With the ``stratified`` sampler (1 spp, no jitter)
  the ray goes through the pixel centre as in a5soln;
* materials: ``diffuse`` (reflectance = kd) when ``|specularColor| ≤ 0.001`` and ``refractionIndex = 0``;
  otherwise a ``blendbsdf`` with weight ``w = clamp(max specularColor, 0, 1)`` between that ``diffuse`` and a
  perfect mirror (``conductor``, ``material='none'``) or, for ``refractionIndex n > 0``, a ``dielectric``
  with ``int_ior = n``, ``ext_ior = 1.0`` (its defaults are BK7 and air), both with specular
  reflectance/transmittance ``specularColor / w``. a5soln *adds* the mirror term to the full diffuse one;
  a physically based blend cannot, so stock renders are darker or brighter there;
* textures: stock ``bitmap`` with ``raw=True``, ``filter_type='bilinear'``, ``wrap_mode='clamp'``: it has
  Mitsuba's half-texel offset, unlike A.4; Noise (3D marble): the mean colour ``(color1 + color2)/2`` (the
  mean of ``t`` over a period of the sine), with a warning;
* ``a5_point`` -> ``point`` with ``intensity = color·d²/(1 + falloff·d²)``, ``d`` the distance from the light
  to the centre of the scene's finite geometry: exact at that distance, inverse-square elsewhere;
* cube map -> ``envmap`` from a 2048 x 1024 latitude-longitude image baked by evaluating the ``a5_cubemap``
  plugin (loaded by name, so the a5 plugins must be registered for this step) at the pixel-centre directions
  ``d = (sin θ sin φ, cos θ, −sin θ cos φ)``, ``θ = π (j + ½)/1024``, ``φ = 2π (i + ½)/2048`` (Mitsuba's
  envmap parametrisation); the envmap then filters it bilinearly.
"""

from __future__ import annotations

import math
import os
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np

from . import transforms as tf
from .errors import FileLoc, SceneSemanticError
from .model import (
    DirectionalLight,
    Material,
    Placed,
    Plane,
    PointLight,
    Scene,
    Sphere,
    Triangle,
    TriangleMesh,
    resolve_path,
)
from .obj import FLOAT32_MAX, NormalMode, ObjMesh, load_obj, vertex_normals

#: Half-size of the rectangle standing in for an infinite plane (scene units); see the module docstring.
PLANE_HALF_SIZE = 1.0e7
#: Cube-map faces (SPEC A.4) and the image extensions looked for, in the ``a5_cubemap`` plugin's order.
CUBE_FACES = ("left", "right", "up", "down", "front", "back")
IMAGE_EXTENSIONS = (".bmp", ".png", ".jpg", ".jpeg", ".tga", ".ppm", ".tif", ".tiff", ".exr", ".hdr")
#: Size of the baked latitude-longitude environment in stock mode.
ENVMAP_SIZE = (2048, 1024)
MIRROR_THRESHOLD = 0.001


@dataclass
class RenderSettings:
    """Render options of SPEC B.1/B.3 that end up in the scene dict (film size and integrator flags)."""

    width: int = 100
    height: int = 100
    bounces: int = 4
    shadows: bool = False
    phong: bool = False
    fresnel: Literal["a5", "schlick", "exact"] = "a5"
    reflection: bool = True
    refraction: bool = True


@dataclass(eq=False)
class MeshData:
    """A triangle mesh in world space: positions (N, 3), faces (F, 3) uint32, optional normals / texcoords."""

    name: str
    positions: np.ndarray
    faces: np.ndarray
    normals: np.ndarray | None = None
    texcoords: np.ndarray | None = None


@dataclass
class Built:
    """The plain description shared by :func:`to_dict` and :func:`.to_xml.write_xml`.

    ``scene`` is a Mitsuba-style dict whose values are plain data: dicts, numbers, strings, lists of 3
    numbers, ``np.ndarray`` (4, 4) for transforms, and two placeholders the writers materialise:
    ``{'type': '_mesh', 'data': MeshData, 'bsdf': ref}`` and ``{'type': 'envmap', '_bake_cubemap': folder}``.
    BSDFs are top-level entries referenced as ``{'type': 'ref', 'id': key}``."""

    scene: dict[str, Any]
    warnings: list[tuple[FileLoc, str]] = field(default_factory=list)


def rgb(c: Any) -> dict[str, Any]:
    """``{'type': 'rgb', 'value': [r, g, b]}``."""
    return {"type": "rgb", "value": [float(x) for x in c]}


# ------------------------------------------------------------------------------------------------- file paths
_MESH_CACHE: dict[tuple[str, int, int], ObjMesh] = {}
_IMAGES: dict[tuple[str, int, int], np.ndarray] = {}  # file identity -> pixels decoded by check_image
_CACHE_SIZE = 16
_IMAGE_CACHE_BYTES = 256 << 20
_IMAGES_LOCK = threading.Lock()


def _file_key(path: Path) -> tuple[str, int, int] | None:
    """``(absolute path, mtime_ns, size)``: a file's identity for the caches below (None if stat fails)."""
    try:
        st = path.stat()
    except OSError:
        return None
    return (str(path.resolve()), st.st_mtime_ns, st.st_size)


def load_mesh(path: Path, loc: FileLoc) -> ObjMesh:
    """:func:`.obj.load_obj`, remembered per (path, mtime, size), so that :func:`check_files` (run by the CLI
    before Mitsuba is imported) and the :func:`build` that follows read each OBJ once."""
    key = _file_key(path)
    if key is not None and key in _MESH_CACHE:
        return _MESH_CACHE[key]
    mesh = load_obj(path, loc)
    if key is not None:
        if len(_MESH_CACHE) >= _CACHE_SIZE:
            del _MESH_CACHE[next(iter(_MESH_CACHE))]
        _MESH_CACHE[key] = mesh
    return mesh


def check_image(path: Path, loc: FileLoc, what: str) -> None:
    """Read the whole image at ``path`` with OpenImageIO, as the ``a5_bitmap`` / ``a5_cubemap`` plugins will
    (8 bits per channel, SPEC A.4), so a bad file is reported at the scene keyword that named it instead of
    failing inside ``mi.load_dict``. Raises :class:`SceneSemanticError` at ``loc``:
    ``{what} '{path}' is not a readable image: {reason}`` (empty, unreadable, not an image, truncated).
    A file that passed is remembered per (path, mtime, size) with its pixels, which :func:`decoded_image`
    hands to the plugins (``a5mi.plugins.imagedata.set_pixel_source``) so the file is decoded once."""
    key = _file_key(path)
    if key is not None and key in _IMAGES:
        return
    if key is not None and key[2] == 0:
        raise SceneSemanticError(f"{what} '{path}' is not a readable image: the file is empty", loc)
    import OpenImageIO as oiio  # deferred: only scenes with images pay for it

    inp = oiio.ImageInput.open(str(path))
    if inp is None:
        reason = oiio.geterror()
    else:
        try:
            spec = inp.spec()
            pixels = (inp.read_image(0, 0, 0, spec.nchannels, "uint8")
                      if spec.width > 0 and spec.height > 0 else None)
            reason = "" if pixels is not None else (inp.geterror() or oiio.geterror() or "no pixel data")
        finally:
            inp.close()
    if reason:
        reason = " ".join(reason.split())  # OpenImageIO messages may span lines
        raise SceneSemanticError(f"{what} '{path}' is not a readable image: {reason}", loc)
    if key is not None:
        decoded = np.asarray(pixels, dtype=np.uint8).reshape(spec.height, spec.width, spec.nchannels)
        decoded.flags.writeable = False  # shared with every reader of the cache
        with _IMAGES_LOCK:  # _prefetch_images runs checks in threads
            while _IMAGES and sum(a.nbytes for a in _IMAGES.values()) + decoded.nbytes > _IMAGE_CACHE_BYTES:
                del _IMAGES[next(iter(_IMAGES))]  # oldest first
            _IMAGES[key] = decoded


def _prefetch_images(paths: list[Path]) -> None:
    """Run :func:`check_image` on ``paths`` in parallel (OpenImageIO decodes without the GIL) to fill the
    cache; errors are dropped here: the sequential checks that follow find the bad file again and report
    it at its keyword, in the usual order."""
    todo = list(dict.fromkeys(p for p in paths if (k := _file_key(p)) is not None and k not in _IMAGES))
    workers = min(len(todo), os.cpu_count() or 1, 8)
    if workers < 2:
        return

    def one(path: Path) -> None:
        try:
            check_image(path, None, "image")  # type: ignore[arg-type]
        except SceneSemanticError:
            pass

    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(workers) as pool:
        list(pool.map(one, todo))


def _image_candidates(scene: Scene, used_with_uv: set[int]) -> list[Path]:
    """The cube-map faces and the textures (of materials used on shapes with uv) that :func:`build` will
    check, where they resolve without error (no warnings, no exceptions: the real resolution follows)."""
    out: list[Path] = []
    bg = scene.background
    if bg.cube_map is not None:
        try:
            folder = resolve_path(bg.cube_map, scene.base_dir, bg.cube_map_loc or bg.loc, "cubeMap",  # type: ignore[arg-type]
                                  directory=True)
            out += [f for f in (find_cube_face(folder, face) for face in CUBE_FACES) if f is not None]
        except (SceneSemanticError, OSError):
            pass
    for index in sorted(used_with_uv):
        mat = scene.materials[index]
        if mat.texture is not None and mat.noise is None:
            try:
                out.append(resolve_path(mat.texture, scene.base_dir, mat.texture_loc or mat.loc, "texture"))  # type: ignore[arg-type]
            except (SceneSemanticError, OSError):
                pass
    return out


def decoded_image(path: str | Path) -> np.ndarray | None:
    """The (H, W, C) uint8 pixels :func:`check_image` read from ``path`` (exactly as OpenImageIO's
    ``read_image(..., "uint8")`` returned them), or None if the file was not checked or has changed since
    (same path, mtime and size). A pixel source for ``a5mi.plugins.imagedata.set_pixel_source``."""
    key = _file_key(Path(path))
    return None if key is None else _IMAGES.get(key)


def find_cube_face(folder: Path, face: str) -> Path | None:
    """The file the ``a5_cubemap`` plugin reads for ``face``: ``face`` + the first of :data:`IMAGE_EXTENSIONS`
    that exists, else the first other ``face.*`` file (sorted); None if there is none."""
    for ext in IMAGE_EXTENSIONS:
        if (folder / f"{face}{ext}").is_file():
            return folder / f"{face}{ext}"
    return next((p for p in sorted(folder.glob(f"{face}.*")) if p.is_file()), None)


def resolve_cube_map(scene: Scene, warnings: list[tuple[FileLoc, str]]) -> Path:
    """The cube-map folder (scene folder first, then cwd). A small regular file whose content is a relative
    path to an existing folder (a git symlink checked out as text, like extras/sibenik/tex/church) is
    followed, with a warning. Each of the six faces must exist and be a readable image (SPEC A.4,
    :func:`check_image`)."""
    bg = scene.background
    assert bg.cube_map is not None
    loc = bg.cube_map_loc or bg.loc
    try:
        folder = resolve_path(bg.cube_map, scene.base_dir, loc, "cubeMap", directory=True)  # type: ignore[arg-type]
    except SceneSemanticError:
        folder = None
        p = Path(bg.cube_map)
        for cand in ([p] if p.is_absolute() else [scene.base_dir / p, Path.cwd() / p]):
            if cand.is_file() and cand.stat().st_size < 4096:
                try:
                    target = cand.read_text().strip()
                except (OSError, UnicodeDecodeError):
                    continue
                dest = cand.parent / target
                if target and "\n" not in target and dest.is_dir():
                    warnings.append((loc, f"cubeMap '{bg.cube_map}' is a text file holding the path '{target}' "  # type: ignore[arg-type]
                                          "(a symlink checked out as a file): following it"))
                    folder = dest
                    break
        if folder is None:
            raise
    for face in CUBE_FACES:
        path = find_cube_face(folder, face)
        if path is None:
            raise SceneSemanticError(f"cubeMap folder '{folder}' has no '{face}' face (expected {face}.bmp or "
                                     f"{face}.png)", loc)
        check_image(path, loc, "cubeMap face")  # type: ignore[arg-type]
    return folder.resolve()


def resolve_texture(scene: Scene, mat: Material) -> Path:
    """The material's texture file (scene folder first, then cwd); missing, unreadable or not an image
    (:func:`check_image`) -> :class:`SceneSemanticError` at its loc."""
    assert mat.texture is not None
    loc = mat.texture_loc or mat.loc
    p = resolve_path(mat.texture, scene.base_dir, loc, "texture")  # type: ignore[arg-type]
    check_image(p, loc, "texture")  # type: ignore[arg-type]
    return p.resolve()


# ------------------------------------------------------------------------------------------------- geometry
def _face_normals_flip(faces: np.ndarray, m: np.ndarray) -> np.ndarray:
    """Reverse the winding when det(M) < 0 so the world face normal is ``(M⁻¹)ᵀ n`` (see module doc)."""
    return faces[:, ::-1].copy() if np.linalg.det(m[:3, :3]) < 0 else faces


_MESH_DATA: dict[tuple[str, int, bytes, str], tuple[ObjMesh, MeshData]] = {}


def mesh_from_obj(name: str, obj: ObjMesh, m: np.ndarray, normals: NormalMode = "auto") -> MeshData:
    """World-space :class:`MeshData` for an OBJ placed with ``M`` (module docstring: normals, winding, uv).

    Remembered per (name, OBJ object, M, normals), so :func:`check_files` and the :func:`build` that
    follows compute it once; the result is shared and must not be modified."""
    key = (name, id(obj), np.asarray(m, dtype=np.float64).tobytes(), str(normals))
    hit = _MESH_DATA.get(key)
    if hit is not None and hit[0] is obj:
        return hit[1]
    data = _mesh_from_obj(name, obj, m, normals)
    if len(_MESH_DATA) >= 4 * _CACHE_SIZE:
        del _MESH_DATA[next(iter(_MESH_DATA))]
    _MESH_DATA[key] = (obj, data)  # holds obj, so its id is not reused while the entry lives
    return data


def _mesh_from_obj(name: str, obj: ObjMesh, m: np.ndarray, normals: NormalMode) -> MeshData:
    vn = vertex_normals(obj.vertices, obj.faces, normals)
    faces = obj.faces
    positions = obj.vertices
    texcoords = None
    if obj.texcoords is not None and obj.face_texcoords is not None:
        # Split vertices per distinct (v, vt) pair: Mitsuba stores one uv per vertex. The pairs, in
        # lexicographic order, are the sorted keys v·T + vt (0 <= vt < T, checked by load_obj).
        nt = len(obj.texcoords)
        pair_key = faces.ravel().astype(np.int64) * nt + obj.face_texcoords.ravel()
        uniq, inverse = np.unique(pair_key, return_inverse=True)
        faces = inverse.reshape(-1, 3)
        uniq_v, uniq_t = uniq // nt, uniq % nt
        positions = obj.vertices[uniq_v]
        texcoords = obj.texcoords[uniq_t]
        if vn is not None:
            vn = vn[uniq_v]
    world = tf.transform_points(m, positions)
    world_n = None
    if vn is not None:
        world_n = vn @ tf.normal_matrix(m).T  # A n, deliberately not renormalised
    else:
        faces = _face_normals_flip(faces, m)
    return MeshData(name, world, faces.astype(np.uint32), world_n, texcoords)


def mesh_from_triangle(name: str, tri: Triangle, m: np.ndarray) -> MeshData:
    """One-face world-space mesh with a flat normal (winding reversed when det M < 0)."""
    v = tf.transform_points(m, np.array([tri.vertex0, tri.vertex1, tri.vertex2], dtype=np.float64))
    faces = _face_normals_flip(np.array([[0, 1, 2]]), m)
    return MeshData(name, v, faces.astype(np.uint32))


def world_plane(plane: Plane, m: np.ndarray) -> tuple[np.ndarray, float]:
    """``(n_w, offset_w)`` with ``P·n_w = offset_w`` the image of ``P·n = offset`` under ``M``
    (planes map by ``M⁻ᵀ``: ``(n_w, −offset_w) = M⁻ᵀ (n, −offset)``)."""
    pi = np.linalg.inv(m).T @ np.array([*plane.normal, -plane.offset], dtype=np.float64)
    return pi[:3], float(-pi[3])


def plane_rectangle_to_world(n: np.ndarray, offset: float, near: np.ndarray,
                             half_size: float = PLANE_HALF_SIZE) -> np.ndarray:
    """``to_world`` of a ``rectangle`` ([-1,1]², z = 0, normal +z) covering the plane ``P·n = offset`` within
    ``half_size`` of the foot of the perpendicular from ``near``; its z axis is ``n/|n|``."""
    nn = float(np.dot(n, n))
    z = n / math.sqrt(nn)
    foot = near - (float(np.dot(n, near)) - offset) / nn * n
    helper = np.array([1.0, 0, 0]) if abs(z[0]) < 0.9 else np.array([0, 1.0, 0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    out = np.eye(4)
    out[:3, 0], out[:3, 1], out[:3, 2], out[:3, 3] = x * half_size, y * half_size, z, foot
    return out


def _check_float32(prim: Any, *values: Any) -> None:
    """Every world-space number handed to Mitsuba (float32) must be finite there: ``|x| <= 3.4028235e38``.
    The parser bounds each number as written; an enclosing ``Transform`` can still scale them past float32
    (``Scale 1e30`` on a vertex at 1e10), which is a :class:`SceneSemanticError` at the primitive."""
    for v in values:
        a = np.asarray(v, dtype=np.float64)
        if not (np.all(np.isfinite(a)) and np.all(np.abs(a) <= FLOAT32_MAX)):
            raise SceneSemanticError(f"{type(prim).__name__} is out of float32 range in world space (the enclosing "
                                     "Transforms scale it beyond 3.4e38)", prim.loc)


def _has_uv(p: Placed, meshes: dict[str, ObjMesh]) -> bool:
    prim = p.primitive
    return isinstance(prim, TriangleMesh) and meshes[prim.obj_file].texcoords is not None


# ------------------------------------------------------------------------------------------------- materials
def a5_bsdf(scene: Scene, mat: Material, with_uv: bool) -> dict[str, Any]:
    """``a5_material`` (contract in ARCHITECTURE.md); ``kd`` = marble, else bitmap (only ``with_uv``)."""
    d: dict[str, Any] = {
        "type": "a5_material",
        "diffuse_color": rgb(mat.diffuse_color),
        "specular_color": rgb(mat.specular_color),
        "shininess": float(mat.shininess),
        "refraction_index": float(mat.refraction_index),
    }
    if mat.noise is not None:
        n = mat.noise
        d["kd"] = {"type": "a5_marble", "color1": rgb(n.color1), "color2": rgb(n.color2), "octaves": int(n.octaves),
                   "frequency": float(n.frequency), "amplitude": float(n.amplitude)}
    elif mat.texture is not None and with_uv:
        d["kd"] = {"type": "a5_bitmap", "filename": str(resolve_texture(scene, mat))}
    return d


def stock_bsdf(scene: Scene, mat: Material, with_uv: bool, warnings: list[tuple[FileLoc, str]]) -> dict[str, Any]:
    """Stock approximation (module docstring): diffuse, blended with a mirror or a dielectric."""
    kd: dict[str, Any]
    if mat.noise is not None:
        n = mat.noise
        kd = rgb((np.asarray(n.color1) + np.asarray(n.color2)) / 2)
        warnings.append((n.loc or mat.loc, "stock conversion: Noise (marble) replaced by its mean colour"))  # type: ignore[arg-type]
    elif mat.texture is not None and with_uv:
        kd = {"type": "bitmap", "filename": str(resolve_texture(scene, mat)), "raw": True,
              "filter_type": "bilinear", "wrap_mode": "clamp"}
    else:
        kd = rgb(mat.diffuse_color)
    diffuse = {"type": "diffuse", "reflectance": kd}
    spec = np.asarray(mat.specular_color, dtype=np.float64)
    w = float(np.clip(spec.max(), 0.0, 1.0))
    if mat.refraction_index > 0.0:
        other: dict[str, Any] = {"type": "dielectric", "int_ior": float(mat.refraction_index), "ext_ior": 1.0}
        if w > 0:
            other["specular_reflectance"] = rgb(spec / w)
            other["specular_transmittance"] = rgb(spec / w)
    elif float(np.linalg.norm(spec)) > MIRROR_THRESHOLD:
        other = {"type": "conductor", "material": "none", "specular_reflectance": rgb(spec / w)}
    else:
        return diffuse
    if w == 0.0:
        return diffuse
    return {"type": "blendbsdf", "weight": w, "bsdf_0": diffuse, "bsdf_1": other}


# ------------------------------------------------------------------------------------------------- the build
def _camera_dicts(scene: Scene, s: RenderSettings, stock: bool) -> dict[str, Any]:
    cam = scene.camera
    film = {"type": "hdrfilm", "width": int(s.width), "height": int(s.height), "rfilter": {"type": "box"},
            "pixel_format": "rgb"}
    sampler = {"type": "stratified", "sample_count": 1, "jitter": False}
    if not stock:
        return {"type": "a5_camera", "center": list(cam.center), "direction": list(cam.direction),
                "up": list(cam.up), "angle": float(cam.angle), "film": film, "sampler": sampler}
    w = max(int(s.width), 2)
    fov = math.degrees(2.0 * math.atan(math.tan(math.radians(cam.angle) / 2.0) * w / (w - 1)))
    c = np.asarray(cam.center, dtype=np.float64)
    return {"type": "perspective", "fov": fov, "fov_axis": "x",
            "to_world": tf.look_at(c, c + np.asarray(cam.direction), np.asarray(cam.up)),
            "film": film, "sampler": sampler}


def _geometry_centre(placed: tuple[Placed, ...], meshes: dict[str, ObjMesh]) -> np.ndarray | None:
    pts = []
    for p in placed:
        prim = p.primitive
        if isinstance(prim, Sphere):
            pts.append(tf.transform_points(p.to_world, np.asarray(prim.center))[None])
        elif isinstance(prim, Triangle):
            pts.append(tf.transform_points(p.to_world, np.array([prim.vertex0, prim.vertex1, prim.vertex2])))
        elif isinstance(prim, TriangleMesh):
            pts.append(tf.transform_points(p.to_world, meshes[prim.obj_file].vertices))
    if not pts:
        return None
    allp = np.concatenate(pts)
    return (allp.min(0) + allp.max(0)) / 2


def build(scene: Scene, settings: RenderSettings | None = None, *, stock: bool = False,
          normals: NormalMode = "auto") -> Built:
    """The plain description of ``scene`` (see :class:`Built`); raises :class:`SceneSemanticError` for missing
    meshes, textures or cube-map faces, at the keyword that named them, and for geometry that nested
    ``Transform`` s push out of float32 range or make singular, at the primitive. numpy's floating-point
    warnings are silenced here: such overflows are checked and reported as errors instead."""
    with np.errstate(all="ignore"):
        return _build(scene, settings, stock=stock, normals=normals)


def _build(scene: Scene, settings: RenderSettings | None, *, stock: bool, normals: NormalMode) -> Built:
    s = settings or RenderSettings()
    out = Built({"type": "scene"})
    d, warnings = out.scene, out.warnings

    # ---------------------------------------------------------------- integrator (SPEC B.3)
    if stock:
        d["integrator"] = {"type": "path", "max_depth": int(s.bounces) + 2}
        if any(scene.ambient):
            warnings.append((scene.background.loc or scene.camera.loc,
                             "stock conversion: the ambient term has no equivalent in 'path' and is dropped"))
    else:
        d["integrator"] = {"type": "a5_whitted", "max_depth": int(s.bounces), "shadows": bool(s.shadows),
                           "ambient": rgb(scene.ambient), "phong": bool(s.phong), "fresnel": str(s.fresnel),
                           "reflection": bool(s.reflection), "refraction": bool(s.refraction)}

    # ---------------------------------------------------------------- sensor (SPEC B.2)
    d["sensor"] = _camera_dicts(scene, s, stock)

    # ---------------------------------------------------------------- meshes (loaded once per file)
    placed = scene.objects
    for p in placed:
        m32 = p.to_world.astype(np.float32)
        det = float(np.linalg.det(m32[:3, :3].astype(np.float64)))
        if not (np.all(np.isfinite(m32)) and math.isfinite(det) and det != 0.0):
            raise SceneSemanticError(f"{type(p.primitive).__name__} is placed by nested Transforms whose product is "
                                     f"{'singular' if det == 0.0 else 'out of float32 range'}", p.primitive.loc)
    meshes: dict[str, ObjMesh] = {}
    for p in placed:
        prim = p.primitive
        if isinstance(prim, TriangleMesh) and prim.obj_file not in meshes:
            path = resolve_path(prim.obj_file, scene.base_dir, prim.obj_file_loc, "obj_file")
            meshes[prim.obj_file] = load_mesh(path, prim.obj_file_loc)
            warnings.extend(meshes[prim.obj_file].warnings)

    # ---------------------------------------------------------------- lights (SPEC A.3)
    centre = _geometry_centre(placed, meshes)
    for i, light in enumerate(scene.lights):
        key = f"light_{i:03d}"
        if isinstance(light, DirectionalLight):
            d[key] = {"type": "directional", "direction": list(light.direction), "irradiance": rgb(light.color)}
        elif isinstance(light, PointLight):
            if not stock:
                d[key] = {"type": "a5_point", "position": list(light.position), "color": rgb(light.color),
                          "falloff": float(light.falloff)}
            else:
                dist2 = 1.0 if centre is None else float(np.sum((centre - np.asarray(light.position)) ** 2))
                scale = dist2 / (1.0 + light.falloff * dist2)
                d[key] = {"type": "point", "position": list(light.position),
                          "intensity": rgb(np.asarray(light.color) * scale)}

    # ---------------------------------------------------------------- images: decode in parallel first
    _prefetch_images(_image_candidates(scene, {p.primitive.material for p in placed if _has_uv(p, meshes)}))

    # ---------------------------------------------------------------- background (SPEC A.4)
    bg = scene.background
    if bg.cube_map is not None:
        folder = resolve_cube_map(scene, warnings)
        d["background"] = ({"type": "envmap", "_bake_cubemap": str(folder)} if stock
                           else {"type": "a5_cubemap", "filename": str(folder)})
    else:
        d["background"] = {"type": "constant", "radiance": rgb(bg.color)}

    # ---------------------------------------------------------------- materials (SPEC A.5), on demand
    def bsdf_ref(index: int, with_uv: bool) -> dict[str, Any]:
        mat = scene.materials[index]
        textured = mat.texture is not None and mat.noise is None  # Noise overrides the texture (B.3)
        key = f"mat_{index:03d}" + ("_nouv" if textured and not with_uv else "")
        if key not in d:
            d[key] = stock_bsdf(scene, mat, with_uv, warnings) if stock else a5_bsdf(scene, mat, with_uv)
        return {"type": "ref", "id": key}

    # ---------------------------------------------------------------- shapes (SPEC A.6)
    cam_c = np.asarray(scene.camera.center, dtype=np.float64)
    for i, p in enumerate(placed):
        prim, m = p.primitive, p.to_world
        bsdf = bsdf_ref(prim.material, _has_uv(p, meshes))
        if isinstance(prim, Sphere):
            key = f"sphere_{i:03d}"
            scale = tf.similarity_scale(m)
            if scale is not None:
                center = tf.transform_points(m, np.asarray(prim.center))
                _check_float32(prim, center, prim.radius * scale)
                d[key] = {"type": "sphere", "center": center.tolist(), "radius": float(prim.radius * scale),
                          "bsdf": bsdf}
            else:
                _check_float32(prim, m)
                d[key + "_group"] = {"type": "shapegroup", "shape": {
                    "type": "sphere", "center": list(prim.center), "radius": float(prim.radius), "bsdf": bsdf}}
                d[key] = {"type": "instance", "shapegroup": {"type": "ref", "id": key + "_group"}, "to_world": m}
        elif isinstance(prim, Plane):
            n_w, off_w = world_plane(prim, m)
            rect = plane_rectangle_to_world(n_w, off_w, cam_c)
            _check_float32(prim, rect)
            d[f"plane_{i:03d}"] = {"type": "rectangle", "to_world": rect, "bsdf": bsdf}
        elif isinstance(prim, Triangle):
            key = f"triangle_{i:03d}"
            data = mesh_from_triangle(key, prim, m)
            _check_float32(prim, data.positions)
            d[key] = {"type": "_mesh", "data": data, "bsdf": bsdf}
        else:
            key = f"mesh_{i:03d}"
            data = mesh_from_obj(key, meshes[prim.obj_file], m, normals)
            _check_float32(prim, data.positions, 0.0 if data.normals is None else data.normals)
            d[key] = {"type": "_mesh", "data": data, "bsdf": bsdf}
    return out


def check_files(scene: Scene, *, stock: bool = False) -> list[tuple[FileLoc, str]]:
    """Resolve and validate every file the conversion reads (OBJ meshes, textures used on shapes with uv,
    cube-map faces), exactly as :func:`build` does and without importing Mitsuba, so the CLI reports a bad file
    before it starts the JIT. Returns the conversion warnings (OBJ quirks, zero-area faces, followed cube-map
    links, stock approximations); raises :class:`SceneSemanticError` at the keyword that named a bad file or
    at the OBJ line at fault."""
    return build(scene, stock=stock).warnings


# ------------------------------------------------------------------------------------------------- Mitsuba
def make_mesh(data: MeshData, bsdf: Any = None) -> Any:
    """An ``mi.Mesh`` from :class:`MeshData` (``bsdf``: a loaded BSDF object or None)."""
    import mitsuba as mi

    props = mi.Properties()
    if bsdf is not None:
        props["bsdf"] = bsdf
    mesh = mi.Mesh(data.name, vertex_count=len(data.positions), face_count=len(data.faces),
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
    return mesh


def bake_cubemap_envmap(folder: str, size: tuple[int, int] = ENVMAP_SIZE) -> np.ndarray:
    """(H, W, 3) float32 latitude-longitude image of the ``a5_cubemap`` at ``folder``, sampled at pixel-centre
    directions in Mitsuba's envmap parametrisation (module docstring)."""
    import drjit as dr
    import mitsuba as mi

    w, h = size
    emitter = mi.load_dict({"type": "a5_cubemap", "filename": folder})
    jj, ii = np.meshgrid(np.arange(h), np.arange(w), indexing="ij")
    theta = (jj.ravel() + 0.5) / h * math.pi
    phi = (ii.ravel() + 0.5) / w * 2 * math.pi
    dirs = mi.Vector3f(np.sin(theta) * np.sin(phi), np.cos(theta), -np.sin(theta) * np.cos(phi))
    si = dr.zeros(mi.SurfaceInteraction3f, dr.width(dirs))
    si.wi = -dirs
    color = emitter.eval(si)
    return np.stack([np.asarray(c, dtype=np.float32) for c in color], axis=-1).reshape(h, w, 3)


def write_float_image(pixels: np.ndarray, path: Path) -> None:
    """Write an (H, W, 3) float image (EXR for the stock envmap) through ``mi.Bitmap`` (keeps the Mitsuba
    import in this module)."""
    import mitsuba as mi

    mi.Bitmap(np.ascontiguousarray(pixels, dtype=np.float32)).write(str(path))


def _materialise(value: Any, objects: dict[str, Any]) -> Any:
    """Plain description value -> ``mi.load_dict`` value (transforms, meshes, refs to loaded BSDFs)."""
    import mitsuba as mi

    if isinstance(value, np.ndarray):
        return mi.ScalarTransform4f(value.tolist())
    if isinstance(value, dict):
        if value.get("type") == "ref" and value["id"] in objects:
            return objects[value["id"]]
        if value.get("type") == "_mesh":
            return make_mesh(value["data"], _materialise(value["bsdf"], objects))
        if "_bake_cubemap" in value:
            return {"type": "envmap", "bitmap": mi.Bitmap(bake_cubemap_envmap(value["_bake_cubemap"]))}
        return {k: _materialise(v, objects) for k, v in value.items()}
    return value


def to_dict(scene: Scene, settings: RenderSettings | None = None, *, stock: bool = False,
            normals: NormalMode = "auto", warnings_out: list[tuple[FileLoc, str]] | None = None) -> dict:
    """A dict for ``mi.load_dict`` (module docstring). BSDFs are loaded first (``mi.load_dict``) because the
    meshes built from numpy take their BSDF object at construction. ``warnings_out`` receives the
    conversion warnings (OBJ quirks, followed cube-map links, stock approximations) as (loc, message)."""
    import mitsuba as mi

    built = build(scene, settings, stock=stock, normals=normals)
    if warnings_out is not None:
        warnings_out.extend(built.warnings)
    objects: dict[str, Any] = {}
    for key, value in built.scene.items():
        if key.startswith("mat_"):
            objects[key] = mi.load_dict(_materialise(value, objects))
    result: dict[str, Any] = {}
    for key, value in built.scene.items():
        if key.startswith("mat_"):
            continue  # used through the shapes that reference them
        result[key] = _materialise(value, objects)
    return result

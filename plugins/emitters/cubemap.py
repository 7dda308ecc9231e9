"""The ``a5_cubemap`` environment emitter: the course's CubeMap background (SPEC A.4)."""

from __future__ import annotations

from pathlib import Path

import drjit as dr
import mitsuba as mi

from a5mi.plugins.textures.imagedata import ImageAtlas, bitmap_rgb8, load_rgb8, resolve
from a5mi.spec import CUBE_FACES, IMAGE_EXTENSIONS, find_cube_face

#: Face order of the atlas (image index used by :meth:`A5CubeMap.lookup`): SPEC A.4's six faces.
FACES: tuple[str, ...] = CUBE_FACES
LEFT, RIGHT, UP, DOWN, FRONT, BACK = range(6)

#: Distance used for ``ds.dist`` by ``sample_direction`` (the emitter does not know the scene's size).
FAR = 1.0e6


def find_face(folder: Path, face: str) -> Path:
    """The file holding ``face`` in ``folder``: :func:`a5mi.spec.find_cube_face` (``face`` + the first of
    ``IMAGE_EXTENSIONS`` that exists, else the first other ``face.*`` file).

    Raises ``ValueError`` naming the face and the names tried.
    """
    path = find_cube_face(folder, face)
    if path is None:
        raise ValueError(
            f"a5_cubemap: parameter 'filename' ({str(folder)!r}): face '{face}' not found "
            f"(looked for {face}{{{','.join(IMAGE_EXTENSIONS)}}})"
        )
    return path


def face_uv(d: mi.Vector3f) -> tuple[mi.UInt32, mi.Float, mi.Float, mi.Bool]:
    """Face index and (u, v) of the unit direction ``d`` per the SPEC A.4 table; ties go to x, then y.

    ========  =====  ===============  ===============
    major     face   u                v
    ========  =====  ===============  ===============
    x > 0     right  (z/x+1)/2        (y/x+1)/2
    x < 0     left   (z/x+1)/2        1 − (y/x+1)/2
    y > 0     up     (x/y+1)/2        (z/y+1)/2
    y < 0     down   1 − (x/y+1)/2    1 − (z/y+1)/2
    z > 0     front  1 − (x/z+1)/2    (y/z+1)/2
    z < 0     back   (x/z+1)/2        1 − (y/z+1)/2
    ========  =====  ===============  ===============

    Output ``valid`` is false only for d = 0 (the binary returns black there).
    """
    ax, ay, az = dr.abs(d.x), dr.abs(d.y), dr.abs(d.z)
    x_major = (ax >= ay) & (ax >= az)
    y_major = ~x_major & (ay >= az)
    z_major = ~x_major & ~y_major
    major = dr.select(x_major, d.x, dr.select(y_major, d.y, d.z))
    # the two minor coordinates, in the table's order (s for u, t for v), divided by the major one
    s = dr.select(x_major, d.z, d.x)
    t = dr.select(x_major, d.y, dr.select(y_major, d.z, d.y))
    su = (s / major + 1.0) * 0.5
    tv = (t / major + 1.0) * 0.5
    pos = major > 0
    face = dr.select(
        x_major,
        dr.select(pos, RIGHT, LEFT),
        dr.select(y_major, dr.select(pos, UP, DOWN), dr.select(pos, FRONT, BACK)),
    )
    face = mi.UInt32(face)
    flip_u = (y_major & ~pos) | (z_major & pos)  # down, front
    flip_v = ~pos  # left, down, back: every negative face
    u = dr.select(flip_u, 1.0 - su, su)
    v = dr.select(flip_v, 1.0 - tv, tv)
    return face, u, v, major != 0


class A5CubeMap(mi.Emitter):
    """Cube-map background of the 6.837 scene format (SPEC A.4, ``Background { cubeMap NAME }``).

    .. list-table::
       :header-rows: 1

       * - Parameter
         - Type
         - Description
       * - ``filename``
         - string
         - Folder holding the six faces ``left right up down front back``, each any 8-bit image
           (``.bmp`` in 2012, ``.png`` in 2015; the first of .bmp, .png, .jpg, ... that exists), decoded
           with ``a5mi.platform.imageio.read_uint8``.
       * - ``left``, ``right``, ``up``, ``down``, ``front``, ``back``
         - ``mi.Bitmap``
         - Instead of ``filename``: the six faces' already decoded 8-bit pixels (row 0 = top). Either
           ``filename`` or all six are required.

    A ray that misses sees the colour ``lookup(d)`` for its direction d (``eval(si)`` uses d = −si.wi):
    d is normalised (float32, d / sqrt((x²+y²)+z²)), its major axis picks a face (ties go to x, then y),
    the A.4 table gives (u, v) and the face is sampled with the A.4 texture lookup (bilinear, clamped,
    no half-texel offset, bytes / 255, no gamma). The faces are not rotated or flipped in any other way.

    The emitter is an environment (``Infinite`` flag, ``is_environment()`` true). For stock integrators
    it also samples directions uniformly over the sphere (pdf 1/4π, ``ds.dist`` = 1e6); that is not
    importance sampling, only enough to make it usable by ``path`` or ``direct``.

    .. code-block:: python

        'background': {'type': 'a5_cubemap', 'filename': 'tex/church'}
        'background': {'type': 'a5_cubemap', 'left': mi.Bitmap(left_pixels), ..., 'back': mi.Bitmap(...)}
    """

    def __init__(self, props: mi.Properties) -> None:
        super().__init__(props)
        given = [face for face in FACES if face in props]
        if "filename" in props and given:
            raise ValueError(f"a5_cubemap: give either 'filename' or the six faces, not both (found {given})")
        self.face_files: dict[str, Path] = {}
        images = []
        if given:
            missing = [face for face in FACES if face not in given]
            if missing:
                raise ValueError(f"a5_cubemap: faces {missing} are missing (all six bitmaps are required)")
            self.filename: str | None = None
            images = [bitmap_rgb8(props[face], f"a5_cubemap: parameter '{face}'") for face in FACES]
        else:
            if "filename" not in props:
                raise ValueError("a5_cubemap: parameter 'filename' (a folder with the six faces) or the six "
                                 "face bitmaps are required")
            self.filename = str(props["filename"])
            folder = resolve(self.filename)
            if not folder.is_dir():
                raise ValueError(f"a5_cubemap: parameter 'filename' ({self.filename!r}) is not a folder")
            for face in FACES:
                path = find_face(folder, face)
                try:
                    images.append(load_rgb8(path))
                except ValueError as exc:
                    raise ValueError(f"a5_cubemap: parameter 'filename', face '{face}': {exc}") from None
                self.face_files[face] = path
        self.atlas = ImageAtlas(images)
        self.m_flags = mi.EmitterFlags.Infinite | mi.EmitterFlags.SpatiallyVarying

    def lookup(self, d: mi.Vector3f, active: mi.Bool | bool = True) -> mi.Color3f:
        """Output the background colour for the direction ``d`` (any length), per SPEC A.4."""
        d = mi.Vector3f(d)
        norm = dr.sqrt((d.x * d.x + d.y * d.y) + d.z * d.z)
        d = d / norm
        face, u, v, valid = face_uv(d)
        valid &= mi.Bool(active)
        return dr.select(valid, self.atlas.sample(u, v, face, valid), 0.0)

    def eval(self, si: mi.SurfaceInteraction3f, active: mi.Bool = True) -> mi.Color3f:
        """Output lookup(−si.wi): the colour seen by a ray of direction −si.wi that missed the scene."""
        return self.lookup(-si.wi, active)

    def sample_direction(
        self, it: mi.Interaction3f, sample: mi.Point2f, active: mi.Bool = True
    ) -> tuple[mi.DirectionSample3f, mi.Color3f]:
        """Uniform direction over the sphere; value = lookup(d) / pdf with pdf = 1/(4π)."""
        d = mi.warp.square_to_uniform_sphere(sample)
        ds = dr.zeros(mi.DirectionSample3f, dr.width(d))
        ds.p = it.p + d * FAR
        ds.n = -d
        ds.time = it.time
        ds.pdf = mi.warp.square_to_uniform_sphere_pdf(d)
        ds.delta = mi.Bool(False)
        ds.d = d
        ds.dist = mi.Float(FAR)
        ds.emitter = mi.EmitterPtr(self)
        return ds, dr.select(active, self.lookup(d, active) / ds.pdf, 0.0)

    def pdf_direction(self, it: mi.Interaction3f, ds: mi.DirectionSample3f, active: mi.Bool = True) -> mi.Float:
        """1/(4π) (uniform sphere sampling)."""
        return dr.select(active, mi.warp.square_to_uniform_sphere_pdf(ds.d), 0.0)

    def eval_direction(self, it: mi.Interaction3f, ds: mi.DirectionSample3f, active: mi.Bool = True) -> mi.Color3f:
        """lookup(ds.d)."""
        return self.lookup(ds.d, active)

    def sample_wavelengths(
        self, si: mi.SurfaceInteraction3f, sample: mi.Float, active: mi.Bool = True
    ) -> tuple[mi.Color0f, mi.Color3f]:
        """RGB rendering (a5mi's variants) has no wavelengths to sample: (none, the colour seen along
        ``-si.wi``). Mitsuba's integrators call it on every emitter alive in the process."""
        return dr.zeros(mi.Color0f), self.lookup(-si.wi, active)

    def set_scene(self, scene: mi.Scene) -> None:
        """Keep the scene's bounding sphere (:meth:`sample_ray` starts light rays on a disc of its radius)."""
        box = scene.bbox()
        sphere = box.bounding_sphere() if box.valid() else mi.ScalarBoundingSphere3f(mi.ScalarPoint3f(0.0), 1.0)
        self._centre = mi.Point3f(sphere.center)
        self._radius = mi.Float(max(float(sphere.radius), 1e-3))
        dr.make_opaque(self._centre, self._radius)

    def sample_ray(
        self, time: mi.Float, sample1: mi.Float, sample2: mi.Point2f, sample3: mi.Point2f, active: mi.Bool = True
    ) -> tuple[mi.Ray3f, mi.Color3f]:
        """A light ray from the environment for light tracers (as Mitsuba's ``constant``): a direction ``d``
        uniform over the sphere (pdf 1/4π), the ray travelling along ``-d`` from a point uniform on the disc
        of the scene's bounding sphere (radius ``R``) facing ``d``; weight = lookup(d) · 4π · πR²."""
        d = mi.warp.square_to_uniform_sphere(sample2)
        disc = mi.warp.square_to_uniform_disk_concentric(sample3)
        centre = getattr(self, "_centre", mi.Point3f(0.0))
        radius = getattr(self, "_radius", mi.Float(1.0))
        origin = centre + radius * (d + mi.Frame3f(-d).to_world(mi.Vector3f(disc.x, disc.y, 0.0)))
        weight = self.lookup(d, active) * (4.0 * dr.pi * dr.pi * radius * radius)
        return mi.Ray3f(origin, -d, time), dr.select(active, weight, 0.0)

    def sample_position(self, time: mi.Float, sample: mi.Point2f,
                        active: mi.Bool = True) -> tuple[mi.PositionSample3f, mi.Float]:
        """An environment lies at infinity: no position to sample (pdf 0, weight 0), as Mitsuba's ``constant``
        and ``envmap``, which refuse the call."""
        ps = dr.zeros(mi.PositionSample3f, dr.width(sample))
        ps.time = time
        return ps, dr.zeros(mi.Float, dr.width(sample))

    def bbox(self) -> mi.ScalarBoundingBox3f:
        return mi.ScalarBoundingBox3f()  # occupies no region of space

    def traverse(self, cb: mi.TraversalCallback) -> None:
        cb.put("data", self.atlas.data, mi.ParamFlags.NonDifferentiable)

    def parameters_changed(self, keys: list[str]) -> None:
        dr.make_opaque(self.atlas.data)

    def to_string(self) -> str:
        sizes = ", ".join(f"{f}={w}x{h}" for f, (w, h) in zip(FACES, self.atlas.sizes, strict=True))
        return f"A5CubeMap[filename={self.filename!r}, {sizes}]"


def register() -> None:
    """Register ``a5_cubemap`` with Mitsuba (call after selecting a JIT variant)."""
    mi.register_emitter("a5_cubemap", lambda props: A5CubeMap(props))

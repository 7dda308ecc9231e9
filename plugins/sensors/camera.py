"""Camera rays of the sample solution and the ``a5_camera`` sensor (SPEC B.2; thin lens of docs/EXTENSIONS.md E.3)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from functools import partial

import drjit as dr
import mitsuba as mi
import numpy as np

from a5mi.plugins.params import vec3_param
from a5mi.vecmath32 import _cross32, _normalize32, camera_basis  # noqa: F401 - the camera's float32 basis

#: Film-position samples within this many pixels of a pixel centre are snapped onto it (see A5Camera).
SNAP_PIXELS = 2.0**-10


def focal_factor(angle_deg: float) -> np.float32:
    """f = (float)(1 / tan((double)angle_rad · 0.5)) with angle_rad = (float)(π · angle_deg / 180).

    The parser stores the radians as a float (DegreesToRadians on the float degrees, in double); the
    camera then widens it to double for tan. ``angle_deg`` is the full field of view.
    """
    angle_rad = np.float32(math.pi * float(np.float32(angle_deg)) / 180.0)
    if not 0.0 < float(angle_rad) < math.pi:
        raise ValueError(f"camera angle must be in (0, 180) degrees, got {angle_deg}")
    return np.float32(1.0 / math.tan(float(angle_rad) * 0.5))


def camera_rays(
    center: Sequence[float],
    direction: Sequence[float],
    up: Sequence[float],
    angle_deg: float,
    x_pix: mi.Float,
    y_pix: mi.Float,
    width: int,
    height: int,
) -> mi.Ray3f:
    """Camera rays of the sample solution (SPEC B.2), in the binary's float32 operation order.

    Parameter ``x_pix``, ``y_pix`` (mi.Float): continuous pixel coordinates i + jx and j + jy, with j = 0
    the **bottom** row and integer values at pixel centres.
    Parameter ``width``, ``height`` (int): the render size W × H.
    Output: rays with origin ``center`` and unit direction, per lane::

        x = x_pix / (W − 1);  x = (x + x) − 1         (likewise y with H − 1; 0 when W or H is 1)
        f = (float)(1 / tan((double)angle_rad · 0.5))
        d = ((f·w + x·u) + y·v);  dir = d / sqrtf((dx² + dy²) + dz²)

    The first and last pixel centres fall exactly on −1 and +1; the same f serves both axes (no
    aspect-ratio correction). W = 1 (or H = 1) has no W − 1 to divide by; the coordinate is then 0, the
    centre of the view (the binary would divide by zero).

    The basis, f, W − 1 and H − 1 enter the kernel as opaque values, so one kernel serves every camera.
    """
    if width < 1 or height < 1:
        raise ValueError(f"image size must be at least 1x1, got {width}x{height}")
    w, u, v = camera_basis(direction, up)
    f = focal_factor(angle_deg)

    def opaque(value: float) -> mi.Float:
        out = mi.Float(float(value))
        dr.make_opaque(out)
        return out

    wx, wy, wz = (opaque(c) for c in w)
    ux, uy, uz = (opaque(c) for c in u)
    vx, vy, vz = (opaque(c) for c in v)
    fo = opaque(f)
    x_pix = mi.Float(x_pix)
    y_pix = mi.Float(y_pix)
    if width > 1:
        x = x_pix / opaque(width - 1)
        x = (x + x) - 1.0
    else:
        x = dr.zeros(mi.Float, dr.width(x_pix))
    if height > 1:
        y = y_pix / opaque(height - 1)
        y = (y + y) - 1.0
    else:
        y = dr.zeros(mi.Float, dr.width(y_pix))
    dx = (fo * wx + x * ux) + y * vx
    dy = (fo * wy + x * uy) + y * vy
    dz = (fo * wz + x * uz) + y * vz
    norm = dr.sqrt((dx * dx + dy * dy) + dz * dz)
    n = max(dr.width(x), dr.width(y))
    origin = mi.Point3f(*(opaque(np.float32(float(c))) for c in center)) + dr.zeros(mi.Vector3f, n)
    return mi.Ray3f(origin, mi.Vector3f(dx / norm, dy / norm, dz / norm))


def thin_lens(ray: mi.Ray3f, direction: Sequence[float], up: Sequence[float], aperture: float,
              focus_distance: float, sample: mi.Point2f) -> mi.Ray3f:
    """The E.3 thin-lens ray for the pinhole ``ray`` (B.2) of a camera looking along ``direction`` with ``up``,
    lens diameter ``aperture`` and ``focus_distance``, for a unit-square ``sample``::

        P  = o + (F / (d·w)) d                 the point of the focus plane on the pinhole ray
        o' = o + (A/2)(x u + y v)              (x, y) = concentric map of ``sample`` onto the unit disc
        ray = (o', normalize(P − o'))

    Every camera value is opaque: a keyframed camera (EXTENSIONS E.11) turns without a new kernel."""
    w, u, v = (dr.opaque(mi.Vector3f, [float(c) for c in a]) for a in camera_basis(direction, up))
    radius = dr.opaque(mi.Float, 0.5 * float(aperture))
    focus = dr.opaque(mi.Float, float(focus_distance))
    focal_point = ray.o + (focus / dr.dot(ray.d, w)) * ray.d
    disk = mi.warp.square_to_uniform_disk_concentric(sample)
    origin = ray.o + radius * (disk.x * u + disk.y * v)
    return mi.Ray3f(origin, dr.normalize(focal_point - origin))


#: A 3-number parameter of ``a5_camera`` (:func:`a5mi.plugins.params.vec3_param`).
_vec3 = partial(vec3_param, "a5_camera")


class A5Camera(mi.Sensor):
    """The 6.837 PerspectiveCamera as a Mitsuba sensor (SPEC B.2; scene block of A.2).

    .. list-table::
       :header-rows: 1

       * - Parameter
         - Type
         - Description
       * - ``center``
         - point
         - Eye position (Default: 0, 0, 0)
       * - ``direction``
         - vector
         - Viewing direction, any length (Default: 0, 0, −1)
       * - ``up``
         - vector
         - Up vector, need not be perpendicular to ``direction`` (Default: 0, 1, 0)
       * - ``angle``
         - float
         - Full field of view in **degrees**, used for both axes (Default: 30)
       * - ``aperture``
         - float
         - Lens diameter ``A >= 0`` of the E.3 thin lens; 0 is the pinhole (Default: 0)
       * - ``focus_distance``
         - float
         - Distance ``F > 0`` along the view direction of the plane in focus (Default: 1)
       * - ``pixel_centres``
         - boolean
         - Trace every sample through its pixel's centre, whatever the sampler's position inside the
           pixel (Default: false)
       * - ``film``
         - film
         - Usually ``hdrfilm`` with ``width``/``height`` and a ``box`` reconstruction filter

    ``sample_ray(time, s1, pos, s3)`` maps Mitsuba's film position ``pos`` ∈ [0, 1]² (row 0 = top) to
    the a5 pixel coordinates ``x_pix = pos.x·W − 0.5`` and ``y_pix = H·(1 − pos.y) − 0.5`` (row 0 =
    bottom) and returns :func:`camera_rays` for them, weight 1. A position within 1/1024 pixel of a pixel
    centre is snapped onto it, undoing Mitsuba's float rounding of ``(i + 0.5)·(1/W)``.

    **One ray through each pixel centre, as a5soln renders without -jitter.** ``mi.render`` places the
    sample at ``pixel + sampler.next_2d()``; the ``independent`` sampler therefore jitters uniformly inside
    each pixel (antialiased, not the a5 image). For exact pixel centres use the ``stratified`` sampler with
    ``jitter: False`` and ``sample_count: 1`` (its sample is the stratum centre, 0.5) and a ``box``
    reconstruction filter, so each sample lands in its own pixel only::

        'sensor': {
            'type': 'a5_camera',
            'center': [0, 0.8, 5], 'direction': [0, 0, -1], 'up': [0, 1, 0], 'angle': 30.0,
            'film': {'type': 'hdrfilm', 'width': 300, 'height': 300, 'rfilter': {'type': 'box'},
                     'pixel_format': 'rgb'},
            'sampler': {'type': 'stratified', 'sample_count': 1, 'jitter': False},
        }

    **Several samples per pixel, as** ``a5 -spp N``. A sampler with ``sample_count > 1`` spreads the film
    positions over the pixel (the ``stratified`` sampler at the centres of a √N × √N grid of strata, jittered
    or not): an antialiased image whose edges differ from ``a5 -spp N``, which keeps the B.2 pixel centre and
    samples only the stochastic dimensions (EXTENSIONS E.5). With ``pixel_centres`` true the camera traces
    pixel ``i = floor(pos.x·W)``, ``j = H − 1 − floor(pos.y·H)`` through its centre, ``x_pix = i``, ``y_pix = j``
    (the box filter keeps the sample in that pixel), so ``N`` samples sample the lens and the lights only.
    ``a5mi convert`` writes it.

    **Thin lens (E.3).** With ``aperture > 0`` the ray is :func:`thin_lens` of the pinhole ray with the
    sampler's aperture sample (``sample3``); ``aperture 0`` leaves the pinhole ray untouched (the lens code
    is not traced).

    As in the binary, W − 1 and H − 1 scale the two axes (no aspect correction); a 1-pixel axis gives
    coordinate 0. ``a5mi.render.driver`` calls :func:`camera_rays` itself (with the B.5 jitter offsets).
    """

    def __init__(self, props: mi.Properties) -> None:
        super().__init__(props)
        # JIT arrays of width 1, so that mi.traverse / SceneParameters can update them
        self.params = {
            "center": mi.Point3f(_vec3(props, "center", (0.0, 0.0, 0.0))),
            "direction": mi.Vector3f(_vec3(props, "direction", (0.0, 0.0, -1.0))),
            "up": mi.Vector3f(_vec3(props, "up", (0.0, 1.0, 0.0))),
            "angle": mi.Float(float(props.get("angle", 30.0))),
            "aperture": mi.Float(float(props.get("aperture", 0.0))),
            "focus_distance": mi.Float(float(props.get("focus_distance", 1.0))),
        }
        self.pixel_centres = bool(props.get("pixel_centres", False))
        self._read_params()

    def _read_params(self) -> None:
        """Copy the traversable parameters to Python numbers (validated) for :func:`camera_rays`."""
        p = self.params
        self.center = tuple(float(dr.slice(c, 0)) for c in p["center"])
        self.direction = tuple(float(dr.slice(c, 0)) for c in p["direction"])
        self.up = tuple(float(dr.slice(c, 0)) for c in p["up"])
        self.angle = float(dr.slice(p["angle"], 0))
        self.aperture = float(dr.slice(p["aperture"], 0))
        self.focus_distance = float(dr.slice(p["focus_distance"], 0))
        try:
            camera_basis(self.direction, self.up)
            focal_factor(self.angle)
        except ValueError as exc:
            raise ValueError(f"a5_camera: {exc}") from None
        if not (0.0 <= self.aperture < math.inf and 0.0 < self.focus_distance < math.inf):
            raise ValueError(f"a5_camera: aperture must be >= 0 and focus_distance > 0, got {self.aperture} and "
                             f"{self.focus_distance}")
        self.m_needs_sample_3 = self.aperture > 0.0

    def sample_ray(
        self,
        time: mi.Float,
        sample1: mi.Float,
        sample2: mi.Point2f,
        sample3: mi.Point2f,
        active: mi.Bool = True,
    ) -> tuple[mi.Ray3f, mi.Color3f]:
        """Output (camera ray for the film position ``sample2``, weight 1); see the class docstring."""
        size = self.film().size()
        width, height = int(size.x), int(size.y)
        if self.pixel_centres:
            x_pix = dr.clip(dr.floor(sample2.x * width), 0.0, width - 1.0)
            y_pix = (height - 1.0) - dr.clip(dr.floor(sample2.y * height), 0.0, height - 1.0)
        else:
            x_pix = snap(sample2.x * width - 0.5)
            y_pix = snap(height * (1.0 - sample2.y) - 0.5)
        ray = camera_rays(self.center, self.direction, self.up, self.angle, x_pix, y_pix, width, height)
        if self.aperture > 0.0:
            ray = thin_lens(ray, self.direction, self.up, self.aperture, self.focus_distance, mi.Point2f(sample3))
        ray.time = mi.Float(time)
        return ray, dr.full(mi.Color3f, 1.0, dr.width(x_pix))

    def sample_ray_differential(self, time: mi.Float, sample1: mi.Float, sample2: mi.Point2f, sample3: mi.Point2f,
                                active: mi.Bool = True) -> tuple[mi.RayDifferential3f, mi.Color3f]:
        """As :meth:`sample_ray`, without differentials."""
        ray, weight = self.sample_ray(time, sample1, sample2, sample3, active)
        return mi.RayDifferential3f(ray), weight

    def bbox(self) -> mi.ScalarBoundingBox3f:
        return mi.ScalarBoundingBox3f(mi.ScalarPoint3f(*self.center))

    def traverse(self, cb: mi.TraversalCallback) -> None:
        for name, value in self.params.items():
            cb.put(name, value, mi.ParamFlags.NonDifferentiable)

    def parameters_changed(self, keys: list[str]) -> None:
        self._read_params()

    def to_string(self) -> str:
        return (
            f"A5Camera[center={self.center}, direction={self.direction}, up={self.up}, "
            f"angle={self.angle}, aperture={self.aperture}, focus_distance={self.focus_distance}, "
            f"film={self.film()}]"
        )


def snap(pix: mi.Float) -> mi.Float:
    """pix rounded to the nearest integer when within SNAP_PIXELS of it, else unchanged."""
    r = dr.round(pix)
    return dr.select(dr.abs(pix - r) <= SNAP_PIXELS, r, pix)


def register() -> None:
    """Register ``a5_camera`` with Mitsuba (call after selecting a JIT variant)."""
    mi.register_sensor("a5_camera", lambda props: A5Camera(props))

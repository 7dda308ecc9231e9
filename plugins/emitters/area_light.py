"""The ``a5_area`` emitter: the extension's AreaLight and SphereLight (docs/EXTENSIONS.md E.2).

An a5 area light is the mean of point lights spread over it: with ``S = samples`` stratified points ``y_j``
(:mod:`.sampling`), a shading point ``p`` receives::

    colour(p) = (1/S) Σ_j V(p, y_j) · max(L_j·N, 0) · color / (1 + falloff |y_j - p|²) ⊙ kd,   L_j = (y_j - p)/|y_j - p|

(no inverse-square law and no cosine at the light, like the a5 PointLight), an unbiased estimate of the
mean over the light of ``V · max(L·N, 0) · color / (1 + falloff d²)``:

* ``shape = parallelogram``: ``y = corner + u·edge1 + v·edge2``, ``(u, v)`` uniform on the unit square (the
  mean over the parallelogram's area, both faces emit);
* ``shape = sphere``: ``y`` is the near point of the sphere along a direction uniform in the cone of
  half-angle ``asin(radius/|center - p|)`` around ``center - p`` (the mean over the solid angle of the
  visible disc); from inside the sphere, uniform over all directions.

The light is attached to the ``rectangle`` / ``sphere`` shape of its geometry, so camera and secondary rays
that hit it see ``eval = color``. ``samples`` (int, 16) is read by ``a5_whitted`` (:attr:`A5AreaLight.samples`).
"""

from __future__ import annotations

import math

import drjit as dr
import mitsuba as mi

from a5mi.plugins.emitters.point_light import _vec3_param, attenuation, light_sample


class A5AreaLight(mi.Emitter):
    """``a5_area``: ``shape`` (``parallelogram``: ``corner``, ``edge1``, ``edge2``; ``sphere``: ``center``,
    ``radius``), ``color`` rgb (1), ``falloff`` float (0), ``samples`` int (16); see the module docstring."""

    def __init__(self, props: mi.Properties) -> None:
        super().__init__(props)
        self.kind = str(props.get("shape", "parallelogram"))
        if self.kind not in ("parallelogram", "sphere"):
            raise ValueError(f"a5_area: 'shape' must be parallelogram or sphere, got {self.kind!r}")
        self.samples = int(props.get("samples", 16))
        falloff = float(props.get("falloff", 0.0))
        if self.samples < 1 or not math.isfinite(falloff) or falloff < 0.0:
            raise ValueError(f"a5_area: need samples >= 1 and falloff >= 0, got {self.samples}, {falloff}")
        self.color = mi.Color3f(*_vec3_param(props, "color", (1.0, 1.0, 1.0)))
        self.falloff = mi.Float(falloff)
        if self.kind == "parallelogram":
            self.corner = mi.Point3f(*_vec3_param(props, "corner", None))
            self.edge1 = mi.Vector3f(*_vec3_param(props, "edge1", None))
            self.edge2 = mi.Vector3f(*_vec3_param(props, "edge2", None))
            dr.make_opaque(self.corner, self.edge1, self.edge2)
        else:
            self.center = mi.Point3f(*_vec3_param(props, "center", None))
            radius = float(props.get("radius", 1.0))
            if not radius > 0.0:
                raise ValueError(f"a5_area: 'radius' must be positive, got {radius}")
            self.radius = mi.Float(radius)
            dr.make_opaque(self.center, self.radius)
        dr.make_opaque(self.color, self.falloff)
        self.m_flags = mi.EmitterFlags.Surface

    def _point(self, p: mi.Point3f, sample: mi.Point2f) -> mi.Point3f:
        """The light point ``y`` for the shading point ``p`` and the unit-square sample (module docstring)."""
        if self.kind == "parallelogram":
            return self.corner + sample.x * self.edge1 + sample.y * self.edge2
        to_c = self.center - p
        dc = dr.norm(to_c)
        outside = dc > self.radius
        sin_max = dr.minimum(self.radius / dr.maximum(dc, 1e-30), 1.0)
        cos_max = dr.select(outside, dr.safe_sqrt(1.0 - sin_max * sin_max), -1.0)
        local = mi.warp.square_to_uniform_cone(sample, cos_max)
        w = mi.Frame3f(to_c / dr.maximum(dc, 1e-30)).to_world(local)
        # ray p + t w against the sphere: t² - 2 (w·c') t + |c'|² - r² = 0, c' = center - p
        b = dr.dot(w, to_c)
        disc = dr.safe_sqrt(b * b - (dc * dc - self.radius * self.radius))
        t = dr.select(outside, b - disc, b + disc)
        return p + t * w

    def sample_direction(
        self, it: mi.Interaction3f, sample: mi.Point2f, active: mi.Bool = True
    ) -> tuple[mi.DirectionSample3f, mi.Color3f]:
        """``ds.d = L``, ``ds.dist = |y - p|`` and ``color / (1 + falloff dist²)`` for the point ``y`` of ``sample``."""
        y = self._point(it.p, sample)
        d = y - it.p
        dist = dr.norm(d)
        # a point on the light's own sphere (a ray that hit the light) may sample y = p: no direction, term 0
        d, dist = dr.select(dist > 0.0, d, 0.0), dr.maximum(dist, 1e-30)
        ds = light_sample(self, it, y, d, dist, delta=False)
        return ds, dr.select(active, attenuation(self.color, self.falloff, dist), 0.0)

    def eval(self, si: mi.SurfaceInteraction3f, active: mi.Bool = True) -> mi.Color3f:
        """``color``: what a ray hitting the light's shape sees (both faces)."""
        return dr.select(active, mi.Color3f(self.color), 0.0)

    def eval_direction(self, it: mi.Interaction3f, ds: mi.DirectionSample3f, active: mi.Bool = True) -> mi.Color3f:
        return dr.select(active, attenuation(self.color, self.falloff, ds.dist), 0.0)

    def pdf_direction(self, it: mi.Interaction3f, ds: mi.DirectionSample3f, active: mi.Bool = True) -> mi.Float:
        return dr.zeros(mi.Float, dr.width(ds.d))

    def sample_position(self, time: mi.Float, sample: mi.Point2f,
                        active: mi.Bool = True) -> tuple[mi.PositionSample3f, mi.Float]:
        ps = dr.zeros(mi.PositionSample3f, dr.width(sample))
        if self.kind == "parallelogram":
            ps.p = self.corner + sample.x * self.edge1 + sample.y * self.edge2
        else:
            ps.p = self.center + self.radius * mi.warp.square_to_uniform_sphere(sample)
        ps.time = time
        ps.pdf = mi.Float(1.0)
        return ps, dr.full(mi.Float, 1.0, dr.width(sample))

    def sample_ray(
        self, time: mi.Float, sample1: mi.Float, sample2: mi.Point2f, sample3: mi.Point2f, active: mi.Bool = True
    ) -> tuple[mi.Ray3f, mi.Color3f]:
        """A light ray for light tracers (Mitsuba's ``ptracer``), the light read as the Lambertian emitter that
        ``eval`` shows (radiance ``color``; the a5 ``falloff`` has no counterpart there): a point uniform on
        the surface of area ``A`` (a parallelogram's two faces, each chosen with probability 1/2; a sphere's
        outside), a cosine-weighted direction about that face's normal; weight = power / pdf = ``π A color``
        (``2 π A color`` for the parallelogram's two faces)."""
        local = mi.warp.square_to_cosine_hemisphere(sample3)
        if self.kind == "parallelogram":
            p = self.corner + sample2.x * self.edge1 + sample2.y * self.edge2
            cross = dr.cross(self.edge1, self.edge2)
            area = dr.norm(cross)
            n = cross / dr.maximum(area, 1e-30)
            n = dr.select(sample1 < 0.5, n, -n)
            weight = 2.0 * dr.pi * area
        else:
            n = mi.warp.square_to_uniform_sphere(sample2)
            p = self.center + self.radius * n
            weight = 4.0 * dr.pi * dr.pi * self.radius * self.radius
        ray = mi.Ray3f(p, mi.Frame3f(n).to_world(local), time)
        return ray, dr.select(active, weight * self.color, 0.0)

    def sample_wavelengths(
        self, si: mi.SurfaceInteraction3f, sample: mi.Float, active: mi.Bool = True
    ) -> tuple[mi.Color0f, mi.Color3f]:
        """RGB rendering (a5mi's variants) has no wavelengths to sample: (none, ``color``). Mitsuba's own
        integrators (``ptracer``) call it on every emitter alive in the process, a5mi's included."""
        return dr.zeros(mi.Color0f), dr.select(active, mi.Color3f(self.color), 0.0)

    def bbox(self) -> mi.ScalarBoundingBox3f:
        if self.kind == "parallelogram":
            c = [float(dr.slice(x, 0)) for x in self.corner]
            e1 = [float(dr.slice(x, 0)) for x in self.edge1]
            e2 = [float(dr.slice(x, 0)) for x in self.edge2]
            box = mi.ScalarBoundingBox3f(mi.ScalarPoint3f(*c))
            for s, t in ((1, 0), (0, 1), (1, 1)):
                box.expand(mi.ScalarPoint3f(*(c[i] + s * e1[i] + t * e2[i] for i in range(3))))
            return box
        c = mi.ScalarPoint3f(*(float(dr.slice(x, 0)) for x in self.center))
        r = float(dr.slice(self.radius, 0))
        return mi.ScalarBoundingBox3f(c - r, c + r)

    def traverse(self, cb: mi.TraversalCallback) -> None:
        cb.put("color", self.color, mi.ParamFlags.NonDifferentiable)
        cb.put("falloff", self.falloff, mi.ParamFlags.NonDifferentiable)

    def to_string(self) -> str:
        return f"A5AreaLight[shape={self.kind}, samples={self.samples}, color={self.color}]"


def register() -> None:
    """Register ``a5_area`` with Mitsuba (call after selecting a JIT variant)."""
    mi.register_emitter("a5_area", lambda props: A5AreaLight(props))

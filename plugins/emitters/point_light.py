"""The ``a5_point`` emitter: the course's PointLight with its ``1 + falloff·d²`` attenuation (SPEC A.3)."""

from __future__ import annotations

import math
from functools import partial

import drjit as dr
import mitsuba as mi

from a5mi.plugins.params import put_params, vec3_param

#: A 3-number parameter of ``a5_point`` (:func:`a5mi.plugins.params.vec3_param`).
_vec3_param = partial(vec3_param, "a5_point")


def light_sample(emitter: mi.Emitter, it: mi.Interaction3f, p: mi.Point3f, d: mi.Vector3f, dist: mi.Float,
                 delta: bool) -> mi.DirectionSample3f:
    """The ``DirectionSample3f`` of an a5 light seen from ``it``: towards ``p`` along ``d`` (unnormalised, length
    ``dist``), pdf 1 (one sample is the light, SPEC A.3), normal 0."""
    ds = dr.zeros(mi.DirectionSample3f, dr.width(it.p))
    ds.p, ds.n, ds.time, ds.pdf = p, mi.Normal3f(0.0), it.time, mi.Float(1.0)
    ds.delta, ds.d, ds.dist, ds.emitter = mi.Bool(delta), d / dist, dist, mi.EmitterPtr(emitter)
    return ds


def attenuation(color: mi.Color3f, falloff: mi.Float, dist: mi.Float) -> mi.Color3f:
    """Colour arriving at distance d: color / (1 + falloff·d²) (SPEC A.3; no inverse-square law)."""
    return color / (1.0 + falloff * dist * dist)


class A5PointLight(mi.Emitter):
    """Point light of the 6.837 scene format (SPEC A.3, ``PointLight { position color [falloff] }``).

    .. list-table::
       :header-rows: 1

       * - Parameter
         - Type
         - Description
       * - ``position``
         - point
         - Position of the light (required)
       * - ``color``
         - rgb
         - Colour of the light (Default: 1, 1, 1)
       * - ``falloff``
         - float
         - Attenuation coefficient, ≥ 0 (Default: 0, i.e. no attenuation)

    For a shading point p, ``sample_direction(it, sample)`` returns a direction sample with::

        d    = position − p
        dist = sqrt((dx² + dy²) + dz²)          (float32, vecmath order)
        ds.d = d / dist,  ds.dist = dist,  ds.p = position,  ds.pdf = 1,  ds.delta = True
        value = color / (1 + falloff · dist²)     (the colour arriving at p)

    The a5 light has **no** inverse-square law, unlike Mitsuba's stock ``point`` emitter
    (intensity/dist²); ``falloff`` 0 gives a light whose colour does not depend on distance. The flags say
    ``DeltaPosition``, so a Whitted integrator treats it as a light and a path tracer never hits it
    (``eval`` and ``pdf_direction`` are 0).

    .. code-block:: python

        'light_000': {
            'type': 'a5_point',
            'position': [0.5, 2.0, 1.0],
            'color': {'type': 'rgb', 'value': [0.9, 0.7, 0.5]},
            'falloff': 0.0,
        }
    """

    def __init__(self, props: mi.Properties) -> None:
        super().__init__(props)
        position = _vec3_param(props, "position", None)
        color = _vec3_param(props, "color", (1.0, 1.0, 1.0))
        falloff = float(props.get("falloff", 0.0))
        if not math.isfinite(falloff) or falloff < 0.0:
            raise ValueError(f"a5_point: parameter 'falloff' must be a finite number >= 0, got {falloff}")
        self.position = mi.Point3f(*position)
        self.color = mi.Color3f(*color)
        self.falloff = mi.Float(falloff)
        self._make_opaque()
        self.m_flags = mi.EmitterFlags.DeltaPosition

    def _make_opaque(self) -> None:
        dr.make_opaque(self.position, self.color, self.falloff)

    def sample_direction(
        self, it: mi.Interaction3f, sample: mi.Point2f, active: mi.Bool = True
    ) -> tuple[mi.DirectionSample3f, mi.Color3f]:
        """Output (ds, colour arriving at ``it.p``) per the class docstring; ``sample`` is unused."""
        d = self.position - it.p
        dist = dr.sqrt((d.x * d.x + d.y * d.y) + d.z * d.z)
        ds = light_sample(self, it, mi.Point3f(self.position), d, dist, delta=True)
        return ds, dr.select(active, attenuation(self.color, self.falloff, dist), 0.0)

    def pdf_direction(self, it: mi.Interaction3f, ds: mi.DirectionSample3f, active: mi.Bool = True) -> mi.Float:
        """0: a delta light cannot be sampled by direction."""
        return dr.zeros(mi.Float, dr.width(ds.d))

    def eval_direction(self, it: mi.Interaction3f, ds: mi.DirectionSample3f, active: mi.Bool = True) -> mi.Color3f:
        """color / (1 + falloff · ds.dist²), as for ``sample_direction``."""
        return dr.select(active, attenuation(self.color, self.falloff, ds.dist), 0.0)

    def eval(self, si: mi.SurfaceInteraction3f, active: mi.Bool = True) -> mi.Color3f:
        """0: a point light is never hit by a ray."""
        return dr.zeros(mi.Color3f, dr.width(si.p))

    def sample_position(
        self, time: mi.Float, sample: mi.Point2f, active: mi.Bool = True
    ) -> tuple[mi.PositionSample3f, mi.Float]:
        """The light's position (pdf 1, delta), weight 1."""
        ps = dr.zeros(mi.PositionSample3f, dr.width(sample))
        ps.p = mi.Point3f(self.position)
        ps.time = time
        ps.pdf = mi.Float(1.0)
        ps.delta = mi.Bool(True)
        return ps, dr.full(mi.Float, 1.0, dr.width(sample))

    def pdf_position(self, ps: mi.PositionSample3f, active: mi.Bool = True) -> mi.Float:
        return dr.zeros(mi.Float, dr.width(ps.p))

    def sample_ray(
        self, time: mi.Float, sample1: mi.Float, sample2: mi.Point2f, sample3: mi.Point2f, active: mi.Bool = True
    ) -> tuple[mi.Ray3f, mi.Color3f]:
        """A ray leaving the light uniformly over the sphere; weight = 4π·color (the light's power)."""
        d = mi.warp.square_to_uniform_sphere(sample3)
        ray = mi.Ray3f(mi.Point3f(self.position), d, time)
        return ray, dr.select(active, 4.0 * dr.pi * self.color, 0.0)

    def sample_wavelengths(
        self, si: mi.SurfaceInteraction3f, sample: mi.Float, active: mi.Bool = True
    ) -> tuple[mi.Color0f, mi.Color3f]:
        """RGB rendering (a5mi's variants) has no wavelengths to sample: (none, ``color``), as Mitsuba's ``point``
        answers with an RGB intensity. Mitsuba's own integrators (``ptracer``) call it on every emitter alive in
        the process, a5mi's included."""
        return dr.zeros(mi.Color0f), dr.select(active, mi.Color3f(self.color), 0.0)

    def bbox(self) -> mi.ScalarBoundingBox3f:
        p = mi.ScalarPoint3f(*(float(dr.slice(c, 0)) for c in self.position))
        return mi.ScalarBoundingBox3f(p)

    def traverse(self, cb: mi.TraversalCallback) -> None:
        put_params(cb, self, ("position", "color", "falloff"), differentiable=("color",))

    def parameters_changed(self, keys: list[str]) -> None:
        self._make_opaque()

    def to_string(self) -> str:
        return f"A5PointLight[position={self.position}, color={self.color}, falloff={self.falloff}]"


def register() -> None:
    """Register ``a5_point`` with Mitsuba (call after selecting a JIT variant)."""
    mi.register_emitter("a5_point", lambda props: A5PointLight(props))

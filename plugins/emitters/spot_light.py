"""The ``a5_spot`` emitter: a PointLight inside a cone (docs/EXTENSIONS.md E.1).

Arriving colour at ``p`` (``L = normalize(position - p)``, ``d = |position - p|``, ``θ`` the angle between
``-L`` and the unit axis ``direction``)::

    colour = color · profile(θ) / (1 + falloff d²)
    profile(θ) = 1                                    θ <= beamWidth
               = (angle - θ) / (angle - beamWidth)    beamWidth < θ < angle   (linear in the angle)
               = 0                                    θ >= angle

the law of Mitsuba's stock ``spot`` (``cutoff_angle = angle``, ``beam_width = beamWidth``), so the stock
conversion differs only by the a5 attenuation (no inverse-square law), as for ``a5_point``.
"""

from __future__ import annotations

import math

import drjit as dr
import mitsuba as mi

from a5mi.plugins.emitters.point_light import A5PointLight, _vec3_param, attenuation


def profile(cos_theta: mi.Float, angle_rad: mi.Float, beam_rad: mi.Float) -> mi.Float:
    """The cone profile of the module docstring for ``cos θ`` (angles in radians)."""
    theta = dr.acos(dr.clip(cos_theta, -1.0, 1.0))
    ramp = (angle_rad - theta) / dr.maximum(angle_rad - beam_rad, 1e-12)
    return dr.select(theta <= beam_rad, 1.0, dr.select(theta < angle_rad, ramp, 0.0))


class A5SpotLight(A5PointLight):
    """``a5_spot``: ``position`` point, ``direction`` vector (the axis), ``color`` rgb, ``falloff`` float (0),
    ``angle`` float (degrees, cut-off from the axis, 20), ``beam_width`` float (degrees, ``3/4 angle``)."""

    def __init__(self, props: mi.Properties) -> None:
        super().__init__(props)
        axis = _vec3_param(props, "direction", (0.0, 0.0, -1.0))
        norm = math.sqrt(sum(c * c for c in axis))
        angle = float(props.get("angle", 20.0))
        beam = float(props.get("beam_width", 0.75 * angle))
        if norm == 0.0 or not 0.0 < beam <= angle < 90.0:
            raise ValueError(f"a5_spot: need a non-zero direction and 0 < beam_width <= angle < 90, got "
                             f"{axis}, {beam}, {angle}")
        self.axis = mi.Vector3f(*(c / norm for c in axis))
        self.angle_rad = mi.Float(math.radians(angle))
        self.beam_rad = mi.Float(math.radians(beam))
        dr.make_opaque(self.axis, self.angle_rad, self.beam_rad)

    def sample_direction(
        self, it: mi.Interaction3f, sample: mi.Point2f, active: mi.Bool = True
    ) -> tuple[mi.DirectionSample3f, mi.Color3f]:
        """The point light's sample times :func:`profile` of ``-ds.d`` against the axis."""
        ds, value = super().sample_direction(it, sample, active)
        return ds, value * profile(dr.dot(-ds.d, self.axis), self.angle_rad, self.beam_rad)

    def eval_direction(self, it: mi.Interaction3f, ds: mi.DirectionSample3f, active: mi.Bool = True) -> mi.Color3f:
        value = dr.select(active, attenuation(self.color, self.falloff, ds.dist), 0.0)
        return value * profile(dr.dot(-ds.d, self.axis), self.angle_rad, self.beam_rad)

    def traverse(self, cb: mi.TraversalCallback) -> None:
        """The point light's parameters plus ``axis``, the unit cone axis (docs/EXTENSIONS.md E.11: keyframed
        ``direction`` d arrives as ``d / |d|``, computed as in the constructor)."""
        super().traverse(cb)
        cb.put("axis", self.axis, mi.ParamFlags.NonDifferentiable)

    def parameters_changed(self, keys: list[str]) -> None:
        super().parameters_changed(keys)
        dr.make_opaque(self.axis)

    def to_string(self) -> str:
        return f"A5SpotLight[position={self.position}, axis={self.axis}, angle={self.angle_rad} rad]"


def register() -> None:
    """Register ``a5_spot`` with Mitsuba (call after selecting a JIT variant)."""
    mi.register_emitter("a5_spot", lambda props: A5SpotLight(props))

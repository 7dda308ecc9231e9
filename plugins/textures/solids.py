"""The ``a5_solid`` procedural textures: wood, turbulence, veins (docs/EXTENSIONS.md E.6).

Solid textures on the marble's improved noise (:mod:`a5mi.plugins.textures.perlin`, SPEC B.4): the same ``noise``, the
same octave points, the same double precision. The marble (``a5_marble``) is untouched. With p = ``si.p`` the
world-space hit point, ``â`` the unit ``axis``, ``s`` = ``scale``::

    N(x) = Σ_{i<octaves} noise(2^i x) / 2^i          (perlin.octave_noise, the marble's sum)
    T(x) = Σ_{i<octaves} |noise(2^i x)| / 2^i        (perlin.turbulence)

    wood:        r = |q − (q·â) â|, q = p − center     M = sin(frequency · r + amplitude · N(s p))
    turbulence:                                          t = clamp(amplitude · T(s p), 0, 1)
    veins:       x = p·â                                 M = sin(frequency · x + amplitude · T(s p))

    t  = clamp(0.5 M + 0.5, 0, 1) (wood, veins);  kd = t · color1 + (1 − t) · color2

Precision: ``s p``, ``q``, ``r``, ``x`` and ``frequency · r`` (or ``· x``) are float32; N, T and the sine's argument
double; t is rounded to float32, as in the marble.
"""

from __future__ import annotations

import math
from functools import partial

import drjit as dr
import mitsuba as mi

from a5mi.plugins.params import vec3_param
from a5mi.plugins.textures.marble import BlendTexture
from a5mi.plugins.textures.perlin import octave_noise, turbulence

#: The kinds of ``a5_solid`` (the scene blocks ``Wood``, ``Turbulence``, ``Veins``).
KINDS: tuple[str, ...] = ("wood", "turbulence", "veins")


#: A 3-number parameter of ``a5_solid`` (:func:`a5mi.plugins.params.vec3_param`).
_vec3 = partial(vec3_param, "a5_solid")


class A5Solid(BlendTexture):
    """Procedural solid texture (docs/EXTENSIONS.md E.6; formulas in the module docstring).

    ============ ======== =========== =====================================================
    parameter    type     default     meaning
    ============ ======== =========== =====================================================
    kind         string   (required)  ``wood``, ``turbulence`` or ``veins``
    color1       rgb      0, 0, 0     colour at t = 1
    color2       rgb      0, 0, 0     colour at t = 0
    octaves      int      4           improved-noise octaves, 0..31
    frequency    float    1           rings per 2π world units (wood), stripes (veins)
    amplitude    float    1           weight of N (wood) or T (veins, turbulence)
    scale        float    1           the noise is evaluated at ``scale · p``
    axis         vector   0, 1, 0     wood: the rings' axis; veins: the stripes' direction
    center       point    0, 0, 0     wood: a point of the rings' axis
    ============ ======== =========== =====================================================

    ``kind`` is baked into the kernel (one kernel per kind); every other value is opaque.

    .. code-block:: python

        'kd': {'type': 'a5_solid', 'kind': 'wood', 'color1': {'type': 'rgb', 'value': [0.6, 0.4, 0.2]},
               'color2': {'type': 'rgb', 'value': [0.3, 0.15, 0.05]}, 'frequency': 20.0, 'amplitude': 1.0}
    """

    #: The ``traverse`` names, all non-differentiable.
    PARAMS = ("color1", "color2", "octaves", "frequency", "amplitude", "scale", "axis", "center")

    def __init__(self, props: mi.Properties) -> None:
        super().__init__(props)
        kind = props.get("kind", "")
        if kind not in KINDS:
            raise ValueError(f"a5_solid: parameter 'kind' must be one of {', '.join(KINDS)}, got {kind!r}")
        octaves = props.get("octaves", 4)
        if isinstance(octaves, bool) or not isinstance(octaves, int) or not 0 <= octaves <= 31:
            raise ValueError(f"a5_solid: parameter 'octaves' must be an integer in 0..31, got {octaves!r}")
        axis = _vec3(props, "axis", (0.0, 1.0, 0.0))
        length = math.sqrt(sum(c * c for c in axis))
        if length == 0.0:
            raise ValueError("a5_solid: parameter 'axis' must not be the zero vector")
        self.kind: str = kind
        self.color1 = mi.Color3f(*_vec3(props, "color1", (0.0, 0.0, 0.0)))
        self.color2 = mi.Color3f(*_vec3(props, "color2", (0.0, 0.0, 0.0)))
        self.octaves = mi.UInt32(octaves)
        self.frequency = mi.Float(float(props.get("frequency", 1.0)))
        self.amplitude = mi.Float(float(props.get("amplitude", 1.0)))
        self.scale = mi.Float(float(props.get("scale", 1.0)))
        self.axis = mi.Vector3f(*(c / length for c in axis))
        self.center = mi.Point3f(*_vec3(props, "center", (0.0, 0.0, 0.0)))
        self._make_opaque()

    def _make_opaque(self) -> None:
        dr.make_opaque(self.color1, self.color2, self.octaves, self.frequency, self.amplitude, self.scale,
                       self.axis, self.center)

    def blend(self, p: mi.Point3f) -> mi.Float:
        """t at the world-space point ``p`` (module docstring), as float32. Where the formula is not finite
        (``scale · p`` or ``frequency · x`` overflowing float32: the noise of an infinitely far point is
        undefined) t is ½, the mean of ``½ sin + ½``, so the image stays finite."""
        sp = p * self.scale
        if self.kind == "turbulence":
            t = mi.Float(dr.clip(mi.Float64(self.amplitude) * turbulence(sp, self.octaves), 0.0, 1.0))
            return dr.select(dr.isfinite(t), t, 0.5)
        if self.kind == "wood":
            q = p - self.center
            radial = q - dr.dot(q, self.axis) * self.axis
            x = dr.norm(radial)
            n = octave_noise(sp, self.octaves)
        else:  # veins
            x = dr.dot(p, self.axis)
            n = turbulence(sp, self.octaves)
        arg = mi.Float64(self.frequency * x) + mi.Float64(self.amplitude) * n
        t = mi.Float(dr.clip(0.5 * dr.sin(arg) + 0.5, 0.0, 1.0))
        return dr.select(dr.isfinite(t), t, 0.5)


    def to_string(self) -> str:
        return (f"A5Solid[kind={self.kind!r}, color1={self.color1}, color2={self.color2}, octaves={self.octaves}, "
                f"frequency={self.frequency}, amplitude={self.amplitude}, scale={self.scale}]")


def register() -> None:
    """Register ``a5_solid`` with Mitsuba (call after selecting a JIT variant)."""
    mi.register_texture("a5_solid", lambda props: A5Solid(props))

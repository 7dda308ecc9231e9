"""The ``a5_marble`` procedural texture: the sample solution's Noise material colour (SPEC B.4)."""

from __future__ import annotations

from collections.abc import Sequence

import drjit as dr
import mitsuba as mi

from a5mi.plugins.params import put_params
from a5mi.plugins.textures.perlin import octave_noise
from a5mi.render.options import MARBLE_MISTAKES


def _rgb_param(props: mi.Properties, name: str, default: Sequence[float]) -> mi.ScalarColor3f:
    """Read an ``rgb`` (or 3-number) parameter as a ScalarColor3f, naming the parameter on error."""
    if name not in props:
        return mi.ScalarColor3f(*default)
    value = props[name]
    try:
        r, g, b = (float(value[i]) for i in range(3))
    except (TypeError, IndexError, ValueError):
        raise ValueError(f"a5_marble: parameter '{name}' must be an rgb colour, got {value!r}") from None
    return mi.ScalarColor3f(r, g, b)


class BlendTexture(mi.Texture):
    """A texture kd = t·color1 + (1 − t)·color2 with t = ``blend(p)`` at the world-space point (SPEC B.4 for
    the marble, docs/EXTENSIONS.md E.6 for the solids). A subclass sets ``color1``, ``color2``, a ``blend``,
    ``_make_opaque`` (every value opaque) and ``PARAMS``/``DIFFERENTIABLE``, the ``traverse`` names."""

    PARAMS: tuple[str, ...] = ()
    DIFFERENTIABLE: tuple[str, ...] = ()
    color1: mi.Color3f
    color2: mi.Color3f

    def blend(self, p: mi.Point3f) -> mi.Float:
        """t in [0, 1] at the world-space point ``p``, as float32: each subclass's formula."""
        raise NotImplementedError(f"{type(self).__name__} defines no blend")

    def _make_opaque(self) -> None:
        """Make every parameter an opaque JIT value (one kernel serves every value)."""
        raise NotImplementedError(f"{type(self).__name__} defines no _make_opaque")

    def eval(self, si: mi.SurfaceInteraction3f, active: mi.Bool = True) -> mi.Color3f:
        """kd at ``si.p``."""
        return self.color_at(si.p)

    def color_at(self, p: mi.Point3f) -> mi.Color3f:
        """kd = t·color1 + (1 − t)·color2 at the world-space point ``p``."""
        t = self.blend(p)
        return t * self.color1 + (1.0 - t) * self.color2

    def eval_3(self, si: mi.SurfaceInteraction3f, active: mi.Bool = True) -> mi.Color3f:
        return self.eval(si, active)

    def eval_1(self, si: mi.SurfaceInteraction3f, active: mi.Bool = True) -> mi.Float:
        """Channel mean of kd (used by stock plugins that want a scalar texture)."""
        return dr.mean(self.eval(si, active))

    def mean(self) -> float:
        """(color1 + color2)/2 averaged over channels: exact for the marble (its t is symmetric about 1/2), an
        estimate for the solids."""
        return float(dr.mean(dr.mean(0.5 * (self.color1 + self.color2)))[0])

    def is_spatially_varying(self) -> bool:
        return True

    def traverse(self, cb: mi.TraversalCallback) -> None:
        put_params(cb, self, self.PARAMS, self.DIFFERENTIABLE)

    def parameters_changed(self, keys: list[str]) -> None:
        self._make_opaque()


class A5Marble(BlendTexture):
    """Marble texture of the 6.837 a5 sample solution (SPEC B.4, ``Noise`` block of A.5).

    .. list-table::
       :header-rows: 1

       * - Parameter
         - Type
         - Description
       * - ``color1``
         - rgb
         - First ``color`` line of the ``Noise`` block (Default: 0, 0, 0)
       * - ``color2``
         - rgb
         - Second ``color`` line (Default: 0, 0, 0)
       * - ``octaves``
         - int
         - Number of improved-noise octaves, ≥ 0; 0 gives N = 0 (Default: 0)
       * - ``frequency``
         - float
         - Frequency of the stripes along world x (Default: 1)
       * - ``amplitude``
         - float
         - Weight of the noise in the sine's phase (Default: 1)
       * - ``mistake``
         - string
         - docs/MISTAKES.md: render as a student with this mistake would: ``marble_no_octaves``
           (``N = 0``), ``marble_sine_unmapped`` (``t = clamp(M, 0, 1)``, the handout's wording),
           ``marble_freq_amp_swapped`` (``M = sin(amplitude · p.x + frequency · N)``); a compile-time
           choice (Default: none, SPEC B.4)

    With p = ``si.p``, the world-space hit point, unscaled::

        N  = Σ_{i<octaves} noise(2^i p) / 2^i          (improved noise, see a5mi.plugins.textures.perlin)
        M  = sin((double)(float)(frequency · p.x) + amplitude · N)
        t  = clamp(0.5 M + 0.5, 0, 1)
        kd = t · color1 + (1 − t) · color2

    Precision is the binary's: the frequency product is float32, N and the sine argument are double.
    The handout says "clamp M and interpolate with it"; the sample solution maps [−1, 1] to [0, 1] as
    above, which is what the reference images show, so that is the only behaviour offered.

    All parameters are opaque JIT values, so one compiled kernel serves every marble in every scene;
    ``traverse`` exposes them (``color1``, ``color2``, ``frequency``, ``amplitude``, ``octaves``).

    .. code-block:: python

        'kd': {
            'type': 'a5_marble',
            'color1': {'type': 'rgb', 'value': [0.9, 0.9, 0.9]},
            'color2': {'type': 'rgb', 'value': [0.2, 0.2, 0.5]},
            'octaves': 4, 'frequency': 5.0, 'amplitude': 2.0,
        }
    """

    #: The ``traverse`` names; the two colours are differentiable.
    PARAMS = ("color1", "color2", "frequency", "amplitude", "octaves")
    DIFFERENTIABLE = ("color1", "color2")

    def __init__(self, props: mi.Properties) -> None:
        super().__init__(props)
        c1 = _rgb_param(props, "color1", (0.0, 0.0, 0.0))
        c2 = _rgb_param(props, "color2", (0.0, 0.0, 0.0))
        octaves = props.get("octaves", 0)
        if isinstance(octaves, bool) or not isinstance(octaves, int) or octaves < 0:
            raise ValueError(f"a5_marble: parameter 'octaves' must be an integer >= 0, got {octaves!r}")
        frequency = float(props.get("frequency", 1.0))
        amplitude = float(props.get("amplitude", 1.0))
        self.color1 = mi.Color3f(c1)
        self.color2 = mi.Color3f(c2)
        self.octaves = mi.UInt32(octaves)
        self.frequency = mi.Float(frequency)
        self.amplitude = mi.Float(amplitude)
        self.mistake = str(props.get("mistake", ""))
        if self.mistake not in ("", *MARBLE_MISTAKES):
            raise ValueError(f"a5_marble: parameter 'mistake' must be one of {', '.join(MARBLE_MISTAKES)}, "
                             f"got {self.mistake!r}")
        self._make_opaque()

    def _make_opaque(self) -> None:
        dr.make_opaque(self.color1, self.color2, self.octaves, self.frequency, self.amplitude)

    def blend(self, p: mi.Point3f) -> mi.Float:
        """t = clamp(0.5·sin((double)(float)(frequency·p.x) + amplitude·N) + 0.5, 0, 1), as float32."""
        n = octave_noise(p, self.octaves)
        if self.mistake == "marble_no_octaves":          # a Python choice: the default kernel is unchanged
            n = dr.zeros(mi.Float64, dr.width(p))
        if self.mistake == "marble_freq_amp_swapped":
            arg = mi.Float64(p.x * self.amplitude) + mi.Float64(self.frequency) * n
        else:
            arg = mi.Float64(p.x * self.frequency) + mi.Float64(self.amplitude) * n
        if self.mistake == "marble_sine_unmapped":
            return mi.Float(dr.clip(dr.sin(arg), 0.0, 1.0))
        t = dr.clip(0.5 * dr.sin(arg) + 0.5, 0.0, 1.0)
        return mi.Float(t)

    def to_string(self) -> str:
        return (
            f"A5Marble[color1={self.color1}, color2={self.color2}, octaves={self.octaves}, "
            f"frequency={self.frequency}, amplitude={self.amplitude}, mistake='{self.mistake}']"
        )


def register() -> None:
    """Register ``a5_marble`` with Mitsuba (call after selecting a JIT variant)."""
    mi.register_texture("a5_marble", lambda props: A5Marble(props))

"""The kernel's inputs besides the rays: :class:`Features` (compile-time flags) and :class:`SceneData` (opaque values).

:func:`build_features` is the one place where an integrator's parameters and the scene decide which blocks a
kernel contains (SPEC B.3's options, docs/EXTENSIONS.md E.2, E.4, E.7-E.10, record mode). The kernel reads the
flags only as ``if dr.hint(features.x, mode='scalar'):`` (plain Python at trace time), so equal features mean
one compiled kernel for any number of scenes; everything a scene changes travels in :class:`SceneData`, whose
values are ``dr.opaque`` (a literal would be baked into the kernel and force a recompile per scene).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, NamedTuple, Protocol

import mitsuba as mi

from a5mi.plugins.kernel import pbr_gather
from a5mi.plugins.kernel.scene import Lights, has_area_lights
from a5mi.plugins.materials.milled import uses_milled
from a5mi.render.options import KERNEL_MISTAKES

if TYPE_CHECKING:
    from a5mi.plugins.emulation.planes import PlaneSet
    from a5mi.plugins.emulation.triangle_rule import RuleTable
    from a5mi.plugins.media.medium import MediumParams


class Features(NamedTuple):
    """Which blocks a kernel contains; every field is a Python value baked into the compiled kernel. Immutable
    (a NamedTuple, not a frozen dataclass: Dr.Jit's symbolic loops carry every value read in a loop as state and
    write dataclass fields back, which a frozen dataclass refuses; a tuple is rebuilt instead).

    ============== ======== ===================================================================
    field          type     the block
    ============== ======== ===================================================================
    shadows        bool     shadow rays of the light loop (SPEC B.3 ``S``)
    phong          bool     the handout's highlight ``clamp(L·R)^shininess lightColor ⊙ ks``
    fresnel        str      Fresnel mode of refracting hits: ``a5`` | ``schlick`` | ``exact``
    reflection     bool     mirror children (``-reflection_off``: false)
    refraction     bool     refracted children (``-refraction_off``: false)
    area_lights    bool     E.2: stratified light samples, the emission of a light seen directly
    glossy         bool     E.4: sampled GGX facets of materials with roughness > 0
    bump           bool     E.7: the bump / normal-mapped shading normal
    media          bool     E.8, E.9: transmittance and in-scattering of segments in air
    media_light    bool     E.8, E.9 with ``medium_bounces >= 1`` and shadows: shadow rays carry T_light
    dispersion     bool     E.10: a wavelength per lane, Cauchy n(λ), the w(λ) weight
    subsurface     str      E.18: ``none`` | ``dipole`` | ``walk``: light under materials with ``sss_*``
    milled         bool     E.20: the Ward lobe of ``a5_milled`` BSDFs in the light loop
    environment    bool     the scene has an environment emitter (else misses are black)
    triangle_rule  bool     some mesh carries the binary's triangle data (plugins/emulation/triangle_rule.py)
    record         bool     record mode: the ray tree's values are scattered into a recorder
    ray_log        bool     ray-log mode: every node ray and shadow ray cast is written to a
                            :class:`~.raylog.RayLog` (``a5mi bench``'s traversal floor)
    indirect       int      E.15: cosine-weighted rays gathered at each diffuse hit (0: none)
    two_sided      bool     E.15: the light loop's ``clamp(L·N)`` with N turned toward the ray (both faces lit)
    stale_uv       bool     ``-quirks binary``: some plane-set entry has a textured BSDF (``plane_<id>_bsdf_uv``)
                            and a rule mesh exists: the sample solution's stale uv (docs/FIDELITY.md)
    stack_size     int      entries of the pending-ray stack (:func:`stack_size`)
    mistakes       tuple    docs/MISTAKES.md: names of :data:`KERNEL_MISTAKES` compiled in (sorted; empty:
                            SPEC B.3 exactly, the default kernel's IR unchanged)
    ============== ======== ===================================================================
    """

    shadows: bool = False
    phong: bool = False
    fresnel: str = "a5"
    reflection: bool = True
    refraction: bool = True
    area_lights: bool = False
    glossy: bool = False
    bump: bool = False
    media: bool = False
    media_light: bool = False
    dispersion: bool = False
    subsurface: str = "none"
    milled: bool = False
    environment: bool = False
    triangle_rule: bool = False
    record: bool = False
    stack_size: int = 8
    indirect: int = 0
    two_sided: bool = False
    stale_uv: bool = False
    ray_log: bool = False
    mistakes: tuple[str, ...] = ()


def depth_budget(max_depth: int, mistakes: tuple[str, ...] = ()) -> int:
    """The bounce budget the kernel runs with (SPEC B.3 ``bounces``): ``max_depth``, or with docs/MISTAKES.md's
    ``bounces_plus_one`` ``max_depth + 1``, ``bounces_minus_one`` ``max(max_depth - 1, 0)``, ``no_recursion`` 0."""
    if "no_recursion" in mistakes:
        return 0
    if "bounces_plus_one" in mistakes:
        max_depth += 1
    if "bounces_minus_one" in mistakes:
        max_depth -= 1
    return max(max_depth, 0)


class SceneData(NamedTuple):
    """The per-scene values of a kernel call, all opaque: ``max_depth`` (bounce budget), ``ambient``, ``tmin``
    (of secondary and shadow rays), the :class:`~.lights.Lights`, the planes (plugins/emulation/planes.py), the
    triangle-rule table (None: no rule mesh) and the medium (None: no medium)."""

    max_depth: mi.UInt32
    ambient: mi.Color3f
    tmin: mi.Float
    lights: Lights
    planes: PlaneSet
    rules: RuleTable | None
    medium: MediumParams | None


__all__ = ["KERNEL_MISTAKES", "FeatureSource", "Features", "SceneData", "build_features", "depth_budget",
           "stack_size"]


class FeatureSource(Protocol):
    """What :func:`build_features` reads from an integrator: its checked parameters."""

    shadows: bool
    phong: bool
    fresnel: str
    reflection: bool
    refraction: bool
    glossy: bool
    bump: bool
    dispersion: bool
    max_depth: int
    glossy_samples: int
    indirect: int
    subsurface: str
    two_sided: bool
    mistakes: tuple[str, ...]
    planes: list[Any]

    @property
    def stack_depth(self) -> int:
        """The bounce budget the pending-ray stack holds (``max_depth``; one more for a tree whose last level
        is traced past the budget, as ``a5_irradiancecache``'s camera tree)."""


def stack_size(max_depth: int, glossy_samples: int = 1) -> int:
    """Pending-ray stack entries for a bounce budget: depth-first, pop one / push two, so ``max_depth + 1``;
    a glossy camera hit pushes ``2 G`` children (docs/EXTENSIONS.md E.4), so ``max_depth + 2 G - 1``.

    Rounded up to at least 8, so every budget from 0 to 7 shares one compiled kernel.
    """
    return max(8, max_depth + 2 * glossy_samples - 1)


def build_features(source: FeatureSource, scene: mi.Scene, data: SceneData, record: bool = False,
                   ray_log: bool = False) -> Features:
    """The :class:`Features` of a kernel call: the integrator's flags, what ``scene`` holds (area lights, an
    environment) and what ``data`` carries (a triangle-rule table, a medium); the stack holds
    ``source.stack_depth`` bounces (:func:`stack_size`, with docs/MISTAKES.md's :func:`depth_budget`; with
    E.15's ``indirect`` gathered rays :func:`.pbr_gather.stack_size`); ``record`` and ``ray_log``: the call
    hands a recorder / a ray log to the kernel."""
    indirect = int(source.indirect)
    mistakes = tuple(sorted(source.mistakes))
    size = stack_size(depth_budget(source.stack_depth, mistakes), source.glossy_samples)
    if indirect > 0:
        size = pbr_gather.stack_size(source.stack_depth, source.glossy_samples, indirect)
    return Features(
        shadows=source.shadows and "no_shadows" not in mistakes,
        phong=source.phong or "phong_highlight" in mistakes, fresnel=source.fresnel, reflection=source.reflection,
        refraction=source.refraction, area_lights=has_area_lights(scene), glossy=source.glossy,
        bump=source.bump, media=data.medium is not None,
        media_light=data.medium is not None and data.medium.bounces > 0 and source.shadows,
        dispersion=source.dispersion, subsurface=source.subsurface,
        milled=uses_milled(scene, [p[3] for p in source.planes]),
        environment=scene.environment() is not None, triangle_rule=data.rules is not None, record=record,
        stack_size=size, indirect=indirect, two_sided=source.two_sided,
        stale_uv=data.planes.bsdf_uv is not None and data.rules is not None, ray_log=ray_log,
        mistakes=tuple(m for m in mistakes if m not in ("no_shadows", "phong_highlight", "bounces_plus_one",
                                                         "bounces_minus_one", "no_recursion")),
    )

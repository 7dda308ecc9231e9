"""The material at a hit, through the vcall-able BSDF attribute interface (SPEC A.5, B.3), and the background.

Any BSDF works: ``a5_material`` answers ``diffuse_color``, ``specular_color``, ``refraction_index``,
``shininess``, ``roughness``, ``glossy_samples``, ``cauchy_b`` and ``shading_normal``; a BSDF without them
(``has_attribute("diffuse_color")`` false) shades as diffuse only with ``kd = eval_diffuse_reflectance``
(SPEC B.3: ``ambient ⊙ diffuseColor`` uses the raw diffuseColor, the light loop ``kd``). Only the attributes a
kernel's :class:`~.features.Features` need are read: ``shininess`` with ``phong``, ``roughness`` and
``glossy_samples`` with ``glossy`` (E.4), ``cauchy_b`` with ``dispersion`` (E.10), ``shading_normal`` with
``bump`` (E.7).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, NamedTuple

import drjit as dr
import mitsuba as mi

from a5mi.plugins.materials import spectral
from a5mi.plugins.materials.bump import shading_normal

if TYPE_CHECKING:
    from a5mi.plugins.kernel.features import Features


class Surface(NamedTuple):
    """The material values of a hit (module docstring): ``a5`` (an a5 material), ``kd``, ``diffuse_color``,
    ``specular``, ``ior`` (n(λ) with dispersion), ``dispersive`` (None without dispersion), ``shininess``,
    ``n`` (the shading normal: bumped with ``bump``), ``alpha`` (GGX roughness, 0 without ``glossy``) and
    ``n_gloss`` (glossy children of a camera hit, capped)."""

    a5: mi.Bool
    kd: mi.Color3f
    diffuse_color: mi.Color3f
    specular: mi.Color3f
    ior: mi.Float
    dispersive: mi.Bool | None
    shininess: mi.Float
    n: mi.Vector3f
    alpha: mi.Float
    n_gloss: mi.UInt32


def surface_at(bsdf: mi.BSDFPtr, si: mi.SurfaceInteraction3f, hit: mi.Bool, n: mi.Vector3f, f: Features,
               lam: mi.Float | None, glossy_cap: mi.UInt32) -> Surface:
    """The :class:`Surface` of the hit ``si`` on ``bsdf`` (lanes ``hit``, shading normal ``n``, the
    :class:`~.intersect.Hit` fields); ``lam``: the lane's wavelength (E.10), ``glossy_cap``: the integrator's cap
    on glossy children (E.4)."""
    a5 = bsdf.has_attribute("diffuse_color", hit) & hit
    kd = mi.Color3f(bsdf.eval_diffuse_reflectance(si, hit))
    diffuse_color = dr.select(a5, bsdf.eval_attribute_3("diffuse_color", si, a5), kd)
    specular = bsdf.eval_attribute_3("specular_color", si, a5)
    ior = bsdf.eval_attribute_1("refraction_index", si, a5)
    dispersive = None
    if dr.hint(f.dispersion, mode="scalar"):    # E.10: Cauchy's n(λ)
        ior, dispersive = spectral.index_at(bsdf, si, a5, ior, lam)
    shininess = mi.Float(0.0)
    if dr.hint(f.phong, mode="scalar"):
        shininess = bsdf.eval_attribute_1("shininess", si, a5)
    if dr.hint(f.bump, mode="scalar"):          # E.7: the bump / normal-mapped N for lights, mirror, refraction
        n = shading_normal(bsdf, si, n, a5)
    alpha, n_gloss = mi.Float(0.0), mi.UInt32(1)
    if dr.hint(f.glossy, mode="scalar"):        # E.4: roughness and the number of glossy children
        alpha = bsdf.eval_attribute_1("roughness", si, a5)
        n_gloss = dr.minimum(mi.UInt32(dr.maximum(bsdf.eval_attribute_1("glossy_samples", si, a5), 1.0)),
                             glossy_cap)
    return Surface(a5, kd, diffuse_color, specular, ior, dispersive, shininess, n, alpha, n_gloss)


def background(scene: mi.Scene, d: mi.Vector3f, miss: mi.Bool) -> mi.Color3f:
    """The environment emitter's colour for direction ``d`` on the lanes of ``miss`` (SPEC A.4: ``background(dir)``;
    call only when the scene has one, :attr:`Features.environment`)."""
    si_env = dr.zeros(mi.SurfaceInteraction3f, dr.width(d))
    si_env.wi = -d
    return mi.Color3f(scene.environment().eval(si_env, miss))

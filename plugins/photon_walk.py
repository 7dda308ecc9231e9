"""One scattering step of a photon or of a camera path at an a5 material (docs/EXTENSIONS.md E.16).

The a5 material is the sum ``kd·D + ks·M`` of SPEC B.3 read physically: ``D`` the Lambert lobe ``1/π``, ``M``
the perfect mirror (``|ks| > 0.001``) or, for ``refractionIndex > 0``, the dielectric whose reflected share
``R`` is the ``-fresnel`` mode's (plugins/common.py ``fresnel_weight``; total internal reflection ``R = 1``).

:func:`scatter` (photons): one of the lobes is chosen with ``p_D = max kd / s``, ``p_M = max ks / s``,
``s = max(max kd + max ks, 1)``, else the photon is absorbed (Russian roulette); the chosen lobe's direction
is sampled (``D``: cosine-weighted about the normal facing the photon; ``M``: the mirror direction, or for a
dielectric reflection with probability ``R`` and refraction with ``1 − R``) and the power is multiplied by
``kd / p_D`` or ``ks / p_M``, so its expectation is the material's albedo times the power.

:func:`specular_step` (camera paths): the ``M`` lobe alone, weight ``ks`` (reflection or refraction by ``R``).
"""

from __future__ import annotations

from typing import NamedTuple

import drjit as dr
import mitsuba as mi

from a5mi.spec import MIRROR_THRESHOLD

from .common import fresnel_weight, reflect, snell


class Step(NamedTuple):
    """A scattered direction ``d``, the weight ``factor`` (rgb), ``alive`` (not absorbed), ``diffuse`` (the
    Lambert lobe was chosen)."""

    d: mi.Vector3f
    factor: mi.Color3f
    alive: mi.Bool
    diffuse: mi.Bool


def facing(d: mi.Vector3f, n: mi.Vector3f) -> mi.Vector3f:
    """The normal ``n`` turned to face a ray of direction ``d`` (``d·n_f <= 0``)."""
    return dr.select(dr.dot(d, n) < 0.0, n, -n)


def has_mirror(ks: mi.Color3f, ior: mi.Float) -> mi.Bool:
    """Whether the material has the ``M`` lobe (SPEC B.3: a mirror child when ``|ks| > 0.001``, a refracted
    one when ``refractionIndex > 0``)."""
    return (dr.norm(ks) > MIRROR_THRESHOLD) | (ior > 0.0)


def mirror_direction(fresnel: str, d: mi.Vector3f, n: mi.Vector3f, ior: mi.Float, u: mi.Float,
                     refraction: bool = True) -> mi.Vector3f:
    """The ``M`` lobe's direction for the incoming ``d`` at normal ``n`` (any side): the mirror direction, or
    for ``ior > 0`` (and ``refraction``) the refracted one with probability ``1 − R`` (``u`` uniform)."""
    n_f = facing(d, n)
    mirror = dr.normalize(reflect(d, n_f))
    if not refraction:
        return mirror
    inside = dr.dot(d, n) > 0.0
    n_medium = dr.select(inside, ior, 1.0)
    nt = dr.select(inside, 1.0, ior)
    t, exists = snell(d, n_f, n_medium, nt)
    glass = (ior > 0.0) & exists
    r = dr.select(glass, fresnel_weight(fresnel, d, n_f, t, n_medium, nt), 1.0)
    return dr.select(glass & (u >= r), t, mirror)


def scatter(fresnel: str, d: mi.Vector3f, n: mi.Vector3f, kd: mi.Color3f, ks: mi.Color3f, ior: mi.Float,
            u_lobe: mi.Float, u_fresnel: mi.Float, u_dir: mi.Point2f, refraction: bool = True) -> Step:
    """A photon's step at the material ``(kd, ks, ior)`` (module docstring)."""
    pd = dr.max(kd)
    pm = dr.select(has_mirror(ks, ior), dr.max(ks), 0.0)
    s = dr.maximum(pd + pm, 1.0)
    pd, pm = pd / s, pm / s
    diffuse = u_lobe < pd
    mirror = ~diffuse & (u_lobe < pd + pm)
    n_f = facing(d, n)
    d_diffuse = mi.Frame3f(n_f).to_world(mi.warp.square_to_cosine_hemisphere(u_dir))
    d_mirror = mirror_direction(fresnel, d, n, ior, u_fresnel, refraction)
    factor = dr.select(diffuse, kd / dr.maximum(pd, 1e-12), ks / dr.maximum(pm, 1e-12))
    return Step(dr.select(diffuse, d_diffuse, d_mirror), factor, diffuse | mirror, diffuse)


def specular_step(fresnel: str, d: mi.Vector3f, n: mi.Vector3f, ks: mi.Color3f, ior: mi.Float, u: mi.Float,
                  refraction: bool = True) -> Step:
    """A camera path's step through the ``M`` lobe (weight ``ks``); ``alive`` where the lobe exists."""
    alive = has_mirror(ks, ior)
    return Step(mirror_direction(fresnel, d, n, ior, u, refraction), ks, alive, dr.zeros(mi.Bool, dr.width(d)))

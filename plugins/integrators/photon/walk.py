"""One scattering step of a photon or of a camera path, by the physically based reading of the a5 Material
(plugins/kernel/pbr.py, docs/EXTENSIONS.md E.13; used here as E.16 says).

:func:`photon_step`: :func:`.kernel.pbr.sample` picks a lobe (Lambert, mirror ``ks R``, refraction
``ks (1 − R)``) with probabilities ``p`` proportional to their mean weights and returns the weight
``w = lobe weight / p``. Photons carry flux, not radiance, so the refraction's radiance factor ``(n/nt)²``
(E.13) is divided out again: ``w_flux = w (nt/n)²`` on refracted lanes. Russian roulette then keeps the photon
with ``q = min(q_max, max w_flux)`` and divides by ``q`` (Jensen 2001, 5.2): a Lambert bounce on ``kd``
survives with ``max kd`` at unchanged power, so the expected power after a hit is the material's albedo times it
(``E[alive · w/q] = w`` for any ``q > 0``: unbiased). ``q_max`` is 1 for a photon's first bounces and below 1
after them (plugins/integrators/photon/trace.py), so that a path of lossless bounces (a white room, facing mirrors) ends
with probability 1.

:func:`camera_step`: a camera path's step through the delta lobes alone (the Lambert part of the hit is
estimated from the photon maps there): the same sampling with ``kd`` set to 0, radiance weights (E.13's
``(n/nt)²`` kept).
"""

from __future__ import annotations

from typing import NamedTuple

import drjit as dr
import mitsuba as mi

from a5mi.plugins.kernel import pbr


class Step(NamedTuple):
    """A scattered direction ``d``, the weight ``factor`` (rgb), ``alive`` (not absorbed), ``diffuse`` (the
    Lambert lobe was chosen), ``n_medium`` (the index the new ray travels in)."""

    d: mi.Vector3f
    factor: mi.Color3f
    alive: mi.Bool
    diffuse: mi.Bool
    n_medium: mi.Float


def facing(d: mi.Vector3f, n: mi.Vector3f) -> mi.Vector3f:
    """The normal ``n`` turned to face a ray of direction ``d`` (``d·n_f <= 0``)."""
    return dr.select(dr.dot(d, n) < 0.0, n, -n)


def photon_step(fresnel: str, d: mi.Vector3f, n: mi.Vector3f, n_mirror: mi.Vector3f, kd: mi.Color3f,
                ks: mi.Color3f, ior: mi.Float, n_medium: mi.Float, hit: mi.Bool, u_lobe: mi.Float,
                u_dir: mi.Point2f, u_rr: mi.Float, refraction: bool = True, reflection: bool = True,
                q_max: float = 1.0) -> Step:
    """A photon's step (module docstring) at a hit with shading normal ``n``, delta-lobe normal ``n_mirror``
    and material ``(kd, ks, ior)``, travelling in the index ``n_medium``; survival ``q = min(q_max, max w)``."""
    b = pbr.lobes(fresnel, kd, ks, ior, d, n, n_mirror, n_medium, hit, refraction, reflection)
    s = pbr.sample(b, n_medium, u_lobe, u_dir, hit)
    refracted = s.valid & s.delta & (s.n_medium != n_medium)
    ratio = s.n_medium / n_medium
    w = dr.select(refracted, s.weight * (ratio * ratio), s.weight)
    q = dr.minimum(dr.max(w), q_max)
    alive = s.valid & (u_rr < q)
    return Step(s.wo, w / dr.maximum(q, 1e-30), alive, alive & ~s.delta, s.n_medium)


def camera_step(fresnel: str, d: mi.Vector3f, n: mi.Vector3f, n_mirror: mi.Vector3f, ks: mi.Color3f,
                ior: mi.Float, n_medium: mi.Float, hit: mi.Bool, u_lobe: mi.Float, refraction: bool = True,
                reflection: bool = True) -> Step:
    """A camera path's step through the delta lobes (module docstring); ``alive`` where one exists."""
    zero = dr.zeros(mi.Color3f, dr.width(d))
    b = pbr.lobes(fresnel, zero, ks, ior, d, n, n_mirror, n_medium, hit, refraction, reflection)
    s = pbr.sample(b, n_medium, u_lobe, mi.Point2f(0.5), hit)
    alive = s.valid & s.delta
    return Step(s.wo, s.weight, alive, dr.zeros(mi.Bool, dr.width(d)), s.n_medium)

"""Shared Dr.Jit helpers for the a5 shading rules (SPEC B.3): mirror direction, Snell, Fresnel weights.

Pure functions on Dr.Jit arrays of the active variant (no plugin state), used by ``whitted.py`` and
``a5_material.py``. Names follow ARCHITECTURE.md: ``n`` is the (possibly flipped) normal, ``n_medium`` the
index of the current medium, ``nt`` the index on the far side, ``r_fresnel`` the SPEC's ``R``.
"""

from __future__ import annotations

import drjit as dr
import mitsuba as mi

from a5mi.spec import FRESNEL_MODES


def dot32(a: mi.Vector3f, b: mi.Vector3f) -> mi.Float:
    """vecmath ``Vector3f::dot`` as the binary computes it: ``(a_x b_x + a_y b_y) + a_z b_z`` in float32,
    without the fused multiply-adds of ``dr.dot``."""
    return (a.x * b.x + a.y * b.y) + a.z * b.z


def reflect(d: mi.Vector3f, n: mi.Vector3f) -> mi.Vector3f:
    """Mirror direction (SPEC B.3): ``d - 2 (d·N) N``, per component ``d_k − N_k (2 (d·N))`` with the
    binary's :func:`dot32` (``mirrorDirection``; not renormalised). Unchanged when N is negated."""
    return d - 2.0 * dot32(d, n) * n


def snell(
    d: mi.Vector3f, n: mi.Vector3f, n_medium: mi.Float, nt: mi.Float
) -> tuple[mi.Vector3f, mi.Bool]:
    """Refracted direction by Snell's law, as the sample solution computes it (SPEC B.3 notes).

    ``T = (n/nt)(d - N(d·N)) - N sqrt(1 - (n/nt)² (1 - (d·N)²))``, normalised; ``N`` must face the incoming
    ray (``d·N <= 0``). Returns ``(T, exists)``; ``exists`` is False (and T is zero) under total internal
    reflection, i.e. when the square-root argument is negative.
    """
    eta = n_medium / nt
    d_dot_n = dr.dot(d, n)
    radicand = 1.0 - eta * eta * (1.0 - d_dot_n * d_dot_n)
    exists = radicand >= 0.0
    t = eta * (d - n * d_dot_n) - n * dr.safe_sqrt(radicand)
    t = dr.select(exists, dr.normalize(t), mi.Vector3f(0.0))
    return t, exists


def schlick(c: mi.Float, r0: mi.Float) -> mi.Float:
    """Schlick's approximation (SPEC B.3): ``R = R0 + (1 - R0)(1 - c)^5``."""
    m = 1.0 - c
    m2 = m * m
    return r0 + (1.0 - r0) * (m2 * m2 * m)


def r0_a5(nt: mi.Float) -> mi.Float:
    """The sample solution's R0 (SPEC B.3, "the binary uses 1 in place of n"): ``((nt - 1)/(nt + 1))²``."""
    q = (nt - 1.0) / (nt + 1.0)
    return q * q


def r0_schlick(n_medium: mi.Float, nt: mi.Float) -> mi.Float:
    """The textbook R0: ``((nt - n)/(nt + n))²``."""
    q = (nt - n_medium) / (nt + n_medium)
    return q * q


def fresnel_weight(
    mode: str, d: mi.Vector3f, n: mi.Vector3f, t: mi.Vector3f, n_medium: mi.Float, nt: mi.Float
) -> mi.Float:
    """Reflected fraction ``R`` of a refracting hit (SPEC B.3); the transmitted fraction is ``1 - R``.

    ``n`` faces the incoming ray and ``t`` is the refracted direction from :func:`snell` (call this only
    where it exists; total internal reflection is ``R = 1`` and is the caller's job).

    * ``a5`` (default, the binary): ``R0 = ((nt-1)/(nt+1))²``; ``schlick``: ``R0 = ((nt-n)/(nt+n))²``;
      both then ``c = |d·N|`` if ``nt > n`` else ``|T·N|`` and ``R = R0 + (1-R0)(1-c)^5``.
    * ``exact``: the unpolarised dielectric Fresnel term ``mi.fresnel(|d·N|, nt/n)`` (stock ``dielectric``).
    """
    if mode == "exact":
        f, _, _, _ = mi.fresnel(dr.abs(dr.dot(d, n)), nt / n_medium)
        return f
    if mode == "a5":
        r0 = r0_a5(nt)
    elif mode == "schlick":
        r0 = r0_schlick(n_medium, nt)
    else:
        raise ValueError(f"fresnel must be one of {', '.join(FRESNEL_MODES)}, not {mode!r}")
    c = dr.select(nt > n_medium, dr.abs(dr.dot(d, n)), dr.abs(dr.dot(t, n)))
    return schlick(c, r0)

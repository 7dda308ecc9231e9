"""The irradiance cache's formulas, in numpy (docs/EXTENSIONS.md E.23; Ward, Rubinstein, Clear 1988;
Ward, Heckbert 1992).

A *record* ``i`` holds, at a diffuse point ``p_i`` with normal ``n_i``, the indirect irradiance ``E_i``
(RGB), its validity radius ``R_i`` and the rotation and translation gradients ``∇r E_i``, ``∇t E_i`` (3 x RGB
each). Everything here is host-side numpy on arrays of records or query points; the rays are traced by
:mod:`plugins.irradiance_cache_kernel`.

Hemisphere sampling (stratified, cosine-weighted, ``M x N`` strata): sample ``(j, k)`` has
``sin²θ = (j + ξ1)/M`` and ``φ = 2π (k + ξ2)/N``, so each stratum holds an equal share ``π/(MN)`` of the
projected solid angle, and with ``L_jk`` the radiance arriving along it and ``r_jk`` its hit distance::

    E     = π/(MN) Σ_jk L_jk
    R     = MN / Σ_jk 1/r_jk                           (harmonic mean distance; a miss adds 0)
    ∇r E  = π/(MN) Σ_k v_k Σ_j T_j L_jk                (φ_k the stratum centre, v_k = n × u_k)
    ∇t E  = Σ_k u_k (2π/N) Σ_{j≥1} sin θ_j− cos² θ_j− (L_jk − L_j−1,k) / min(r_jk, r_j−1,k)
          + Σ_k v_k− Σ_j (sin θ_j+ − sin θ_j−) (L_jk − L_j,k−1) / min(r_jk, r_j,k−1)

with ``T_j = M [θ − sin θ cos θ]_{θ_j−}^{θ_j+}`` the mean of ``tan θ`` over ring ``j`` in the cosine measure
(Ward and Heckbert's ``tan θ_j`` at the ring centre, which falls short on the horizon ring: 4.12 for 5.89
at M = 9), ``u_k`` the tangent direction of azimuth ``φ_k``, ``v_k−`` the tangent direction ``φ_k− + π/2``
(``φ_k− = 2πk/N``, the wall between strata ``k − 1`` and ``k``), ``sin² θ_j− = j/M`` and
``sin² θ_j+ = (j + 1)/M`` (the ring boundaries). The two translation terms are what moving the point by δ
sweeps across a ring boundary (a feature at distance r moves by ``δ cos θ / r`` in θ) and across an azimuth
wall (``δ / (r sin θ)`` in φ), times the difference of the radiance on both sides; the rotation term is
the derivative of ``∫ L cos θ dω`` when the normal tilts. ``R`` is then limited by the translation
gradient (``R ≤ E_c / |∇t E_c|`` per channel, Křivánek et al. 2005) and clamped to ``[m_min, m_max]``
pixel spacings divided by ``a`` (the record's reach ``a R`` lies between ``m_min`` and ``m_max`` pixels of
the image, as pbrt-v2's ``minpixelspacing`` / ``maxpixelspacing``); ``∇t E`` is scaled by
``min(1, r_min / R_lo)`` (``r_min`` the nearest hit, ``R_lo`` the lower clamp), as Mitsuba 0.6 does.

Interpolation at ``(p, n)`` over the records with ``ε_i < a`` that are not in front of ``p``::

    ε_i   = |p − p_i| / R_i + sqrt(1 − n·n_i)           w_i = 1 / ε_i
    E(p)  = Σ w_i (E_i + (n_i × n)·∇r E_i + (p − p_i)·∇t E_i) / Σ w_i

(each extrapolated term clamped at 0, as Mitsuba 0.6); "in front": ``d_i = (p − p_i)·(n + n_i)/2 <
−0.05 R_i``, Ward's test against records that see what ``p`` does not.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import numpy.typing as npt

F = npt.NDArray[np.float64]

#: a weight's ε is at least this (w = 1/ε stays finite at a record's own point)
EPS_MIN = 1e-6
#: Ward's "in front" tolerance, as a fraction of R_i
FRONT_TOLERANCE = 0.05


def strata(samples: int) -> tuple[int, int]:
    """``(M, N)`` for about ``samples`` hemisphere rays with ``N ≈ π M`` (Ward, Heckbert 1992): ``M =
    max(2, round(sqrt(samples/π)))``, ``N = max(3, round(samples/M))``."""
    if samples < 6:
        raise ValueError(f"the irradiance cache needs at least 6 hemisphere samples, got {samples}")
    m = max(2, int(round(np.sqrt(samples / np.pi))))
    return m, max(3, int(round(samples / m)))


def frames(n: F) -> tuple[F, F]:
    """Tangents ``(s, t)`` with ``(s, t, n)`` right-handed orthonormal (Duff et al. 2017, as
    ``mi.coordinate_system``), for unit normals ``n`` of shape ``(K, 3)``."""
    sign = np.where(n[:, 2] >= 0.0, 1.0, -1.0)
    a = -1.0 / (sign + n[:, 2])
    b = n[:, 0] * n[:, 1] * a
    s = np.stack([1.0 + sign * n[:, 0] ** 2 * a, sign * b, -sign * n[:, 0]], axis=1)
    t = np.stack([b, sign + n[:, 1] ** 2 * a, -n[:, 1]], axis=1)
    return s, t


def directions(n: F, m: int, nn: int, xi: F) -> F:
    """World directions ``(K, M, N, 3)`` of the stratified samples about normals ``n`` (K, 3), jitters ``xi``
    (K, M, N, 2) in [0, 1): ``sin²θ = (j + ξ1)/M``, ``φ = 2π (k + ξ2)/N``."""
    j = np.arange(m)[None, :, None]
    k = np.arange(nn)[None, None, :]
    sin2 = (j + xi[..., 0]) / m
    sin_t = np.sqrt(sin2)
    cos_t = np.sqrt(np.maximum(1.0 - sin2, 0.0))
    phi = 2.0 * np.pi * (k + xi[..., 1]) / nn
    s, t = frames(n)
    local = (sin_t * np.cos(phi), sin_t * np.sin(phi), cos_t)
    return (local[0][..., None] * s[:, None, None, :] + local[1][..., None] * t[:, None, None, :]
            + local[2][..., None] * n[:, None, None, :])


class Estimate(NamedTuple):
    """What a record's hemisphere gives (module docstring): ``E`` (K, 3), ``R`` (K,) (inf: every ray
    missed), ``grad_r`` and ``grad_t`` (K, 3 axes, 3 channels)."""

    E: F
    R: F
    grad_r: F
    grad_t: F


def estimate(n: F, L: F, r: F) -> Estimate:
    """The :class:`Estimate` of records with normals ``n`` (K, 3) from the radiance ``L`` (K, M, N, 3) and
    hit distances ``r`` (K, M, N; ``inf`` for a miss) of their stratified samples (module docstring)."""
    _, m, nn, _ = L.shape
    E = np.pi / (m * nn) * L.sum(axis=(1, 2))
    inv = np.where(np.isfinite(r) & (r > 0.0), 1.0 / np.where(r > 0.0, r, 1.0), 0.0)
    inv_sum = inv.sum(axis=(1, 2))
    with np.errstate(divide="ignore"):
        R = np.where(inv_sum > 0.0, (m * nn) / inv_sum, np.inf)
    s, t = frames(n)

    def tangent(phi: F) -> F:   # (N, K, 3): cos φ s + sin φ t
        return np.cos(phi)[:, None, None] * s[None] + np.sin(phi)[:, None, None] * t[None]

    k = np.arange(nn)
    phi_c = 2.0 * np.pi * (k + 0.5) / nn
    u_k = tangent(phi_c)
    v_k = tangent(phi_c + 0.5 * np.pi)
    v_km = tangent(2.0 * np.pi * k / nn + 0.5 * np.pi)
    j = np.arange(m)
    theta_lo, theta_hi = np.arcsin(np.sqrt(j / m)), np.arcsin(np.sqrt((j + 1) / m))
    tan_c = m * ((theta_hi - np.sin(theta_hi) * np.cos(theta_hi)) - (theta_lo - np.sin(theta_lo) * np.cos(theta_lo)))
    sin_lo = np.sqrt(j / m)
    sin_hi = np.sqrt((j + 1) / m)
    cos_lo2 = 1.0 - j / m

    # rotation: π/(MN) Σ_k v_k Σ_j T_j L_jk
    ring = np.einsum("j,kjnc->knc", tan_c, L)                     # (K, N, 3)
    grad_r = np.pi / (m * nn) * np.einsum("nkx,knc->kxc", v_k, ring)

    with np.errstate(divide="ignore", invalid="ignore"):
        # across ring boundaries j-1 | j (j >= 1), along u_k
        r_min = np.minimum(r[:, 1:, :], r[:, :-1, :])
        fac = (2.0 * np.pi / nn) * (sin_lo[1:] * cos_lo2[1:])[None, :, None] / r_min
        fac = np.where(np.isfinite(fac), fac, 0.0)
        du = np.einsum("kjn,kjnc->knc", fac, L[:, 1:] - L[:, :-1])
        # across azimuth walls k-1 | k, along v_k-
        r_prev = np.roll(r, 1, axis=2)
        fac_v = (sin_hi - sin_lo)[None, :, None] / np.minimum(r, r_prev)
        fac_v = np.where(np.isfinite(fac_v), fac_v, 0.0)
        dv = np.einsum("kjn,kjnc->knc", fac_v, L - np.roll(L, 1, axis=2))
    grad_t = np.einsum("nkx,knc->kxc", u_k, du) + np.einsum("nkx,knc->kxc", v_km, dv)
    return Estimate(E, R, grad_r, grad_t)


def limit_radius(R: F, E: F, grad_t: F, r_min: F, spacing: F, a: float, m_min: float,
                 m_max: float) -> tuple[F, F]:
    """``(R, ∇t E)`` of records after the limits of the module docstring: ``R ← min(R, E_c/|∇t E_c|)`` over the
    channels with a gradient, clamped to ``[m_min, m_max] · spacing / a`` (``spacing``: the pixel spacing at
    the record); ``∇t E`` scaled by ``min(1, r_min / R_lo)`` with ``r_min`` the nearest hit of the hemisphere
    and ``R_lo = m_min · spacing / a`` (Křivánek et al. 2005, as Mitsuba 0.6: a record in a crease, whose
    gradient comes from hits nearer than the smallest radius it may have, extrapolates less)."""
    g = np.linalg.norm(grad_t, axis=1)                            # (K, 3)
    with np.errstate(divide="ignore", invalid="ignore"):
        limit = np.where(g > 1e-12, E / np.where(g > 1e-12, g, 1.0), np.inf).min(axis=1)
    R_lo, R_hi = m_min * spacing / a, m_max * spacing / a
    scale = np.minimum(1.0, r_min / R_lo)
    return np.clip(np.minimum(R, limit), R_lo, R_hi), grad_t * scale[:, None, None]


def epsilon(p: F, n: F, pi: F, ni: F, Ri: F) -> F:
    """Ward's error ``ε = |p − p_i|/R_i + sqrt(1 − n·n_i)`` of pairs (rows of equal length)."""
    dist = np.linalg.norm(p - pi, axis=-1)
    cos = np.clip(np.einsum("...x,...x->...", n, ni), -1.0, 1.0)
    return dist / Ri + np.sqrt(1.0 - cos)


def in_front(p: F, n: F, pi: F, ni: F, Ri: F) -> npt.NDArray[np.bool_]:
    """Ward's test: record ``i`` lies in front of ``p`` (``(p − p_i)·(n + n_i)/2 < −0.05 R_i``)."""
    return np.einsum("...x,...x->...", p - pi, 0.5 * (n + ni)) < -FRONT_TOLERANCE * Ri


def extrapolate(p: F, n: F, pi: F, ni: F, Ei: F, grad_r: F, grad_t: F) -> F:
    """``max(E_i + (n_i × n)·∇r E_i + (p − p_i)·∇t E_i, 0)`` of pairs (``grad_*``: (..., 3 axes, 3 channels))."""
    rot = np.cross(ni, n)
    value = Ei + np.einsum("...x,...xc->...c", rot, grad_r) + np.einsum("...x,...xc->...c", p - pi, grad_t)
    return np.maximum(value, 0.0)

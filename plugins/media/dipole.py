"""The dipole diffusion profile of Jensen, Marschner, Levoy, Hanrahan 2001 (docs/EXTENSIONS.md E.18).

For a medium with absorption ``σ_a``, scattering ``σ_s`` and Henyey-Greenstein ``g`` under a boundary of
relative index ``η`` (all per colour channel)::

    σ_s' = σ_s (1 − g),  σ_t' = σ_a + σ_s',  α' = σ_s'/σ_t',  σ_tr = sqrt(3 σ_a σ_t')
    F_dr = −1.440/η² + 0.710/η + 0.668 + 0.0636 η,   A = (1 + F_dr)/(1 − F_dr)
    z_r = 1/σ_t',  z_v = z_r (1 + 4A/3),  d_r = sqrt(r² + z_r²),  d_v = sqrt(r² + z_v²)
    R_d(r) = α'/(4π) [ z_r (1 + σ_tr d_r) e^{−σ_tr d_r}/d_r³ + z_v (1 + σ_tr d_v) e^{−σ_tr d_v}/d_v³ ]

and its integral over the plane (``∫ R_d 2πr dr``; each term integrates to ``2π e^{−σ_tr z}``)::

    R_d,total = (α'/2) (1 + e^{−(4/3) A sqrt(3(1 − α'))}) e^{−sqrt(3(1 − α'))}

Both are written once here for Dr.Jit colours (the kernel) and work on numpy arrays too (``xp = numpy``).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import drjit as dr
import mitsuba as mi


class Dipole(NamedTuple):
    """The dipole's per-channel constants (module docstring): ``alpha`` (α'), ``sigma_tr``, ``z_r``, ``z_v``,
    ``sigma_t`` (σ_t', the reduced extinction)."""

    alpha: Any
    sigma_tr: Any
    z_r: Any
    z_v: Any
    sigma_t: Any


def diffuse_fresnel(eta: Any) -> Any:
    """``F_dr(η) = −1.440/η² + 0.710/η + 0.668 + 0.0636 η`` (Jensen et al. 2001, eq. 5's fit)."""
    return -1.440 / (eta * eta) + 0.710 / eta + 0.668 + 0.0636 * eta


def dipole(sigma_a: Any, sigma_s: Any, g: Any, eta: Any, xp: Any = dr) -> Dipole:
    """The :class:`Dipole` of a medium (module docstring); ``xp``: ``drjit`` (default) or ``numpy``."""
    sigma_sp = sigma_s * (1.0 - g)
    sigma_tp = sigma_a + sigma_sp
    safe = xp.maximum(sigma_tp, 1e-30)
    alpha = sigma_sp / safe
    sigma_tr = xp.sqrt(3.0 * sigma_a * sigma_tp)
    fdr = diffuse_fresnel(eta)
    a = (1.0 + fdr) / (1.0 - fdr)
    z_r = 1.0 / safe
    return Dipole(alpha, sigma_tr, z_r, z_r * (1.0 + 4.0 * a / 3.0), sigma_tp)


def profile(dp: Dipole, r: Any, xp: Any = dr) -> Any:
    """``R_d(r)`` (module docstring), per channel, for the distance ``r >= 0``."""
    d_r = xp.sqrt(r * r + dp.z_r * dp.z_r)
    d_v = xp.sqrt(r * r + dp.z_v * dp.z_v)
    real = dp.z_r * (1.0 + dp.sigma_tr * d_r) * xp.exp(-dp.sigma_tr * d_r) / (d_r * d_r * d_r)
    virtual = dp.z_v * (1.0 + dp.sigma_tr * d_v) * xp.exp(-dp.sigma_tr * d_v) / (d_v * d_v * d_v)
    return dp.alpha / (4.0 * dr.pi) * (real + virtual)


def total_reflectance(alpha: Any, eta: Any, xp: Any = dr) -> Any:
    """``R_d,total(α', η)`` (module docstring): the albedo a uniformly lit half-space shows."""
    fdr = diffuse_fresnel(eta)
    a = (1.0 + fdr) / (1.0 - fdr)
    s = xp.sqrt(3.0 * (1.0 - alpha))
    return 0.5 * alpha * (1.0 + xp.exp(-4.0 / 3.0 * a * s)) * xp.exp(-s)


def profile_color(sigma_a: mi.Color3f, sigma_s: mi.Color3f, g: mi.Float, eta: mi.Float,
                  r: mi.Float) -> mi.Color3f:
    """``R_d(r)`` of a material's colours (the kernel's call)."""
    return mi.Color3f(profile(dipole(sigma_a, sigma_s, g, eta), r))

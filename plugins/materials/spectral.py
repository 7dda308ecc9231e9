"""Dispersion: wavelength samples, the Cauchy index and the RGB weight of a wavelength (docs/EXTENSIONS.md E.10).

Functions called from the ``a5_whitted`` kernel when its Python flag ``dispersion`` is on (a scene with a
``refractionIndex dispersion A B`` material); with the flag off none of them runs and the kernel is the one of
SPEC B.3 / E.1-E.5.

* **Wavelength**: each camera ray (one per ``-spp`` pass, E.5) carries one ``λ`` uniform on
  :data:`a5mi.spec.DISPERSION_RANGE_NM` (400-700 nm), stratified over the passes of a pixel: pass ``k`` of
  ``N`` lies in stratum ``s = (k + shift) mod N``, ``λ = λ0 + (λ1 − λ0)(s + ξ)/N`` with ``shift`` a hash of
  (pixel, seed) and ``ξ`` a hash of (pixel, seed, pass) (:mod:`.sampling`'s scheme, dimension
  :data:`WAVELENGTH_DIM`).
* **Index**: Cauchy's ``n(λ) = A + B/λ²`` with ``λ`` in µm.
* **RGB weight**: ``w(λ) = M · (x̄, ȳ, z̄)(λ) / c``: the CIE 1931 2° colour matching functions (Mitsuba's
  ``mi.cie1931_xyz``) tabulated every :data:`TABLE_STEP_NM` nm on the range, converted to linear sRGB by the
  XYZ -> sRGB (D65) matrix :data:`XYZ_TO_SRGB`, linearly interpolated, and divided per channel by
  ``c = (1/(λ1 − λ0)) ∫ M x̄ȳz̄ dλ`` (the trapezoid integral of the table, exact for the interpolant), so the
  mean of ``w`` over the range is exactly ``(1, 1, 1)``: white light stays white and the estimator
  ``w(λ) · L(λ)`` with uniform ``λ`` is unbiased for the RGB of the spectrum. ``w`` has negative lobes (spectral
  colours lie outside the sRGB gamut); a pixel of one pure wavelength is clipped when it is quantised.
* A path is weighted **once**, by its first refraction at a material with ``B ≠ 0`` (a flag per pending ray,
  :func:`weigh`); paths that never refract dispersively keep their weight, so they get no colour noise.
"""

from __future__ import annotations

from functools import cache

import drjit as dr
import mitsuba as mi
import numpy as np

from a5mi.plugins.sampling import Stochastic, tea
from a5mi.spec import DISPERSION_RANGE_NM

#: Sampling dimension of the wavelength (E.5's scheme; ray-tree dimensions are < 2^24, the lens 0xFFFFFFF0).
WAVELENGTH_DIM = 0xFFFFFFF1
#: Draw counter of the wavelength jitter ``ξ`` (the kernel's per-lane counter never gets near it).
WAVELENGTH_DRAW = 0xFFFFFFF1
#: Spacing of the colour-matching table (nm).
TABLE_STEP_NM = 5.0
#: CIE XYZ -> linear sRGB (D65 white), the matrix of Mitsuba's ``mi.xyz_to_srgb``.
XYZ_TO_SRGB = ((3.240479, -1.537150, -0.498535),
               (-0.969256, 1.875991, 0.041556),
               (0.055648, -0.204043, 1.057311))


def table_wavelengths() -> np.ndarray:
    """The table's wavelengths (nm): ``λ0, λ0 + 5, ..., λ1``."""
    lo, hi = DISPERSION_RANGE_NM
    return lo + TABLE_STEP_NM * np.arange(int(round((hi - lo) / TABLE_STEP_NM)) + 1)


@cache
def rgb_table() -> np.ndarray:
    """``w`` at :func:`table_wavelengths`, shape ``(K, 3)`` (module docstring), float64, from Mitsuba's CIE
    1931 table; the trapezoid mean of every column is 1."""
    lam = table_wavelengths()
    xyz = mi.cie1931_xyz(mi.Float(lam.astype(np.float32)))
    xyz_np = np.array([np.asarray(xyz[i], dtype=np.float64) for i in range(3)])
    rgb = np.asarray(XYZ_TO_SRGB, dtype=np.float64) @ xyz_np            # (3, K)
    mean = 0.5 * (rgb[:, :-1] + rgb[:, 1:]).sum(axis=1) / (len(lam) - 1)  # trapezoid mean over the range
    return (rgb / mean[:, None]).T


@cache
def _table_jit() -> mi.Float:
    """:func:`rgb_table` flattened (r, g, b per row) as a Dr.Jit array, for ``dr.gather``."""
    return mi.Float(rgb_table().astype(np.float32).ravel())


def rgb_weight(lam_nm: mi.Float) -> mi.Color3f:
    """``w(λ)``: the table linearly interpolated (clamped to the range)."""
    lo, hi = DISPERSION_RANGE_NM
    k = len(table_wavelengths())
    x = dr.clip((mi.Float(lam_nm) - lo) * (1.0 / TABLE_STEP_NM), 0.0, float(k - 1))
    i = dr.minimum(mi.UInt32(dr.floor(x)), k - 2)
    f = x - mi.Float(i)
    table = _table_jit()
    a = dr.gather(mi.Color3f, table, i)
    b = dr.gather(mi.Color3f, table, i + 1)
    return a + f * (b - a)


def cauchy_index(a: mi.Float, b: mi.Float, lam_nm: mi.Float) -> mi.Float:
    """Cauchy's ``n(λ) = A + B/λ²``, ``λ`` in µm (``lam_nm / 1000``); ``B = 0`` gives ``A`` exactly."""
    lam_um = mi.Float(lam_nm) * 1e-3
    return a + b / (lam_um * lam_um)


def wavelength(pixel_key: mi.UInt32, pass_key: mi.UInt32, pass_index: mi.UInt32, passes: mi.UInt32) -> mi.Float:
    """The camera ray's wavelength (nm): pass ``pass_index`` of ``passes``, stratified (module docstring)."""
    lo, hi = DISPERSION_RANGE_NM
    count = dr.maximum(mi.UInt32(passes), 1)
    shift = tea(pixel_key, mi.UInt32(WAVELENGTH_DIM)) % count
    s = (mi.UInt32(pass_index) + shift) % count
    xi = mi.sample_tea_float32(mi.UInt32(pass_key), mi.UInt32(WAVELENGTH_DRAW))
    u = dr.minimum((mi.Float(s) + xi) / mi.Float(count), 0.99999994)
    return lo + (hi - lo) * u


def lane_wavelength(rng: Stochastic, width: int) -> mi.Float:
    """The wavelength of each of ``width`` lanes (:func:`wavelength` of the kernel's sampling state ``rng``)."""
    _table_jit()  # built here, outside the kernel's symbolic loop (its first evaluation reads Mitsuba's CIE table)
    lam = wavelength(rng.pixel_key, rng.pass_key, rng.pass_index, rng.passes)
    return lam + dr.zeros(mi.Float, width)


def index_at(bsdf: mi.BSDFPtr, si: mi.SurfaceInteraction3f, a5: mi.Bool, ior: mi.Float,
             lam_nm: mi.Float) -> tuple[mi.Float, mi.Bool]:
    """``(n(λ), dispersive)`` of the hit material: ``refraction_index`` is Cauchy's ``A``, the attribute
    ``cauchy_b`` its ``B``; ``dispersive`` where ``B ≠ 0`` (and the material refracts)."""
    b = bsdf.eval_attribute_1("cauchy_b", si, a5)
    dispersive = a5 & (ior > 0.0) & (b != 0.0)
    return dr.select(dispersive, cauchy_index(ior, b, lam_nm), ior), dispersive


def weigh(w: mi.Color3f, weighted: mi.UInt32, dispersive: mi.Bool, lam_nm: mi.Float) -> tuple[mi.Color3f, mi.UInt32]:
    """The refracted child's weight and "weighted" flag (UInt32 0/1, a pending-ray field of the kernel's
    :class:`~.kernel.stack.RayStack`): multiplied by ``w(λ)`` where the refraction is ``dispersive`` and the path
    is not ``weighted`` yet; the flag then becomes 1."""
    apply = dispersive & (weighted == 0)
    return dr.select(apply, w * rgb_weight(lam_nm), w), dr.select(dispersive, 1, weighted)

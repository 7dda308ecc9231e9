"""Seeded, stratified sample numbers for the distribution-ray-tracing extension (docs/EXTENSIONS.md E.5).

Stateless: every number is a TEA hash (``mi.sample_tea_32`` / ``mi.sample_tea_float32``) of per-lane keys,
so a render is reproducible for a given ``-seed`` whatever the tile size or thread count.

* ``pixel_key = tea(pixel, seed)``: one per render-buffer sample (pixel) and seed;
* ``pass_key = tea(pixel_key, pass)``: one per ``-spp`` pass (the uniform jitter ``ξ`` of each draw is
  ``tea_float(pass_key, counter)``, ``counter`` advancing by 2 per 2D draw);
* a *dimension* ``dim`` (the camera lens, light k at ray-tree node t, the glossy lobe at node t) has ``M``
  samples per pixel (``M = spp · samples``); sample ``i`` of them (``i = pass · samples + j``) lies in
  stratum ``s = (π_dim(i) + shift) mod M``, with the per-pixel shift ``shift = tea(pixel_key, dim) mod M`` and
  ``π_dim = permute(·, M, key_dim)`` Kensler's hashed permutation of ``[0, M)`` (Correlated Multi-Jittered
  Sampling, Pixar TM 13-01, 2013: invertible integer mixing on the smallest power-of-two range ``2^b ≥ M``,
  repeated while the result is ``≥ M``, a bijection of ``[0, M)``), ``key_dim`` the second word of
  ``sample_tea_32(pixel_key, dim)``. Each dimension is stratified over the pixel's ``M`` samples and each sample
  is uniform; two dimensions of one pixel are paired by the pseudo-random ``π_B ∘ π_A⁻¹`` (padded,
  Latin-hypercube-like sampling), so a pixel's estimate converges to the pixel's value. (A cyclic shift alone
  paired stratum ``s`` of one dimension with ``s + c`` of another for one per-pixel ``c``: the pixel converged
  to a seed-dependent value wherever two dimensions interact, e.g. the lens and an area light in a defocused
  soft shadow.) ``M = 1`` (``-spp 1``, one sample): ``π(0) = 0``, the plain jitter ``ξ``;
* stratum ``s`` of ``M`` with ``q = floor(sqrt M)``: for ``s < q²`` the cell ``(s mod q, s div q)`` of a
  ``q x q`` grid, ``u = ((s mod q) + ξ1)/q``, ``v = ((s div q) + ξ2)/q``; the ``M - q²`` remaining samples are
  uniform on the square. Both are uniform densities, so the mixture is unbiased.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import drjit as dr
import mitsuba as mi

from a5mi.plugins.syntax import syntax

#: ``dim`` of the thin-lens sample (EXTENSIONS E.3); ray-tree dimensions are ``node · 256 + slot`` < 2^24.
LENS_DIM = 0xFFFFFFF0
#: slot of the glossy lobe at a node; light k uses slot k (k < 255).
GLOSSY_SLOT = 255


def tea(a: mi.UInt32, b: mi.UInt32) -> mi.UInt32:
    """A 32-bit hash of two 32-bit words (TEA, 4 rounds): the first word of ``mi.sample_tea_32``."""
    return mi.sample_tea_32(mi.UInt32(a), mi.UInt32(b))[0]


def pixel_keys(pixel: mi.UInt32, seed: mi.UInt32, pass_index: mi.UInt32) -> tuple[mi.UInt32, mi.UInt32]:
    """``(pixel_key, pass_key)`` of the module docstring."""
    pk = tea(pixel, seed)
    return pk, tea(pk, pass_index)


def _mix(i: mi.UInt32, w: mi.UInt32, p: mi.UInt32) -> mi.UInt32:
    """One round of Kensler's ``permute``: a bijection of ``[0, w]`` (``w + 1`` a power of two)."""
    i = i ^ p
    i = i * 0xE170893D
    i = i ^ (p >> 16)
    i = i ^ ((i & w) >> 4)
    i = i ^ (p >> 8)
    i = i * 0x0929EB3F
    i = i ^ (p >> 23)
    i = i ^ ((i & w) >> 1)
    i = i * (1 | (p >> 27))
    i = i * 0x6935FA69
    i = i ^ ((i & w) >> 11)
    i = i * 0x74DCB303
    i = i ^ ((i & w) >> 2)
    i = i * 0x9E501CC3
    i = i ^ ((i & w) >> 2)
    i = i * 0xC860A3DF
    i = i & w
    return i ^ (i >> 5)


@syntax
def permute(index: mi.UInt32, count: mi.UInt32, key: mi.UInt32) -> mi.UInt32:
    """``π(index)`` for the permutation of ``[0, count)`` chosen by ``key`` (module docstring; cycle walking:
    fewer than two rounds on average)."""
    count = dr.maximum(mi.UInt32(count), 1)
    w = count - 1
    w = w | (w >> 1)
    w = w | (w >> 2)
    w = w | (w >> 4)
    w = w | (w >> 8)
    w = w | (w >> 16)
    key = mi.UInt32(key)
    i = _mix(mi.UInt32(index), w, key)
    while i >= count:
        i = _mix(i, w, key)
    return (i + key) % count


def stratified_2d(pixel_key: mi.UInt32, pass_key: mi.UInt32, dim: mi.UInt32, index: mi.UInt32,
                  count: mi.UInt32, counter: mi.UInt32) -> mi.Point2f:
    """Sample ``index`` of ``count`` of dimension ``dim`` in stratum ``(π_dim(index) + shift) mod count``, jittered
    by the draws ``counter``, ``counter + 1`` of ``pass_key`` (module docstring)."""
    count = dr.maximum(mi.UInt32(count), 1)
    keys = mi.sample_tea_32(mi.UInt32(pixel_key), mi.UInt32(dim))
    shift = keys[0] % count
    s = (permute(mi.UInt32(index), count, keys[1]) + shift) % count
    q = mi.UInt32(dr.floor(dr.sqrt(mi.Float(count))))
    q = dr.select(q * q > count, q - 1, q)                      # guard sqrt rounding up
    xi1 = mi.sample_tea_float32(pass_key, mi.UInt32(counter))
    xi2 = mi.sample_tea_float32(pass_key, mi.UInt32(counter) + 1)
    grid = s < q * q
    qf = mi.Float(q)
    u = dr.select(grid, (mi.Float(s % q) + xi1) / qf, xi1)
    v = dr.select(grid, (mi.Float(s // q) + xi2) / qf, xi2)
    return mi.Point2f(dr.minimum(u, 0.99999994), dr.minimum(v, 0.99999994))


def ggx_normal(n: mi.Vector3f, alpha: mi.Float, u: mi.Point2f) -> mi.Vector3f:
    """A GGX microfacet normal around ``n`` (EXTENSIONS E.4): ``tan²θm = α² u1/(1 - u1)``, ``φm = 2π u2``;
    pdf ``D(m) cos θm`` with ``D(m) = α² / (π cos⁴θm (α² + tan²θm)²)``. ``α = 0`` returns ``n``."""
    tan2 = alpha * alpha * u.x / dr.maximum(1.0 - u.x, 1e-7)
    cos_t = dr.rsqrt(1.0 + tan2)
    sin_t = dr.safe_sqrt(1.0 - cos_t * cos_t)
    s, c = dr.sincos(2.0 * dr.pi * u.y)
    frame = mi.Frame3f(n)
    m = frame.to_world(mi.Vector3f(sin_t * c, sin_t * s, cos_t))
    return dr.select(alpha > 0.0, dr.normalize(m), n)


class SamplePass(NamedTuple):
    """Which samples a batch of camera rays is (docs/EXTENSIONS.md E.5), handed to ``a5_whitted``'s ``sample`` /
    ``trace`` with each call (``a5mi.render.passes.sample_passes``): lane ``i`` is render-buffer sample
    ``first_pixel + i``, in pass ``index`` of ``count`` (``-spp``), with ``seed``. Without one (``mi.render``) a
    lane's key comes from the sampler and every pass is independent."""

    first_pixel: int
    index: int
    count: int
    seed: int
    #: E.5 wavefront: the lanes hold ``batch`` consecutive passes, pass-major with ``stride`` lanes each (lane
    #: ``L``: sample ``first_pixel + L mod stride`` in pass ``index + L div stride``); 1: every lane pass ``index``
    batch: int = 1
    stride: int = 0
    #: the lanes' render-buffer samples when they are not consecutive (a crop render, a5mi/render/crop.py): a
    #: ``mi.UInt32`` of one absolute sample index per sample (lane ``i`` of a pass is sample ``pixels[i]``, not
    #: ``first_pixel + i``); None: consecutive from ``first_pixel``
    pixels: Any = None


class Stochastic(NamedTuple):
    """Per-lane sampling state of a kernel call (module docstring): ``pixel_key`` and ``pass_key`` (UInt32 per
    lane), the pass index and the number of passes (``-spp``) and the cap on glossy children (opaque)."""

    pixel_key: mi.UInt32
    pass_key: mi.UInt32
    pass_index: mi.UInt32
    passes: mi.UInt32
    glossy_cap: mi.UInt32


def stochastic(sample_pass: SamplePass | None, sampler: mi.Sampler | None, width: int,
               glossy_cap: int) -> Stochastic:
    """The :class:`Stochastic` state of ``width`` camera rays: keys of ``sample_pass``, or without one keys
    drawn from ``sampler`` (pass 0 of 1, seed 0; no sampler: key 0)."""
    if sample_pass is not None and int(sample_pass.batch) > 1:
        first, index, count, seed, _batch, stride = (int(v) for v in sample_pass[:6])
        lane = dr.arange(mi.UInt32, width)
        k = lane // dr.opaque(mi.UInt32, stride)
        pixel = lane - k * dr.opaque(mi.UInt32, stride)
        if sample_pass.pixels is None:
            pixel = pixel + dr.opaque(mi.UInt32, first)
        else:   # the padding lanes (inactive) take the pass's last sample
            last = dr.opaque(mi.UInt32, dr.width(sample_pass.pixels) - 1)
            pixel = dr.gather(mi.UInt32, sample_pass.pixels, dr.minimum(pixel, last))
        pass_index = k + dr.opaque(mi.UInt32, index)
        pixel_key, pass_key = pixel_keys(pixel, dr.opaque(mi.UInt32, seed & 0xFFFFFFFF), pass_index)
        return Stochastic(pixel_key, pass_key, pass_index, dr.opaque(mi.UInt32, count),
                          dr.opaque(mi.UInt32, glossy_cap))
    if sample_pass is not None:
        first, index, count, seed = (int(v) for v in sample_pass[:4])
        seed &= 0xFFFFFFFF
        pixel = (dr.arange(mi.UInt32, width) + dr.opaque(mi.UInt32, first) if sample_pass.pixels is None
                 else mi.UInt32(sample_pass.pixels))
    else:
        index, count, seed = 0, 1, 0
        rnd = sampler.next_1d() if sampler is not None else dr.zeros(mi.Float, width)
        pixel = mi.UInt32(rnd * 16777216.0) + dr.zeros(mi.UInt32, width)
    pixel_key, pass_key = pixel_keys(pixel, dr.opaque(mi.UInt32, seed), dr.opaque(mi.UInt32, index))
    return Stochastic(pixel_key, pass_key, dr.opaque(mi.UInt32, index), dr.opaque(mi.UInt32, count),
                      dr.opaque(mi.UInt32, glossy_cap))

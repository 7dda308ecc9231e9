"""Padded stratified samples for the physically based integrators (docs/EXTENSIONS.md E.14, E.15): the E.5
strata of :func:`..sampling.stratified_2d`, assigned to the passes by an independent pseudo-random permutation
per pixel and dimension.

E.5 puts sample ``i`` of dimension ``dim`` in stratum ``(i + shift_dim) mod M`` (``M = spp · samples``): every
dimension of a pixel is a cyclic shift of the same sequence, so two dimensions of one path (the BSDF sample at
vertex 0 and the light sample at vertex 1, say) always pair stratum ``s`` with stratum ``s + c`` for one
per-pixel constant ``c``. Averaged over pixels (over ``c``) that is unbiased, but one pixel's estimate converges
to the integral along that fixed pairing, not to the pixel's value: its error stops falling at a level set by
the integrand (measured on a diffuse scene lit by the sky: the mean |difference| of two 16 x 16 renders with
different seeds 17 % of the mean at 16 passes, 14 % at 1,024).

Here sample ``i`` lies in stratum ``π(i)`` with ``π = permute(·, M, key_dim)``, Kensler's hashed permutation
of ``[0, M)`` (Correlated Multi-Jittered Sampling, Pixar TM 13-01, 2013: invertible integer mixing on the
smallest power-of-two range ``2^b ≥ M``, repeated while the result is ``≥ M``, so it stays a bijection of
``[0, M)``), ``key_dim`` a TEA hash of the pixel key and the dimension. Each dimension is still stratified over
the pixel's ``M`` samples, and the pairing of two dimensions is the pseudo-random ``π_B ∘ π_A⁻¹``: padded
(Latin-hypercube-like) sampling, whose per-pixel error falls as ``M^(-1/2)`` or faster.
"""

from __future__ import annotations

import drjit as dr
import mitsuba as mi

from ..sampling import Stochastic, stratified_2d
from ..syntax import syntax


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


def padded_2d(rng: Stochastic, dim: mi.UInt32, index: mi.UInt32, count: mi.UInt32,
              counter: mi.UInt32) -> mi.Point2f:
    """Sample ``index`` of ``count`` of dimension ``dim`` in the stratum ``π(index)`` (module docstring), jittered
    by the draws ``counter``, ``counter + 1`` of the pass key."""
    key = mi.sample_tea_32(mi.UInt32(rng.pixel_key), mi.UInt32(dim))[1]
    return stratified_2d(rng.pixel_key, rng.pass_key, dim, permute(index, count, key), count, counter)

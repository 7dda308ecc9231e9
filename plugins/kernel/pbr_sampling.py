"""Padded stratified samples for the physically based integrators (docs/EXTENSIONS.md E.5, E.14, E.15): the E.5
samples of :func:`..sampling.stratified_2d`, each pixel and dimension with its own pseudo-random permutation of
the strata.

E.5 once put sample ``i`` of dimension ``dim`` in stratum ``(i + shift_dim) mod M`` (``M = spp · samples``): every
dimension of a pixel was a cyclic shift of the same sequence, so two dimensions of one path (the BSDF sample at
vertex 0 and the light sample at vertex 1, say) always paired stratum ``s`` with stratum ``s + c`` for one
per-pixel constant ``c``. Averaged over pixels (over ``c``) that is unbiased, but one pixel's estimate converged
to the integral along that fixed pairing, not to the pixel's value: its error stopped falling at a level set by
the integrand (measured on a diffuse scene lit by the sky: the mean |difference| of two 16 x 16 renders with
different seeds 17 % of the mean at 16 passes, 14 % at 1,024).

Sample ``i`` now lies in stratum ``(π_dim(i) + shift_dim) mod M`` with ``π_dim = permute(·, M, key_dim)``,
Kensler's hashed permutation of ``[0, M)`` (:func:`..sampling.permute`, the one implementation, shared with
``a5_whitted``'s light, gloss and lens samples). Each dimension is still stratified over the pixel's ``M``
samples, and the pairing of two dimensions is the pseudo-random ``π_B ∘ π_A⁻¹``: padded (Latin-hypercube-like)
sampling, whose per-pixel error falls as ``M^(-1/2)`` or faster.
"""

from __future__ import annotations

import mitsuba as mi

from a5mi.plugins.sampling import (
    Stochastic,
    stratified_2d,
)


def padded_2d(rng: Stochastic, dim: mi.UInt32, index: mi.UInt32, count: mi.UInt32,
              counter: mi.UInt32) -> mi.Point2f:
    """Sample ``index`` of ``count`` of dimension ``dim`` in the stratum ``(π(index) + shift) mod count`` (module
    docstring), jittered by the draws ``counter``, ``counter + 1`` of the pass key."""
    return stratified_2d(rng.pixel_key, rng.pass_key, dim, index, count, counter)

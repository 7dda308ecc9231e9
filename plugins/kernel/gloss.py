"""Glossy children (docs/EXTENSIONS.md E.4): a sampled GGX microfacet normal instead of N.

With roughness ``α > 0`` both children of a hit turn about a microfacet normal ``m`` drawn from GGX around the
side of N that faces the ray (:func:`plugins.sampling.ggx_normal`: ``tan²θm = α² u1/(1 − u1)``, ``φm = 2π u2``),
a camera hit pushes ``G = glossySamples`` such pairs with weight ``1/G`` each, and a child on the wrong side of
the surface is dropped (the kernel's push masks). The lobe sample is stratified over the ``-spp`` passes and
the G children (E.5, dimension ``node · 256 + GLOSSY_SLOT``).
"""

from __future__ import annotations

import drjit as dr
import mitsuba as mi

from a5mi.plugins.optics import reflect
from a5mi.plugins.sampling import GLOSSY_SLOT, Stochastic, ggx_normal, stratified_2d


def facet(d: mi.Vector3f, n_side: mi.Vector3f, r_view: mi.Vector3f, alpha: mi.Float, glossy: mi.Bool,
          rng: Stochastic, node: mi.UInt32, g: mi.UInt32, n_children: mi.UInt32,
          counter: mi.UInt32) -> tuple[mi.Vector3f, mi.Vector3f, mi.UInt32]:
    """``(m, mirror direction about m, counter)`` of child pair ``g`` of ``n_children``: where ``glossy``,
    ``m`` is the sampled facet (module docstring) and two draws are used; elsewhere ``(n_side, r_view)``."""
    u_g = stratified_2d(rng.pixel_key, rng.pass_key, node * 256 + GLOSSY_SLOT, rng.pass_index * n_children + g,
                        rng.passes * n_children, counter)
    counter += dr.select(glossy, 2, 0)
    m_facing = dr.select(glossy, ggx_normal(n_side, alpha, u_g), n_side)
    r_dir = dr.select(glossy, reflect(d, m_facing), r_view)
    return m_facing, r_dir, counter

"""Light attenuated on its way through a medium (docs/EXTENSIONS.md E.8, E.9 "Attenuated light").

With ``medium_bounces >= 1`` (``-media_bounces N``) every shadow ray of the light loop, and of the in-scattering
points of a medium, carries the transmittance of the medium it crosses from ``tmin`` to the light::

    T_light = exp(−∫_tmin^dist σ_t(x(t)) dt)

* Fog (``σ_t = density`` everywhere outside glass): the closed form ``exp(−σ (dist − tmin))``; a directional
  light is at infinity, so its light does not arrive through a fog at all (``T = 0``, as in Mitsuba's
  ``volpath``, whose homogeneous medium fills all space);
* Volume (``σ_t = density · grid(x)`` inside the box, 0 outside): the ray clipped to the box ``[ta, tb]``
  (a directional light: ``tb`` = where the ray leaves the box), then **ratio tracking** (Novák et al. 2014)
  with the majorant ``μ = density · max(grid)``: tentative collisions ``t_{j+1} = t_j − ln(1 − ξ_j)/μ`` while
  ``t < tb``, ``T = Π_j (1 − σ_t(x(t_j))/μ)``, an unbiased estimate of the transmittance (exact for a constant
  grid, where every factor is 0 or the walk never collides: a constant grid at its maximum gives
  ``T ∈ {0, 1}`` with mean ``exp(−μ d)``: that is delta tracking's estimate; a grid below its maximum gets
  fractional weights). The numbers ``ξ_j`` are TEA hashes ``tea_float(pass_key, counter)`` of the lane's
  E.5 pass key with its draw counter (plugins/sampling.py), so a render is reproducible for a ``-seed``.

``density 0``: ``T = exp(0) = 1`` (fog) or no collision at all (volume, ``μ = 0``): the light term is unchanged
bit for bit.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import drjit as dr
import mitsuba as mi

from a5mi.plugins.syntax import syntax

if TYPE_CHECKING:
    from a5mi.plugins.media.medium import MediumParams
    from a5mi.plugins.sampling import Stochastic


def box_span(box_min: mi.Point3f, box_max: mi.Point3f, o: mi.Point3f, d: mi.Vector3f, t0: mi.Float,
             t1: mi.Float) -> tuple[mi.Float, mi.Float]:
    """``[ta, tb]``: the part of ``[t0, t1]`` of the ray ``o + t d`` inside the box (slab test; empty when
    ``tb <= ta``)."""
    inv = dr.rcp(d)
    lo = (box_min - o) * inv
    hi = (box_max - o) * inv
    near = dr.minimum(lo, hi)
    far = dr.maximum(lo, hi)
    ta = dr.maximum(dr.maximum(dr.maximum(near.x, near.y), near.z), t0)
    tb = dr.minimum(dr.minimum(dr.minimum(far.x, far.y), far.z), t1)
    return ta, tb


def light_distance(dist: mi.Float, is_area: mi.Bool, far: mi.Bool) -> mi.Float:
    """Where a shadow ray's medium ends: the light's distance, short of an area light's own shape
    (``dist (1 − 10⁻⁴)``, as its shadow ray), ``∞`` for a directional light (``far``)."""
    return dr.select(far, dr.inf, dr.select(is_area, dist * (1.0 - 1e-4), dist))


@syntax
def ratio_tracking(med: MediumParams, o: mi.Point3f, d: mi.Vector3f, ta: mi.Float, tb: mi.Float,
                   active: mi.Bool, key: mi.UInt32, counter: mi.UInt32) -> tuple[mi.Float, mi.UInt32]:
    """``(T, counter)``: the ratio-tracking estimate of ``exp(−∫_ta^tb σ_t)`` in the volume ``med`` (module
    docstring), one draw ``tea_float(key, counter)`` per tentative collision."""
    width = dr.width(ta)
    mu = med.density * med.grid_max
    live = active & (tb > ta) & (mu > 0.0)
    inv_mu = dr.rcp(dr.maximum(mu, 1e-30))
    tr = dr.full(mi.Float, 1.0, width)
    t = mi.Float(ta)
    while live:
        xi = mi.sample_tea_float32(key, counter)
        counter += dr.select(live, 1, 0)
        t = t - dr.log(1.0 - xi) * inv_mu
        inside = live & (t < tb)
        it = dr.zeros(mi.Interaction3f, width)
        it.p = o + t * d
        sigma = med.density * med.grid.eval_1(it, inside)
        tr = dr.select(inside, tr * dr.maximum(1.0 - sigma * inv_mu, 0.0), tr)
        live = inside & (tr > 0.0)
    return tr, counter


def transmittance(med: MediumParams, o: mi.Point3f, d: mi.Vector3f, t0: mi.Float, t1: mi.Float,
                  active: mi.Bool, rng: Stochastic, counter: mi.UInt32) -> tuple[mi.Float, mi.UInt32]:
    """``(T, counter)``: the transmittance of the medium ``med`` along ``o + t d``, ``t0 <= t <= t1``
    (``t1 = ∞`` allowed) on the lanes ``active`` (1 elsewhere); module docstring."""
    if med.kind == "fog":
        tau = dr.select(active & (med.density > 0.0), med.density * (t1 - t0), 0.0)   # σ = 0: no 0·∞
        return dr.exp(-tau), counter
    ta, tb = box_span(med.box_min, med.box_max, o, d, t0, t1)
    tr, counter = ratio_tracking(med, o, d, ta, tb, active, rng.pass_key, counter)
    return dr.select(active, tr, 1.0), counter


def shadow_transmittance(med: MediumParams, p: mi.Point3f, d_light: mi.Vector3f, tmin: mi.Float, dist: mi.Float,
                         is_area: mi.Bool, far: mi.Bool, seen: mi.Bool, rng: Stochastic,
                         counter: mi.UInt32) -> tuple[mi.Float, mi.UInt32]:
    """``(T_light, counter)`` of a shadow ray from ``p`` toward a light (``d_light``, distance ``dist``,
    ``is_area``, ``far``: directional) on the lanes that see it (``seen``); module docstring."""
    return transmittance(med, p, d_light, tmin, light_distance(dist, is_area, far), seen, rng, counter)

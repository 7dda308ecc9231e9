"""``-indirect N``: distribution ray tracing of indirect light in ``a5_whitted``'s ray tree (docs/EXTENSIONS.md
E.15), the Features block ``indirect`` of :func:`.raytree.trace_tree`.

At a hit with ``max(kd) > 0`` and bounces left, ``N`` rays ``ω_j`` are drawn cosine-weighted about the side of
``N`` the ray comes from (E.13's two-sided Lambert), each pushed as a child of weight ``w ⊙ kd / N`` (the
Lambert estimator ``f cos θ / pdf = (kd/π) cos θ / (cos θ/π) = kd``), so the node gains the E.13 estimate of
its indirect light ``kd ⊙ (1/N) Σ_j L(ω_j)``, with ``L`` what the ray tree computes at the child (recursively,
within ``-bounces``). The directions are E.5 samples: dimension ``256 node + GATHER_SLOT``, sample ``pass · N + j``
of ``spp · N``, stratified over the rays and the passes and padded across nodes (:func:`.pbr_sampling.padded_2d`).

A gathered child does not add the emission of an area light it hits: the parent's light loop already
counted that light (E.2), so the gather holds only the light that arrives after at least one more bounce and
the environment (which the light loop never counts). The flag travels in the top bit of the pending ray's
``origin`` (the rule-table row of the face it leaves, far below 2³¹): :func:`split_origin`.
"""

from __future__ import annotations

import drjit as dr
import mitsuba as mi

from a5mi.plugins.kernel import stack as ray_stack
from a5mi.plugins.kernel.pbr_sampling import padded_2d
from a5mi.plugins.sampling import Stochastic
from a5mi.plugins.syntax import syntax

#: the E.5 slot of the gathered rays at a node (light k uses slot k, the glossy lobe 255)
GATHER_SLOT = 254
#: the bit of a pending ray's ``origin`` that marks a gathered ray
GATHERED = 0x80000000


def split_origin(origin: mi.UInt32) -> tuple[mi.UInt32, mi.Bool]:
    """``(rule-table row, gathered)`` of a popped ray's ``origin`` field."""
    return origin & (GATHERED - 1), origin >= GATHERED


def stack_size(max_depth: int, glossy_samples: int, n: int) -> int:
    """Pending-ray entries with ``n`` gathered rays per hit: each of ``max_depth`` levels leaves at most ``n + 1``
    entries pending (``n + 2`` pushed, one popped), a glossy camera hit ``2 G`` more; at least 8."""
    return max(8, max_depth * (n + 1) + 2 * glossy_samples + 1)


@syntax
def gather(stack: tuple, top: mi.UInt32, go: mi.Bool, p: mi.Point3f, d: mi.Vector3f, n: mi.Vector3f,
           kd: mi.Color3f, weight: mi.Color3f, bounces: mi.UInt32, n_medium: mi.Float, tmin: mi.Float,
           row: mi.UInt32, weighted: mi.UInt32 | None, rng: Stochastic, node: mi.UInt32, counter: mi.UInt32,
           n_refl: mi.Float, count: int) -> tuple[mi.UInt32, mi.UInt32, mi.Float]:
    """Push the ``count`` gathered children of the lanes ``go`` (module docstring) from the hit ``p`` (shading
    normal ``n``, incoming ``d``, Lambert colour ``kd``, path weight ``weight``); returns ``(top, counter,
    n_refl)`` (each gathered ray counts as a reflected one, so record mode's node numbers hold)."""
    diffuse = go & (dr.max(kd) > 0.0)
    n_face = dr.select(dr.dot(d, n) < 0.0, n, -n)
    frame = mi.Frame3f(n_face)
    w = weight * kd * (1.0 / count)
    j = dr.zeros(mi.UInt32, dr.width(p))
    while diffuse & (j < count):
        u = padded_2d(rng, node * 256 + GATHER_SLOT, rng.pass_index * count + j, rng.passes * count, counter)
        counter += 2
        omega = frame.to_world(mi.warp.square_to_cosine_hemisphere(u))
        top = ray_stack.push(stack, top, diffuse, p, omega, w, bounces - 1, n_medium, tmin, row | GATHERED,
                             weighted)
        n_refl += dr.select(diffuse, 1.0, 0.0)
        j += 1
    return top, counter, n_refl

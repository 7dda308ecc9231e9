"""The irradiance cache's two Dr.Jit kernels (docs/EXTENSIONS.md E.23), built from the kernel library and the
E.13 reading (:mod:`.kernel.pbr`, :mod:`.kernel.pbr_lights`).

:func:`camera_tree` follows each camera ray through its delta lobes, as SPEC B.3's ray tree (both children,
weights ``ks R`` and ``ks (1 − R)(n/nt)²`` of :func:`.kernel.pbr.lobes`, within the ``max_depth`` budget),
and at every node adds what needs no cache: the environment a ray escapes to, the emission of a light's
shape it hits, and at a diffuse node next-event estimation (:func:`.kernel.pbr_lights.direct`, the
environment left to the cache, the Lambert pdf taken as ``cos θ/π``). Each diffuse node is appended to flat
:class:`Nodes` buffers (``dr.scatter_inc``): lane, its number in the lane's tree, ``p``, ``N`` turned toward
the ray, ``β kd/π`` and its pixel spacing ``s = θ_pix · T / sqrt(max(|d·N|, 0.05))`` (``T`` the distance
travelled from the camera, ``θ_pix`` the angle of a pixel: a ray cone, mirrors taken as flat) and the index of
the medium on its side. The host adds ``β kd/π ⊙ E(p, N)`` afterwards. The budget is E.14's: nodes
``0 .. max_depth`` deep shade and scatter, the rays leaving the deepest add only the emission they find.

:func:`gather` is the radiance of the hemisphere rays of new records (the ``L_jk`` and ``r_jk`` of
:mod:`.irradiance_cache_math`): a path from the record's point along each ray, as pbrt-v2's ``pathL``
(its first hit's emission weighted against the node's next-event estimation), then E.14's estimator: at each
vertex next-event estimation with the environment and the BSDF's next direction, emission weighted by the power
heuristic, Russian roulette from ``rr_depth`` scatterings on. Vertices ``0 .. max_depth − 1`` of the path
(the record's node being vertex 0 of the camera's path) gather light, as ``a5_path`` with the same budget.
"""

from __future__ import annotations

from typing import NamedTuple

import drjit as dr
import mitsuba as mi

from a5mi.plugins.kernel import stack as ray_stack
from a5mi.plugins.kernel.features import Features, SceneData
from a5mi.plugins.kernel.intersect import intersect
from a5mi.plugins.kernel.pbr import power_heuristic, sample
from a5mi.plugins.kernel.pbr_lights import PbrLights, direct, emission, environment, light_point
from a5mi.plugins.kernel.pbr_surface import surface_lobes
from a5mi.plugins.kernel.surfaces import background
from a5mi.plugins.sampling import Stochastic
from a5mi.plugins.syntax import syntax

#: the E.5 slot of the BSDF sample at a vertex of a hemisphere path (``a5_path``'s)
BSDF_SLOT = 255


class Nodes(NamedTuple):
    """Flat buffers of the diffuse nodes of a batch of ray trees (module docstring); ``count`` (one UInt32)
    is how many were found, possibly more than the buffers hold (``capacity``)."""

    count: mi.UInt32
    lane: mi.UInt32
    seq: mi.UInt32
    p: mi.Float
    n: mi.Float
    beta: mi.Float
    spacing: mi.Float
    n_medium: mi.Float


def node_buffers(capacity: int) -> Nodes:
    """Empty :class:`Nodes` buffers of ``capacity`` entries (``p``, ``n``, ``beta``: three floats each;
    ``n_medium``: the index of the medium on the side of ``n``)."""
    return Nodes(dr.zeros(mi.UInt32, 1), dr.zeros(mi.UInt32, capacity), dr.zeros(mi.UInt32, capacity),
                 dr.zeros(mi.Float, 3 * capacity), dr.zeros(mi.Float, 3 * capacity),
                 dr.zeros(mi.Float, 3 * capacity), dr.zeros(mi.Float, capacity), dr.zeros(mi.Float, capacity))


def _scatter3(target: mi.Float, value: mi.Vector3f | mi.Color3f, slot: mi.UInt32, mask: mi.Bool) -> None:
    for c in range(3):
        dr.scatter(target, value[c], slot * 3 + c, mask)


#: ``(colour without the cache, first-hit normal, first-hit t, n_reflection, n_refraction, n_shadow)``
TreeOut = tuple[mi.Color3f, mi.Vector3f, mi.Float, mi.Float, mi.Float, mi.Float]


@syntax
def camera_tree(scene: mi.Scene, ray_o: mi.Point3f, ray_d: mi.Vector3f, active: mi.Bool, data: SceneData,
                lights: PbrLights, rng: Stochastic, f: Features, pixel_angle: mi.Float, nodes: Nodes,
                capacity: mi.UInt32) -> TreeOut:
    """The delta-lobe ray tree of each camera ray (module docstring): returns the colour of everything but the
    cached indirect light and the first hit's AOVs; fills ``nodes`` (at most ``capacity`` entries)."""
    width = dr.width(ray_d)
    stack = ray_stack.create(f.stack_size, width, ray_o, ray_d, data.max_depth + 1)
    travelled = dr.alloc_local(mi.Float, f.stack_size)          # T at each pending ray's origin
    zero_u = dr.zeros(mi.UInt32, width)
    travelled[zero_u] = dr.zeros(mi.Float, width)
    lane = dr.arange(mi.UInt32, width)
    top = dr.select(active, zero_u + 1, zero_u)
    color = dr.zeros(mi.Color3f, width)                          # radiance found so far
    aov_n = dr.zeros(mi.Vector3f, width)                         # first hit's shading normal
    aov_t = dr.full(mi.Float, dr.inf, width)                     # first hit's distance
    first = dr.full(mi.Bool, True, width)                        # the camera ray is being traced
    n_refl = dr.zeros(mi.Float, width)                           # mirror rays pushed
    n_refr = dr.zeros(mi.Float, width)                           # refracted rays pushed
    n_shadow = dr.zeros(mi.Float, width)                         # shadow rays traced
    counter = dr.zeros(mi.UInt32, width)                         # E.5 draw counter
    node = dr.zeros(mi.UInt32, width)                            # nodes popped (E.5 dimensions, Nodes.seq)

    while top > 0:
        top -= 1
        o, d, weight, bounces, n_medium, t_min, origin, _ = ray_stack.pop(stack, top)
        t_origin = travelled[top]
        si, t_hit, p, n, hit, on_plane, plane_idx, row, bsdf = intersect(scene, data.planes, data.rules, o, d,
                                                                         t_min, origin)
        if dr.hint(f.environment, mode="scalar"):               # escaping after the camera or a delta lobe
            color += dr.select(~hit, weight * background(scene, d, ~hit), 0.0)
        if dr.hint(f.area_lights, mode="scalar"):               # a light's shape, seen through delta lobes
            le, _ = emission(scene, lights, si, hit & ~on_plane, o, d, t_hit)
            color += dr.select(hit, weight * le, 0.0)

        b, n = surface_lobes(data, f, bsdf, si, n, d, n_medium, on_plane, plane_idx, hit)
        inside = hit & (bounces > 0)                            # within the budget (else: emission only)
        diffuse = inside & (dr.max(b.kd) > 0.0)
        b_nee = b._replace(p_d=dr.select(diffuse, 1.0, 0.0))    # MIS partner: the cache's cos θ/π rays
        nee, counter, n_shadow = direct(scene, data, lights, False, si, p, b_nee, diffuse,
                                        rng, node * 256, counter, n_shadow)
        color += dr.select(diffuse, weight * nee, 0.0)

        t_node = t_origin + t_hit
        spacing = pixel_angle * t_node * dr.rsqrt(dr.maximum(dr.abs(dr.dot(d, n)), 0.05))
        slot = dr.scatter_inc(nodes.count, mi.UInt32(0), diffuse)
        keep = diffuse & (slot < capacity)
        dr.scatter(nodes.lane, lane, slot, keep)
        dr.scatter(nodes.seq, node, slot, keep)
        _scatter3(nodes.p, p, slot, keep)
        _scatter3(nodes.n, b.n_face, slot, keep)
        _scatter3(nodes.beta, weight * b.kd * dr.inv_pi, slot, keep)
        dr.scatter(nodes.spacing, spacing, slot, keep)
        dr.scatter(nodes.n_medium, n_medium, slot, keep)

        aov_n = dr.select(first & hit, n, aov_n)
        aov_t = dr.select(first & hit, t_hit, aov_t)
        first = dr.full(mi.Bool, False, width)

        go = hit & (bounces > 0)
        push_t = go & (dr.max(b.w_t) > 0.0)
        travelled.write(t_node, top, push_t)
        top = ray_stack.push(stack, top, push_t, p, b.t_dir, weight * b.w_t, bounces - 1, b.nt, data.tmin, row)
        n_refr += dr.select(push_t, 1.0, 0.0)
        push_r = go & (dr.max(b.w_r) > 0.0)
        travelled.write(t_node, top, push_r)
        top = ray_stack.push(stack, top, push_r, p, b.r_dir, weight * b.w_r, bounces - 1, n_medium, data.tmin,
                             row)
        n_refl += dr.select(push_r, 1.0, 0.0)
        node += 1

    return color, aov_n, aov_t, n_refl, n_refr, n_shadow


@syntax
def gather(scene: mi.Scene, ray_o: mi.Point3f, ray_d: mi.Vector3f, first_pdf: mi.Float, first_medium: mi.Float,
           data: SceneData, lights: PbrLights, rng: Stochastic, f: Features,
           rr_depth: mi.UInt32) -> tuple[mi.Color3f, mi.Float, mi.Float]:
    """``(L, r, rays)`` of hemisphere rays ``(ray_o, ray_d)`` leaving a surface (module docstring): the radiance
    arriving along each ray, without what the record's node estimates itself (the environment counts in full;
    a light's shape by the power heuristic of ``first_pdf`` = cos θ/π against its light-sampling pdf), and the
    distance ``r`` to the first hit (+inf for a miss) and the rays each lane cast (traced and shadow rays);
    ``first_medium``: the index of the medium the rays start in."""
    width = dr.width(ray_d)
    o, d = mi.Point3f(ray_o), mi.Vector3f(ray_d)
    beta = dr.full(mi.Color3f, 1.0, width)                       # path throughput
    result = dr.zeros(mi.Color3f, width)                         # radiance gathered
    n_medium = mi.Float(first_medium)                            # index of the medium the ray is in
    depth = dr.zeros(mi.UInt32, width)                           # vertex number along the path
    prev_pdf = mi.Float(first_pdf)                               # pdf of the ray being traced
    prev_delta = dr.full(mi.Bool, False, width)                  # ... drawn from a delta lobe
    origin = dr.zeros(mi.UInt32, width)                          # rule-table row of the face left
    t_min = data.tmin + dr.zeros(mi.Float, width)                # tmin of the ray being traced
    r_first = dr.full(mi.Float, dr.inf, width)                   # distance of the first hit
    n_shadow = dr.zeros(mi.Float, width)                         # shadow rays
    n_traced = dr.zeros(mi.Float, width)                         # rays traced (the hemisphere ray included)
    counter = dr.zeros(mi.UInt32, width)                         # E.5 draw counter
    alive = dr.full(mi.Bool, True, width)                        # lanes still tracing

    while alive:
        si, t_hit, p, n, hit, on_plane, plane_idx, row, bsdf = intersect(scene, data.planes, data.rules, o, d,
                                                                         t_min, origin)
        r_first = dr.select(depth == 0, t_hit, r_first)
        n_traced += dr.select(alive, 1.0, 0.0)
        if dr.hint(f.environment, mode="scalar"):
            le, pdf_l = environment(scene, d, alive & ~hit)
            w = dr.select(prev_delta | (depth == 0), 1.0, power_heuristic(prev_pdf, pdf_l))
            result += dr.select(alive & ~hit, beta * le * w, 0.0)
        if dr.hint(f.area_lights, mode="scalar"):
            le, pdf_l = emission(scene, lights, si, alive & hit & ~on_plane, o, d, t_hit)
            w = dr.select(prev_delta, 1.0, power_heuristic(prev_pdf, pdf_l))
            result += dr.select(alive & hit, beta * le * w, 0.0)
        alive &= hit & (depth < data.max_depth)

        b, n = surface_lobes(data, f, bsdf, si, n, d, n_medium, on_plane, plane_idx, alive)
        nee, counter, n_shadow = direct(scene, data, lights, f.environment, si, p, b, alive,
                                        rng, depth * 256, counter, n_shadow)
        result += dr.select(alive, beta * nee, 0.0)
        u_lobe = mi.sample_tea_float32(rng.pass_key, counter)
        u = light_point(rng, depth * 256 + BSDF_SLOT, counter + 1)
        counter += 3
        s = sample(b, n_medium, u_lobe, u, alive)
        beta = dr.select(alive, beta * s.weight, beta)
        alive &= s.valid
        prev_pdf, prev_delta = s.pdf, s.delta
        o, d, n_medium, origin = mi.Point3f(p), s.wo, s.n_medium, row
        depth += 1

        q = dr.minimum(dr.max(beta), 0.95)                       # Russian roulette (E.14)
        roulette = alive & (depth + 1 >= rr_depth)
        survive = mi.sample_tea_float32(rng.pass_key, counter) < q
        counter += 1
        alive &= ~roulette | survive
        beta = dr.select(roulette & survive, beta / q, beta)

    return result, r_first, n_traced + n_shadow

"""The ``a5_whitted`` kernel: the sample solution's ``traceRay`` (SPEC B.3) for a batch of camera rays.

The recursion of SPEC B.3 is linear in the ray tree: a node at path weight ``w`` adds ``w ⊙ local`` to the
pixel, and its children carry ``w ⊙ specularColor ⊙ R`` (reflection) and ``w ⊙ specularColor ⊙ (1 − R)``
(refraction). :func:`trace_tree` walks that tree depth-first with a stack of pending rays (:mod:`.stack`)
inside one ``@dr.syntax`` while-loop, so the whole render is one kernel. Each popped node reads as SPEC B.3:
intersect, background on a miss, the material, ambient plus the light loop, then the children. The optional
blocks (docs/EXTENSIONS.md E.2, E.4, E.7-E.10, E.15, record mode) are named helpers under
``if dr.hint(f.<feature>, mode='scalar'):``, decided by the :class:`~.features.Features` ``f``; so are the student
mistakes of docs/MISTAKES.md (``if dr.hint("name" in f.mistakes, mode='scalar'):``), which change one step each.
"""

from __future__ import annotations

from typing import NamedTuple

import drjit as dr
import mitsuba as mi

from a5mi.plugins.integrators.whitted import medium_segment, subsurface
from a5mi.plugins.kernel import gloss, lights, pbr_gather, placing
from a5mi.plugins.kernel import stack as ray_stack
from a5mi.plugins.kernel.features import Features, SceneData
from a5mi.plugins.kernel.intersect import intersect, mirror_normal
from a5mi.plugins.kernel.raylog import RayLog
from a5mi.plugins.kernel.record import TreeRecorder, shape_id
from a5mi.plugins.kernel.surfaces import background, surface_at
from a5mi.plugins.materials import spectral
from a5mi.plugins.optics import fresnel_weight, r0_a5, reflect, schlick, snell
from a5mi.plugins.sampling import Stochastic
from a5mi.plugins.syntax import syntax
from a5mi.spec import MIRROR_THRESHOLD

#: Values of the ``class`` AOV: the camera ray misses; the SPEC B.3 ray tree never hits a material with
#: ``refraction_index > 0``; some node of the tree (the last level included) hits one.
MISS, OPAQUE, GLASS = 0, 1, 2



class TreeResult(NamedTuple):
    """What :func:`trace_tree` returns per camera ray: the colour, the first hit's normal ``n`` and distance ``t``
    (SPEC B.6), the ray-tree ``cls`` (:data:`MISS`, :data:`OPAQUE`, :data:`GLASS`) and the rays traced by kind."""

    color: mi.Color3f
    n: mi.Vector3f
    t: mi.Float
    cls: mi.Float
    n_reflection: mi.Float
    n_refraction: mi.Float
    n_shadow: mi.Float


@syntax
def trace_tree(scene: mi.Scene, ray_o: mi.Point3f, ray_d: mi.Vector3f, active: mi.Bool, data: SceneData,
               rng: Stochastic, f: Features, rec: TreeRecorder | None = None,
               log: RayLog | None = None) -> TreeResult:
    """SPEC B.3 for camera rays (unit ``ray_d``, tmin 0, index 1.0, budget ``data.max_depth``).

    Returns ``(colour, first-hit normal, first-hit t, class, n_reflection, n_refraction, n_shadow)``; the
    first-hit normal is the one the binary's hit record holds and its ``-normals`` image shows (SPEC B.6): the
    shading normal, except on a plane, whose normal is as written (unnormalised, as the mirror ray uses it;
    ``Plane { normal 0 -12.6 0 }`` gives ``|n_y| = 12.6``, 255 in the image), with
    ``class = GLASS`` if some node of the ray tree hits a material with ``refraction_index > 0``, else
    ``OPAQUE`` if the camera ray hits, else ``MISS`` (the tree is the one the colour walks). Only ``f`` is
    baked into the kernel; ``data`` and ``rng`` are opaque. ``rec`` (with ``f.record``): the
    :class:`~..whitted_record.TreeRecorder` that each node's values are scattered into. ``log`` (with
    ``f.ray_log``): the :class:`~.raylog.RayLog` that each node ray and shadow ray is written to.
    """
    width = dr.width(ray_d)
    stack = ray_stack.create(f.stack_size, width, ray_o, ray_d, data.max_depth, weighted=f.dispersion)
    lam = None
    if dr.hint(f.dispersion, mode="scalar"):     # E.10: the lane's wavelength
        lam = spectral.lane_wavelength(rng, width)

    zero_u = dr.zeros(mi.UInt32, width)
    top = dr.select(active, zero_u + 1, zero_u)
    first = dr.full(mi.Bool, True, width)
    color = dr.zeros(mi.Color3f, width)
    aov_n = dr.zeros(mi.Vector3f, width)
    aov_t = dr.full(mi.Float, dr.inf, width)
    aov_class = dr.full(mi.Float, float(MISS), width)
    n_refl = dr.zeros(mi.Float, width)
    n_refr = dr.zeros(mi.Float, width)
    n_shadow = dr.zeros(mi.Float, width)
    counter = dr.zeros(mi.UInt32, width)         # E.5: per-lane draw counter
    node = dr.zeros(mi.UInt32, width)            # E.5: ray-tree node number (sampling dimensions)

    while top > 0:
        # (the helpers' NamedTuples are unpacked at once: each value has one name in the loops that carry it)
        top -= 1
        o, d, weight, bounces, n_medium, t_min, origin, weighted = ray_stack.pop(stack, top)
        gathered = None
        if dr.hint(f.indirect > 0, mode="scalar"):   # E.15: the gathered flag rides on origin's top bit
            origin, gathered = pbr_gather.split_origin(origin)
        at = None
        if dr.hint(f.record, mode="scalar"):
            at = rec.index(n_refl, n_refr, top)
        if dr.hint(f.ray_log, mode="scalar"):        # ray-log mode: the node's ray, as intersect casts it
            log.node(o, d, t_min, mi.UInt32(n_refl + n_refr) - top)

        # ---- nearest hit (meshes by the binary's rules, spheres, exact planes); background on a miss
        si, t_hit, p, n, hit, on_plane, plane_idx, row, bsdf = intersect(scene, data.planes, data.rules, o, d,
                                                                         t_min, origin, f.stale_uv)
        if dr.hint(placing.makes(f.mistakes), mode="scalar"):   # MISTAKES.md: N by M, or not normalised
            n = placing.mistaken_normal(f.mistakes, data.planes, data.rules, on_plane, plane_idx, row, n, hit)
        bg = dr.zeros(mi.Color3f, width)
        if dr.hint(f.environment, mode="scalar"):
            if dr.hint("background_wrong_direction" in f.mistakes, mode="scalar"):   # MISTAKES.md: bg(-d)
                bg = background(scene, -d, ~hit)
            else:
                bg = background(scene, d, ~hit)

        # ---- the material; N (bumped with E.7); the mirror direction (planes: about n as written)
        a5, kd, diffuse_color, specular, ior, dispersive, shininess, n, alpha, n_gloss = surface_at(
            bsdf, si, hit, n, f, lam, rng.glossy_cap)
        n_mirror = mirror_normal(data.planes, on_plane, plane_idx, n)
        r_view = reflect(d, n_mirror)
        if dr.hint("mirror_sign" in f.mistakes, mode="scalar"):     # MISTAKES.md: 2(d·N)N - d
            r_view = -r_view

        # ---- local shading: ambient ⊙ diffuseColor + Σ S clamp(L·N) lightColor ⊙ kd
        local = data.ambient * diffuse_color
        if dr.hint("no_ambient" in f.mistakes, mode="scalar"):      # MISTAKES.md: no ambient term
            local = dr.zeros(mi.Color3f, width)
        if dr.hint("ambient_uses_kd" in f.mistakes, mode="scalar"):  # MISTAKES.md: ambient ⊙ kd
            local = data.ambient * kd
        if dr.hint(f.subsurface != "none", mode="scalar"):   # E.18: light under the surface replaces Lambert
            kd, local, counter = subsurface.shade(scene, data, f, bsdf, si, p, d, n, hit, kd, local, rng, counter)
        n_light = n
        if dr.hint("normal_faces_viewer" in f.mistakes, mode="scalar"):   # MISTAKES.md: N flipped toward -d
            n_light = dr.select(dr.dot(d, n) > 0.0, -n, n)
        if dr.hint(f.two_sided, mode="scalar"):      # E.15: the face the ray sees is lit (physical reading)
            n_light = dr.select(dr.dot(d, n) > 0.0, -n, n)
        kd_light = kd
        if dr.hint("kd_ignores_texture" in f.mistakes, mode="scalar"):   # MISTAKES.md: diffuseColor for kd
            kd_light = diffuse_color
        shading = lights.ShadingPoint(si, p, hit, n_light, kd_light, specular, shininess, r_view, bsdf)
        local, counter, n_shadow = lights.direct(scene, data, f, shading, local, rng, node, counter, n_shadow, rec,
                                                 at, log)
        if dr.hint(f.area_lights, mode="scalar"):   # E.2: an area light seen directly
            on_shape = hit & ~on_plane
            if dr.hint(f.indirect > 0, mode="scalar"):   # E.15: not by a gathered ray (the light loop has it)
                on_shape &= ~gathered
            local = lights.emission(scene, si, on_shape, local)

        if dr.hint(f.media, mode="scalar"):         # E.8, E.9: the segment o -> p (o -> infinity on a miss)
            seg_t, seg_light, counter = medium_segment.segment(scene, data, o, d, t_min, t_hit, n_medium == 1.0,
                                                               f.shadows, rng, node, counter)
            color += weight * seg_light
            weight = weight * seg_t
        color += weight * dr.select(hit, local, bg)
        aov_n = dr.select(first & hit, n_mirror, aov_n)   # the hit's normal as the binary stores it (B.6)
        aov_t = dr.select(first & hit, t_hit, aov_t)
        aov_class = dr.select(first & hit, float(OPAQUE), aov_class)   # only the camera ray sets OPAQUE
        aov_class = dr.select(a5 & (ior > 0.0), float(GLASS), aov_class)
        root = mi.Bool(first)
        first = dr.full(mi.Bool, False, width)
        if dr.hint(f.record, mode="scalar"):
            rec.node(at, valid=True, o=o, d=d, tmin=t_min, n_medium=n_medium, weight=weight, bounces=bounces,
                     hit=hit, on_plane=on_plane, plane=plane_idx, shape=shape_id(si.shape), t=t_hit, p=p, n=n,
                     uv=si.uv, a5=a5, diffuse_color=diffuse_color, kd=kd, specular=specular, ior=ior,
                     shininess=shininess, local=local, background=bg,
                     contribution=weight * dr.select(hit, local, bg), color=color)

        # ---- children (SPEC B.3, "if bounces > 0"): refraction, then mirror, each pair weighted by `share`
        go = hit & (bounces > 0)
        glossy = alpha > 0.0
        n_children = dr.select(go & glossy & root, n_gloss, 1)     # E.4: G pairs at a glossy camera hit
        share = 1.0 / mi.Float(n_children)
        leaving = dr.dot(d, n_mirror) > 0.0
        n_side = dr.select(leaving, -n_mirror, n_mirror)            # faces the incoming ray
        t_child = data.tmin
        if dr.hint("secondary_acne" in f.mistakes, mode="scalar"):   # MISTAKES.md: children start at tmin 0
            t_child = dr.zeros(mi.Float, width)
        g = dr.zeros(mi.UInt32, width)
        while go & (g < n_children):
            m_facing, r_dir = n_side, r_view
            if dr.hint(f.glossy, mode="scalar"):                    # E.4: a sampled GGX facet
                m_facing, r_dir, counter = gloss.facet(d, n_side, r_view, alpha, glossy, rng, node, g, n_children,
                                                       counter)
            r_fresnel = dr.full(mi.Float, 1.0, width)               # SPEC R
            if dr.hint(f.refraction, mode="scalar"):
                refractive = go & (ior > 0.0)
                nt = dr.select(leaving, 1.0, ior)
                n_in, n_out, m_snell = n_medium, nt, m_facing
                if dr.hint("eta_inverted" in f.mistakes, mode="scalar"):          # MISTAKES.md: nt/n
                    n_in, n_out = nt, n_medium
                if dr.hint("eta_inside_inverted" in f.mistakes, mode="scalar"):   # MISTAKES.md: 1/ior inside
                    n_in, n_out = dr.select(leaving, nt, n_medium), dr.select(leaving, n_medium, nt)
                if dr.hint("normal_not_flipped_inside" in f.mistakes, mode="scalar"):   # MISTAKES.md: N as is
                    m_snell = n_mirror
                t_dir, exists = snell(d, m_snell, n_in, n_out)
                exists &= ~glossy | (dr.dot(t_dir, n_side) < 0.0)
                push_refr = refractive & exists
                r_fresnel = dr.select(push_refr, fresnel_weight(f.fresnel, d, m_facing, t_dir, n_medium, nt), 1.0)
                if dr.hint("schlick_wrong_c" in f.mistakes, mode="scalar"):   # MISTAKES.md: c from the other ray
                    c = dr.select(nt > n_medium, dr.abs(dr.dot(t_dir, m_facing)), dr.abs(dr.dot(d, m_facing)))
                    r_fresnel = dr.select(push_refr, schlick(c, r0_a5(nt)), 1.0)
                if dr.hint("tir_ignored" in f.mistakes, mode="scalar"):   # MISTAKES.md: R = Schlick(|d·N|) at TIR
                    r_fresnel = dr.select(refractive & ~exists, schlick(dr.abs(dr.dot(d, m_facing)), r0_a5(nt)),
                                          r_fresnel)
                r_mirror = r_fresnel
                if dr.hint("refl_refr_added" in f.mistakes, mode="scalar"):   # MISTAKES.md: refl + refr
                    r_mirror = dr.full(mi.Float, 1.0, width)
                    r_fresnel = dr.zeros(mi.Float, width)
                spec_t = specular
                if dr.hint("refraction_unweighted" in f.mistakes, mode="scalar"):   # MISTAKES.md: no ks
                    spec_t = dr.full(mi.Color3f, 1.0, width)
                w_t = weight * spec_t * (1.0 - r_fresnel) * share
                weighted_t = weighted
                if dr.hint(f.dispersion, mode="scalar"):   # E.10: the first dispersive refraction weighs w(λ)
                    w_t, weighted_t = spectral.weigh(w_t, weighted, dispersive, lam)
                top = ray_stack.push(stack, top, push_refr, p, t_dir, w_t, bounces - 1, nt, t_child, row,
                                     weighted_t)
                n_refr += dr.select(push_refr, 1.0, 0.0)
                if dr.hint(f.record, mode="scalar"):
                    rec.node(at, refractive=refractive, leaving=leaving, nt=nt, refr_exists=exists, t_dir=t_dir,
                             r_fresnel=r_fresnel, push_refr=push_refr,
                             w_refr=weight * spec_t * (1.0 - r_fresnel) * share)
                r_fresnel = r_mirror
            if dr.hint(f.reflection, mode="scalar"):
                push_refl = go & (dr.norm(specular) > MIRROR_THRESHOLD)
                push_refl &= ~glossy | (dr.dot(r_dir, n_side) > 0.0)
                spec_r = specular
                if dr.hint("reflection_unweighted" in f.mistakes, mode="scalar"):   # MISTAKES.md: no ks
                    spec_r = dr.full(mi.Color3f, 1.0, width)
                top = ray_stack.push(stack, top, push_refl, p, r_dir, weight * spec_r * r_fresnel * share,
                                     bounces - 1, n_medium, t_child, row, weighted)
                n_refl += dr.select(push_refl, 1.0, 0.0)
                if dr.hint(f.record, mode="scalar"):
                    rec.node(at, push_refl=push_refl, r_dir=r_dir, r_fresnel=r_fresnel,
                             w_refl=weight * spec_r * r_fresnel * share)
            g += 1
        if dr.hint(f.indirect > 0, mode="scalar"):   # E.15: N cosine-weighted rays gather indirect light
            top, counter, n_refl = pbr_gather.gather(stack, top, go, p, d, n, kd, weight, bounces, n_medium,
                                                     data.tmin, row, weighted, rng, node, counter, n_refl,
                                                     f.indirect)
        node += 1

    return TreeResult(color, aov_n, aov_t, aov_class, n_refl, n_refr, n_shadow)

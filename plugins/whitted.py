"""The ``a5_whitted`` integrator: the sample solution's ``traceRay`` (SPEC B.3) as one Dr.Jit kernel.

The recursion of SPEC B.3 is linear in the ray tree: a node at path weight ``w`` adds ``w ⊙ local`` to the
pixel, and its children carry ``w ⊙ specularColor ⊙ R`` (reflection) and ``w ⊙ specularColor ⊙ (1 - R)``
(refraction). :func:`_trace` walks that tree depth-first with a per-lane ``dr.alloc_local`` stack of pending
rays inside one ``@dr.syntax`` while-loop, so the whole render is a single kernel whose size does not grow
with the bounce budget (a Python recursion unrolled into the trace grows as 2^bounces).
"""

from __future__ import annotations

import drjit as dr
import mitsuba as mi

from a5mi.spec import FRESNEL_MODES, MIRROR_THRESHOLD, TMIN

from . import media, octree_rule, spectral, triangle_rule
from .bump import shading_normal
from .common import fresnel_weight, reflect, snell
from .planes import (
    PlaneSet,
    intersect_planes,
    plane_bsdf,
    plane_mirror_normal,
    plane_normal,
    plane_set,
    planes_from_props,
)
from .sampling import GLOSSY_SLOT, Stochastic, ggx_normal, pixel_keys, stratified_2d
from .syntax import syntax
from .whitted_record import TreeRecorder, shape_id

#: AOV groups of the ``aovs`` parameter (a5mi.options.AOV_GROUPS) and the channels each adds, in order:
#: first-hit shading normal and distance (SPEC B.6), the ray-tree class (:data:`MISS`, :data:`OPAQUE`,
#: :data:`GLASS`), and rays traced per camera ray by kind.
AOV_CHANNELS: dict[str, tuple[str, ...]] = {
    "normal": ("nx", "ny", "nz"),
    "depth": ("t",),
    "class": ("class",),
    "counts": ("n_reflection", "n_refraction", "n_shadow"),
}
#: Values of the ``class`` AOV: the camera ray misses; the SPEC B.3 ray tree never hits a material with
#: ``refraction_index > 0``; some node of the tree (the last level included) hits one.
MISS, OPAQUE, GLASS = 0, 1, 2


def stack_size(max_depth: int, glossy_samples: int = 1) -> int:
    """Pending-ray stack entries for a bounce budget: depth-first, pop one / push two, so ``max_depth + 1``;
    a glossy camera hit pushes ``2 G`` children (docs/EXTENSIONS.md E.4), so ``max_depth + 2 G - 1``.

    Rounded up to at least 8, so every budget from 0 to 7 shares one compiled kernel.
    """
    return max(8, max_depth + 2 * glossy_samples - 1)


def _push(stacks: tuple, top: mi.UInt32, mask: mi.Bool, o: mi.Point3f, d: mi.Vector3f, w: mi.Color3f,
          bounces: mi.UInt32, n_medium: mi.Float, t_min: mi.Float, origin: mi.UInt32, *extra: object) -> mi.UInt32:
    """Push a child ray (origin, direction, path weight, bounces left, medium index, tmin, the rule-table row
    of the mesh face it leaves (0: none; plugins/triangle_rule.py), then one value per extension stack, e.g.
    E.10's "weighted" flag) onto the pending-ray stacks of the lanes in ``mask``; returns the new stack
    pointer."""
    for stack, value in zip(stacks, (o, d, w, bounces, n_medium, t_min, origin, *extra), strict=True):
        stack.write(value, top, mask)
    return top + dr.select(mask, 1, 0)


@syntax
def _trace(
    scene: mi.Scene,
    ray_o: mi.Point3f,
    ray_d: mi.Vector3f,
    active: mi.Bool,
    max_depth: mi.UInt32,
    ambient: mi.Color3f,
    tmin: mi.Float,
    lights: mi.EmitterPtr,
    n_lights: mi.UInt32,
    planes: PlaneSet,
    size: int,
    shadows: bool,
    phong: bool,
    fresnel: str,
    reflection: bool,
    refraction: bool,
    rng: Stochastic,
    rec: TreeRecorder | None = None,
    medium: media.MediumParams | None = None,
    dispersion: bool = False,
    bump: bool = False,
    sample_lights: bool = True,
    sample_gloss: bool = True,
    rules: triangle_rule.RuleTable | None = None,
) -> tuple[mi.Color3f, mi.Vector3f, mi.Float, mi.Float, mi.Float, mi.Float, mi.Float]:
    """SPEC B.3 for a batch of camera rays (unit ``ray_d``, tmin 0, index 1.0, budget ``max_depth``).

    Returns ``(colour, first-hit normal, first-hit t, class, n_reflection, n_refraction, n_shadow)``, with
    ``class = GLASS`` if some node of the ray tree hits a material with ``refraction_index > 0``, else
    ``OPAQUE`` if the camera ray hits, else ``MISS`` (the tree is the one the colour walks, so the push
    rules are the same by construction). Only ``size`` and the Python flags are baked into the kernel;
    scene values arrive as opaque variables or arrays. ``rec`` (``a5mi trace`` only; None for renders, whose
    kernel it leaves untouched): a :class:`~.whitted_record.TreeRecorder` that the marked ``# record`` calls
    fill with each node's values (plugins/whitted_record.py). ``medium`` (docs/EXTENSIONS.md E.8, E.9; None
    leaves the kernel as it is): the node's segment transmittance scales its contribution and its children's
    weights, its in-scattered light is added (plugins/media.py). ``dispersion`` (docs/EXTENSIONS.md E.10): each
    lane carries a wavelength, dispersive materials refract with n(λ) (plugins/spectral.py).
    ``sample_lights`` / ``sample_gloss`` (False when the scene has no area light / no glossy material): leave
    the E.2 / E.4 sampling out of the kernel. ``rules``: the scene's :class:`~.triangle_rule.RuleTable` (None:
    no mesh carries the binary's triangle data, and the kernel has no triangle rule).
    """
    width = dr.width(ray_d)
    env = scene.environment()

    stack_o = dr.alloc_local(mi.Point3f, size)
    stack_d = dr.alloc_local(mi.Vector3f, size)
    stack_w = dr.alloc_local(mi.Color3f, size)
    stack_b = dr.alloc_local(mi.UInt32, size)   # remaining bounces
    stack_n = dr.alloc_local(mi.Float, size)    # index of the medium the ray travels in
    stack_t = dr.alloc_local(mi.Float, size)    # the ray's tmin
    stack_m = dr.alloc_local(mi.UInt32, size)   # rule-table row of the mesh face the ray leaves (0: none)
    stacks = (stack_o, stack_d, stack_w, stack_b, stack_n, stack_t, stack_m)

    zero_u = dr.zeros(mi.UInt32, width)
    stack_o[zero_u] = mi.Point3f(ray_o)
    stack_d[zero_u] = mi.Vector3f(ray_d)
    stack_w[zero_u] = dr.full(mi.Color3f, 1.0, width)
    stack_b[zero_u] = zero_u + max_depth
    stack_n[zero_u] = dr.full(mi.Float, 1.0, width)
    stack_t[zero_u] = dr.zeros(mi.Float, width)
    stack_m[zero_u] = zero_u
    # ---- extension E.10: the lane's wavelength; per pending ray, "weighted by w(λ) already" (plugins/spectral.py)
    lam, stack_s = spectral.start(rng, width, size) if dispersion else (None, None)
    stacks = (*stacks, stack_s) if dispersion else stacks

    top = dr.select(active, zero_u + 1, zero_u)
    first = dr.full(mi.Bool, True, width)
    color = dr.zeros(mi.Color3f, width)
    aov_n = dr.zeros(mi.Vector3f, width)
    aov_t = dr.full(mi.Float, dr.inf, width)
    aov_class = dr.full(mi.Float, float(MISS), width)
    n_refl = dr.zeros(mi.Float, width)
    n_refr = dr.zeros(mi.Float, width)
    n_shadow = dr.zeros(mi.Float, width)
    # ---- extension E.5: per-lane draw counter and ray-tree node number (sampling dimensions)
    pixel_key, pass_key = mi.UInt32(rng.pixel_key), mi.UInt32(rng.pass_key)
    counter = dr.zeros(mi.UInt32, width)
    node = dr.zeros(mi.UInt32, width)

    while top > 0:
        top -= 1
        o = stack_o[top]
        d = stack_d[top]
        weight = stack_w[top]
        bounces = stack_b[top]
        n_medium = stack_n[top]
        t_min = stack_t[top]
        origin = stack_m[top]
        weighted = stack_s[top] if dispersion else None

        # Mitsuba rays have no tmin: start at o + tmin d and add tmin back to t. Planes: analytic (SPEC A.6).
        # Meshes: as the binary's octree sees them (plugins/octree_rule.py).
        si, offset, row = octree_rule.intersect(scene, o, d, t_min, dr.full(mi.Bool, True, width), rules, origin)
        shape_hit = si.is_valid()
        t_hit = dr.select(shape_hit, si.t + offset, dr.inf)
        on_plane, t_hit, plane_idx = intersect_planes(planes, o, d, t_min, t_hit, dr.full(mi.Bool, True, width))
        hit = shape_hit | on_plane
        row = dr.select(on_plane, 0, row)                   # the face the children leave (plugins/octree_rule.py)
        p = o + t_hit * d                                   # SPEC: p = o + t d
        n = dr.select(on_plane, plane_normal(planes, plane_idx, on_plane),
                      mi.Vector3f(si.sh_frame.n))           # SPEC N: not flipped toward the viewer
        si.p = dr.select(hit, p, si.p)
        si.t = dr.select(hit, t_hit, si.t)
        si.n = dr.select(on_plane, n, si.n)
        si.sh_frame = dr.select(on_plane, mi.Frame3f(n), si.sh_frame)
        si.uv = dr.select(on_plane, mi.Point2f(0.0), si.uv)
        si.wi = dr.select(on_plane, si.sh_frame.to_local(-d), si.wi)

        # ---- miss: the background for this ray's direction (camera and secondary rays alike)
        background = dr.zeros(mi.Color3f, width)
        if env is not None:
            si_env = dr.zeros(mi.SurfaceInteraction3f, width)
            si_env.wi = -d
            background = mi.Color3f(env.eval(si_env, ~hit))

        # ---- the material, through the vcall-able BSDF attribute interface
        bsdf = dr.select(on_plane, plane_bsdf(planes, plane_idx, on_plane), si.bsdf())
        a5 = bsdf.has_attribute("diffuse_color", hit) & hit
        kd = mi.Color3f(bsdf.eval_diffuse_reflectance(si, hit))
        diffuse_color = dr.select(a5, bsdf.eval_attribute_3("diffuse_color", si, a5), kd)
        specular = bsdf.eval_attribute_3("specular_color", si, a5)
        ior = bsdf.eval_attribute_1("refraction_index", si, a5)
        ior, dispersive = spectral.index_at(bsdf, si, a5, ior, lam) if dispersion else (ior, None)  # E.10: n(λ)
        shininess = mi.Float(0.0)
        if phong:
            shininess = bsdf.eval_attribute_1("shininess", si, a5)
        if bump:  # docs/EXTENSIONS.md E.7: the bump / normal-mapped N for lights, mirror and refraction
            n = shading_normal(bsdf, si, n, a5)
        # The binary mirrors (and refracts) off a plane with its normal as written (plugins/planes.py).
        r_view = reflect(d, dr.select(on_plane, plane_mirror_normal(planes, plane_idx, on_plane), n))
        # ---- extension E.2: the emitter seen by this ray (an AreaLight / SphereLight shape), E.4: gloss
        sees_light, emitter_hit = mi.Bool(False), dr.zeros(mi.EmitterPtr, 1)
        if sample_lights:
            emitter_hit = si.emitter(scene, hit & ~on_plane)
            sees_light = hit & ~on_plane & (emitter_hit != None)  # noqa: E711 - a Dr.Jit pointer comparison
        alpha, n_gloss = mi.Float(0.0), mi.UInt32(1)
        if sample_gloss:
            alpha = bsdf.eval_attribute_1("roughness", si, a5)
            n_gloss = dr.minimum(mi.UInt32(dr.maximum(bsdf.eval_attribute_1("glossy_samples", si, a5), 1.0)),
                                 rng.glossy_cap)

        # ---- local shading: ambient ⊙ diffuseColor + Σ S clamp(L·N) lightColor ⊙ kd
        local = ambient * diffuse_color
        k = dr.zeros(mi.UInt32, width)
        while hit & (k < n_lights):
            emitter = dr.gather(mi.EmitterPtr, lights, k, hit)
            # extension E.2: S stratified samples of an area light (S = 1 and the sample unused for the others)
            n_samples = dr.gather(mi.UInt32, rng.light_samples, k, hit)
            is_area = dr.gather(mi.UInt32, rng.light_area, k, hit) > 0
            acc = dr.zeros(mi.Color3f, width)
            j = dr.zeros(mi.UInt32, width)
            while hit & (j < n_samples):
                u = mi.Point2f(0.5)
                if sample_lights:
                    u = stratified_2d(pixel_key, pass_key, node * 256 + k, rng.pass_index * n_samples + j,
                                      rng.passes * n_samples, counter)
                counter += 2
                ds, light_color = emitter.sample_direction(si, u, hit)
                d_light = ds.d                                   # SPEC L
                dist = dr.select(is_area, ds.dist * (1.0 - 1e-4), ds.dist)  # not the light's own shape
                visible = mi.Bool(hit)                           # SPEC S
                if shadows:
                    visible &= ~octree_rule.occluded(scene, p, d_light, tmin, dist, hit)
                    # Planes block up to the light; a directional light (Infinite) is at FLT_MAX in the binary.
                    far = (emitter.flags() & int(mi.EmitterFlags.Infinite)) != 0
                    blocked, _, _ = intersect_planes(planes, p, d_light, tmin,
                                                     dr.select(far, dr.inf, dist), visible)
                    visible &= ~blocked
                    n_shadow += dr.select(hit, 1.0, 0.0)
                    if rec is not None:  # record: the occluder's identity (a nearest-hit query of its own)
                        rec.occluder(scene, planes, n_refl, n_refr, top, k, p, d_light, tmin, dist, far, hit)
                term = dr.maximum(dr.dot(d_light, n), 0.0) * light_color * kd
                if phong:
                    l_dot_r = dr.maximum(dr.dot(d_light, dr.normalize(r_view)), 0.0)
                    highlight = dr.select(shininess == 0.0, 1.0, dr.power(l_dot_r, shininess))
                    term += highlight * light_color * specular
                    if rec is not None:  # record
                        rec.light(n_refl, n_refr, top, k, highlight=highlight)
                acc += dr.select(visible, term, 0.0)
                if rec is not None:  # record (an area light keeps its last sample's ray and verdict)
                    rec.light(n_refl, n_refr, top, k, valid=hit, L=d_light, n_dot_l=dr.dot(d_light, n),
                              light_color=light_color, dist=ds.dist, visible=visible, tested=shadows,
                              term=term * (1.0 / mi.Float(dr.maximum(n_samples, 1))))
                j += 1
            local += acc * (1.0 / mi.Float(dr.maximum(n_samples, 1)))
            k += 1
        if sample_lights:
            local = dr.select(sees_light, local + mi.Color3f(emitter_hit.eval(si, sees_light)), local)

        if medium is not None:  # ---- extensions E.8, E.9: the segment o -> p (o -> infinity on a miss), in air
            seg_t, seg_light, counter = media.segment(scene, planes, medium, o, d, t_min, t_hit, n_medium == 1.0,
                                                      lights, n_lights, tmin, shadows, rng, node, counter)
            color += weight * seg_light
            weight = weight * seg_t
        color += weight * dr.select(hit, local, background)
        aov_n = dr.select(first & hit, n, aov_n)
        aov_t = dr.select(first & hit, t_hit, aov_t)
        aov_class = dr.select(first & hit, float(OPAQUE), aov_class)   # only the camera ray sets OPAQUE
        aov_class = dr.select(a5 & (ior > 0.0), float(GLASS), aov_class)
        root = mi.Bool(first)
        first = dr.full(mi.Bool, False, width)
        if rec is not None:  # record
            rec.node(n_refl, n_refr, top, valid=True, o=o, d=d, tmin=t_min, n_medium=n_medium, weight=weight,
                     bounces=bounces, hit=hit, on_plane=on_plane, plane=plane_idx, shape=shape_id(si.shape),
                     t=t_hit, p=p, n=n, uv=si.uv, a5=a5, diffuse_color=diffuse_color, kd=kd, specular=specular,
                     ior=ior, shininess=shininess, local=local, background=background,
                     contribution=weight * dr.select(hit, local, background), color=color)

        # ---- children: mirror and refraction (SPEC B.3, "if bounces > 0"). Extension E.4: with roughness
        # alpha > 0 both children use a sampled GGX microfacet normal m instead of N (m = N for alpha = 0), a
        # camera hit pushes G = glossySamples such pairs with weight 1/G, and a child on the wrong side of the
        # surface is dropped.
        go = hit & (bounces > 0)
        glossy = alpha > 0.0
        n_children = dr.select(go & glossy & root, n_gloss, 1)
        share = 1.0 / mi.Float(n_children)
        # Planes refract about the binary's normal too (as written outside a Transform; measured).
        n_r = dr.select(on_plane, plane_mirror_normal(planes, plane_idx, on_plane), n)
        leaving = dr.dot(d, n_r) > 0.0
        n_side = dr.select(leaving, -n_r, n_r)              # faces the incoming ray
        g = dr.zeros(mi.UInt32, width)
        while go & (g < n_children):
            m_facing = n_side
            r_dir = r_view
            u_g = mi.Point2f(0.5)
            if sample_gloss:
                u_g = stratified_2d(pixel_key, pass_key, node * 256 + GLOSSY_SLOT, rng.pass_index * n_children + g,
                                    rng.passes * n_children, counter)   # E.4 lobe sample (unused for alpha = 0)
            counter += dr.select(glossy, 2, 0)
            m_facing = dr.select(glossy, ggx_normal(n_side, alpha, u_g), n_side)
            r_dir = dr.select(glossy, reflect(d, m_facing), r_view)
            r_fresnel = dr.full(mi.Float, 1.0, width)           # SPEC R
            push_refr = mi.Bool(False)
            t_dir = dr.zeros(mi.Vector3f, width)
            nt = mi.Float(n_medium)
            if refraction:
                refractive = go & (ior > 0.0)
                nt = dr.select(leaving, 1.0, ior)
                t_dir, exists = snell(d, m_facing, n_medium, nt)
                exists &= ~glossy | (dr.dot(t_dir, n_side) < 0.0)
                push_refr = refractive & exists
                r_fresnel = dr.select(push_refr, fresnel_weight(fresnel, d, m_facing, t_dir, n_medium, nt), 1.0)
                w_t = weight * specular * (1.0 - r_fresnel) * share
                # E.10: the first dispersive refraction of a path multiplies its weight by w(λ)
                w_t, tail_t = spectral.weigh(w_t, weighted, dispersive, lam) if dispersion else (w_t, ())
                top = _push(stacks, top, push_refr, p, t_dir, w_t, bounces - 1, nt, tmin, row, *tail_t)
                n_refr += dr.select(push_refr, 1.0, 0.0)
                if rec is not None:  # record
                    rec.node(n_refl, n_refr, top, refractive=refractive, leaving=leaving, nt=nt, refr_exists=exists,
                             t_dir=t_dir, r_fresnel=r_fresnel, push_refr=push_refr,
                             w_refr=weight * specular * (1.0 - r_fresnel) * share)
            if reflection:
                push_refl = go & (dr.norm(specular) > MIRROR_THRESHOLD)
                push_refl &= ~glossy | (dr.dot(r_dir, n_side) > 0.0)
                top = _push(stacks, top, push_refl, p, r_dir, weight * specular * r_fresnel * share, bounces - 1,
                            n_medium, tmin, row, *((weighted,) if dispersion else ()))
                n_refl += dr.select(push_refl, 1.0, 0.0)
                if rec is not None:  # record
                    rec.node(n_refl, n_refr, top, push_refl=push_refl, r_dir=r_dir, r_fresnel=r_fresnel,
                             w_refl=weight * specular * r_fresnel * share)
            g += 1
        node += 1

    return color, aov_n, aov_t, aov_class, n_refl, n_refr, n_shadow


def _width(ray: mi.Ray3f, active: mi.Bool | bool) -> int:
    """Number of lanes of a ray batch: the widest of origin, direction and mask."""
    return max(dr.width(ray.o), dr.width(ray.d), dr.width(active) if isinstance(active, mi.Bool) else 1)


class A5WhittedIntegrator(mi.SamplingIntegrator):
    """Whitted ray tracing exactly as the sample solution ``a5soln`` does it (SPEC B.3).

    ================ ======= ======= ==========================================================
    parameter        type    default meaning
    ================ ======= ======= ==========================================================
    max_depth        int     4       bounce budget (``-bounces``); 0 = no secondary rays
    shadows          bool    false   shadow rays (``-shadows``), blocked by 0.001 < t < dist
    ambient          rgb     0       ambient light (``Background { ambientLight }``)
    phong            bool    false   add the handout's ``clamp(L·R)^shininess lightColor ⊙ ks``
    fresnel          string  a5      ``a5`` (binary's R0), ``schlick`` (textbook R0), ``exact``
    reflection       bool    true    trace mirror rays (``-reflection_off`` = false)
    refraction       bool    true    trace refracted rays (``-refraction_off`` = false)
    tmin             float   0.001   tmin of secondary and shadow rays (``a5mi.spec.TMIN``)
    glossy_samples   int     1       cap on the glossy children of a camera hit (docs/EXTENSIONS.md E.4)
    dispersion       bool    false   wavelength per camera ray, Cauchy n(λ) (docs/EXTENSIONS.md E.10)
    bump             bool    false   bump / normal-mapped shading normal (``-bump``, docs/EXTENSIONS.md E.7)
    glossy           bool    true    false: no material has roughness > 0 (the E.4 lobe sampling is
                                     left out of the kernel; the converter says so for its scenes)
    aovs             string  ""      comma-separated AOV groups: ``normal`` (nx, ny, nz), ``depth``
                                     (t), ``class`` (class), ``counts`` (n_reflection, n_refraction,
                                     n_shadow)
    medium           string  none    ``fog`` / ``volume``: a participating medium (EXTENSIONS E.8,
                                     E.9; ``medium_*`` parameters, plugins/media.py)
    ================ ======= ======= ==========================================================

    Per hit (``p = o + t d``, ``N`` the shading normal, never flipped toward the viewer)::

        colour = ambient ⊙ diffuseColor + Σ_lights S · max(L·N, 0) · lightColor ⊙ kd
               + specularColor ⊙ (R · trace(reflect(d, N)) + (1 - R) · trace(T))

    The mirror ray exists when ``|specularColor| > 0.001``; the refracted one when ``refractionIndex > 0``
    and Snell has a solution (inside/outside by the sign of d·N, then ``nt = 1`` or ``refractionIndex``);
    without it (or under total internal reflection) ``R = 1``. ``R = R0 + (1 - R0)(1 - c)^5`` with
    ``c = |d·N|`` if ``nt > n`` else ``|T·N|`` and ``R0 = ((nt-1)/(nt+1))²`` (``a5``, the binary) or
    ``((nt-n)/(nt+n))²`` (``schlick``); ``exact`` uses ``mi.fresnel``. With ``refraction = false`` the whole
    refraction branch is skipped (``R = 1``). Misses return ``scene.environment()`` for the ray's direction,
    black without one. Lights are the emitters with a delta flag and the ``a5_area`` emitters
    (``sample_direction`` gives ``L``, the arriving colour and the distance; stock ``directional`` reports
    ``2 max(R, |p - c|)`` for the scene's bounding sphere, always past every object, so its shadow test equals
    the binary's FLT_MAX; an ``a5_area`` light is sampled ``samples`` times, docs/EXTENSIONS.md E.2).

    ``sample()`` treats its ray as a camera ray (unit direction, tmin 0, index 1) and returns the colour,
    the ``active`` mask, and the AOVs asked for by ``aovs`` (none by default, so ``mi.render`` gives RGB):
    ``nx, ny, nz, t`` of the first hit (0 and +inf on a miss); ``class`` = 0 (the camera ray misses),
    1 (opaque: no node of the ray tree hits a material with ``refraction_index > 0``) or 2 (glass: some
    node does, the last level included); the ray counts.

    Dict form: ``{'type': 'a5_whitted', 'max_depth': 4, 'shadows': True, 'ambient': {'type': 'rgb',
    'value': [0.1, 0.1, 0.1]}}``.
    """

    def __init__(self, props: mi.Properties) -> None:
        super().__init__(props)
        max_depth = props.get("max_depth", 4)
        if isinstance(max_depth, bool) or not isinstance(max_depth, int) or max_depth < 0:
            raise ValueError(f"a5_whitted: 'max_depth' must be an integer >= 0, got {max_depth!r}")
        fresnel = props.get("fresnel", "a5")
        if fresnel not in FRESNEL_MODES:
            raise ValueError(f"a5_whitted: 'fresnel' must be one of {', '.join(FRESNEL_MODES)}, got {fresnel!r}")
        tmin = props.get("tmin", TMIN)
        if isinstance(tmin, bool) or not isinstance(tmin, (int, float)) or not 0.0 <= tmin < float("inf"):
            raise ValueError(f"a5_whitted: 'tmin' must be a finite number >= 0, got {tmin!r}")
        ambient = props.get("ambient", mi.ScalarColor3d(0.0))
        try:
            if isinstance(ambient, str):
                raise TypeError
            ambient_rgb = [float(ambient)] * 3 if isinstance(ambient, (int, float)) else [
                float(ambient[i]) for i in range(3)]
        except (TypeError, IndexError, ValueError):
            raise ValueError(f"a5_whitted: 'ambient' must be an rgb colour, got {ambient!r}") from None
        flags = {}
        for name, default in (("shadows", False), ("phong", False), ("reflection", True),
                              ("refraction", True), ("dispersion", False), ("bump", False), ("glossy", True)):
            value = props.get(name, default)
            if not isinstance(value, bool):
                raise ValueError(f"a5_whitted: '{name}' must be a boolean, got {value!r}")
            flags[name] = value
        self.max_depth = max_depth
        self.fresnel = fresnel
        self.tmin = float(tmin)
        self.ambient = ambient_rgb
        self.shadows = flags["shadows"]
        self.phong = flags["phong"]
        self.reflection = flags["reflection"]
        self.refraction = flags["refraction"]
        self.dispersion = flags["dispersion"]  # docs/EXTENSIONS.md E.10
        self.bump = flags["bump"]  # docs/EXTENSIONS.md E.7
        self.glossy = flags["glossy"]  # False: no glossy material (E.4), its lobe sampling stays out of the kernel
        aovs = props.get("aovs", "")
        groups = [g.strip() for g in aovs.split(",") if g.strip()] if isinstance(aovs, str) else None
        if groups is None or any(g not in AOV_CHANNELS for g in groups):
            raise ValueError(f"a5_whitted: 'aovs' must list groups of {', '.join(AOV_CHANNELS)}, got {aovs!r}")
        self.aovs = tuple(g for g in AOV_CHANNELS if g in groups)
        self.planes = planes_from_props(props)
        self._planes = plane_set(self.planes)
        glossy_samples = props.get("glossy_samples", 1)  # docs/EXTENSIONS.md E.4: cap on glossy children
        if isinstance(glossy_samples, bool) or not isinstance(glossy_samples, int) or glossy_samples < 1:
            raise ValueError(f"a5_whitted: 'glossy_samples' must be an integer >= 1, got {glossy_samples!r}")
        self.glossy_samples = glossy_samples
        self._pass: tuple[int, int, int, int] | None = None
        self._medium = media.params_from_props(props)   # docs/EXTENSIONS.md E.8, E.9 (None: no medium)
        self._rules: dict[int, triangle_rule.RuleTable] = {}   # id(scene) -> its rule table (the last scene only)

    def set_pass(self, first_pixel: int, index: int, count: int, seed: int) -> None:
        """Extension E.5 (called by ``a5mi.passes.sample_passes`` before each ``sample``): lane ``i`` of the next
        batch is render-buffer sample ``first_pixel + i``, in pass ``index`` of ``count`` (``-spp``), with ``seed``.
        Without it (``mi.render``), a lane's key comes from the sampler and every pass is independent."""
        self._pass = (int(first_pixel), int(index), int(count), int(seed) & 0xFFFFFFFF)

    def _stochastic(self, scene: mi.Scene, sampler: mi.Sampler | None, width: int) -> Stochastic:
        """The :class:`Stochastic` state of a batch: keys from :meth:`set_pass` (or the sampler)."""
        emitters = [e for e in scene.emitters() if self._is_light(e)]
        samples = [int(getattr(e, "samples", 1)) for e in emitters] or [1]
        area = [1 if hasattr(e, "samples") else 0 for e in emitters] or [0]
        if self._pass is not None:
            first, index, count, seed = self._pass
            pixel = dr.arange(mi.UInt32, width) + dr.opaque(mi.UInt32, first)
        else:
            index, count, seed = 0, 1, 0
            rnd = sampler.next_1d() if sampler is not None else dr.zeros(mi.Float, width)
            pixel = mi.UInt32(rnd * 16777216.0) + dr.zeros(mi.UInt32, width)
        pixel_key, pass_key = pixel_keys(pixel, dr.opaque(mi.UInt32, seed), dr.opaque(mi.UInt32, index))
        return Stochastic(pixel_key, pass_key, dr.opaque(mi.UInt32, index), dr.opaque(mi.UInt32, count),
                          mi.UInt32(samples), mi.UInt32(area), dr.opaque(mi.UInt32, self.glossy_samples))

    @staticmethod
    def _is_light(e: mi.Emitter) -> bool:
        """A light of the light loop: a delta emitter (SPEC A.3, E.1) or an ``a5_area`` emitter (E.2)."""
        return mi.has_flag(e.flags(), mi.EmitterFlags.Delta) or hasattr(e, "samples")

    # ------------------------------------------------------------------ Mitsuba interface

    def aov_names(self) -> list[str]:
        return [name for g in self.aovs for name in AOV_CHANNELS[g]]

    def _lights(self, scene: mi.Scene) -> tuple[mi.EmitterPtr, mi.UInt32]:
        """The scene's lights (:meth:`_is_light`: delta and ``a5_area`` emitters) as a gatherable pointer array,
        and their count (opaque)."""
        emitters = scene.emitters()
        idx = [i for i, e in enumerate(emitters) if self._is_light(e)]
        if not idx:
            return dr.zeros(mi.EmitterPtr, 1), dr.opaque(mi.UInt32, 0)
        ptrs = dr.gather(mi.EmitterPtr, scene.emitters_dr(), mi.UInt32(idx))
        dr.eval(ptrs)
        return ptrs, dr.opaque(mi.UInt32, len(idx))

    def _rule_table(self, scene: mi.Scene) -> triangle_rule.RuleTable | None:
        """The scene's triangle-rule table (plugins/triangle_rule.py), kept while its buffers are unchanged."""
        cached = self._rules.get(id(scene))
        table = triangle_rule.rule_table(scene, cached)
        self._rules = {id(scene): table} if table is not None else {}
        return table

    def trace(
        self, scene: mi.Scene, ray: mi.Ray3f, active: mi.Bool | bool = True, sampler: mi.Sampler | None = None,
        record: TreeRecorder | None = None,
    ) -> tuple[mi.Color3f, mi.Vector3f, mi.Float, mi.Float, mi.Float, mi.Float, mi.Float]:
        """SPEC B.3 for camera rays: ``(colour, normal, t, class, n_reflection, n_refraction, n_shadow)``;
        ``record`` (``a5mi trace``): fill this recorder with every node of each lane's ray tree."""
        lights, n_lights = self._lights(scene)
        width = _width(ray, active)
        # Every loop variable must be full width (a width-1 stack pointer makes lanes loop forever).
        o = mi.Point3f(ray.o) + dr.zeros(mi.Point3f, width)
        d = mi.Vector3f(ray.d) + dr.zeros(mi.Vector3f, width)
        return _trace(
            scene, o, d, dr.full(mi.Bool, True, width) & active,
            dr.opaque(mi.UInt32, self.max_depth), dr.opaque(mi.Color3f, self.ambient),
            dr.opaque(mi.Float, self.tmin), lights, n_lights, self._planes,
            stack_size(self.max_depth, self.glossy_samples), self.shadows, self.phong, self.fresnel,
            self.reflection, self.refraction, self._stochastic(scene, sampler, width), record, self._medium,
            dispersion=self.dispersion, bump=self.bump,
            sample_lights=any(hasattr(e, "samples") or e.get_shape() is not None for e in scene.emitters()),
            sample_gloss=self.glossy, rules=self._rule_table(scene),
        )

    def sample(
        self, scene: mi.Scene, sampler: mi.Sampler | None, ray: mi.Ray3f, medium: mi.Medium | None = None,
        active: mi.Bool | bool = True,
    ) -> tuple[mi.Color3f, mi.Bool, list[mi.Float]]:
        """Colour of one camera ray per lane, the ``active`` mask, and the AOVs of :meth:`aov_names`."""
        color, n, t, cls, n_refl, n_refr, n_shadow = self.trace(scene, ray, active, sampler)
        channels = {"normal": [n.x, n.y, n.z], "depth": [t], "class": [cls], "counts": [n_refl, n_refr, n_shadow]}
        aovs = [a for g in self.aovs for a in channels[g]]
        width = _width(ray, active)
        return color, dr.full(mi.Bool, True, width) & active, aovs

    def traverse(self, callback: mi.TraversalCallback) -> None:
        flags = int(mi.ParamFlags.NonDifferentiable)
        callback.put("max_depth", self.max_depth, flags)
        callback.put("shadows", self.shadows, flags)
        callback.put("ambient", mi.ScalarColor3f(self.ambient), flags)
        callback.put("phong", self.phong, flags)
        callback.put("fresnel", self.fresnel, flags)
        callback.put("reflection", self.reflection, flags)
        callback.put("refraction", self.refraction, flags)
        callback.put("tmin", self.tmin, flags)
        callback.put("aovs", ",".join(self.aovs), flags)
        callback.put("glossy_samples", self.glossy_samples, flags)
        callback.put("dispersion", self.dispersion, flags)
        callback.put("bump", self.bump, flags)
        callback.put("glossy", self.glossy, flags)

    def to_string(self) -> str:
        return (
            f"A5WhittedIntegrator[max_depth={self.max_depth}, shadows={self.shadows}, "
            f"ambient={self.ambient}, phong={self.phong}, fresnel='{self.fresnel}', "
            f"reflection={self.reflection}, refraction={self.refraction}, tmin={self.tmin}, "
            f"aovs='{','.join(self.aovs)}', glossy_samples={self.glossy_samples}, "
            f"dispersion={self.dispersion}, bump={self.bump}, glossy={self.glossy}, "
            f"medium='{self._medium.kind if self._medium is not None else 'none'}', planes={len(self.planes)}]"
        )


def register() -> None:
    """Register ``a5_whitted`` with Mitsuba for the active variant."""
    mi.register_integrator("a5_whitted", lambda props: A5WhittedIntegrator(props))

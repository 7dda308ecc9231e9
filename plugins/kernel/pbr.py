"""The physically based reading of an a5 Material: a BSDF (docs/EXTENSIONS.md E.13), for ``@dr.syntax`` kernels.

SPEC A.5's Material read as a BSDF at a hit with incoming unit direction ``d`` (toward the surface), shading
normal ``N`` (SPEC B.3, not flipped; the mirror normal of :func:`.intersect.mirror_normal` for the delta lobes),
``kd`` (Lambert colour), ``ks = specularColor`` and ``η = refractionIndex`` (:class:`.surfaces.Surface`)::

    f(d, ω) = kd/π · [ω on the side of d's origin]                       two-sided Lambert
            + ks · R · δ(ω − reflect(d, N))                    if |ks| > 0.001 (SPEC B.3 mirror rule)
            + ks · (1 − R) · (n/nt)² · δ(ω − T)                if η > 0 and Snell has a solution T

``R`` is SPEC B.3's reflected fraction by the ``-fresnel`` mode (:func:`plugins.common.fresnel_weight`:
``a5`` / ``schlick`` / ``exact``), ``R = 1`` without refraction or under total internal reflection; ``n`` is
the index of the medium the ray travels in (1 for camera rays, the index it refracted into after that),
``nt = 1`` when ``d·N > 0`` (leaving) else ``η``. The factor ``(n/nt)²`` is the radiance rule of refraction:
radiance is scaled by ``1/η²`` entering glass and by ``η²`` leaving it (Mitsuba's ``dielectric`` in radiance
mode), so it cancels on every path from an outside camera to an outside light. The ambient term is off;
``roughness`` (E.4) and ``shininess`` (the handout's Phong option) are not part of the reading.

Sampling: one lobe chosen with probability proportional to the mean of its weight (``kd``, ``ks·R``,
``ks·(1 − R)(n/nt)²``); the Lambert lobe draws ``ω`` cosine-weighted about the side of ``N`` that ``d`` comes
from (``pdf = P_d cos θ/π``), so its sample weight is ``f |cos θ| / pdf = kd / P_d``; a delta lobe's weight is
its weight divided by its probability, with ``pdf = 0`` and ``delta = True``. :func:`eval_diffuse` gives the
non-delta part ``f |cos θ|`` and the solid-angle pdf that a sample would have, for next-event estimation and
multiple importance sampling.
"""

from __future__ import annotations

from typing import NamedTuple

import drjit as dr
import mitsuba as mi

from a5mi.plugins.optics import fresnel_weight, reflect, snell
from a5mi.spec import MIRROR_THRESHOLD


class Lobes(NamedTuple):
    """The BSDF of one hit (module docstring): ``kd`` (Lambert albedo), ``n_face`` (``N`` turned toward the
    side ``d`` comes from: the Lambert hemisphere), the delta directions ``r_dir`` / ``t_dir`` with weights
    ``w_r = ks·R`` and ``w_t = ks(1 − R)(n/nt)²`` (0 where the lobe does not exist), ``nt`` (the index behind the
    refracted ray), ``r_fresnel`` (SPEC ``R``) and the lobe probabilities ``p_d``, ``p_r``, ``p_t`` (sum 1, or
    all 0 for a black material)."""

    kd: mi.Color3f
    n_face: mi.Vector3f
    r_dir: mi.Vector3f
    t_dir: mi.Vector3f
    w_r: mi.Color3f
    w_t: mi.Color3f
    nt: mi.Float
    r_fresnel: mi.Float
    p_d: mi.Float
    p_r: mi.Float
    p_t: mi.Float


class Scatter(NamedTuple):
    """A sampled direction (:func:`sample`): ``wo`` (unit), ``weight`` (``f |cos θ| / pdf``, the lobe's weight
    over its probability), ``pdf`` (solid angle; 0 for a delta lobe), ``delta``, ``n_medium`` (the index the
    ray travels in afterwards) and ``valid`` (False: the path is absorbed)."""

    wo: mi.Vector3f
    weight: mi.Color3f
    pdf: mi.Float
    delta: mi.Bool
    n_medium: mi.Float
    valid: mi.Bool


def _mean(c: mi.Color3f) -> mi.Float:
    return (c.x + c.y + c.z) * (1.0 / 3.0)


def lobes(fresnel: str, kd: mi.Color3f, ks: mi.Color3f, ior: mi.Float, d: mi.Vector3f, n: mi.Vector3f,
          n_mirror: mi.Vector3f, n_medium: mi.Float, hit: mi.Bool, refraction: bool = True,
          reflection: bool = True) -> Lobes:
    """The :class:`Lobes` of a hit (module docstring). ``n``: shading normal (Lambert side), ``n_mirror``: the
    normal the delta lobes turn about (SPEC B.3; planes: as written), ``n_medium``: the index the incoming ray
    travels in, ``fresnel``: the ``-fresnel`` mode, ``refraction``: False reads every material as opaque,
    ``reflection``: False drops the mirror lobe (``-reflection_off``; the refracted lobe keeps ``1 − R``)."""
    n_face = dr.select(dr.dot(d, n) < 0.0, n, -n)
    leaving = dr.dot(d, n_mirror) > 0.0
    n_side = dr.normalize(dr.select(leaving, -n_mirror, n_mirror))       # faces the incoming ray
    r_dir = dr.normalize(reflect(d, n_mirror))
    r_fresnel = dr.full(mi.Float, 1.0, dr.width(d))
    t_dir = dr.zeros(mi.Vector3f, dr.width(d))
    nt = mi.Float(n_medium)
    w_t = dr.zeros(mi.Color3f, dr.width(d))
    if refraction:
        refractive = hit & (ior > 0.0)
        nt = dr.select(leaving, 1.0, ior)
        t_dir, exists = snell(d, n_side, n_medium, nt)
        refracts = refractive & exists
        r_fresnel = dr.select(refracts, fresnel_weight(fresnel, d, n_side, t_dir, n_medium, nt), 1.0)
        eta = n_medium / dr.select(refracts, nt, 1.0)
        w_t = dr.select(refracts, ks * (1.0 - r_fresnel) * (eta * eta), 0.0)
        nt = dr.select(refracts, nt, n_medium)
    w_r = dr.select(hit & (dr.norm(ks) > MIRROR_THRESHOLD) & reflection, ks * r_fresnel, 0.0)
    kd = dr.select(hit, kd, 0.0)
    m_d, m_r, m_t = dr.maximum(_mean(kd), 0.0), dr.maximum(_mean(w_r), 0.0), dr.maximum(_mean(w_t), 0.0)
    total = m_d + m_r + m_t
    inv = dr.select(total > 0.0, 1.0 / total, 0.0)
    return Lobes(kd, n_face, r_dir, t_dir, w_r, w_t, nt, r_fresnel, m_d * inv, m_r * inv, m_t * inv)


def eval_diffuse(b: Lobes, wo: mi.Vector3f) -> tuple[mi.Color3f, mi.Float]:
    """``(f |cos θ|, pdf)`` of the non-delta part for the unit direction ``wo``: ``kd/π · cos θ`` and
    ``P_d cos θ/π`` with ``cos θ = wo·n_face`` on the Lambert side, both 0 on the other."""
    cos = dr.maximum(dr.dot(wo, b.n_face), 0.0)
    return b.kd * (cos * dr.inv_pi), b.p_d * cos * dr.inv_pi


def sample(b: Lobes, n_medium: mi.Float, u_lobe: mi.Float, u: mi.Point2f, active: mi.Bool) -> Scatter:
    """One :class:`Scatter` of the lanes ``active``: lobe by ``u_lobe`` (uniform in [0, 1)), the Lambert
    direction by ``u`` (cosine-weighted hemisphere about ``n_face``); see the module docstring."""
    diffuse = active & (u_lobe < b.p_d)
    mirror = active & ~diffuse & (u_lobe < b.p_d + b.p_r)
    refract = active & ~diffuse & ~mirror & (b.p_t > 0.0)
    local = mi.warp.square_to_cosine_hemisphere(u)
    wo_d = mi.Frame3f(b.n_face).to_world(local)
    wo = dr.select(diffuse, wo_d, dr.select(mirror, b.r_dir, b.t_dir))
    weight = dr.select(diffuse, b.kd / dr.maximum(b.p_d, 1e-30),
                       dr.select(mirror, b.w_r / dr.maximum(b.p_r, 1e-30), b.w_t / dr.maximum(b.p_t, 1e-30)))
    pdf = dr.select(diffuse, b.p_d * mi.warp.square_to_cosine_hemisphere_pdf(local), 0.0)
    valid = diffuse & (local.z > 0.0) | mirror | refract
    n_next = dr.select(refract, b.nt, n_medium)
    return Scatter(wo, dr.select(valid, weight, 0.0), pdf, ~diffuse, n_next, valid)


def power_heuristic(pdf_a: mi.Float, pdf_b: mi.Float) -> mi.Float:
    """Veach's power heuristic ``p_a² / (p_a² + p_b²)`` (0 when both are 0)."""
    a2, b2 = pdf_a * pdf_a, pdf_b * pdf_b
    return dr.select(a2 > 0.0, a2 / (a2 + b2), 0.0)

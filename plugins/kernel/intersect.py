"""One hit query for every kernel: meshes as the binary sees them, spheres, exact planes (SPEC A.6, B.3).

:func:`intersect` is the nearest hit with ``t > t_min`` of a ray ``(o, d)``: Mitsuba's scene (meshes by the
binary's triangle and octree rules, plugins/emulation/triangle_rule.py and plugins/emulation/octree_rule.py; spheres
exactly), then
the analytic planes (plugins/emulation/planes.py, ``t = (offset − n·o)/(n·d)``) and spheres under a non-similarity
transform (the same set: the binary's object-space sphere test), the nearer one winning. The result is one
:class:`Hit` whose ``si`` describes a plane hit too (``p = o + t d``, shading frame about ``n/|n|``, ``uv = 0``),
so the material and light code never asks which kind of surface it is. :func:`visible` is SPEC B.3's shadow
test ``S``: nothing the binary sees with ``tmin < t < dist`` between ``p`` and the light (planes up to +∞ for a
directional light, which the binary places at FLT_MAX). With ``stale_uv`` (``-quirks binary``) a sphere or plane
with a textured BSDF is shaded at the stale uv of a mesh behind it, as the sample solution does (:func:`stale`).
"""

from __future__ import annotations

from typing import NamedTuple

import drjit as dr
import mitsuba as mi

from a5mi.plugins.emulation import octree_rule
from a5mi.plugins.emulation.plane_hits import intersect_planes, plane_bsdf, plane_mirror_normal, plane_normal
from a5mi.plugins.emulation.planes import PlaneSet
from a5mi.plugins.emulation.triangle_rule import NO_PLACE, RuleTable
from a5mi.plugins.syntax import syntax

#: Mesh hits walked front to back, at most, to find the stale uv (:func:`stale`).
STALE_WALK = 6


class Hit(NamedTuple):
    """A ray's nearest hit: ``si`` (planes folded in), ``t`` (+inf on a miss), ``p = o + t d``, ``n`` the shading
    normal (SPEC N, not flipped toward the viewer), ``hit``, ``on_plane`` and ``plane`` (its index), ``row``
    (the rule-table row of the mesh face hit, 0 for none: what the children leave, plugins/emulation/octree_rule.py) and
    ``bsdf`` (the plane's or the shape's)."""

    si: mi.SurfaceInteraction3f
    t: mi.Float
    p: mi.Point3f
    n: mi.Vector3f
    hit: mi.Bool
    on_plane: mi.Bool
    plane: mi.UInt32
    row: mi.UInt32
    bsdf: mi.BSDFPtr


def intersect(scene: mi.Scene, planes: PlaneSet, rules: RuleTable | None, o: mi.Point3f, d: mi.Vector3f,
              t_min: mi.Float, origin: mi.UInt32, stale_uv: bool = False) -> Hit:
    """The :class:`Hit` of ``(o, d)`` with ``t > t_min`` (module docstring); ``origin``: the rule-table row of the
    face the ray leaves (0: none), ``rules`` the scene's table (None: no rule mesh); ``stale_uv``
    (:attr:`.features.Features.stale_uv`): the sample solution's stale texture coordinates (:func:`stale`)."""
    width = dr.width(d)
    # Mitsuba rays have no tmin: start at o + tmin d and add tmin back to t. Meshes: as the binary's octree
    # and triangle test see them (plugins/emulation/octree_rule.py).
    si, offset, row = octree_rule.intersect(scene, o, d, t_min, dr.full(mi.Bool, True, width), rules, origin)
    shape_hit = si.is_valid()
    t_hit = dr.select(shape_hit, si.t + offset, dr.inf)
    if stale_uv and rules is not None:
        t_shape, uv_shape, shape = mi.Float(t_hit), mi.Point2f(si.uv), si.shape
    on_plane, t_hit, plane_idx = intersect_planes(planes, o, d, t_min, t_hit, dr.full(mi.Bool, True, width))
    hit = shape_hit | on_plane
    row = dr.select(on_plane, 0, row)                   # a plane's children leave no mesh face
    p = o + t_hit * d                                   # SPEC: p = o + t d
    n = dr.select(on_plane, plane_normal(planes, plane_idx, on_plane, o, d, t_hit),
                  mi.Vector3f(si.sh_frame.n))           # SPEC N: not flipped toward the viewer
    si.p = dr.select(hit, p, si.p)
    si.t = dr.select(hit, t_hit, si.t)
    si.n = dr.select(on_plane, n, si.n)
    si.sh_frame = dr.select(on_plane, mi.Frame3f(n), si.sh_frame)
    si.uv = dr.select(on_plane, mi.Point2f(0.0), si.uv)
    si.wi = dr.select(on_plane, si.sh_frame.to_local(-d), si.wi)
    bsdf = dr.select(on_plane, plane_bsdf(planes, plane_idx, on_plane), si.bsdf())
    if stale_uv and rules is not None:      # a Python flag (Features.stale_uv): compiled in or not
        moved, uv = stale(scene, planes, rules, shape, uv_shape, t_shape, on_plane & shape_hit, plane_idx, o, d,
                          t_min)
        bsdf = dr.select(moved, dr.gather(mi.BSDFPtr, planes.bsdf_uv, plane_idx, moved), bsdf)
        si.uv = dr.select(moved, uv, si.uv)
    return Hit(si, t_hit, p, n, hit, on_plane, plane_idx, row, bsdf)


@syntax
def stale(scene: mi.Scene, planes: PlaneSet, rules: RuleTable, shape: mi.ShapePtr, uv: mi.Point2f, t: mi.Float,
          behind: mi.Bool, plane: mi.UInt32, o: mi.Point3f, d: mi.Vector3f,
          t_min: mi.Float) -> tuple[mi.Bool, mi.Point2f]:
    """``(stale, uv)``: where the sample solution shades the plane-set hit ``plane`` (a sphere or plane, on the
    lanes of ``behind``, which have a mesh hit ``shape``, ``uv``, ``t`` behind it) with its textured material
    at the uv of a mesh behind it (docs/FIDELITY.md "Stale texture coordinates"). Its ``Group::intersect``
    tests objects in scene order; a mesh takes the hit when its nearest ``t <= t_current`` and a triangle
    with uv then sets the hit record's uv; a sphere or plane that takes the hit later (``t < t_current``)
    leaves that uv. So the uv is that of the last textured mesh, in scene order before the winner, that took
    the hit: walking the mesh hits front to back, the first textured mesh ``j`` before the winner with no
    mesh of a smaller position met so far (nearer) and no plane-set entry before it nearer than its ``t``
    (up to :data:`STALE_WALK` mesh hits)."""
    textured = dr.gather(mi.Bool, planes.textured, plane, behind)
    late = dr.gather(mi.UInt32, planes.order, plane, behind)     # the winner's scene position
    live = mi.Bool(behind) & textured
    found = dr.zeros(mi.Bool, dr.width(t))
    lowest = dr.full(mi.UInt32, NO_PLACE, dr.width(t))           # smallest position among the meshes met
    n = mi.UInt32(0)
    while live & (n < STALE_WALK):
        sid = dr.minimum(dr.reinterpret_array(mi.UInt32, shape), rules.last)
        pos = dr.gather(mi.UInt32, rules.place, sid, live)
        cand = live & dr.gather(mi.Bool, rules.has_uv, sid, live) & (pos < lowest) & (pos < late)
        earlier, _, _ = intersect_planes(planes, o, d, t_min, t, cand, before=pos)
        take = cand & ~earlier
        found |= take
        lowest = dr.select(live, dr.minimum(lowest, pos), lowest)
        live &= ~take & (lowest > 0)
        start = t + dr.maximum(1e-6, t * 1e-6)
        si, offset, _ = octree_rule.intersect(scene, o, d, start, live, rules, dr.zeros(mi.UInt32, dr.width(t)))
        live &= si.is_valid()
        shape = dr.select(live, si.shape, shape)
        uv = dr.select(take | ~live, uv, mi.Point2f(si.uv))
        t = dr.select(live, si.t + offset, t)
        n += 1
    return found, uv


def mirror_normal(planes: PlaneSet, on_plane: mi.Bool, plane: mi.UInt32, n: mi.Vector3f) -> mi.Vector3f:
    """The normal mirror and refracted rays turn about: ``n``, except on plane ``plane`` (where ``on_plane``),
    which the binary mirrors about its normal as written (``plane_<id>_mirror_normal``, plugins/emulation/planes.py; a
    non-similarity sphere of the plane set: ``n``)."""
    return dr.select(on_plane, plane_mirror_normal(planes, plane, on_plane, n), n)


def visible(scene: mi.Scene, planes: PlaneSet, p: mi.Point3f, d_light: mi.Vector3f, tmin: mi.Float,
            dist: mi.Float, far: mi.Bool, active: mi.Bool, rules: RuleTable | None = None) -> mi.Bool:
    """SPEC B.3's ``S`` on the lanes of ``active``: no shape the binary sees (plugins/emulation/octree_rule.py) and
    no plane
    with ``tmin < t < dist`` on the ray ``p + t d_light``; ``far`` (a directional light): planes up to +∞."""
    seen = mi.Bool(active)
    seen &= ~octree_rule.occluded(scene, p, d_light, tmin, dist, active, rules)
    blocked, _, _ = intersect_planes(planes, p, d_light, tmin, dr.select(far, dr.inf, dist), seen)
    seen &= ~blocked
    return seen

"""Bump and normal mapping of ``a5_material`` (docs/EXTENSIONS.md E.7): the perturbed shading normal.

Used only with ``-bump`` (``a5_whitted``'s ``bump`` flag): :func:`shading_normal` is the one call in the
kernel; it asks the hit's BSDF for ``eval_attribute_3("shading_normal", si)``, which ``a5_material`` answers
with :func:`perturb` (its own normal when it has no map). Without ``-bump`` nothing here is traced.

Tangent frame: the hit's ``dp_du``, ``dp_dv`` are the mesh's uv derivatives (for a triangle with corners
``P0, P1, P2`` and uv ``w0, w1, w2``: ``[P1 − P0, P2 − P0] = [dp_du, dp_dv] · [w1 − w0, w2 − w0]``, solved for the
2x2 uv matrix; Mitsuba's mesh computes exactly this). With the shading normal ``N``:

* height field: ``g(u, v)`` the grey (channel mean / 255) of the A.4 lookup, ``h = bumpScale · g`` world units of
  displacement along ``N``; ``h_u, h_v`` its exact partial derivatives (the lookup is bilinear in each texel
  cell: ``∂g/∂u = W [(1−b)(P10 − P00) + b(P11 − P01)] / 255``, ``∂g/∂v = −H [(1−a)(P01 − P00) + a(P11 − P10)] / 255``);
  the displaced surface ``P + h N`` has (N's variation neglected, Blinn 1978)
  ``P_u' = dp_du + N (h_u − N·dp_du)``, ``P_v' = dp_dv + N (h_v − N·dp_dv)`` and the normal
  ``N' = normalize(P_u' × P_v')``, turned to the side of ``N``;
* normal map: per texel ``t = clamp((P − 128)/127, −1, 1)`` (so 128 is exactly 0), bilinear in the A.4 weights;
  ``T = normalize(dp_du − N (N·dp_du))``, ``B = N × T``; ``N' = normalize(t_x T + t_y B + t_z N)``.

Where the gradient (or ``t_x, t_y``) is exactly 0, or the frame is degenerate, ``N'`` is ``N`` bit for bit.
"""

from __future__ import annotations

import drjit as dr
import mitsuba as mi

from a5mi.plugins.textures.imagedata import ImageAtlas


def height_gradient(atlas: ImageAtlas, uv: mi.Point2f, active: mi.Bool | bool = True) -> tuple[mi.Float, mi.Float]:
    """``(∂g/∂u, ∂g/∂v)`` of the grey A.4 lookup ``g`` at ``uv`` (module docstring)."""
    (p00, p10, p01, p11), a, b, w, h = atlas.texels(uv.x, uv.y, 0, active)
    grey = [dr.mean(p) for p in (p00, p10, p01, p11)]
    g_a = (1.0 - b) * (grey[1] - grey[0]) + b * (grey[3] - grey[2])
    g_b = (1.0 - a) * (grey[2] - grey[0]) + a * (grey[3] - grey[1])
    return g_a * (mi.Float(w) / 255.0), g_b * (-mi.Float(h) / 255.0)


def bump_normal(n: mi.Vector3f, dp_du: mi.Vector3f, dp_dv: mi.Vector3f, h_u: mi.Float, h_v: mi.Float
                ) -> mi.Vector3f:
    """``N'`` of a height field with world-space gradient ``(h_u, h_v)`` per unit uv (module docstring)."""
    pu = dp_du + n * (h_u - dr.dot(n, dp_du))
    pv = dp_dv + n * (h_v - dr.dot(n, dp_dv))
    c = dr.cross(pu, pv)
    length = dr.norm(c)
    nb = c / length
    nb = dr.select(dr.dot(nb, n) < 0.0, -nb, nb)
    keep = ((h_u == 0.0) & (h_v == 0.0)) | ~(length > 0.0) | ~dr.isfinite(length)
    return dr.select(keep, n, nb)


def tangent_normal(atlas: ImageAtlas, uv: mi.Point2f, active: mi.Bool | bool = True) -> mi.Vector3f:
    """The decoded tangent-space normal ``t`` at ``uv`` (per texel ``clamp((P − 128)/127, −1, 1)``, bilinear)."""
    (p00, p10, p01, p11), a, b, _, _ = atlas.texels(uv.x, uv.y, 0, active)

    def dec(p: mi.Color3f) -> mi.Vector3f:
        return mi.Vector3f(dr.clip((p - 128.0) / 127.0, -1.0, 1.0))

    t = (1.0 - a) * (1.0 - b) * dec(p00)
    t += a * (1.0 - b) * dec(p10)
    t += (1.0 - a) * b * dec(p01)
    t += a * b * dec(p11)
    return t


def mapped_normal(n: mi.Vector3f, dp_du: mi.Vector3f, t: mi.Vector3f) -> mi.Vector3f:
    """``N' = normalize(t_x T + t_y B + t_z N)`` in the frame of the module docstring."""
    s = dp_du - n * dr.dot(n, dp_du)
    s_len = dr.norm(s)
    tangent = s / s_len
    bitangent = dr.cross(n, tangent)
    m = dr.normalize(t.x * tangent + t.y * bitangent + t.z * n)
    keep = ((t.x == 0.0) & (t.y == 0.0)) | ~(s_len > 0.0) | ~dr.isfinite(s_len) | ~dr.all(dr.isfinite(m))
    return dr.select(keep, n, m)


def perturb(si: mi.SurfaceInteraction3f, bump: ImageAtlas | None, bump_scale: mi.Float,
            normal_map: ImageAtlas | None, active: mi.Bool | bool = True) -> mi.Vector3f:
    """The shading normal of a hit (``si.sh_frame.n`` = N): the height field first, then the normal map in the
    frame of the bumped normal (the order of Mitsuba's ``bumpmap`` around ``normalmap``)."""
    n = mi.Vector3f(si.sh_frame.n)
    if bump is not None:
        g_u, g_v = height_gradient(bump, si.uv, active)
        n = bump_normal(n, si.dp_du, si.dp_dv, bump_scale * g_u, bump_scale * g_v)
    if normal_map is not None:
        n = mapped_normal(n, si.dp_du, tangent_normal(normal_map, si.uv, active))
    return n


def shading_normal(bsdf: mi.BSDFPtr, si: mi.SurfaceInteraction3f, n: mi.Vector3f, a5: mi.Bool) -> mi.Vector3f:
    """The kernel's call (``a5_whitted`` with ``bump``): the a5 material's perturbed normal where the hit has
    one, else ``n``. ``si.sh_frame.n`` must be ``n``."""
    nb = mi.Vector3f(bsdf.eval_attribute_3("shading_normal", si, a5))
    return dr.select(a5 & (dr.squared_norm(nb) > 0.0), nb, n)

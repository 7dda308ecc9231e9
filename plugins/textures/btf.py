"""The ``a5_btf`` texture: images per view direction, interpolated bilinearly in its angles (docs/EXTENSIONS.md E.19).

A bidirectional texture function with a fixed light: image ``I_ij`` shows the surface seen from elevation
``e_i`` (the polar angle of the view direction from the normal, degrees) and azimuth ``a_j`` (degrees from the
shading frame's tangent ``s`` towards ``t``; on a mesh with uv ``s`` is ``dp/du`` made perpendicular to the
normal, E.7's ``T``). The view direction is ``si.wi`` (Mitsuba's convention: towards the viewer, in the shading
frame), so every integrator that fills ``si.wi`` (Mitsuba's, ``a5_whitted``: SPEC B.3's ``−d``) gets it::

    θ = acos(|wi.z|) in degrees,  φ = atan2(wi.y, wi.x) in [0, 360)
    i: e_i <= θ < e_{i+1} (θ clamped to [e_0, e_last]),     s = (θ − e_i)/(e_{i+1} − e_i)     (one elevation: s = 0)
    j: a_j <= φ < a_{j+1}, cyclically (after a_last comes a_0 + 360), t = (φ − a_j) mod 360 / (a_{j+1} − a_j)
    kd = (1−s)(1−t) I_ij(uv) + (1−s) t I_i,j+1(uv) + s(1−t) I_i+1,j(uv) + s t I_i+1,j+1(uv)

each ``I(uv)`` the SPEC A.4 lookup of ``a5_bitmap`` (:class:`~.imagedata.ImageAtlas`). At a sampled angle pair
the result is that image's lookup exactly (weights 1, 0, 0, 0).

Parameters: ``elevations``, ``azimuths`` (strings of degrees, increasing; elevations in [0, 90], azimuths in
[0, 360)), and per image ``(i, j)`` either ``filename_i_j`` (an 8-bit image file) or ``bitmap_i_j`` (``mi.Bitmap``).
"""

from __future__ import annotations

import drjit as dr
import mitsuba as mi
import numpy as np

from a5mi.plugins.textures.atlas_texture import AtlasTexture
from a5mi.plugins.textures.imagedata import ImageAtlas, bitmap_rgb8, load_rgb8, resolve


def _angles(props: mi.Properties, name: str, hi: float, hi_open: bool) -> list[float]:
    try:
        values = [float(x) for x in str(props.get(name, "")).split()]
    except ValueError:
        values = []
    inside = all(0.0 <= v < hi if hi_open else 0.0 <= v <= hi for v in values)
    if not values or not inside or any(b <= a for a, b in zip(values, values[1:], strict=False)):
        raise ValueError(f"a5_btf: '{name}' must be increasing degrees in [0, {hi:g}], got {props.get(name, '')!r}")
    return values


class A5Btf(AtlasTexture):
    """View-dependent image texture (module docstring)."""

    def __init__(self, props: mi.Properties) -> None:
        super().__init__(props)
        self.elevations = _angles(props, "elevations", 90.0, False)
        self.azimuths = _angles(props, "azimuths", 360.0, True)
        images = []
        for i in range(len(self.elevations)):
            for j in range(len(self.azimuths)):
                fkey, bkey = f"filename_{i}_{j}", f"bitmap_{i}_{j}"
                if (fkey in props) == (bkey in props):
                    raise ValueError(f"a5_btf: exactly one of '{fkey}' and '{bkey}' is required")
                if bkey in props:
                    images.append(bitmap_rgb8(props[bkey], f"a5_btf: parameter '{bkey}'"))
                else:
                    try:
                        images.append(load_rgb8(resolve(str(props[fkey]))))
                    except ValueError as exc:
                        raise ValueError(f"a5_btf: parameter '{fkey}': {exc}") from None
        self.atlas = ImageAtlas(images)
        self._mean = float(np.mean([img.mean() for img in images]) / 255.0)
        self.elev = mi.Float(self.elevations)
        self.azim = mi.Float(self.azimuths + [self.azimuths[0] + 360.0])
        dr.make_opaque(self.elev, self.azim)

    def weights(self, wi: mi.Vector3f) -> tuple[mi.UInt32, mi.UInt32, mi.UInt32, mi.UInt32, mi.Float, mi.Float]:
        """``(i, i + 1, j, j + 1 mod A, s, t)`` of the module docstring for the view direction ``wi``."""
        n_e, n_a = len(self.elevations), len(self.azimuths)
        theta = dr.acos(dr.clip(dr.abs(wi.z), 0.0, 1.0)) * (180.0 / dr.pi)
        phi = dr.atan2(wi.y, wi.x) * (180.0 / dr.pi)
        phi = dr.select(phi < 0.0, phi + 360.0, phi)
        e0, e_last = dr.gather(mi.Float, self.elev, 0), dr.gather(mi.Float, self.elev, n_e - 1)
        theta = dr.clip(theta, e0, e_last)
        i = mi.UInt32(0)
        for k in range(1, n_e - 1):
            i += dr.select(theta >= dr.gather(mi.Float, self.elev, k), 1, 0)
        i1 = dr.minimum(i + 1, n_e - 1)
        e_i, e_i1 = dr.gather(mi.Float, self.elev, i), dr.gather(mi.Float, self.elev, i1)
        s = dr.select(e_i1 > e_i, (theta - e_i) / (e_i1 - e_i), 0.0)
        # azimuth: before a_0 counts as after a_last (φ + 360 lies in [a_last, a_0 + 360))
        a0 = dr.gather(mi.Float, self.azim, 0)
        phi = dr.select(phi < a0, phi + 360.0, phi)
        j = mi.UInt32(0)
        for k in range(1, n_a):
            j += dr.select(phi >= dr.gather(mi.Float, self.azim, k), 1, 0)
        a_j, a_j1 = dr.gather(mi.Float, self.azim, j), dr.gather(mi.Float, self.azim, j + 1)
        t = (phi - a_j) / (a_j1 - a_j) if n_a > 1 else mi.Float(0.0)
        j1 = dr.select(j + 1 >= n_a, 0, j + 1)
        return i, i1, j, j1, dr.clip(s, 0.0, 1.0), dr.clip(t, 0.0, 1.0)

    def eval(self, si: mi.SurfaceInteraction3f, active: mi.Bool = True) -> mi.Color3f:
        """The bilinear blend of the four images around the view direction (module docstring)."""
        i, i1, j, j1, s, t = self.weights(si.wi)
        n_a = len(self.azimuths)
        u, v = si.uv.x, si.uv.y
        c = (1.0 - s) * (1.0 - t) * self.atlas.sample(u, v, i * n_a + j, active)
        c += (1.0 - s) * t * self.atlas.sample(u, v, i * n_a + j1, active)
        c += s * (1.0 - t) * self.atlas.sample(u, v, i1 * n_a + j, active)
        c += s * t * self.atlas.sample(u, v, i1 * n_a + j1, active)
        return c

    def to_string(self) -> str:
        return f"A5Btf[elevations={self.elevations}, azimuths={self.azimuths}]"


def register() -> None:
    """Register ``a5_btf`` with Mitsuba (call after selecting a JIT variant)."""
    mi.register_texture("a5_btf", lambda props: A5Btf(props))

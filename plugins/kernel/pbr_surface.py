"""The lobes of a hit for the physically based integrators (``a5_path``, ``a5_irradiancecache``;
docs/EXTENSIONS.md E.14, E.23): the surface of the hit (:func:`.surfaces.surface_at`, bump applied with
``bump``) turned into :class:`~.pbr.Lobes` about the plane set's mirror normal (:func:`.intersect.mirror_normal`).

Part of the kernel library: imports its siblings only, never an integrator.
"""

from __future__ import annotations

import mitsuba as mi

from a5mi.plugins.kernel.features import Features, SceneData
from a5mi.plugins.kernel.intersect import mirror_normal
from a5mi.plugins.kernel.pbr import Lobes, lobes
from a5mi.plugins.kernel.surfaces import surface_at


def surface_lobes(data: SceneData, f: Features, bsdf: mi.BSDFPtr, si: mi.SurfaceInteraction3f, n: mi.Vector3f,
                  d: mi.Vector3f, n_medium: mi.Float, on_plane: mi.Bool, plane_idx: mi.UInt32,
                  active: mi.Bool) -> tuple[Lobes, mi.Vector3f]:
    """``(lobes, shading normal)`` of the hit ``si`` on ``bsdf`` (lanes ``active``; ``n`` the geometric normal
    of :func:`.intersect.intersect`, ``d`` the incoming direction, ``n_medium`` the index it travels in): kd,
    ks and the index of :func:`.surfaces.surface_at` (no wavelength, one glossy child), the delta lobes turned
    about :func:`.intersect.mirror_normal` (SPEC B.3: a plane mirrors about its normal as written)."""
    s = surface_at(bsdf, si, active, n, f, None, mi.UInt32(1))
    n_mirror = mirror_normal(data.planes, on_plane, plane_idx, s.n)
    return lobes(f.fresnel, s.kd, s.specular, s.ior, d, s.n, n_mirror, n_medium, active, f.refraction,
                 f.reflection), s.n

"""``a5mi photons``: where the photons land, drawn over the image, and how many each surface holds (EXTENSIONS E.16).

:func:`photon_report` builds the scene with an ``a5_photon`` integrator of the given options, traces one
global photon set (``photons``) and one caustic set (``caustic_photons``, aimed at the specular shapes as the
integrator does), and returns per surface (a shape of the scene or an exact plane, named by its Mitsuba id)
the stored photons by kind and their power, plus the camera's view of them: each stored photon projected
through the a5 camera (SPEC B.2: ``x = (P−c)·u / ((P−c)·w tan(θ/2))``, ``y`` likewise with ``v``; pixel
``i = (x+1)(W−1)/2``, ``j = (1−y)(H−1)/2``, row 0 at the top) and kept where the camera sees it (the first
hit toward it within 10⁻³ of its distance). :func:`overlay` draws them over a rendered image: global photons
(direct and indirect) in blue, caustic photons in orange, on the image darkened to half.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from a5mi.render.options import RenderOptions

if TYPE_CHECKING:
    from a5mi.converters.describe import SceneDescription

GLOBAL_RGB = np.array([0.25, 0.55, 1.0], dtype=np.float32)
CAUSTIC_RGB = np.array([1.0, 0.6, 0.1], dtype=np.float32)
KINDS = ("direct", "caustic", "indirect")


@dataclass
class SurfaceCount:
    """Photons stored on one surface: ``name``, the global map's ``direct`` / ``indirect`` counts, the
    ``caustic`` map's count and the power (luminance) stored by each map."""

    name: str
    direct: int = 0
    indirect: int = 0
    caustic: int = 0
    global_power: float = 0.0
    caustic_power: float = 0.0


@dataclass
class PhotonReport:
    """What :func:`photon_report` found: per-surface counts, the photons emitted per map, seconds spent, and
    the visible photons' pixel positions (``global_px``, ``caustic_px``: ``(n, 2)`` arrays of ``(i, j)``)."""

    surfaces: list[SurfaceCount]
    emitted: dict[str, int]
    seconds: float
    global_px: np.ndarray = field(repr=False, default_factory=lambda: np.zeros((0, 2)))
    caustic_px: np.ndarray = field(repr=False, default_factory=lambda: np.zeros((0, 2)))

    def as_json(self) -> dict[str, Any]:
        return {"emitted": self.emitted, "seconds": round(self.seconds, 3),
                "surfaces": [vars(s) for s in self.surfaces],
                "visible": {"global": int(len(self.global_px)), "caustic": int(len(self.caustic_px))}}


def _luminance(rgb: np.ndarray) -> np.ndarray:
    return rgb @ np.array([0.2126, 0.7152, 0.0722])


def project(camera: Any, size: tuple[int, int], pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pixel ``(i, j)`` of points ``pos`` (module docstring) and the mask of those in front and in the image."""
    from a5mi.vecmath32 import camera_basis

    w, u, v = (np.asarray(a, dtype=np.float64) for a in camera_basis(camera.direction, camera.up))
    rel = pos - np.asarray(camera.center, dtype=np.float64)
    z = rel @ w
    t = math.tan(math.radians(float(camera.angle)) / 2.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        x, y = (rel @ u) / (z * t), (rel @ v) / (z * t)
    width, height = size
    ij = np.column_stack([(x + 1.0) * (width - 1) / 2.0, (1.0 - y) * (height - 1) / 2.0])
    inside = (z > 0) & (np.abs(x) <= 1.0) & (np.abs(y) <= 1.0)
    return np.rint(np.nan_to_num(ij)).astype(np.int64), inside


def _visible(integ: Any, scene: Any, camera: Any, pos: np.ndarray) -> np.ndarray:
    """Whether the camera's first hit toward each point lies within 10⁻³ of it (relative)."""
    import drjit as dr
    import mitsuba as mi

    from a5mi.plugins.kernel.intersect import intersect

    if len(pos) == 0:
        return np.zeros(0, dtype=bool)
    c = np.asarray(camera.center, dtype=np.float64)
    rel = pos - c
    dist = np.linalg.norm(rel, axis=1)
    d = rel / np.maximum(dist, 1e-30)[:, None]
    data = integ.scene_data(scene)
    n = len(pos)
    o = mi.Point3f(*(mi.Float(np.full(n, c[i], dtype=np.float32)) for i in range(3)))
    dd = mi.Vector3f(*(mi.Float(d[:, i].astype(np.float32)) for i in range(3)))
    h = intersect(scene, data.planes, data.rules, o, dd, dr.zeros(mi.Float, n), dr.zeros(mi.UInt32, n))
    t = dr.select(h.hit, h.t, dr.inf)
    dr.eval(t)
    return np.abs(np.asarray(t, dtype=np.float64) - dist) <= 1e-3 * np.maximum(dist, 1.0)


def _names(scene: Any, integ: Any) -> dict[int, str]:
    names = {i: s.id() or f"shape {i}" for i, s in enumerate(scene.shapes())}
    names.update({-1 - k: f"plane_{p[0]}" if not str(p[0]).startswith("plane") else str(p[0])
                  for k, p in enumerate(integ.planes)})
    return names


def photon_report(desc: SceneDescription, options: RenderOptions, size: tuple[int, int]) -> PhotonReport:
    """The per-surface counts and the visible photons of ``desc`` (module docstring) for an image of ``size``.
    Needs an active JIT variant with the a5mi plugins registered."""
    import dataclasses
    import time

    from a5mi.plugins.integrators.photon.trace import CAUSTIC, DIRECT, INDIRECT
    from a5mi.render.session import build_scene

    t0 = time.perf_counter()
    opts = options if options.integrator == "photon" else dataclasses.replace(options, integrator="photon")
    scene = build_scene(desc, opts)
    integ = scene.integrator()
    seed = int(options.seed or 0)
    g = integ.photon_set(scene, opts.photons, seed, 0, (DIRECT, CAUSTIC, INDIRECT), shapes=True)
    c = integ.photon_set(scene, opts.caustic_photons, seed, 1, (CAUSTIC,), shapes=True)
    g = g.select(g.kind != CAUSTIC)            # the global map's caustic photons are the caustic map's job
    names = _names(scene, integ)
    counts: dict[int, SurfaceCount] = {}
    for ps, which in ((g, "global"), (c, "caustic")):
        lum = _luminance(ps.power)
        for sid in np.unique(ps.shape):
            sel = ps.shape == sid
            sc = counts.setdefault(int(sid), SurfaceCount(names.get(int(sid), f"shape {sid}")))
            if which == "global":
                sc.direct += int((sel & (ps.kind == DIRECT)).sum())
                sc.indirect += int((sel & (ps.kind == INDIRECT)).sum())
                sc.global_power += float(lum[sel].sum())
            else:
                sc.caustic += int(sel.sum())
                sc.caustic_power += float(lum[sel].sum())
    pixels = []
    for ps in (g, c):
        ij, inside = project(desc.camera, size, ps.pos)
        keep = inside.copy()
        keep[inside] = _visible(integ, scene, desc.camera, ps.pos[inside])
        pixels.append(ij[keep])
    surfaces = sorted(counts.values(), key=lambda s: s.name)
    return PhotonReport(surfaces, {"global": opts.photons, "caustic": opts.caustic_photons},
                        time.perf_counter() - t0, pixels[0], pixels[1])


def overlay(image: np.ndarray, report: PhotonReport) -> np.ndarray:
    """``image`` (H x W x 3 float, row 0 at the top) at half brightness with the global photons in blue and
    the caustic photons in orange on top (module docstring)."""
    out = np.clip(np.asarray(image, dtype=np.float32), 0.0, 1.0) * np.float32(0.5)
    h, w = out.shape[:2]
    for px, rgb in ((report.global_px, GLOBAL_RGB), (report.caustic_px, CAUSTIC_RGB)):
        ok = (px[:, 0] >= 0) & (px[:, 0] < w) & (px[:, 1] >= 0) & (px[:, 1] < h)
        out[px[ok, 1], px[ok, 0]] = rgb
    return out

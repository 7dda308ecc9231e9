"""Photon mapping against Mitsuba's stock light tracer ``ptracer`` on one a5 scene (docs/EXTENSIONS.md E.16).

The two renders read the same scene, materials included (the marble, the glass with its ``kd``):

* ``ptracer`` runs on the stock geometry of the ``--stock`` conversion (spheres, meshes, the finite rectangle
  that stands in for an infinite plane) whose BSDFs are the a5 plugins' own ``a5_material`` (with its
  ``a5_marble`` / ``a5_bitmap`` textures): Lambert ``kd/π`` plus the delta lobes by exact Fresnel, the E.13
  reading, sampled in importance mode (no ``(n/nt)²`` on the light's side);
* ``a5_photon`` / ``a5_ppm`` runs on the a5 conversion (exact planes) with ``-fresnel exact``.

What a light tracer cannot estimate is removed from both (:func:`versus_dicts`): the camera path stops at its
first hit (``max_depth`` 0: the diffuse part ``kd/π`` of the first surface, what ptracer connects to the
camera; a mirror's or glass's view through it is not), both renders use the stock ``perspective`` camera
(rays spread over the pixel's area, as ptracer's splats), the a5 point lights become the conversion's stock
``point`` (``intensity = color D²``, D the distance to the scene's centre: an a5 light's ``1/(1 + falloff d²)``
without ``1/d²`` has no light-tracing counterpart), and only point lights are kept (a directional light's
rays start on a disc covering the plane's stand-in, 8192 units wide, and a cube map emits no photons).

:func:`caustic_region`: the pixels whose first hit is a diffuse surface lying in the shadow of a glass shape
(``refraction_index > 0``) from a point light, by ray casts through the pixel centres on the ptracer scene.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from a5mi.platform.loading import load_dict
from a5mi.render.options import RenderOptions

#: A viewpoint on the course's scene10 (center, look-at point, angle in degrees) from which the caustic of its
#: glass ball under the point light is seen (from the scene's own camera it lies behind the ball).
SCENE10_VIEW = ((1.5, 4.5, 0.5), (1.3, -1.0, -1.8), 35.0)


def with_camera(desc: Any, center: tuple[float, float, float], look_at: tuple[float, float, float],
                up: tuple[float, float, float] = (0.0, 1.0, 0.0), angle: float | None = None) -> Any:
    """``desc`` seen from ``center`` toward ``look_at`` (SPEC A.2 camera fields; ``angle`` kept if None): a
    viewpoint from which a scene's caustic is visible, without editing the scene file."""
    d = tuple(float(b) - float(a) for a, b in zip(center, look_at, strict=True))
    cam = dataclasses.replace(desc.camera, center=tuple(float(x) for x in center), direction=d,
                              up=tuple(float(x) for x in up),
                              angle=float(desc.camera.angle if angle is None else angle))
    return dataclasses.replace(desc, camera=cam)


def _points_only(d: dict[str, Any], stock_lights: dict[str, Any]) -> dict[str, Any]:
    out = {k: v for k, v in d.items()
           if not (isinstance(v, dict) and v.get("type") in ("a5_point", "point", "directional", "a5_cubemap",
                                                             "envmap", "constant"))
           and k != "background"}
    return out | stock_lights


def versus_dicts(desc: Any, options: RenderOptions, spp: int, ptracer_spp: int,
                 max_depth: int = 12) -> tuple[dict[str, Any], dict[str, Any]]:
    """``(photon dict, ptracer dict)`` for ``mi.load_dict`` (module docstring). ``options``: the photon
    integrator's (``integrator`` ``photon`` or ``ppm``, photon counts, ``k``); ``spp`` camera rays per pixel
    of the photon render, ``ptracer_spp`` light paths per pixel of ptracer, ``max_depth`` its path length."""
    from a5mi.converters import to_mitsuba as tm

    opts = dataclasses.replace(options, fresnel="exact", bounces=0)
    a5_backend = tm._DictBackend(desc, stock=False)

    class _StockShapesA5Materials(tm._DictBackend):
        def bsdf(self, entries: dict[str, Any], material: int, with_uv: bool) -> Any:
            return a5_backend.bsdf(entries, material, with_uv)

    photon = tm._transforms(tm.scene_entries(desc, opts, a5_backend))
    tracer = tm._transforms(tm.scene_entries(desc, opts, _StockShapesA5Materials(desc, stock=True)))
    points = {k: v for k, v in tracer.items() if isinstance(v, dict) and v.get("type") == "point"}
    photon, tracer = _points_only(photon, points), _points_only(tracer, points)
    sensor = tracer["sensor"]
    photon["sensor"] = dict(sensor, sampler={"type": "independent", "sample_count": int(spp)})
    tracer["sensor"] = dict(sensor, sampler={"type": "independent", "sample_count": int(ptracer_spp)})
    tracer["integrator"] = {"type": "ptracer", "max_depth": int(max_depth), "hide_emitters": True}
    return photon, tracer


def caustic_region(mi: Any, tracer: dict[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    """``(region, seen)`` boolean images of the ptracer scene's film: ``seen`` the pixels whose centre ray hits
    a shape, ``region`` those whose first hit is not glass and lies in the shadow of a glass shape from a point
    light (module docstring)."""
    scene = load_dict(dict(tracer, integrator={"type": "direct"}))
    sensor = scene.sensors()[0]
    w, h = (int(x) for x in sensor.film().size())
    j, i = np.mgrid[0:h, 0:w]
    uv = mi.Point2f(((i + 0.5) / w).ravel().astype(np.float32), ((j + 0.5) / h).ravel().astype(np.float32))
    ray, _ = sensor.sample_ray(0.0, 0.5, uv, mi.Point2f(0.5, 0.5))
    si = scene.ray_intersect(ray)
    glass = [mi.ShapePtr(s) for s in scene.shapes()
             if s.bsdf() is not None and float(np.asarray(getattr(s.bsdf(), "refraction_index", 0.0)).ravel()[0]) > 0.0]

    def on_glass(it: Any) -> np.ndarray:
        m = np.zeros(w * h, dtype=bool)
        for g in glass:
            m |= np.asarray(it.is_valid() & (it.shape == g))
        return m

    hit = np.asarray(si.is_valid())
    region = np.zeros(w * h, dtype=bool)
    for e in scene.emitters():
        if not mi.has_flag(e.flags(), mi.EmitterFlags.DeltaPosition):
            continue
        ds, _ = e.sample_direction(mi.Interaction3f(si), mi.Point2f(0.5, 0.5))
        shadow = scene.ray_intersect(si.spawn_ray_to(ds.p))
        region |= hit & ~on_glass(si) & on_glass(shadow)
    return region.reshape(h, w), hit.reshape(h, w)


def metrics(photon: np.ndarray, reference: list[np.ndarray], region: np.ndarray) -> dict[str, float]:
    """Figures of a photon render against ptracer renders of independent seeds (luminance = channel mean):
    ``region_ratio`` = photon region mean / reference region mean, ``region_sigma`` the reference region mean's
    standard error (std of the seeds' means / sqrt(seeds)), ``image_ratio`` the whole-image means' ratio and
    ``image_sigma`` its standard error, ``mre`` = Σ|p − r| / Σ r over the image and ``mre_ref`` = Σ|a − b| / (2 Σ r)
    for the means a, b of the two halves of the reference seeds: the reference's own part of ``mre`` (a − b has
    √2 times a half's noise, the mean of all seeds 1/√2 of it)."""
    p = photon.mean(axis=-1)
    refs = [r.mean(axis=-1) for r in reference]
    ref = np.mean(refs, axis=0)
    n = len(refs)
    reg = [r[region].mean() for r in refs]
    img = [r.mean() for r in refs]
    half = n // 2
    a, b = np.mean(refs[:half], axis=0), np.mean(refs[half:2 * half], axis=0)
    return {"region_ratio": float(p[region].mean() / ref[region].mean()),
            "region_sigma": float(np.std(reg, ddof=1) / np.sqrt(n) / ref[region].mean()),
            "image_ratio": float(p.mean() / ref.mean()),
            "image_sigma": float(np.std(img, ddof=1) / np.sqrt(n) / ref.mean()),
            "mre": float(np.abs(p - ref).sum() / ref.sum()),
            "mre_ref": float(np.abs(a - b).sum() / ref.sum() / 2.0)}


def render_versus(mi: Any, desc: Any, options: RenderOptions, passes: int, spp: int, ptracer_spp: int,
                  ptracer_seeds: int) -> dict[str, Any]:
    """Render ``desc`` by ``options``' photon integrator (``ppm``: passes ``0 .. passes−1``, their mean;
    ``photon``: one image) and by ptracer (``ptracer_seeds`` seeds of ``ptracer_spp``), timed; returns the
    images, the region, :func:`metrics` and the seconds of each."""
    import time

    photon, tracer = versus_dicts(desc, options, spp, ptracer_spp)
    region, _ = caustic_region(mi, tracer)
    t0 = time.perf_counter()
    scene = load_dict(tracer)
    refs = [np.asarray(mi.render(scene, seed=s), dtype=np.float64) for s in range(ptracer_seeds)]
    t_ref = time.perf_counter() - t0
    t0 = time.perf_counter()
    if options.integrator == "ppm":
        imgs = [np.asarray(mi.render(load_dict(dict(photon, integrator=dict(photon["integrator"], first_pass=k,
                                                                                   passes=1))), seed=k),
                           dtype=np.float64) for k in range(passes)]
        image = np.mean(imgs, axis=0)
    else:
        image = np.asarray(mi.render(load_dict(photon)), dtype=np.float64)
    t_photon = time.perf_counter() - t0
    return {"photon": image, "ptracer": np.mean(refs, axis=0), "region": region,
            "metrics": metrics(image, refs, region), "photon_seconds": t_photon, "ptracer_seconds": t_ref}

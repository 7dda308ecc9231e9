"""Samples per render-buffer pixel for the distribution-ray-tracing extension (docs/EXTENSIONS.md E.3, E.5).

:func:`sample_passes` traces one tile ``spp`` times and averages the colours: pass ``k`` tells ``a5_whitted``
its sample index with each call (a :class:`a5mi.plugins.sampling.SamplePass`: pixel ``first + i``, pass ``k`` of
``spp``, the seed; nothing stays set on the integrator between calls), so light, lens and gloss
samples are stratified over the ``spp`` passes of each pixel and reproducible for a given seed. The pixel
position stays the one of SPEC B.2 / B.5 (centre, or the ``-jitter`` offset): ``-spp`` samples only the
stochastic dimensions. With ``spp = 1`` and a pinhole camera the pass is exactly the course render.

Thin lens (E.3), for a camera with ``aperture A > 0`` and ``focusDistance F``: the pinhole ray ``(o, d)`` of
B.2 (``w`` the unit view direction) meets the focus plane at ``P = o + (F / (d·w)) d``; the lens point is
``o' = o + (A/2)(x u + y v)`` with ``(x, y)`` uniform on the unit disc (concentric map of a stratified
sample); the ray is ``(o', normalize(P - o'))``.
"""

from __future__ import annotations

from typing import Any


def thin_lens(ray: Any, camera: Any, sample: Any) -> Any:
    """The E.3 thin-lens ray for the pinhole ``ray`` of ``camera`` (``direction``, ``up``, ``aperture``,
    ``focus_distance``) and a unit-square ``sample`` (``mi.Point2f``)."""
    import drjit as dr
    import mitsuba as mi

    from a5mi.plugins.camera import camera_basis

    # opaque: a keyframed camera (docs/EXTENSIONS.md E.11) turns without a new kernel
    w, u, v = (dr.opaque(mi.Vector3f, [float(c) for c in a]) for a in camera_basis(camera.direction, camera.up))
    radius = dr.opaque(mi.Float, 0.5 * float(camera.aperture))
    focus = dr.opaque(mi.Float, float(camera.focus_distance))
    focal_point = ray.o + (focus / dr.dot(ray.d, w)) * ray.d
    disk = mi.warp.square_to_uniform_disk_concentric(sample)
    origin = ray.o + radius * (disk.x * u + disk.y * v)
    return mi.Ray3f(origin, dr.normalize(focal_point - origin))


def sample_passes(scene: Any, integrator: Any, sampler: Any, ray: Any, camera: Any, first: int, n: int,
                  spp: int, seed: int, only: int | None = None) -> tuple[Any, list[Any]]:
    """``(mean colour over spp passes, AOVs of pass 0)`` for the camera rays ``ray`` of samples
    ``first .. first + n - 1`` (module docstring); each pass is evaluated as it is traced (one kernel).
    ``only = k``: pass ``k`` of ``spp`` alone, its colour not scaled (motion blur, docs/EXTENSIONS.md E.12)."""
    import drjit as dr
    import mitsuba as mi

    from a5mi.plugins.sampling import LENS_DIM, SamplePass, pixel_keys, stratified_2d
    from a5mi.plugins.whitted import A5WhittedIntegrator

    # a5 integrators take the pass (``takes_sample_pass``); any other integrator samples alone
    a5 = isinstance(integrator, A5WhittedIntegrator) or getattr(integrator, "takes_sample_pass", False)

    aperture = float(getattr(camera, "aperture", 0.0) or 0.0)
    total = None
    aovs0: list[Any] = []
    for k in range(spp) if only is None else (only,):
        traced = ray
        if aperture > 0.0:
            pixel = dr.arange(mi.UInt32, n) + dr.opaque(mi.UInt32, first)
            pk, pass_key = pixel_keys(pixel, dr.opaque(mi.UInt32, seed & 0xFFFFFFFF), dr.opaque(mi.UInt32, k))
            u = stratified_2d(pk, pass_key, mi.UInt32(LENS_DIM), dr.opaque(mi.UInt32, k), dr.opaque(mi.UInt32, spp),
                              mi.UInt32(0x7FFFFFF0))
            traced = thin_lens(ray, camera, u)
        sampler.seed(k, n)
        extra = {"sample_pass": SamplePass(first, k, spp, seed)} if a5 else {}
        rgb, _valid, aovs = integrator.sample(scene, sampler, mi.RayDifferential3f(traced), None, mi.Bool(True),
                                              **extra)
        if total is None:
            aovs0 = list(aovs)
            total = rgb
        else:
            dr.eval(total, rgb)
            total = total + rgb
    if spp > 1 and only is None:
        total = total * (1.0 / spp)
    return total, aovs0

"""Samples per render-buffer pixel for the distribution-ray-tracing extension (docs/EXTENSIONS.md E.3, E.5, E.24).

:func:`sample_passes` traces one tile ``spp`` times and averages the colours: pass ``k`` tells ``a5_whitted``
its sample index with each call (a :class:`a5mi.plugins.sampling.SamplePass`: pixel ``first + i``, pass ``k`` of
``spp``, the seed; nothing stays set on the integrator between calls), so light, lens and gloss
samples are stratified over the ``spp`` passes of each pixel and reproducible for a given seed. The pixel
position stays the one of SPEC B.2 / B.5 (centre, or the ``-jitter`` offset): ``-spp`` samples only the
stochastic dimensions. With ``spp = 1`` and a pinhole camera the pass is exactly the course render.

Wavefront (``a5_whitted``, ``a5_path``): a batch of ``b`` consecutive passes is one call of the integrator
over ``b · s`` lanes, pass-major (lane ``L`` = sample ``first + L mod s`` of pass ``k0 + L div s``; ``s`` = ``n``
rounded up to :data:`PACKET` lanes, the ``s - n`` padding lanes inactive, so every sample shares its SIMD
packet with the neighbours it has in a one-pass call), ``b · s <=`` :data:`WAVEFRONT_LANES` (``s`` above half
of it: one call per pass, the trace then small beside the kernel). The integrator
is traced once per batch instead of once per pass; each lane computes exactly what its pass would alone (the
E.5 keys are per lane), and the mean is the same float32 sum in pass order, ``((c_0 + c_1) + c_2) + ...``,
times ``1/spp`` (a symbolic loop over the batch's passes), so the image is bit for bit the pass-by-pass one.

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
    from a5mi.plugins.sensors.camera import thin_lens as lens  # the a5_camera sensor's lens, the same operations

    return lens(ray, camera.direction, camera.up, camera.aperture, camera.focus_distance, sample)


#: lanes of one wavefront call (the tile limit of a5mi.render.options.TILE_RAYS: ~100 bytes of kernel state a lane)
WAVEFRONT_LANES = 1 << 20
#: a pass's lanes start on a multiple of this (a5mi.render.tiles.PACKET_ALIGN: the widest SIMD packet and then some)
PACKET = 64


def wavefront(integrator: Any) -> bool:
    """True for the integrators that trace many E.5 passes in one call (their per-lane keys are all the state a
    pass has): ``a5_whitted`` and ``a5_path`` exactly; the photon and irradiance-cache integrators keep state
    between passes and are called once per pass."""
    from a5mi.plugins.integrators.path import A5PathIntegrator
    from a5mi.plugins.integrators.whitted.integrator import A5WhittedIntegrator

    return type(integrator) in (A5WhittedIntegrator, A5PathIntegrator)


def _batch_sum(total: Any, rgb: Any, n: int, stride: int, batch: int) -> Any:
    """``total + c_0 + c_1 + ... + c_{batch-1}`` in that order (``c_k`` = lanes ``k·stride .. k·stride + n - 1``
    of ``rgb``; ``total`` None: start from ``c_0``), one symbolic loop over the passes."""
    import drjit as dr
    import mitsuba as mi

    dr.eval(rgb)
    idx = dr.arange(mi.UInt32, n)
    k = dr.zeros(mi.UInt32, n)
    if total is None:
        total = dr.gather(mi.Color3f, rgb, idx)
        k += 1
    else:
        total = mi.Color3f(total)

    def body(k: Any, acc: Any) -> tuple[Any, Any]:
        return k + 1, acc + dr.gather(mi.Color3f, rgb, idx + k * dr.opaque(mi.UInt32, stride))

    k, total = dr.while_loop((k, total), lambda k, acc: k < dr.opaque(mi.UInt32, batch), body)
    return total


def _lens_rays(ray: Any, camera: Any, pixel: Any, seed: int, pass_index: Any, spp: int) -> Any:
    """The E.3 thin-lens rays of samples ``pixel`` in passes ``pass_index`` (lens dimension of E.5)."""
    import drjit as dr
    import mitsuba as mi

    from a5mi.plugins.sampling import LENS_DIM, pixel_keys, stratified_2d

    pk, pass_key = pixel_keys(pixel, dr.opaque(mi.UInt32, seed & 0xFFFFFFFF), pass_index)
    u = stratified_2d(pk, pass_key, mi.UInt32(LENS_DIM), pass_index, dr.opaque(mi.UInt32, spp),
                      mi.UInt32(0x7FFFFFF0))
    return thin_lens(ray, camera, u)


def sample_passes(scene: Any, integrator: Any, sampler: Any, ray: Any, camera: Any, first: int, n: int,
                  spp: int, seed: int, only: int | None = None, pixels: Any = None) -> tuple[Any, list[Any]]:
    """``(mean colour over spp passes, AOVs of pass 0)`` for the camera rays ``ray`` of samples
    ``first .. first + n - 1`` (module docstring); each pass is evaluated as it is traced (one kernel).
    ``only = k``: pass ``k`` of ``spp`` alone, its colour not scaled (motion blur, docs/EXTENSIONS.md E.12).
    ``pixels``: the rays' samples when they are not consecutive (a crop, :mod:`a5mi.render.crop`): ``n``
    absolute sample indices (numpy), the E.5 keys of ray ``i`` those of sample ``pixels[i]``."""
    stride = -(-n // PACKET) * PACKET
    if only is None and spp > 1 and wavefront(integrator) and 2 * stride <= WAVEFRONT_LANES:
        return _wavefront_passes(scene, integrator, ray, camera, first, n, spp, seed, stride, _lanes(pixels, stride))
    return _pass_by_pass(scene, integrator, sampler, ray, camera, first, n, spp, seed, only, _lanes(pixels, n))


def _lanes(pixels: Any, width: int) -> Any:
    """``pixels`` (numpy) as a ``mi.UInt32`` of ``width`` lanes, the last sample repeated on the padding
    lanes; None stays None."""
    if pixels is None:
        return None
    import mitsuba as mi
    import numpy as np

    padded = np.empty(width, np.uint32)
    padded[:len(pixels)] = pixels
    padded[len(pixels):] = pixels[-1]
    return mi.UInt32(padded)


def _wavefront_passes(scene: Any, integrator: Any, ray: Any, camera: Any, first: int, n: int, spp: int,
                      seed: int, stride: int, pixels: Any) -> tuple[Any, list[Any]]:
    """:func:`sample_passes` in batches of passes, one integrator call each (module docstring, Wavefront)."""
    import drjit as dr
    import mitsuba as mi

    from a5mi.plugins.sampling import SamplePass

    per_call = max(1, WAVEFRONT_LANES // stride)
    origins = mi.Point3f(ray.o) + dr.zeros(mi.Point3f, n)        # the pinhole origin may be one lane
    directions = mi.Vector3f(ray.d) + dr.zeros(mi.Vector3f, n)
    dr.eval(origins, directions)
    aperture = float(getattr(camera, "aperture", 0.0) or 0.0)
    total = None
    aovs0: list[Any] = []
    for k0 in range(0, spp, per_call):
        batch = min(per_call, spp - k0)
        width = batch * stride
        lane = dr.arange(mi.UInt32, width)
        k = lane // dr.opaque(mi.UInt32, stride)
        i = lane - k * dr.opaque(mi.UInt32, stride)
        active = i < dr.opaque(mi.UInt32, n)
        src = dr.minimum(i, dr.opaque(mi.UInt32, n - 1))
        traced = mi.Ray3f(dr.gather(mi.Point3f, origins, src), dr.gather(mi.Vector3f, directions, src))
        if aperture > 0.0:
            pixel = i + dr.opaque(mi.UInt32, first) if pixels is None else dr.gather(mi.UInt32, pixels, i)
            traced = _lens_rays(traced, camera, pixel, seed, k + dr.opaque(mi.UInt32, k0), spp)
        sample_pass = SamplePass(first, k0, spp, seed, batch if batch > 1 else 1, stride if batch > 1 else 0,
                                 pixels)
        rgb, _valid, aovs = integrator.sample(scene, None, mi.RayDifferential3f(traced), None, active,
                                              sample_pass=sample_pass)
        if k0 == 0:
            dr.eval(rgb, *aovs)     # one kernel: a gather from an unevaluated AOV would trace the batch again
            idx = dr.arange(mi.UInt32, n)
            aovs0 = [dr.gather(type(a), a, idx) for a in aovs]
        total = _batch_sum(total, rgb, n, stride, batch)
    return total * (1.0 / spp), aovs0


def _pass_by_pass(scene: Any, integrator: Any, sampler: Any, ray: Any, camera: Any, first: int, n: int,
                  spp: int, seed: int, only: int | None, pixels: Any) -> tuple[Any, list[Any]]:
    """:func:`sample_passes` one integrator call per pass."""
    import drjit as dr
    import mitsuba as mi

    from a5mi.plugins.integrators.whitted.integrator import A5WhittedIntegrator
    from a5mi.plugins.sampling import SamplePass

    # a5 integrators take the pass (``takes_sample_pass``); any other integrator samples alone
    a5 = isinstance(integrator, A5WhittedIntegrator) or getattr(integrator, "takes_sample_pass", False)

    aperture = float(getattr(camera, "aperture", 0.0) or 0.0)
    total = None
    aovs0: list[Any] = []
    for k in range(spp) if only is None else (only,):
        traced = ray
        if aperture > 0.0:
            pixel = dr.arange(mi.UInt32, n) + dr.opaque(mi.UInt32, first) if pixels is None else pixels
            traced = _lens_rays(ray, camera, pixel, seed, dr.opaque(mi.UInt32, k), spp)
        sampler.seed(k, n)
        extra = {"sample_pass": SamplePass(first, k, spp, seed, pixels=pixels)} if a5 else {}
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

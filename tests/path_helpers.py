"""Helpers of the path-tracing tests (tests/plugins/integrators/test_path*.py, test_indirect.py): a5 scene text
-> loaded Mitsuba scenes, and per-pixel means with their standard errors over ``-spp`` passes of an a5 integrator or of
Mitsuba's stock ``path``, all through the SPEC B.2 pixel centres (``a5mi.crosscheck._pixel_rays``)."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np


def load(mi: Any, text: str, *, stock: bool = False, **options: Any) -> tuple[Any, Any, Any]:
    """``(description, loaded scene, RenderOptions)`` of the scene ``text`` converted with ``options``
    (``RenderOptions`` fields; ``stock``: the ``--stock`` conversion)."""
    from a5mi.converters.a5_parser import parse_text
    from a5mi.converters.describe import describe
    from a5mi.converters.to_mitsuba import to_dict
    from a5mi.render.options import RenderOptions

    ro = RenderOptions(**options)
    desc = describe(parse_text(text), stock=stock)
    return desc, mi.load_dict(to_dict(desc, ro, stock=stock)), ro


def integrator(mi: Any, scene_dict_integrator: dict, **params: Any) -> Any:
    """An integrator loaded from a scene's ``integrator`` entry with ``params`` laid over it."""
    return mi.load_dict({**scene_dict_integrator, **params})


def a5_passes(mi: Any, scene: Any, integ: Any, camera: Any, width: int, height: int, spp: int,
              seed: int = 0, replicas: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """``(mean, standard error of the mean)`` per pixel and channel (HxWx3, row 0 = bottom) of ``spp`` passes of
    an a5 integrator (``sample(..., sample_pass=SamplePass(0, k, spp, seed))``). The passes are stratified
    (E.5), so the sample variance over-estimates the mean's error: a conservative sigma. ``replicas = R > 1``:
    R independent renders in the same launches (the lanes of copy r are samples ``r·W·H + i``, other E.5 keys),
    arrays ``R x H x W x 3``."""
    import drjit as dr

    from a5mi.crosscheck import _pixel_rays
    from a5mi.plugins.sampling import SamplePass

    ray = mi.RayDifferential3f(_pixel_rays(camera, width, height, repeat=replicas))
    total = np.zeros((3, replicas * width * height))
    total_sq = np.zeros_like(total)
    for k in range(spp):
        rgb, _, _ = integ.sample(scene, None, ray, None, mi.Bool(True), sample_pass=SamplePass(0, k, spp, seed))
        dr.eval(rgb)
        c = np.asarray(rgb, dtype=np.float64)
        total += c
        total_sq += c * c
    if replicas == 1:
        return _stats(total, total_sq, spp, width, height)
    return _stats(total, total_sq, spp, width, height * replicas, (replicas, height, width, 3))


def stock_passes(mi: Any, scene: Any, camera: Any, width: int, height: int, spp: int, max_depth: int,
                 seed: int = 0, rr_depth: int = 5) -> tuple[np.ndarray, np.ndarray]:
    """:func:`a5_passes` for Mitsuba's stock ``path`` (``max_depth`` segments), an ``independent`` sampler."""
    import drjit as dr

    from a5mi.crosscheck import _pixel_rays

    integ = mi.load_dict({"type": "path", "max_depth": max_depth, "rr_depth": rr_depth, "hide_emitters": False})
    sampler = mi.load_dict({"type": "independent", "sample_count": 1})
    n = width * height
    per = max(1, min(spp, (1 << 18) // n))
    ray = mi.RayDifferential3f(_pixel_rays(camera, width, height, repeat=per))
    total = np.zeros((3, n))
    total_sq = np.zeros_like(total)
    done = 0
    while done < spp:
        sampler.seed(seed * 1_000_003 + done, per * n)
        rgb, _, _ = integ.sample(scene, sampler, ray, None, mi.Bool(True))
        dr.eval(rgb)
        c = np.asarray(rgb, dtype=np.float64).reshape(3, per, n)
        k = min(per, spp - done)
        total += c[:, :k].sum(axis=1)
        total_sq += (c[:, :k] ** 2).sum(axis=1)
        done += k
    return _stats(total, total_sq, spp, width, height)


def _stats(total: np.ndarray, total_sq: np.ndarray, spp: int, width: int, height: int,
           shape: tuple[int, ...] | None = None) -> tuple[np.ndarray, np.ndarray]:
    mean = total / spp
    var = np.maximum(total_sq / spp - mean * mean, 0.0) * spp / max(spp - 1, 1)
    se = np.sqrt(var / spp)
    shape = shape or (height, width, 3)
    return mean.T.reshape(shape), se.T.reshape(shape)


def with_options(ro: Any, **changes: Any) -> Any:
    """``dataclasses.replace`` of a RenderOptions."""
    return dataclasses.replace(ro, **changes)

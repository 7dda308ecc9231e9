"""In-process measurements: stages of one render, the traversal floor of the same rays, stock Mitsuba."""

from __future__ import annotations

import contextlib
import gc
import tempfile
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from a5mi.spec import TMIN


def lane_repeat(counts: npt.ArrayLike) -> npt.NDArray[np.int64]:
    """Lane index ``i`` repeated ``counts[i]`` times (rounded, negatives as 0): ``[2, 0, 1] -> [0, 0, 2]``.

    Used to re-cast, from each camera ray's first hit, as many rays of a kind as that camera ray's tree cast.
    """
    c = np.rint(np.asarray(counts, dtype=np.float64)).clip(min=0).astype(np.int64)
    return np.repeat(np.arange(c.size, dtype=np.int64), c)


def rank_within_lane(lanes: npt.NDArray[np.int64]) -> npt.NDArray[np.int64]:
    """For sorted lane indices, the occurrence number of each entry within its lane: ``[0,0,2,2,2] -> [0,1,0,1,2]``.

    Shadow ray ``r`` of a camera ray goes to light ``r mod n_lights`` (lights are visited in order per hit)."""
    if lanes.size == 0:
        return lanes.copy()
    start = np.r_[0, np.flatnonzero(np.diff(lanes)) + 1]
    first = np.repeat(start, np.diff(np.r_[start, lanes.size]))
    return np.arange(lanes.size, dtype=np.int64) - first



# --------------------------------------------------------------------------------------------------------
# In-process measurements (need Mitsuba)
# --------------------------------------------------------------------------------------------------------


_chdir = contextlib.chdir


def _free(*_objs: Any) -> None:
    """Drop Mitsuba scenes: kernels are only reused across scenes once the previous scene is gone."""
    import drjit as dr

    gc.collect()
    gc.collect()
    dr.flush_malloc_cache()


def _timed_kernels(fn: Any, repeat: int) -> tuple[float, Any]:
    """Best Dr.Jit kernel execution time (s) of ``fn()`` (which must ``dr.eval`` its outputs) over ``repeat``
    runs after one warm-up run, from ``dr.kernel_history()``; also returns the last result."""
    import drjit as dr

    best = float("inf")
    out = None
    for k in range(repeat + 1):
        with dr.scoped_set_flag(dr.JitFlag.KernelHistory, True):
            dr.kernel_history_clear()
            out = fn()
            dr.sync_thread()
            hist = dr.kernel_history()
        if k > 0:
            best = min(best, sum(e.get("execution_time", 0.0) for e in hist) / 1000.0)
    return best, out


@dataclass
class InProcess:
    """Floor and render-kernel figures of one scene, measured in this process."""

    kernel_execute: float  # s, the a5 render's kernels (warm, best of repeat)
    rays: dict[str, int]
    floor: dict[str, float]  # s per ray kind
    lights: int
    stages: dict[str, float] = field(default_factory=dict)  # first render in this process (s)
    recompiles: int = 0  # of the ``renders`` repeated renders of one loaded scene, how many compiled a kernel
    renders: int = 0

    @property
    def floor_total(self) -> float:
        return sum(self.floor.values())


def _camera_rays_for(model: Any, rw: int, rh: int) -> Any:
    """The render's camera rays, all of them, in the driver's order (SPEC B.2, B.5 glibc jitter)."""
    import mitsuba as mi

    from a5mi.arrays import aligned_float32
    from a5mi.plugins.camera import camera_rays
    from a5mi.tiles import jitter_stream

    jx, jy = jitter_stream(None)(rw * rh)
    x = np.tile(np.arange(rw, dtype=np.float32), rh) + jx
    y = np.repeat(np.arange(rh, dtype=np.float32), rw) + jy
    cam = model.camera
    return camera_rays(cam.center, cam.direction, cam.up, cam.angle, mi.Float(aligned_float32(x)),
                       mi.Float(aligned_float32(y)), rw, rh)


def _full_ray(o: Any, d: Any, maxt: Any) -> Any:
    """A ``Ray3f`` whose every field is full width (``ray_test`` rejects an evaluated width-1 ``time``)."""
    import drjit as dr
    import mitsuba as mi

    n = dr.width(o)
    ray = mi.Ray3f(o, d)
    ray.maxt = maxt if maxt is not None else dr.full(mi.Float, dr.largest(mi.Float), n)
    ray.time = dr.zeros(mi.Float, n)
    return ray


def _floor_passes(
    scene: Any, model: Any, rw: int, rh: int, repeat: int
) -> tuple[dict[str, int], dict[str, float], int]:
    """Per-lane ray counts from the counting integrator, then the timed traversal passes (module docstring)."""
    import drjit as dr
    import mitsuba as mi

    from a5mi.plugins.common import reflect

    ray = _camera_rays_for(model, rw, rh)
    dr.eval(ray)
    sampler = mi.load_dict({"type": "independent", "sample_count": 1})
    sampler.seed(0, rw * rh)
    integrator = scene.integrator()
    _rgb, _valid, aovs = integrator.sample(scene, sampler, mi.RayDifferential3f(ray), None, mi.Bool(True))
    named = dict(zip(integrator.aov_names(), aovs, strict=True))
    counts = {name: np.asarray(named[f"n_{name}"]) for name in ("reflection", "refraction", "shadow")}
    si = scene.ray_intersect(ray)
    o, d = np.asarray(ray.o), np.asarray(ray.d)
    t, n = np.asarray(si.t), np.asarray(si.sh_frame.n)
    hit_p = o + np.where(np.isfinite(t), t, 0.0) * d

    def floor_intersect(ro: npt.NDArray[np.float32], rd: npt.NDArray[np.float32]) -> float:
        r = _full_ray(mi.Point3f(ro), mi.Vector3f(rd), None)
        dr.eval(r)

        def cast() -> Any:
            s = scene.ray_intersect(r)
            dr.eval(s.t, s.sh_frame.n)
            return s.t

        return _timed_kernels(cast, repeat)[0] if ro.shape[1] else 0.0

    floor = {"camera": floor_intersect(o, d)}
    lanes = lane_repeat(counts["reflection"])
    refl = np.asarray(reflect(mi.Vector3f(d[:, lanes]), mi.Vector3f(n[:, lanes])))
    floor["reflection"] = floor_intersect(hit_p[:, lanes] + TMIN * refl, refl)
    lanes = lane_repeat(counts["refraction"])
    floor["refraction"] = floor_intersect(hit_p[:, lanes] + TMIN * d[:, lanes], d[:, lanes])

    # shadow rays: from the first hit towards light (rank mod n_lights), tmax = dist - tmin
    emitters = [e for e in scene.emitters() if mi.has_flag(e.flags(), mi.EmitterFlags.Delta)]
    lanes = lane_repeat(counts["shadow"])
    parts: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
    if emitters and lanes.size:
        which = rank_within_lane(lanes) % len(emitters)
        for k, emitter in enumerate(emitters):
            sel = lanes[which == k]
            if not sel.size:
                continue
            sub = mi.Ray3f(mi.Point3f(o[:, sel]), mi.Vector3f(d[:, sel]))
            s = scene.ray_intersect(sub)
            ds, _ = emitter.sample_direction(s, mi.Point2f(0.5, 0.5))
            p = s.p
            dr.eval(p, ds.d, ds.dist)
            # a directional light gives one direction and distance for all lanes: broadcast
            ld = np.broadcast_to(np.asarray(ds.d).reshape(3, -1), (3, sel.size))
            dist = np.broadcast_to(np.asarray(ds.dist), (sel.size,))
            parts.append((np.asarray(p) + TMIN * ld, ld, dist - TMIN))
    if parts:
        so = np.concatenate([q[0] for q in parts], axis=1)
        sd = np.concatenate([q[1] for q in parts], axis=1)
        st = np.concatenate([q[2] for q in parts])
        sray = _full_ray(mi.Point3f(so), mi.Vector3f(sd), mi.Float(st))
        dr.eval(sray)

        def cast_shadow() -> Any:
            b = scene.ray_test(sray)
            dr.eval(b)
            return b

        floor["shadow"] = _timed_kernels(cast_shadow, repeat)[0]
    else:
        floor["shadow"] = 0.0
    rays = {"camera": rw * rh} | {k: int(np.rint(v).sum()) for k, v in counts.items()}
    return rays, floor, len(emitters)


def measure_in_process(scene_file: Path, options: Any, repeat: int = 3) -> InProcess:
    """Stages of the first render of ``scene_file`` in this process, then the render's best kernel time and
    the traversal floor for the same rays (see the module docstring). Run from the scene's folder."""
    from a5mi import driver, imageio
    from a5mi.converters.a5_parser import parse_file
    from a5mi.session import build_scene

    rw, rh = options.render_size

    # 1. stages of one a5 run (what the child process does after its imports), then the warm kernel time
    from a5mi.converters.describe import describe

    t0 = time.perf_counter()
    model = parse_file(scene_file)
    stages = {"parse": time.perf_counter() - t0}
    t0 = time.perf_counter()
    desc = describe(model)  # the files are read here, once (the a5 command does the same)
    scene = build_scene(desc, options)
    stages["build"] = time.perf_counter() - t0
    recompiles = 0
    best = float("inf")
    for k in range(repeat + 1):
        res = driver.render_scene(scene, desc.camera, options)
        if k == 0:
            stages.update({key: res.timings[key] for key in ("compile", "execute", "render", "filter")})
            with tempfile.TemporaryDirectory(prefix="a5bench-") as tmp:
                t0 = time.perf_counter()
                imageio.write_images([(str(Path(tmp) / "out.png"), res.image)])
                stages["write"] = time.perf_counter() - t0
        else:
            best = min(best, res.timings["execute"])
            recompiles += res.kernels.get("compiled", 0) + res.kernels.get("disk", 0) > 0  # not in memory
    del scene, res
    _free()

    # 2. per-lane ray counts and first hits with the counting integrator, then the floor passes
    scene = build_scene(desc, replace(options, count_rays=True))
    rays, floor, n_lights = _floor_passes(scene, desc, rw, rh, repeat)
    del scene
    _free()
    return InProcess(kernel_execute=best, rays=rays, floor=floor, lights=n_lights, stages=stages,
                     recompiles=int(recompiles), renders=repeat)


def measure_stock(model: Any, options: Any, repeat: int = 3) -> dict[str, float]:
    """Wall time (best of ``repeat`` after a warm-up) of ``mi.render`` with the stock ``direct`` and ``path``
    integrators on the ``stock=True`` conversion, at the render resolution and 1 spp (see module docstring).
    ``model``: a parsed scene or its description."""
    import drjit as dr
    import mitsuba as mi

    from a5mi.converters.describe import SceneDescription, describe
    from a5mi.converters.to_mitsuba import to_dict

    rw, rh = options.render_size
    desc = model if isinstance(model, SceneDescription) else describe(model, stock=True)
    base = to_dict(desc, options, stock=True)
    n_lights = sum(1 for v in base.values() if isinstance(v, dict) and v.get("type") in ("point", "directional",
                                                                                          "spot", "a5_point"))
    integrators = {
        "direct": {"type": "direct", "emitter_samples": max(1, n_lights), "bsdf_samples": 0},
        "path": {"type": "path", "max_depth": options.bounces + 2, "rr_depth": options.bounces + 3},
    }
    out: dict[str, float] = {}
    for name, integ in integrators.items():
        scene_dict = dict(base)
        scene_dict["integrator"] = integ
        scene = mi.load_dict(scene_dict)
        sensor = scene.sensors()[0]
        size = sensor.film().crop_size()
        if (int(size[0]), int(size[1])) != (rw, rh):
            raise RuntimeError(f"stock sensor film is {size[0]}x{size[1]}, expected {rw}x{rh}")
        best = float("inf")
        for k in range(repeat + 1):
            t0 = time.perf_counter()
            img = mi.render(scene, spp=1)
            dr.eval(img)
            dr.sync_thread()
            if k > 0:
                best = min(best, time.perf_counter() - t0)
        out[name] = best
        del scene, sensor, img
        _free()
    return out

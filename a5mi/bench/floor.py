"""In-process measurements: stages of one render, the traversal floor of the same rays, stock Mitsuba.

The traversal floor (:func:`logged_floor`) is Mitsuba's traversal of exactly the rays the render kernel casts:
the kernel runs once in ray-log mode (plugins/kernel/raylog.py), which writes every node ray ``(o, d, t_min)``
and every shadow ray ``(p, L, tmin, dist, far)`` it casts, in the order its SIMD packets cast them; those rays
are then traversed as wavefronts on the ``stock=True`` conversion of the scene (spheres as Mitsuba spheres,
planes as rectangles: every primitive the kernel intersects is a Mitsuba shape there). The former estimate,
:func:`first_hit_floor` (each camera ray's first-hit secondary and shadow rays, repeated per lane by the
counts), is kept beside it for comparison with earlier runs.
"""

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

from a5mi.platform.loading import load_dict
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
    floor: dict[str, float]  # s per ray kind of the logged rays: camera, secondary, shadow (logged_floor)
    lights: int
    floor_first_hits: dict[str, float] = field(default_factory=dict)  # s per ray kind (first_hit_floor)
    logged: dict[str, int] = field(default_factory=dict)  # rays in the log: nodes, shadow
    stages: dict[str, float] = field(default_factory=dict)  # first render in this process (s)
    recompiles: int = 0  # of the ``renders`` repeated renders of one loaded scene, how many compiled a kernel
    renders: int = 0

    @property
    def floor_total(self) -> float:
        return sum(self.floor.values())

    @property
    def floor_first_hits_total(self) -> float | None:
        return sum(self.floor_first_hits.values()) if self.floor_first_hits else None


def _camera_rays_for(model: Any, rw: int, rh: int) -> Any:
    """The render's camera rays, all of them, in the driver's order (SPEC B.2, B.5 glibc jitter)."""
    import mitsuba as mi

    from a5mi.platform.arrays import aligned_float32
    from a5mi.plugins.sensors.camera import camera_rays
    from a5mi.render.tiles import jitter_stream

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


def _count_pass(scene: Any, ray: Any, width: int) -> dict[str, npt.NDArray[np.float32]]:
    """Per-lane ray counts by kind from the counting integrator's ``counts`` AOV (one launch)."""
    import mitsuba as mi

    sampler = load_dict({"type": "independent", "sample_count": 1})
    sampler.seed(0, width)
    integrator = scene.integrator()
    _rgb, _valid, aovs = integrator.sample(scene, sampler, mi.RayDifferential3f(ray), None, mi.Bool(True))
    named = dict(zip(integrator.aov_names(), aovs, strict=True))
    return {name: np.asarray(named[f"n_{name}"]) for name in ("reflection", "refraction", "shadow")}


def _cast_timed(scene: Any, o: npt.NDArray[np.float32], d: npt.NDArray[np.float32], maxt: Any, repeat: int,
                test: bool = False) -> float:
    """Best kernel time of one wavefront: ``ray_intersect`` (evaluating ``t`` and the shading normal) or, with
    ``test``, ``ray_test`` of the rays ``(o, d)`` (columns, in order) up to ``maxt`` (None: unbounded)."""
    import drjit as dr
    import mitsuba as mi

    if not o.shape[1]:
        return 0.0
    ray = _full_ray(mi.Point3f(o), mi.Vector3f(d), None if maxt is None else mi.Float(maxt))
    dr.eval(ray)

    def cast() -> Any:
        if test:
            b = scene.ray_test(ray)
            dr.eval(b)
            return b
        s = scene.ray_intersect(ray)
        dr.eval(s.t, s.sh_frame.n)
        return s.t

    return _timed_kernels(cast, repeat)[0]


def first_hit_floor(scene: Any, ray: Any, counts: dict[str, npt.NDArray[np.float32]],
                    repeat: int) -> tuple[dict[str, float], int]:
    """The former floor estimate on the render's own scene: the camera rays, then per camera ray as many
    reflection (``reflect(d, N)``), refraction (straight on, ``d``) and shadow rays (``ray_test`` towards each
    delta light in turn, ``tmax = dist - tmin``) as its tree cast, all re-cast from its first hit. Returns
    ``(seconds by ray kind, delta lights)``. Optimistic: a packet holds copies of one ray, the rays are not the
    tree's deeper ones, and plane-set spheres and planes are not shapes of that scene."""
    import drjit as dr
    import mitsuba as mi

    from a5mi.plugins.optics import reflect

    si = scene.ray_intersect(ray)
    o, d = np.asarray(ray.o), np.asarray(ray.d)
    t, n = np.asarray(si.t), np.asarray(si.sh_frame.n)
    hit_p = o + np.where(np.isfinite(t), t, 0.0) * d
    floor = {"camera": _cast_timed(scene, o, d, None, repeat)}
    lanes = lane_repeat(counts["reflection"])
    refl = np.asarray(reflect(mi.Vector3f(d[:, lanes]), mi.Vector3f(n[:, lanes])))
    floor["reflection"] = _cast_timed(scene, hit_p[:, lanes] + TMIN * refl, refl, None, repeat)
    lanes = lane_repeat(counts["refraction"])
    floor["refraction"] = _cast_timed(scene, hit_p[:, lanes] + TMIN * d[:, lanes], d[:, lanes], None, repeat)

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
            s = scene.ray_intersect(mi.Ray3f(mi.Point3f(o[:, sel]), mi.Vector3f(d[:, sel])))
            ds, _ = emitter.sample_direction(s, mi.Point2f(0.5, 0.5))
            p = s.p
            dr.eval(p, ds.d, ds.dist)
            # a directional light gives one direction and distance for all lanes: broadcast
            ld = np.broadcast_to(np.asarray(ds.d).reshape(3, -1), (3, sel.size))
            dist = np.broadcast_to(np.asarray(ds.dist), (sel.size,))
            parts.append((np.asarray(p) + TMIN * ld, ld, dist - TMIN))
    floor["shadow"] = 0.0
    if parts:
        floor["shadow"] = _cast_timed(scene, np.concatenate([q[0] for q in parts], axis=1),
                                      np.concatenate([q[1] for q in parts], axis=1),
                                      np.concatenate([q[2] for q in parts]), repeat, test=True)
    return floor, len(emitters)


def ray_log(scene: Any, ray: Any, counts: dict[str, npt.NDArray[np.float32]]) -> tuple[dict[str, Any], dict[str, Any]]:
    """Every ray the ``a5_whitted`` kernel of ``scene`` casts for the camera rays ``ray`` (its ray-log mode,
    plugins/kernel/raylog.py), with buffers sized by the counting pass's ``counts``: ``(nodes, shadows)``, numpy
    fields by name in the kernel's packet order. ``RuntimeError`` if the kernel cast more rays than counted."""
    import drjit as dr
    import mitsuba as mi

    from a5mi.plugins.kernel.raylog import RayLog

    width = dr.width(ray.d)
    n_nodes = width + int(np.rint(counts["reflection"]).sum() + np.rint(counts["refraction"]).sum())
    log = RayLog(n_nodes, int(np.rint(counts["shadow"]).sum()))
    sampler = load_dict({"type": "independent", "sample_count": 1})
    sampler.seed(0, width)
    out = scene.integrator().trace(scene, ray, mi.Bool(True), sampler, ray_log=log)
    dr.eval(out)
    if log.nodes > log.max_nodes or log.shadows > log.max_shadows:
        raise RuntimeError(f"ray log: {log.nodes} node rays and {log.shadows} shadow rays cast, "
                           f"{log.max_nodes} and {log.max_shadows} counted")
    return log.read()


def logged_floor(stock: Any, nodes: dict[str, Any], shadows: dict[str, Any], repeat: int) -> dict[str, float]:
    """Traversal time of the logged rays (:func:`ray_log`) on the ``stock=True`` scene ``stock``, in logged
    order, best of ``repeat``: ``camera`` (nodes of ordinal 0) and ``secondary`` (the other nodes) by
    ``ray_intersect`` of ``o + t_min d`` along ``d`` (``t`` and the shading normal evaluated, as the kernel's
    intersect), ``shadow`` by ``ray_test`` of ``p + tmin L`` along ``L`` up to ``dist - tmin`` (``far``, a
    directional light: unbounded, as the kernel tests planes up to +inf)."""
    start = nodes["o"] + nodes["tmin"] * nodes["d"]
    cam = nodes["ordinal"] == 0
    floor = {"camera": _cast_timed(stock, start[:, cam], nodes["d"][:, cam], None, repeat),
             "secondary": _cast_timed(stock, start[:, ~cam], nodes["d"][:, ~cam], None, repeat)}
    big = np.float32(np.finfo(np.float32).max)
    maxt = np.where(shadows["far"], big, shadows["dist"] - shadows["tmin"]).astype(np.float32)
    floor["shadow"] = _cast_timed(stock, shadows["p"] + shadows["tmin"] * shadows["d"], shadows["d"], maxt, repeat,
                                  test=True)
    return floor


def measure_in_process(scene_file: Path, options: Any, repeat: int = 3) -> InProcess:
    """Stages of the first render of ``scene_file`` in this process, then the render's best kernel time and
    the traversal floor for the same rays (see the module docstring). Run from the scene's folder."""
    from a5mi.converters.a5_parser import parse_file
    from a5mi.platform import imageio
    from a5mi.render import driver
    from a5mi.render.session import build_scene

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

    # 2. per-lane ray counts (the counting integrator), the former first-hit estimate, the ray log
    import drjit as dr

    from a5mi.converters.to_mitsuba import to_dict

    scene = build_scene(desc, replace(options, count_rays=True))
    ray = _camera_rays_for(desc, rw, rh)
    dr.eval(ray)
    counts = _count_pass(scene, ray, rw * rh)
    first_hits, n_lights = first_hit_floor(scene, ray, counts, repeat)
    nodes, shadows = ray_log(scene, ray, counts)
    del scene
    _free()
    # 3. the logged rays on the stock conversion, where every primitive the kernel intersects is a shape
    stock = load_dict(to_dict(describe(model, stock=True), options, stock=True))
    floor = logged_floor(stock, nodes, shadows, repeat)
    del stock
    _free()
    rays = {"camera": rw * rh} | {k: int(np.rint(v).sum()) for k, v in counts.items()}
    return InProcess(kernel_execute=best, rays=rays, floor=floor, lights=n_lights, stages=stages,
                     recompiles=int(recompiles), renders=repeat, floor_first_hits=first_hits,
                     logged={"nodes": int(nodes["ordinal"].size), "shadow": int(shadows["ordinal"].size)})


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
        scene = load_dict(scene_dict)
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

"""``a5mi bench``: how fast the real ``a5`` command is, and how far it is from what Mitsuba can do (issue 7).

For each benchmark scene (the four assignment test scenes, ``scene13_diamond`` and ``extras/sibenik/s.txt``)
at the assignment's test command ``-size 300 300 -shadows -bounces 4 -jitter -filter`` (SPEC B.1, B.5):

* **process**: the real ``a5`` command as a child process, run from the scene's folder (as the reference
  images were made), once with an empty Dr.Jit kernel cache (``DRJIT_CACHE_DIR`` set to a fresh folder:
  *cold*) and once more with the same cache (*warm*). Wall time is measured around ``fork`` .. ``wait4``;
  peak memory is the child's own ``ru_maxrss`` from ``os.wait4``. No ``-v`` in these runs: its ray counting
  adds three AOVs to the render kernel (a different kernel; the counts themselves come from the same launch).
* **process stages**: ``--verbose-runs`` more warm runs with ``-v`` (the first also compiles the ``-v``
  kernel into the scene's cache; the best is kept): the command's own stage times, where ``parse`` includes
  the file checks (meshes read, images decoded) and ``startup`` = wall minus the reported stages
  (interpreter start, imports before the parse, exit).
* **stages**: in this process, the first render of the scene (warm disk cache): parse, build, kernel compile
  and execution (``dr.kernel_history()`` via the driver), filter, write; ``startup`` = warm process wall
  minus those (interpreter start, imports, variant activation, exit). Ray counts come from ``a5_whitted``'s
  ``counts`` AOVs.
* **floor**: in this process, the same Mitsuba scene and the render's exact camera rays (glibc jitter,
  SPEC B.2/B.5) replayed through ``scene.ray_intersect`` (evaluating ``t`` and the shading normal), plus
  secondary and shadow rays in the render's counts per camera ray, re-cast from that camera ray's first hit
  (reflection: ``reflect(d, N)``; refraction: straight on, ``d``; shadow: ``ray_test`` towards each light in
  turn, ``tmax = dist - tmin``) -- a pure traversal pass, timed by ``dr.kernel_history()`` execution time
  (best of ``repeat``). ``kernel / floor`` = the render's kernel execution time (same process, warm) over
  the floor.
* **stock**: the same scene converted with ``stock=True`` and rendered by Mitsuba's C++ integrators at the
  render resolution (``3W x 3H``), 1 sample per pixel, so the camera-ray count is identical: ``direct``
  with one emitter sample per light (the camera rays + one shadow ray per light per first hit: a lower
  bound of the a5 ray budget) and ``path`` with ``max_depth = bounces + 2`` and no Russian roulette (every
  vertex continues and samples a light: an upper bound). Time = best of ``repeat`` after a warm-up render.
* **a5soln**: with ``--a5soln PATH`` the sample-solution binary is timed the same way; otherwise the
  published single-core figures of ``reference/README.md`` are printed with ``a5soln / warm``.

``--4k`` adds one ``-size 3840 2160 -jitter -filter`` process run (peak memory is bounded by the tiles: the
driver streams the blur + downsample per tile and keeps only the W x H output). Output: markdown tables on
stdout, or JSON with ``--json``.
"""

from __future__ import annotations

import gc
import json
import os
import re
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from a5mi import data_dir, require_data_dir
from a5mi.spec import TMIN

#: The benchmark scenes, relative to the course data folder.
SCENES: tuple[str, ...] = (
    "scenes/scene06_bunny_1k.txt",
    "scenes/scene10_sphere.txt",
    "scenes/scene11_cube.txt",
    "scenes/scene12_vase.txt",
    "scenes/scene13_diamond.txt",
    "extras/sibenik/s.txt",
)
#: The four assignment test scenes (the targets apply to these).
TEST_SCENES: tuple[str, ...] = ("scene06_bunny_1k", "scene10_sphere", "scene11_cube", "scene12_vase")

#: Used when ``reference/README.md`` cannot be read: a5soln, 2-vCPU Xeon, one core, ``-jitter -filter -bounces 4``.
PUBLISHED_A5SOLN: dict[str, float] = {"scene06": 5.7, "scene10": 4.8, "scene11": 3.5, "scene12": 64.7}

#: Targets of issue 7 (reported, never asserted by a timed test).
TARGET_WARM_S = 0.6
TARGET_COLD_S = 3.0
TARGET_FLOOR_RATIO = 2.0
TARGET_PEAK_MB = 1024.0

#: Stages printed by ``a5 -v`` (its ``render`` = compile + execute + the tile loop's Python work).
VERBOSE_STAGES: tuple[str, ...] = ("parse", "variant", "build", "render", "filter", "write")
#: Stages measured in-process for the table (``render`` split into kernel compile and execution).
STAGES: tuple[str, ...] = ("parse", "build", "compile", "execute", "filter", "write")
RAY_KINDS: tuple[str, ...] = ("camera", "reflection", "refraction", "shadow")


# --------------------------------------------------------------------------------------------------------
# Child processes
# --------------------------------------------------------------------------------------------------------


@dataclass
class ProcessRun:
    """One child process: wall time (s), its own peak RSS (MB), exit status, stderr, and its ``-v`` report."""

    wall: float
    peak_mb: float
    returncode: int
    stderr: str
    stages: dict[str, float] = field(default_factory=dict)
    rays: dict[str, int] = field(default_factory=dict)

    @property
    def startup(self) -> float | None:
        """Wall time not covered by the reported stages (interpreter start, imports, exit); None without ``-v``."""
        if not self.stages:
            return None
        return self.wall - sum(self.stages.get(k, 0.0) for k in VERBOSE_STAGES)


#: Runs the measured command as its own child: on Linux a child's ``ru_maxrss`` starts from the RSS of the
#: process that spawned it (``exec`` keeps the old image's high-water mark), so the command is launched from
#: this small interpreter rather than from the benchmark process, which holds scenes and buffers.
_LAUNCHER = """\
import json, os, subprocess, sys, threading, time
cmd, timeout = json.loads(sys.argv[1]), float(sys.argv[2])
t0 = time.perf_counter()
proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL)
timer = threading.Timer(timeout, proc.kill)
timer.start()
_, status, usage = os.wait4(proc.pid, 0)
timer.cancel()
wall = time.perf_counter() - t0
print(json.dumps({"wall": wall, "maxrss_kb": usage.ru_maxrss, "returncode": os.waitstatus_to_exitcode(status)}))
"""


def run_process(
    cmd: Sequence[str], *, cwd: str | Path | None = None, env: dict[str, str] | None = None, timeout: float = 600.0
) -> ProcessRun:
    """Run ``cmd``: wall time from spawn to reaping, peak memory = that child's own ``ru_maxrss`` (KiB on
    Linux) from ``os.wait4``, both taken by a small launcher interpreter (see :data:`_LAUNCHER`). The child is
    killed after ``timeout`` seconds (returncode then negative); its stderr is returned."""
    with tempfile.TemporaryFile() as err:
        proc = subprocess.run([sys.executable, "-c", _LAUNCHER, json.dumps(list(cmd)), str(timeout)], cwd=cwd,
                              env=env, stdout=subprocess.PIPE, stderr=err, check=False)
        err.seek(0)
        text = err.read().decode(errors="replace")
    try:
        m = json.loads(proc.stdout.decode().strip().splitlines()[-1])
    except (ValueError, IndexError):
        raise RuntimeError(f"bench launcher failed (exit {proc.returncode}): {text.strip()[-300:]}") from None
    stages, rays = parse_verbose(text)
    return ProcessRun(wall=m["wall"], peak_mb=m["maxrss_kb"] / 1024.0, returncode=m["returncode"], stderr=text,
                      stages=stages, rays=rays)


_TIMES = re.compile(r"^a5: times (.*)$", re.M)
_TIME_ITEM = re.compile(r"(\w+) ([0-9.]+) s")
_CAMERA = re.compile(r"\((\d+) camera rays")
_SECONDARY = re.compile(r"^a5: secondary rays (.*)$", re.M)
_RAY_ITEM = re.compile(r"(\w+) (\d+)")


def parse_verbose(text: str) -> tuple[dict[str, float], dict[str, int]]:
    """The stage times (s) and ray counts printed by ``a5 -v`` (see :func:`a5mi.cli._render_command`).

    ``a5: times parse 0.010 s, build 0.200 s, ...`` -> ``{'parse': 0.01, 'build': 0.2, ...}``;
    ``(810000 camera rays`` and ``a5: secondary rays reflection 5, refraction 0, shadow 7`` ->
    ``{'camera': 810000, 'reflection': 5, 'refraction': 0, 'shadow': 7}``. Missing lines give empty dicts.
    """
    stages: dict[str, float] = {}
    rays: dict[str, int] = {}
    m = _TIMES.search(text)
    if m:
        stages = {k: float(v) for k, v in _TIME_ITEM.findall(m.group(1))}
    m = _CAMERA.search(text)
    if m:
        rays["camera"] = int(m.group(1))
    m = _SECONDARY.search(text)
    if m:
        rays.update({k: int(v) for k, v in _RAY_ITEM.findall(m.group(1))})
    return stages, rays


def cpu_busy(interval: float = 0.5, stat: str = "/proc/stat") -> float:
    """Fraction of all CPUs busy over ``interval`` s, from the ``cpu`` line of ``/proc/stat``
    (busy = 1 - (idle + iowait) / total jiffies); 0.0 where ``/proc/stat`` is unreadable."""

    def sample() -> tuple[int, int]:
        with open(stat) as f:
            fields = [int(v) for v in f.readline().split()[1:]]
        return fields[3] + (fields[4] if len(fields) > 4 else 0), sum(fields)

    try:
        idle0, total0 = sample()
        time.sleep(interval)
        idle1, total1 = sample()
    except (OSError, ValueError, IndexError):
        return 0.0
    return 1.0 - (idle1 - idle0) / max(1, total1 - total0)


def wait_for_idle(max_wait: float, threshold: float = 0.1) -> float:
    """Wait (up to ``max_wait`` s) until other processes use less than ``threshold`` of the CPUs, so timings
    are not shared with someone else's work; returns the last busy fraction seen."""
    deadline = time.monotonic() + max_wait
    busy = cpu_busy()
    while busy >= threshold and time.monotonic() < deadline:
        busy = cpu_busy()
    return busy


def a5_command() -> list[str]:
    """The installed ``a5`` console script beside this interpreter, else ``python -m a5mi`` (the same entry)."""
    script = Path(sys.executable).with_name("a5")
    if script.is_file() and os.access(script, os.X_OK):
        return [str(script)]
    return [sys.executable, "-m", "a5mi"]


def render_flags(width: int, height: int, bounces: int) -> list[str]:
    """The assignment's test flags at a size: ``-size W H -shadows -bounces N -jitter -filter``."""
    return ["-size", str(width), str(height), "-shadows", "-bounces", str(bounces), "-jitter", "-filter"]


def cache_env(cache_dir: str | Path) -> dict[str, str]:
    """This environment with Dr.Jit's kernel cache (``DRJIT_CACHE_DIR``; default ``~/.drjit``) moved."""
    env = dict(os.environ)
    env["DRJIT_CACHE_DIR"] = str(cache_dir)
    return env


# --------------------------------------------------------------------------------------------------------
# Published figures, scene names, tables
# --------------------------------------------------------------------------------------------------------

_PUBLISHED = re.compile(r"(scene\d+) ([0-9.]+) s")


def published_times(readme: str) -> dict[str, float]:
    """``scene06 5.7 s, scene10 4.8 s`` in ``reference/README.md`` -> ``{'scene06': 5.7, 'scene10': 4.8}``."""
    return {k: float(v) for k, v in _PUBLISHED.findall(readme)}


def load_published(root: Path | None = None) -> dict[str, float]:
    """The sample solution's published times, from the course README when readable (else the copy above)."""
    path = (root or data_dir()) / "reference" / "README.md"
    try:
        found = published_times(path.read_text())
    except OSError:
        found = {}
    return found or dict(PUBLISHED_A5SOLN)


def scene_name(path: str | Path) -> str:
    """Display name: the file stem, or ``folder/stem`` for generic stems (``extras/sibenik/s.txt`` -> ``sibenik/s``)."""
    p = Path(path)
    return p.stem if p.stem.startswith("scene") else f"{p.parent.name}/{p.stem}"


def published_key(name: str) -> str | None:
    """``scene06_bunny_1k`` -> ``scene06`` (the README's key); None for other names."""
    m = re.match(r"(scene\d+)", name)
    return m.group(1) if m else None


def resolve_scenes(names: Sequence[str], root: Path | None = None) -> list[Path]:
    """Benchmark scene files: :data:`SCENES` when ``names`` is empty; else each name is a path, or a stem /
    prefix of one of :data:`SCENES` (``scene10`` -> ``scenes/scene10_sphere.txt``). Raises ``ValueError``."""
    root = root or require_data_dir()
    if not names:
        return [root / s for s in SCENES]
    out = []
    for name in names:
        p = Path(name)
        if p.suffix == ".txt" and p.is_file():
            out.append(p.resolve())
            continue
        hits = [s for s in SCENES if scene_name(s).startswith(name) or Path(s).stem.startswith(name)]
        if len(hits) != 1:
            raise ValueError(f"unknown benchmark scene '{name}' (expected a .txt file or one of "
                             f"{', '.join(scene_name(s) for s in SCENES)})")
        out.append(root / hits[0])
    return out


def format_table(headers: Sequence[str], rows: Sequence[Sequence[Any]]) -> str:
    """A markdown table, columns padded to their widest cell; floats with 3 significant-ish decimals."""

    def cell(v: Any) -> str:
        if v is None:
            return "-"
        if isinstance(v, float):
            return f"{v:.3f}" if abs(v) < 10 else f"{v:.1f}" if abs(v) < 1000 else f"{v:.0f}"
        return str(v)

    table = [[cell(h) for h in headers]] + [[cell(v) for v in r] for r in rows]
    widths = [max(len(r[c]) for r in table) for c in range(len(headers))]
    lines = ["| " + " | ".join(c.ljust(w) if i == 0 else c.rjust(w)
                               for i, (c, w) in enumerate(zip(r, widths, strict=True))) + " |" for r in table]
    lines.insert(1, "|" + "|".join("-" * (w + 2) if i == 0 else "-" * (w + 1) + ":" for i, w in enumerate(widths))
                 + "|")
    return "\n".join(lines)


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


@contextmanager
def _chdir(path: Path) -> Iterator[None]:
    old = os.getcwd()
    os.chdir(path)
    try:
        yield
    finally:
        os.chdir(old)


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

    from a5mi.driver import aligned_float32, jitter_stream
    from a5mi.plugins.camera import camera_rays

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

    rw, rh = options.render_size

    # 1. stages of one a5 run (what the child process does after its imports), then the warm kernel time
    from a5mi.converters.describe import describe

    t0 = time.perf_counter()
    model = parse_file(scene_file)
    stages = {"parse": time.perf_counter() - t0}
    t0 = time.perf_counter()
    desc = describe(model)  # the files are read here, once (the a5 command does the same)
    scene = driver.build_scene(desc, options)
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
    scene = driver.build_scene(desc, replace(options, count_rays=True))
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


# --------------------------------------------------------------------------------------------------------
# The benchmark
# --------------------------------------------------------------------------------------------------------


@dataclass
class SceneResult:
    name: str
    path: str
    cold: ProcessRun | None = None
    warm: ProcessRun | None = None
    verbose: ProcessRun | None = None  # best warm ``a5 -v`` run: the process's own stage times
    inproc: InProcess | None = None
    stock: dict[str, float] = field(default_factory=dict)
    a5soln: float | None = None  # measured here
    a5soln_published: float | None = None
    busy_before: float | None = None  # CPU fraction used by others just before this scene's runs
    errors: list[str] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        d = asdict(self)
        for key in ("cold", "warm", "verbose"):
            if d[key] is not None:
                d[key].pop("stderr")
                d[key]["startup"] = getattr(self, key).startup
        if self.inproc is not None:
            d["inproc"]["floor_total"] = self.inproc.floor_total
        return d


def bench_scene(path: Path, args: BenchSettings, published: dict[str, float], log: Any) -> SceneResult:
    """All measurements of one scene (each part records its error instead of aborting the run)."""
    name = scene_name(path)
    res = SceneResult(name=name, path=str(path))
    key = published_key(name)
    res.a5soln_published = published.get(key) if key else None
    w, h = args.size
    flags = render_flags(w, h, args.bounces)
    if args.wait_idle > 0:
        log(f"{name}: waiting for idle CPUs (up to {args.wait_idle:.0f} s) ...")
        res.busy_before = wait_for_idle(args.wait_idle)
    with tempfile.TemporaryDirectory(prefix="a5bench-") as tmp:
        out = str(Path(tmp) / "out.png")
        if not args.no_process:
            cache = Path(tmp) / "drjit-cache"
            cache.mkdir()
            cmd = a5_command() + ["-input", path.name, "-output", out, *flags]
            for k in range(1 + args.warm_runs):
                label = "cold" if k == 0 else "warm"
                log(f"{name}: {label} process ...")
                run = run_process(cmd, cwd=path.parent, env=cache_env(cache), timeout=args.timeout)
                if run.returncode != 0:
                    res.errors.append(f"{label} a5 exited {run.returncode}: {run.stderr.strip()[-300:]}")
                if k == 0:
                    res.cold = run
                elif res.warm is None or run.wall < res.warm.wall:
                    res.warm = run  # best of the warm runs
            for _ in range(args.verbose_runs):
                log(f"{name}: warm process -v ...")
                run = run_process(cmd + ["-v"], cwd=path.parent, env=cache_env(cache), timeout=args.timeout)
                if run.returncode != 0:
                    res.errors.append(f"a5 -v exited {run.returncode}: {run.stderr.strip()[-300:]}")
                elif res.verbose is None or run.wall < res.verbose.wall:
                    res.verbose = run
        if args.a5soln:
            log(f"{name}: a5soln ...")
            run = run_process([args.a5soln, "-input", path.name, "-output", str(Path(tmp) / "soln.bmp"), *flags],
                              cwd=path.parent, timeout=args.timeout)
            if run.returncode == 0:
                res.a5soln = run.wall
            else:
                res.errors.append(f"a5soln exited {run.returncode}: {run.stderr.strip()[-300:]}")
    if args.no_inprocess:
        return res
    from a5mi import driver
    from a5mi.converters.a5_parser import parse_file

    options = driver.RenderOptions(width=w, height=h, bounces=args.bounces, shadows=True, jitter=True, filter=True)
    with _chdir(path.parent):
        log(f"{name}: stages and floor ...")
        try:
            res.inproc = measure_in_process(Path(path.name), options, repeat=args.repeat)
        except Exception as exc:  # noqa: BLE001 - a benchmark reports what failed and goes on
            res.errors.append(f"floor: {type(exc).__name__}: {exc}")
        if not args.no_stock:
            log(f"{name}: stock ...")
            try:
                res.stock = measure_stock(parse_file(path.name), options, repeat=args.repeat)
            except Exception as exc:  # noqa: BLE001
                res.errors.append(f"stock: {type(exc).__name__}: {exc}")
    return res


def machine_info() -> dict[str, Any]:
    """CPU model, logical cores, LLVM library, Mitsuba / Dr.Jit versions (what BENCHMARKS.md quotes)."""
    cpu = "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    info: dict[str, Any] = {"cpu": cpu, "cores": os.cpu_count(), "python": sys.version.split()[0]}
    try:
        from a5mi import llvm

        lib = llvm.check()
        info["llvm"] = f"{lib.major} ({lib.path})"
    except Exception as exc:  # noqa: BLE001
        info["llvm"] = f"unavailable: {exc}"
    try:
        import drjit as dr
        import mitsuba as mi

        info["mitsuba"], info["drjit"] = mi.__version__, dr.__version__
    except Exception:  # noqa: BLE001
        pass
    return info


def _ratio(a: float | None, b: float | None) -> float | None:
    return a / b if a is not None and b else None


def report(results: Sequence[SceneResult], info: dict[str, Any], extra: dict[str, Any]) -> str:
    """The markdown tables of a run."""
    out = [f"machine: {info.get('cpu')}, {info.get('cores')} logical cores, LLVM {info.get('llvm')}, "
           f"Mitsuba {info.get('mitsuba')}, Dr.Jit {info.get('drjit')}", ""]
    rows = []
    for r in results:
        rows.append([r.name,
                     r.cold.wall if r.cold else None, r.warm.wall if r.warm else None,
                     r.cold.peak_mb if r.cold else None, r.warm.peak_mb if r.warm else None,
                     r.a5soln if r.a5soln is not None else r.a5soln_published,
                     "measured" if r.a5soln is not None else ("published" if r.a5soln_published else None),
                     _ratio(r.a5soln if r.a5soln is not None else r.a5soln_published, r.warm.wall if r.warm else None),
                     r.busy_before])
    out += ["Whole process (`a5 -input SCENE -output OUT.png " + " ".join(extra.get("flags", [])) + "`, wall s, "
            "warm = best of the warm runs; peak RSS MB; busy = CPU share used by other processes just before)", "",
            format_table(["scene", "cold s", "warm s", "cold MB", "warm MB", "a5soln s", "a5soln", "a5soln/warm",
                          "busy"],
                         rows), ""]
    rows = [[r.name, r.verbose.wall, r.verbose.startup, *(r.verbose.stages.get(k) for k in VERBOSE_STAGES),
             r.verbose.stages.get("compile"), r.verbose.stages.get("execute"), r.verbose.stages.get("jitter")]
            for r in results if r.verbose is not None and r.verbose.stages]
    if rows:
        out += ["Warm process by stage (`a5 ... -v`, best of the -v runs; s): `parse` includes the file checks "
                "(meshes read, images decoded); `startup` = wall - parse - variant - build - render - filter - "
                "write (interpreter, imports before the parse, exit); compile, execute and jitter are inside "
                "render; -v adds the ray-count AOVs to the kernel", "",
                format_table(["scene", "wall", "startup", *VERBOSE_STAGES, "compile", "execute", "jitter"], rows),
                ""]
    rows = []
    for r in results:
        if r.inproc is None or not r.inproc.stages:
            continue
        st = r.inproc.stages
        rest = None
        if r.warm is not None:
            rest = r.warm.wall - sum(st.get(k, 0.0) for k in ("parse", "build", "render", "filter", "write"))
        rows.append([r.name, rest] + [st.get(k) for k in STAGES] + [f"{r.inproc.recompiles}/{r.inproc.renders}"])
    if rows:
        out += ["Stages of one render (s; in-process, first render of the scene; `startup` = warm process wall - "
                "parse - build - render - filter - write: interpreter, imports, variant, exit; `recompiled` = "
                "repeated renders of the loaded scene that compiled a kernel again)", "",
                format_table(["scene", "startup", *STAGES, "recompiled"], rows), ""]
    rows = []
    for r in results:
        ip = r.inproc
        rays = ip.rays if ip else (r.warm.rays if r.warm else {})
        total = sum(rays.get(k, 0) for k in RAY_KINDS) if rays else None
        rows.append([r.name] + [rays.get(k) for k in RAY_KINDS] + [
            total / ip.kernel_execute / 1e6 if ip and total else None,
            ip.kernel_execute if ip else None,
            ip.floor.get("camera") if ip else None,
            ip.floor.get("reflection", 0) + ip.floor.get("refraction", 0) if ip else None,
            ip.floor.get("shadow") if ip else None,
            ip.floor_total if ip else None,
            _ratio(ip.kernel_execute, ip.floor_total) if ip else None])
    out += ["Rays and the traversal floor (in-process, warm kernels, best of repeat; times in s)", "",
            format_table(["scene", *RAY_KINDS, "Mrays/s", "kernel", "floor cam", "floor refl+refr",
                          "floor shadow", "floor", "kernel/floor"], rows), ""]
    rows = [[r.name, r.inproc.kernel_execute if r.inproc else None, r.stock.get("direct"), r.stock.get("path"),
             _ratio(r.inproc.kernel_execute if r.inproc else None, r.stock.get("path"))]
            for r in results]
    out += ["Stock Mitsuba, same scene (`stock=True`), render resolution, 1 spp (s, best of repeat)", "",
            format_table(["scene", "a5 kernel", "stock direct", "stock path", "a5 kernel/path"], rows), ""]
    if "4k" in extra:
        run = extra["4k"]
        out += [f"4K: `{extra['4k_cmd']}`: wall {run.wall:.1f} s, peak {run.peak_mb:.0f} MB, exit {run.returncode}"
                + (f"; stages {run.stages}" if run.stages else ""), ""]
    errors = [f"- {r.name}: {e}" for r in results for e in r.errors]
    if errors:
        out += ["Errors:", *errors, ""]
    return "\n".join(out)


@dataclass(frozen=True)
class BenchSettings:
    """What ``a5mi bench`` measures (its flags): image size and bounces of the test command, repetitions,
    which parts run, the optional a5soln binary and the 4K run, idle wait and child timeout (s)."""

    size: tuple[int, int] = (300, 300)
    bounces: int = 4
    repeat: int = 3
    a5soln: str | None = None
    k4: bool = False
    k4_scene: str = "scene10"
    no_process: bool = False
    no_inprocess: bool = False
    no_stock: bool = False
    warm_runs: int = 2
    verbose_runs: int = 2
    wait_idle: float = 30.0
    timeout: float = 600.0

    def __post_init__(self) -> None:
        if min(self.size) <= 0 or self.bounces < 0 or self.repeat < 1 or self.warm_runs < 1 or self.verbose_runs < 0:
            raise ValueError("--size, --repeat and --warm-runs must be positive, --bounces and --verbose-runs >= 0")


@dataclass
class BenchRun:
    """A whole run: per-scene results, the machine, the command's flags, the 4K run, this process's peak."""

    results: list[SceneResult]
    info: dict[str, Any]
    extra: dict[str, Any]
    self_peak_mb: float

    @property
    def failed(self) -> bool:
        return any(r.errors for r in self.results) or ("4k" in self.extra and self.extra["4k"].returncode != 0)

    def report(self) -> str:
        return report(self.results, self.info, self.extra)

    def to_json(self) -> str:
        doc: dict[str, Any] = {"machine": self.info, "flags": self.extra["flags"], "bench_peak_mb": self.self_peak_mb,
                               "scenes": [r.to_json() for r in self.results]}
        if "4k" in self.extra:
            k4 = asdict(self.extra["4k"])
            k4.pop("stderr")
            doc["4k"] = {"cmd": self.extra["4k_cmd"], **k4}
        return json.dumps(doc, indent=2)


def find_executable(path: str) -> str:
    """The absolute path of an executable given by name or path; ``ValueError`` if there is none."""
    found = shutil.which(path) or (path if os.access(path, os.X_OK) and os.path.isfile(path) else None)
    if found is None:
        raise ValueError(f"'{path}' is not an executable")
    return os.path.abspath(found)


def run_benchmark(paths: Sequence[Path], settings: BenchSettings, log: Any) -> BenchRun:
    """Measure every scene of ``paths`` (and the 4K run) as the module docstring says; ``log(msg)`` receives
    progress lines. Needs the variant active unless ``no_inprocess``."""
    published = load_published()
    results = [bench_scene(p, settings, published, log) for p in paths]
    extra: dict[str, Any] = {"flags": render_flags(*settings.size, settings.bounces)}
    if settings.k4:
        (p4,) = resolve_scenes([settings.k4_scene])
        with tempfile.TemporaryDirectory(prefix="a5bench-4k-") as tmp:
            cmd = a5_command() + ["-input", p4.name, "-output", str(Path(tmp) / "4k.png"),
                                  *render_flags(3840, 2160, settings.bounces)]
            log(f"4K: {scene_name(p4)} ...")
            extra["4k"] = run_process(cmd, cwd=p4.parent, timeout=settings.timeout)
            extra["4k_cmd"] = " ".join(["a5", *cmd[len(a5_command()):]]).replace(str(Path(tmp)) + "/", "")
    return BenchRun(results, machine_info(), extra, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0)

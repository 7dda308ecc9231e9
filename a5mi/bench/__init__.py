"""``a5mi bench``: how fast the real ``a5`` command is, and how far it is from what Mitsuba can do (SPEC B.1, B.5).

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
* **floor**: in this process, Mitsuba's traversal of exactly the rays the render kernel casts. The kernel
  runs once more in its ray-log mode (plugins/kernel/raylog.py; buffers sized by the ``counts`` AOV), on the
  render's exact camera rays (glibc jitter, SPEC B.2/B.5), and writes every node of the SPEC B.3 ray tree it
  pops (camera, reflection, refraction: ``(o, d, t_min)``) and every shadow ray it casts (``(p, L, tmin,
  dist, far)``; a light whose term is exactly 0 casts none) in the order its SIMD packets cast them. Those
  rays are then traversed on the ``stock=True`` conversion of the scene, where spheres are Mitsuba spheres and
  planes rectangles, so every primitive the kernel intersects is a shape: node rays by ``ray_intersect`` of
  ``o + t_min d`` along ``d`` (evaluating ``t`` and the shading normal), camera (the nodes of ordinal 0) and
  secondary as two wavefronts; shadow rays by ``ray_test`` of ``p + tmin L`` along ``L`` up to ``dist - tmin``
  (unbounded for a directional light, whose planes the kernel tests up to +inf). Each wavefront is timed by
  ``dr.kernel_history()`` execution time (best of ``repeat``); ``floor`` is their sum and ``kernel / floor``
  = the render's kernel execution time (same process, warm) over it. ``floor (first hits)`` is the former
  estimate, kept so earlier runs compare: the camera rays plus, per camera ray, as many secondary and shadow
  rays as its tree cast, all re-cast from its first hit (reflection ``reflect(d, N)``, refraction straight on,
  shadow towards each light in turn), on the a5 scene (which lacks the plane-set spheres and planes); its
  packets hold copies of one ray, so it is optimistic.
* **stock**: the same scene converted with ``stock=True`` and rendered by Mitsuba's C++ integrators at the
  render resolution (``3W x 3H``), 1 sample per pixel, so the camera-ray count is identical: ``direct``
  with one emitter sample per light (the camera rays + one shadow ray per light per first hit: a lower
  bound of the a5 ray budget) and ``path`` with ``max_depth = bounces + 2`` and no Russian roulette (every
  vertex continues and samples a light: an upper bound). Time = best of ``repeat`` after a warm-up render.
* **a5soln**: with ``--a5soln PATH`` the sample-solution binary is timed the same way; otherwise the
  published single-core figures of ``reference/README.md`` are printed with ``a5soln / warm``.

**batch** (:mod:`a5mi.bench.batch`, ``a5mi render`` with several jobs): per test scene, ``--batch-renders``
extra renders in one :class:`a5mi.render.session.RenderSession`, each written, their wall time against kernel +
filter + write; and one ``a5mi render`` process over the test scenes against the sum of their warm ``a5``
processes.

``--4k`` adds one ``-size 3840 2160 -jitter -filter`` process run (peak memory is bounded by the tiles: the
driver streams the blur + downsample per tile and keeps only the W x H output). Output: markdown tables on
stdout, or JSON with ``--json``; ``--json-file FILE`` also writes the JSON.
"""

from __future__ import annotations

import json
import os
import resource
import shutil
import tempfile
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from a5mi.bench.floor import InProcess, _chdir, lane_repeat, measure_in_process, measure_stock, rank_within_lane
from a5mi.bench.process import (
    ProcessRun,
    a5_command,
    cache_env,
    cpu_busy,
    parse_verbose,
    render_flags,
    run_process,
    wait_for_idle,
)
from a5mi.bench.report import format_table, machine_info, report
from a5mi.bench.results import SceneResult
from a5mi.bench.scenes import (
    PUBLISHED_A5SOLN,
    RAY_KINDS,
    SCENES,
    STAGES,
    TARGET_COLD_S,
    TARGET_FLOOR_RATIO,
    TARGET_PEAK_MB,
    TARGET_WARM_S,
    TEST_SCENES,
    VERBOSE_STAGES,
    load_published,
    published_key,
    published_times,
    resolve_scenes,
    scene_name,
)
from a5mi.render.options import RenderOptions
from a5mi.spec import MAX_SIZE

#: The parts of a run (module docstring; ``--no-process``, ``--no-inprocess``, ``--no-stock`` leave one out): the
#: ``a5`` child processes (and a5soln's, the 4K run, the batch process), the in-process stages, floor and batch,
#: and the stock Mitsuba comparison (in-process too).
PARTS: frozenset[str] = frozenset({"process", "inprocess", "stock"})


def assignment_command(width: int = 300, height: int = 300, bounces: int = 4) -> RenderOptions:
    """The assignment's test command (SPEC B.1, B.5) at a size: ``-size W H -shadows -bounces N -jitter -filter``
    as in-process options (:func:`~a5mi.bench.process.render_flags` are its flags)."""
    return RenderOptions(width=width, height=height, bounces=bounces, shadows=True, jitter=True, filter=True)

# --------------------------------------------------------------------------------------------------------
# The benchmark
# --------------------------------------------------------------------------------------------------------


def bench_scene(path: Path, args: BenchSettings, published: dict[str, float], log: Any) -> SceneResult:
    """All measurements of one scene (each part records its error instead of aborting the run)."""
    name = scene_name(path)
    res = SceneResult(name=name, path=str(path))
    key = published_key(name)
    res.a5soln_published = published.get(key) if key else None
    flags = render_flags(args.test.width, args.test.height, args.test.bounces)
    if args.wait_idle > 0:
        log(f"{name}: waiting for idle CPUs (up to {args.wait_idle:.0f} s) ...")
        res.busy_before = wait_for_idle(args.wait_idle)
    with tempfile.TemporaryDirectory(prefix="a5bench-") as tmp:
        out = str(Path(tmp) / "out.png")
        if "process" in args.parts:
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
    if "inprocess" not in args.parts:
        return res
    from a5mi.converters.a5_parser import parse_file

    with _chdir(path.parent):
        log(f"{name}: stages and floor ...")
        try:
            res.inproc = measure_in_process(Path(path.name), args.test, repeat=args.repeat)
        except Exception as exc:  # noqa: BLE001 - a benchmark reports what failed and goes on
            res.errors.append(f"floor: {type(exc).__name__}: {exc}")
        if "stock" in args.parts:
            log(f"{name}: stock ...")
            try:
                res.stock = measure_stock(parse_file(path.name), args.test, repeat=args.repeat)
            except Exception as exc:  # noqa: BLE001
                res.errors.append(f"stock: {type(exc).__name__}: {exc}")
    return res


@dataclass(frozen=True)
class BenchSettings:
    """What ``a5mi bench`` measures (its flags): the test command (:func:`assignment_command`: image size and
    bounces), in-process repetitions, the optional a5soln binary, the scene of the 4K run (None: no 4K run), which
    :data:`PARTS` run, warm and ``-v`` process runs per scene, idle wait and child timeout (s), batch renders."""

    test: RenderOptions = field(default_factory=assignment_command)
    repeat: int = 3
    a5soln: str | None = None
    k4_scene: str | None = None
    parts: frozenset[str] = PARTS
    warm_runs: int = 2
    verbose_runs: int = 2
    wait_idle: float = 30.0
    timeout: float = 600.0
    batch_renders: int = 3

    def __post_init__(self) -> None:
        if self.repeat < 1 or self.warm_runs < 1 or self.verbose_runs < 0:
            raise ValueError("--repeat and --warm-runs must be positive, --verbose-runs >= 0")
        if max(self.test.width, self.test.height) > MAX_SIZE:
            raise ValueError(f"--size {self.test.width} {self.test.height}: the largest side is {MAX_SIZE} (SPEC B.1)")
        if not self.parts <= PARTS:
            raise ValueError(f"parts must be among {', '.join(sorted(PARTS))}, got {', '.join(sorted(self.parts))}")


@dataclass
class BenchRun:
    """A whole run: per-scene results, the machine, the command's flags, the 4K run, this process's peak."""

    results: list[SceneResult]
    info: dict[str, Any]
    extra: dict[str, Any]
    self_peak_mb: float

    @property
    def failed(self) -> bool:
        return (any(r.errors for r in self.results) or ("4k" in self.extra and self.extra["4k"].returncode != 0)
                or "batch_error" in self.extra
                or ("batch_process" in self.extra and self.extra["batch_process"]["warm"].returncode != 0))

    def report(self) -> str:
        return report(self.results, self.info, self.extra)

    def to_json(self) -> str:
        doc: dict[str, Any] = {"machine": self.info, "flags": self.extra["flags"], "bench_peak_mb": self.self_peak_mb,
                               "scenes": [r.to_json() for r in self.results]}
        if "batch" in self.extra:
            doc["batch"] = [{"name": b.name, "first": b.first, "extra": b.extra, "ratio": b.ratio}
                            for b in self.extra["batch"]]
        if "batch_process" in self.extra:
            bp = dict(self.extra["batch_process"])
            for key in ("cold", "warm"):
                run = asdict(bp[key])
                run.pop("stderr")
                bp[key] = run
            doc["batch_process"] = bp
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


def _bench_batch(results: list[SceneResult], settings: BenchSettings, extra: dict[str, Any], log: Any) -> None:
    """The batch figures (module docstring) over the test scenes among ``results``, into ``extra``."""
    from a5mi.bench.batch import measure_batch, measure_batch_process

    tests = [r for r in results if r.name in TEST_SCENES] or results
    paths = [Path(r.path).resolve() for r in tests]
    test = settings.test
    if "inprocess" in settings.parts:
        try:
            extra["batch"] = measure_batch(paths, test, settings.batch_renders, log)
        except Exception as exc:  # noqa: BLE001 - a benchmark reports what failed and goes on
            extra["batch_error"] = f"{type(exc).__name__}: {exc}"
    if "process" in settings.parts:
        log("batch process ...")
        with tempfile.TemporaryDirectory(prefix="a5bench-bcache-") as cache:
            runs = [measure_batch_process(paths, render_flags(test.width, test.height, test.bounces), cache_env(cache),
                                          settings.timeout) for _ in range(1 + settings.warm_runs)]
        best = min((r for r, _ in runs[1:]), key=lambda r: r.wall)  # the first run fills the kernel cache
        extra["batch_process"] = {"cmd": runs[0][1], "cold": runs[0][0], "warm": best,
                                  "separate_warm": [r.warm.wall if r.warm else None for r in tests],
                                  "scenes": [r.name for r in tests]}


def run_benchmark(paths: Sequence[Path], settings: BenchSettings, log: Any) -> BenchRun:
    """Measure every scene of ``paths`` (and the 4K run) as the module docstring says; ``log(msg)`` receives
    progress lines. Needs the variant active where ``"inprocess"`` is among its parts."""
    published = load_published()
    results = [bench_scene(p, settings, published, log) for p in paths]
    test = settings.test
    extra: dict[str, Any] = {"flags": render_flags(test.width, test.height, test.bounces)}
    if settings.batch_renders > 0:
        _bench_batch(results, settings, extra, log)
    if settings.k4_scene is not None:
        (p4,) = resolve_scenes([settings.k4_scene])
        with tempfile.TemporaryDirectory(prefix="a5bench-4k-") as tmp:
            cmd = a5_command() + ["-input", p4.name, "-output", str(Path(tmp) / "4k.png"),
                                  *render_flags(3840, 2160, test.bounces)]
            log(f"4K: {scene_name(p4)} ...")
            extra["4k"] = run_process(cmd, cwd=p4.parent, timeout=settings.timeout)
            extra["4k_cmd"] = " ".join(["a5", *cmd[len(a5_command()):]]).replace(str(Path(tmp)) + "/", "")
    return BenchRun(results, machine_info(), extra, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0)


__all__ = [
    "PARTS", "PUBLISHED_A5SOLN", "RAY_KINDS", "SCENES", "STAGES", "TARGET_COLD_S", "TARGET_FLOOR_RATIO",
    "TARGET_PEAK_MB", "TARGET_WARM_S", "TEST_SCENES", "VERBOSE_STAGES", "BenchRun", "BenchSettings", "InProcess",
    "ProcessRun", "SceneResult", "a5_command", "assignment_command", "bench_scene", "cache_env", "cpu_busy",
    "find_executable", "format_table", "lane_repeat", "load_published", "machine_info", "measure_in_process",
    "measure_stock", "parse_verbose", "published_key", "published_times", "rank_within_lane", "render_flags",
    "report", "resolve_scenes", "run_benchmark", "run_process", "scene_name", "wait_for_idle",
]

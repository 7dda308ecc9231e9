"""One render split across Dask workers by bands of render-buffer rows (docs/EXTENSIONS.md E.24).

A sample's colour depends only on the scene, the options and its index ``j · RW + i`` (its pixel position and
E.5 keys), never on the process or the tile that traces it (:func:`a5mi.render.driver.render_band`). The render
buffer's rows are cut into ``parts`` bands of about equal height, each starting on a multiple of
``m = PACKET_ALIGN / gcd(RW, PACKET_ALIGN)`` rows (so every sample keeps its SIMD packet neighbours); each
band is one Dask task (``retries``: a task whose worker dies is handed to another worker, or to the restarted
one, and traced again from scratch), rendered on a worker process that keeps its loaded scene between tasks.
The client stitches the bands bottom-up and runs the ``-filter`` step (:func:`a5mi.render.driver.assemble`), so the
image is bit for bit the one-process render with the same ``-seed``.

Cost model: a render of ``S`` samples at ``r`` samples/s per worker on ``N`` workers takes about
``t_start + t_load + S / (N r) + t_ship``: ``t_start`` the cluster (a ``LocalCluster``: its processes, ~2-4 s),
``t_load`` each worker's scene load and first-kernel compile (once per worker, in parallel), ``t_ship`` the
float32 bands (12 bytes a sample). It pays when ``S / r`` is well above ``t_start + t_load``.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from a5mi.render.options import RenderOptions
from a5mi.render.tiles import PACKET_ALIGN

_WARM: dict[tuple[str, float, RenderOptions, str | None], Any] = {}   # this process's loaded scene


@dataclass(frozen=True)
class BandJob:
    """One unit of work: render-buffer rows ``band`` of ``scene`` (absolute path) with ``options``."""

    scene: str
    options: RenderOptions
    band: tuple[int, int]
    variant: str | None = None


def split_rows(rw: int, rh: int, parts: int) -> list[tuple[int, int]]:
    """At most ``parts`` bands ``[j0, j1)`` covering rows ``0 .. rh-1`` bottom-up, about equal, every ``j0`` a
    multiple of ``m = PACKET_ALIGN / gcd(rw, PACKET_ALIGN)`` (module docstring)."""
    m = PACKET_ALIGN // math.gcd(rw, PACKET_ALIGN)
    units = math.ceil(rh / m)
    parts = max(1, min(parts, units))
    bounds = [min(rh, round(units * k / parts) * m) for k in range(parts + 1)]
    return [(a, b) for a, b in zip(bounds[:-1], bounds[1:], strict=True) if b > a]


def _warm(job: BandJob) -> tuple[Any, Any]:
    """``(description, loaded scene)`` of the job's scene for this process (built on first use)."""
    key = (job.scene, os.stat(job.scene).st_mtime, job.options, job.variant)
    if key not in _WARM:
        from a5mi.render.session import build_scene, describe_file
        from a5mi.runtime import variant as variants

        variants.activate(job.variant)
        desc, _ = describe_file(job.scene, bump=job.options.bump)
        _WARM.clear()
        _WARM[key] = (desc, build_scene(desc, job.options))
    return _WARM[key]


def render_job(job: BandJob) -> dict[str, Any]:
    """A worker's task: ``{"band": Band, "seconds": float, "pid": int}``."""
    from a5mi.render.driver import render_band

    t0 = time.perf_counter()
    desc, scene = _warm(job)
    band = render_band(scene, desc.camera, job.options, job.band)
    return {"band": band, "seconds": time.perf_counter() - t0, "pid": os.getpid()}


def splittable(options: RenderOptions) -> str | None:
    """None when a render with ``options`` can be split into bands, else why not: only the integrators whose
    samples carry all their state (``whitted``, ``path``: :func:`a5mi.render.passes.wavefront`), no quadrant AOV
    rays."""
    if options.crop is not None:
        return "-crop renders one region in one process"
    if options.integrator not in ("whitted", "path"):
        return f"-integrator {options.integrator} keeps state across the image; only whitted and path split"
    if (options.normals or options.depth is not None) and options.aov_mode == "quadrant":
        return "-aov_mode quadrant traces a second set of rays; split renders use -aov_mode main"
    return None


def render_split(scene: str | os.PathLike[str], options: RenderOptions, *, workers: int | None = None,
                 scheduler: str | None = None, security: Any = None, variant: str | None = None,
                 parts: int | None = None, client: Any = None,
                 progress: Callable[[int, int], None] | None = None) -> tuple[Any, dict[str, Any]]:
    """``(RenderResult, summary)`` of ``scene`` rendered in bands (module docstring) on ``client``, or on a
    client of ``scheduler`` (with ``security``) or of a local TLS cluster of ``workers`` processes
    (:func:`a5mi.runtime.cluster.start_client`). ``parts``: bands (default 2 per worker). ``progress(bands done,
    bands)``. The summary: ``seconds`` per band, ``pids``, ``bands``, ``wall_s``."""
    from a5mi.render.driver import assemble
    from a5mi.runtime import cluster
    from a5mi.runtime.extras import require

    why = splittable(options)
    if why is not None:
        raise ValueError(why)
    t0 = time.perf_counter()
    path = os.path.abspath(os.fspath(scene))
    rw, rh = options.render_size

    def run(c: Any) -> tuple[Any, dict[str, Any]]:
        n = parts or 2 * (len(c.nthreads()) or workers or 2)
        jobs = [BandJob(path, options, b, variant) for b in split_rows(rw, rh, n)]
        futures = c.map(render_job, jobs, retries=3, pure=False)
        records = []
        for fut in require("distributed", "grade").as_completed(futures):
            records.append(fut.result())
            if progress is not None:
                progress(len(records), len(jobs))
        result = assemble(options, [r["band"] for r in records])
        result.timings["render"] = time.perf_counter() - t0
        order = sorted(records, key=lambda r: r["band"].j0)
        return result, {"seconds": [r["seconds"] for r in order], "pids": sorted({r["pid"] for r in records}),
                        "bands": [(r["band"].j0, r["band"].j1) for r in order], "wall_s": time.perf_counter() - t0}

    if client is not None:
        return run(client)
    with cluster.start_client(workers or 2, scheduler, security=security) as c:
        return run(c)

"""Progressive photon mapping passes, here or across Dask workers (docs/EXTENSIONS.md E.17).

Pass ``k`` (0-based) of ``-integrator ppm`` is a whole image rendered by an ``a5_ppm`` integrator with
``first_pass = k`` and one sample per pixel (:func:`render_pass`): its photon maps are seeded by ``(seed, k)``
and its radius is ``r_(k+1)``, so a pass depends only on the scene, the options and ``k``, never on the
process that renders it. :func:`render_ppm` renders passes ``0 .. N−1`` in this process or, with ``workers``
(a ``LocalCluster`` of worker processes bound to 127.0.0.1, TLS, :func:`a5mi.runtime.cluster.start_client`) or
``scheduler``, in contiguous chunks on Dask (each worker process keeps its loaded scene for its chunks), then
sums the pass images in pass order in float32 and scales by ``1/N``: the same operations on the same
images, so the result is bit for bit the same image wherever the passes ran.
"""

from __future__ import annotations

import dataclasses
import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from a5mi.render.options import RenderOptions

_WARM: dict[tuple[str, float, RenderOptions], Any] = {}   # this process's loaded scene per (file, options)


@dataclass(frozen=True)
class PassChunk:
    """One unit of work: passes ``passes`` of ``scene`` (absolute path) with ``options``."""

    scene: str
    options: RenderOptions
    passes: tuple[int, ...]
    variant: str | None = None


def _warm(scene: str, options: RenderOptions, variant: str | None) -> Any:
    """``(description, loaded scene, integrator dict)`` of ``scene`` for this process (built on first use)."""
    key = (scene, os.stat(scene).st_mtime, options)
    if key not in _WARM:
        from a5mi.platform.loading import load_dict
        from a5mi.render.session import describe_file, scene_dict
        from a5mi.runtime import variant as variants

        variants.activate(variant)
        desc, _ = describe_file(scene, bump=options.bump)
        d = scene_dict(desc, options)
        _WARM.clear()
        _WARM[key] = (desc, load_dict(d), d["integrator"])
    return _WARM[key]


def render_pass(scene: str, options: RenderOptions, k: int, variant: str | None = None) -> np.ndarray:
    """Pass ``k`` of ``scene`` (module docstring) as a float32 image (rows from the top)."""
    from a5mi.platform.loading import load_dict
    from a5mi.render.driver import render_scene

    desc, mi_scene, entry = _warm(scene, options, variant)
    integrator = load_dict({**entry, "first_pass": int(k)})
    one = dataclasses.replace(options, spp=1)
    return np.asarray(render_scene(mi_scene, desc.camera, one, integrator=integrator).image, dtype=np.float32)


def render_chunk(chunk: PassChunk) -> dict[str, Any]:
    """Every pass of ``chunk``: ``{"passes": [...], "images": [...], "seconds": [...], "pid": ...}``."""
    images, seconds = [], []
    for k in chunk.passes:
        t0 = time.perf_counter()
        images.append(render_pass(chunk.scene, chunk.options, k, chunk.variant))
        seconds.append(time.perf_counter() - t0)
    return {"passes": list(chunk.passes), "images": images, "seconds": seconds, "pid": os.getpid()}


def _chunks(n: int, parts: int) -> list[tuple[int, ...]]:
    parts = max(1, min(n, parts))
    bounds = np.linspace(0, n, parts + 1).round().astype(int)
    return [tuple(range(a, b)) for a, b in zip(bounds[:-1], bounds[1:], strict=True) if b > a]


def mean_of_passes(images: dict[int, np.ndarray]) -> np.ndarray:
    """``(1/N) Σ_k image_k`` summed in pass order in float32 (module docstring)."""
    keys = sorted(images)
    total = np.zeros_like(images[keys[0]], dtype=np.float32)
    for k in keys:
        total = total + images[k]
    return total * np.float32(1.0 / len(keys))


def render_ppm(scene: str | os.PathLike[str], options: RenderOptions, passes: int, *, workers: int | None = None,
               scheduler: str | None = None, security: Any = None, variant: str | None = None,
               progress: Callable[[int, int], None] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
    """The mean of ``passes`` ppm passes (module docstring) and a summary (``seconds`` per pass, ``pids``,
    ``wall_s``). ``options.integrator`` must be ``ppm``. ``scheduler`` is joined with the client credentials
    ``security`` (:func:`a5mi.runtime.cluster.check_scheduler`)."""
    if options.integrator != "ppm":
        raise ValueError(f"render_ppm needs the ppm integrator, got {options.integrator!r}")
    t0 = time.perf_counter()
    path = str(Path(scene).resolve())
    images: dict[int, np.ndarray] = {}
    seconds: dict[int, float] = {}
    pids: set[int] = set()

    def take(rec: dict[str, Any]) -> None:
        for k, img, s in zip(rec["passes"], rec["images"], rec["seconds"], strict=True):
            images[k], seconds[k] = img, s
        pids.add(rec["pid"])
        if progress is not None:
            progress(len(images), passes)

    if workers is None and scheduler is None:
        for k in range(passes):
            take(render_chunk(PassChunk(path, options, (k,), variant)))
    else:
        from a5mi.runtime import cluster

        n_workers = workers or 2
        chunks = [PassChunk(path, options, c, variant) for c in _chunks(passes, 2 * n_workers)]
        with cluster.start_client(n_workers, scheduler, security=security) as client:
            futures = client.map(render_chunk, chunks, retries=2, pure=False)
            for fut in futures:
                take(fut.result())
    image = mean_of_passes(images)
    return image, {"seconds": [seconds[k] for k in sorted(seconds)], "pids": sorted(pids),
                   "wall_s": time.perf_counter() - t0}

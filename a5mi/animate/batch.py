"""Render an animation's frames here or across Dask workers (docs/EXTENSIONS.md E.11).

:func:`render_animation` finds the frames of ``A:B`` that are not done (:mod:`.frames`; all of them unless
``resume``), then renders them

* in this process, one :class:`~.warm.WarmScene`, frame after frame; or
* on a Dask cluster (:func:`a5mi.cluster.start_client`: ``workers`` local worker processes bound to 127.0.0.1,
  or the cluster of ``scheduler``), as contiguous chunks of frames (:func:`.frames.chunks`, about four per
  worker) through :func:`a5mi.cluster.run_units`. Each worker process keeps one warm scene per (scene file,
  options) for all the chunks it gets, so only its first chunk loads the scene and compiles the kernel.

A frame depends only on its number (the scene is updated from ``t`` alone), so it is the same bit for bit
whichever worker renders it, and a chunk that a dying worker leaves unfinished is simply rendered again
(the scheduler retries it; frames already written stay, the rest come next time with ``--resume``).
"""

from __future__ import annotations

import os
import resource
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from a5mi.animate import frames as framefiles
from a5mi.options import RenderOptions

#: (frames done, frames to do) after each frame (here) or each chunk (Dask).
Progress = Callable[[int, int], None]

_WARM: dict[tuple[str, float, RenderOptions], Any] = {}  # this process's warm scenes


@dataclass(frozen=True)
class Chunk:
    """One unit of work: render ``frames`` of ``scene`` (absolute path) into ``folder``."""

    scene: str
    folder: str
    options: RenderOptions
    frames: tuple[int, ...]
    variant: str | None = None


@dataclass
class Outcome:
    """What a run did: ``rendered`` frame numbers, ``skipped`` (already done), per-chunk records (``pid``,
    ``update_s``, ``render_s``, ``kernel_s``, ``kernels``, ``peak_mb``, ``build_s``), the wall time."""

    rendered: list[int] = field(default_factory=list)
    skipped: int = 0
    records: list[dict[str, Any]] = field(default_factory=list)
    wall_s: float = 0.0
    errors: list[str] = field(default_factory=list)


def warm_scene(scene: str, options: RenderOptions, variant: str | None = None) -> tuple[Any, float]:
    """This process's :class:`~.warm.WarmScene` of ``scene`` with ``options`` (built on first use) and the
    seconds spent building it now (0 when it was warm)."""
    from a5mi import variant as variants
    from a5mi.animate.warm import WarmScene
    from a5mi.converters.a5_parser import parse_file

    key = (scene, os.stat(scene).st_mtime, options)
    if key in _WARM:
        return _WARM[key], 0.0
    t0 = time.perf_counter()
    variants.activate(variant)
    if options.threads is not None:
        import drjit as dr

        dr.set_thread_count(options.threads)
    _WARM.clear()
    _WARM[key] = WarmScene(parse_file(scene), options)
    return _WARM[key], time.perf_counter() - t0


def render_chunk(chunk: Chunk, on_frame: Callable[[int], None] | None = None) -> dict[str, Any]:
    """Render and write every frame of ``chunk`` with this process's warm scene; returns the chunk's record."""
    from a5mi.animate.warm import FrameTiming

    warm, build_s = warm_scene(chunk.scene, chunk.options, chunk.variant)
    timing = FrameTiming()
    kernel_s = 0.0
    for f in chunk.frames:
        result = warm.render(f, timing)
        kernel_s += result.timings.get("execute", 0.0)
        framefiles.write_frame(chunk.folder, f, result.image)
        if on_frame is not None:
            on_frame(f)
    return {"frames": list(chunk.frames), "pid": os.getpid(), "build_s": build_s, "update_s": timing.update,
            "render_s": timing.render, "kernel_s": kernel_s, "kernels": timing.kernels,
            "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0}


def _dask_chunk(chunk: Chunk) -> dict[str, Any]:
    """:func:`render_chunk` on a worker (a module-level function, so Dask can pickle it by name)."""
    return render_chunk(chunk)


def render_animation(scene: str | os.PathLike[str], folder: str | os.PathLike[str], options: RenderOptions,
                     frame_range: range, *, workers: int | None = None, scheduler: str | None = None,
                     security: Any = None, resume: bool = False, variant: str | None = None,
                     progress: Progress | None = None) -> Outcome:
    """Render the frames of ``frame_range`` of the animated ``scene`` into ``folder`` (module docstring):
    here when neither ``workers`` nor ``scheduler`` is given, else on Dask (``scheduler``'s client credentials:
    ``security``, else the Dask configuration's). With ``resume`` only the frames
    that are not done are rendered."""
    t0 = time.perf_counter()
    scene_path = str(Path(scene).resolve())
    Path(folder).mkdir(parents=True, exist_ok=True)
    todo = framefiles.missing_frames(folder, frame_range) if resume else list(frame_range)
    out = Outcome(skipped=len(frame_range) - len(todo))
    total, done = len(frame_range), len(frame_range) - len(todo)
    if progress is not None:
        progress(done, total)
    if not todo:
        out.wall_s = time.perf_counter() - t0
        return out
    if workers is None and scheduler is None:
        def frame_done(f: int) -> None:
            nonlocal done
            done += 1
            out.rendered.append(f)
            if progress is not None:
                progress(done, total)

        out.records.append(render_chunk(Chunk(scene_path, str(Path(folder).resolve()), options, tuple(todo),
                                              variant), frame_done))
        out.wall_s = time.perf_counter() - t0
        return out

    from a5mi import cluster

    n_workers = workers or 2
    parts = framefiles.chunks(todo, 4 * n_workers)
    units = [(f"frames-{c[0]}-{c[-1]}", Chunk(scene_path, str(Path(folder).resolve()), options, c, variant))
             for c in parts]

    def record(rec: dict[str, Any]) -> None:
        nonlocal done
        if "error" in rec:
            out.errors.append(f"{rec['key']}: {rec['error']}")
            return
        done += len(rec["frames"])
        out.rendered.extend(rec["frames"])
        if progress is not None:
            progress(done, total)

    journal = cluster.Journal(Path(folder) / "animate.journal.jsonl")
    with cluster.start_client(n_workers, scheduler, security=security) as client:
        out.records = [r for r in cluster.run_units(client, units, _dask_chunk, journal, on_record=record)
                       if "error" not in r]
    out.rendered.sort()
    out.wall_s = time.perf_counter() - t0
    return out

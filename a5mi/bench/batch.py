"""Batch renders in one process (docs/SPEED.md): the cost of each extra render against its kernel + filter + write.

* **in-process** (:func:`measure_batch`): per scene, one :class:`a5mi.render.session.RenderSession` render that is
  written (warm-up: builds the scene, loads the kernel from the disk cache), then ``renders`` more renders of
  the same scene and options, each written to a PNG (:func:`a5mi.platform.imageio.write_images`). For each extra
  render: ``wall`` = ``session.render`` + the write, ``kernel`` = compile + execute of its kernels from
  ``dr.kernel_history()`` (:attr:`a5mi.render.driver.RenderResult.timings`), ``filter`` (streamed blur +
  downsample), ``write``; ``ratio`` = median wall / median (kernel + filter + write), the target being
  <= :data:`TARGET_BATCH_RATIO`. ``recompiled`` counts extra renders that compiled a kernel (should be 0).
  What the ratio's excess holds: the Python trace of the integrator (Dr.Jit builds the kernel's IR before it
  can look the kernel up), the jitter draw, the camera rays and the buffer copies.
* **process** (:func:`measure_batch_process`): one ``a5mi render S1 S2 ... --output-dir DIR FLAGS`` child
  process against the sum of the scenes' best warm ``a5`` processes of the same run.
"""

from __future__ import annotations

import statistics
import sys
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from a5mi.bench.floor import _chdir
from a5mi.bench.process import ProcessRun, run_process

#: Target (docs/SPEED.md): an extra render in a batch costs at most this times its kernel + filter + write.
TARGET_BATCH_RATIO = 1.3


@dataclass
class BatchScene:
    """The extra renders of one scene in a session (module docstring): per render ``wall``, ``kernel``,
    ``filter``, ``write`` (s) and whether it compiled a kernel."""

    name: str
    first: float = 0.0  # the written warm-up render (build + disk-cached kernel), s
    extra: list[dict[str, float]] = field(default_factory=list)

    def median(self, key: str) -> float | None:
        values = [e[key] for e in self.extra]
        return statistics.median(values) if values else None

    @property
    def base(self) -> float | None:
        """Median of kernel + filter + write over the extra renders."""
        values = [e["kernel"] + e["filter"] + e["write"] for e in self.extra]
        return statistics.median(values) if values else None

    @property
    def ratio(self) -> float | None:
        wall, base = self.median("wall"), self.base
        return wall / base if wall is not None and base else None

    @property
    def recompiled(self) -> int:
        return sum(1 for e in self.extra if e["compiled"] > 0)


def _timed_render(session: Any, desc: Any, options: Any, out: Path) -> dict[str, float]:
    from a5mi.platform.imageio import write_images

    t0 = time.perf_counter()
    result = session.render(desc, options)
    t1 = time.perf_counter()
    write_images([(out, result.image)])
    t2 = time.perf_counter()
    t = result.timings
    return {"wall": t2 - t0, "kernel": t["compile"] + t["execute"], "filter": t["filter"], "write": t2 - t1,
            "trace_etc": (t1 - t0) - t["compile"] - t["execute"] - t["filter"],
            "compiled": float(result.kernels.get("compiled", 0))}


def measure_batch(paths: Sequence[Path], options: Any, renders: int, log: Any) -> list[BatchScene]:
    """In-process batch figures of each scene (module docstring); needs the variant active."""
    from a5mi.render.session import RenderSession, describe_file

    session = RenderSession()
    out: list[BatchScene] = []
    with tempfile.TemporaryDirectory(prefix="a5bench-batch-") as tmp:
        for path in paths:
            from a5mi.bench.scenes import scene_name

            res = BatchScene(scene_name(path))
            log(f"{res.name}: batch, {renders} extra renders ...")
            with _chdir(path.parent):
                desc, _ = describe_file(path.name)
                target = Path(tmp) / "out.png"
                res.first = _timed_render(session, desc, options, target)["wall"]
                res.extra = [_timed_render(session, desc, options, target) for _ in range(renders)]
            session.forget(desc)
            out.append(res)
    return out


def a5mi_command() -> list[str]:
    """The installed ``a5mi`` console script beside this interpreter, else its entry point run by this Python."""
    script = Path(sys.executable).with_name("a5mi")
    if script.is_file():
        return [str(script)]
    return [sys.executable, "-c", "from a5mi.entry import a5mi; a5mi()"]


def measure_batch_process(paths: Sequence[Path], flags: Sequence[str], env: dict[str, str] | None,
                          timeout: float) -> tuple[ProcessRun, str]:
    """One ``a5mi render`` child process over every scene of ``paths`` (absolute paths, run from the first
    scene's folder); returns the run and the command as printed in BENCHMARKS.md."""
    with tempfile.TemporaryDirectory(prefix="a5bench-batchp-") as tmp:
        cwd = paths[0].parent
        names = [p.name if p.parent == cwd else str(p) for p in paths]
        cmd = a5mi_command() + ["render", *names, "--output-dir", tmp, *flags]
        run = run_process(cmd, cwd=cwd, env=env, timeout=timeout)
    shown = " ".join(["a5mi render", *names, "--output-dir", "DIR", *flags])
    return run, shown


__all__ = ["TARGET_BATCH_RATIO", "BatchScene", "a5mi_command", "measure_batch", "measure_batch_process"]

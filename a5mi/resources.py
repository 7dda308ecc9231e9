"""Memory a render and its images need, against what the machine has (issue 19, item 9).

Measured on this project's renderer (``a5 -v`` peak resident memory, llvm variant, ``scene03``; figures in
BENCHMARKS.md): about 170 MB before the first ray (interpreter, Dr.Jit, Mitsuba), then per sample of the
render buffer (RW x RH, 3W x 3H with ``-jitter``)

* ~60 bytes while the colour buffer is kept whole (float32 RGB plus the quantisation and flip copies),
  ~30 more with ``-normals`` / ``-depth`` (their buffers and images), ~16 more with ``-jitter`` (offsets);
* a tile in flight: ~100 bytes per ray of :data:`a5mi.options.TILE_RAYS` (Dr.Jit's kernel buffers);
* with ``-jitter -filter`` the colour buffer is streamed: only the W x H result is kept.

:func:`render_bytes` is that model, rounded up; a decoded texture or cube-map face costs ~8 bytes per pixel
(:data:`IMAGE_BYTES_PER_PIXEL`: the decoded bytes, the RGB copy, the packed texel words). :func:`available`
is ``MemAvailable`` of ``/proc/meminfo``, lowered to the cgroup's ``memory.max`` headroom when one is set.
A leaf module: standard library only.
"""

from __future__ import annotations

import os
from pathlib import Path

BASE_BYTES = 200 << 20
SAMPLE_BYTES = 60
AOV_SAMPLE_BYTES = 30
JITTER_SAMPLE_BYTES = 16
TILE_RAY_BYTES = 100
IMAGE_BYTES_PER_PIXEL = 8


def render_bytes(rw: int, rh: int, *, width: int, height: int, aovs: bool, jitter: bool, filtered: bool,
                 tile_rays: int) -> int:
    """Estimated peak bytes of a render (module docstring): ``BASE + min(N, tile)·100 + N·(60 [kept colour]
    + 30 [AOVs] + 16 [jitter])`` with N = RW·RH render-buffer samples; with ``-jitter -filter`` the colour
    is streamed and ``W·H·60`` is kept instead."""
    n = rw * rh
    streamed = filtered and jitter
    per = (0 if streamed else SAMPLE_BYTES) + (AOV_SAMPLE_BYTES if aovs else 0) + (JITTER_SAMPLE_BYTES if jitter else 0)
    out = width * height * SAMPLE_BYTES if streamed else 0
    return BASE_BYTES + min(n, tile_rays) * TILE_RAY_BYTES + n * per + out


def image_bytes(width: int, height: int, channels: int) -> int:
    """Estimated bytes of one decoded scene image: ``W·H·(C + 8)``."""
    return width * height * (channels + IMAGE_BYTES_PER_PIXEL)


def _read_int(path: str) -> int | None:
    try:
        text = Path(path).read_text().split()[0]
    except (OSError, IndexError):
        return None
    return int(text) if text.isdigit() else None


def available() -> int | None:
    """Bytes the process may still allocate: ``MemAvailable``, capped by a cgroup v2 limit
    (``memory.max - memory.current``) when there is one; ``$A5MI_MEMORY_LIMIT`` (bytes) overrides both. None
    when unknown (not Linux)."""
    env = os.environ.get("A5MI_MEMORY_LIMIT", "")
    if env.isdigit():
        return int(env)
    free: int | None = None
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                free = int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        free = None
    limit, used = _read_int("/sys/fs/cgroup/memory.max"), _read_int("/sys/fs/cgroup/memory.current")
    if limit is not None and used is not None:
        free = limit - used if free is None else min(free, limit - used)
    return free


def fits(need: int) -> tuple[bool, int | None]:
    """(``need`` bytes fit in :func:`available`, the available bytes); unknown availability fits."""
    have = available()
    return (have is None or need <= have), have


def gb(n: int) -> str:
    """``1.9 GB``."""
    return f"{n / 1e9:.1f} GB"


__all__ = ["available", "fits", "gb", "image_bytes", "render_bytes"]

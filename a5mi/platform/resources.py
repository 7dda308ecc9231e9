"""Memory a render and its images need, against what the process may still allocate.

Measured on this project's renderer (``a5 -v`` peak resident memory, llvm variant, ``scene03``; figures in
BENCHMARKS.md): about 170 MB before the first ray (interpreter, Dr.Jit, Mitsuba), then per sample of the
render buffer (RW x RH, 3W x 3H with ``-jitter``)

* ~60 bytes while the colour buffer is kept whole (float32 RGB plus the quantisation and flip copies),
  ~30 more with ``-normals`` / ``-depth`` (their buffers and images), ~16 more with ``-jitter`` (offsets);
* a tile in flight: ~100 bytes per ray of :data:`a5mi.render.options.TILE_RAYS` (Dr.Jit's kernel buffers);
* with ``-jitter -filter`` the colour buffer is streamed: only the W x H result is kept.

:func:`render_bytes` is that model, rounded up; :func:`integrator_bytes` adds what an integrator keeps beyond
the tile (photon maps and their kd-trees, ppm statistics, irradiance records) and :func:`split_bytes` a render
split into bands over local worker processes; a decoded texture or cube-map face costs ~8 bytes per pixel
(:data:`IMAGE_BYTES_PER_PIXEL`: the decoded bytes, the RGB copy, the packed texel words). :func:`available`
is the smallest of three limits the process actually has: ``MemAvailable`` of ``/proc/meminfo``, the cgroup's
headroom (v2 ``memory.max - memory.current``, v1 ``memory.limit_in_bytes - memory.usage_in_bytes``) and the
address-space headroom under ``RLIMIT_AS`` (``ulimit -v``): ``soft limit - VmSize - reserve``, the reserve
(:func:`address_space_reserve`) being the address space the libraries map beyond what they touch (measured:
a 50x50 render peaks at 0.78 GB of address space for 0.20 GB resident on 2 CPUs; thread stacks and malloc
arenas grow with the CPUs). A leaf module: standard library only.
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


#: docs/EXTENSIONS.md E.16, E.17: bytes per emitted photon of ``-integrator photon`` / ``ppm`` (one map's
#: wavefront while it is traced, the stored hits as float64 ``pos``/``dir``/``power``, their kind and shape, the
#: concatenated copies and the kd-trees). Measured (BENCHMARKS.md): 16x16 of a closed white box with a glass
#: sphere (every photon bounces until ``photon_depth``: the worst case), 2 x 250k photons 0.59 GB, 2 x 1M photons
#: 1.77 GB peak resident: 782 bytes per photon, 0.86 GB for 2 x 400k against 0.83 GB by that slope; 1000
#: leaves room for that spread. That was at ``photon_depth`` 10, ten hits per photon. Later, 2 x 400k at
#: ``photon_depth`` 10 peaked at 0.79-0.83 GB alone (cold and warm caches) but at 1.05, 1.20 and 1.54 GB inside
#: the test suite's worker processes on the loaded machine (BENCHMARKS.md "Test suite"): the same command's peak
#: spreads about 2x; 2000 bytes per photon, 200 per hit, covers the highest seen.
PHOTON_BYTES = 2000
PHOTON_DEPTH_MEASURED = 10
PHOTON_HIT_BYTES = PHOTON_BYTES // PHOTON_DEPTH_MEASURED
#: Hits per photon bounded for Russian roulette alone (``photon_depth`` 0, docs/EXTENSIONS.md E.16): survival is
#: the surface's albedo (at most 1) for the first 32 hits, then at most 0.95, so a photon makes at most
#: ``32 + 0.95/0.05 = 51`` hits on average (a lossless scene); a dimmer scene makes fewer (1/(1 - albedo)).
ROULETTE_MEAN_HITS = 32 + 19
#: docs/EXTENSIONS.md E.17: ``-integrator ppm``'s per-sample statistics (float64 rgb sums and counts).
PPM_SAMPLE_BYTES = 48
#: docs/EXTENSIONS.md E.23: one irradiance record (29 float64: p, n, E, R, two 3x3 gradients, spacing; 232
#: bytes) with its concatenation copy and grid index; at most one per render-buffer sample (a node covers itself).
IC_RECORD_BYTES = 600
#: docs/EXTENSIONS.md E.23: the hemisphere rays of one gather chunk (``GATHER_RAYS`` = 2^20 of them).
IC_GATHER_RAYS = 1 << 20
#: docs/EXTENSIONS.md E.24: a split render's band as shipped to the client (float32 rgb per sample).
BAND_SAMPLE_BYTES = 12


def integrator_bytes(integrator: str, samples: int, *, photons: int = 0, caustic_photons: int = 0,
                     photon_depth: int = 0) -> int:
    """Estimated bytes an integrator holds beyond :func:`render_bytes` for a render of ``samples``
    render-buffer samples: ``photon``: ``(photons + caustic) · 200 · H`` (:data:`PHOTON_HIT_BYTES` per hit, the
    two maps and their kd-trees; ``H`` = ``photon_depth`` hits, or :data:`ROULETTE_MEAN_HITS` for Russian
    roulette alone, the lossless worst case); ``ppm``: the same per pass (one pass's maps at a time) ``+ samples · 48``;
    ``irradiancecache``: ``samples · 600`` (records) ``+ 2^20 · 100`` (one gather chunk in flight);
    ``whitted`` / ``path``: 0 (their buffers are the tile's, in :func:`render_bytes`)."""
    hits = photon_depth if photon_depth > 0 else ROULETTE_MEAN_HITS
    maps = (max(photons, 0) + max(caustic_photons, 0)) * PHOTON_HIT_BYTES * hits
    if integrator == "photon":
        return maps
    if integrator == "ppm":
        return maps + samples * PPM_SAMPLE_BYTES
    if integrator == "irradiancecache":
        return samples * IC_RECORD_BYTES + IC_GATHER_RAYS * TILE_RAY_BYTES
    return 0


def split_bytes(render: int, extra: int, samples: int, workers: int) -> int:
    """Estimated bytes of a render split into bands (docs/EXTENSIONS.md E.24) over ``workers`` local worker
    processes: the client keeps the one-process buffers ``render`` (:func:`render_bytes`) and the shipped bands
    (``samples · 12``); each worker is a whole renderer with its share of the samples and the integrator's own
    buffers ``extra`` (:func:`integrator_bytes`: every worker builds the same photon maps):
    ``render + 12 samples + workers · (BASE + extra + (render − BASE) / workers)``. ``workers`` = 0: a remote
    scheduler's workers are not on this machine, only the client counts."""
    share = (render - BASE_BYTES) // workers if workers > 0 else 0
    return render + samples * BAND_SAMPLE_BYTES + workers * (BASE_BYTES + extra + share)


def image_bytes(width: int, height: int, channels: int) -> int:
    """Estimated bytes of one decoded scene image: ``W·H·(C + 8)``."""
    return width * height * (channels + IMAGE_BYTES_PER_PIXEL)


def _read_int(path: str) -> int | None:
    try:
        text = Path(path).read_text().split()[0]
    except (OSError, IndexError):
        return None
    return int(text) if text.isdigit() else None


#: Address space mapped but not resident, independent of the CPUs (the interpreter, Dr.Jit, LLVM, Mitsuba).
RESERVE_BASE_BYTES = 512 << 20
#: ... and per CPU (a thread's 8 MiB stack and its 64 MiB malloc arena).
RESERVE_CPU_BYTES = 72 << 20


def address_space_reserve() -> int:
    """Address space a render maps beyond its resident memory: ``512 MiB + 72 MiB · CPUs`` (module docstring;
    0.66 GB on 2 CPUs against the 0.58 GB measured)."""
    return RESERVE_BASE_BYTES + RESERVE_CPU_BYTES * (os.cpu_count() or 1)


def _address_space_headroom() -> int | None:
    """``RLIMIT_AS`` soft limit - ``VmSize`` - :func:`address_space_reserve`; None without a limit."""
    try:
        import resource

        soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    except (ImportError, OSError, ValueError):
        return None
    if soft == resource.RLIM_INFINITY or soft < 0:
        return None
    size = 0
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmSize:"):
                size = int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        size = 0
    return max(0, soft - size - address_space_reserve())


def available() -> int | None:
    """Bytes the process may still allocate: the smallest of ``MemAvailable``, the cgroup headroom (v2 or v1)
    and the ``RLIMIT_AS`` headroom (module docstring); ``$A5MI_MEMORY_LIMIT`` (bytes) overrides them all.
    None when unknown (not Linux, no limit)."""
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
    for limit_file, used_file in (("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory.current"),
                                  ("/sys/fs/cgroup/memory/memory.limit_in_bytes",
                                   "/sys/fs/cgroup/memory/memory.usage_in_bytes")):
        limit, used = _read_int(limit_file), _read_int(used_file)
        if limit is not None and used is not None:
            free = limit - used if free is None else min(free, limit - used)
    room = _address_space_headroom()
    if room is not None:
        free = room if free is None else min(free, room)
    return free


def fits(need: int) -> tuple[bool, int | None]:
    """(``need`` bytes fit in :func:`available`, the available bytes); unknown availability fits."""
    have = available()
    return (have is None or need <= have), have


def gb(n: int) -> str:
    """``1.9 GB``."""
    return f"{n / 1e9:.1f} GB"


__all__ = ["address_space_reserve", "available", "fits", "gb", "image_bytes", "integrator_bytes", "render_bytes",
           "split_bytes"]

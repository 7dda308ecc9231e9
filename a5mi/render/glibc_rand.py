"""glibc ``rand()`` from the default seed, vectorised with numpy (SPEC B.5).

The sample solution draws its jitter offsets from an unseeded glibc ``rand()``, i.e. the TYPE_3 additive
feedback generator seeded with 1. glibc's algorithm (``srandom_r`` / ``random_r``):

* ``r[0] = seed``; ``r[i] = 16807 * r[i-1] mod (2^31 - 1)`` for ``i = 1..30`` (Schrage's method, which for
  seed 1 equals the plain product modulo 2^31 - 1);
* ``r[i] = r[i-31]`` for ``i = 31..33``;
* ``r[i] = r[i-3] + r[i-31] mod 2^32`` for ``i >= 34``;
* the k-th output of ``rand()`` is ``r[k + 344] >> 1`` (glibc discards the first 310 values after the 34
  initial ones).

The recurrence is linear over Z/2^32, so a block of ``N`` consecutive values is ``M @ s`` where ``s`` holds
the 31 values before the block and ``M`` (N x 31) is the recurrence applied to unit vectors. We evaluate
``M @ S`` for many blocks at once with float64 BLAS on 16-bit limbs (every partial sum stays below 2^37,
so it is exact): ``r = lo*lo + 2^16 (hi*lo + lo*hi) mod 2^32``. Only the 31-value state is carried from
block to block, sequentially (one 31 x 31 integer product per block). This makes the 2 x 9WH values of a
1920x1080 ``-jitter`` render a fraction of a second instead of a Python loop's minutes.

The stream never changes, so :func:`glibc_stream` also keeps its first :data:`PREFIX_VALUES` values (8 MB:
a 300x300 ``-jitter`` render needs 1.62 M) and the generator state after them on disk, in ``$A5MI_CACHE_DIR``
or ``~/.cache/a5mi``: a warm render then memory-maps them instead of computing them (~6 ms instead of ~35
ms). The state file also holds CRC-32s of both arrays, checked on every load, and the first values are
compared with freshly computed ones; a cache that is missing, unreadable or fails a check is rebuilt, and
when it cannot be written the stream is simply computed. Small draws (fewer than :data:`SMALL_DRAW` values)
never touch the cache.
"""

from __future__ import annotations

import os
import stat
import zlib
from pathlib import Path

import numpy as np
import numpy.typing as npt

from a5mi import cache_dir  # noqa: F401 - re-exported: glibc_rand.cache_dir is where the prefix lives

_MASK32 = np.uint64(0xFFFFFFFF)
_LAG = 31  # r[i] = r[i-3] + r[i-31]
_SHORT = 3
_DISCARD = 310
_BLOCK = 4096  # values per matrix block (rows of M)

#: 2^-31 as the binary uses it: jitter = (float)r * 2^-31 - 0.5 (SPEC B.5).
INV_2_31 = np.float32(2.0**-31)


def _initial_state(seed: int = 1) -> np.ndarray:
    """The 34 values ``r[0..33]`` glibc ``srandom_r(seed)`` writes for TYPE_3 (see the module docstring)."""
    seed = seed & 0xFFFFFFFF
    if seed == 0:
        seed = 1  # glibc: "We must make sure the seed is not 0."
    r = [0] * 34
    r[0] = seed
    for i in range(1, 31):
        # Schrage: hi = r/127773, lo = r%127773, word = 16807*lo - 2836*hi (+ 2^31-1 if negative), on int32.
        prev = r[i - 1] - (1 << 32) if r[i - 1] >= (1 << 31) else r[i - 1]
        hi, lo = int(prev / 127773), prev - int(prev / 127773) * 127773  # C division truncates toward 0
        word = 16807 * lo - 2836 * hi
        if word < 0:
            word += 2147483647
        r[i] = word & 0xFFFFFFFF
    for i in range(31, 34):
        r[i] = r[i - 31]
    return np.array(r, dtype=np.uint64)


def _discarded_state(seed: int) -> list[int]:
    """The 31 raw values after glibc's 310 discarded ones: the state before the first ``rand()`` output."""
    r = [int(v) for v in _initial_state(seed)]
    for i in range(34, 34 + _DISCARD):
        r.append((r[i - _SHORT] + r[i - _LAG]) & 0xFFFFFFFF)
    return r[-_LAG:]


def first_values(k: int, seed: int = 1) -> npt.NDArray[np.uint32]:
    """The first ``k`` outputs by the plain recurrence (pure Python; for checks and small ``k``)."""
    r = _discarded_state(seed)
    out = []
    for _ in range(k):
        r.append((r[-_SHORT] + r[-_LAG]) & 0xFFFFFFFF)
        out.append(r[-1] >> 1)
    return np.array(out, dtype=np.uint32)


def _block_matrix(n: int) -> np.ndarray:
    """``M`` (n x 31, uint64 < 2^32): row k gives ``r[B+k]`` from the state ``r[B-31..B-1]``."""
    c = np.zeros((n + _LAG, _LAG), dtype=np.uint64)
    c[:_LAG] = np.eye(_LAG, dtype=np.uint64)
    for k in range(n):
        c[_LAG + k] = (c[_LAG + k - _SHORT] + c[k]) & _MASK32
    return c[_LAG:]


class GlibcRand:
    """The stream of glibc ``rand()`` outputs for one seed (default 1, as an unseeded program sees it).

    ``next(n)`` returns the next ``n`` outputs (uint32 in [0, 2^31)), exactly as ``n`` calls of ``rand()``;
    consecutive calls continue the stream, so a renderer can draw it tile by tile with bounded memory.
    """

    def __init__(self, seed: int = 1, block: int = _BLOCK, *, state: npt.ArrayLike | None = None) -> None:
        self._block = block
        m = _block_matrix(block)
        m_lo = (m & np.uint64(0xFFFF)).astype(np.float64).T  # 31 x N
        m_hi = (m >> np.uint64(16)).astype(np.float64).T
        self._m_lo_t = np.ascontiguousarray(m_lo)
        self._m_mid_t = np.ascontiguousarray(np.vstack([m_hi, m_lo]))  # [s_lo s_hi] @ this = hi*lo + lo*hi
        self._m_tail = m[-_LAG:]  # state after one block = m_tail @ state
        if state is not None:
            # Continue a stream from a saved state (:meth:`state`), e.g. after the cached prefix.
            self._state = np.asarray(state, dtype=np.uint64).copy()
            if self._state.shape != (_LAG,):
                raise ValueError(f"state must hold {_LAG} values, got shape {self._state.shape}")
        else:
            self._state = np.array(_discarded_state(seed), dtype=np.uint64)
        self._pending = np.empty(0, dtype=np.uint32)  # generated but not yet returned

    def state(self) -> npt.NDArray[np.uint64]:
        """The 31 raw values that determine the rest of the stream (only at a block boundary)."""
        if len(self._pending):
            raise ValueError("the state is defined only between whole blocks (values are pending)")
        return self._state.copy()

    def _blocks(self, count: int) -> np.ndarray:
        """Generate ``count`` whole blocks (raw r values, uint64) and advance the state."""
        states = np.empty((_LAG, count), dtype=np.uint64)
        s = self._state
        for b in range(count):
            states[:, b] = s
            s = (self._m_tail @ s) & _MASK32
        self._state = s
        st = states.T  # count x 31: one block per row, so the result rows come out in stream order
        s_lo = (st & np.uint64(0xFFFF)).astype(np.float64)
        s_hi = (st >> np.uint64(16)).astype(np.float64)
        low = (s_lo @ self._m_lo_t).astype(np.uint64)  # < 31 * 2^32: exact in float64
        mid = (np.hstack([s_lo, s_hi]) @ self._m_mid_t).astype(np.uint64)
        mid &= np.uint64(0xFFFF)
        mid <<= np.uint64(16)
        low += mid
        low &= _MASK32
        return low.reshape(-1)


    def next(self, n: int) -> npt.NDArray[np.uint32]:
        """The next ``n`` values of ``rand()`` (``r >> 1``), as uint32."""
        if n < 0:
            raise ValueError(f"n must be >= 0, got {n}")
        parts = [self._pending]
        have = len(self._pending)
        chunk = max(1, (1 << 22) // self._block)  # bound the float64 temporaries (~32 MB each)
        while have < n:
            need_blocks = min(chunk, -(-(n - have) // self._block))
            raw = self._blocks(need_blocks)
            parts.append((raw >> np.uint64(1)).astype(np.uint32))
            have += len(raw)
        stream = np.concatenate(parts) if len(parts) > 1 else parts[0]
        self._pending = stream[n:]
        return stream[:n]


#: Values of the seed-1 stream kept on disk (8 MB): a 341x341 -jitter render's worth. A multiple of the block.
PREFIX_VALUES = 1 << 21
#: Draws below this many values are computed directly (cheaper than reading the cache).
SMALL_DRAW = 1 << 16
_CHECK_VALUES = 1024  # how many cached values are also compared with freshly computed ones on load


class CachedStream:
    """The seed-1 ``rand()`` stream whose first values come from a memory-mapped prefix, then computed on.

    ``next(n)`` behaves exactly like :meth:`GlibcRand.next` on a fresh seed-1 generator.
    """

    def __init__(self, prefix: npt.NDArray[np.uint32], tail_state: npt.NDArray[np.uint64]) -> None:
        self._prefix = prefix
        self._tail_state = tail_state
        self._tail: GlibcRand | None = None
        self._pos = 0

    def next(self, n: int) -> npt.NDArray[np.uint32]:
        if n < 0:
            raise ValueError(f"n must be >= 0, got {n}")
        take = max(0, min(n, len(self._prefix) - self._pos))
        head = np.array(self._prefix[self._pos : self._pos + take], dtype=np.uint32)
        self._pos += take
        if take == n:
            return head
        if self._tail is None:
            self._tail = GlibcRand(state=self._tail_state)
        return np.concatenate([head, self._tail.next(n - take)])


def _prefix_paths(folder: Path, seed: int) -> tuple[Path, Path]:
    stem = f"glibc-rand-seed{seed}-{PREFIX_VALUES}"
    return folder / f"{stem}.npy", folder / f"{stem}.state.npy"


def _crc(a: np.ndarray) -> int:
    return zlib.crc32(np.ascontiguousarray(a).tobytes())


def _load_prefix(folder: Path, seed: int) -> CachedStream | None:
    """The cached prefix, or None when it is missing or fails any check (never raises)."""
    values_path, state_path = _prefix_paths(folder, seed)
    try:
        # regular files only: np.load of a FIFO blocks forever, of a device reads without end (issue 19)
        if not all(stat.S_ISREG(os.stat(p).st_mode) for p in (values_path, state_path)):
            return None
        values = np.load(values_path, mmap_mode="r")
        meta = np.load(state_path)
        if values.dtype != np.uint32 or values.shape != (PREFIX_VALUES,) or meta.shape != (_LAG + 2,):
            return None
        state = meta[:_LAG].astype(np.uint64)
        if int(meta[_LAG]) != _crc(values) or int(meta[_LAG + 1]) != _crc(state):
            return None
        if not np.array_equal(np.asarray(values[:_CHECK_VALUES]), first_values(_CHECK_VALUES, seed)):
            return None
    except Exception:  # noqa: BLE001 - a cache must never be fatal (empty, truncated, garbage files)
        return None
    return CachedStream(values, state)


def _atomic_save(path: Path, array: np.ndarray) -> None:
    from a5mi.platform.imageio import atomic_file

    with atomic_file(path, "wb") as f:
        np.save(f, array)


def glibc_stream(seed: int = 1, folder: Path | None = None, need: int | None = None) -> CachedStream | GlibcRand:
    """The ``rand()`` stream of ``seed``, its first :data:`PREFIX_VALUES` values from the disk cache.

    ``need``: how many values the caller will draw, if known; below :data:`SMALL_DRAW` the stream is just
    computed. The first large draw on a machine computes the prefix (~0.1 s) and stores it (values, then the
    state and checksums, each written atomically); any file problem just means the stream is computed.
    """
    if need is not None and need < SMALL_DRAW:
        return GlibcRand(seed)
    folder = cache_dir() if folder is None else folder
    cached = _load_prefix(folder, seed)
    if cached is not None:
        return cached
    rng = GlibcRand(seed)
    prefix = rng.next(PREFIX_VALUES)
    state = rng.state()
    try:
        folder.mkdir(parents=True, exist_ok=True)
        values_path, state_path = _prefix_paths(folder, seed)
        _atomic_save(values_path, prefix)
        meta = np.concatenate([state, np.array([_crc(prefix), _crc(state)], dtype=np.uint64)])
        _atomic_save(state_path, meta)
    except OSError:
        pass
    return CachedStream(prefix, state)


def jitter_offsets(values: npt.NDArray[np.uint32]) -> npt.NDArray[np.float32]:
    """SPEC B.5 offset of one ``rand()`` value: ``(float)r * 2^-31 - 0.5`` in float32, in [-0.5, 0.5)."""
    return values.astype(np.float32) * INV_2_31 - np.float32(0.5)


def glibc_jitter(n_samples: int, rng: GlibcRand | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Offsets ``(jx, jy)`` for ``n_samples`` consecutive samples in the binary's order (SPEC B.5).

    Per sample the binary calls ``r1 = rand(); r2 = rand()``; ``jy`` comes from ``r1`` (the FIRST call) and
    ``jx`` from ``r2``. ``rng`` continues an existing stream (tile by tile); by default a fresh seed-1 stream.
    """
    rng = rng if rng is not None else GlibcRand()
    pairs = rng.next(2 * n_samples).reshape(n_samples, 2)
    jy = jitter_offsets(pairs[:, 0])
    jx = jitter_offsets(pairs[:, 1])
    return jx, jy

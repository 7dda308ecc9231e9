"""Where the samples of a render go: tiles of whole rows, their pixel coordinates and jitter (SPEC B.2, B.5, B.6).

The render buffer is ``RW x RH`` samples, row ``j = 0`` at the bottom, visited bottom-up, ``i`` fastest.

* :func:`tile_rows`: the rows of each kernel launch (at most ``tile_rays`` samples, about
  :data:`PROGRESS_STEPS` per render when someone watches, each starting on a multiple of :data:`PACKET_ALIGN`
  samples so the image does not depend on the tile size);
* :func:`jitter_stream`: SPEC B.5 offsets, per sample ``r1 = rand(); r2 = rand()``,
  ``jy = (float)r1·2^-31 - 0.5`` first, then ``jx``, from glibc's seed-1 stream (:mod:`a5mi.render.glibc_rand`), or
  numpy's PCG64 for a ``seed``;
* :func:`pixel_coords`: float32 ``x_pix = i + jx``, ``y_pix = j + jy``, the B.2 camera-ray parameters;
  :func:`quadrant_coords`: the sample solution's own AOV rays (B.6 ``aov_mode="quadrant"``);
* :func:`main_tiles`, :func:`quadrant_tiles`: the :class:`Tile` sequence one pass over the buffer traces
  (the next tile's jitter drawn in a worker thread while the current one renders).

Pure numpy: no Dr.Jit, no Mitsuba.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from typing import NamedTuple

import numpy as np

from a5mi.render.glibc_rand import glibc_stream, jitter_offsets

Offsets = tuple[np.ndarray, np.ndarray]  # (jx, jy), float32, one entry per sample

#: Tiles start on a sample index that is a multiple of this (every SIMD packet width of Dr.Jit's LLVM backend
#: divides it: 4, 8, 16). Some sample's result depends, in the last bits, on which samples share its SIMD packet
#: (seen on scene10 at 30x30 -jitter, 8-wide AVX2: one pixel off by 2.8e-5 whenever a tile started off an
#: 8-sample boundary, none when it started on one). Narrowed down: it stays without the cube mesh, the glass,
#: the cube map or -bounces (0), and goes with -shadows off, so it is a shadow test (Mitsuba's ray queries in
#: plugins/octree_rule.occluded) flipping for one grazing sample whose light term is 2.8e-5; which query
#: depends on its packet was not isolated. Aligned tiles keep every packet as in a one-launch render.
PACKET_ALIGN = 64
#: With a progress callback, a render of many samples is split into about this many tiles (points where the
#: progress bar learns the render's rate); without one it is one tile up to ``tile_rays`` ...
PROGRESS_STEPS = 4
#: ... of at least this many samples each: every launch re-traces the integrator in Python (about 50-90 ms
#: for the course scenes on the shared 2-core machine), so finer tiles would cost more than they show; the
#: bar moves between tiles on the measured rate (a5mi.cli.progress.ProgressBar).
MIN_TILE_RAYS = 1 << 18


class Tile(NamedTuple):
    """Rows ``j0 .. j1-1`` of the render buffer and the float32 pixel coordinates of their samples (row-major,
    ``i`` fastest), the ``x_pix``, ``y_pix`` of SPEC B.2's camera rays."""

    j0: int
    j1: int
    x_pix: np.ndarray
    y_pix: np.ndarray


def tile_rows(rw: int, rh: int, tile_rays: int, *, align: int | None = None,
              steps: int | None = None) -> list[tuple[int, int]]:
    """Row ranges ``[j0, j1)`` (bottom-up) of the ``rw x rh`` render buffer, one per kernel launch.

    Rows per tile: ``max(1, target // rw)`` with ``target = min(tile_rays, max(MIN_TILE_RAYS, ceil(rw·rh /
    steps)))`` (``steps`` = :data:`PROGRESS_STEPS`), rounded down to a multiple of ``m = align / gcd(rw,
    align)`` (``align`` = :data:`PACKET_ALIGN`) and at least ``m``, then evened out (the same number of tiles,
    ``ceil(rh / count)`` rows rounded up to ``m``); a buffer that fits in one tile is one tile. Every tile
    starts on a sample index that is a multiple of ``align``: each sample then shares its SIMD packet with the
    same neighbours whatever the tile size, and the image is bit-identical for any ``tile_rays`` (a tile may
    exceed ``tile_rays`` by up to ``m`` rows when the width is odd).
    """
    align = PACKET_ALIGN if align is None else align
    steps = PROGRESS_STEPS if steps is None else steps
    target = min(tile_rays, max(MIN_TILE_RAYS, math.ceil(rw * rh / max(1, steps))))
    m = align // math.gcd(rw, align)
    rows = max(1, target // rw)
    if rows >= rh:
        return [(0, rh)]  # one launch: nothing to align
    rows = max(m, rows - rows % m)
    count = math.ceil(rh / rows)
    rows = math.ceil(math.ceil(rh / count) / m) * m  # the same number of tiles, evened out (still <= rows)
    return [(j0, min(rh, j0 + rows)) for j0 in range(0, rh, rows)]


def jitter_stream(seed: int | None, total: int | None = None) -> Callable[[int], Offsets]:
    """A function ``next(n) -> (jx, jy)`` giving the offsets of the next ``n`` samples (SPEC B.5 order).

    ``seed=None``: glibc ``rand()`` from seed 1 (r1 -> jy first, r2 -> jx), its fixed prefix read from the
    disk cache of :func:`a5mi.render.glibc_rand.glibc_stream`; else numpy's PCG64 with that seed, also drawn in
    (jy, jx) pairs so a sample's offsets do not depend on the tile size. ``total``: the number of samples
    that will be drawn, if known (small renders skip the disk cache).
    """
    if seed is None:
        rng = glibc_stream(need=None if total is None else 2 * total)

        def glibc_next(n: int) -> Offsets:
            pairs = rng.next(2 * n).reshape(n, 2)
            return jitter_offsets(pairs[:, 1]), jitter_offsets(pairs[:, 0])

        return glibc_next
    gen = np.random.default_rng(seed)

    def numpy_next(n: int) -> Offsets:
        pairs = gen.random((n, 2), dtype=np.float32) - np.float32(0.5)
        return np.ascontiguousarray(pairs[:, 1]), np.ascontiguousarray(pairs[:, 0])

    return numpy_next


def pixel_coords(rw: int, j0: int, j1: int, jitter: Offsets | None) -> tuple[np.ndarray, np.ndarray]:
    """float32 ``x_pix = i + jx``, ``y_pix = j + jy`` for rows ``j0..j1-1``, row-major (i fastest)."""
    i = np.tile(np.arange(rw, dtype=np.float32), j1 - j0)
    j = np.repeat(np.arange(j0, j1, dtype=np.float32), rw)
    if jitter is None:
        return i, j
    jx, jy = jitter
    return i + jx, j + jy


def quadrant_coords(rw: int, rh: int, j0: int, j1: int) -> tuple[np.ndarray, np.ndarray]:
    """``x_pix``, ``y_pix`` of the sample solution's AOV rays (SPEC B.6 compatibility, ``aov_mode="quadrant"``).

    Pixel (X, Y) uses the camera-plane point ``p = ((X+0.5-W/2)/max(W,H) + 0.5, (Y+0.5-H/2)/max(W,H) + 0.5)``
    in [0, 1] directly as B.2's ``(x, y)`` in [-1, 1] (only the top-right quadrant, magnified 2x). Expressed as
    pixel coordinates of the B.2 camera rays: ``x_pix = (p_x + 1)(W-1)/2`` (likewise y), in float64 then
    rounded to float32, so the rays agree with the binary's to float precision, not bit for bit.
    """
    x_pix, y_pix = quadrant_axes(rw, rh, j0, j1)
    return np.tile(x_pix, j1 - j0), np.repeat(y_pix, rw)


def quadrant_axes(rw: int, rh: int, j0: int = 0, j1: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """:func:`quadrant_coords`' ``x_pix`` of each column ``0 .. rw-1`` and ``y_pix`` of each row ``j0 .. j1-1``
    (default all ``rh``), float32, each computed elementwise (a subset of rows gives the same values)."""
    m = float(max(rw, rh))
    xs = (np.arange(rw) + 0.5 - rw / 2) / m + 0.5
    ys = (np.arange(j0, rh if j1 is None else j1) + 0.5 - rh / 2) / m + 0.5
    return ((xs + 1.0) * (rw - 1) / 2.0).astype(np.float32), ((ys + 1.0) * (rh - 1) / 2.0).astype(np.float32)


def jittered_rows(rw: int, rows: list[tuple[int, int]], seed: int | None,
                  timings: dict[str, float]) -> Iterator[tuple[int, int, Offsets]]:
    """Yield ``(j0, j1, offsets)`` per row range; the next range's offsets are drawn in a worker thread while
    the caller renders the current one (numpy's BLAS and Dr.Jit's kernels both release the GIL). The draw
    time is added to ``timings["jitter"]``."""
    draw = jitter_stream(seed, total=rw * sum(j1 - j0 for j0, j1 in rows))

    def timed(n: int) -> Offsets:
        t0 = time.perf_counter()
        out = draw(n)
        timings["jitter"] = timings.get("jitter", 0.0) + time.perf_counter() - t0
        return out

    with ThreadPoolExecutor(max_workers=1) as pool:
        pending: Future[Offsets] = pool.submit(timed, (rows[0][1] - rows[0][0]) * rw)
        for k, (j0, j1) in enumerate(rows):
            current = pending.result()
            if k + 1 < len(rows):
                nj0, nj1 = rows[k + 1]
                pending = pool.submit(timed, (nj1 - nj0) * rw)
            yield j0, j1, current


def main_tiles(rw: int, rows: list[tuple[int, int]], seed: int | None, jitter: bool,
               timings: dict[str, float], mistakes: tuple[str, ...] = ()) -> Iterator[Tile]:
    """The main image's tiles: sample ``(i, j)`` at ``(i + jx, j + jy)`` with ``-jitter``, else at ``(i, j)``.
    docs/MISTAKES.md ``mistakes``: ``no_jitter`` (offsets 0 on the 3W x 3H grid), ``jitter_0_1`` (offsets
    ``jx + 0.5`` in [0, 1) instead of [-0.5, 0.5)).

    The jittered tiles of a render of at most :data:`KEEP_SAMPLES` samples are kept for the next render with the
    same width, rows, seed and mistakes (a warm session's next save or request): the offsets are a function of
    those alone (glibc's seed-1 stream, or PCG64 with the seed), so the kept coordinates are the ones a new draw
    gives, bit for bit, and are read-only."""
    if not jitter or "no_jitter" in mistakes:
        for j0, j1 in rows:
            yield Tile(j0, j1, *pixel_coords(rw, j0, j1, None))
        return
    key = (rw, tuple(rows), seed, "jitter_0_1" in mistakes)
    kept = _KEPT_TILES.get(key)
    if kept is not None:
        yield from kept
        return
    made = []
    for j0, j1, offsets in jittered_rows(rw, rows, seed, timings):
        tile = Tile(j0, j1, *pixel_coords(rw, j0, j1, mistaken_offsets(offsets, mistakes)))
        made.append(tile)
        yield tile
    if rw * sum(j1 - j0 for j0, j1 in rows) <= KEEP_SAMPLES:   # every tile made: keep them
        for tile in made:
            tile.x_pix.flags.writeable = tile.y_pix.flags.writeable = False
        _KEPT_TILES.clear()
        _KEPT_TILES[key] = made


#: The last jittered tile sequence of :func:`main_tiles`, by ``(width, rows, seed, jitter_0_1)`` (one entry), and
#: the largest render it keeps, in samples (8 bytes each: 32 MiB; the 3W x 3H buffer of -size 300 300 -jitter is
#: 810,000 samples).
_KEPT_TILES: dict[tuple[object, ...], list[Tile]] = {}
KEEP_SAMPLES = 1 << 22


def mistaken_offsets(offsets: Offsets, mistakes: tuple[str, ...]) -> Offsets:
    """The ``-jitter`` offsets as docs/MISTAKES.md's ``jitter_0_1`` makes them (``jx + 0.5``, ``jy + 0.5`` in
    float32, in [0, 1)); unchanged without it."""
    if "jitter_0_1" in mistakes:
        return offsets[0] + np.float32(0.5), offsets[1] + np.float32(0.5)
    return offsets


def quadrant_tiles(rw: int, rh: int, rows: list[tuple[int, int]]) -> Iterator[Tile]:
    """The AOV pass's tiles of ``aov_mode="quadrant"`` (:func:`quadrant_coords`)."""
    for j0, j1 in rows:
        yield Tile(j0, j1, *quadrant_coords(rw, rh, j0, j1))

"""The render progress bar of the command layer: one line on a terminal's stderr (``a5 -v`` and long renders)."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import TextIO

from a5mi.cli.streams import write_diagnostic


class ProgressBar:
    """A one-line bar on a terminal's stderr, shown once a render has taken more than ``delay`` seconds.

    A callback ``(done, total)`` for the driver, which calls it after each tile (:func:`a5mi.render.tiles.tile_rows`:
    a few large tiles, since each launch re-traces the integrator). Used as a context manager it also redraws
    every ``tick`` seconds from a thread, so the line moves while a tile renders: ``#`` are samples finished,
    ``-`` the estimate since the last tile at the rate measured so far (over the tiles after the first, which
    also compiled the kernel), never past the end of the tile in flight; before the first tile ends a block
    sweeps the bar (no rate is known yet). The caller enables it only when the stream is a terminal, so a log
    never gets a ``\\r`` line."""

    def __init__(self, stream: TextIO, enabled: bool, delay: float = 1.0, width: int = 30, tick: float = 0.1,
                 clock: Callable[[], float] = time.perf_counter) -> None:
        import threading

        self.stream, self.enabled, self.delay, self.width, self.tick = stream, enabled, delay, width, tick
        self.clock = clock
        self.start = clock()
        self.shown = False
        self.finished = False
        self.done = self.total = 0
        self._marks: list[tuple[float, int]] = []  # (time, done) at each callback
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    # -------------------------------------------------------------------------------- context manager
    def __enter__(self) -> ProgressBar:
        import threading

        if self.enabled:
            self._thread = threading.Thread(target=self._run, name="a5mi-progress", daemon=True)
            self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
        with self._lock:
            if self.shown and not self.finished:
                write_diagnostic(self.stream, "\n")
                self.finished = True

    def _run(self) -> None:
        while not self._stop.wait(self.tick):
            with self._lock:
                self._draw(self.clock())

    # -------------------------------------------------------------------------------- the callback
    def __call__(self, done: int, total: int) -> None:
        with self._lock:
            now = self.clock()
            self.done, self.total = done, total
            self._marks.append((now, done))
            self._draw(now)

    def estimate(self, now: float) -> int:
        """Samples probably finished at ``now``: ``done`` plus the measured rate times the time since the last
        tile, capped one sample short of the end of the tile in flight (tiles are of equal size)."""
        if len(self._marks) < 1 or self.done >= self.total:
            return self.done
        marks = [(self.start, 0), *self._marks]
        t_last, d_last = marks[-1]
        steps = [(t1 - t0, d1 - d0) for (t0, d0), (t1, d1) in zip(marks, marks[1:], strict=False)]
        timed = steps[1:] or steps  # the first tile also compiled the kernel
        seconds = sum(t for t, _ in timed)
        rate = sum(d for _, d in timed) / seconds if seconds > 0 else 0.0
        step = max(d for _, d in steps)
        cap = min(self.total, d_last + step) - 1
        return max(self.done, min(cap, d_last + int(rate * (now - t_last))))

    def line(self, now: float) -> str:
        """The bar as drawn at ``now`` (without the leading carriage return)."""
        elapsed = now - self.start
        w = self.width
        if not self._marks:  # nothing measured yet: a block sweeping the bar
            pos = int(elapsed / max(self.tick, 1e-3)) % (2 * (w - 4))
            pos = pos if pos < w - 4 else 2 * (w - 4) - pos
            return f"[{'.' * pos}####{'.' * (w - 4 - pos)}]   ..  {elapsed:6.1f} s"
        total = self.total or 1
        est = self.estimate(now)
        fill, guess = int(self.done / total * w), int(est / total * w)
        guess = max(guess, fill)
        frac = est / total
        eta = elapsed / frac - elapsed if frac > 0 else 0.0
        bar = "#" * fill + "-" * (guess - fill) + "." * (w - guess)
        return f"[{bar}] {frac:4.0%}  {elapsed:6.1f} s  eta {eta:5.1f} s"

    def _draw(self, now: float) -> None:
        if not self.enabled or self.finished:
            return
        complete = self.total > 0 and self.done >= self.total
        if (now - self.start < self.delay and not complete) or (not self.shown and complete):
            return
        write_diagnostic(self.stream, "\r" + self.line(now))
        self.shown = True
        if complete:
            write_diagnostic(self.stream, "\n")
            self.finished = True


# ------------------------------------------------------------------------------------------ running commands

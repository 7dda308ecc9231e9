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
                 clock: Callable[[], float] = time.perf_counter, *, log: bool = False, log_every: float = 10.0,
                 rays: float | None = None, seconds: float | None = None, unit: str = "samples",
                 prog: str = "a5") -> None:
        import threading

        self.stream, self.enabled, self.delay, self.width, self.tick = stream, enabled, delay, width, tick
        self.clock = clock
        self.start = clock()
        self.shown = False
        self.finished = False
        self.done = self.total = 0
        #: ``-v`` off a terminal: whole lines (:meth:`log_line`) every ``log_every`` seconds instead of the bar;
        #: ``rays`` / ``seconds``: the work estimate's bound (a5mi.render.estimate), for the rays so far and
        #: the ETA before the first tile
        self.log, self.log_every, self.rays, self.seconds = log, log_every, rays, seconds
        self.unit, self.prog = unit, prog
        self._logged = self.start
        self._marks: list[tuple[float, int]] = []  # (time, done) at each callback
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    # -------------------------------------------------------------------------------- context manager
    def __enter__(self) -> ProgressBar:
        import threading

        if self.enabled or self.log:
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
                now = self.clock()
                self._draw(now)
                self._write_log(now, False)

    # -------------------------------------------------------------------------------- the callback
    def __call__(self, done: int, total: int) -> None:
        with self._lock:
            now = self.clock()
            self.done, self.total = done, total
            self._marks.append((now, done))
            self._draw(now)
            self._write_log(now, done >= total)

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
            left = None if self.seconds is None else self.seconds - elapsed
            eta = f"  eta <{left:5.0f} s" if left is not None and left > 0 else ""
            return f"[{'.' * pos}####{'.' * (w - 4 - pos)}]   ..  {elapsed:6.1f} s{eta}"
        total = self.total or 1
        est = self.estimate(now)
        fill, guess = int(self.done / total * w), int(est / total * w)
        guess = max(guess, fill)
        frac = est / total
        eta = elapsed / frac - elapsed if frac > 0 else 0.0
        bar = "#" * fill + "-" * (guess - fill) + "." * (w - guess)
        rays = f"  up to {self.rays * self.done / total:.2g} rays" if self.rays is not None else ""
        return f"[{bar}] {frac:4.0%}  {elapsed:6.1f} s  eta {eta:5.1f} s{rays}"

    def eta(self, now: float) -> float | None:
        """Seconds left: from the measured rate once a tile is done, else the work estimate's ``seconds``
        minus the time spent (an upper bound, as the estimate), else None."""
        elapsed = now - self.start
        if self._marks and self.total:
            frac = self.estimate(now) / self.total
            return elapsed / frac - elapsed if frac > 0 else None
        if self.seconds is not None:
            return max(self.seconds - elapsed, 0.0)
        return None

    def log_line(self, now: float) -> str:
        """``a5: progress 50% (405000 of 810000 samples), up to 3.7e7 rays so far, 1.2 s, eta 1.2 s``."""
        from a5mi.render.estimate import duration

        elapsed = now - self.start
        frac = self.done / self.total if self.total else 0.0
        text = f"{self.prog}: progress {frac:.0%} ({self.done} of {self.total or '?'} {self.unit})"
        if self.rays is not None and self.total:
            text += f", up to {self.rays * frac:.3g} rays so far"
        eta = self.eta(now)
        return text + f", {duration(elapsed)}" + (f", eta {duration(eta)}" if eta is not None else "")

    def _write_log(self, now: float, complete: bool) -> None:
        """A :meth:`log_line` when ``log_every`` seconds passed since the last (or the start); not at the end."""
        if not self.log or complete or now - self._logged < self.log_every:
            return
        self._logged = now
        write_diagnostic(self.stream, self.log_line(now) + "\n")

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

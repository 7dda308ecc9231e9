"""The engine's work queue of the live page (docs/VIEW.md "How it runs"): the HTTP and watcher threads post, the
engine's thread (:func:`a5mi.view.live.run_engine`) takes one job at a time."""

from __future__ import annotations

import threading
import time
from collections import deque
from concurrent.futures import Future
from typing import Any


class Jobs:
    """Work for the engine's thread: traces (first come, first served), one pending render (a reload of the
    scene files and/or new options; later requests replace earlier ones) and one pending diagnosis; and the marked
    region (:mod:`a5mi.view.region`), which every render renders first: marking one asks for a render."""

    def __init__(self) -> None:
        self._cond = threading.Condition()
        self._traces: deque[tuple[int, int, Future[Any]]] = deque()
        self._reload = False
        self._options: Any = None
        self._diagnose: str | None = None
        self._marked = False
        #: the marked region ``(X0, X1, Y0, Y1)`` of the saved image (row 0 the top), or None
        self.region: tuple[int, int, int, int] | None = None
        #: wall-clock time (``time.time()``) of the first reload request not yet taken, and of the last taken one
        self.reload_at: float | None = None
        self.taken_reload_at: float | None = None

    def render(self, options: Any = None, *, reload: bool = False) -> None:
        with self._cond:
            if reload and not self._reload:
                self.reload_at = time.time()
            self._reload = self._reload or reload
            if options is not None:
                self._options = options
            self._cond.notify()

    def diagnose(self, image: str) -> None:
        """Ask for a diagnosis of the current frame's ``image`` (one waits at most; a later request replaces it)."""
        with self._cond:
            self._diagnose = image
            self._cond.notify()

    def mark(self, region: tuple[int, int, int, int] | None) -> None:
        """Set the marked region (None: clear it); a region set asks for a render (its region first, now)."""
        with self._cond:
            self.region = region
            self._marked = region is not None
            self._cond.notify()

    def render_pending(self) -> bool:
        """Whether a render request waits (a newer save, control change or marked region than the render under
        way)."""
        with self._cond:
            return self._reload or self._options is not None or self._marked

    def trace(self, x: int, y: int) -> Future[Any]:
        fut: Future[Any] = Future()
        with self._cond:
            self._traces.append((x, y, fut))
            self._cond.notify()
        return fut

    def next(self, timeout: float) -> tuple[str, Any] | None:
        """``("trace", (x, y, future))``, ``("render", (reload, options or None))`` (a marked region alone: ``(False,
        None)``), ``("diagnose", image)`` or None after ``timeout``. Traces first, then renders (a diagnosis is of the
        newest frame), then a diagnosis."""
        with self._cond:
            if not (self._traces or self._reload or self._options is not None or self._marked or self._diagnose):
                self._cond.wait(timeout)
            if self._traces:
                return "trace", self._traces.popleft()
            if self._reload or self._options is not None or self._marked:
                job = (self._reload, self._options)
                self.taken_reload_at, self.reload_at = self.reload_at, None
                self._reload, self._options, self._marked = False, None, False
                return "render", job
            if self._diagnose:
                image, self._diagnose = self._diagnose, None
                return "diagnose", image
        return None


__all__ = ["Jobs"]

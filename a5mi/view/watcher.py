"""The files a scene description read, polled for changes (docs/VIEW.md "Live reload").

No inotify: a thread takes a :func:`snapshot` of every watched file every :data:`POLL_SECONDS` (the
``(st_mtime_ns, st_size, st_ino)`` of each path, None for a missing one, so a file that appears, disappears or is
replaced by an editor's rename counts) and calls ``changed()`` when a snapshot differs from the last one. The
paths are handed over by the engine's thread after each load (:meth:`Watcher.watch`).
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable, Iterable
from pathlib import Path

#: Seconds between two polls (50 Hz: a save waits 10 ms for its poll on average; a poll is one stat() per file).
POLL_SECONDS = 0.02

Stamp = tuple[int, int, int] | None


def stamp(path: Path) -> Stamp:
    """``(mtime in ns, size, inode)`` of ``path`` (following links), None when it cannot be stat'ed."""
    try:
        st = os.stat(path)
    except OSError:
        return None
    return st.st_mtime_ns, st.st_size, st.st_ino


def snapshot(paths: Iterable[Path]) -> dict[Path, Stamp]:
    """:func:`stamp` of every path."""
    return {p: stamp(p) for p in paths}


class Watcher:
    """Polls the watched paths on a daemon thread and calls ``changed()`` (from that thread) on a change."""

    def __init__(self, changed: Callable[[], None], interval: float = POLL_SECONDS) -> None:
        self._changed = changed
        self.interval = interval
        self._lock = threading.Lock()
        self._paths: list[Path] = []
        self._last: dict[Path, Stamp] = {}
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def watch(self, paths: Iterable[Path], before: dict[Path, Stamp] | None = None) -> None:
        """Watch ``paths`` from now on. The baseline (no change is reported for it) is ``before`` where it has the
        path (a snapshot taken before the files were read, so a save during the read is still seen), else the
        present state."""
        paths = list(dict.fromkeys(Path(p) for p in paths))
        now = snapshot(paths)
        with self._lock:
            self._paths = paths
            self._last = {p: (before[p] if before is not None and p in before else now[p]) for p in paths}

    @property
    def paths(self) -> list[Path]:
        with self._lock:
            return list(self._paths)

    def poll(self) -> bool:
        """One poll: True (and ``changed()`` called) when a watched file differs from the last poll."""
        with self._lock:
            paths = list(self._paths)
        now = snapshot(paths)
        with self._lock:
            if paths != self._paths:  # watch() ran meanwhile: its baseline wins
                return False
            differs = now != self._last
            self._last = now
        if differs:
            self._changed()
        return differs

    def _run(self) -> None:
        while not self._stop.wait(self.interval):
            self.poll()

    def start(self) -> None:
        self._thread = threading.Thread(target=self._run, name="a5mi-view-watcher", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2 * self.interval + 1)


__all__ = ["POLL_SECONDS", "Watcher", "snapshot", "stamp"]

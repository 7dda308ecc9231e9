"""Signals as exceptions at safe points: SIGINT, SIGTERM and SIGHUP never tear a write or an import apart.

The command layer calls :func:`install` first thing. From then on, SIGINT, SIGTERM and SIGHUP raise
:class:`Interrupted` (a ``KeyboardInterrupt``, so every ``except BaseException`` clean-up runs: temporary
files are removed, see :mod:`a5mi.imageio`) at once while the program runs plain Python, and are **deferred**
inside :func:`deferred` blocks: loading Dr.Jit / Mitsuba (an exception raised in the middle of a native
module's import leaves the interpreter broken: ``Fatal Python error: PyThreadState_Get``), a kernel launch, an
image being written. A deferred signal is raised when the outermost block ends; long native work is split
into short steps (the driver's tiles) with :func:`check` between them, so a render stops within about one
tile of the signal. Exit status: ``128 + signal number`` (130 for SIGINT, 143 SIGTERM, 129 SIGHUP).

A leaf module: standard library only.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from types import FrameType

#: The signals turned into :class:`Interrupted`.
SIGNALS: tuple[signal.Signals, ...] = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)

_state = {"depth": 0, "pending": 0, "installed": False}


class Interrupted(KeyboardInterrupt):
    """A signal (``signum``) arrived; ``status`` = 128 + signum is the exit status the command returns."""

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum

    @property
    def status(self) -> int:
        return 128 + self.signum

    @property
    def name(self) -> str:
        return signal.Signals(self.signum).name


def _handler(signum: int, frame: FrameType | None) -> None:
    if _state["depth"] > 0:
        _state["pending"] = _state["pending"] or signum
        return
    raise Interrupted(signum)


def install() -> None:
    """Route :data:`SIGNALS` to :class:`Interrupted` (main thread only; a no-op elsewhere or twice)."""
    if _state["installed"] or threading.current_thread() is not threading.main_thread():
        return
    for sig in SIGNALS:
        try:
            if sig != signal.SIGINT and signal.getsignal(sig) == signal.SIG_IGN:
                continue  # nohup: a hang-up the user asked to ignore stays ignored
            signal.signal(sig, _handler)
        except (OSError, ValueError):  # pragma: no cover - platforms without the signal
            pass
    _state["installed"] = True


def pending() -> int:
    """The deferred signal number, 0 when none."""
    return int(_state["pending"])


def check() -> None:
    """Raise :class:`Interrupted` if a signal arrived in a deferred block (call it between short steps)."""
    signum = _state["pending"]
    if signum:
        _state["pending"] = 0
        raise Interrupted(int(signum))


@contextmanager
def deferred() -> Iterator[None]:
    """Hold signals back in the body (main thread); a held signal is raised when the outermost block exits."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    _state["depth"] += 1
    try:
        yield
    finally:
        _state["depth"] -= 1
    if _state["depth"] == 0:
        check()


__all__ = ["SIGNALS", "Interrupted", "check", "deferred", "install", "pending"]

"""Signals as exceptions at safe points: SIGINT, SIGTERM and SIGHUP never tear a write or an import apart.

The command layer calls :func:`install` first thing. From then on, SIGINT, SIGTERM and SIGHUP raise
:class:`Interrupted` (a ``KeyboardInterrupt``, so every ``except BaseException`` clean-up runs: temporary
files are removed, see :mod:`a5mi.platform.imageio`) at once while the program runs plain Python, and are **deferred**
inside :func:`deferred` blocks: loading Dr.Jit / Mitsuba (an exception raised in the middle of a native
module's import leaves the interpreter broken: ``Fatal Python error: PyThreadState_Get``), a kernel launch, an
image being written. A deferred signal is raised when the outermost block ends; long native work is split
into short steps (the driver's tiles) with :func:`check` between them, so a render stops within about one
tile of the signal. Exit status: ``128 + signal number`` (130 for SIGINT, 143 SIGTERM, 129 SIGHUP).

A kernel can run for minutes (a glass ray tree at ``-bounces 64``) and the Python-level handler only runs
when it returns, so :func:`install` also starts a watchdog thread woken by ``signal.set_wakeup_fd`` (the C
handler writes the signal number at once; Dr.Jit releases the GIL while kernels run): if the program has not
finished :data:`GRACE` seconds after a signal, the watchdog reports it (the ``report`` callback of
:func:`install`, once) and ends the process with ``os._exit(128 + signum)``. It never does so inside a
:func:`protected` block (an atomic write or rename: the clean-up must run); it waits for the block to end.
A process that runs one command after another (``a5mi serve``) calls :func:`reset` when a command has ended:
the watchdog then lets the process live on.
A temporary that a hard exit leaves (a cache file being written in another thread) has this process's pid in
its name and is removed by the next run (:func:`a5mi.platform.paths.remove_stale`).

A leaf module: standard library only.
"""

from __future__ import annotations

import os
import re
import signal
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from types import FrameType

#: The signals turned into :class:`Interrupted`.
SIGNALS: tuple[signal.Signals, ...] = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
#: Seconds after a signal before the watchdog ends a process that has not stopped by itself.
GRACE = 1.0

_state: dict[str, int] = {"depth": 0, "pending": 0, "installed": False, "protect": 0, "reported": 0, "arrived": 0,
                          "epoch": 0}
#: The watchdog's report of a hard exit (:func:`install`, :func:`set_reporter`).
_reporter: list[Callable[[int], None]] = [lambda signum: None]
_report_lock = threading.Lock()


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


def _importing(frame: FrameType | None) -> bool:
    """True while a module is being imported (an exception there can break a native extension for good)."""
    while frame is not None:
        if frame.f_code.co_filename.startswith("<frozen importlib"):
            return True
        frame = frame.f_back
    return False


def _handler(signum: int, frame: FrameType | None) -> None:
    _state["arrived"] = _state["arrived"] or signum
    if _state["depth"] > 0 or _importing(frame):
        _state["pending"] = _state["pending"] or signum
        return
    raise Interrupted(signum)


def _watchdog(fd: int) -> None:
    while True:
        try:
            data = os.read(fd, 64)
        except InterruptedError:
            continue
        except OSError:
            return
        signums = [b for b in data if b in {int(s) for s in SIGNALS}]
        if not signums:
            continue
        epoch = _state["epoch"]
        deadline = time.monotonic() + GRACE
        while (time.monotonic() < deadline or _state["protect"] > 0) and _state["epoch"] == epoch:
            if _state["protect"] > 0:
                deadline = time.monotonic() + GRACE
            time.sleep(0.02)
        if _state["epoch"] != epoch:
            continue  # the command the signal stopped has ended and the process lives on (:func:`reset`)
        first = signums[0]
        report_once(lambda s=first: _reporter[0](s))
        os._exit(128 + first)


def install(report: Callable[[int], None] | None = None) -> None:
    """Route :data:`SIGNALS` to :class:`Interrupted` and start the watchdog (module docstring); ``report``
    prints the one line of a hard exit. Main thread only; a no-op elsewhere or twice."""
    if _state["installed"] or threading.current_thread() is not threading.main_thread():
        return
    if report is not None:
        _reporter[0] = report
        r, w = os.pipe()
        os.set_blocking(w, False)
        signal.set_wakeup_fd(w, warn_on_full_buffer=False)
        threading.Thread(target=_watchdog, args=(r,), name="a5mi-signal-watchdog", daemon=True).start()
    for sig in SIGNALS:
        try:
            if sig != signal.SIGINT and signal.getsignal(sig) == signal.SIG_IGN:
                continue  # nohup: a hang-up the user asked to ignore stays ignored
            signal.signal(sig, _handler)
        except (OSError, ValueError):  # pragma: no cover - platforms without the signal
            pass
    _state["installed"] = True


def report_once(emit: Callable[[], None]) -> None:
    """Print the interruption's one line with ``emit`` unless it was printed already (by the command layer's
    guard or by the watchdog: a lock makes the two exclusive, so there is exactly one line)."""
    with _report_lock:
        if not _state["reported"]:
            _state["reported"] = 1
            emit()


def ignore() -> None:
    """The command has finished (its status is decided, its files are written): from now on the signals are
    ignored, so interpreter shutdown (Dr.Jit's atexit clean-up) is never interrupted halfway."""
    if threading.current_thread() is not threading.main_thread():
        return
    for sig in SIGNALS:
        try:
            signal.signal(sig, signal.SIG_IGN)
        except (OSError, ValueError):  # pragma: no cover
            pass


def hold(signum: int) -> None:
    """Record ``signum`` as arrived and deferred (a signal caught before :func:`install`, by a handler that
    could only note it): the next :func:`check` raises it."""
    _state["pending"] = _state["pending"] or int(signum)
    _state["arrived"] = _state["arrived"] or int(signum)


def arrived() -> int:
    """The first signal of :data:`SIGNALS` this process received since :func:`install` (raised, deferred or
    held), 0 when none."""
    return int(_state["arrived"])


#: The last line of a Python traceback that Mitsuba's ``load_dict`` folds into its own message when a plugin's
#: constructor raised: ``Interrupted: 2`` or ``KeyboardInterrupt``.
_EMBEDDED = re.compile(r"^(?:[\w.]*\.)?(Interrupted|KeyboardInterrupt)\b(?::\s*(\d+))?\s*$", re.M)


def signal_behind(exc: BaseException) -> int:
    """The signal an exception stands for, 0 when none: a signal raised as :class:`Interrupted` in Python code
    that native code called (a ``dr.while_loop`` body, a plugin constructor in ``mi.load_dict``) comes back
    wrapped in a ``RuntimeError``: Dr.Jit chains it (``__cause__``), Mitsuba folds its traceback into the
    message. Looks through the chain, then the message, then :func:`arrived` (any exception after a signal
    is the signal's doing: the command was being stopped). docs/GUARANTEES.md, "Signals"."""
    seen: set[int] = set()
    link: BaseException | None = exc
    while link is not None and id(link) not in seen:
        seen.add(id(link))
        if isinstance(link, Interrupted):
            return link.signum
        if isinstance(link, KeyboardInterrupt):
            return int(signal.SIGINT)
        match = _EMBEDDED.search(str(link))
        if match:
            return int(match.group(2)) if match.group(1) == "Interrupted" and match.group(2) else int(signal.SIGINT)
        link = link.__cause__ or link.__context__
    return arrived()


def reset() -> None:
    """Forget the signals of a finished command (arrived, deferred, reported), and tell the watchdog that the
    command a signal stopped has ended (no hard exit follows it): a process that runs one command after another
    (``a5mi serve``, docs/SERVE.md) starts each with a clean slate. Main thread, between commands."""
    _state.update(pending=0, arrived=0, reported=0, epoch=_state["epoch"] + 1)


def set_reporter(report: Callable[[int], None]) -> None:
    """Replace the watchdog's report of a hard exit (:func:`install`'s ``report``)."""
    _reporter[0] = report


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


@contextmanager
def protected() -> Iterator[None]:
    """:func:`deferred`, and the watchdog waits for the block to end (atomic writes and renames)."""
    _state["protect"] += 1
    try:
        with deferred():
            yield
    finally:
        _state["protect"] -= 1


__all__ = ["GRACE", "SIGNALS", "Interrupted", "arrived", "check", "deferred", "hold", "ignore",
           "install", "pending", "protected", "report_once", "reset", "set_reporter", "signal_behind"]

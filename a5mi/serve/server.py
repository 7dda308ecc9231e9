"""The listening loop of ``a5mi serve`` (docs/SERVE.md): one render at a time, in this process's main thread.

:func:`serve` binds the socket (:func:`a5mi.serve.protocol.socket_path`, created ``0600`` in a ``0700``
folder; a stale socket of a dead server is replaced, a live one is a :class:`ServeError`), then runs until a
signal that was not passed on by a client, or ``idle_timeout`` seconds without a request.

An **acceptor thread** owns the listening socket: it checks each peer's uid (``SO_PEERCRED``; another uid is
closed at once, counted in :attr:`Stats.refused`), reads the request with its descriptors, and declines it
(``DECLINE`` with the reason; the client renders in-process) when a render is already running, when the
request's :data:`a5mi.serve.protocol.PROCESS_WIDE` environment differs from the server's, or when a module of
a5mi the server has loaded changed on disk since (then the server also stops: its code is stale). An accepted
request goes to the **main thread**, which puts the client's descriptors on 0, 1 and 2, calls
``handle(request)`` (the command layer's: it runs the command in the client's folder, with its environment and
umask), puts the server's own descriptors back and sends the exit status. Python
plugins and Dr.Jit see one thread, as in an ``a5`` process.

While a request runs, a **watcher thread** reads the client's connection: a ``SIGNAL`` frame (the client's
Ctrl-C), or the connection closing (the client is gone), raises that signal (SIGTERM for a closed connection)
in this process, where :mod:`a5mi.platform.interrupts` stops the render as in an ``a5`` process; a signal
raised so is the request's and the server goes on (:func:`a5mi.platform.interrupts.reset` after each request).
A render that does not stop within :data:`a5mi.platform.interrupts.GRACE` seconds of the signal ends the
server as it would end an ``a5`` process (the watchdog's hard exit; the client then prints the signal's line
itself, and the next ``a5`` renders in-process). Nothing here prints: ``log`` receives one line per event.
"""

from __future__ import annotations

import os
import queue
import select
import signal
import socket
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from a5mi.platform import interrupts
from a5mi.serve import protocol

Handler = Callable[[dict[str, Any]], int]


class ServeError(OSError):
    """The socket cannot be made (a server already listens there, a path too long, a folder not ours)."""


@dataclass
class Stats:
    """What a server did: requests run, declined (with their reasons) and connections refused."""

    served: int = 0
    declined: int = 0
    refused: int = 0


def _modules_mtime() -> dict[str, int]:
    out: dict[str, int] = {}
    for name, mod in list(sys.modules.items()):
        path = getattr(mod, "__file__", None)
        if path and (name == "a5mi" or name.startswith("a5mi.")):
            try:
                out[path] = os.stat(path).st_mtime_ns
            except OSError:
                out[path] = -1
    return out


class _CodeWatch:
    """Which loaded a5mi source files changed on disk since the server first saw them loaded."""

    def __init__(self) -> None:
        self.seen = _modules_mtime()

    def changed(self) -> str | None:
        now = _modules_mtime()
        for path, mtime in now.items():
            if self.seen.setdefault(path, mtime) != mtime:
                return path
        return None


def bind(path: Path) -> socket.socket:
    """A listening socket at ``path`` (module docstring); raises :class:`ServeError`."""
    if len(os.fsencode(path)) > protocol.MAX_PATH:
        raise ServeError(f"socket path longer than {protocol.MAX_PATH} bytes: {path}")
    path.parent.mkdir(mode=0o700, parents=True, exist_ok=True)
    st = os.stat(path.parent)
    if st.st_uid != os.getuid() or st.st_mode & 0o022:
        raise ServeError(f"the socket's folder {path.parent} is not this user's or others may write to it")
    if os.path.lexists(path):
        probe = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        try:
            probe.connect(str(path))
            raise ServeError(f"a server already listens on {path}")
        except (ConnectionRefusedError, FileNotFoundError):
            os.unlink(path)  # a dead server's socket
        except OSError as exc:
            if isinstance(exc, ServeError):
                raise
            raise ServeError(f"{path} exists and is not a server's socket ({exc.strerror or exc})") from None
        finally:
            probe.close()
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    old = os.umask(0o177)  # the socket is created 0600: never a moment open to others
    try:
        sock.bind(str(path))
    finally:
        os.umask(old)
    os.chmod(path, 0o600)
    sock.listen(16)
    return sock


class _Server:
    def __init__(self, listener: socket.socket, handle: Handler, log: Callable[[str], None]) -> None:
        self.listener, self.handle, self.log = listener, handle, log
        self.jobs: queue.Queue[tuple[socket.socket, dict[str, Any], list[int]]] = queue.Queue(maxsize=1)
        self.busy = threading.Event()
        self.stopping = threading.Event()
        self.code = _CodeWatch()
        self.env = protocol.process_wide(dict(os.environ))
        self.stats = Stats()
        self.forwarded = 0

    def _decline(self, conn: socket.socket, fds: list[int], reason: str) -> None:
        for fd in fds:
            os.close(fd)
        self.stats.declined += 1
        self.log(f"declined: {reason}")
        try:
            conn.sendall(protocol.frame(protocol.DECLINE, reason))
        except OSError:
            pass
        conn.close()

    def accept_loop(self) -> None:
        while not self.stopping.is_set():
            try:
                ready, _, _ = select.select([self.listener], [], [], 0.2)
                if not ready:
                    continue
                conn, _ = self.listener.accept()
            except OSError:
                return
            if protocol.peer_uid(conn) != os.getuid():
                self.stats.refused += 1
                self.log("refused a connection of another uid")
                conn.close()
                continue
            try:
                conn.settimeout(5.0)
                request, fds = protocol.read_request(conn)
                conn.settimeout(None)
            except OSError:
                conn.close()
                continue
            reason = self._check(request)
            if reason is None and self.busy.is_set():
                reason = "busy with another render"
            if reason is not None:
                self._decline(conn, fds, reason)
                continue
            self.busy.set()
            self.jobs.put((conn, request, fds))

    def _check(self, request: dict[str, Any]) -> str | None:
        env = request.get("env")
        if not isinstance(env, dict) or not isinstance(request.get("argv"), list):
            return "malformed request"
        if request.get("prog") != "a5":
            return f"unknown command {request.get('prog')!r}"
        if protocol.process_wide(env) != self.env:
            return "another environment (the JIT, interpreter or locale variables differ from the server's)"
        stale = self.code.changed()
        if stale is not None:
            self.stopping.set()
            return f"a5mi's code changed on disk since the server started ({stale}); stopping"
        return None

    def _watch(self, conn: socket.socket, done: threading.Event) -> None:
        """Pass on the client's signal, or SIGTERM when its connection closes (module docstring); a client that
        is gone gets no more output (the standard descriptors point at ``/dev/null``)."""
        while not done.is_set():
            ready, _, _ = select.select([conn], [], [], 0.1)
            if not ready or done.is_set():
                continue
            try:
                tag, payload = protocol.read_frame(conn)
            except OSError:
                tag, payload = protocol.SIGNAL, int(signal.SIGTERM)
                _silence()
            if tag == protocol.SIGNAL and payload in {int(s) for s in interrupts.SIGNALS} and not done.is_set():
                self.forwarded = self.forwarded or int(payload)
                os.kill(os.getpid(), int(payload))
                return

    def run_one(self, conn: socket.socket, request: dict[str, Any], fds: list[int]) -> None:
        """Run one accepted request on the client's descriptors 0, 1, 2 and send its exit status."""
        done = threading.Event()
        self.forwarded = 0
        t0 = time.perf_counter()
        saved = [os.dup(i) for i in (0, 1, 2)]
        watcher = threading.Thread(target=self._watch, args=(conn, done), name="a5mi-serve-watch", daemon=True)
        status: int = 70
        try:
            for i, fd in enumerate(fds):
                os.dup2(fd, i)
                os.close(fd)
            conn.sendall(protocol.frame(protocol.ACCEPT))
            watcher.start()
            status = self.handle(request)
        except OSError as exc:  # the client went away before the command started
            self.log(f"request dropped: {exc}")
            status = -1
        finally:
            try:
                with interrupts.deferred():  # a passed-on signal that lands after the command ended is spent here
                    done.set()
                    if watcher.is_alive():
                        watcher.join()
                    for i, fd in enumerate(saved):
                        os.dup2(fd, i)
                        os.close(fd)
            except interrupts.Interrupted:
                if not self.forwarded:
                    raise
        if status >= 0:
            try:
                conn.sendall(protocol.frame(protocol.STATUS, int(status)))
            except OSError:
                pass
            self.stats.served += 1
        conn.close()
        self.busy.clear()
        self.log(f"served {request['prog']} {' '.join(map(str, request['argv']))[:200]}: exit {status} in "
                 f"{time.perf_counter() - t0:.2f} s")


def _silence() -> None:
    try:
        null = os.open(os.devnull, os.O_RDWR)
    except OSError:
        return
    for fd in (1, 2):
        try:
            os.dup2(null, fd)
        except OSError:
            pass
    os.close(null)


def serve(path: Path, handle: Handler, log: Callable[[str], None], *, idle_timeout: float | None = None,
          ready: Callable[[], None] | None = None) -> Stats:
    """Serve ``path`` until a signal of this process's own (raised as :class:`interrupts.Interrupted`), a stale
    code tree, or ``idle_timeout`` seconds without a request; ``ready`` is called once the socket listens.
    The socket is removed at the end (when it is still ours). Returns the :class:`Stats`."""
    interrupts.set_reporter(lambda signum: log(f"hard exit: signal {signum}, render still running"))
    listener = bind(path)
    inode = os.stat(path).st_ino
    server = _Server(listener, handle, log)
    acceptor = threading.Thread(target=server.accept_loop, name="a5mi-serve-accept", daemon=True)
    acceptor.start()
    if ready is not None:
        ready()
    last = time.monotonic()
    try:
        while not server.stopping.is_set():
            try:
                conn, request, fds = server.jobs.get(timeout=0.2)
            except queue.Empty:
                if idle_timeout is not None and time.monotonic() - last > idle_timeout:
                    log(f"idle for {idle_timeout:g} s; stopping")
                    break
                continue
            server.run_one(conn, request, fds)
            last = time.monotonic()
            if interrupts.arrived() and not server.forwarded:
                break  # a signal of the server's own arrived during the render
            interrupts.reset()
    finally:
        server.stopping.set()
        acceptor.join()
        listener.close()
        try:
            if os.stat(path).st_ino == inode:
                os.unlink(path)
        except OSError:
            pass
    return server.stats

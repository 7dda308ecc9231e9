"""The ``a5`` side of ``a5mi serve`` (docs/SERVE.md): hand the command to a warm server when one runs.

:func:`run` is called by the ``a5`` console script (:mod:`a5mi.entry`) before the command layer is imported.
It returns ``None`` whenever the command must run in this process instead: ``$A5MI_NO_SERVE`` set, no usable
socket (:func:`a5mi.serve.protocol.usable_socket`), no server listening, a server of another uid, a request
the server declines (busy with another render, another environment, its code changed on disk), or a server
that stops before it reports an exit status. An image is written atomically by whichever process renders it,
so a fallback after a failed server never meets half an image. Otherwise the server has run the command with
this process's standard streams, working folder, environment and umask, and :func:`run` returns its exit
status. A SIGINT, SIGTERM or SIGHUP while it waits is passed on to the server (its render stops as an
in-process render would, and prints the same line); if the server has not answered :data:`GRACE` seconds
later, this process prints that line itself and returns ``128 + N``.

Standard library only, besides :mod:`a5mi.platform.interrupts`: a served ``a5`` costs an interpreter start
and this module (docs/SERVE.md "What it saves").
"""

from __future__ import annotations

import json
import os
import socket
import struct
import time
from collections.abc import Sequence

from a5mi.platform import interrupts
from a5mi.serve import protocol

#: Seconds the client waits for the server's exit status after passing on a signal.
GRACE = interrupts.GRACE
#: Seconds a connect and the server's first answer may take before the client renders in-process.
CONNECT_TIMEOUT = 5.0


def _request(prog: str, argv: Sequence[str], closed: Sequence[int]) -> dict[str, object]:
    umask = os.umask(0o022)
    os.umask(umask)
    return {"prog": prog, "argv": list(argv), "cwd": os.getcwd(), "env": dict(os.environ), "umask": umask,
            "closed": list(closed)}


class _Reader:
    """Frames from the server, read into a buffer so that a signal in ``recv`` loses no byte."""

    def __init__(self, sock: socket.socket) -> None:
        self.sock, self.buf = sock, b""

    def next(self) -> tuple[bytes, object]:
        while True:
            if len(self.buf) >= 5:
                (size,) = struct.unpack(">I", self.buf[1:5])
                if size > protocol.MAX_FRAME:
                    raise protocol.ProtocolError(f"frame of {size} bytes")
                if len(self.buf) >= 5 + size:
                    tag, data = self.buf[:1], self.buf[5:5 + size]
                    self.buf = self.buf[5 + size:]
                    try:
                        return tag, json.loads(data)
                    except ValueError as exc:
                        raise protocol.ProtocolError(f"bad frame: {exc}") from None
            chunk = self.sock.recv(65536)
            if not chunk:
                raise protocol.ProtocolError("connection closed")
            self.buf += chunk


def _connect(path: str) -> socket.socket | None:
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    try:
        sock.settimeout(CONNECT_TIMEOUT)
        sock.connect(path)
        if protocol.peer_uid(sock) != os.getuid():
            sock.close()
            return None
    except OSError:
        sock.close()
        return None
    return sock


def run(prog: str, argv: Sequence[str], closed: Sequence[int] = ()) -> int | None:
    """``prog ARGV`` run by the server: its exit status, or ``None`` to run it here (module docstring).
    ``closed``: the standard descriptors that were closed when this process started (:mod:`a5mi.entry`)."""
    if os.environ.get("A5MI_NO_SERVE"):
        return None
    path = protocol.socket_path()
    if len(os.fsencode(path)) > protocol.MAX_PATH or not protocol.usable_socket(path):
        return None
    sock = _connect(str(path))
    if sock is None:
        return None
    with sock:
        reader = _Reader(sock)
        try:
            protocol.send_request(sock, _request(prog, argv, closed), [0, 1, 2])
            tag, _ = reader.next()
        except (OSError, ValueError):
            return None
        if tag != protocol.ACCEPT:
            return None
        sock.settimeout(None)
        return _wait(sock, reader)


def _wait(sock: socket.socket, reader: _Reader) -> int | None:
    """The exit status the server reports; signals passed on (module docstring)."""
    signum = 0
    deadline = None
    while True:
        try:
            if deadline is not None:
                sock.settimeout(max(0.01, deadline - time.monotonic()))
            tag, payload = reader.next()
            if tag == protocol.STATUS and isinstance(payload, int):
                return payload
        except interrupts.Interrupted as exc:
            if not signum:
                signum, deadline = exc.signum, time.monotonic() + GRACE
                try:
                    sock.sendall(protocol.frame(protocol.SIGNAL, signum))
                except OSError:
                    pass
        except OSError:  # the server stopped (or, after a signal, did not answer in time)
            if signum:
                raise interrupts.Interrupted(signum) from None
            return None

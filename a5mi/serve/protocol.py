"""The socket of ``a5mi serve`` and its messages (docs/SERVE.md "Protocol and security").

**Where**: ``$A5MI_SERVE_SOCKET`` when set; else ``$XDG_RUNTIME_DIR/a5mi/serve-TAG.sock`` when that folder
is owned by this user and closed to others, else ``serve-TAG.sock`` in :func:`a5mi.cache_dir`; ``TAG`` = the
CRC-32 (8 hex digits) of this installation's package folder and interpreter, so two checkouts (two virtual
environments) never share one server. The folder is created ``0700``, the socket ``0600``; a client uses a
socket only when it is a socket owned by its own uid with no group or other permission bits, and then checks
the server's uid with ``SO_PEERCRED``; the server refuses any peer whose uid differs from its own.

**Messages** on the stream: a frame is one tag byte, a 4-byte big-endian length and that many bytes of UTF-8
JSON. The client sends ``REQUEST`` (its argv, working folder, environment, umask and the descriptors 0, 1 and
2 as ``SCM_RIGHTS``); the server answers ``DECLINE`` (a reason: the client then renders in-process) or
``ACCEPT``, and after the command ``STATUS`` (its exit status). While waiting, the client sends ``SIGNAL``
for a SIGINT, SIGTERM or SIGHUP it receives; the server raises it in its render as if it had arrived there.

Standard library only (the client's import must stay cheap).
"""

from __future__ import annotations

import json
import os
import socket
import stat
import struct
import sys
import zlib
from collections.abc import Callable
from pathlib import Path
from typing import Any

REQUEST, ACCEPT, DECLINE, STATUS, SIGNAL = b"R", b"A", b"D", b"X", b"K"
#: Largest frame read (bytes): an argv and an environment.
MAX_FRAME = 1 << 20
#: Environment variables a process reads once (the JIT back-end, the interpreter, the locale of the standard
#: streams): a request whose values differ from the server's is declined (the client renders in-process).
PROCESS_WIDE = ("A5MI_VARIANT", "DRJIT_", "LD_", "PYTHON", "LANG", "LC_", "MI_")
#: Longest socket path ``bind`` takes on Linux (``sun_path`` less its terminating NUL).
MAX_PATH = 107


class ProtocolError(OSError):
    """A frame that is not one of this protocol's, or a connection closed in the middle of one."""


def installation_tag() -> str:
    """8 hex digits naming this installation: its package folder and interpreter (module docstring; CRC-32, not a
    digest: it tells installations apart, it guards nothing, and ``hashlib`` would load OpenSSL in every ``a5``)."""
    here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    crc = zlib.crc32(b"\0".join((os.fsencode(here), os.fsencode(sys.executable))))
    return f"{crc:08x}"


def _owned_private(path: str | Path, is_kind: Callable[[int], bool], stat_of: Callable[..., os.stat_result]) -> bool:
    """True when ``path`` (``stat_of``: ``os.stat`` or ``os.lstat``) is of the kind ``is_kind``, owned by this
    user, with no group or other permission bits."""
    try:
        st = stat_of(path)
    except OSError:
        return False
    return is_kind(st.st_mode) and st.st_uid == os.getuid() and not st.st_mode & 0o077


def socket_path() -> Path:
    """The socket's path (module docstring "Where")."""
    env = os.environ.get("A5MI_SERVE_SOCKET")
    if env:
        return Path(env)
    runtime = os.environ.get("XDG_RUNTIME_DIR")
    if runtime and _owned_private(runtime, stat.S_ISDIR, os.stat):
        base = Path(runtime) / "a5mi"
    else:
        from a5mi import cache_dir

        base = cache_dir()
    return base / f"serve-{installation_tag()}.sock"


def usable_socket(path: Path) -> bool:
    """True when ``path`` is a socket owned by this user with mode ``0600`` or stricter (module docstring)."""
    return _owned_private(path, stat.S_ISSOCK, os.lstat)


def peer_uid(sock: socket.socket) -> int:
    """The uid of the process at the other end of a Unix socket (``SO_PEERCRED``)."""
    creds = sock.getsockopt(socket.SOL_SOCKET, socket.SO_PEERCRED, struct.calcsize("3i"))
    return struct.unpack("3i", creds)[1]


def process_wide(env: dict[str, str]) -> dict[str, str]:
    """The entries of ``env`` named by :data:`PROCESS_WIDE`."""
    return {k: v for k, v in env.items() if k.startswith(PROCESS_WIDE)}


def frame(tag: bytes, payload: Any = None) -> bytes:
    """One frame: ``tag``, the length, the JSON of ``payload``."""
    data = json.dumps(payload).encode()
    return tag + struct.pack(">I", len(data)) + data


def _recv_exact(sock: socket.socket, n: int) -> bytes:
    out = b""
    while len(out) < n:
        chunk = sock.recv(n - len(out))
        if not chunk:
            raise ProtocolError("connection closed")
        out += chunk
    return out


def read_frame(sock: socket.socket) -> tuple[bytes, Any]:
    """The next frame's ``(tag, payload)``; :class:`ProtocolError` at the end of the stream or on a bad frame."""
    head = sock.recv(5)
    if not head:
        raise ProtocolError("connection closed")
    head += _recv_exact(sock, 5 - len(head))
    tag, (size,) = head[:1], struct.unpack(">I", head[1:])
    if size > MAX_FRAME:
        raise ProtocolError(f"frame of {size} bytes")
    try:
        return tag, json.loads(_recv_exact(sock, size))
    except ValueError as exc:
        raise ProtocolError(f"bad frame: {exc}") from None


def read_request(sock: socket.socket) -> tuple[dict[str, Any], list[int]]:
    """The client's request and the three descriptors that came with it (the receiver owns them)."""
    data, fds, _flags, _addr = socket.recv_fds(sock, MAX_FRAME + 5, 3)
    try:
        if len(data) < 5 or data[:1] != REQUEST or len(fds) != 3:
            raise ProtocolError("not a request")
        (size,) = struct.unpack(">I", data[1:5])
        if size > MAX_FRAME:
            raise ProtocolError(f"frame of {size} bytes")
        data += _recv_exact(sock, 5 + size - len(data)) if len(data) < 5 + size else b""
        request = json.loads(data[5:5 + size])
        if not isinstance(request, dict):
            raise ProtocolError("not a request")
    except (ProtocolError, ValueError, struct.error):
        for fd in fds:
            os.close(fd)
        raise ProtocolError("not a request") from None
    return request, list(fds)


def send_request(sock: socket.socket, request: dict[str, Any], fds: list[int]) -> None:
    """Send ``request`` with the descriptors ``fds`` (``SCM_RIGHTS`` on the first bytes)."""
    data = frame(REQUEST, request)
    sent = socket.send_fds(sock, [data], fds)
    if sent < len(data):
        sock.sendall(data[sent:])

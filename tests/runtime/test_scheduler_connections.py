"""Joining an existing Dask scheduler (``a5 -scheduler``, ``a5mi animate|photons|grade --scheduler``): a plain
``tcp://`` one only with the explicit opt-in, named in the spelling of the command that refuses; every connection
has a time limit covering Dask's handshake, so a peer that accepts and never answers, or nothing listening, is one
line and exit 2 (a5mi/runtime/cluster.py ``probe_scheduler``)."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest
from helpers import RED_SPHERE

pytest.importorskip("distributed")

SCENE = RED_SPHERE
ANIMATED = SCENE + "Animation { frames 2 fps 24 }\n"


@pytest.fixture
def silent_peer() -> Iterator[str]:
    """``tcp://127.0.0.1:PORT`` of a server that accepts every connection and never sends a byte."""
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(16)
    held: list[socket.socket] = []
    stop = threading.Event()

    def accept() -> None:
        while not stop.is_set():
            try:
                conn, _ = server.accept()
            except OSError:
                return
            held.append(conn)

    t = threading.Thread(target=accept, daemon=True)
    t.start()
    try:
        yield f"tcp://127.0.0.1:{server.getsockname()[1]}"
    finally:
        stop.set()
        server.close()
        for c in held:
            c.close()


@pytest.fixture
def closed_port() -> str:
    """``tcp://127.0.0.1:PORT`` where nothing listens (a port bound and released)."""
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return f"tcp://127.0.0.1:{port}"


def _run(cwd: Path, prog: str, *argv: str) -> subprocess.CompletedProcess[str]:
    (cwd / "s.txt").write_text(SCENE)
    (cwd / "anim.txt").write_text(ANIMATED)
    py = f"import sys; from a5mi.entry import {prog}; sys.argv = ['{prog}'] + sys.argv[1:]; {prog}()"
    env = {**os.environ, "A5MI_CACHE_DIR": str(cwd), "DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT": "3s"}
    try:  # the connection's own limit is 3 s: a hang fails the test here, not the suite
        return subprocess.run([sys.executable, "-c", py, *argv], cwd=cwd, capture_output=True, text=True,
                              timeout=240, env=env)
    except subprocess.TimeoutExpired:
        pytest.fail(f"{prog} {' '.join(argv)} still waiting after 240 s")


COMMANDS = {
    "a5": ("a5", ["-input", "s.txt", "-output", "o.png", "-size", "8", "8", "-scheduler"], "-insecure_scheduler",
           "-tls_ca/-tls_cert/-tls_key"),
    "animate": ("a5mi", ["animate", "anim.txt", "-o", "frames", "-size", "8", "8", "--scheduler"],
                "--insecure-scheduler", "--tls-ca/--tls-cert/--tls-key"),
    "photons": ("a5mi", ["photons", "s.txt", "--ppm", "o.png", "--passes", "2", "-size", "8", "8", "--scheduler"],
                "--insecure-scheduler", "--tls-ca/--tls-cert/--tls-key"),
}


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_a_plain_tcp_scheduler_needs_the_opt_in_in_the_commands_spelling(tmp_path: Path, closed_port: str,
                                                                          command: str) -> None:
    prog, argv, opt_in, tls = COMMANDS[command]
    p = _run(tmp_path, prog, *argv, closed_port)
    lines = p.stderr.strip().splitlines()
    assert p.returncode == 2 and len(lines) == 1, p.stderr
    assert f"use tls:// with {tls}, or {opt_in}" in lines[0], lines[0]
    assert not (tmp_path / "o.png").exists() and not (tmp_path / "frames").exists()


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_a_peer_that_accepts_and_never_answers_is_one_line(tmp_path: Path, silent_peer: str, command: str) -> None:
    prog, argv, opt_in, _ = COMMANDS[command]
    p = _run(tmp_path, prog, *argv, silent_peer, opt_in)
    lines = p.stderr.strip().splitlines()
    assert p.returncode == 2 and len(lines) == 1, p.stderr
    assert lines[0].endswith(f"scheduler {silent_peer}: no Dask handshake within 3 s (is it a Dask scheduler?)"), \
        lines[0]
    assert not (tmp_path / "o.png").exists()


def test_nothing_listening_is_one_line(tmp_path: Path, closed_port: str) -> None:
    prog, argv, opt_in, _ = COMMANDS["a5"]
    p = _run(tmp_path, prog, *argv, closed_port, opt_in)
    lines = p.stderr.strip().splitlines()
    assert p.returncode == 2 and len(lines) == 1, p.stderr
    assert f"scheduler {closed_port}: cannot connect: Connection refused" in lines[0], lines[0]

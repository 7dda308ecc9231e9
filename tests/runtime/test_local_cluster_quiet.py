"""``a5 -workers N``'s local cluster (a5mi/runtime/cluster.py ``start_client``) binds its scheduler's HTTP server on
a free
loopback port: with 127.0.0.1:8787 (Dask's default dashboard port) taken by another program, the run still prints
nothing on stderr (no ``Port 8787 is already in use`` warning) and writes its image."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
from pathlib import Path

import pytest
from helpers import RED_SPHERE

pytest.importorskip("distributed")

SCENE = RED_SPHERE


def test_a_taken_dashboard_port_prints_nothing(tmp_path: Path) -> None:
    holder = socket.socket()
    try:
        holder.bind(("127.0.0.1", 8787))
        holder.listen(1)
    except OSError:
        pass  # another program holds it already: the condition under test
    try:
        (tmp_path / "s.txt").write_text(SCENE)
        py = "import sys; from a5mi.entry import a5; sys.argv = ['a5'] + sys.argv[1:]; a5()"
        p = subprocess.run([sys.executable, "-c", py, "-input", "s.txt", "-output", "o.png", "-size", "8", "8",
                            "-workers", "2"], cwd=tmp_path, capture_output=True, text=True, timeout=600,
                           env={**os.environ, "A5MI_CACHE_DIR": str(tmp_path)})
    finally:
        holder.close()
    assert p.returncode == 0 and p.stderr == "", p.stderr
    assert (tmp_path / "o.png").exists()

"""``a5mi view --reference IMG``: a FIFO, a device or a folder named as the reference is one line and exit 2 at
once (as ``compare`` and ``trace --diff`` refuse it), never an ``open()`` that blocks the process and its
signals: every image is opened by :func:`a5mi.platform.imageio._open_input`, which takes regular files only."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from view_scenes import write_scene


@pytest.mark.parametrize("name, kind", [("fifo.png", "FIFO"), ("/dev/zero", "character device"),
                                        ("folder.png", "folder")])
def test_a_special_file_as_the_reference_is_refused_at_once(tmp_path: Path, name: str, kind: str) -> None:
    os.mkfifo(tmp_path / "fifo.png")
    (tmp_path / "folder.png").mkdir()
    write_scene(tmp_path / "s.txt")
    py = "import sys; from a5mi.entry import a5mi; sys.argv = ['a5mi'] + sys.argv[1:]; a5mi()"
    argv = ["view", "s.txt", "-size", "8", "8", "--reference", name]
    try:  # a blocking open must fail the test, not hang it
        p = subprocess.run([sys.executable, "-c", py, *argv], cwd=tmp_path, capture_output=True, text=True,
                           timeout=60, env={**os.environ, "A5MI_CACHE_DIR": str(tmp_path)})
    except subprocess.TimeoutExpired:
        pytest.fail(f"a5mi {' '.join(argv)} blocked for 60 s")
    lines = p.stderr.strip().splitlines()
    assert p.returncode == 2 and len(lines) == 1, p.stderr
    assert f"not a regular file ({kind})" in lines[0] and name in lines[0], lines[0]


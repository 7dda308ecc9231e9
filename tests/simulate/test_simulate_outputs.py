"""``a5mi simulate smoke -o DIR``: a full disk is one line and exit 2 naming the frame (every frame written is
whole, no temporary is left), and a file in ``DIR`` under a frame's name that is not a ``.vol`` grid is never
replaced (docs/CLI.md "Exit status"; docs/EXTENSIONS.md E.22)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from helpers import small_tmpfs

from a5mi.converters.volgrid import read_vol


@pytest.fixture
def tiny_fs(tmp_path: Path):  # noqa: ANN201 - a fixture
    """A 64 KiB tmpfs at ``tmp_path/fs`` (root only; skipped otherwise), unmounted afterwards."""
    with small_tmpfs(tmp_path, "64k") as mnt:
        yield mnt


def _simulate(cwd: Path, *argv: str) -> subprocess.CompletedProcess[str]:
    py = "import sys; from a5mi.entry import a5mi; sys.argv = ['a5mi'] + sys.argv[1:]; a5mi()"
    return subprocess.run([sys.executable, "-c", py, "simulate", "smoke", *argv], cwd=cwd, capture_output=True,
                          text=True, timeout=600)


def test_a_full_disk_is_one_line_naming_the_frame(tiny_fs: Path) -> None:
    # a 12³ frame is 6912 + 48 bytes: a 64 KiB tmpfs holds 9 of the 20
    p = _simulate(tiny_fs, "-o", "f", "--frames", "20", "--grid", "12")
    lines = p.stderr.strip().splitlines()
    assert p.returncode == 2 and len(lines) == 1, p.stderr
    assert "No space left on device" in lines[0] and "frames written)" in lines[0], lines[0]
    written = sorted((tiny_fs / "f").iterdir())
    assert 0 < len(written) < 20 and all(w.name.startswith("smoke_") for w in written), written
    for w in written:  # whole frames only, no temporary
        assert read_vol(w).shape == (12, 12, 12, 1)
    assert f"'f/smoke_{len(written):03d}.vol'" in lines[0] and f"({len(written)} of 20 frames" in lines[0]


@pytest.mark.parametrize("what", ["text", "fifo", "link"])
def test_a_file_it_did_not_write_is_not_overwritten(tmp_path: Path, what: str) -> None:
    out = tmp_path / "f"
    out.mkdir()
    victim = out / "smoke_001.vol"
    if what == "text":
        victim.write_text("my notes\n")
    elif what == "fifo":
        os.mkfifo(victim)
    else:
        (tmp_path / "elsewhere.vol").write_text("x")
        victim.symlink_to(tmp_path / "elsewhere.vol")
    p = _simulate(tmp_path, "-o", "f", "--frames", "3", "--grid", "8")
    lines = p.stderr.strip().splitlines()
    assert p.returncode == 2 and len(lines) == 1, p.stderr
    assert "'f/smoke_001.vol' exists and" in lines[0] and "not overwritten" in lines[0], lines[0]
    assert sorted(x.name for x in out.iterdir()) == ["smoke_001.vol"]  # nothing written before the refusal
    if what == "text":
        assert victim.read_text() == "my notes\n"


def test_its_own_frames_are_replaced(tmp_path: Path) -> None:
    for _ in range(2):
        p = _simulate(tmp_path, "-o", "f", "--frames", "2", "--grid", "8")
        assert p.returncode == 0, p.stderr
    assert sorted(x.name for x in (tmp_path / "f").iterdir()) == ["smoke_000.vol", "smoke_001.vol"]

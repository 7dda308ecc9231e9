"""Image writes on a full disk, stale temporaries, special files (docs/CLI.md "Exit status": 2, nothing half-written).

The disk-full tests mount a small tmpfs made inside the test (root only; skipped otherwise) and fill it.
"""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import numpy as np
import pytest
from helpers import small_tmpfs

from a5mi.platform import imageio, paths
from a5mi.platform.errors import ImageWriteError, UserError


@pytest.fixture
def tiny_fs(tmp_path: Path):
    """A 256 KiB tmpfs at ``tmp_path/fs``, unmounted afterwards."""
    with small_tmpfs(tmp_path, "256k") as mnt:
        yield mnt


def _fill(mnt: Path, leave: int) -> None:
    """Fill the filesystem until about ``leave`` bytes are free."""
    st = os.statvfs(mnt)
    free = st.f_bavail * st.f_frsize
    with open(mnt / "filler", "wb") as f:
        try:
            f.write(b"\0" * max(0, free - leave))
        except OSError:
            pass


def _noise(h: int = 120, w: int = 160) -> np.ndarray:
    return np.random.default_rng(5).random((h, w, 3), dtype=np.float32)


@pytest.mark.parametrize("ext", [".png", ".bmp", ".tga", ".ppm", ".tif", ".exr"])
@pytest.mark.parametrize("leave", [0, 8192])
def test_disk_full_keeps_the_old_image(tiny_fs: Path, ext: str, leave: int) -> None:
    """on a full filesystem the write fails (one ImageWriteError), the old image is untouched
    byte for byte and no temporary is left."""
    target = tiny_fs / f"out{ext}"
    small = np.full((4, 4, 3), 0.5, np.float32)
    imageio.write_image(target, small)
    before = target.read_bytes()
    _fill(tiny_fs, leave)
    with pytest.raises(ImageWriteError, match=r"write failed"):
        imageio.write_image(target, _noise())
    assert target.read_bytes() == before
    assert sorted(p.name for p in tiny_fs.iterdir()) == sorted(["filler", target.name])


def test_disk_full_message_names_the_cause(tiny_fs: Path) -> None:
    _fill(tiny_fs, 0)
    with pytest.raises(ImageWriteError, match="no space left on device"):
        imageio.write_image(tiny_fs / "o.png", _noise())


def test_write_is_verified_round_trip(tmp_path: Path) -> None:
    """A normal write reads back exactly (the verification does not reject good files)."""
    img = _noise(7, 9)
    for ext in (".png", ".bmp", ".tga", ".ppm", ".tiff", ".exr"):
        imageio.write_image(tmp_path / f"a{ext}", img)
        back = imageio.read_image(tmp_path / f"a{ext}")
        want = img if ext == ".exr" else imageio.quantize(img) / np.float32(255)
        np.testing.assert_array_equal(back, want)


def test_stale_temporaries_of_dead_processes_are_removed(tmp_path: Path) -> None:
    """a temporary left by a killed process (its pid no longer runs) is removed by the next write;
    one of a live process (a concurrent writer) and other people's files are kept."""
    proc = subprocess.Popen(["true"])
    proc.wait()
    stale = tmp_path / f".o.png.a5mi-{proc.pid}-abc123.png"
    live = tmp_path / f".o.png.a5mi-{os.getppid()}-abc123.png"
    other = tmp_path / ".o.png.mine.png"
    for p in (stale, live, other):
        p.write_bytes(b"partial")
    imageio.write_image(tmp_path / "o.png", _noise(3, 3))
    assert not stale.exists() and live.exists() and other.exists()
    with imageio.atomic_file(tmp_path / "c.npy") as f:
        f.write(b"x")
    assert (tmp_path / "c.npy").read_bytes() == b"x"


def test_read_regular_refuses_special_files(tmp_path: Path) -> None:
    """a FIFO does not block, /dev/zero is not read, a large file is refused by size."""
    fifo = tmp_path / "f.txt"
    os.mkfifo(fifo)
    with pytest.raises(UserError, match=r"not a regular file \(FIFO\)"):
        paths.read_regular(fifo, 1000, "scene file")
    with pytest.raises(UserError, match=r"not a regular file \(character device\)"):
        paths.read_regular("/dev/zero", 1000, "scene file")
    with pytest.raises(UserError, match=r"not a regular file \(folder\)"):
        paths.read_regular(tmp_path, 1000, "scene file")
    big = tmp_path / "big.txt"
    big.write_bytes(b"a" * 1001)
    with pytest.raises(UserError, match="1001 bytes is more than the limit of 1000 bytes"):
        paths.read_regular(big, 1000, "scene file")
    assert paths.read_regular(big, 1001) == b"a" * 1001


def test_output_that_is_a_fifo_or_device_is_refused(tmp_path: Path) -> None:
    """a FIFO or device as an output is named for what it is, not "a folder"."""
    fifo = tmp_path / "o.png"
    os.mkfifo(fifo)
    with pytest.raises(ImageWriteError, match=r"not a regular file \(FIFO\)"):
        imageio.check_output_path(fifo)
    with pytest.raises(ImageWriteError, match="no image extension"):
        imageio.check_output_path("/dev/null")


def test_texture_too_large_for_memory_is_refused_before_decoding(tmp_path: Path, monkeypatch) -> None:
    """the header is read first; an image whose decoded pixels would not fit is refused by size."""
    from a5mi.platform import resources

    img = np.zeros((2000, 3000, 3), np.uint8)
    imageio.write_image(tmp_path / "t.png", img)
    need = resources.image_bytes(3000, 2000, 3)
    monkeypatch.setenv("A5MI_MEMORY_LIMIT", str(need - 1))
    with pytest.raises(imageio.ImageReadError, match=r"3000x2000 pixels need about 0.1 GB of memory to decode"):
        imageio.read_uint8(tmp_path / "t.png")
    monkeypatch.setenv("A5MI_MEMORY_LIMIT", str(need))
    assert imageio.read_uint8(tmp_path / "t.png").shape == (2000, 3000, 3)


def test_render_memory_model() -> None:
    """the model of a5mi.platform.resources (figures measured with a5 -v, BENCHMARKS.md): 16384^2 is ~16 GB,
    -jitter -filter keeps only the W x H result."""
    from a5mi.platform import resources

    big = resources.render_bytes(16384, 16384, width=16384, height=16384, aovs=False, jitter=False,
                                 filtered=False, tile_rays=1 << 20)
    assert 16e9 < big < 17e9
    plain = resources.render_bytes(2100, 2100, width=700, height=700, aovs=False, jitter=True, filtered=False,
                                   tile_rays=1 << 20)
    streamed = resources.render_bytes(2100, 2100, width=700, height=700, aovs=False, jitter=True, filtered=True,
                                      tile_rays=1 << 20)
    assert plain - streamed == (2100 * 2100 - 700 * 700) * resources.SAMPLE_BYTES


# ------------------------------------------------------------------------------- C libraries' own stderr
def _corrupt_png(path: Path) -> None:
    """A PNG whose image data fails its CRC (libpng prints ``libpng error: IDAT: CRC error`` on fd 2)."""
    imageio.write_image(path, _noise(16, 16))
    data = bytearray(path.read_bytes())
    data[-20] ^= 0xFF
    path.write_bytes(bytes(data))


def test_libpng_errors_are_folded_into_the_one_error(tmp_path: Path, capfd) -> None:
    """Decoding a corrupt PNG: one ImageReadError naming the cause; nothing printed on the process's stderr."""
    _corrupt_png(tmp_path / "bad.png")
    with pytest.raises(imageio.ImageReadError, match="PNG read error"):
        imageio.read_uint8(tmp_path / "bad.png")
    assert capfd.readouterr().err == ""


def test_disk_full_png_write_prints_nothing_else(tiny_fs: Path, capfd) -> None:
    """A PNG cut short by a full disk: the read-back check's libpng error is part of the one error."""
    _fill(tiny_fs, 8192)
    with pytest.raises(ImageWriteError, match="write failed"):
        imageio.write_image(tiny_fs / "o.png", _noise())
    assert capfd.readouterr().err == ""


@pytest.mark.parametrize("use", ["texture", "cube", "bump"])
def test_corrupt_png_input_is_one_line(tmp_path: Path, use: str) -> None:
    """``a5`` with a corrupt PNG texture, cube-map face or bump map: exactly one error line, exit 2."""
    import sys

    from a5mi.spec import CUBE_FACES

    mat = "diffuseColor 1 1 1"
    bg = "Background { color 0 0 0 ambientLight 0.2 0.2 0.2 }"
    flags: list[str] = []
    if use == "texture":
        _corrupt_png(tmp_path / "t.png")
        mat += " texture t.png"
    elif use == "bump":
        _corrupt_png(tmp_path / "t.png")
        imageio.write_image(tmp_path / "k.png", _noise(16, 16))
        mat += " texture k.png bump t.png"
        flags = ["-bump"]
    else:
        (tmp_path / "cube").mkdir()
        for face in CUBE_FACES:
            imageio.write_image(tmp_path / "cube" / f"{face}.png", _noise(16, 16))
        _corrupt_png(tmp_path / "cube" / f"{CUBE_FACES[0]}.png")
        bg = "Background { color 0 0 0 ambientLight 0.2 0.2 0.2 cubeMap cube }"
    (tmp_path / "s.txt").write_text(
        "PerspectiveCamera { center 0 0 10 direction 0 0 -1 up 0 1 0 angle 30 }\n"
        "Lights { numLights 1 DirectionalLight { direction 0 0 -1 color 1 1 1 } }\n" + bg + "\n"
        f"Materials {{ numMaterials 1 Material {{ {mat} }} }}\n"
        "Group { numObjects 1 MaterialIndex 0 TriangleMesh { obj_file m.obj } }\n")
    (tmp_path / "m.obj").write_text("v -1 -1 0\nv 1 -1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nf 1/1 2/2 3/3\n")
    p = subprocess.run([sys.executable, "-m", "a5mi", "-input", "s.txt", "-output", "o.png", "-size", "8", "8",
                        *flags], cwd=tmp_path, capture_output=True, text=True, timeout=120)
    lines = p.stderr.splitlines()
    assert p.returncode == 2 and len(lines) == 1 and "PNG read error" in lines[0], p.stderr
    assert not (tmp_path / "o.png").exists()


# ------------------------------------------------------------------------------- the process's own memory limits
def _under_address_limit(limit: int):
    import resource

    return lambda: resource.setrlimit(resource.RLIMIT_AS, (limit, limit))


def test_available_memory_counts_the_address_space_limit(tmp_path: Path) -> None:
    """``ulimit -v``: available() is at most the RLIMIT_AS soft limit less the reserve."""
    import sys

    from a5mi.platform import resources

    limit = 3 << 30
    p = subprocess.run([sys.executable, "-c", "from a5mi.platform import resources; print(resources.available())"],
                       capture_output=True, text=True, preexec_fn=_under_address_limit(limit), timeout=60,
                       env={k: v for k, v in os.environ.items() if k != "A5MI_MEMORY_LIMIT"})
    assert p.returncode == 0, p.stderr
    assert 0 < int(p.stdout) <= limit - resources.address_space_reserve()


def test_a5_refuses_a_render_beyond_ulimit_v_at_once(tmp_path: Path) -> None:
    """``a5 -size 5000 5000`` (about 1.7 GB) under a 2.5 GB address-space limit: one line and 2 before
    anything is read, not a MemoryError after the render started."""
    import sys

    (tmp_path / "s.txt").write_text("PerspectiveCamera { center 0 0 10 direction 0 0 -1 up 0 1 0 angle 30 }\n"
                                    "Lights { numLights 0 }\nMaterials { numMaterials 0 }\n"
                                    "Group { numObjects 0 }\n")
    p = subprocess.run([sys.executable, "-m", "a5mi", "-input", "s.txt", "-output", "o.png", "-size", "5000",
                        "5000"], cwd=tmp_path, capture_output=True, text=True, timeout=120,
                       preexec_fn=_under_address_limit(5 << 29))
    assert p.returncode == 2 and p.stderr.splitlines() == [p.stderr.strip()], p.stderr
    assert "-size 5000 5000 needs about" in p.stderr and "is available" in p.stderr
    assert not (tmp_path / "o.png").exists()


@pytest.mark.parametrize("reader", ["read_uint8", "read_levels"])
def test_an_image_bomb_is_refused_by_its_header_under_ulimit_v(tmp_path: Path, reader: str) -> None:
    """A 2.6 MB PNG of 30000 x 30000 pixels under a 3 GB address-space limit: refused by its header's size
    (one ImageReadError), never ``std::bad_alloc`` or a MemoryError halfway through the decode."""
    import sys

    from hostile import png_bomb

    (tmp_path / "bomb.png").write_bytes(png_bomb(30000))
    code = (f"from a5mi.platform import imageio\ntry:\n    imageio.{reader}('bomb.png')\n"
            "except imageio.ImageReadError as e:\n    print(e)\n")
    p = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=120,
                       preexec_fn=_under_address_limit(3 << 30),
                       env={k: v for k, v in os.environ.items() if k != "A5MI_MEMORY_LIMIT"})
    assert p.returncode == 0 and p.stderr == "", p.stderr
    assert "30000x30000 pixels need about" in p.stdout, p.stdout


def test_levels_count_their_float64_copies(tmp_path: Path, monkeypatch) -> None:
    """read_levels converts to float64 (two copies) and replicates grey: its estimate includes them."""
    from a5mi.platform import resources

    imageio.write_image(tmp_path / "g.png", np.zeros((100, 100, 1), np.uint8))
    need = resources.image_bytes(100, 100, 1) + 100 * 100 * (16 + 24)
    monkeypatch.setenv("A5MI_MEMORY_LIMIT", str(need - 1))
    with pytest.raises(imageio.ImageReadError, match="100x100 pixels need"):
        imageio.read_levels(tmp_path / "g.png")
    monkeypatch.setenv("A5MI_MEMORY_LIMIT", str(need))
    assert imageio.read_levels(tmp_path / "g.png").shape == (100, 100, 3)

"""Helpers shared by the test folders (importable from any of them: tests/ is on ``sys.path`` through its
conftest): the project's folders, a5 scene text rendered in-process or converted, and a command's refusal (exit
2, one line, nothing written) checked in one place."""

from __future__ import annotations

import os
import struct
import subprocess
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pytest

#: tests/
TESTS = Path(__file__).resolve().parent
#: the project root
ROOT = TESTS.parent
#: the project's own scenes (scenes/)
SCENES = ROOT / "scenes"
#: A red sphere lit head-on (SPEC A.1-A.6): the smallest scene that renders something.
RED_SPHERE = """PerspectiveCamera { center 0 0 5 direction 0 0 -1 up 0 1 0 angle 30 }
Lights { numLights 1 DirectionalLight { direction 0 0 -1 color 1 1 1 } }
Background { color 0 0 0 ambientLight 0.1 0.1 0.1 }
Materials { numMaterials 1 Material { diffuseColor 1 0 0 } }
Group { numObjects 1 MaterialIndex 0 Sphere { center 0 0 0 radius 1 } }
"""


class FakeClock:
    """A clock the test moves by hand (``clock.now += dt``), for code that takes a ``clock`` callable."""

    def __init__(self, now: float = 100.0) -> None:
        self.now = now

    def __call__(self) -> float:
        return self.now


@contextmanager
def small_tmpfs(tmp_path: Path, size: str) -> Iterator[Path]:
    """A tmpfs of ``size`` (``mount -o size=``, e.g. ``"64k"``) mounted at ``tmp_path/fs`` for a full-disk test,
    unmounted afterwards; the test is skipped where it cannot be mounted (root only)."""
    if os.geteuid() != 0:
        pytest.skip("mounting a tmpfs needs root")
    mnt = tmp_path / "fs"
    mnt.mkdir()
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(mnt)], capture_output=True)
    if r.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {r.stderr.decode().strip()}")
    try:
        yield mnt
    finally:
        subprocess.run(["umount", "-l", str(mnt)], check=False)


def sandbox_class_root(tmp_path_factory: pytest.TempPathFactory, name: str) -> Path:
    """A fresh folder for a graded class, opened (0755) together with the pytest folders above it, so the
    sandbox's user id reaches the submissions."""
    root = tmp_path_factory.mktemp(name)
    for p in (root, *root.parents):
        if str(p).startswith("/tmp/pytest-of"):
            p.chmod(0o755)
    return root


def write_image(path: Path, pixels: np.ndarray) -> Path:
    """Write an (H, W, C) uint8 array with OpenImageIO (row 0 = top)."""
    import OpenImageIO as oiio

    h, w, c = pixels.shape
    out = oiio.ImageOutput.create(str(path))
    assert out is not None, oiio.geterror()
    assert out.open(str(path), oiio.ImageSpec(w, h, c, "uint8"))
    assert out.write_image(np.ascontiguousarray(pixels))
    out.close()
    return path


def read_bmp24(path: Path) -> np.ndarray:
    """Independent 24-bit BMP reader: bottom-up rows padded to 4 bytes, BGR -> (H, W, 3) RGB, top row first."""
    raw = path.read_bytes()
    assert raw[:2] == b"BM"
    (offset,) = struct.unpack_from("<I", raw, 10)
    width, height, _, bpp = struct.unpack_from("<iiHH", raw, 18)
    assert bpp == 24
    stride = (width * 3 + 3) & ~3
    rows = [np.frombuffer(raw, np.uint8, width * 3, offset + r * stride).reshape(width, 3) for r in range(abs(height))]
    img = np.stack(rows)[:, :, ::-1]
    return img[::-1] if height > 0 else img


def render_text(text: str, path: str = "<string>", **options: Any) -> np.ndarray:
    """a5 scene ``text`` (positions and relative file names as if it were the file ``path``) rendered in-process
    with ``RenderOptions(**options)``: the float image as :func:`a5mi.render.session.render` returns it (row 0
    at the top, before quantisation). The JIT variant must be active: use the ``render_text`` fixture."""
    from a5mi.converters.a5_parser import parse_text
    from a5mi.converters.describe import describe
    from a5mi.render.options import RenderOptions
    from a5mi.render.session import render

    return np.asarray(render(describe(parse_text(text, path)), RenderOptions(**options)).image)


def files_under(root: Path) -> dict[str, bytes]:
    """Every path below ``root`` -> its bytes (``b""`` for a folder or a symlink): a snapshot to compare."""
    return {str(p.relative_to(root)): (p.read_bytes() if p.is_file() and not p.is_symlink() else b"")
            for p in sorted(root.rglob("*"))}


def one_error_line(capsys: pytest.CaptureFixture[str]) -> str:
    """What a command printed on stderr, asserted to be one line and no traceback (docs/GUARANTEES.md); the line."""
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


def refused(capsys: pytest.CaptureFixture[str], root: Path, run: Callable[[list[str]], int], argv: list[str]) -> str:
    """``run(argv)`` (``a5mi.cli.run`` for ``a5``, ``run_a5mi``) refuses (docs/GUARANTEES.md): exit status 2, one
    line on stderr (:func:`one_error_line`), every file below ``root`` as it was (:func:`files_under`); the line."""
    before = files_under(root)
    assert run(argv) == 2
    line = one_error_line(capsys)
    assert files_under(root) == before
    return line


def converted_material(text: str) -> tuple[Any, dict[str, Any], dict[str, Any], list[str]]:
    """The first material of a5 scene ``text`` (read as ``scenes/x.txt``, so its files resolve in :data:`SCENES`)
    through the converter with ``stock=True``: its model value, its a5 and stock BSDF dicts (on a shape with uv)
    and the description's warnings."""
    from a5mi.converters.a5_parser import parse_text
    from a5mi.converters.describe import describe
    from a5mi.converters.materials import a5_bsdf, stock_bsdf

    model = parse_text(text, str(SCENES / "x.txt"))
    desc = describe(model, stock=True)
    material = desc.materials[0]
    return model.materials[0], a5_bsdf(material, True), stock_bsdf(material, True), [w for _, w in desc.warnings]

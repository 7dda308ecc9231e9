"""Mitsuba's ``.vol`` binary grid format (docs/EXTENSIONS.md E.9): reader and writer, numpy only.

Little-endian, no padding::

    bytes  0-2   'V' 'O' 'L'
    byte   3     version = 3
    int32        encoding = 1 (float32; the only one Mitsuba 3 reads and the only one written here)
    int32 x3     xres, yres, zres (each >= 1)
    int32        channels (1 for a density grid)
    float32 x6   bounding box xmin ymin zmin xmax ymax zmax (informative: Mitsuba 3 and a5mi place the grid
                 with the scene's ``to_world`` / the ``Volume``'s ``min``/``max`` instead)
    float32 x (xres·yres·zres·channels)   values, x fastest: index ((z·yres + y)·xres + x)·channels + c

The array form used in a5mi is ``(zres, yres, xres, channels)`` float32 (C order), the layout of
``mi.VolumeGrid`` and of the ``data`` tensor of Mitsuba's ``gridvolume``. Values sit at the cell centres
``((x + ½)/xres, (y + ½)/yres, (z + ½)/zres)`` of the unit cube and are interpolated trilinearly, clamped at
the border (``gridvolume``'s lookup, which a5mi uses too).
"""

from __future__ import annotations

import os
import re
import struct
import tempfile
from pathlib import Path

import numpy as np

HEADER = struct.Struct("<3sBi3ii6f")
#: Largest grid read (cells x channels): 2^28 floats = 1 GiB.
MAX_VALUES = 1 << 28


class VolFormatError(ValueError):
    """A file that is not a readable ``.vol`` grid; ``reason`` says why."""

    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason


def decode(data: bytes) -> np.ndarray:
    """The ``(z, y, x, channels)`` float32 array of a ``.vol`` file's bytes (module docstring). Raises
    :class:`VolFormatError` for a wrong magic, version or encoding, a bad resolution, or a size that does
    not match the header."""
    if len(data) < HEADER.size:
        raise VolFormatError(f"{len(data)} bytes is shorter than the {HEADER.size}-byte .vol header")
    magic, version, encoding, xres, yres, zres, channels, *_bbox = HEADER.unpack_from(data)
    if magic != b"VOL":
        raise VolFormatError("does not start with 'VOL'")
    if version != 3:
        raise VolFormatError(f"version {version}, expected 3")
    if encoding != 1:
        raise VolFormatError(f"encoding {encoding}, expected 1 (float32)")
    if min(xres, yres, zres, channels) < 1:
        raise VolFormatError(f"resolution {xres} x {yres} x {zres} with {channels} channels")
    count = xres * yres * zres * channels
    if count > MAX_VALUES:
        raise VolFormatError(f"{count} values is more than the {MAX_VALUES} read")
    expected = HEADER.size + 4 * count
    if len(data) != expected:
        raise VolFormatError(f"{len(data)} bytes, expected {expected} for {xres} x {yres} x {zres} x {channels}")
    values = np.frombuffer(data, dtype="<f4", count=count, offset=HEADER.size)
    return values.astype(np.float32).reshape(zres, yres, xres, channels)


def read_vol(path: str | Path) -> np.ndarray:
    """:func:`decode` of the file at ``path``."""
    return decode(Path(path).read_bytes())


def encode(grid: np.ndarray, bbox: tuple[float, ...] = (0.0, 0.0, 0.0, 1.0, 1.0, 1.0)) -> bytes:
    """The ``.vol`` bytes of a ``(z, y, x)`` or ``(z, y, x, channels)`` array (float32)."""
    a = np.asarray(grid, dtype=np.float32)
    if a.ndim == 3:
        a = a[..., None]
    if a.ndim != 4 or min(a.shape) < 1:
        raise ValueError(f"a .vol grid is (z, y, x[, channels]) with every size >= 1, got shape {a.shape}")
    zres, yres, xres, channels = a.shape
    return HEADER.pack(b"VOL", 3, 1, xres, yres, zres, channels, *map(float, bbox)) + a.astype("<f4").tobytes()


def write_vol(path: str | Path, grid: np.ndarray, bbox: tuple[float, ...] = (0.0, 0.0, 0.0, 1.0, 1.0, 1.0)) -> None:
    """Write :func:`encode` to ``path`` atomically (a temporary file beside it, then ``os.replace``)."""
    target = Path(path)
    payload = encode(grid, bbox)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", dir=target.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(payload)
        os.replace(tmp, target)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


# ------------------------------------------------------------------------------ a grid per frame (E.11, E.22)
#: A printf integer conversion in a grid name: ``%d``, ``%3d``, ``%03d``.
_FRAME = re.compile(r"%(0?\d{0,2})d")


def is_pattern(name: str) -> bool:
    """True when ``name`` holds exactly one ``%d`` / ``%0Nd`` (a grid per frame, ``smoke_%03d.vol``)."""
    return len(_FRAME.findall(name)) == 1


def frame_name(name: str, frame: int) -> str:
    """``name`` with its ``%0Nd`` replaced by ``frame`` (printf's rule: ``smoke_%03d.vol``, 7 ->
    ``smoke_007.vol``); a name without one is returned as it is."""
    if not is_pattern(name):
        return name
    return _FRAME.sub(lambda m: f"%{m.group(1)}d" % frame, name)

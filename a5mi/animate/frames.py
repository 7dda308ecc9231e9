"""Frame files of ``a5mi animate`` (docs/EXTENSIONS.md E.11): atomic images with a checksum beside each.

Frame ``i`` is ``FRAMES_DIR/frame_{i:05d}.png``, written atomically (:func:`a5mi.platform.imageio.write_image`: a
temporary file, then ``os.replace``), and then ``frame_{i:05d}.png.sha256`` (``sha256sum`` format, also
atomic). A frame is **done** when both files exist and the image's SHA-256 is the one recorded; anything else
(no image, no checksum, a checksum that does not match: a damaged or foreign file) is rendered again by
``--resume``. A process killed at any point leaves no partial file under a frame's name.
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Iterable
from pathlib import Path

import numpy.typing as npt

from a5mi.platform import imageio, paths

EXTENSION = ".png"


def frame_path(folder: str | os.PathLike[str], frame: int) -> Path:
    """``folder/frame_NNNNN.png``."""
    return Path(folder) / f"frame_{frame:05d}{EXTENSION}"


def checksum_path(image: Path) -> Path:
    """The checksum file beside ``image``: ``NAME.sha256``."""
    return image.with_name(image.name + ".sha256")


def sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def write_frame(folder: str | os.PathLike[str], frame: int, image: npt.ArrayLike) -> Path:
    """Write frame ``frame`` (row 0 = top) and then its checksum, each atomically; returns the image path."""
    p = frame_path(folder, frame)
    imageio.write_image(p, image)
    with imageio.atomic_file(checksum_path(p), "w") as f:
        f.write(f"{sha256(p)}  {p.name}\n")
    return p


def frame_done(folder: str | os.PathLike[str], frame: int) -> bool:
    """True when the frame's image and checksum exist and agree (module docstring)."""
    p = frame_path(folder, frame)
    try:
        recorded = checksum_path(p).read_text(encoding="utf-8").split()
        return bool(recorded) and recorded[0] == sha256(p)
    except (OSError, UnicodeDecodeError):
        return False


def missing_frames(folder: str | os.PathLike[str], frames: Iterable[int]) -> list[int]:
    """The frames of ``frames`` that are not done (missing or damaged), in order; the temporaries that a
    killed process left for them are removed (:func:`a5mi.platform.paths.remove_stale`)."""
    out = []
    for f in frames:
        p = frame_path(folder, f)
        paths.remove_stale(folder, p.name)
        paths.remove_stale(folder, checksum_path(p).name)
        if not frame_done(folder, f):
            out.append(f)
    return out


def chunks(frames: list[int], count: int) -> list[tuple[int, ...]]:
    """``frames`` (sorted) cut into at most ``count`` chunks of consecutive frame numbers, as even as possible:
    a worker renders a chunk in order with its warm scene."""
    runs: list[list[int]] = []
    for f in frames:
        if runs and runs[-1][-1] == f - 1:
            runs[-1].append(f)
        else:
            runs.append([f])
    size = max(1, -(-len(frames) // max(1, count)))
    return [tuple(run[i:i + size]) for run in runs for i in range(0, len(run), size)]

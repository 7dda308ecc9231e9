"""Outputs never destroy inputs or each other, for every command (docs/GUARANTEES.md).

Every file a command writes is compared, before anything is rendered, with every file the scene reads (the
scene itself, its OBJ meshes, textures and cube-map faces) and with the other outputs, by resolved path
(``os.path.realpath``: symlinked folders, ``..``) and, for files that exist, by device and inode (hard links,
bind mounts). A conversion's meshes folder must not hold an input either (it is replaced whole).
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

from a5mi.platform.errors import UsageError


def input_files(desc: Any) -> list[Path]:
    """The files a scene description was built from: the scene, OBJ files, textures, cube-map faces."""
    out = [Path(desc.path)]
    for shape in getattr(desc, "shapes", ()):
        obj = getattr(shape, "obj_file", None)
        if obj is not None:
            out.append(Path(obj))
    for mat in getattr(desc, "materials", ()):
        for image in (getattr(mat, "texture", None), getattr(mat, "kd", None)):
            if image is not None and hasattr(image, "path") and hasattr(image, "pixels"):
                out.append(Path(image.path))
    for face in getattr(getattr(desc, "background", None), "faces", ()) or ():
        if hasattr(face, "path"):
            out.append(Path(face.path))
    return list(dict.fromkeys(out))


def _identity(path: str | os.PathLike[str]) -> tuple[str, tuple[int, int] | None]:
    real = os.path.realpath(path)
    try:
        st = os.stat(real)
        return real, (st.st_dev, st.st_ino)
    except OSError:
        return real, None


def same_file(a: str | os.PathLike[str], b: str | os.PathLike[str]) -> bool:
    """True when ``a`` and ``b`` name the same file: same resolved path, or same device and inode."""
    (ra, ia), (rb, ib) = _identity(a), _identity(b)
    return ra == rb or (ia is not None and ia == ib)


def check_outputs(outputs: Sequence[tuple[str, str | os.PathLike[str]]], inputs: Iterable[str | os.PathLike[str]],
                  of: str = " of the scene") -> None:
    """Raise :class:`UsageError` when an output (``(flag, path)``) is an input or another output; ``of`` ends
    the words "is the input file '...'" (what the inputs belong to)."""
    ins = list(inputs)
    for k, (role, path) in enumerate(outputs):
        for other_role, other in outputs[:k]:
            if same_file(path, other):
                raise UsageError(f"{other_role} '{other}' and {role} '{path}' are the same file")
        for src in ins:
            if same_file(path, src):
                raise UsageError(f"{role} '{path}' is the input file '{src}'{of}: it would be overwritten")


def check_folder_holds_no_input(role: str, folder: str | os.PathLike[str],
                                inputs: Iterable[str | os.PathLike[str]]) -> None:
    """Raise :class:`UsageError` when an input lies inside ``folder`` (which is about to be replaced)."""
    root = os.path.realpath(folder)
    for src in inputs:
        real = os.path.realpath(src)
        if real == root or real.startswith(root.rstrip(os.sep) + os.sep):
            raise UsageError(f"{role} '{folder}' holds the input file '{src}' of the scene: it would be replaced")


__all__ = ["check_folder_holds_no_input", "check_outputs", "input_files", "same_file"]

"""Another a5 program on the live page (``a5mi view --binary``, docs/VIEW.md): the SPEC B.1 flags it is given,
and the files it may see: every file the scene names, linked into a fresh folder, nothing else of the scene's
folder or the working directory."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from a5mi.render.options import RenderOptions


def scene_inputs(desc: Any, model: Any) -> list[Path]:
    """Every file the description read or names (:func:`a5mi.platform.clobber.input_files`), and the texture names of
    the model resolved both ways (scene folder first, then the working directory), absolute."""
    from a5mi.platform.clobber import input_files

    out = [Path(p).absolute() for p in input_files(desc)]
    for mat in getattr(model, "materials", None) or ():
        tex = getattr(mat, "texture", None)
        if tex:
            out += [(Path(model.base_dir) / tex).absolute(), (Path.cwd() / tex).absolute()]
    return list(dict.fromkeys(out))


def binary_argv(options: RenderOptions) -> list[str]:
    """The SPEC B.1 flags of ``options`` for another a5 binary (the extensions are a5mi's own)."""
    argv = ["-size", str(options.width), str(options.height), "-bounces", str(options.bounces)]
    argv += ["-shadows"] * options.shadows + ["-jitter"] * options.jitter + ["-filter"] * options.filter
    argv += ["-reflection_off"] * (not options.reflection) + ["-refraction_off"] * (not options.refraction)
    return argv


def staged_links(folder: Path, named: list[Path], roots: tuple[Path, ...]) -> tuple[str, ...]:
    """Link each existing regular file of ``named`` into ``folder`` at its path relative to the first of
    ``roots`` it lies under (a name leaving ``folder`` through ``..`` is skipped); the resolved files, the
    only paths the sandbox binds for them."""
    out: list[str] = []
    top = folder.resolve()
    for path in named:
        for root in roots:
            try:
                rel = path.relative_to(root)
            except ValueError:
                continue
            real = path.resolve()
            dst = folder / rel
            if not real.is_file() or not dst.resolve().is_relative_to(top) or dst.exists() or dst.is_symlink():
                break
            dst.parent.mkdir(parents=True, exist_ok=True)
            os.symlink(real, dst)
            out.append(str(real))
            break
    return tuple(dict.fromkeys(out))

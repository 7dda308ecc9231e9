"""a5mi: the MIT 6.837 Assignment 5 ray tracer as Mitsuba 3 plugins.

Data flows one way: scene text -> :mod:`a5mi.converters` (tokens, typed model, scene description, Mitsuba
dict) -> :mod:`a5mi.render.session` (``mi.load_dict``: :mod:`a5mi.plugins` objects, the integrator, BSDFs, textures,
emitters) -> :mod:`a5mi.render.driver` (camera rays, jitter, tiles, filter) -> :mod:`a5mi.platform.imageio` (image
file). Only
:mod:`a5mi.cli` prints.
"""

from __future__ import annotations

import os
from pathlib import Path

__version__ = "0.1.0"

PROJECT_ROOT = Path(__file__).resolve().parent.parent


def cache_dir() -> Path:
    """Where a5mi keeps files it can always recompute (deleting the folder costs only time; each module that
    writes there names its own file or sub-folder): ``$A5MI_CACHE_DIR``, else ``$XDG_CACHE_HOME/a5mi``, else
    ``~/.cache/a5mi``."""
    env = os.environ.get("A5MI_CACHE_DIR")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "a5mi"


#: The page and section that say what the course data is, where it comes from and how to point a5mi at it.
DATA_DOC = 'docs/INSTALL.md "The course data"'


def data_candidates() -> list[Path]:
    """Where the course data (SPEC.md, scenes/, reference/) is looked for, in order: ``$A5_DATA`` alone when
    it is set; else ``../shared/a5`` beside the project checkout (when a5mi runs from one), then
    ``./shared/a5`` and ``../shared/a5`` from the working directory."""
    env = os.environ.get("A5_DATA")
    if env:
        return [Path(env).expanduser().resolve()]
    out = []
    if (PROJECT_ROOT / "pyproject.toml").is_file():
        out.append((PROJECT_ROOT.parent / "shared" / "a5").resolve())
    out += [(Path.cwd() / "shared" / "a5").resolve(), (Path.cwd().parent / "shared" / "a5").resolve()]
    return list(dict.fromkeys(out))


def data_dir() -> Path:
    """The course data folder: the first of :func:`data_candidates` holding ``SPEC.md`` (else the first)."""
    candidates = data_candidates()
    return next((c for c in candidates if (c / "SPEC.md").is_file()), candidates[0])


def require_data_dir() -> Path:
    """:func:`data_dir` if it holds the course data (``SPEC.md``), else a :class:`~a5mi.platform.errors.UserError`
    naming where it looked, ``A5_DATA`` and :data:`DATA_DOC`."""
    from a5mi.platform.errors import UserError

    root = data_dir()
    if not (root / "SPEC.md").is_file():
        looked = ", ".join(str(c) for c in data_candidates())
        raise UserError(f"course data not found (looked in {looked}); set A5_DATA to the folder holding SPEC.md "
                        f"(see {DATA_DOC})")
    return root

"""a5mi: the MIT 6.837 Assignment 5 ray tracer as Mitsuba 3 plugins.

Data flows one way: scene text -> :mod:`a5mi.converters` (tokens, typed model, Mitsuba dict) ->
:mod:`a5mi.plugins` (integrator, BSDF, textures, emitters) -> :mod:`a5mi.driver` (camera rays, jitter,
filter) -> :mod:`a5mi.imageio` (image file). Only :mod:`a5mi.cli` prints.
"""

from __future__ import annotations

import os
from pathlib import Path

__version__ = "0.1.0"

PROJECT_ROOT = Path(__file__).resolve().parent.parent


def data_dir() -> Path:
    """The course data (SPEC, scenes, references): ``$A5_DATA``, else ``../shared/a5`` beside the project."""
    env = os.environ.get("A5_DATA")
    if env:
        return Path(env).resolve()
    return (PROJECT_ROOT.parent / "shared" / "a5").resolve()


def require_data_dir() -> Path:
    """:func:`data_dir` if it holds the course data (``SPEC.md``), else a :class:`~a5mi.errors.UserError`
    naming where it looked and ``A5_DATA``."""
    from a5mi.errors import UserError

    root = data_dir()
    if not (root / "SPEC.md").is_file():
        how = "$A5_DATA" if os.environ.get("A5_DATA") else "../shared/a5 beside the project"
        raise UserError(f"course data not found at {root} ({how}); set A5_DATA to the folder holding SPEC.md")
    return root

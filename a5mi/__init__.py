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

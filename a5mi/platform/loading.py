"""Mitsuba objects from a dict or an XML file, built on the calling thread (docs/MITSUBA.md "Loading in parallel").

Mitsuba 3.9 loads in parallel unless told otherwise: every object of the dict or XML becomes a task of Dr.Jit's
thread pool, its constructor run on a worker once its children exist. The a5 plugins are safe there (no
constructor of theirs loads anything: a load swaps Mitsuba's global file resolver, which the other tasks read;
tests/plugins/materials/test_a5_material.py loads a scene of many materials in parallel). a5mi itself builds on
one thread all the same (``parallel=False``): the a5 constructors are Python and take the GIL one at a time, and
on a5mi's dicts the parallel load gains nothing measurable (BENCHMARKS.md "Loading").

Every load of a5mi goes through :func:`load_dict` or :func:`load_file` (tests/platform/test_loading.py checks the
source), with signals held back for the native call (:func:`a5mi.platform.interrupts.deferred`: the plugin
constructors run inside Mitsuba's C++ loader).

A leaf module: it imports :mod:`a5mi.platform.interrupts` and, when called, Mitsuba.
"""

from __future__ import annotations

import os
from typing import Any

from a5mi.platform import interrupts


def load_dict(entry: dict[str, Any]) -> Any:
    """``mi.load_dict(entry, parallel=False)``: a scene, or one object (an integrator, a texture, a sampler)."""
    import mitsuba as mi

    with interrupts.deferred():
        return mi.load_dict(entry, parallel=False)


def load_file(path: str | os.PathLike[str], **defaults: Any) -> Any:
    """``mi.load_file(path, parallel=False, **defaults)``: ``defaults`` set the XML's ``<default>`` parameters
    (``$name``); Mitsuba's file resolver looks beside the XML first while it loads."""
    import mitsuba as mi

    with interrupts.deferred():
        return mi.load_file(os.fspath(path), parallel=False, **defaults)


__all__ = ["load_dict", "load_file"]

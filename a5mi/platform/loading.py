"""Mitsuba objects from a dict or an XML file, built on the calling thread (docs/MITSUBA.md "Load on one thread").

Mitsuba 3.9 loads with ``parallel=True`` unless told otherwise: every object of the dict or XML becomes a task of
Dr.Jit's thread pool, its constructor run on a worker once its children exist. The a5 plugins' constructors are
Python (each takes the GIL on its worker), and a thread that waits inside a constructor (for a kernel, for the
GIL) runs other objects' construction tasks meanwhile (nanothread's ``task_wait`` helps with any queued task).
A plain script loading a converted XML that way failed natively in a5mi's suite: ``failed to instantiate
rfilter plugin of type "box": std::bad_alloc``, once ``basic_string::_M_create``, never when run alone
(BENCHMARKS.md "Loading"). ``parallel=False`` builds the objects one after the other on the calling thread,
children first, so no constructor runs beside another; its cost is in BENCHMARKS.md "Loading".

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

"""Optional dependencies: the modules a command needs beyond what ``a5`` needs, each from a pip extra.

``pip install a5mi`` installs what ``a5`` (and ``a5mi render``, ``convert``, ``compare``, ...) renders with:
Mitsuba, Dr.Jit, numpy and OpenImageIO. The extras add the rest (pyproject.toml
``[project.optional-dependencies]``):

* ``grade``: ``distributed`` (the Dask cluster), ``flip-evaluator`` (NVIDIA FLIP: ``a5mi grade``,
  ``a5mi compare --flip``), ``tqdm`` (progress bar);
* ``animate``: ``imageio-ffmpeg`` (``--video``), ``distributed`` (``--workers``/``--scheduler``), ``tqdm``;
* ``test``: both of those plus the test tools (pytest, pytest-xdist, hypothesis, ruff, playwright).

Every import of such a module goes through :func:`require`, so a missing one is the one-line user error
``a5mi grade: error: needs the 'grade' extra: pip install 'a5mi[grade]' (missing module distributed)``
(exit status 2), never a traceback.
"""

from __future__ import annotations

import importlib
from types import ModuleType

from a5mi.platform.errors import MissingExtraError


def require(module: str, extra: str) -> ModuleType:
    """``import module``, or raise :class:`~a5mi.platform.errors.MissingExtraError` naming ``extra`` when it (or a
    module it imports) is not installed. Any other import failure of an installed module propagates."""
    try:
        return importlib.import_module(module)
    except ModuleNotFoundError as exc:
        raise MissingExtraError(module=exc.name or module, extra=extra) from exc


__all__ = ["require"]

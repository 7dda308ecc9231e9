"""Reading and exposing plugin parameters, shared by the a5 plugins (SPEC B.2, B.4; docs/EXTENSIONS.md E.6).

:func:`vec3_param` reads a 3-number parameter (point, vector or rgb) from ``mi.Properties`` with the one error
wording of every plugin; :func:`put_params` hands a plugin's opaque values to ``traverse``.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Iterable, Sequence

import mitsuba as mi


def vec3_param(plugin: str, props: mi.Properties, name: str,
               default: Sequence[float] | None) -> tuple[float, float, float]:
    """``props[name]`` as three finite Python floats, or ``default`` when absent (required when ``None``);
    a ValueError naming ``plugin`` and the parameter otherwise."""
    if name not in props:
        if default is None:
            raise ValueError(f"{plugin}: parameter '{name}' is required")
        return (float(default[0]), float(default[1]), float(default[2]))
    value = props[name]
    try:
        out = (float(value[0]), float(value[1]), float(value[2]))
    except (TypeError, IndexError, ValueError):
        raise ValueError(f"{plugin}: parameter '{name}' must be 3 numbers, got {value!r}") from None
    if not all(math.isfinite(c) for c in out):
        raise ValueError(f"{plugin}: parameter '{name}' must be finite, got {out}")
    return out


def put_params(cb: mi.TraversalCallback, plugin: object, names: Iterable[str],
               differentiable: Collection[str] = ()) -> None:
    """``cb.put`` each attribute ``names`` of ``plugin`` in order: ``Differentiable`` for the names in
    ``differentiable``, ``NonDifferentiable`` for the rest."""
    for name in names:
        flags = mi.ParamFlags.Differentiable if name in differentiable else mi.ParamFlags.NonDifferentiable
        cb.put(name, getattr(plugin, name), flags)

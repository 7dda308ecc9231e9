"""Reading and exposing plugin parameters, shared by the a5 plugins (SPEC B.2, B.4; docs/EXTENSIONS.md E.6).

The typed readers take a parameter from ``mi.Properties`` with its default and check it, with the one error
wording of every plugin (``<plugin>: '<name>' must be ..., got <value>``): :func:`read_bool`, :func:`read_int`
(an integer ``>= low``), :func:`read_number` (a number in an interval), :func:`read_choice` (one of a list of
strings), :func:`read_rgb` (a colour or one grey value) and :func:`vec3_param` (a 3-number point, vector or
rgb). :func:`put_params` hands a plugin's opaque values to ``traverse``.
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


def read_bool(plugin: str, props: mi.Properties, name: str, default: bool) -> bool:
    """``props[name]`` (``default`` when absent), which must be a boolean."""
    value = props.get(name, default)
    if not isinstance(value, bool):
        raise ValueError(f"{plugin}: '{name}' must be a boolean, got {value!r}")
    return value


def read_int(plugin: str, props: mi.Properties, name: str, default: int, low: int) -> int:
    """``props[name]`` (``default`` when absent), which must be an integer ``>= low`` (a boolean is not)."""
    value = props.get(name, default)
    if isinstance(value, bool) or not isinstance(value, int) or value < low:
        raise ValueError(f"{plugin}: '{name}' must be an integer >= {low}, got {value!r}")
    return value


def read_number(plugin: str, props: mi.Properties, name: str, default: float, low: float = 0.0,
                high: float = math.inf, *, open_low: bool = False, closed_high: bool = False) -> float:
    """``props[name]`` (``default`` when absent) as a float in ``[low, high)``; ``open_low`` excludes ``low``,
    ``closed_high`` includes ``high`` (never infinity: ``high = inf`` means a finite number)."""
    value = props.get(name, default)
    ok = not isinstance(value, bool) and isinstance(value, (int, float)) and math.isfinite(value)
    if ok:
        ok = (low < value if open_low else low <= value) and (value <= high if closed_high else value < high)
    if not ok:
        if math.isinf(high):
            wanted = f"a finite number {'>' if open_low else '>='} {low:g}"
        else:
            wanted = f"a number in {'(' if open_low else '['}{low:g}, {high:g}{']' if closed_high else ')'}"
        raise ValueError(f"{plugin}: '{name}' must be {wanted}, got {value!r}")
    return float(value)


def read_choice(plugin: str, props: mi.Properties, name: str, default: str, choices: Sequence[str]) -> str:
    """``props[name]`` (``default`` when absent), which must be one of ``choices``."""
    value = props.get(name, default)
    if value not in choices:
        raise ValueError(f"{plugin}: '{name}' must be one of {', '.join(choices)}, got {value!r}")
    return str(value)


def read_names(plugin: str, props: mi.Properties, name: str, allowed: Sequence[str], what: str) -> set[str]:
    """``props[name]``, a comma-separated string (empty when absent), as the set of its names, each of which must
    be one of ``allowed`` (``what`` names them in the error: ``'aovs' must list groups of ...``)."""
    value = props.get(name, "")
    names = {n.strip() for n in value.split(",") if n.strip()} if isinstance(value, str) else None
    if names is None or not names <= set(allowed):
        raise ValueError(f"{plugin}: '{name}' must list {what} of {', '.join(allowed)}, got {value!r}")
    return names


def read_rgb(plugin: str, props: mi.Properties, name: str, default: float = 0.0) -> list[float]:
    """``props[name]`` as three floats: an rgb colour, or one number for a grey (``default`` when absent)."""
    value = props.get(name, mi.ScalarColor3d(default))
    try:
        if isinstance(value, str):
            raise TypeError
        return [float(value)] * 3 if isinstance(value, (int, float)) else [float(value[i]) for i in range(3)]
    except (TypeError, IndexError, ValueError):
        raise ValueError(f"{plugin}: '{name}' must be an rgb colour, got {value!r}") from None


def put_params(cb: mi.TraversalCallback, plugin: object, names: Iterable[str],
               differentiable: Collection[str] = ()) -> None:
    """``cb.put`` each attribute ``names`` of ``plugin`` in order: ``Differentiable`` for the names in
    ``differentiable``, ``NonDifferentiable`` for the rest."""
    for name in names:
        flags = mi.ParamFlags.Differentiable if name in differentiable else mi.ParamFlags.NonDifferentiable
        cb.put(name, getattr(plugin, name), flags)

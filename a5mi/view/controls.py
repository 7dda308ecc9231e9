"""The flag controls of the live page: which :class:`~a5mi.render.options.RenderOptions` fields the page may set, and
the check of what it sends (SPEC B.1 flags, and the extension modes of docs/EXTENSIONS.md).

Each control is ``(field, kind, label, choices)``: ``int`` (with its bounds), ``bool`` or ``choice``. The page
posts ``{field: value}``; :func:`apply` checks every value as the command line's flag table would (an unknown
field, a value of the wrong type or out of range, a render too large for the memory: :class:`ControlError`)
and returns the options with those fields replaced.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from a5mi.platform.errors import UsageError
from a5mi.render.options import INTEGRATORS, RenderOptions
from a5mi.spec import FRESNEL_MODES, MAX_SIZE


class ControlError(UsageError):
    """A control value the page sent that the flags would refuse (one line)."""


#: field -> (kind, label, bounds or choices): the page's controls, in the page's order.
CONTROLS: dict[str, tuple[str, str, Any]] = {
    "width": ("int", "width (-size W)", (1, MAX_SIZE)),
    "height": ("int", "height (-size H)", (1, MAX_SIZE)),
    "bounces": ("int", "-bounces", (0, 64)),
    "shadows": ("bool", "-shadows", None),
    "jitter": ("bool", "-jitter", None),
    "filter": ("bool", "-filter", None),
    "reflection": ("bool", "reflection (off: -reflection_off)", None),
    "refraction": ("bool", "refraction (off: -refraction_off)", None),
    "integrator": ("choice", "-integrator", tuple(INTEGRATORS)),
    "fresnel": ("choice", "-fresnel", FRESNEL_MODES),
    "phong": ("bool", "-phong", None),
    "bump": ("bool", "-bump", None),
    "spp": ("int", "-spp", (1, 65536)),
    "indirect": ("int", "-indirect (whitted)", (0, 4096)),
    "rr_depth": ("int", "-rr_depth (path)", (0, 1 << 16)),
}


def describe_controls(options: RenderOptions) -> list[dict[str, Any]]:
    """The controls as JSON for the page, each with the value of ``options``."""
    out = []
    for name, (kind, label, extra) in CONTROLS.items():
        item: dict[str, Any] = {"name": name, "kind": kind, "label": label, "value": getattr(options, name)}
        if kind == "int":
            item["min"], item["max"] = extra
        elif kind == "choice":
            item["choices"] = list(extra)
        out.append(item)
    return out


def _value(name: str, value: Any) -> Any:
    kind, _, extra = CONTROLS[name]
    if kind == "bool":
        if not isinstance(value, bool):
            raise ControlError(f"{name}: expected true or false, found {value!r:.40}")
        return value
    if kind == "int":
        if isinstance(value, bool) or not isinstance(value, int):
            raise ControlError(f"{name}: expected an integer, found {value!r:.40}")
        lo, hi = extra
        if not lo <= value <= hi:
            raise ControlError(f"{name}: {value} is outside {lo}..{hi}")
        return value
    if value not in extra:
        raise ControlError(f"{name}: expected one of {', '.join(extra)}, found {value!r:.40}")
    return value


def apply(options: RenderOptions, values: Any) -> RenderOptions:
    """``options`` with the page's ``values`` (a JSON object) applied, checked (module docstring): each value by
    its control's range, then the options together by the command line's own check
    (:func:`a5mi.render.limits.check_options`: the sample budget, ``-indirect`` with ``-bounces``, ``-filter``'s
    minimum size, the memory of the render and of the integrator's buffers)."""
    from a5mi.render import limits

    if not isinstance(values, dict):
        raise ControlError("expected a JSON object of control values")
    unknown = sorted(set(values) - set(CONTROLS))
    if unknown:
        raise ControlError(f"unknown control '{unknown[0][:40]}'")
    new = dataclasses.replace(options, **{k: _value(k, v) for k, v in values.items()})
    try:
        limits.check_options(new)
    except UsageError as exc:
        raise ControlError(str(exc)) from None
    return new


__all__ = ["CONTROLS", "ControlError", "apply", "describe_controls"]

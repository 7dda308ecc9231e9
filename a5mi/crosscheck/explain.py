"""Explaining ``stock path − exact Whitted`` term by term, each term isolated by a render (``--explain``)."""


from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from a5mi.crosscheck.core import (
    GLASS,
    NO_RR_DEPTH,
    OPAQUE,
    CrosscheckOptions,
    _description,
    _render_options,
    path_dict,
    pixel_classes,
    render_path,
    render_whitted,
)
from a5mi.platform.loading import load_dict
from a5mi.spec import TMIN

# --------------------------------------------------------------------------------------------------------
# Explaining the difference to path: one term per render
# --------------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ExplainTerm:
    """One term of ``stock path − exact Whitted``: mean signed levels per region (glass, other surfaces)."""

    term: str
    isolated_by: str
    glass: float
    other: float


def explain(desc_or_model: Any, options: CrosscheckOptions) -> list[ExplainTerm]:
    """Split ``stock path − exact Whitted`` into terms that add up exactly, each isolated by a render.

    With A = exact Whitted, B = A without ambient, C = B with light colours ÷ π, F = C without lamps,
    D = the physically based reading of the a5 scene (docs/EXTENSIONS.md E.13) rendered by ``a5_path``
    (``-fresnel exact``, no Russian roulette; Mitsuba's ``path`` on the a5-plugin scene when the scene has a
    medium, which E.13 does not read), E = D without lamps, G = ``path`` on the ``--stock`` conversion::

        G − A = (G − D) + (B − A) + (C − B) + (E − F) + ((D − C) − (E − F))

    i.e. stock-conversion approximations, the ambient term, Lambert's 1/π, environment light on diffuse
    surfaces, and indirect light from the lamps (plus what remains). Means over the glass and the other
    surface pixels of :func:`pixel_classes` (background excluded), in 8-bit levels (unquantised).
    """
    import dataclasses

    from a5mi.converters.to_mitsuba import to_dict

    desc = _description(desc_or_model)
    ro = _render_options(options)
    a5d = to_dict(desc, ro)
    stock = to_dict(desc, ro, stock=True)
    cam = desc.camera
    integ = dict(a5d["integrator"])

    def whitted(d: Mapping[str, Any], integrator: Mapping[str, Any]) -> npt.NDArray[np.float64]:
        return render_whitted(load_dict(dict(d)), cam, integrator, options, "exact").astype(np.float64) * 255

    def path(d: Mapping[str, Any]) -> npt.NDArray[np.float64]:
        img, _ = render_path(load_dict(path_dict(d, options)), cam, options.width, options.height,
                             options.spp, options.path_max_depth, seed=options.seed + 1)
        return img.astype(np.float64) * 255

    def reading(d: Mapping[str, Any]) -> npt.NDArray[np.float64]:
        """E.13 by ``a5_path`` (the a5 dict's integrator entry carries the planes), through the pixel centres."""
        from a5mi.render.driver import render_scene
        from a5mi.render.options import RenderOptions

        if str(d["integrator"].get("medium", "none")) != "none":
            return path(d)
        whitted_only = ("medium_bounces", "subsurface", "indirect")  # a5_whitted's modes, not a5_path parameters
        entry = {**{k: v for k, v in d["integrator"].items() if k not in whitted_only}, "type": "a5_path",
                 "max_depth": options.bounces, "rr_depth": NO_RR_DEPTH,
                 "fresnel": "exact", "aovs": ""}
        ro = RenderOptions(width=options.width, height=options.height, bounces=options.bounces, spp=options.spp,
                           seed=options.seed + 1, integrator="path", fresnel="exact", bump=options.bump)
        scene = load_dict({**d, "integrator": entry})
        return render_scene(scene, cam, ro, integrator=scene.integrator()).image.astype(np.float64) * 255

    no_ambient = dict(integ, ambient={"type": "rgb", "value": [0.0, 0.0, 0.0]})
    # The lights' colours divided by pi (C), and no lights at all (E, F); the ambient term stays as described.
    dimmed = to_dict(dataclasses.replace(desc, lights=tuple(
        dataclasses.replace(light, color=tuple(v / math.pi for v in light.color)) for light in desc.lights)), ro)
    no_lamps = to_dict(dataclasses.replace(desc, lights=()), ro)
    a, b = whitted(a5d, integ), whitted(a5d, no_ambient)
    c, f = whitted(dimmed, no_ambient), whitted(no_lamps, no_ambient)
    d, e, g = reading(a5d), reading(no_lamps), path(stock)
    classes = pixel_classes(load_dict(a5d), cam, options.width, options.height, options.bounces,
                            tmin=float(integ.get("tmin", TMIN)), integrator=integ)

    def term(name: str, how: str, x: npt.NDArray[np.float64]) -> ExplainTerm:
        glass, other = classes == GLASS, classes == OPAQUE
        return ExplainTerm(name, how, float(x[glass].mean()) if glass.any() else 0.0,
                           float(x[other].mean()) if other.any() else 0.0)

    return [
        term("stock-conversion approximations", "stock path - E.13 reading (a5_path)", g - d),
        term("no ambient term in path", "Whitted with ambient 0", b - a),
        term("Lambert kd/pi against a5's kd", "Whitted with light colours / pi", c - b),
        term("environment light on diffuse surfaces", "path - Whitted, both without lamps", e - f),
        term("indirect light from the lamps, and the rest", "remainder", (d - c) - (e - f)),
        term("total: stock path - exact", "", g - a),
    ]


def explain_table(terms: Sequence[ExplainTerm]) -> str:
    """The terms of :func:`explain` as text (mean signed levels)."""
    lines = [f"{'term':<46}{'isolated by':<44}{'glass':>8}{'other':>8}"]
    lines += [f"{t.term:<46}{t.isolated_by:<44}{t.glass:>+8.1f}{t.other:>+8.1f}" for t in terms]
    return "\n".join(lines)

"""``a5mi crosscheck``: the a5 dielectric against textbook Schlick, exact Fresnel and Mitsuba's ``path``.

One scene, five passes, all through the **same camera rays** (SPEC B.2, pixel centres, no jitter), so every
difference is light transport, never sampling:

* ``a5``, ``schlick``, ``exact``: ``a5_whitted`` (SPEC B.3) with its three Fresnel modes
  (:func:`a5mi.plugins.optics.fresnel_weight`): ``R = R0 + (1 − R0)(1 − c)⁵`` with the binary's
  ``R0 = ((nt − 1)/(nt + 1))²`` or the textbook ``R0 = ((nt − n)/(nt + n))²``, or the unpolarised exact
  ``R = ½(r_s² + r_p²)`` of ``mi.fresnel`` (stock ``dielectric``);
* ``path``: the ``stock=True`` conversion rendered by Mitsuba's own ``path`` integrator, ``spp`` samples
  through each pixel centre, ``max_depth = bounces + 2`` (camera segment + ``bounces`` secondary segments +
  the light connection of the last hit, the longest path ``a5_whitted`` forms) and no Russian roulette;
* a class pass: ``a5_whitted``'s ``class`` AOV (computed inside the same SPEC B.3 ray-tree kernel, so the
  push rules are the colour's), rendered by :func:`a5mi.render.driver.render_scene`, marks each pixel as
  *background* (the camera ray misses), *opaque* (the tree never hits a material with
  ``refraction_index > 0``) or *glass* (some node of the tree hits one, the last level included).

The three Fresnel modes can only differ where a refracted ray is pushed, so they agree **exactly** (bit for
bit) on every non-glass pixel; :func:`crosscheck` reports per pair the metrics of :mod:`a5mi.compare` over
the glass pixels and over all other pixels, in 8-bit levels as the images would be saved
(``byte = clamp(int(c·255))``, SPEC B.1), plus the signed ``bias = mean(B − A)``.
:func:`write_montage` draws ``a5 | schlick | exact | path`` with their error maps.

``path`` renders the physically based reading of the scene (docs/EXTENSIONS.md E.13: Lambert ``kd/π``, the
mirror lobe ``ks R``, the dielectric ``ks (1 − R)/η²``, lights as emitters, the environment as a light, no
ambient term), the one ``a5mi``'s own ``-integrator path`` (E.14) renders from ``plugins/kernel/pbr.py``; the
stock conversion agrees with it where ``kd + ks <= 1``, front faces are seen and the lights are directional or
the background (its point, spot and area lights are scaled to agree at the scene's centre only).

What separates ``path`` from Whitted (measured on scene10 in the README section "Cross-check against
physically based rendering"): the ``stock=True`` conversion's approximations (``converters/to_mitsuba.py``:
Noise -> mean colour, ``blendbsdf`` instead of a5's diffuse + mirror sum, inverse-square point lights); the
a5 ``ambient ⊙ diffuseColor`` term, which ``path`` drops; Lambert's ``kd/π`` against a5's ``kd`` for the same
light colour; environment light on diffuse surfaces (Whitted only shows the environment to rays that miss);
indirect diffuse light; and Mitsuba's dielectric scaling radiance by ``1/η²`` into glass and ``η²`` out of
it, which cancels on every path from an outside camera to an outside light. Shadows are always on here, as
``path`` cannot do otherwise.
"""

from __future__ import annotations

from a5mi.crosscheck.core import (
    BACKGROUND,
    FRESNEL_MODES,
    FRESNEL_SCALE,
    GLASS,
    LABELS,
    NO_RR_DEPTH,
    OPAQUE,
    PAIRS,
    PATH_LANES,
    CrosscheckOptions,
    CrosscheckResult,
    PairReport,
    _pixel_rays,
    crosscheck,
    crosscheck_dicts,
    levels,
    masked_metrics,
    pair_reports,
    path_dict,
    pixel_classes,
    render_path,
    render_whitted,
)
from a5mi.crosscheck.explain import ExplainTerm, explain, explain_table
from a5mi.crosscheck.report import error_scale, montage_image, table, to_json, write_montage

__all__ = [
    "BACKGROUND", "GLASS", "OPAQUE", "FRESNEL_MODES", "FRESNEL_SCALE", "LABELS", "NO_RR_DEPTH", "PAIRS",
    "PATH_LANES", "error_scale", "levels", "_pixel_rays",
    "CrosscheckOptions", "CrosscheckResult", "ExplainTerm", "PairReport",
    "crosscheck", "crosscheck_dicts", "explain", "explain_table", "masked_metrics", "montage_image",
    "pair_reports", "path_dict",
    "pixel_classes", "render_path", "render_whitted", "table", "to_json", "write_montage",
]


"""The ``subsurface`` block of a ``Material`` (docs/EXTENSIONS.md E.18): grammar, presets, the model value.

::

    subsurface { [preset NAME] [sigma_a V3] [sigma_s V3] [eta F] [g F] [scale F] [samples I] }

Any order, each keyword at most once; either ``preset`` or both ``sigma_a`` and ``sigma_s`` (a preset's values
may be overridden one by one). ``sigma_a``, ``sigma_s`` >= 0 are the absorption and scattering coefficients
per millimetre; ``scale`` (> 0, default 1) is the millimetres per scene unit, so the coefficients the renderer
uses are ``σ · scale`` per scene unit. ``eta`` (in :data:`ETA_RANGE`, default 1.3) the relative index of refraction
of the boundary, ``g`` in (−1, 1) (default 0) the Henyey-Greenstein asymmetry inside, ``samples`` (1..256, default 8)
the probe points (dipole) or walks (random walk) per hit and pass.

Presets (:func:`presets`, read from :data:`PRESETS_FILE` on first use): Jensen, Marschner, Levoy, Hanrahan 2001,
"A Practical Model for Subsurface Light Transport", Figure 5: the reduced scattering ``σ_s'`` and ``σ_a`` in mm⁻¹
(R, G, B), measured with ``η = 1.3``; a preset sets ``sigma_s = σ_s'`` with ``g = 0`` (the reduced coefficients
of an isotropic medium).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from importlib import resources
from typing import Final

from a5mi.converters.errors import FileLoc
from a5mi.converters.lexer import Token
from a5mi.converters.tokens import TokenStream, block_keys

Vec3 = tuple[float, float, float]

#: The presets' file (package data): name -> ``sigma_s`` (σ_s') and ``sigma_a`` in mm⁻¹, Jensen et al. 2001, Figure 5.
PRESETS_FILE: Final = "subsurface_presets.toml"
#: Jensen et al. 2001's index of refraction of every preset.
PRESET_ETA: Final = 1.3
#: The relative indices ``eta`` may take: the boundary's Fresnel terms square it (and its inverse) in float32, so
#: a value like 1e-30 or 1e30 makes ``0 · inf`` = NaN at normal incidence; real boundaries lie in about 1-3.
ETA_RANGE: Final = (0.01, 100.0)
MAX_SAMPLES: Final = 256


@functools.cache
def presets() -> dict[str, tuple[Vec3, Vec3]]:
    """name -> ``(σ_s', σ_a)`` in mm⁻¹ (module docstring), in the file's order; read once, when a ``preset`` is
    first named (the parse of a scene without one does not import ``tomllib``)."""
    import tomllib

    table = tomllib.loads(resources.files(__package__).joinpath(PRESETS_FILE).read_text(encoding="utf-8"))
    return {name: (tuple(row["sigma_s"]), tuple(row["sigma_a"])) for name, row in table.items()}


@dataclass(frozen=True)
class Subsurface:
    """A material's subsurface medium in scene units: ``sigma_a``, ``sigma_s`` (per scene unit, ``scale``
    applied), ``eta``, ``g``, ``samples``; ``loc`` where ``subsurface`` was written."""

    sigma_a: Vec3
    sigma_s: Vec3
    eta: float = PRESET_ETA
    g: float = 0.0
    samples: int = 8
    loc: FileLoc | None = None


def parse_subsurface(ts: TokenStream, start: Token) -> Subsurface:
    """The ``subsurface { ... }`` block after the keyword ``start`` (module docstring); range errors at the
    offending keyword's value."""
    ts.expect("{", "after 'subsurface'")
    seen: dict[str, Token] = {}
    vecs: dict[str, Vec3] = {}
    nums: dict[str, float] = {}
    preset: str | None = None
    samples = 8
    keys = ("preset", "sigma_a", "sigma_s", "eta", "g", "scale", "samples")
    for tok in block_keys(ts, "subsurface", keys):
        seen[tok.text] = tok
        if tok.text == "preset":
            name = ts.name("preset")
            if name.text.lower() not in presets():
                raise ts.semantic_error(f"unknown subsurface preset '{name.text}' (one of {', '.join(presets())})",
                                        name.loc)
            preset = name.text.lower()
        elif tok.text in ("sigma_a", "sigma_s"):
            v = ts.vec3(tok.text)
            if min(v) < 0.0:
                raise ts.semantic_error(f"subsurface {tok.text} must not be negative", tok.loc)
            vecs[tok.text] = v
        elif tok.text == "samples":
            samples, n_tok = ts.integer("samples")
            if not 1 <= samples <= MAX_SAMPLES:
                raise ts.semantic_error(f"subsurface samples must be between 1 and {MAX_SAMPLES}, found {samples}",
                                        n_tok.loc)
        else:
            nums[tok.text] = ts.number(tok.text)
    if preset is not None:
        sigma_s, sigma_a = presets()[preset]
        vecs.setdefault("sigma_s", sigma_s)
        vecs.setdefault("sigma_a", sigma_a)
    for key in ("sigma_a", "sigma_s"):
        if key not in vecs:
            raise ts.semantic_error(f"subsurface needs a preset or '{key}'", start.loc)
    checks = (("eta", lambda v: ETA_RANGE[0] <= v <= ETA_RANGE[1],
               f"must be between {ETA_RANGE[0]:g} and {ETA_RANGE[1]:g}"), ("g", lambda v: -1.0 < v < 1.0,
              "must be between -1 and 1 (exclusive)"), ("scale", lambda v: v > 0.0, "must be positive"))
    for key, ok, msg in checks:
        if key in nums and not ok(nums[key]):
            raise ts.semantic_error(f"subsurface {key} {msg}, found {nums[key]:g}", seen[key].loc)
    scale = nums.get("scale", 1.0)
    sa = tuple(c * scale for c in vecs["sigma_a"])
    ss = tuple(c * scale for c in vecs["sigma_s"])
    return Subsurface(sa, ss, nums.get("eta", PRESET_ETA), nums.get("g", 0.0), samples,  # type: ignore[arg-type]
                      start.loc)

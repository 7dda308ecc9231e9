"""Parser rules of the scene-language extensions (docs/EXTENSIONS.md E.1-E.4, E.6-E.10).

New blocks and keywords, read from the same :class:`~.tokens.TokenStream` with the same positioned errors
as the course grammar (SPEC A): ``SpotLight``, ``AreaLight``, ``SphereLight`` inside ``Lights`` (E.1, E.2);
``aperture`` / ``focusDistance`` at the end of ``PerspectiveCamera`` (E.3); in ``Material``, ``roughness`` /
``glossySamples`` (E.4), ``Wood`` / ``Turbulence`` / ``Veins`` blocks (E.6), ``bumpScale`` / ``normalMap``
(E.7) and ``refractionIndex dispersion A B`` (E.10), each a rule of :data:`MATERIAL_RULES` that fills the
:class:`~.builders.MaterialBuilder`; the top-level ``Fog`` and ``Volume`` blocks (E.8, E.9; at most one medium
per scene). A course scene contains none of them, so it parses to the same model as before (every new field
has the default that means "as SPEC B").
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Final

from a5mi.converters.builders import MaterialBuilder, SolidBuilder
from a5mi.converters.errors import FileLoc
from a5mi.converters.lexer import Token
from a5mi.converters.model import AreaLight, Fog, Light, Medium, Solid, SphereLight, SpotLight, Vec3, Volume
from a5mi.converters.obj import FLOAT32_MAX
from a5mi.converters.subsurface import parse_subsurface
from a5mi.converters.surface_ext import MATERIAL_RULES as SURFACE_RULES
from a5mi.converters.tokens import Rule, TokenStream, block_keys, keyword_block, quoted_raw
from a5mi.spec import DISPERSION_RANGE_NM

#: The smallest normal float32 (smaller values are flushed to 0 by the kernels).
FLOAT32_TINY: Final = 1.1754943508222875e-38
#: Upper bound of ``samples`` / ``glossySamples`` (one kernel loop bound / stack size, EXTENSIONS E.5).
MAX_LIGHT_SAMPLES: Final = 4096
MAX_GLOSSY_SAMPLES: Final = 64
#: The procedural solid blocks (E.6) -> the ``a5_solid`` kind, and the keywords each takes besides ``color``.
SOLIDS: Final = {"Wood": "wood", "Turbulence": "turbulence", "Veins": "veins"}
SOLID_KEYWORDS: Final = {
    "Wood": ("octaves", "frequency", "amplitude", "scale", "axis", "center"),
    "Turbulence": ("octaves", "amplitude", "scale"),
    "Veins": ("octaves", "frequency", "amplitude", "scale", "axis"),
}

#: Upper bound of a medium's ``steps`` (EXTENSIONS E.8, E.9): a kernel loop bound.
MAX_MEDIUM_STEPS: Final = 1024
#: Top-level blocks this module adds (the course's error message keeps listing only the course's five).
TOP_LEVEL: Final = ("Fog", "Volume")

_V3, _F, _I, _N = "vec3", "number", "integer", "name"


@dataclass
class Fields:
    """The values of one extension block, by kind (``V3``, ``F``, ``I``, ``NAME``), and where each keyword was
    written (``locs``), so that a range check reports at the offending keyword (SPEC A.0 style)."""

    vecs: dict[str, Vec3] = field(default_factory=dict)
    nums: dict[str, float] = field(default_factory=dict)
    ints: dict[str, int] = field(default_factory=dict)
    names: dict[str, Token] = field(default_factory=dict)
    locs: dict[str, FileLoc] = field(default_factory=dict)

    def check(self, ts: TokenStream, ok: bool, key: str, msg: str) -> None:
        """``msg`` at keyword ``key`` unless ``ok``."""
        if not ok:
            raise ts.semantic_error(msg, self.locs[key])


def _fields(ts: TokenStream, start: Token, block: str, kinds: dict[str, str], required: tuple[str, ...]) -> Fields:
    """``BLOCK { (KEY value)* }``, keys of ``kinds`` in any order, each at most once; ``required`` must appear.
    Values are checked here for type only; the callers check ranges with :meth:`Fields.check`."""
    ts.expect("{", f"after '{block}'")
    f = Fields()
    for tok in block_keys(ts, block, kinds):
        key = tok.text
        kind = kinds[key]
        if kind == _N:
            f.names[key] = ts.name(key)
        elif kind == _V3:
            f.vecs[key] = ts.vec3(key)
        elif kind == _F:
            f.nums[key] = ts.number(key)
        else:
            f.ints[key] = ts.integer(key)[0]
        f.locs[key] = tok.loc
    for key in required:
        if key not in f.locs:
            raise ts.semantic_error(f"{block} needs '{key}'", start.loc)
    return f


def _nonzero(v: Vec3) -> bool:
    return any(c != 0.0 for c in v)


def _falloff_samples(ts: TokenStream, block: str, f: Fields) -> tuple[float, int]:
    falloff = f.nums.get("falloff", 0.0)
    f.check(ts, falloff >= 0.0, "falloff", f"{block} falloff must not be negative, found {falloff:g}")
    samples = f.ints.get("samples", 16)
    f.check(ts, 1 <= samples <= MAX_LIGHT_SAMPLES, "samples",
            f"{block} samples must be between 1 and {MAX_LIGHT_SAMPLES}, found {samples}")
    return falloff, samples


def parse_spot_light(ts: TokenStream, start: Token) -> SpotLight:
    """``SpotLight { position V3 direction V3 color V3 [falloff F] angle F [beamWidth F] }`` (E.1): any order;
    ``0 < beamWidth <= angle < 90`` degrees, ``beamWidth`` defaulting to ``3/4 angle``."""
    f = _fields(ts, start, "SpotLight", {"position": _V3, "direction": _V3, "color": _V3, "falloff": _F,
                                         "angle": _F, "beamWidth": _F}, ("position", "direction", "color", "angle"))
    v = f.vecs
    f.check(ts, _nonzero(v["direction"]), "direction", "SpotLight direction must not be the zero vector")
    angle = f.nums["angle"]
    f.check(ts, 0.0 < angle < 90.0, "angle", f"SpotLight angle must be between 0 and 90 degrees, found {angle:g}")
    beam = f.nums.get("beamWidth", 0.75 * angle)
    f.check(ts, 0.0 < beam <= angle, "beamWidth",
            f"SpotLight beamWidth must be in (0, angle = {angle:g}] degrees, found {beam:g}")
    falloff, _ = _falloff_samples(ts, "SpotLight", f)
    return SpotLight(v["position"], v["direction"], v["color"], falloff, angle, beam, start.loc)


def parse_area_light(ts: TokenStream, start: Token) -> AreaLight:
    """``AreaLight { corner V3 edge1 V3 edge2 V3 color V3 [falloff F] [samples I] }`` (E.2); the edges must
    span a parallelogram of non-zero area (``edge1 × edge2 ≠ 0``); ``samples`` defaults to 16."""
    f = _fields(ts, start, "AreaLight", {"corner": _V3, "edge1": _V3, "edge2": _V3, "color": _V3, "falloff": _F,
                                         "samples": _I}, ("corner", "edge1", "edge2", "color"))
    e1, e2 = f.vecs["edge1"], f.vecs["edge2"]
    cross = (e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0])
    f.check(ts, _nonzero(cross), "edge2", "AreaLight edge1 and edge2 must span a non-zero area")
    falloff, samples = _falloff_samples(ts, "AreaLight", f)
    return AreaLight(f.vecs["corner"], e1, e2, f.vecs["color"], falloff, samples, start.loc)


def parse_sphere_light(ts: TokenStream, start: Token) -> SphereLight:
    """``SphereLight { center V3 radius F color V3 [falloff F] [samples I] }`` (E.2); radius > 0."""
    f = _fields(ts, start, "SphereLight", {"center": _V3, "radius": _F, "color": _V3, "falloff": _F,
                                           "samples": _I}, ("center", "radius", "color"))
    radius = f.nums["radius"]
    f.check(ts, radius > 0.0, "radius", f"SphereLight radius must be positive, found {radius:g}")
    falloff, samples = _falloff_samples(ts, "SphereLight", f)
    return SphereLight(f.vecs["center"], radius, f.vecs["color"], falloff, samples, start.loc)


#: ``Lights`` entries this module adds (name -> parse function).
LIGHTS: Final[dict[str, Callable[[TokenStream, Token], Light]]] = {
    "SpotLight": parse_spot_light, "AreaLight": parse_area_light, "SphereLight": parse_sphere_light}


def parse_camera_lens(ts: TokenStream) -> tuple[float, float]:
    """The optional ``[aperture F] [focusDistance F]`` after the camera's ``angle``, then ``}`` (E.3):
    ``aperture >= 0`` (the lens diameter; 0, the default, is the pinhole), ``focusDistance > 0`` (default 1) and at
    least the smallest normal float32 (a subnormal is flushed to 0 in the kernels)."""
    aperture, focus = 0.0, 1.0
    seen: set[str] = set()
    while True:
        tok = ts.next()
        if tok is not None and tok.text == "}":
            return aperture, focus
        if tok is None or tok.text not in ("aperture", "focusDistance") or tok.text in seen:
            raise ts.syntax_error(f"expected '}}' to close PerspectiveCamera (or aperture, focusDistance), "
                                  f"found {quoted_raw(tok)}", tok)
        seen.add(tok.text)
        value = ts.number(tok.text)
        if tok.text == "aperture":
            if value < 0.0:
                raise ts.semantic_error(f"camera aperture must not be negative, found {value:g}", tok.loc)
            aperture = value
        else:
            if value < FLOAT32_TINY:  # a float32 subnormal is flushed to 0 by the kernels
                raise ts.semantic_error(f"camera focusDistance must be at least {FLOAT32_TINY:.3g} (the smallest "
                                        f"normal float32), found {value:g}", tok.loc)
            focus = value


# ---------------------------------------------------------------------------------------- E.6 solid textures
def _solid_once(ts: TokenStream, tok: Token, s: SolidBuilder) -> None:
    if tok.text in s.given:
        raise ts.syntax_error(f"{s.block} gives '{tok.text}' twice", tok)
    s.given.add(tok.text)


def _solid_color(ts: TokenStream, tok: Token, s: SolidBuilder) -> None:
    if len(s.colors) == 2:
        raise ts.syntax_error(f"{s.block} takes two colors, found a third 'color'", tok)
    s.colors.append(ts.vec3("color"))


def _solid_octaves(ts: TokenStream, tok: Token, s: SolidBuilder) -> None:
    _solid_once(ts, tok, s)
    n, n_tok = ts.integer("octaves")
    if not 0 <= n <= 31:
        raise ts.semantic_error(f"{s.block} octaves must be between 0 and 31, found {n}", n_tok.loc)
    s.octaves = n


def _solid_frequency(ts: TokenStream, tok: Token, s: SolidBuilder) -> None:
    _solid_once(ts, tok, s)
    s.frequency = ts.number(tok.text)


def _solid_amplitude(ts: TokenStream, tok: Token, s: SolidBuilder) -> None:
    _solid_once(ts, tok, s)
    s.amplitude = ts.number(tok.text)


def _solid_scale(ts: TokenStream, tok: Token, s: SolidBuilder) -> None:
    _solid_once(ts, tok, s)
    x = ts.number(tok.text)
    if x <= 0.0:
        raise ts.semantic_error(f"{s.block} scale must be positive, found {x:g}", tok.loc)
    s.scale = x


def _solid_axis(ts: TokenStream, tok: Token, s: SolidBuilder) -> None:
    _solid_once(ts, tok, s)
    axis = ts.vec3(tok.text)
    if not _nonzero(axis):
        raise ts.semantic_error(f"{s.block} axis must not be the zero vector", tok.loc)
    s.axis = axis


def _solid_center(ts: TokenStream, tok: Token, s: SolidBuilder) -> None:
    _solid_once(ts, tok, s)
    s.center = ts.vec3(tok.text)


#: Every keyword of the solid blocks and its rule; each block takes ``color`` and its :data:`SOLID_KEYWORDS`.
SOLID_RULES: Final[dict[str, Rule[SolidBuilder]]] = {
    "color": _solid_color, "octaves": _solid_octaves, "frequency": _solid_frequency, "amplitude": _solid_amplitude,
    "scale": _solid_scale, "axis": _solid_axis, "center": _solid_center}


def parse_solid(ts: TokenStream, start: Token) -> Solid:
    """``Wood { color V3 color V3 [octaves I] [frequency F] [amplitude F] [scale F] [axis V3] [center V3] }``,
    ``Turbulence { color V3 color V3 [octaves I] [amplitude F] [scale F] }``, ``Veins { color V3 color V3
    [octaves I] [frequency F] [amplitude F] [scale F] [axis V3] }`` (E.6): any order, each keyword at most once,
    exactly two colours; ``0 <= octaves <= 31``, ``scale > 0``, ``axis`` not zero."""
    block = start.text
    keys = SOLID_KEYWORDS[block]
    ts.expect("{", f"after '{block}'")
    s = SolidBuilder(block, SOLIDS[block])
    keyword_block(ts, {k: SOLID_RULES[k] for k in ("color", *keys)}, s, lambda tok: ts.syntax_error(
        f"expected color, {', '.join(keys)} or '}}' in {block}, found {quoted_raw(tok)}", tok))
    if len(s.colors) < 2:
        raise ts.semantic_error(f"{block} needs two colors, found {len(s.colors)}", start.loc)
    return s.build(start.loc)


# ------------------------------------------------------------------------------- Material: E.4, E.6, E.7, E.10
def _material_solid(ts: TokenStream, tok: Token, m: MaterialBuilder) -> None:
    """E.6: one colour source, so not after ``Noise`` or another solid."""
    if m.noise is not None or m.solid is not None:
        raise ts.semantic_error(f"a Material takes one of Noise, {', '.join(SOLIDS)}; found '{tok.text}' "
                                "after another", tok.loc)
    m.solid = parse_solid(ts, tok)


def _bump_scale(ts: TokenStream, tok: Token, m: MaterialBuilder) -> None:
    """E.7: ``bumpScale F``, the height of grey 1 in world units."""
    m.bump_scale = ts.number(tok.text)


def _normal_map(ts: TokenStream, tok: Token, m: MaterialBuilder) -> None:
    """E.7: ``normalMap NAME``, a tangent-space normal map."""
    name = ts.name(tok.text)
    m.normal_map, m.normal_map_loc = name.text, name.loc


def _roughness(ts: TokenStream, tok: Token, m: MaterialBuilder) -> None:
    """E.4: ``roughness F``, the GGX alpha, 0 <= alpha <= 1."""
    alpha = ts.number(tok.text)
    if not 0.0 <= alpha <= 1.0:
        raise ts.semantic_error(f"roughness must be between 0 and 1, found {alpha:g}", tok.loc)
    m.roughness = alpha


def _glossy_samples(ts: TokenStream, tok: Token, m: MaterialBuilder) -> None:
    """E.4: ``glossySamples I``, 1 <= G <= :data:`MAX_GLOSSY_SAMPLES`."""
    n, n_tok = ts.integer(tok.text)
    if not 1 <= n <= MAX_GLOSSY_SAMPLES:
        raise ts.semantic_error(f"glossySamples must be between 1 and {MAX_GLOSSY_SAMPLES}, found {n}", n_tok.loc)
    m.glossy_samples = n


def _subsurface(ts: TokenStream, tok: Token, m: MaterialBuilder) -> None:
    """E.18: ``subsurface { ... }`` (converters/subsurface.py), at most once."""
    if m.subsurface is not None:
        raise ts.semantic_error("a Material takes one subsurface block", tok.loc)
    m.subsurface = parse_subsurface(ts, tok)


#: The keywords this module adds to ``Material`` and their rules, in the order the parser's message lists them.
MATERIAL_RULES: Final[dict[str, Rule[MaterialBuilder]]] = {
    "roughness": _roughness, "glossySamples": _glossy_samples, "Wood": _material_solid,
    "Turbulence": _material_solid, "Veins": _material_solid, "bumpScale": _bump_scale, "normalMap": _normal_map,
    "subsurface": _subsurface, **SURFACE_RULES}  # E.19 btf, E.20 milled
MATERIAL_KEYWORDS: Final = tuple(MATERIAL_RULES)


def parse_dispersion(ts: TokenStream, tok: Token, m: MaterialBuilder) -> bool:
    """After ``refractionIndex`` (``tok``): ``dispersion A B`` (E.10), Cauchy's ``n(λ) = A + B/λ²`` with ``λ`` in
    µm and ``B`` in µm². Sets ``m.refraction_index = A`` and ``m.dispersion = B`` and returns True; ``A > 0``
    and ``n(λ) > 0`` over the sampled range (:data:`a5mi.spec.DISPERSION_RANGE_NM`), each checked at its
    number. Any other next token: consumes nothing, forgets an earlier ``dispersion`` (the last
    ``refractionIndex`` of a Material wins, as in SPEC A.5) and returns False."""
    nxt = ts.peek()
    if nxt is None or nxt.text != "dispersion":
        m.dispersion = None
        return False
    ts.next()
    a, a_tok = ts.number_at("dispersion")
    if a <= 0.0:
        raise ts.semantic_error(f"dispersion A (the index far in the infrared) must be positive, found {a:g}",
                                a_tok.loc)
    b, b_tok = ts.number_at("dispersion")
    top = math.sqrt(FLOAT32_MAX)  # Snell's (n/nt)² must stay finite in float32, as for refractionIndex F
    if a > top:
        raise ts.semantic_error(f"dispersion A {a:g} is too large: its square overflows float32 (at most 1.8e19)",
                                a_tok.loc)
    for lam_nm in DISPERSION_RANGE_NM:
        n = a + b / (lam_nm * 1e-3) ** 2
        if n <= 0.0:
            raise ts.semantic_error(f"dispersion {a:g} {b:g} gives the index {n:g} at {lam_nm:g} nm: it must stay "
                                    "positive over the sampled range", b_tok.loc)
        if n > top:
            raise ts.semantic_error(f"dispersion {a:g} {b:g} gives the index {n:g} at {lam_nm:g} nm: its square "
                                    "overflows float32 (at most 1.8e19)", b_tok.loc)
    m.refraction_index, m.dispersion = a, b
    return True


# ------------------------------------------------------------------------------------------- E.8, E.9 media
def _phase_g(ts: TokenStream, block: str, f: Fields) -> float:
    """E.8: ``g`` in (−1, 1), the Henyey-Greenstein asymmetry (default 0: isotropic)."""
    g = f.nums.get("g", 0.0)
    f.check(ts, -1.0 < g < 1.0, "g", f"{block} g must be between -1 and 1 (exclusive), found {g:g}")
    return g


def _medium_common(ts: TokenStream, block: str, f: Fields, default_steps: int) -> tuple[float, Vec3, int]:
    density = f.nums["density"]
    f.check(ts, density >= 0.0, "density", f"{block} density must not be negative, found {density:g}")
    color = f.vecs.get("color", (1.0, 1.0, 1.0))
    f.check(ts, all(0.0 <= c <= 1.0 for c in color), "color",
            f"{block} color is the single-scattering albedo: each component must be in [0, 1], found "
            f"{' '.join(f'{c:g}' for c in color)}")
    steps = f.ints.get("steps", default_steps)
    f.check(ts, 1 <= steps <= MAX_MEDIUM_STEPS, "steps",
            f"{block} steps must be between 1 and {MAX_MEDIUM_STEPS}, found {steps}")
    return density, color, steps


def parse_fog(ts: TokenStream, start: Token) -> Fog:
    """``Fog { color V3 density F [steps I] [g F] }`` (E.8): any order; ``density >= 0`` (extinction per unit
    length), ``color`` in [0, 1]³ (the albedo), ``1 <= steps <= 1024`` (default 16)."""
    f = _fields(ts, start, "Fog", {"color": _V3, "density": _F, "steps": _I, "g": _F}, ("color", "density"))
    density, color, steps = _medium_common(ts, "Fog", f, 16)
    return Fog(color, density, steps, start.loc, _phase_g(ts, "Fog", f))


def parse_volume(ts: TokenStream, start: Token) -> Volume:
    """``Volume { grid NAME density F min V3 max V3 [color V3] [steps I] }`` (E.9): any order; ``min < max``
    in every coordinate, ``density >= 0`` (scales the grid's values), ``color`` the albedo (default 1 1 1),
    ``steps`` the marching steps across the box (default 64)."""
    f = _fields(ts, start, "Volume", {"grid": _N, "density": _F, "min": _V3, "max": _V3, "color": _V3,
                                      "steps": _I, "g": _F}, ("grid", "density", "min", "max"))
    lo, hi = f.vecs["min"], f.vecs["max"]
    f.check(ts, all(a < b for a, b in zip(lo, hi, strict=True)), "max",
            "Volume max must exceed min in every coordinate")
    density, color, steps = _medium_common(ts, "Volume", f, 64)
    grid = f.names["grid"]
    return Volume(density, lo, hi, color, steps, start.loc, grid=grid.text, grid_loc=grid.loc,
                  g=_phase_g(ts, "Volume", f))


#: Top-level blocks (name -> parse function); each sets the scene's ``medium``.
MEDIA: Final[dict[str, Callable[[TokenStream, Token], Medium]]] = {"Fog": parse_fog, "Volume": parse_volume}

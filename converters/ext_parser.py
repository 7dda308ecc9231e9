"""Parser rules of the scene-language extensions (docs/EXTENSIONS.md E.1-E.4, E.6, E.7).

New blocks and keywords, read from the same :class:`~.a5_parser.TokenStream` with the same positioned errors
as the course grammar (SPEC A): ``SpotLight``, ``AreaLight``, ``SphereLight`` inside ``Lights``; ``aperture`` /
``focusDistance`` at the end of ``PerspectiveCamera``; ``roughness`` / ``glossySamples`` in ``Material``;
``refractionIndex dispersion A B`` (E.10); the top-level ``Fog`` and ``Volume`` blocks (E.8, E.9; at most one
medium per scene). A course scene contains none of them, so it parses to the same model as before (every new
field has the default that means "as SPEC B").. Part 2: ``Wood`` / ``Turbulence`` / ``Veins`` blocks (E.6) and
``bumpScale`` / ``normalMap`` (E.7) in ``Material``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Final

from a5mi.spec import DISPERSION_RANGE_NM

from .model import AreaLight, Fog, Solid, SphereLight, SpotLight, Vec3, Volume

if TYPE_CHECKING:
    from .a5_parser import TokenStream
    from .lexer import Token

#: Upper bound of ``samples`` / ``glossySamples`` (one kernel loop bound / stack size, EXTENSIONS E.5).
MAX_LIGHT_SAMPLES: Final = 4096
MAX_GLOSSY_SAMPLES: Final = 64
#: The keywords this module adds to ``Material`` (for the parser's error message).
MATERIAL_KEYWORDS: Final = ("roughness", "glossySamples", "Wood", "Turbulence", "Veins", "bumpScale", "normalMap")
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


def _fields(ts: TokenStream, start: Token, block: str, kinds: dict[str, str],
            required: tuple[str, ...]) -> dict[str, object]:
    """``BLOCK { (KEY value)* }``, keys of ``kinds`` in any order, each at most once; ``required`` must appear.
    Values are checked here for type only; the callers check ranges at the keyword's position, so every
    error points at the offending token (SPEC A.0 style)."""
    ts.expect("{", f"after '{block}'")
    values: dict[str, object] = {}
    locs: dict[str, object] = {}
    while True:
        tok = ts.next()
        if tok is not None and tok.text == "}":
            break
        if tok is None or tok.text not in kinds:
            found = "end of file" if tok is None else f"'{tok.text}'"
            raise ts.syntax_error(f"expected {', '.join(kinds)} or '}}' in {block}, found {found}", tok)
        if tok.text in values:
            raise ts.syntax_error(f"{block} gives '{tok.text}' twice", tok)
        kind = kinds[tok.text]
        if kind == _N:
            name = ts.name(tok.text)
            values[tok.text], locs[tok.text + ":value"] = name.text, name.loc
        else:
            values[tok.text] = (ts.vec3(tok.text) if kind == _V3 else ts.number(tok.text) if kind == _F
                                else ts.integer(tok.text)[0])
        locs[tok.text] = tok.loc
    for key in required:
        if key not in values:
            raise ts.semantic_error(f"{block} needs '{key}'", start.loc)
    values["_locs"] = locs
    return values


def _check(ts: TokenStream, ok: bool, values: dict[str, object], key: str, msg: str) -> None:
    if not ok:
        raise ts.semantic_error(msg, values["_locs"][key])  # type: ignore[index]


def _nonzero(v: Vec3) -> bool:
    return any(c != 0.0 for c in v)


def _falloff_samples(ts: TokenStream, block: str, values: dict[str, object]) -> tuple[float, int]:
    falloff = float(values.get("falloff", 0.0))  # type: ignore[arg-type]
    _check(ts, falloff >= 0.0, values, "falloff", f"{block} falloff must not be negative, found {falloff:g}")
    samples = int(values.get("samples", 16))  # type: ignore[call-overload]
    _check(ts, 1 <= samples <= MAX_LIGHT_SAMPLES, values, "samples",
           f"{block} samples must be between 1 and {MAX_LIGHT_SAMPLES}, found {samples}")
    return falloff, samples


def parse_spot_light(ts: TokenStream, start: Token) -> SpotLight:
    """``SpotLight { position V3 direction V3 color V3 [falloff F] angle F [beamWidth F] }`` (E.1): any order;
    ``0 < beamWidth <= angle < 90`` degrees, ``beamWidth`` defaulting to ``3/4 angle``."""
    v = _fields(ts, start, "SpotLight", {"position": _V3, "direction": _V3, "color": _V3, "falloff": _F,
                                         "angle": _F, "beamWidth": _F}, ("position", "direction", "color", "angle"))
    _check(ts, _nonzero(v["direction"]), v, "direction", "SpotLight direction must not be the zero vector")  # type: ignore[arg-type]
    angle = float(v["angle"])  # type: ignore[arg-type]
    _check(ts, 0.0 < angle < 90.0, v, "angle", f"SpotLight angle must be between 0 and 90 degrees, found {angle:g}")
    beam = float(v.get("beamWidth", 0.75 * angle))  # type: ignore[arg-type]
    _check(ts, 0.0 < beam <= angle, v, "beamWidth",
           f"SpotLight beamWidth must be in (0, angle = {angle:g}] degrees, found {beam:g}")
    falloff, _ = _falloff_samples(ts, "SpotLight", v)
    return SpotLight(v["position"], v["direction"], v["color"], falloff, angle, beam, start.loc)  # type: ignore[arg-type]


def parse_area_light(ts: TokenStream, start: Token) -> AreaLight:
    """``AreaLight { corner V3 edge1 V3 edge2 V3 color V3 [falloff F] [samples I] }`` (E.2); the edges must
    span a parallelogram of non-zero area; ``samples`` defaults to 16."""
    v = _fields(ts, start, "AreaLight", {"corner": _V3, "edge1": _V3, "edge2": _V3, "color": _V3, "falloff": _F,
                                         "samples": _I}, ("corner", "edge1", "edge2", "color"))
    e1, e2 = v["edge1"], v["edge2"]
    cross = (e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0])  # type: ignore[index]
    _check(ts, _nonzero(cross), v, "edge2", "AreaLight edge1 and edge2 must span a non-zero area")
    falloff, samples = _falloff_samples(ts, "AreaLight", v)
    return AreaLight(v["corner"], e1, e2, v["color"], falloff, samples, start.loc)  # type: ignore[arg-type]


def parse_sphere_light(ts: TokenStream, start: Token) -> SphereLight:
    """``SphereLight { center V3 radius F color V3 [falloff F] [samples I] }`` (E.2); radius > 0."""
    v = _fields(ts, start, "SphereLight", {"center": _V3, "radius": _F, "color": _V3, "falloff": _F,
                                           "samples": _I}, ("center", "radius", "color"))
    radius = float(v["radius"])  # type: ignore[arg-type]
    _check(ts, radius > 0.0, v, "radius", f"SphereLight radius must be positive, found {radius:g}")
    falloff, samples = _falloff_samples(ts, "SphereLight", v)
    return SphereLight(v["center"], radius, v["color"], falloff, samples, start.loc)  # type: ignore[arg-type]


#: ``Lights`` entries this module adds (name -> parse function).
LIGHTS: Final = {"SpotLight": parse_spot_light, "AreaLight": parse_area_light, "SphereLight": parse_sphere_light}


def parse_camera_lens(ts: TokenStream) -> tuple[float, float]:
    """The optional ``[aperture F] [focusDistance F]`` after the camera's ``angle``, then ``}`` (E.3):
    ``aperture >= 0`` (the lens diameter; 0, the default, is the pinhole), ``focusDistance > 0`` (default 1)."""
    aperture, focus = 0.0, 1.0
    seen: set[str] = set()
    while True:
        tok = ts.next()
        if tok is not None and tok.text == "}":
            return aperture, focus
        if tok is None or tok.text not in ("aperture", "focusDistance") or tok.text in seen:
            found = "end of file" if tok is None else f"'{tok.text}'"
            raise ts.syntax_error(f"expected '}}' to close PerspectiveCamera (or aperture, focusDistance), "
                                  f"found {found}", tok)
        seen.add(tok.text)
        value = ts.number(tok.text)
        if tok.text == "aperture":
            if value < 0.0:
                raise ts.semantic_error(f"camera aperture must not be negative, found {value:g}", tok.loc)
            aperture = value
        else:
            if value <= 0.0:
                raise ts.semantic_error(f"camera focusDistance must be positive, found {value:g}", tok.loc)
            focus = value


def parse_solid(ts: TokenStream, start: Token) -> Solid:
    """``Wood { color V3 color V3 [octaves I] [frequency F] [amplitude F] [scale F] [axis V3] [center V3] }``,
    ``Turbulence { color V3 color V3 [octaves I] [amplitude F] [scale F] }``, ``Veins { color V3 color V3
    [octaves I] [frequency F] [amplitude F] [scale F] [axis V3] }`` (E.6): any order, each keyword at most once,
    exactly two colours; ``0 <= octaves <= 31``, ``scale > 0``, ``axis`` not zero."""
    block = start.text
    keys = SOLID_KEYWORDS[block]
    ts.expect("{", f"after '{block}'")
    colors: list[Vec3] = []
    v: dict[str, object] = {}
    while True:
        tok = ts.next()
        if tok is not None and tok.text == "}":
            break
        if tok is None or (tok.text != "color" and tok.text not in keys):
            found = "end of file" if tok is None else f"'{tok.text}'"
            raise ts.syntax_error(f"expected color, {', '.join(keys)} or '}}' in {block}, found {found}", tok)
        if tok.text == "color":
            if len(colors) == 2:
                raise ts.syntax_error(f"{block} takes two colors, found a third 'color'", tok)
            colors.append(ts.vec3("color"))
            continue
        if tok.text in v:
            raise ts.syntax_error(f"{block} gives '{tok.text}' twice", tok)
        if tok.text == "octaves":
            n, n_tok = ts.integer("octaves")
            if not 0 <= n <= 31:
                raise ts.semantic_error(f"{block} octaves must be between 0 and 31, found {n}", n_tok.loc)
            v["octaves"] = n
        elif tok.text in ("axis", "center"):
            vec = ts.vec3(tok.text)
            if tok.text == "axis" and not _nonzero(vec):
                raise ts.semantic_error(f"{block} axis must not be the zero vector", tok.loc)
            v[tok.text] = vec
        else:
            x = ts.number(tok.text)
            if tok.text == "scale" and x <= 0.0:
                raise ts.semantic_error(f"{block} scale must be positive, found {x:g}", tok.loc)
            v[tok.text] = x
    if len(colors) < 2:
        raise ts.semantic_error(f"{block} needs two colors, found {len(colors)}", start.loc)
    return Solid(SOLIDS[block], colors[0], colors[1], loc=start.loc, **v)  # type: ignore[arg-type]


def parse_material_keyword(ts: TokenStream, tok: Token, values: dict[str, object]) -> None:
    """Inside ``Material``: ``roughness F`` (GGX alpha, 0 <= alpha <= 1) or ``glossySamples I`` (1..64) (E.4);
    a ``Wood`` / ``Turbulence`` / ``Veins`` block (E.6; one colour source: not with ``Noise`` or another solid);
    ``bumpScale F`` (finite, E.7) or ``normalMap NAME`` (E.7)."""
    if tok.text in SOLIDS:
        if "noise" in values or "solid" in values:
            raise ts.semantic_error(f"a Material takes one of Noise, {', '.join(SOLIDS)}; found '{tok.text}' "
                                    "after another", tok.loc)
        values["solid"] = parse_solid(ts, tok)
    elif tok.text == "bumpScale":
        values["bump_scale"] = ts.number(tok.text)
    elif tok.text == "normalMap":
        name = ts.name(tok.text)
        values["normal_map"], values["normal_map_loc"] = name.text, name.loc
    elif tok.text == "roughness":
        alpha = ts.number(tok.text)
        if not 0.0 <= alpha <= 1.0:
            raise ts.semantic_error(f"roughness must be between 0 and 1, found {alpha:g}", tok.loc)
        values["roughness"] = alpha
    else:
        n, n_tok = ts.integer(tok.text)
        if not 1 <= n <= MAX_GLOSSY_SAMPLES:
            raise ts.semantic_error(f"glossySamples must be between 1 and {MAX_GLOSSY_SAMPLES}, found {n}",
                                    n_tok.loc)
        values["glossy_samples"] = n


# ------------------------------------------------------------------------------------------- E.8, E.9 media
def _medium_common(ts: TokenStream, block: str, v: dict[str, object], default_steps: int) -> tuple[float, Vec3, int]:
    density = float(v["density"])  # type: ignore[arg-type]
    _check(ts, density >= 0.0, v, "density", f"{block} density must not be negative, found {density:g}")
    color: Vec3 = v.get("color", (1.0, 1.0, 1.0))  # type: ignore[assignment]
    _check(ts, all(0.0 <= c <= 1.0 for c in color), v, "color",
           f"{block} color is the single-scattering albedo: each component must be in [0, 1], found "
           f"{' '.join(f'{c:g}' for c in color)}")
    steps = int(v.get("steps", default_steps))  # type: ignore[call-overload]
    _check(ts, 1 <= steps <= MAX_MEDIUM_STEPS, v, "steps",
           f"{block} steps must be between 1 and {MAX_MEDIUM_STEPS}, found {steps}")
    return density, color, steps


def parse_fog(ts: TokenStream, start: Token) -> Fog:
    """``Fog { color V3 density F [steps I] }`` (E.8): any order; ``density >= 0`` (extinction per unit
    length), ``color`` in [0, 1]³ (the albedo), ``1 <= steps <= 1024`` (default 16)."""
    v = _fields(ts, start, "Fog", {"color": _V3, "density": _F, "steps": _I}, ("color", "density"))
    density, color, steps = _medium_common(ts, "Fog", v, 16)
    return Fog(color, density, steps, start.loc)


def parse_volume(ts: TokenStream, start: Token) -> Volume:
    """``Volume { grid NAME density F min V3 max V3 [color V3] [steps I] }`` (E.9): any order; ``min < max``
    in every coordinate, ``density >= 0`` (scales the grid's values), ``color`` the albedo (default 1 1 1),
    ``steps`` the marching steps across the box (default 64)."""
    v = _fields(ts, start, "Volume", {"grid": _N, "density": _F, "min": _V3, "max": _V3, "color": _V3,
                                      "steps": _I}, ("grid", "density", "min", "max"))
    lo, hi = v["min"], v["max"]
    _check(ts, all(a < b for a, b in zip(lo, hi, strict=True)), v, "max",  # type: ignore[call-overload]
           "Volume max must exceed min in every coordinate")
    density, color, steps = _medium_common(ts, "Volume", v, 64)
    return Volume(str(v["grid"]), density, lo, hi, color, steps, start.loc, v["_locs"]["grid:value"])  # type: ignore[arg-type, index]


#: Top-level blocks (name -> parse function); each sets the scene's ``medium``.
MEDIA: Final = {"Fog": parse_fog, "Volume": parse_volume}
def parse_dispersion(ts: TokenStream, tok: Token, values: dict[str, object]) -> bool:
    """After ``refractionIndex`` (``tok``): ``dispersion A B`` (E.10), Cauchy's ``n(λ) = A + B/λ²`` with ``λ`` in
    µm and ``B`` in µm². Sets ``values['refraction_index'] = A`` and ``values['dispersion'] = B`` and returns
    True; ``A > 0`` and ``n(λ) > 0`` over the sampled range (:data:`a5mi.spec.DISPERSION_RANGE_NM`), each
    checked at its number. Any other next token: consumes nothing, forgets an earlier ``dispersion`` (the last
    ``refractionIndex`` of a Material wins, as in SPEC A.5) and returns False."""
    nxt = ts.peek()
    if nxt is None or nxt.text != "dispersion":
        values.pop("dispersion", None)
        return False
    ts.next()
    a_tok = ts.peek()
    a = ts.number("dispersion")
    if a <= 0.0:
        raise ts.semantic_error(f"dispersion A (the index far in the infrared) must be positive, found {a:g}",
                                a_tok.loc)  # type: ignore[union-attr]
    b_tok = ts.peek()
    b = ts.number("dispersion")
    for lam_nm in DISPERSION_RANGE_NM:
        n = a + b / (lam_nm * 1e-3) ** 2
        if n <= 0.0:
            raise ts.semantic_error(f"dispersion {a:g} {b:g} gives the index {n:g} at {lam_nm:g} nm: it must stay "
                                    "positive over the sampled range", b_tok.loc)  # type: ignore[union-attr]
    values["refraction_index"], values["dispersion"] = a, b
    return True

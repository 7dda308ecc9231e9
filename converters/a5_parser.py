"""Parser for the 6.837 scene language (SPEC A.1-A.6): tokens -> :class:`~a5mi.converters.model.Scene`.

One function per block (``parse_camera``, ``parse_lights``, ``parse_background``, ``parse_materials``,
``parse_material``, ``parse_noise``; ``Group`` and its objects in :mod:`.group_parser`), each reading the
:class:`~.tokens.TokenStream`. A block of keywords in any order is a table ``keyword -> rule``
(:data:`MATERIAL_RULES`, :data:`BACKGROUND_RULES`, :data:`NOISE_RULES`, :data:`BLOCK_RULES` for the top level),
each rule a small function that fills a typed builder (:mod:`.builders`); the extensions add their rules from
:mod:`.ext_parser` (docs/EXTENSIONS.md) and :mod:`.keyframes` (E.11). Pure Python: no Mitsuba, no file access
beyond the scene text (meshes and textures are the converter's).

Where the sample solution asserted, exited or silently misbehaved, this parser raises a
:class:`~a5mi.converters.errors.SceneSyntaxError` (grammar) or
:class:`~a5mi.converters.errors.SceneSemanticError` (meaning) at the offending token, with a message that says
what was expected and what was found (``expected a number after 'radius', found 'abc'``; at the end of the
file: ``found end of file``). In particular: every keyword is consumed or reported (A.5's "an unknown word
silently ends a Material" is an error at that word); a third ``color`` in ``Noise`` is an error; NaN, inf and
out-of-range numbers are errors; declared counts are compared as objects arrive (nothing is allocated from
them); ``MaterialIndex`` must satisfy ``0 <= I < numMaterials`` (the binary's check was off by one) and must
precede every primitive; degenerate geometry (zero radius, zero-length normal/axis/direction/up, a zero-area
``Triangle``, a singular ``Transform``) is an error.

Accepted as the binary accepted it, with an entry in ``Scene.warnings``: a file name not ending in ``.txt``
(A.0), a block given twice (the later one wins, A.1), no lights (ambient forced to 1, A.1), a ``PointLight``
without ``position`` or ``color`` (0), a ``Noise`` with fewer than two colours (0).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Final

import numpy as np

from a5mi.converters import ext_parser, keyframes
from a5mi.converters.builders import BackgroundBuilder, MaterialBuilder, NoiseBuilder, PointLightBuilder, SceneBuilder
from a5mi.converters.errors import FileLoc, SceneSyntaxError, shown
from a5mi.converters.group_parser import MAX_NESTING, parse_group
from a5mi.converters.lexer import Token, read_source
from a5mi.converters.model import Background, Camera, DirectionalLight, Light, Material, Noise, PointLight, Scene, Vec3
from a5mi.converters.tokens import (
    Rule,
    TokenStream,
    counted_block,
    keyword_block,
    nonzero,
    one_of,
    quoted,
    unknown_keyword,
    vector_then,
)
from a5mi.vecmath32 import camera_basis

__all__ = ["MAX_NESTING", "TOP_LEVEL", "parse_file", "parse_text", "parse_tokens"]

#: The blocks of A.1, as the top-level error message lists them (the extensions' blocks are accepted too).
TOP_LEVEL: Final = ("PerspectiveCamera", "Lights", "Background", "Materials", "Group")


# -- A.2 ------------------------------------------------------------------------------------------------
def parse_camera(ts: TokenStream, start: Token) -> Camera:
    """``PerspectiveCamera { center V3 direction V3 up V3 angle F }`` in this fixed order (A.2); then the
    optional lens of EXTENSIONS E.3."""
    ts.expect("{", "after 'PerspectiveCamera'")
    fields: dict[str, Vec3] = {}
    tok = start
    for key in ("center", "direction", "up"):
        tok = ts.expect(key, "in PerspectiveCamera (fields: center, direction, up, angle, in this order)")
        fields[key] = ts.vec3(key)
        if key != "center":
            nonzero(ts, fields[key], f"camera {key}", tok.loc)
    angle_tok = ts.expect("angle", "in PerspectiveCamera (fields: center, direction, up, angle, in this order)")
    angle = ts.number("angle")
    rad = np.float32(math.pi * float(np.float32(angle)) / 180.0)  # as the camera stores it (B.2)
    tiny = float(np.finfo(np.float32).tiny)  # Mitsuba flushes float32 subnormals to 0
    with np.errstate(over="ignore"):
        focal = np.float32(1.0 / math.tan(float(rad) * 0.5)) if 0.0 < float(rad) < math.pi else np.float32(np.inf)
    if not (0.0 < angle < 180.0 and abs(np.float32(angle)) >= tiny and float(rad) >= tiny and np.isfinite(focal)):
        raise ts.semantic_error(f"camera angle must be between 0 and 180 degrees (in float32), found {angle:g}",
                                angle_tok.loc)
    with np.errstate(over="ignore"):
        focal_sq = focal * focal  # the camera ray's |d|² before normalising (B.2), in float32
    if not np.isfinite(focal_sq):  # below ~6.2e-18 degrees every ray direction is inf/NaN, in a5soln too
        raise ts.semantic_error(f"camera angle {angle:g} is too small: the camera ray's length overflows float32 "
                                "(the sample solution's precision)", angle_tok.loc)
    w = np.asarray(fields["direction"])
    if np.linalg.norm(np.cross(w, np.asarray(fields["up"]))) == 0.0:
        raise ts.semantic_error("camera up must not be parallel to direction", tok.loc)
    try:  # the renderer's float32 basis (SPEC B.2): tiny, huge or nearly parallel vectors fail only there
        camera_basis(fields["direction"], fields["up"])
    except ValueError:
        raise ts.semantic_error("camera direction and up do not define a basis in float32 (the sample solution's "
                                "precision): too small, too large (|x|·|x| > 3.4e38) or nearly parallel",
                                tok.loc) from None
    aperture, focus = ext_parser.parse_camera_lens(ts)  # docs/EXTENSIONS.md E.3; reads the closing '}'
    return Camera(fields["center"], fields["direction"], fields["up"], angle, start.loc, aperture, focus)


# -- A.3 ------------------------------------------------------------------------------------------------
def parse_directional_light(ts: TokenStream, start: Token) -> DirectionalLight:
    """``DirectionalLight { direction V3 color V3 }`` in this order (A.3)."""
    direction, color = vector_then(ts, "DirectionalLight", ("direction", "color"), "light direction", ts.vec3)
    return DirectionalLight(direction, color, start.loc)


def _position(ts: TokenStream, tok: Token, p: PointLightBuilder) -> None:
    p.position = ts.vec3(tok.text)


def _light_color(ts: TokenStream, tok: Token, p: PointLightBuilder) -> None:
    p.color = ts.vec3(tok.text)


def _falloff(ts: TokenStream, tok: Token, p: PointLightBuilder) -> None:
    """``falloff F >= 0``: colour / (1 + falloff d²) would grow with distance and divide by zero at
    d = 1/sqrt(-falloff)."""
    falloff = ts.number("falloff")
    if falloff < 0.0:
        raise ts.semantic_error(f"PointLight falloff must not be negative, found {falloff:g}", tok.loc)
    p.falloff = falloff


POINT_LIGHT_RULES: Final[dict[str, Rule[PointLightBuilder]]] = {
    "position": _position, "color": _light_color, "falloff": _falloff}


def parse_point_light(ts: TokenStream, start: Token) -> PointLight:
    """``PointLight { position V3 color V3 [falloff F] }``, keywords in any order until ``}`` (A.3)."""
    ts.expect("{", "after 'PointLight'")
    p = PointLightBuilder()
    keyword_block(ts, POINT_LIGHT_RULES, p, lambda tok: ts.syntax_error(
        f"expected {', '.join(POINT_LIGHT_RULES)} or '}}' in PointLight, found {quoted(tok)}", tok))
    for key, value in (("position", p.position), ("color", p.color)):
        if value is None:
            ts.warn(start.loc, f"PointLight has no {key}; using 0 0 0 as the sample solution does")
    return p.build(start.loc)


def parse_lights(ts: TokenStream, start: Token) -> tuple[Light, ...]:
    """``Lights { numLights I <light>* }`` with exactly ``numLights`` lights (A.3; EXTENSIONS E.1, E.2)."""
    return counted_block(ts, "Lights", "numLights", "light",
                         {"DirectionalLight": parse_directional_light, "PointLight": parse_point_light,
                          **ext_parser.LIGHTS})


# -- A.4 ------------------------------------------------------------------------------------------------
def _background_color(ts: TokenStream, tok: Token, b: BackgroundBuilder) -> None:
    b.color = ts.vec3(tok.text)


def _ambient_light(ts: TokenStream, tok: Token, b: BackgroundBuilder) -> None:
    b.ambient_light = ts.vec3(tok.text)


def _cube_map(ts: TokenStream, tok: Token, b: BackgroundBuilder) -> None:
    name = ts.name(tok.text)
    b.cube_map, b.cube_map_loc = name.text, name.loc


BACKGROUND_RULES: Final[dict[str, Rule[BackgroundBuilder]]] = {
    "color": _background_color, "ambientLight": _ambient_light, "cubeMap": _cube_map}


def parse_background(ts: TokenStream, start: Token) -> Background:
    """``Background { (color V3 | ambientLight V3 | cubeMap NAME)* }`` in any order (A.4)."""
    ts.expect("{", "after 'Background'")
    b = BackgroundBuilder()
    keyword_block(ts, BACKGROUND_RULES, b, unknown_keyword(ts, "Background", tuple(BACKGROUND_RULES)))
    return b.build(start.loc)


# -- A.5 ------------------------------------------------------------------------------------------------
def _noise_color(ts: TokenStream, tok: Token, n: NoiseBuilder) -> None:
    if len(n.colors) == 2:
        raise ts.syntax_error("Noise takes two colors, found a third 'color'", tok)
    n.colors.append(ts.vec3("color"))


def _octaves(ts: TokenStream, tok: Token, n: NoiseBuilder) -> None:
    octaves, oct_tok = ts.integer("octaves")
    if not 0 <= octaves <= 31:
        raise ts.semantic_error(f"octaves must be between 0 and 31, found {octaves}", oct_tok.loc)
    n.octaves = octaves


def _frequency(ts: TokenStream, tok: Token, n: NoiseBuilder) -> None:
    n.frequency = ts.number(tok.text)


def _amplitude(ts: TokenStream, tok: Token, n: NoiseBuilder) -> None:
    n.amplitude = ts.number(tok.text)


NOISE_RULES: Final[dict[str, Rule[NoiseBuilder]]] = {
    "color": _noise_color, "octaves": _octaves, "frequency": _frequency, "amplitude": _amplitude}


def parse_noise(ts: TokenStream, start: Token) -> Noise:
    """``Noise { color V3 (twice) octaves I frequency F amplitude F }`` in any order (A.5, B.4)."""
    ts.expect("{", "after 'Noise'")
    n = NoiseBuilder()
    keyword_block(ts, NOISE_RULES, n, unknown_keyword(ts, "Noise", tuple(NOISE_RULES)))
    if len(n.colors) < 2:
        ts.warn(start.loc, f"Noise has {len(n.colors)} of its 2 colors; the missing ones are 0 0 0")
    return n.build(start.loc)


def _diffuse_color(ts: TokenStream, tok: Token, m: MaterialBuilder) -> None:
    m.diffuse_color = ts.vec3(tok.text)


def _specular_color(ts: TokenStream, tok: Token, m: MaterialBuilder) -> None:
    m.specular_color = ts.vec3(tok.text)


def _shininess(ts: TokenStream, tok: Token, m: MaterialBuilder) -> None:
    m.shininess = ts.number(tok.text)


def _refraction_index(ts: TokenStream, tok: Token, m: MaterialBuilder) -> None:
    """``refractionIndex F >= 0``, or ``refractionIndex dispersion A B`` (EXTENSIONS E.10)."""
    if ext_parser.parse_dispersion(ts, tok, m):
        return
    n = ts.number(tok.text)
    if n < 0.0:
        raise ts.semantic_error(f"refractionIndex must not be negative, found {n:g}", tok.loc)
    if n * n > float(np.finfo(np.float32).max):  # Snell's (n/nt)² (1 - c²) = inf x 0 = NaN leaving it, a5soln too
        raise ts.semantic_error(f"refractionIndex {n:g} is too large: its square overflows float32 (the sample "
                                "solution's precision; at most 1.8e19)", tok.loc)
    m.refraction_index = n


def _texture(ts: TokenStream, tok: Token, m: MaterialBuilder) -> None:
    name = ts.name(tok.text)
    m.texture, m.texture_loc = name.text, name.loc


def _bump(ts: TokenStream, tok: Token, m: MaterialBuilder) -> None:
    """``bump NAME``: a5soln ignores it; EXTENSIONS E.7 uses it with ``-bump``."""
    name = ts.name(tok.text)
    m.bump, m.bump_loc = name.text, name.loc


def _noise(ts: TokenStream, tok: Token, m: MaterialBuilder) -> None:
    if m.solid is not None:  # docs/EXTENSIONS.md E.6: one procedural colour source
        raise ts.semantic_error("a Material takes one of Noise, Wood, Turbulence, Veins; found 'Noise' after another",
                                tok.loc)
    m.noise = parse_noise(ts, tok)


#: The keywords of ``Material`` and their rules: A.5's, then the extensions' (in the order messages list them).
MATERIAL_RULES: Final[dict[str, Rule[MaterialBuilder]]] = {
    "diffuseColor": _diffuse_color, "specularColor": _specular_color, "shininess": _shininess,
    "refractionIndex": _refraction_index, "texture": _texture, "bump": _bump, "Noise": _noise,
    **ext_parser.MATERIAL_RULES}


def parse_material(ts: TokenStream, start: Token) -> Material:
    """``Material { ... }`` (or ``PhongMaterial``): the keywords of :data:`MATERIAL_RULES` in any order until
    ``}`` (A.5); every keyword is consumed or reported (A.5's "an unknown word ends a Material" is an error)."""
    ts.expect("{", f"after '{start.text}'")
    m = MaterialBuilder(start.loc)
    keyword_block(ts, MATERIAL_RULES, m, unknown_keyword(ts, "Material", tuple(MATERIAL_RULES)))
    return m.build()


def parse_materials(ts: TokenStream, start: Token) -> tuple[Material, ...]:
    """``Materials { numMaterials I Material{...}* }`` with exactly ``numMaterials`` entries (A.5)."""
    return counted_block(ts, "Materials", "numMaterials", "material",
                         {"Material": parse_material, "PhongMaterial": parse_material})


# -- A.1 ------------------------------------------------------------------------------------------------
def _camera_block(ts: TokenStream, tok: Token, s: SceneBuilder) -> None:
    s.camera = parse_camera(ts, tok)


def _lights_block(ts: TokenStream, tok: Token, s: SceneBuilder) -> None:
    s.lights = parse_lights(ts, tok)
    if not s.lights:
        ts.warn(tok.loc, "no lights: the ambient light is forced to 1 1 1 (as the sample solution does)")


def _background_block(ts: TokenStream, tok: Token, s: SceneBuilder) -> None:
    s.background = parse_background(ts, tok)


def _materials_block(ts: TokenStream, tok: Token, s: SceneBuilder) -> None:
    s.materials = parse_materials(ts, tok)
    s.group.num_materials = len(s.materials)
    s.group.materials_line = tok.loc.line
    if s.root is not None:
        ts.warn(tok.loc, "Materials block after the Group: the group keeps the materials it was parsed "
                         "with (as the sample solution does)")


def _group_block(ts: TokenStream, tok: Token, s: SceneBuilder) -> None:
    s.root = parse_group(ts, tok, s.group)  # A.6: one "current material" for the whole file
    s.group_materials = s.materials


def _animation_block(ts: TokenStream, tok: Token, s: SceneBuilder) -> None:
    s.animation = keyframes.parse_animation(ts, tok)  # docs/EXTENSIONS.md E.11


def _medium_block(ts: TokenStream, tok: Token, s: SceneBuilder) -> None:
    """docs/EXTENSIONS.md E.8, E.9: at most one medium."""
    if s.medium is not None:
        raise ts.semantic_error(f"a scene has at most one medium (Fog or Volume); {tok.text} follows the "
                                f"one at line {s.medium.loc.line}", tok.loc)
    s.medium = ext_parser.MEDIA[tok.text](ts, tok)


#: The top-level blocks and their rules: A.1's five, ``Animation`` (E.11), ``Fog`` and ``Volume`` (E.8, E.9).
BLOCK_RULES: Final[dict[str, Rule[SceneBuilder]]] = {
    "PerspectiveCamera": _camera_block, "Lights": _lights_block, "Background": _background_block,
    "Materials": _materials_block, "Group": _group_block, keyframes.KEYWORD: _animation_block,
    **{medium: _medium_block for medium in ext_parser.MEDIA}}


def parse_tokens(ts: TokenStream) -> Scene:
    """The top level (A.1): any sequence of the blocks; a repeated block replaces the earlier one, except that
    the ``Group`` keeps the ``Materials`` it was parsed with."""
    s = SceneBuilder()
    while (tok := ts.next()) is not None:
        rule = BLOCK_RULES.get(tok.text)
        if rule is None:
            raise ts.syntax_error(f"expected {one_of(TOP_LEVEL)}, found '{shown(tok.text)}'", tok)
        if tok.text not in ext_parser.MEDIA:
            earlier = s.blocks.get(tok.text)
            if earlier is not None and not (tok.text == "Materials" and s.root is not None):
                ts.warn(tok.loc, f"second {tok.text} block replaces the one at line {earlier.loc.line}")
            s.blocks[tok.text] = tok
        rule(ts, tok, s)
    if s.camera is None:
        raise ts.syntax_error("expected a PerspectiveCamera block somewhere in the file, found end of file", None)
    if s.root is None:
        raise ts.syntax_error("expected a Group block somewhere in the file, found end of file", None)
    if "Lights" not in s.blocks:
        ts.warn(ts.eof_loc, "no Lights block: the ambient light is forced to 1 1 1 (as the sample solution does)")
    materials = s.group_materials if s.group_materials is not None else s.materials
    scene = Scene(path=ts.path, camera=s.camera, lights=s.lights, background=s.background,
                  materials=materials or (), root=s.root, warnings=tuple(ts.warnings), medium=s.medium,
                  animation=s.animation)
    keyframes.check(ts, scene)  # E.11: the tracks' targets exist (the whole scene is known only now)
    return scene


def parse_text(text: str, path: str = "<string>") -> Scene:
    """Parse scene text; ``path`` is used in positions and to resolve relative file names later."""
    if not isinstance(text, str):
        raise TypeError(f"parse_text expects str, not {type(text).__name__}")
    if not text.strip():
        raise SceneSyntaxError("empty scene file: expected " + one_of(TOP_LEVEL) + ", found end of file",
                               FileLoc(path, 1, 1), "")
    ts = TokenStream(text, path)
    if not path.endswith(".txt") and path != "<string>":
        ts.warn(FileLoc(path, 1, 1), "scene file name does not end in '.txt' (the sample solution refuses it)")
    return parse_tokens(ts)


def parse_file(path: str | Path) -> Scene:
    """Read and parse a scene file (SPEC A); see :func:`parse_text`."""
    return parse_text(read_source(path), str(path))

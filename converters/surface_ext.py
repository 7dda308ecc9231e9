"""View-dependent textures and milled surfaces in ``Material`` (docs/EXTENSIONS.md E.19, E.20).

Grammar (rules of :data:`MATERIAL_RULES`, merged into ``Material``'s by :mod:`.ext_parser`)::

    btf    { images NAME elevations F+ azimuths F+ }
    milled { alphaU F alphaV F [color V3] pattern (straight | circular) axis V3 [center V3] }

``images`` is a file-name pattern with two integer conversions (``btf/stone_%02d_%02d.png``): image ``(i, j)``
is the file ``NAME % (i, j)``, seen from elevation number ``i`` and azimuth number ``j`` (from 0). Elevations are
the polar angles of the view direction from the normal in degrees, strictly increasing in [0, 90]; azimuths are
angles from the tangent ``T`` towards ``B`` (E.7's frame), strictly increasing in [0, 360). ``btf`` is the
material's colour source on shapes with uv (like ``texture``), so a Material with ``btf`` takes no ``texture``,
``Noise`` or solid block. Here: the rules, the description step (:func:`describe_btf`: each image read once,
errors at the pattern) and the BSDF dicts (:func:`btf_texture`, :func:`milled_bsdf`, :func:`stock_milled`); the
model (:class:`.surface_model.Btf`, :class:`.surface_model.Milled`) lives apart. Pure Python: no Mitsuba import.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Final

from a5mi.converters.errors import FileLoc, SceneSemanticError
from a5mi.converters.surface_model import PATTERNS, Btf, Milled
from a5mi.converters.tokens import FLOAT_RE, Rule, TokenStream, block_keys

if TYPE_CHECKING:
    from a5mi.converters.builders import MaterialBuilder
    from a5mi.converters.files import Decoded, Image
    from a5mi.converters.lexer import Token
    from a5mi.converters.model import Material, Scene

#: ``%d`` / ``%02d`` conversions (and ``%%``) of an ``images`` pattern.
_CONVERSION: Final = re.compile(r"%(?:%|0?[0-9]*d)")


@dataclass(frozen=True, eq=False)
class BtfImages:
    """A described :class:`Btf`: its decoded images, ``images[i * len(azimuths) + j]`` for ``(i, j)``."""

    images: tuple[Image, ...]
    elevations: tuple[float, ...]
    azimuths: tuple[float, ...]
    loc: FileLoc


# ----------------------------------------------------------------------------------------------- the rules
def _numbers(ts: TokenStream, key: str) -> list[float]:
    """``F+``: one number or more, up to the next word that is not a number."""
    out = [ts.number(key)]
    while (tok := ts.peek()) is not None and FLOAT_RE.fullmatch(tok.text):
        out.append(ts.number(key))
    return out


def _increasing(ts: TokenStream, values: list[float], lo: float, hi: float, hi_open: bool, what: str,
                loc: FileLoc) -> tuple[float, ...]:
    inside = all(lo <= v < hi if hi_open else lo <= v <= hi for v in values)
    rising = all(a < b for a, b in zip(values, values[1:], strict=False))
    if not (inside and rising):
        bound = f"[{lo:g}, {hi:g}{')' if hi_open else ']'}"
        raise ts.semantic_error(f"btf {what} must increase strictly within {bound} degrees, found "
                                f"{' '.join(f'{v:g}' for v in values)}", loc)
    return tuple(values)


def _btf(ts: TokenStream, tok: Token, m: MaterialBuilder) -> None:
    """E.19: ``btf { images NAME elevations F+ azimuths F+ }``, the keywords in this order."""
    if m.btf is not None:
        raise ts.syntax_error("a Material takes one 'btf'", tok)
    ts.expect("{", "after 'btf'")
    ts.expect("images", "in btf (fields: images, elevations, azimuths)")
    name = ts.name("images")
    convs = [c for c in _CONVERSION.findall(name.text) if c != "%%"]
    if len(convs) != 2 or "%" in _CONVERSION.sub("", name.text):
        raise ts.semantic_error(f"btf images '{name.text}' needs two integer conversions (elevation, azimuth), "
                                "such as btf_%02d_%02d.png", name.loc)
    e_tok = ts.expect("elevations", "after the btf images")
    elevations = _increasing(ts, _numbers(ts, "elevations"), 0.0, 90.0, False, "elevations", e_tok.loc)
    a_tok = ts.expect("azimuths", "after the btf elevations")
    azimuths = _increasing(ts, _numbers(ts, "azimuths"), 0.0, 360.0, True, "azimuths", a_tok.loc)
    ts.expect("}", "to close btf")
    m.btf = Btf(name.text, name.loc, elevations, azimuths, tok.loc)


_MILLED_KINDS: Final = {"alphaU": "number", "alphaV": "number", "color": "vec3", "pattern": "word", "axis": "vec3",
                        "center": "vec3"}


def _milled(ts: TokenStream, tok: Token, m: MaterialBuilder) -> None:
    """E.20: ``milled { alphaU F alphaV F [color V3] pattern P axis V3 [center V3] }``, any order, each once."""
    if m.milled is not None:
        raise ts.syntax_error("a Material takes one 'milled'", tok)
    ts.expect("{", "after 'milled'")
    values: dict[str, Any] = {}
    locs: dict[str, FileLoc] = {}
    for key in block_keys(ts, "milled", _MILLED_KINDS):
        kind = _MILLED_KINDS[key.text]
        locs[key.text] = key.loc
        if kind == "number":   # a range error sits at the number
            values[key.text], num = ts.number_at(key.text)
            locs[key.text] = num.loc
        elif kind == "vec3":
            values[key.text] = ts.vec3(key.text)
        else:
            word = ts.name(key.text)
            if word.text not in PATTERNS:
                raise ts.syntax_error(f"milled pattern must be straight or circular, found '{word.text}'", word)
            values[key.text] = word.text
    for req in ("alphaU", "alphaV", "pattern", "axis"):
        if req not in values:
            raise ts.semantic_error(f"milled needs '{req}'", tok.loc)
    for a in ("alphaU", "alphaV"):
        if not 0.0 < values[a] <= 1.0:
            raise ts.semantic_error(f"milled {a} must be in (0, 1], found {values[a]:g}", locs[a])
    if not any(values["axis"]):
        raise ts.semantic_error("milled axis must not be the zero vector", locs["axis"])
    if "center" in values and values["pattern"] != "circular":
        raise ts.semantic_error("milled center is only used by pattern circular", locs["center"])
    m.milled = Milled(values["alphaU"], values["alphaV"], values.get("color", (1.0, 1.0, 1.0)), values["pattern"],
                      values["axis"], values.get("center", (0.0, 0.0, 0.0)), tok.loc)


MATERIAL_RULES: Final[dict[str, Rule[MaterialBuilder]]] = {"btf": _btf, "milled": _milled}


# --------------------------------------------------------------------------------------------- description
def describe_btf(scene: Scene, mat: Material, decoded: Decoded) -> BtfImages:
    """The images of ``mat.btf``, resolved like a texture (the scene's folder, then the working directory) and
    decoded once (:func:`.files.read_image`, errors at the ``images`` name); a Material with ``btf`` and another
    colour source (``texture``, ``Noise``, a solid) is an error at ``btf``."""
    from a5mi.converters.files import read_image, resolve_path

    def read(name: str) -> Image:
        return read_image(resolve_path(name, scene.base_dir, btf.images_loc, "btf image"), btf.images_loc,
                          "btf image", decoded)

    btf = mat.btf
    assert btf is not None
    other = "texture" if mat.texture is not None else "Noise" if mat.noise is not None else \
        "a solid block" if getattr(mat, "solid", None) is not None else None
    if other is not None:
        raise SceneSemanticError(f"a Material takes one colour source: 'btf' and {other}", btf.loc)
    images = tuple(read(btf.file_name(i, j))
                   for i in range(len(btf.elevations)) for j in range(len(btf.azimuths)))
    return BtfImages(images, btf.elevations, btf.azimuths, btf.loc)


# --------------------------------------------------------------------------------------------- BSDF dicts
def btf_texture(btf: BtfImages, image: Callable[[Image], dict[str, Any]]) -> dict[str, Any]:
    """The ``a5_btf`` texture: ``elevations``, ``azimuths`` (strings of degrees) and per image ``(i, j)`` the
    ``filename_i_j`` or ``bitmap_i_j`` of ``image``."""
    d: dict[str, Any] = {"type": "a5_btf", "elevations": " ".join(repr(float(e)) for e in btf.elevations),
                         "azimuths": " ".join(repr(float(a)) for a in btf.azimuths)}
    n_az = len(btf.azimuths)
    for k, img in enumerate(btf.images):
        for key, value in image(img).items():
            d[f"{key}_{k // n_az}_{k % n_az}"] = value
    return d


def milled_bsdf(milled: Milled, inner: dict[str, Any]) -> dict[str, Any]:
    """``a5_milled`` around the material's ``a5_material`` dict ``inner`` (its a5 channel, forwarded)."""
    return {"type": "a5_milled", "alpha_u": float(milled.alpha_u), "alpha_v": float(milled.alpha_v),
            "specular_reflectance": {"type": "rgb", "value": [float(c) for c in milled.color]},
            "pattern": milled.pattern, "axis": [float(c) for c in milled.axis],
            "center": [float(c) for c in milled.center], "bsdf": inner}


def stock_milled(milled: Milled, kd_max: float, diffuse_of: Callable[[float], dict[str, Any]]) -> dict[str, Any]:
    """The stock approximation: ``roughconductor`` (Beckmann, ``alpha_u``/``alpha_v``, no Fresnel: ``material
    = 'none'``, reflectance ``color``) on the shape's own uv tangent (no tangent field), blended with the
    Lambert part as materials.py blends a mirror: ``d = max kd``, ``m = max color``, weight ``m/(d + m)``,
    ``s = min(d + m, 1)``, ``diffuse_of(s/d)`` the stock ``diffuse`` scaled by ``s/d`` and the lobe's reflectance
    ``color·s/m``, so the blend is the a5 sum ``kd/π + ρs f`` where ``d + m <= 1``."""
    m = max(max(milled.color), 0.0)
    d = max(kd_max, 0.0)
    s = min(d + m, 1.0) if d > 0.0 else 1.0
    spec = [float(c) * s / m for c in milled.color] if m > 0.0 else [0.0, 0.0, 0.0]
    rough = {"type": "roughconductor", "distribution": "beckmann", "alpha_u": float(milled.alpha_u),
             "alpha_v": float(milled.alpha_v), "material": "none",
             "specular_reflectance": {"type": "rgb", "value": spec}}
    if d <= 0.0:
        return rough
    if m <= 0.0:
        return diffuse_of(1.0)
    return {"type": "blendbsdf", "weight": m / (d + m), "bsdf_0": diffuse_of(s / d), "bsdf_1": rough}


STOCK_WARNING: Final = ("stock conversion: milled replaced by roughconductor (Beckmann, alpha_u/alpha_v) on the "
                        "shape's uv tangent: Ward's shadowing term 1/(wi·h)² and the milling tangent field differ")
STOCK_BTF_WARNING: Final = "stock conversion: btf replaced by its first image (elevation 0, azimuth 0)"

"""Material descriptions -> Mitsuba BSDF dicts (SPEC A.5, B.3, B.4): the a5 plugins, or stock approximations.

a5 (:func:`a5_bsdf`): ``a5_material`` (contract in ARCHITECTURE.md) with ``kd`` = ``a5_marble`` (Noise), else
``a5_bitmap`` (texture) on shapes with uv, else the diffuse colour. A textured material used on a shape
without uv (sphere, plane, triangle, OBJ without ``vt``) gets a second BSDF without the texture: SPEC B.3's
"texture(uv) only if the hit has uv" (:meth:`.describe.MaterialDescription.kd_on`).

Stock (:func:`stock_bsdf`, for use outside a5mi; none is needed for a5 renders):

* ``diffuse`` (reflectance = kd) when ``|specularColor| ≤ 0.001`` (:data:`a5mi.spec.MIRROR_THRESHOLD`) and
  ``refractionIndex = 0``; otherwise the a5 sum ``kd·D + ks·M`` (D: the diffuse response, M: the mirror or
  the dielectric, SPEC B.3) as a ``blendbsdf`` of a ``diffuse`` and a perfect mirror (``conductor``,
  ``material='none'``) or, for ``refractionIndex n > 0``, a ``dielectric`` (``int_ior = n``, ``ext_ior = 1``;
  a dispersive ``n(λ) = A + B/λ²`` uses ``n`` at 550 nm, docs/EXTENSIONS.md E.10).
  With ``d = max kd`` and ``m = max ks``: weight ``w = m/(d + m)``, diffuse reflectance ``kd·s/d``, specular
  reflectance (and transmittance) ``ks·s/m``, ``s = min(d + m, 1)``. So ``(1 − w)·kd·s/d = kd·s/(d + m)`` and
  ``w·ks·s/m = ks·s/(d + m)``: exactly the a5 sum when ``d + m ≤ 1``, else the a5 sum divided by ``d + m``
  (energy conservation); both colours survive (a coloured diffuse under a white mirror keeps its hue).
  ``d = 0`` (clear glass, black mirrors) gives the mirror/dielectric alone. A texture (``d`` = its largest
  texel) is kept unscaled, so its diffuse part is ``kd·d/(d + m)`` instead;
* textures: stock ``bitmap`` with ``raw=True``, ``filter_type='bilinear'``, ``wrap_mode='clamp'`` and ``to_uv`` =
  ``(u, v) -> (u, 1 − v)`` (:data:`FLIP_V`: Mitsuba's bitmap puts v = 0 on the top row, A.4 on the bottom one, and
  Mitsuba's own OBJ loader flips v to compensate, which these meshes built from the OBJ's numbers do not): it
  has Mitsuba's half-texel offset, unlike A.4; Noise (3D marble): the mean colour ``(color1 + color2)/2`` (the
  mean of ``t`` over a period of the sine; :func:`.describe.describe` warns with ``stock=True``);
  procedural solids (docs/EXTENSIONS.md E.6): the ``a5_solid`` texture as the reflectance of the stock BSDF,
  unscaled like a bitmap texture, which the back end then bakes into the stock ``volume`` texture of an RGB grid
  (:meth:`.to_mitsuba.Backend.stock_solids`), so the stock scene needs no a5mi plugin;
* bump and normal maps (E.7, with ``-bump``, on shapes with uv): the BSDF wrapped in stock ``bumpmap``
  (``scale = bumpScale``, the height field as a grey ``bitmap``, ``raw``) / ``normalmap`` (the map as a raw
  ``bitmap``); both use Mitsuba's bilinear lookup with its half-texel offset and ``2c − 1`` decoding.

Images enter the dicts through an ``image`` callback (:data:`ImageParams`): the XML names the file
(:func:`file_params`), ``to_dict`` hands the decoded pixels over as an ``mi.Bitmap``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from a5mi.converters.describe import MaterialDescription
from a5mi.converters.ext_mitsuba import centre_index, rough
from a5mi.converters.files import Image
from a5mi.converters.model import Noise, Solid
from a5mi.converters.surface_ext import BtfImages, btf_texture, milled_bsdf, stock_milled
from a5mi.spec import MIRROR_THRESHOLD

#: ``(image) -> the image parameters of a bitmap texture`` (``{'filename': ...}`` or ``{'bitmap': ...}``).
ImageParams = Callable[[Image], dict[str, Any]]

#: The stock ``bitmap``'s ``to_uv``: ``(u, v) -> (u, 1 − v)``, A.4's rows from the bottom (module docstring).
FLIP_V = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, -1.0, 0.0, 1.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]])


def stock_bitmap(image: Image, params: ImageParams) -> dict[str, Any]:
    """The stock ``bitmap`` texture of an A.4 image (module docstring: raw, bilinear, clamp, v flipped)."""
    return {"type": "bitmap", **params(image), "raw": True, "filter_type": "bilinear", "wrap_mode": "clamp",
            "to_uv": FLIP_V.copy()}


def rgb(c: Any) -> dict[str, Any]:
    """``{'type': 'rgb', 'value': [r, g, b]}``."""
    return {"type": "rgb", "value": [float(x) for x in c]}


def reflectance(c: Any) -> dict[str, Any]:
    """A stock reflectance parameter of colour ``c``: :func:`rgb` inside [0, 1]; outside (SPEC A.5 sets no
    range, a5soln renders 1.5 as it is) an ``srgb`` texture with ``unbounded=True``, which Mitsuba accepts
    for any finite value (a plain rgb reflectance outside [0, 1] is a load error)."""
    value = rgb(c)
    if all(0.0 <= x <= 1.0 for x in value["value"]):
        return value
    return {"type": "srgb", "color": value, "unbounded": True}


def file_params(image: Image) -> dict[str, Any]:
    """``{'filename': absolute path}``: the image named by its file (XML)."""
    return {"filename": str(image.path)}


def without_texture(mat: MaterialDescription, with_uv: bool) -> bool:
    """True for the second, untextured BSDF of a textured material on a shape without uv (SPEC B.3); bump and
    normal maps (docs/EXTENSIONS.md E.7) are textures in this sense."""
    return (isinstance(mat.kd, Image) or mat.has_maps) and not with_uv


def solid_texture(solid: Solid) -> dict[str, Any]:
    """The ``a5_solid`` texture of a ``Wood`` / ``Turbulence`` / ``Veins`` block (docs/EXTENSIONS.md E.6)."""
    return {"type": "a5_solid", "kind": solid.kind, "color1": rgb(solid.color1), "color2": rgb(solid.color2),
            "octaves": int(solid.octaves), "frequency": float(solid.frequency), "amplitude": float(solid.amplitude),
            "scale": float(solid.scale), "axis": [float(x) for x in solid.axis],
            "center": [float(x) for x in solid.center]}


def map_params(mat: MaterialDescription, with_uv: bool, image: ImageParams) -> dict[str, Any]:
    """``a5_material``'s ``bump`` (+ ``bump_scale``) and ``normal_map`` textures (E.7), on shapes with uv."""
    if not with_uv:
        return {}
    d: dict[str, Any] = {}
    if mat.bump is not None:
        d["bump"] = {"type": "a5_bitmap", **image(mat.bump)}
        d["bump_scale"] = float(mat.bump_scale)
    if mat.normal_map is not None:
        d["normal_map"] = {"type": "a5_bitmap", **image(mat.normal_map)}
    return d


def stock_maps(mat: MaterialDescription, with_uv: bool, bsdf: dict[str, Any], image: ImageParams) -> dict[str, Any]:
    """``bsdf`` wrapped in the stock ``normalmap`` and then ``bumpmap`` adapters of the module docstring."""
    if not with_uv:
        return bsdf
    if mat.normal_map is not None:
        bsdf = {"type": "normalmap", "normalmap": stock_bitmap(mat.normal_map, image), "bsdf": bsdf}
    if mat.bump is not None:
        bsdf = {"type": "bumpmap", "scale": float(mat.bump_scale), "bsdf": bsdf,
                "height": stock_bitmap(mat.bump, image)}
    return bsdf


def a5_bsdf(mat: MaterialDescription, with_uv: bool, image: ImageParams = file_params) -> dict[str, Any]:
    """``a5_material`` (contract in ARCHITECTURE.md); ``kd`` = marble, else bitmap (only ``with_uv``)."""
    d: dict[str, Any] = {
        "type": "a5_material",
        "diffuse_color": rgb(mat.diffuse_color),
        "specular_color": rgb(mat.specular_color),
        "shininess": float(mat.shininess),
        "refraction_index": float(mat.refraction_index),
    }
    if mat.roughness > 0.0:  # docs/EXTENSIONS.md E.4
        d["roughness"] = float(mat.roughness)
        d["glossy_samples"] = int(mat.glossy_samples)
    if mat.dispersion is not None:  # docs/EXTENSIONS.md E.10: refraction_index is Cauchy's A
        d["cauchy_b"] = float(mat.dispersion)
    if mat.subsurface is not None:  # docs/EXTENSIONS.md E.18 (read by a5_whitted with -subsurface only)
        sss = mat.subsurface
        d.update({"sss_sigma_a": rgb(sss.sigma_a), "sss_sigma_s": rgb(sss.sigma_s), "sss_eta": float(sss.eta),
                  "sss_g": float(sss.g), "sss_samples": int(sss.samples)})
    kd = mat.kd_on(with_uv)
    if isinstance(kd, Noise):
        d["kd"] = {"type": "a5_marble", "color1": rgb(kd.color1), "color2": rgb(kd.color2),
                   "octaves": int(kd.octaves), "frequency": float(kd.frequency), "amplitude": float(kd.amplitude)}
    elif isinstance(kd, Solid):  # docs/EXTENSIONS.md E.6
        d["kd"] = solid_texture(kd)
    elif isinstance(kd, Image):
        d["kd"] = {"type": "a5_bitmap", **image(kd)}
    elif isinstance(kd, BtfImages):  # docs/EXTENSIONS.md E.19
        d["kd"] = btf_texture(kd, image)
    d.update(map_params(mat, with_uv, image))  # E.7 (-bump)
    return d if mat.milled is None else milled_bsdf(mat.milled, d)  # E.20: the a5 channel forwarded


def with_marble_mistake(d: Any, mistake: str) -> Any:
    """``d`` (a BSDF dict or part of one) with every ``a5_marble`` given the ``mistake`` parameter
    (docs/MISTAKES.md, plugins/textures/marble.py)."""
    if not isinstance(d, dict):
        return d
    out = {k: with_marble_mistake(v, mistake) for k, v in d.items()}
    if out.get("type") == "a5_marble":
        out["mistake"] = mistake
    return out


def stock_bsdf(mat: MaterialDescription, with_uv: bool, image: ImageParams = file_params) -> dict[str, Any]:
    """Stock approximation (module docstring): diffuse, blended with a mirror or a dielectric; bump / normal
    maps as the stock adapters around it."""
    return stock_maps(mat, with_uv, _stock_bsdf(mat, with_uv, image), image)


def _stock_bsdf(mat: MaterialDescription, with_uv: bool, image: ImageParams) -> dict[str, Any]:
    kd_src = mat.kd_on(with_uv)
    texture: dict[str, Any] | None = None
    if isinstance(kd_src, Noise):
        kd = (np.asarray(kd_src.color1, dtype=np.float64) + np.asarray(kd_src.color2, dtype=np.float64)) / 2
    elif isinstance(kd_src, Solid):  # E.6: the a5 texture itself, unscaled
        kd = np.ones(3)
        texture = solid_texture(kd_src)
    elif isinstance(kd_src, (Image, BtfImages)):  # E.19: a btf's first image
        kd = np.ones(3)
        texture = stock_bitmap(kd_src if isinstance(kd_src, Image) else kd_src.images[0], image)
    else:
        kd = np.asarray(mat.diffuse_color, dtype=np.float64)
    if mat.milled is not None:  # docs/EXTENSIONS.md E.20: roughconductor on the uv tangent
        return stock_milled(mat.milled, _max_diffuse(kd_src, mat),
                            lambda s: {"type": "diffuse", "reflectance": texture or reflectance(kd * s)})
    spec = np.asarray(mat.specular_color, dtype=np.float64)
    m = float(max(spec.max(), 0.0))
    if mat.refraction_index <= 0.0 and float(np.linalg.norm(spec)) <= MIRROR_THRESHOLD or m == 0.0:
        return {"type": "diffuse", "reflectance": texture or reflectance(kd)}
    d = _max_diffuse(kd_src, mat)
    w = m / (d + m)                       # the mirror's share of the a5 sum kd·D + ks·M
    scale = min(d + m, 1.0)               # 1 when the sum fits in energy, else divide it by d + m
    # a texture cannot be scaled in stock Mitsuba: it is kept as it is
    diffuse = {"type": "diffuse", "reflectance": texture or reflectance(kd * scale / d if d > 0.0 else kd)}
    spec_refl = reflectance(spec * scale / m)
    other: dict[str, Any]
    if mat.refraction_index > 0.0:
        other = {"type": "dielectric", "int_ior": centre_index(mat.refraction_index, mat.dispersion), "ext_ior": 1.0,
                 "specular_reflectance": spec_refl, "specular_transmittance": spec_refl}
    else:
        other = {"type": "conductor", "material": "none", "specular_reflectance": spec_refl}
    other = rough(other, mat.roughness)  # docs/EXTENSIONS.md E.4: roughconductor / roughdielectric
    if d == 0.0:
        return other
    return {"type": "blendbsdf", "weight": w, "bsdf_0": diffuse, "bsdf_1": other}


def _max_diffuse(kd_src: Noise | Solid | Image | BtfImages | None, mat: MaterialDescription) -> float:
    """``d = max kd``: the largest channel of the diffuse colour, of the texture's pixels (/255) or of the
    marble's mean colour."""
    if isinstance(kd_src, (Image, BtfImages)):
        img = kd_src if isinstance(kd_src, Image) else kd_src.images[0]
        return float(img.pixels[..., :3].max()) / 255.0
    if isinstance(kd_src, Noise):
        return float(max(0.0, ((np.asarray(kd_src.color1) + np.asarray(kd_src.color2)) / 2).max()))
    if isinstance(kd_src, Solid):  # the largest channel either colour reaches
        return float(max(0.0, *kd_src.color1, *kd_src.color2))
    return float(max(0.0, max(mat.diffuse_color)))


def bsdf(mat: MaterialDescription, with_uv: bool, *, stock: bool, image: ImageParams = file_params) -> dict[str, Any]:
    """:func:`stock_bsdf` or :func:`a5_bsdf`."""
    return stock_bsdf(mat, with_uv, image) if stock else a5_bsdf(mat, with_uv, image)

"""Mitsuba entries of the distribution-ray-tracing extension (docs/EXTENSIONS.md E.1-E.4, "stock mapping").

Used by :mod:`.to_mitsuba` (and so by :mod:`.to_xml`); plain dicts, no Mitsuba import. a5 mode uses the a5mi
plugins; ``stock=True`` the physically based stock plugins, scaled to agree with the a5 light at the
distance ``D`` from the light to the centre of the scene's finite geometry (as the stock ``point`` mapping
of a PointLight does), so ``a5mi crosscheck`` compares like with like there and explains the rest:

* SpotLight -> ``a5_spot`` | stock ``spot`` (``cutoff_angle = angle``, ``beam_width = beamWidth``, the same
  profile), ``intensity = color·D²/(1 + falloff·D²)``;
* AreaLight -> a ``rectangle`` (``to_world`` maps ``[-1, 1]²`` onto the parallelogram: columns ``edge1/2``,
  ``edge2/2``, ``±n``, translation its centre) carrying ``a5_area`` and a black ``a5_material`` | the same
  rectangle with a stock ``area`` emitter, one-sided, facing the scene centre, ``radiance = color·D² /
  (A cos θ_l (1 + falloff·D²))`` (``A = |edge1 × edge2|``, ``θ_l`` the angle at the light to the centre);
* SphereLight -> a ``sphere`` carrying ``a5_area`` (``shape = sphere``) | stock ``area`` on the sphere with
  ``radiance = color·D² / (π r² (1 + falloff·D²))``;
* camera ``aperture A > 0`` -> stock ``thinlens`` with ``aperture_radius = A/2``, ``focus_distance = F``
  (a5 mode: the driver's thin lens, a5mi/render/passes.py);
* ``roughness α > 0`` -> ``roughconductor`` / ``roughdielectric`` (GGX, ``alpha = α``) in place of the mirror /
  dielectric of the stock material (converters/materials.py); not ``roughplastic``, whose Fresnel-weighted
  coat cannot reproduce the a5 sum ``kd·D + ks·M``;
* ``Fog`` (E.8) -> ``a5_whitted`` parameters ``medium = fog``, ``medium_density``, ``medium_albedo``,
  ``medium_steps`` | a stock ``homogeneous`` medium (``sigma_t = density``, ``albedo = color``, ``isotropic``
  phase) on the sensor, rendered with ``volpath``;
* ``Volume`` (E.9) -> ``medium = volume`` and ``medium_grid``, a ``gridvolume`` placed on the box (``to_world``
  maps the unit cube onto ``[min, max]``) | a stock ``heterogeneous`` medium with that ``gridvolume`` as
  ``sigma_t``, ``scale = density``, on the sensor, with ``volpath``.
* ``Wood`` / ``Turbulence`` / ``Veins`` (E.6) -> ``a5_solid`` | the solid baked (:func:`solid_box`,
  :func:`solid_resolution`, evaluated by ``a5_solid`` at the cell centres ``lo + (i + ½)/n (hi − lo)``) into an
  RGB ``gridvolume`` of at most :data:`SOLID_CELLS` cells over the box of the material's shapes, read by the
  stock ``volume`` texture (trilinear, clamped outside the box): the XML needs no a5mi plugin;
* ``refractionIndex dispersion A B`` (E.10) -> a5: ``refraction_index = A``, ``cauchy_b = B`` on ``a5_material``
  and ``dispersion = true`` on ``a5_whitted`` | stock: the RGB ``dielectric`` has no dispersion, so ``int_ior`` is
  ``n(λc) = A + B/λc²`` at the centre wavelength ``λc = 550 nm`` (:func:`centre_index`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from a5mi.converters.model import AreaLight, Fog, SphereLight, SpotLight
from a5mi.spec import CENTRE_WAVELENGTH_NM

ExtLight = SpotLight | AreaLight | SphereLight


def _rgb(c: Any) -> dict[str, Any]:
    return {"type": "rgb", "value": [float(x) for x in c]}


#: What a ray hitting an area light's shape reflects: nothing (the light adds its ``eval`` colour).
BLACK_A5 = {"type": "a5_material", "diffuse_color": _rgb((0, 0, 0)), "specular_color": _rgb((0, 0, 0))}


def _dist2(centre: np.ndarray | None, p: np.ndarray) -> float:
    return 1.0 if centre is None else max(float(np.sum((centre - p) ** 2)), 1e-12)


def _look_at(origin: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """4x4 camera-style frame at ``origin`` whose +z is ``direction`` (Mitsuba's ``look_at`` convention)."""
    z = direction / np.linalg.norm(direction)
    up = np.array([0.0, 1.0, 0.0]) if abs(z[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    x = np.cross(up, z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = x, y, z, origin
    return m


def parallelogram_to_world(light: AreaLight, towards: np.ndarray | None = None) -> np.ndarray:
    """The ``rectangle`` ``to_world`` of the module docstring; with ``towards`` the normal faces that point."""
    c, e1, e2 = (np.asarray(v, dtype=np.float64) for v in (light.corner, light.edge1, light.edge2))
    n = np.cross(e1, e2)
    n /= np.linalg.norm(n)
    centre = c + 0.5 * (e1 + e2)
    if towards is not None and float(np.dot(n, towards - centre)) < 0.0:
        n = -n
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = 0.5 * e1, 0.5 * e2, n, centre
    return m


def light_entry(light: ExtLight, centre: np.ndarray | None, *, stock: bool) -> dict[str, Any]:
    """The scene-dict entry of one extension light (module docstring)."""
    falloff = float(light.falloff)
    if isinstance(light, SpotLight):
        p, axis = np.asarray(light.position, dtype=np.float64), np.asarray(light.direction, dtype=np.float64)
        if not stock:
            return {"type": "a5_spot", "position": list(light.position), "direction": list(light.direction),
                    "color": _rgb(light.color), "falloff": falloff, "angle": float(light.angle),
                    "beam_width": float(light.beam_width)}
        d2 = _dist2(centre, p)
        return {"type": "spot", "to_world": _look_at(p, axis), "cutoff_angle": float(light.angle),
                "beam_width": float(light.beam_width),
                "intensity": _rgb(np.asarray(light.color) * d2 / (1.0 + falloff * d2))}
    if isinstance(light, AreaLight):
        e1, e2 = np.asarray(light.edge1, dtype=np.float64), np.asarray(light.edge2, dtype=np.float64)
        if not stock:
            emitter = {"type": "a5_area", "shape": "parallelogram", "corner": list(light.corner),
                       "edge1": list(light.edge1), "edge2": list(light.edge2), "color": _rgb(light.color),
                       "falloff": falloff, "samples": int(light.samples)}
            return {"type": "rectangle", "to_world": parallelogram_to_world(light), "bsdf": BLACK_A5,
                    "emitter": emitter}
        m = parallelogram_to_world(light, centre)
        mid = m[:3, 3]
        d2 = _dist2(centre, mid)
        cos_l = 1.0 if centre is None else abs(float(np.dot(m[:3, 2], centre - mid))) / math.sqrt(d2)
        area = float(np.linalg.norm(np.cross(e1, e2)))
        radiance = np.asarray(light.color) * d2 / (area * max(cos_l, 0.05) * (1.0 + falloff * d2))
        return {"type": "rectangle", "to_world": m, "emitter": {"type": "area", "radiance": _rgb(radiance)}}
    c = np.asarray(light.center, dtype=np.float64)
    sphere = {"type": "sphere", "center": list(light.center), "radius": float(light.radius)}
    if not stock:
        return {**sphere, "bsdf": BLACK_A5,
                "emitter": {"type": "a5_area", "shape": "sphere", "center": list(light.center),
                            "radius": float(light.radius), "color": _rgb(light.color), "falloff": falloff,
                            "samples": int(light.samples)}}
    d2 = _dist2(centre, c)
    radiance = np.asarray(light.color) * d2 / (math.pi * light.radius ** 2 * (1.0 + falloff * d2))
    return {**sphere, "emitter": {"type": "area", "radiance": _rgb(radiance)}}


def thinlens_params(aperture: float, focus_distance: float) -> dict[str, Any]:
    """Stock ``thinlens`` parameters of a camera with ``aperture > 0`` (module docstring)."""
    return {"aperture_radius": 0.5 * float(aperture), "focus_distance": float(focus_distance)}


def centre_index(a: float, b: float | None) -> float:
    """Cauchy's ``n(λc) = A + B/λc²`` at :data:`a5mi.spec.CENTRE_WAVELENGTH_NM` (λ in µm); ``A`` when ``B`` is
    None (a plain ``refractionIndex``). The stock index of a dispersive material (module docstring)."""
    if b is None:
        return float(a)
    lam_um = CENTRE_WAVELENGTH_NM * 1e-3
    return float(a) + float(b) / (lam_um * lam_um)


def rough(other: dict[str, Any], roughness: float) -> dict[str, Any]:
    """``conductor`` -> ``roughconductor``, ``dielectric`` -> ``roughdielectric`` (GGX, ``alpha``) for
    ``roughness > 0``; otherwise ``other`` unchanged."""
    if roughness <= 0.0:
        return other
    kind = {"conductor": "roughconductor", "dielectric": "roughdielectric"}[other["type"]]
    return {**other, "type": kind, "distribution": "ggx", "alpha": float(roughness)}


# -------------------------------------------------------------------------------------------- E.8, E.9 media
def box_to_world(box_min: Any, box_max: Any) -> np.ndarray:
    """4x4 map of the unit cube onto the box ``[box_min, box_max]`` (a ``gridvolume``'s ``to_world``)."""
    lo, hi = np.asarray(box_min, dtype=np.float64), np.asarray(box_max, dtype=np.float64)
    m = np.diag([*(hi - lo), 1.0])
    m[:3, 3] = lo
    return m


def grid_volume(medium: Any, source: dict[str, Any]) -> dict[str, Any]:
    """The ``gridvolume`` of a Volume description: ``source`` is ``{'data': tensor}`` (dict) or ``{'filename':
    path}`` (XML); trilinear, clamped, on the box."""
    return {"type": "gridvolume", **source, "filter_type": "trilinear", "wrap_mode": "clamp",
            "to_world": box_to_world(medium.box_min, medium.box_max)}


def medium_params(medium: Any, grid: dict[str, Any] | None) -> dict[str, Any]:
    """The ``a5_whitted`` parameters of a Fog (``grid`` None) or a Volume (its :func:`grid_volume`)."""
    out: dict[str, Any] = {"medium": "fog" if isinstance(medium, Fog) else "volume",
                           "medium_density": float(medium.density), "medium_albedo": _rgb(medium.color),
                           "medium_steps": int(medium.steps)}
    if grid is not None:
        out["medium_grid"] = grid
    if medium.g != 0.0:  # docs/EXTENSIONS.md E.8: Henyey-Greenstein (absent for 0: dicts and XML unchanged)
        out["medium_g"] = float(medium.g)
    return out


def stock_medium(medium: Any, grid: dict[str, Any] | None) -> dict[str, Any]:
    """The stock medium of the sensor: ``homogeneous`` (Fog) or ``heterogeneous`` (Volume), ``isotropic``
    (``hg`` with the block's ``g`` when it is not 0)."""
    phase = {"type": "isotropic"} if medium.g == 0.0 else {"type": "hg", "g": float(medium.g)}
    if isinstance(medium, Fog):
        return {"type": "homogeneous", "sigma_t": float(medium.density), "albedo": _rgb(medium.color),
                "phase": phase}
    return {"type": "heterogeneous", "sigma_t": grid, "scale": float(medium.density), "albedo": _rgb(medium.color),
            "phase": phase}


# ------------------------------------------------------------------------------------- E.6 solids, --stock
#: Cells of a baked solid's grid at most (float32 RGB: 3 MiB per material).
SOLID_CELLS = 1 << 18


def solid_box(desc: Any, material: int) -> tuple[np.ndarray, np.ndarray]:
    """The box a ``--stock`` solid texture is baked over: the union of the world boxes of the shapes of
    ``material`` (a plane's stand-in rectangle clipped to the cube of half-size ``2·max(|camera − C|, 1)``
    around the centre ``C`` of the finite geometry, where it can be seen), padded by 1e-3 of its size."""
    cam = np.asarray(desc.camera.center, dtype=np.float64)
    centre = cam if desc.centre is None else np.asarray(desc.centre, dtype=np.float64)
    reach = 2.0 * max(float(np.linalg.norm(cam - centre)), 1.0)
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    for shape in desc.shapes:
        if shape.material != material:
            continue
        if hasattr(shape, "mesh"):
            pts = np.asarray(shape.mesh.positions, dtype=np.float64).reshape(-1, 3)
        elif hasattr(shape, "rectangle"):
            corners = np.array([[x, y, 0.0, 1.0] for x in (-1, 1) for y in (-1, 1)]) @ np.asarray(shape.rectangle).T
            pts = np.clip(corners[:, :3], centre - reach, centre + reach)
        else:
            c, r = np.asarray(shape.center, dtype=np.float64), float(shape.radius)
            pts = np.array([c + [x, y, z] for x in (-r, r) for y in (-r, r) for z in (-r, r)])
            if shape.to_world is not None:
                pts = np.hstack([pts, np.ones((8, 1))]) @ np.asarray(shape.to_world).T
                pts = pts[:, :3]
        lo, hi = np.minimum(lo, pts.min(axis=0)), np.maximum(hi, pts.max(axis=0))
    if not np.all(np.isfinite(lo)):
        lo, hi = centre - 1.0, centre + 1.0
    pad = 1e-3 * max(float(np.max(hi - lo)), 1e-3)
    return lo - pad, hi + pad


def solid_resolution(lo: np.ndarray, hi: np.ndarray, cells: int = SOLID_CELLS) -> tuple[int, int, int]:
    """``(nx, ny, nz)``: cells in proportion to the box's sides ``e``, ``n_a = clamp(round(k e_a), 2, 1024)`` with
    the largest ``k`` that keeps ``nx·ny·nz <= cells`` (so a flat box spends its cells in its plane)."""
    ext = np.maximum(np.asarray(hi, dtype=np.float64) - np.asarray(lo, dtype=np.float64), 1e-12)

    def size(k: float) -> np.ndarray:
        return np.clip(np.round(k * ext), 2, 1024).astype(np.int64)

    a, b = 0.0, 1e9 / float(ext.max())
    for _ in range(100):
        k = 0.5 * (a + b)
        a, b = (k, b) if int(np.prod(size(k))) <= cells else (a, k)
    n = size(a)
    return int(n[0]), int(n[1]), int(n[2])


def baked_solid(source: dict[str, Any], lo: np.ndarray, hi: np.ndarray) -> dict[str, Any]:
    """The stock ``volume`` texture of a baked solid: an RGB ``gridvolume`` (``source``: ``{'data': tensor}``
    or ``{'filename': path}``) on the box, trilinear, clamped: ``kd(p)`` = the grid at the surface point."""
    return {"type": "volume", "volume": {"type": "gridvolume", **source, "filter_type": "trilinear",
                                         "wrap_mode": "clamp", "to_world": box_to_world(lo, hi)}}

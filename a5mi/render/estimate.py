"""The work of a render before it starts: an upper bound of the rays it may trace and the seconds they may take
(docs/USAGE.md "Work estimate"; the ray trees of SPEC B.3 and docs/EXTENSIONS.md E.2, E.4, E.5, E.14-E.17, E.23).

:func:`estimate` reads only the scene description and the options (no Mitsuba, no file), so the command layer
can refuse a render that would run for hours in well under a second. With ``C`` camera rays (render-buffer
samples ``RW · RH`` times ``-spp``; twice with ``-normals_mode quadrant``), ``B`` = ``-bounces``, ``S`` = the
light samples of one shading point (``Σ_lights samples``, 1 for a point, spot or directional light; 0 without
``-shadows``, as SPEC B.3 casts no shadow ray then) and ``L`` = the lights plus the environment (the next-event
estimation of E.13), the bound per integrator is:

* ``whitted`` (SPEC B.3, E.4, E.15): a node of the ray tree pushes, per material ``m`` used by a shape,
  ``k_m = refl_m + refr_m + N · diff_m`` children (``refl_m``: ``|specularColor| > 0.001`` and reflection on;
  ``refr_m``: ``refractionIndex > 0`` and refraction on; ``diff_m``: a diffuse colour, texture or solid, with
  ``-indirect N``), a camera hit ``k0_m = G_m (refl_m + refr_m) + N · diff_m`` (E.4's ``G = glossySamples`` for
  ``roughness > 0``). With ``k0 = max_m k0_m`` and ``k = max_m k_m`` a camera ray's tree has at most
  ``T = 1 + k0 Σ_{i<B} k^i`` nodes, each with at most ``S`` shadow rays: ``C · T · (1 + S)``;
* ``path`` (E.14): ``B + 2`` rays (the camera ray, a BSDF ray at each of the ``B + 1`` vertices) and ``L``
  shadow rays per vertex: ``C · (B + 2 + (B + 1) L)``;
* ``irradiancecache`` (E.23): the delta-lobe tree (``k`` without ``N``, ``B + 1`` levels: the kernel's stack
  depth) with ``L`` shadow rays per node, plus at most one record per diffuse camera-tree node of the first
  pass, each ``M · N`` hemisphere paths (:func:`hemisphere_rays` of ``-ic_samples``) of at most ``B + 1``
  vertices with a ray and ``L`` shadow rays each: ``C T (1 + L) + (C/spp) T · samples · (B + 1)(1 + L)``;
* ``photon`` (E.16): the camera path (``B + 1`` rays, ``L`` shadow rays and ``-final_gather M`` gather rays per
  vertex) plus ``(photons + caustic_photons) · H`` photon rays (``H`` = ``-photon_depth``, or 51 for Russian
  roulette alone: its mean hits in a lossless scene) and the 4,096
  pilot rays per light of the light powers; ``ppm`` (E.17): the same without final gather, the photon part
  once per ``-spp`` pass.

Seconds are ``rays / rate``: the rate this machine reached before (:func:`measured_rate`, kept in
``a5mi.cache_dir()/ray_rate.json`` by :func:`record_rate` after a counted render) or
:data:`CONSERVATIVE_RATE`. A leaf library: it returns data and never prints.
"""

from __future__ import annotations

import json
import math
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from a5mi.platform.resources import ROULETTE_MEAN_HITS
from a5mi.render.crop import traced_samples
from a5mi.render.options import RenderOptions
from a5mi.spec import MIRROR_THRESHOLD

if TYPE_CHECKING:
    from a5mi.converters.describe import SceneDescription
    from a5mi.converters.errors import FileLoc

#: Rays per second assumed when none was measured on this machine: a5 -v on the shared 2-core machine at load
#: 5 traced scene12_vase (300 x 300, -jitter, -shadows -bounces 4) at 3.5e6 rays/s and scene10_sphere at
#: 4.5e6 (counted rays over kernel time); about half of the slower, so the time is over-stated, not under-.
CONSERVATIVE_RATE: float = 2.0e6
#: Above this many estimated seconds ``a5`` refuses the render unless ``-force`` (one hour).
REFUSE_SECONDS: float = 3600.0
#: Above this many estimated seconds ``a5`` warns (one minute).
WARN_SECONDS: float = 60.0
#: The pilot photons per light of the light powers (plugins/integrators/photon/emit.py ``light_powers``); a
#: photon's hits are ``photon_depth``, or with Russian roulette alone (0) at most
#: :data:`a5mi.platform.resources.ROULETTE_MEAN_HITS` on average (a lossless scene).
PHOTON_PILOT: int = 4096
#: A measured rate is kept only from a render that traced at least this many rays (a tiny render's rate is
#: dominated by start-up costs and would understate the machine).
MIN_RATE_RAYS: int = 1_000_000
RATE_FILE = "ray_rate.json"


@dataclass(frozen=True)
class Estimate:
    """An upper bound of a render's rays and the seconds they may take (module docstring).

    ``camera_rays``: render-buffer samples x passes; ``per_camera_ray``: the bound of rays one camera ray may
    cause (its tree or path with shadow and gather rays); ``extra_rays``: rays not tied to a camera ray
    (photons, irradiance-cache records); ``rays``: the total bound; ``rate`` rays/s and ``measured`` (from this
    machine's cache) or not; ``cause``: what makes ``per_camera_ray`` large, in words; ``loc``: the scene
    element behind it (a material, a light, else the camera); ``hints``: the flags that reduce it."""

    camera_rays: int
    per_camera_ray: float
    extra_rays: int
    rays: float
    seconds: float
    rate: float
    measured: bool
    cause: str
    loc: FileLoc | None
    hints: tuple[str, ...]


def _used_materials(desc: SceneDescription) -> list[Any]:
    used = sorted({s.material for s in desc.shapes if 0 <= s.material < len(desc.materials)})
    return [desc.materials[i] for i in used]


def _branching(m: Any, options: RenderOptions, indirect: int, glossy: bool) -> tuple[int, int]:
    """``(k0_m, k_m)`` of the module docstring: children at a camera hit and at a deeper hit."""
    spec = sum(float(c) ** 2 for c in m.specular_color) ** 0.5
    refl = int(options.reflection and spec > MIRROR_THRESHOLD)
    refr = int(options.refraction and m.refraction_index > 0.0)
    diff = int(max(m.diffuse_color) > 0.0 or m.kd is not None)
    gloss = max(1, int(m.glossy_samples)) if glossy and m.roughness > 0.0 else 1
    return gloss * (refl + refr) + indirect * diff, refl + refr + indirect * diff


def tree_nodes(k0: int, k: int, levels: int) -> float:
    """``1 + k0 Σ_{i<levels} k^i``: the most nodes of a ray tree whose root has ``k0`` children and every
    other node ``k``, ``levels`` levels below the root."""
    if levels <= 0:
        return 1.0
    return 1.0 + k0 * (float(levels) if k == 1 else (float(k) ** levels - 1.0) / (k - 1.0))


def light_samples(desc: SceneDescription) -> tuple[int, Any]:
    """``(Σ_lights samples, the light with the most samples)``: E.2's samples of an area or sphere light, 1
    for the others."""
    total, most, where = 0, 0, None
    for light in desc.lights:
        s = int(getattr(light, "samples", 1) or 1)
        total += s
        if s > most:
            most, where = s, light
    return total, where


def hemisphere_rays(samples: int) -> int:
    """Rays of one irradiance-cache record: ``M · N`` strata, ``M = max(2, round(sqrt(samples/π)))``,
    ``N = max(3, round(samples/M))`` (docs/EXTENSIONS.md E.23, Ward and Heckbert 1992)."""
    m = max(2, int(round(math.sqrt(samples / math.pi))))
    return m * max(3, int(round(samples / m)))


def estimate(desc: SceneDescription, options: RenderOptions, *, rate: float | None = None) -> Estimate:
    """The :class:`Estimate` of rendering ``desc`` with ``options`` (module docstring); ``rate`` (rays/s)
    overrides :func:`measured_rate`."""
    separate = (options.normals or options.depth is not None) and options.aov_mode == "quadrant"
    camera = traced_samples(options) * options.spp * (2 if separate else 1)   # a -crop: its samples alone
    b = options.bounces
    lights, light = light_samples(desc)
    n_lights = len(desc.lights) + 1  # E.13: every light and the environment
    mats = _used_materials(desc)
    cam_loc = desc.camera.loc
    extra = 0
    hints: list[str] = []
    where: Any = None
    if options.integrator == "whitted":
        n = options.indirect
        pairs = [(_branching(m, options, n, True), m) for m in mats] or [((0, 0), None)]
        (k0, _), m0 = max(pairs, key=lambda p: p[0][0])
        (_, k), mk = max(pairs, key=lambda p: p[0][1])
        nodes = tree_nodes(k0, k, b)
        shadows = lights if options.shadows else 0
        per = nodes * (1 + shadows)
        where = mk if k > 1 else m0 if k0 > 1 else None
        cause = f"a ray tree of up to {_num(nodes)} nodes per camera ray"
        if k > 1:
            cause += f", {k} children per hit" + (f" with -indirect {n}" if n else "") + f", -bounces {b}"
            hints += ["-bounces"] + (["-indirect"] if n else [])
        elif k0 > 1:
            cause += f", {k0} children at the camera hit (glossySamples)"
        if shadows:
            cause += f", {shadows} shadow ray{'s' if shadows > 1 else ''} per node"
        if shadows > 1 and int(getattr(light, "samples", 1) or 1) > 1:   # E.2: an area light's samples
            if where is None:
                where = light
            hints.append("the lights' samples")
    elif options.integrator == "path":
        per = (b + 2) + (b + 1) * n_lights
        cause = f"paths of up to {_num(per)} rays per camera ray with -bounces {b}"
        hints.append("-bounces")
    elif options.integrator == "irradiancecache":
        pairs = [_branching(m, options, 0, False) for m in mats] or [(0, 0)]
        k = max(p[1] for p in pairs)
        nodes = tree_nodes(k, k, b + 1)
        per = nodes * (1 + n_lights)
        records = (camera // options.spp) * nodes
        extra = int(records * hemisphere_rays(options.ic_samples) * (b + 1) * (1 + n_lights))
        cause = (f"up to {_num(records)} cache records of {hemisphere_rays(options.ic_samples)} hemisphere paths "
                 f"(-ic_samples {options.ic_samples}, -bounces {b})")
        hints += ["-ic_samples", "-bounces"]
    else:  # photon, ppm
        gather = options.final_gather if options.integrator == "photon" else 0
        per = (b + 1) * (1 + n_lights + gather)
        maps = 1 if options.integrator == "photon" else options.spp
        hits = options.photon_depth if options.photon_depth > 0 else ROULETTE_MEAN_HITS
        extra = maps * ((options.photons + options.caustic_photons) * hits + PHOTON_PILOT * len(desc.lights))
        cause = (f"{_num(options.photons + options.caustic_photons)} photons"
                 + (f" x {maps} passes" if maps > 1 else "") + f", paths of up to {_num(per)} rays per camera ray")
        hints += ["-photons", "-caustic_photons"] + (["-final_gather"] if gather else [])
    if options.spp > 1:
        hints.append("-spp")
    hints.append("-size")
    rays = camera * per + extra
    kept = measured_rate() if rate is None else None
    r = rate if rate is not None else (kept or CONSERVATIVE_RATE)
    measured = kept is not None
    loc = getattr(where, "loc", None) or cam_loc
    return Estimate(camera, float(per), int(extra), float(rays), float(rays) / r, float(r), measured, cause, loc,
                    tuple(dict.fromkeys(hints)))


def _num(x: float) -> str:
    """``4.3e9`` above a million, else the integer."""
    return f"{x:.1e}".replace("e+0", "e").replace("e+", "e") if x >= 1e6 else f"{int(round(x))}"


def duration(seconds: float) -> str:
    """``45 s``, ``12 min``, ``3.5 h``, ``41 days``, ``2.1e5 years``."""
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 5400:
        return f"{seconds / 60:.0f} min"
    if seconds < 2 * 86400:
        return f"{seconds / 3600:.1f} h"
    if seconds < 2 * 365 * 86400:
        return f"{seconds / 86400:.0f} days"
    return f"{_num(seconds / (365 * 86400))} years"


def summary(e: Estimate) -> str:
    """One line: ``up to 3.4e14 rays, about 5 years at 2.0e6 rays/s (assumed): a ray tree of ...``."""
    how = "measured on this machine" if e.measured else "assumed"
    return f"up to {_num(e.rays)} rays, about {duration(e.seconds)} at {_num(e.rate)} rays/s ({how}): {e.cause}"


def progress_tile_rays(e: Estimate, options: RenderOptions, *, tile_seconds: float, max_tiles: int) -> int:
    """The ``tile_rays`` (:attr:`RenderOptions.tile_rays`) that cut a render into tiles of about
    ``tile_seconds`` by the estimate, at most ``max_tiles``: ``ceil(RW·RH / min(max_tiles, ceil(seconds /
    tile_seconds)))``, never above ``options.tile_rays``; each tile is a progress step and a point where a newer
    request can pre-empt the render (the image is the same for any tile size, a5mi.render.tiles.tile_rows)."""
    rw, rh = options.render_size
    tiles = max(1, min(max_tiles, math.ceil(e.seconds / tile_seconds)))
    return max(1, min(options.tile_rays, math.ceil(rw * rh / tiles)))


def refusal(e: Estimate) -> str:
    """The message of a render refused over :data:`REFUSE_SECONDS`: the estimate and the flags that lower it."""
    return f"this render may trace {summary(e)}; lower {', '.join(e.hints)}, or add -force to render it anyway"


def warning(e: Estimate) -> str:
    """The message of a render warned over :data:`WARN_SECONDS`."""
    return f"this render may trace {summary(e)}"


# ------------------------------------------------------------------------------------------ the measured rate
def _rate_path() -> Path:
    from a5mi import cache_dir

    return cache_dir() / RATE_FILE


def _machine_key() -> str:
    return f"{os.uname().machine}-{os.cpu_count() or 1}cpu"


def measured_rate(path: Path | None = None) -> float | None:
    """The rays per second a counted render reached on this machine (:func:`record_rate`), or None."""
    try:
        data = json.loads((path or _rate_path()).read_text())
        value = float(data[_machine_key()])
    except (OSError, ValueError, KeyError, TypeError):
        return None
    return value if value > 0 else None


def record_rate(rays: int, seconds: float, path: Path | None = None) -> float | None:
    """Keep ``rays / seconds`` (a render's counted rays over its kernel time) as this machine's rate, the
    one the next estimate uses; nothing under :data:`MIN_RATE_RAYS` rays. Written atomically; a cache folder
    that cannot be written is skipped. Returns the rate kept, or None."""
    if rays < MIN_RATE_RAYS or seconds <= 0:
        return None
    target = path or _rate_path()
    rate = rays / seconds
    try:
        data = json.loads(target.read_text()) if target.exists() else {}
        if not isinstance(data, dict):
            data = {}
    except (OSError, ValueError):
        data = {}
    data[_machine_key()] = rate
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=".ray_rate-", dir=target.parent)
        with os.fdopen(fd, "w") as f:
            json.dump(data, f)
        os.replace(tmp, target)
    except OSError:
        return None
    return rate


__all__ = ["CONSERVATIVE_RATE", "REFUSE_SECONDS", "WARN_SECONDS", "Estimate", "duration", "estimate",
           "hemisphere_rays", "light_samples", "measured_rate", "progress_tile_rays", "record_rate", "refusal",
           "summary", "tree_nodes", "warning"]

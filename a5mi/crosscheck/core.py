"""The cross-check's renders and metrics: three Fresnel modes of ``a5_whitted``, Mitsuba's ``path`` and the
pixel classes, all through the same camera rays (see the package docstring, :mod:`a5mi.crosscheck`)."""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field, replace
from typing import Any

import numpy as np
import numpy.typing as npt

from a5mi.compare import Metrics, compare_arrays
from a5mi.platform.loading import load_dict
from a5mi.spec import FRESNEL_MODES, TMIN

#: Every rendering of a cross-check, in montage order.
LABELS: tuple[str, ...] = (*FRESNEL_MODES, "path")
#: Reported pairs (A, B); metrics are of B against A.
PAIRS: tuple[tuple[str, str], ...] = (
    ("a5", "schlick"), ("a5", "exact"), ("schlick", "exact"),
    ("a5", "path"), ("schlick", "path"), ("exact", "path"),
)  # fmt: skip
#: Pixel classes of :func:`pixel_classes`: the values of ``a5_whitted``'s ``class`` AOV.
BACKGROUND, OPAQUE, GLASS = 0, 1, 2
#: Upper bound of path-traced lanes per kernel launch (memory); the kernel is compiled once.
PATH_LANES = 1 << 20
#: ``rr_depth`` of the path integrator: far beyond any ``max_depth``, so Russian roulette never starts.
NO_RR_DEPTH = 1 << 16
#: Full scale of the montage's Fresnel-mode heatmaps, in levels (the path row is scaled to its errors).
FRESNEL_SCALE = 16.0


@dataclass(frozen=True)
class CrosscheckOptions:
    """What to render: size (default 300x300), Whitted bounce budget, path samples per pixel and seed."""

    width: int = 300
    height: int = 300
    bounces: int = 4
    spp: int = 256
    seed: int = 0
    shadows: bool = True
    #: docs/EXTENSIONS.md E.7: bump and normal maps on both sides (a5_whitted's bump; stock bumpmap/normalmap)
    bump: bool = False
    #: docs/EXTENSIONS.md E.8, E.9: the a5 side's ``-media_bounces`` (1: shadow rays carry the medium's
    #: transmittance, as volpath's do; 0: the course-era medium)
    media_bounces: int = 1

    def __post_init__(self) -> None:
        from a5mi.render.options import check_size_and_bounces

        check_size_and_bounces(self.width, self.height, self.bounces)
        if self.spp <= 0:
            raise ValueError(f"spp must be positive, got {self.spp}")

    @property
    def path_max_depth(self) -> int:
        """``bounces + 2``: Mitsuba's ``max_depth`` counts path segments (1 = emitters seen directly)."""
        return self.bounces + 2


@dataclass(frozen=True)
class PairReport:
    """Metrics of ``b`` against ``a`` over one region (``glass`` or ``other``); ``metrics`` None if empty."""

    a: str
    b: str
    region: str
    pixels: int
    metrics: Metrics | None
    bias: float  # mean(B - A) over the region's pixels and channels, in levels

    def to_dict(self) -> dict[str, Any]:
        m = None
        if self.metrics is not None:
            m = asdict(self.metrics)
            m["psnr"] = None if math.isinf(self.metrics.psnr) else self.metrics.psnr
        return {"a": self.a, "b": self.b, "region": self.region, "pixels": self.pixels, "bias": self.bias,
                "metrics": m}


@dataclass
class CrosscheckResult:
    """Images (float32 HxWx3, row 0 = top, linear), pixel classes (HxW uint8), the pair table, statistics.

    ``path_stderr`` is the mean standard error of the path image, in levels (Monte Carlo noise floor of
    every comparison against ``path``); ``timings`` are seconds per rendering.
    """

    images: dict[str, npt.NDArray[np.float32]]
    classes: npt.NDArray[np.uint8]
    pairs: list[PairReport]
    options: CrosscheckOptions
    path_stderr: float
    timings: dict[str, float] = field(default_factory=dict)

    @property
    def glass(self) -> npt.NDArray[np.bool_]:
        return self.classes == GLASS


def _pixel_rays(camera: Any, width: int, height: int, repeat: int = 1) -> Any:
    """SPEC B.2 camera rays through the pixel centres, row-major from the bottom row, each ``repeat`` times
    (sample-major: lane ``k·W·H + j·W + i``)."""
    import mitsuba as mi

    from a5mi.plugins.sensors.camera import camera_rays

    i = np.tile(np.arange(width, dtype=np.float32), height * repeat)
    j = np.tile(np.repeat(np.arange(height, dtype=np.float32), width), repeat)
    return camera_rays(camera.center, camera.direction, camera.up, camera.angle, mi.Float(i), mi.Float(j),
                       width, height)


def pixel_classes(
    mi_scene: Any, camera: Any, width: int, height: int, bounces: int, *, tmin: float = TMIN,
    reflection: bool = True, refraction: bool = True, integrator: Mapping[str, Any] | None = None,
) -> npt.NDArray[np.uint8]:
    """Class of each pixel (HxW, row 0 = top): :data:`BACKGROUND`, :data:`OPAQUE` or :data:`GLASS`.

    Parameter ``mi_scene``: a loaded scene with a5 materials. ``camera``: ``center``, ``direction``, ``up``,
    ``angle`` (SPEC A.2). ``bounces``, ``tmin``, ``reflection``, ``refraction``: as ``a5_whitted``'s.
    ``integrator``: the scene's ``a5_whitted`` parameters (its dict entry), which carry what the scene puts
    into the integrator (the exact planes, ``plane_*``); the arguments above override them.
    Output: the ``class`` AOV of ``a5_whitted`` (SPEC B.3 ray tree, pixel centres of SPEC B.2) rendered by
    :func:`a5mi.render.driver.render_scene`: ``GLASS`` where some node of the pixel's ray tree hits a material with
    ``refraction_index > 0``; else ``BACKGROUND`` where the camera ray misses, else ``OPAQUE``.
    """
    from a5mi.render.driver import render_scene
    from a5mi.render.options import RenderOptions

    base = {k: v for k, v in (integrator or {}).items() if k not in ("type", "aovs")}
    integ = load_dict({**base, "type": "a5_whitted", "max_depth": bounces, "tmin": float(tmin),
                       "reflection": reflection, "refraction": refraction, "aovs": "class"})
    ro = RenderOptions(width=width, height=height, bounces=bounces, reflection=reflection,
                       refraction=refraction, classes=True)
    classes = render_scene(mi_scene, camera, ro, integrator=integ).classes
    if classes is None:
        raise RuntimeError("render_scene returned no class image although RenderOptions.classes asked for one")
    return classes


# --------------------------------------------------------------------------------------------------------
# Renderings
# --------------------------------------------------------------------------------------------------------


def render_whitted(
    mi_scene: Any, camera: Any, integrator: Mapping[str, Any], options: CrosscheckOptions, fresnel: str
) -> npt.NDArray[np.float32]:
    """``a5_whitted`` with ``fresnel`` (and ``options.bounces``/``shadows``) over ``integrator``'s other
    parameters (ambient, tmin, ...); float image HxWx3, row 0 = top, through :func:`a5mi.render.driver.render_scene`."""
    from a5mi.render.driver import render_scene
    from a5mi.render.options import RenderOptions

    spec = {**integrator, "type": "a5_whitted", "fresnel": fresnel, "max_depth": options.bounces,
            "shadows": options.shadows, "reflection": True, "refraction": True}
    integ = load_dict(spec)
    ro = RenderOptions(width=options.width, height=options.height, bounces=options.bounces,
                       shadows=options.shadows, fresnel=fresnel)
    return render_scene(mi_scene, camera, ro, integrator=integ).image


def sample_statistics(total: npt.NDArray[np.float64], total_sq: npt.NDArray[np.float64],
                      spp: int) -> tuple[npt.NDArray[np.float64], float]:
    """The per-pixel mean ``Σ L / spp`` and the mean standard error ``mean(sqrt(Var(L)/spp))`` in 8-bit levels
    (``Var`` unbiased, ``spp/(spp − 1)``) of sums ``total`` = Σ L and ``total_sq`` = Σ L². A pixel whose
    samples are not finite (inf radiance: a scene scaled by 1e30) has no standard error and is left out of the
    mean one (0 when no pixel has one); its mean is compared as saved (clamped)."""
    mean = total / spp
    with np.errstate(invalid="ignore", over="ignore"):  # inf − inf
        var = np.maximum(total_sq / spp - mean * mean, 0.0) * (spp / max(spp - 1, 1))
    finite = np.isfinite(var)
    return mean, float(np.mean(np.sqrt(var[finite] / spp)) * 255.0) if finite.any() else 0.0


def render_path(
    mi_scene: Any, camera: Any, width: int, height: int, spp: int, max_depth: int, *, seed: int = 0,
    lanes: int = PATH_LANES,
) -> tuple[npt.NDArray[np.float32], float]:
    """Mitsuba's ``path`` integrator (``max_depth``, no Russian roulette) through the SPEC B.2 pixel centres;
    ``volpath`` when the scene's sensor sits in a medium (EXTENSIONS E.8, E.9), the camera rays starting in it.

    Parameter ``spp``: samples per pixel, all through the pixel centre (no antialiasing, as the a5
    renders). ``lanes``: samples per kernel launch (rounded to whole images). Output: the mean image
    ``L̄ = (1/spp) Σ L_k`` (float32 HxWx3, row 0 = top) and its mean standard error
    ``mean(sqrt(Var(L)/spp))`` in 8-bit levels, over the pixels whose variance is finite (0 when none is).
    """
    import drjit as dr
    import mitsuba as mi

    # docs/EXTENSIONS.md E.8, E.9: a medium on the stock sensor is rendered by volpath, camera rays start in it
    medium = mi_scene.sensors()[0].get_medium() if mi_scene.sensors() else None
    integ = load_dict({"type": "path" if medium is None else "volpath", "max_depth": max_depth,
                          "rr_depth": NO_RR_DEPTH, "hide_emitters": False})
    n_pix = width * height
    per_launch = max(1, min(spp, lanes // n_pix))
    total = np.zeros((3, n_pix), np.float64)
    total_sq = np.zeros((3, n_pix), np.float64)
    sampler = load_dict({"type": "independent", "sample_count": 1})
    done = 0
    launch = 0
    while done < spp:
        k = min(per_launch, spp - done)
        ray = _pixel_rays(camera, width, height, repeat=k)
        sampler.seed(seed * 1_000_003 + launch, k * n_pix)
        rgb, _valid, _aovs = integ.sample(mi_scene, sampler, mi.RayDifferential3f(ray), medium, mi.Bool(True))
        dr.eval(rgb)
        dr.sync_thread()
        c = np.asarray(rgb, dtype=np.float64).reshape(3, k, n_pix)
        total += c.sum(axis=1)
        total_sq += (c * c).sum(axis=1)
        done += k
        launch += 1
    mean, stderr = sample_statistics(total, total_sq, spp)
    img = mean.T.reshape(height, width, 3).astype(np.float32)
    return np.ascontiguousarray(img[::-1]), stderr


# --------------------------------------------------------------------------------------------------------
# Metrics
# --------------------------------------------------------------------------------------------------------


def levels(img: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """8-bit levels as the image would be saved: ``clamp(int(c·255), 0, 255)`` (SPEC B.1)."""
    from a5mi.platform.imageio import quantize

    return quantize(img).astype(np.float64)


def masked_metrics(
    a: npt.NDArray[np.float64], b: npt.NDArray[np.float64], mask: npt.NDArray[np.bool_]
) -> Metrics | None:
    """:func:`a5mi.compare.compare_arrays` over the pixels of ``mask`` only (shares are of those pixels);
    ``bbox`` in image coordinates, ``width``/``height`` the image's. None for an empty mask."""
    if not mask.any():
        return None
    m = compare_arrays(a[mask][None], b[mask][None])
    over = np.zeros(mask.shape, bool)
    over[mask] = np.abs(a[mask] - b[mask]).max(axis=1) > m.threshold
    bbox = None
    if over.any():
        ys, xs = np.nonzero(over)
        bbox = (int(xs.min()), int(ys.min()), int(xs.max()), int(ys.max()))
    return replace(m, bbox=bbox, width=mask.shape[1], height=mask.shape[0])


def pair_reports(
    images: Mapping[str, npt.NDArray[np.float32]], glass: npt.NDArray[np.bool_],
    pairs: Sequence[tuple[str, str]] = PAIRS,
) -> list[PairReport]:
    """Per pair (A, B) and region (``glass``, ``other`` = not glass): metrics in 8-bit levels and the bias
    ``mean(B − A)``."""
    lv = {k: levels(v) for k, v in images.items()}
    out = []
    for a, b in pairs:
        for region, mask in (("glass", glass), ("other", ~glass)):
            n = int(mask.sum())
            bias = float(np.mean(lv[b][mask] - lv[a][mask])) if n else 0.0
            out.append(PairReport(a, b, region, n, masked_metrics(lv[a], lv[b], mask), bias))
    return out


# --------------------------------------------------------------------------------------------------------
# The whole cross-check
# --------------------------------------------------------------------------------------------------------


def path_dict(stock_dict: Mapping[str, Any], options: CrosscheckOptions) -> dict[str, Any]:
    """The stock scene dict with its integrator replaced by ``path`` (``max_depth = bounces + 2``, no RR)."""
    out = dict(stock_dict)
    out["integrator"] = {"type": "path", "max_depth": options.path_max_depth, "rr_depth": NO_RR_DEPTH}
    return out


def crosscheck_dicts(
    a5_dict: Mapping[str, Any], stock_dict: Mapping[str, Any], camera: Any, options: CrosscheckOptions
) -> CrosscheckResult:
    """Render the cross-check of two scene dicts: ``a5_dict`` (a5 plugins, its ``integrator`` entry an
    ``a5_whitted`` dict whose ambient/tmin are kept) for the three Fresnel modes and the class pass, and
    ``stock_dict`` for ``path``. Both must place the same objects; ``camera`` gives the SPEC B.2 rays."""
    timings: dict[str, float] = {}
    integrator = dict(a5_dict.get("integrator") or {"type": "a5_whitted"})
    t0 = time.perf_counter()
    a5_scene = load_dict(dict(a5_dict))
    timings["load"] = time.perf_counter() - t0
    images: dict[str, npt.NDArray[np.float32]] = {}
    for mode in FRESNEL_MODES:
        t0 = time.perf_counter()
        images[mode] = render_whitted(a5_scene, camera, integrator, options, mode)
        timings[mode] = time.perf_counter() - t0
    t0 = time.perf_counter()
    classes = pixel_classes(a5_scene, camera, options.width, options.height, options.bounces,
                            tmin=float(integrator.get("tmin", TMIN)), integrator=integrator)
    timings["classes"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    stock_scene = load_dict(path_dict(stock_dict, options))
    images["path"], stderr = render_path(stock_scene, camera, options.width, options.height, options.spp,
                                         options.path_max_depth, seed=options.seed)
    timings["path"] = time.perf_counter() - t0
    return CrosscheckResult(images, classes, pair_reports(images, classes == GLASS), options, stderr, timings)


def _render_options(options: CrosscheckOptions) -> Any:
    """The converter's :class:`a5mi.render.options.RenderOptions` for the cross-check's size, bounces and shadows
    (the a5 defaults otherwise: no Phong, the binary's Fresnel, reflection and refraction on)."""
    from a5mi.render.options import RenderOptions

    return RenderOptions(width=options.width, height=options.height, bounces=options.bounces,
                         shadows=options.shadows, bump=options.bump, media_bounces=options.media_bounces)


def _description(desc_or_model: Any, bump: bool = False) -> Any:
    from a5mi.converters.describe import SceneDescription, describe

    return desc_or_model if isinstance(desc_or_model, SceneDescription) else describe(desc_or_model, bump=bump)


def crosscheck(desc_or_model: Any, options: CrosscheckOptions) -> CrosscheckResult:
    """The cross-check of a scene description (or a parsed scene, ``a5mi.converters.a5_parser.parse_file``,
    described here): converted with ``to_dict(desc, render_options)`` and ``to_dict(desc, render_options,
    stock=True)``. Needs an active JIT variant with the a5mi plugins registered
    (:func:`a5mi.runtime.variant.activate`)."""
    from a5mi.converters.to_mitsuba import to_dict

    desc = _description(desc_or_model, options.bump)
    ro = _render_options(options)
    return crosscheck_dicts(to_dict(desc, ro), to_dict(desc, ro, stock=True), desc.camera, options)

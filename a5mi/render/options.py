"""The one options object: what to render, from the command line to the integrator dict (SPEC B.1, B.3, B.5).

:class:`RenderOptions` is built once by the command layer (``a5mi/cli``) from the flags and handed, unchanged,
to the converter (film size and the ``a5_whitted`` parameters, :meth:`RenderOptions.integrator_params`) and to
the driver (jitter, filter, tiles, AOV images). A leaf module: standard library and :mod:`a5mi.spec` only, so
every layer may import it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from a5mi.spec import DEFAULT_BOUNCES, DEFAULT_SIZE, FRESNEL_MODES, JITTER_FACTOR

#: Blur kernels of SPEC B.5: the binary's stored taps (centre 0.2921) or the handout's (0.2931, a typo).
KERNELS: tuple[str, ...] = ("binary", "handout")
#: ``-quirks``: ``none`` (SPEC B.3 as written) or ``binary`` (docs/FIDELITY.md "Stale texture coordinates":
#: a sphere or plane with a textured material, hit in front of a textured mesh tested before it, looks its
#: texture up at that mesh's uv, as the sample solution's hit record keeps it)
QUIRKS: tuple[str, ...] = ("none", "binary")
#: Where ``-normals`` / ``-depth`` rays come from (SPEC B.6): the image's rays, or the binary's quadrant rays.
AOV_MODES: tuple[str, ...] = ("main", "quadrant")
#: AOV groups ``a5_whitted`` computes on request (its ``aovs`` parameter), in channel order:
#: ``normal`` -> nx, ny, nz; ``depth`` -> t; ``class`` -> 0 miss / 1 opaque / 2 the ray tree touches glass;
#: ``counts`` -> n_reflection, n_refraction, n_shadow (rays traced per camera ray).
AOV_GROUPS: tuple[str, ...] = ("normal", "depth", "class", "counts")
#: ``-integrator`` modes: name -> the Mitsuba integrator plugin that renders it. ``whitted`` is the sample
#: solution's (SPEC B.3); the others are docs/EXTENSIONS.md's physically based modes. Every a5 integrator plugin
#: accepts the scene part of ``a5_whitted``'s parameters (``ambient``, ``plane_<id>_*``, ``medium*``,
#: ``glossy_samples``, ``glossy``, ``dispersion``: converters/to_mitsuba.py ``integrator_dict``) and the
#: ``aovs`` groups it lists in ``aov_names()``.
INTEGRATORS: dict[str, str] = {"whitted": "a5_whitted", "path": "a5_path", "irradiancecache": "a5_irradiancecache",
                               "photon": "a5_photon", "ppm": "a5_ppm"}
#: Radiance-estimate filters of ``-integrator photon`` / ``ppm`` (docs/EXTENSIONS.md E.16).
PHOTON_FILTERS: tuple[str, ...] = ("none", "cone", "epanechnikov")
#: ``-subsurface`` methods (docs/EXTENSIONS.md E.18; ``none``: the materials' ``subsurface`` blocks are ignored).
SUBSURFACE_METHODS: tuple[str, ...] = ("none", "dipole", "walk")
#: docs/MISTAKES.md: the student mistakes a render can make on request (``-mistake NAME[,NAME]``), by the layer
#: that makes them. Kernel: compile-time blocks of the ``a5_whitted`` kernel (its ``mistakes`` parameter,
#: plugins/kernel/features.py); ``no_shadows``, ``phong_highlight`` and the bounce mistakes through its flags.
KERNEL_MISTAKES: tuple[str, ...] = (
    "no_shadows", "shadow_acne", "shadow_beyond_light", "shadow_first_light_only", "no_ambient", "ambient_uses_kd",
    "ndotl_unclamped", "light_dir_flipped", "normal_faces_viewer", "light_color_ignored", "kd_ignores_texture",
    "phong_highlight", "mirror_sign", "reflection_unweighted", "refraction_unweighted", "refl_refr_added",
    "bounces_plus_one", "bounces_minus_one", "no_recursion", "eta_inverted", "eta_inside_inverted",
    "normal_not_flipped_inside", "tir_ignored", "schlick_wrong_c", "background_wrong_direction", "secondary_acne",
    "normal_by_m", "normal_not_normalised",
)
#: ``a5_marble``'s ``mistake`` parameter (plugins/textures/marble.py, SPEC B.4).
MARBLE_MISTAKES: tuple[str, ...] = ("marble_no_octaves", "marble_sine_unmapped", "marble_freq_amp_swapped")
#: The driver's camera (a5mi/render/driver.py, SPEC B.2) and sample layout (SPEC B.5).
CAMERA_MISTAKES: tuple[str, ...] = ("fov_full_angle", "camera_divides_by_w", "no_supersampling")
#: The jitter offsets (a5mi/render/tiles.py, SPEC B.5).
JITTER_MISTAKES: tuple[str, ...] = ("no_jitter", "jitter_0_1")
#: The blur and downsample (a5mi/render/filters.py, SPEC B.5).
FILTER_MISTAKES: tuple[str, ...] = ("blur_not_normalised", "blur_one_direction", "blur_zero_border",
                                   "downsample_one_sample", "no_blur")
#: The saved image (a5mi/render/filters.py :func:`~a5mi.render.filters.image_mistakes`, SPEC B.1).
IMAGE_MISTAKES: tuple[str, ...] = ("upside_down", "mirrored", "red_blue_swapped", "srgb_gamma", "colours_wrapped",
                                  "rounding")
#: Every mistake name, in docs/MISTAKES.md's order.
MISTAKES: tuple[str, ...] = (KERNEL_MISTAKES + MARBLE_MISTAKES + CAMERA_MISTAKES + JITTER_MISTAKES
                             + FILTER_MISTAKES + IMAGE_MISTAKES)
#: Upper bound of camera rays per kernel launch (bounded memory; the kernel is compiled once).
TILE_RAYS: int = 1 << 20


def check_size_and_bounces(width: int, height: int, bounces: int) -> None:
    """``ValueError`` unless the image size is positive and the bounce budget is not negative (SPEC B.1)."""
    if width <= 0 or height <= 0:
        raise ValueError(f"size must be positive, got {width}x{height}")
    if bounces < 0:
        raise ValueError(f"bounces must be >= 0, got {bounces}")


@dataclass(frozen=True)
class RenderOptions:
    """What to render: the ``a5`` flags (SPEC B.1) and the extras. Frozen: derive variants with
    ``dataclasses.replace``.

    ``width`` x ``height`` is the saved image size as given to ``-size``; :attr:`render_size` is the render
    buffer (3W x 3H with ``jitter``, SPEC B.5). ``seed=None`` replays glibc ``rand()`` from seed 1 as the binary.
    ``normals`` / ``depth`` ask for the AOV images (``depth`` = (dmin, dmax)); ``count_rays`` for the
    per-kind ray counts of ``-v``; ``classes`` for the per-pixel ray-tree class image (0 miss, 1 opaque,
    2 glass, of the main image's rays); ``aov_mode`` says which rays the normal / depth images use (SPEC B.6).
    """

    width: int = DEFAULT_SIZE[0]
    height: int = DEFAULT_SIZE[1]
    bounces: int = DEFAULT_BOUNCES
    shadows: bool = False
    jitter: bool = False
    filter: bool = False
    seed: int | None = None
    phong: bool = False
    fresnel: str = "a5"
    reflection: bool = True
    refraction: bool = True
    kernel: str = "binary"
    normals: bool = False
    depth: tuple[float, float] | None = None
    tile_rays: int = TILE_RAYS
    threads: int | None = None
    count_rays: bool = False
    classes: bool = False
    aov_mode: str = "main"
    #: docs/EXTENSIONS.md E.5: passes per render-buffer pixel over the stochastic dimensions (lights, lens, gloss)
    spp: int = 1
    #: docs/EXTENSIONS.md E.7: bump / normal maps perturb the shading normal (off: the course's ``bump`` is ignored)
    bump: bool = False
    #: ``-integrator``: a key of :data:`INTEGRATORS` (``whitted``: SPEC B.3)
    integrator: str = "whitted"
    #: docs/EXTENSIONS.md E.14: ``-integrator path`` plays Russian roulette from this many scatterings on
    rr_depth: int = 5
    #: docs/EXTENSIONS.md E.15: ``a5_whitted`` gathers indirect light with N cosine-weighted rays per diffuse hit
    indirect: int = 0
    #: docs/EXTENSIONS.md E.15: ``a5_whitted``'s light loop lights both faces (N turned toward the ray)
    two_sided: bool = False
    #: docs/EXTENSIONS.md E.16, E.17 (``-integrator photon`` / ``ppm``): photons per map (per pass for ppm),
    #: nearest photons of an estimate, its filter, final-gather rays (0: off), the ppm radius (0: automatic)
    #: and alpha
    photons: int = 100000
    caustic_photons: int = 100000
    #: E.16: photon hits before a photon path is cut (0: none, Russian roulette alone)
    photon_depth: int = 0
    photon_k: int = 50
    #: E.16: the largest radius of a k-nearest photon disc (0: none)
    photon_max_radius: float = 0.0
    photon_filter: str = "none"
    final_gather: int = 0
    ppm_radius: float = 0.0
    ppm_alpha: float = 2.0 / 3.0
    #: docs/EXTENSIONS.md E.8, E.9: 0 the course-era medium (light unattenuated on its way); N >= 1 shadow rays
    #: carry the medium's transmittance and light scatters up to N times in it
    media_bounces: int = 0
    #: docs/EXTENSIONS.md E.18: ``none`` (materials' ``subsurface`` blocks ignored), ``dipole`` or ``walk``
    subsurface: str = "none"
    #: docs/EXTENSIONS.md E.23: ``-integrator irradiancecache``'s error bound ``a`` and hemisphere rays per record
    ic_error: float = 0.3
    ic_samples: int = 256
    #: ``-quirks`` (:data:`QUIRKS`): ``binary`` emulates the sample solution's stale texture coordinates
    quirks: str = "none"
    #: docs/MISTAKES.md: names of :data:`MISTAKES` to make on purpose (``-mistake``; empty: SPEC as written)
    mistakes: tuple[str, ...] = ()
    #: ``-crop X0 X1 Y0 Y1``: render only the saved image's pixels ``X0 <= x < X1``, ``Y0 <= y < Y1`` (row 0 the
    #: top), bit for bit as in the whole image (a5mi/render/crop.py); None: the whole image
    crop: tuple[int, int, int, int] | None = None

    def __post_init__(self) -> None:
        check_size_and_bounces(self.width, self.height, self.bounces)
        if self.fresnel not in FRESNEL_MODES:
            raise ValueError(f"fresnel must be one of {', '.join(FRESNEL_MODES)}, got '{self.fresnel}'")
        if self.kernel not in KERNELS:
            raise ValueError(f"kernel must be one of {', '.join(KERNELS)}, got '{self.kernel}'")
        if self.aov_mode not in AOV_MODES:
            raise ValueError(f"aov_mode must be one of {', '.join(AOV_MODES)}, got '{self.aov_mode}'")
        if self.integrator not in INTEGRATORS:
            raise ValueError(f"integrator must be one of {', '.join(INTEGRATORS)}, got '{self.integrator}'")
        if self.indirect < 0:
            raise ValueError(f"indirect must be >= 0, got {self.indirect}")
        if self.rr_depth < 0:
            raise ValueError(f"rr_depth must be >= 0, got {self.rr_depth}")
        if self.photon_filter not in PHOTON_FILTERS:
            raise ValueError(f"photon_filter must be one of {', '.join(PHOTON_FILTERS)}, got '{self.photon_filter}'")
        if not 0.0 < self.ic_error <= 1.0 or self.ic_samples < 6:
            raise ValueError(f"ic_error must be in (0, 1] and ic_samples >= 6, got {self.ic_error}, {self.ic_samples}")
        if self.spp < 1:
            raise ValueError(f"spp must be >= 1, got {self.spp}")
        if self.subsurface not in SUBSURFACE_METHODS:
            raise ValueError(f"subsurface must be one of {', '.join(SUBSURFACE_METHODS)}, got '{self.subsurface}'")
        if self.media_bounces < 0:
            raise ValueError(f"media_bounces must be >= 0, got {self.media_bounces}")
        if self.quirks not in QUIRKS:
            raise ValueError(f"quirks must be one of {', '.join(QUIRKS)}, got '{self.quirks}'")
        unknown = [m for m in self.mistakes if m not in MISTAKES]
        if unknown:
            raise ValueError(f"unknown mistake '{unknown[0]}' (docs/MISTAKES.md lists them)")
        if self.crop is not None and (len(self.crop) != 4 or not all(isinstance(v, int) for v in self.crop)):
            raise ValueError(f"crop must be four integers X0 X1 Y0 Y1, got {self.crop!r}")
        if self.tile_rays <= 0:
            raise ValueError(f"tile_rays must be positive, got {self.tile_rays}")

    @property
    def render_size(self) -> tuple[int, int]:
        """``(RW, RH)``: the render buffer, 3W x 3H with ``-jitter`` (SPEC B.5)."""
        k = JITTER_FACTOR if self.jitter else 1
        return k * self.width, k * self.height

    @property
    def aov_groups(self) -> tuple[str, ...]:
        """The AOV groups (:data:`AOV_GROUPS`) the integrator must compute for these options."""
        wanted = {"normal": self.normals, "depth": self.depth is not None, "class": self.classes,
                  "counts": self.count_rays}
        return tuple(g for g in AOV_GROUPS if wanted[g])

    @property
    def plugin(self) -> str:
        """The Mitsuba integrator plugin of :attr:`integrator` (:data:`INTEGRATORS`)."""
        return INTEGRATORS[self.integrator]

    def integrator_params(self) -> dict[str, Any]:
        """The parameters these options set on the :attr:`plugin` integrator (ARCHITECTURE.md, plugin
        contract); the scene adds ``ambient`` and its planes, medium and material flags. For ``a5_whitted``:
        ``aovs`` is a comma-separated list of :data:`AOV_GROUPS` (empty: colour only)."""
        params = {"max_depth": int(self.bounces), "shadows": bool(self.shadows), "phong": bool(self.phong),
                  "fresnel": str(self.fresnel), "reflection": bool(self.reflection),
                  "refraction": bool(self.refraction), "aovs": ",".join(self.aov_groups)}
        if self.bump:  # docs/EXTENSIONS.md E.7; absent otherwise, so course dicts and XML are unchanged
            params["bump"] = True
        if self.indirect > 0 and self.plugin == "a5_whitted":  # E.15; absent at 0: course dicts unchanged
            params["indirect"] = int(self.indirect)
        if self.two_sided and self.plugin == "a5_whitted":  # E.15; absent when off: course dicts unchanged
            params["two_sided"] = True
        if self.plugin in ("a5_path", "a5_irradiancecache"):  # docs/EXTENSIONS.md E.14, E.23
            params["rr_depth"] = int(self.rr_depth)
        if self.integrator in ("photon", "ppm"):  # docs/EXTENSIONS.md E.16, E.17
            del params["phong"]
            params.update(photons=int(self.photons), caustic_photons=int(self.caustic_photons),
                          filter=str(self.photon_filter), seed=int(self.seed or 0),
                          photon_depth=int(self.photon_depth))
            if self.integrator == "photon":
                params.update(k=int(self.photon_k), final_gather=int(self.final_gather),
                              max_radius=float(self.photon_max_radius))
            else:
                params.update(radius=float(self.ppm_radius), alpha=float(self.ppm_alpha))
        if self.media_bounces and self.plugin == "a5_whitted":  # E.8, E.9; absent at 0 (dicts, XML unchanged)
            params["medium_bounces"] = int(self.media_bounces)
        if self.subsurface != "none" and self.plugin == "a5_whitted":  # docs/EXTENSIONS.md E.18
            params["subsurface"] = str(self.subsurface)
        if self.plugin == "a5_irradiancecache":  # docs/EXTENSIONS.md E.23
            params.update(error=float(self.ic_error), samples=int(self.ic_samples))
        kernel_mistakes = self.of_layer(KERNEL_MISTAKES)
        if kernel_mistakes and self.plugin == "a5_whitted":  # docs/MISTAKES.md; absent when none (dicts unchanged)
            params["mistakes"] = ",".join(kernel_mistakes)
        return params

    def of_layer(self, layer: tuple[str, ...]) -> tuple[str, ...]:
        """The :attr:`mistakes` among ``layer`` (e.g. :data:`KERNEL_MISTAKES`), sorted."""
        return tuple(sorted(m for m in set(self.mistakes) if m in layer))

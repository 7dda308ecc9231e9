"""The one base of the a5 integrators (SPEC B.3, B.4; docs/EXTENSIONS.md E.13): what Mitsuba's ``RBIntegrator``
(``python/ad/integrators/common.py``) is to its integrators.

:class:`A5Integrator` reads the parameters every a5 integrator shares, each in exactly one place, with the typed
readers of :mod:`a5mi.plugins.params` (one error wording: ``<plugin>: '<name>' must be ..., got <value>``):

================ ======= ======= ==========================================================
parameter        type    default meaning
================ ======= ======= ==========================================================
max_depth        int     4       bounce budget (``-bounces``, SPEC B.4)
tmin             float   0.001   tmin of secondary and shadow rays (``a5mi.spec.TMIN``)
fresnel          string  a5      ``a5`` | ``schlick`` | ``exact`` (SPEC B.3)
reflection       bool    true    mirror rays / lobes (``-reflection_off`` = false)
refraction       bool    true    refracted rays / lobes (``-refraction_off`` = false)
bump             bool    false   bump / normal-mapped shading normal (E.7)
shadows          bool    false   shadow rays of the light loop (``-shadows``)
phong            bool    false   the handout's Phong highlight
ambient          rgb     0       ambient light (``Background { ambientLight }``)
glossy           bool    true    glossy lobes of materials with roughness (E.4)
glossy_samples   int     1       cap on the glossy children of a camera hit (E.4)
dispersion       bool    false   Cauchy n(λ), a wavelength per camera ray (E.10)
aovs             string  ""      comma-separated groups of :attr:`A5Integrator.aov_groups`
medium           string  none    refused unless :attr:`A5Integrator.has_media`
rr_depth         int     5       Russian roulette depth (only where ``rr_depth`` is in ``options``)
seed             int     0       seed (only where ``seed`` is in ``options``)
plane_<id>_*     ...             exact infinite planes and spheres (SPEC A.6, plugins/emulation/planes.py)
================ ======= ======= ==========================================================

The six Whitted options (``shadows`` .. ``dispersion``) are read and checked by every integrator, since the
converter writes them for all; an integrator of the physically based reading (E.13: no ambient or Phong term,
smooth non-dispersive materials) fixes them in :attr:`A5Integrator.fixed`. The base also keeps the scene's
triangle-rule table (:meth:`A5Integrator.rule_table`), builds the kernel's :class:`SceneData`
(:meth:`A5Integrator.scene_data`) and its :class:`Features` through :func:`build_features` only
(:meth:`A5Integrator.features`), names the AOVs (:data:`AOV_CHANNELS`) and exposes the parameters to
``traverse``. A new integrator names itself, lists its AOV groups and parameters, and writes ``sample``.
"""

from __future__ import annotations

from typing import Any, ClassVar

import drjit as dr
import mitsuba as mi

from a5mi.plugins.emulation import triangle_rule
from a5mi.plugins.emulation.planes import plane_set, planes_from_props
from a5mi.plugins.kernel.features import Features, SceneData, build_features, depth_budget
from a5mi.plugins.kernel.scene import lights_of
from a5mi.plugins.params import read_bool, read_choice, read_int, read_names, read_number, read_rgb
from a5mi.spec import FRESNEL_MODES, TMIN

#: every AOV group (a5mi.render.options.AOV_GROUPS) and the channels it adds, in order: first-hit shading normal
#: and distance (SPEC B.6), the ray-tree class (``MISS``, ``OPAQUE``, ``GLASS`` of
#: plugins/integrators/whitted/raytree.py), and rays traced per camera ray by kind (reflected or scattered to the
#: side the ray came from, refracted, shadow rays). An integrator offers the groups of its ``aov_groups``.
AOV_CHANNELS: dict[str, tuple[str, ...]] = {
    "normal": ("nx", "ny", "nz"),
    "depth": ("t",),
    "class": ("class",),
    "counts": ("n_reflection", "n_refraction", "n_shadow"),
}
#: the values the physically based integrators (E.13) fix for the Whitted options they accept and do not use
E13_FIXED: dict[str, Any] = {"phong": False, "ambient": [0.0, 0.0, 0.0], "glossy": False, "glossy_samples": 1,
                             "dispersion": False}


def ray_width(ray: mi.Ray3f, active: mi.Bool | bool) -> int:
    """Number of lanes of a ray batch: the widest of origin, direction and mask."""
    return max(dr.width(ray.o), dr.width(ray.d), dr.width(active) if isinstance(active, mi.Bool) else 1)


def camera_rays(ray: mi.Ray3f, active: mi.Bool | bool) -> tuple[mi.Point3f, mi.Vector3f, mi.Bool]:
    """``(o, d, active)`` of a camera ray batch, each full width (a width-1 loop variable, e.g. a stack
    pointer, makes lanes loop forever)."""
    width = ray_width(ray, active)
    return (mi.Point3f(ray.o) + dr.zeros(mi.Point3f, width), mi.Vector3f(ray.d) + dr.zeros(mi.Vector3f, width),
            dr.full(mi.Bool, True, width) & active)


class A5Integrator(mi.SamplingIntegrator):
    """The shared parameters and kernel inputs of the a5 integrators (module docstring)."""

    #: the plugin's registered name, the first word of its errors
    name: ClassVar[str] = "a5_integrator"
    #: the AOV groups of :data:`AOV_CHANNELS` the integrator computes
    aov_groups: ClassVar[tuple[str, ...]] = ()
    #: optional shared parameters the integrator reads: ``rr_depth``, ``seed``
    options: ClassVar[tuple[str, ...]] = ()
    #: Whitted options fixed to these values whatever the parameters say (E.13 integrators)
    fixed: ClassVar[dict[str, Any]] = {}
    #: True: the integrator reads ``medium`` itself; False: a medium other than ``none`` is refused
    has_media: ClassVar[bool] = False
    #: the parameters ``traverse`` exposes, in order
    exposed: ClassVar[tuple[str, ...]] = ()
    #: ``a5mi.render.passes.sample_passes`` hands ``sample()`` its :class:`~a5mi.plugins.sampling.SamplePass`
    takes_sample_pass: ClassVar[bool] = True
    #: E.15 gathered rays and the E.18 method: none unless the integrator reads them (:func:`build_features`)
    indirect: int = 0
    subsurface: str = "none"
    two_sided: bool = False
    #: docs/MISTAKES.md: the kernel mistakes compiled in (``a5_whitted``'s ``mistakes`` parameter; none elsewhere)
    mistakes: tuple[str, ...] = ()

    def __init__(self, props: mi.Properties) -> None:
        super().__init__(props)
        name = self.name
        self.max_depth = read_int(name, props, "max_depth", 4, 0)
        self.tmin = read_number(name, props, "tmin", TMIN)
        self.fresnel = read_choice(name, props, "fresnel", "a5", FRESNEL_MODES)
        self.reflection = read_bool(name, props, "reflection", True)
        self.refraction = read_bool(name, props, "refraction", True)
        self.bump = read_bool(name, props, "bump", False)   # docs/EXTENSIONS.md E.7
        self.shadows = read_bool(name, props, "shadows", False)
        self.phong = read_bool(name, props, "phong", False)
        self.ambient = read_rgb(name, props, "ambient")
        self.glossy = read_bool(name, props, "glossy", True)   # False: no glossy material (E.4)
        self.glossy_samples = read_int(name, props, "glossy_samples", 1, 1)   # E.4: cap on glossy children
        self.dispersion = read_bool(name, props, "dispersion", False)   # docs/EXTENSIONS.md E.10
        for key, value in self.fixed.items():
            setattr(self, key, value)
        if "rr_depth" in self.options:
            self.rr_depth = read_int(name, props, "rr_depth", 5, 0)
        if "seed" in self.options:
            self.seed = read_int(name, props, "seed", 0, 0)
        self.aovs = self._read_aovs(props)
        if not self.has_media and props.get("medium", "none") != "none":
            raise ValueError(f"{name}: participating media are not part of E.13 (medium {props['medium']!r})")
        self._medium: Any = None
        self.planes = planes_from_props(props)
        self._planes = plane_set(self.planes)
        self._rules: dict[int, triangle_rule.RuleTable] = {}   # id(scene) -> its rule table (the last scene only)

    def _read_aovs(self, props: mi.Properties) -> tuple[str, ...]:
        """The ``aovs`` groups, in the order of :data:`AOV_CHANNELS`."""
        groups = read_names(self.name, props, "aovs", self.aov_groups, "groups")
        return tuple(g for g in AOV_CHANNELS if g in groups)

    # ------------------------------------------------------------------ kernel inputs

    @property
    def stack_depth(self) -> int:
        """The bounce budget the kernel's pending-ray stack holds (:func:`build_features`): ``max_depth``."""
        return self.max_depth

    def rule_table(self, scene: mi.Scene) -> triangle_rule.RuleTable | None:
        """The scene's triangle-rule table (plugins/emulation/triangle_rule.py), kept while its buffers are
        unchanged: a cache of a value derived from the scene, not state that changes what a call computes."""
        table = triangle_rule.rule_table(scene, self._rules.get(id(scene)))
        self._rules = {id(scene): table} if table is not None else {}
        return table

    def scene_data(self, scene: mi.Scene) -> SceneData:
        """The opaque per-scene values of a kernel call: bounce budget, ambient, tmin, lights, planes, the
        triangle-rule table and the medium."""
        return SceneData(dr.opaque(mi.UInt32, depth_budget(self.max_depth, self.mistakes)),
                         dr.opaque(mi.Color3f, self.ambient),
                         dr.opaque(mi.Float, self.tmin), lights_of(scene), self._planes, self.rule_table(scene),
                         self._medium)

    def features(self, scene: mi.Scene, data: SceneData, record: bool = False, ray_log: bool = False) -> Features:
        """The kernel's compile-time blocks, by :func:`build_features` (the one place that decides them)."""
        return build_features(self, scene, data, record=record, ray_log=ray_log)

    # ------------------------------------------------------------------ Mitsuba interface

    def aov_names(self) -> list[str]:
        return [name for g in self.aovs for name in AOV_CHANNELS[g]]

    def aov_values(self, channels: dict[str, list[mi.Float]]) -> list[mi.Float]:
        """The AOVs of :meth:`aov_names` from every group's channel values."""
        return [a for g in self.aovs for a in channels[g]]

    def traverse(self, callback: mi.TraversalCallback) -> None:
        flags = int(mi.ParamFlags.NonDifferentiable)
        for key in self.exposed:
            value = getattr(self, key)
            if key in ("aovs", "mistakes"):
                value = ",".join(value)
            elif key == "ambient":
                value = mi.ScalarColor3f(value)
            callback.put(key, value, flags)

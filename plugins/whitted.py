"""The ``a5_whitted`` integrator: the sample solution's ``traceRay`` (SPEC B.3) as one Dr.Jit kernel.

This module is the Mitsuba side: parameters, checks, AOVs. The kernel is
:func:`plugins.kernel.raytree.trace_tree`; every call builds its :class:`~.kernel.features.Features` (which blocks
the kernel contains, :func:`~.kernel.features.build_features`), its :class:`~.kernel.features.SceneData`
(opaque per-scene values) and its sampling state (:func:`.sampling.stochastic` of the call's
:class:`~.sampling.SamplePass`), and nothing of one call survives into the next.
"""

from __future__ import annotations

import drjit as dr
import mitsuba as mi

from a5mi.spec import FRESNEL_MODES, TMIN

from . import media, subsurface, triangle_rule
from .kernel.features import KERNEL_MISTAKES, SceneData, build_features, depth_budget
from .kernel.lights import lights_of
from .kernel.raylog import RayLog
from .kernel.raytree import TreeResult, trace_tree
from .planes import plane_set, planes_from_props
from .sampling import SamplePass, stochastic
from .whitted_record import TreeRecorder

#: AOV groups of the ``aovs`` parameter (a5mi.options.AOV_GROUPS) and the channels each adds, in order:
#: first-hit shading normal and distance (SPEC B.6), the ray-tree class (``MISS``, ``OPAQUE``, ``GLASS`` of
#: plugins/kernel/raytree.py), and rays traced per camera ray by kind.
AOV_CHANNELS: dict[str, tuple[str, ...]] = {
    "normal": ("nx", "ny", "nz"),
    "depth": ("t",),
    "class": ("class",),
    "counts": ("n_reflection", "n_refraction", "n_shadow"),
}


def _width(ray: mi.Ray3f, active: mi.Bool | bool) -> int:
    """Number of lanes of a ray batch: the widest of origin, direction and mask."""
    return max(dr.width(ray.o), dr.width(ray.d), dr.width(active) if isinstance(active, mi.Bool) else 1)


class A5WhittedIntegrator(mi.SamplingIntegrator):
    """Whitted ray tracing exactly as the sample solution ``a5soln`` does it (SPEC B.3).

    ================ ======= ======= ==========================================================
    parameter        type    default meaning
    ================ ======= ======= ==========================================================
    max_depth        int     4       bounce budget (``-bounces``); 0 = no secondary rays
    shadows          bool    false   shadow rays (``-shadows``), blocked by 0.001 < t < dist
    ambient          rgb     0       ambient light (``Background { ambientLight }``)
    phong            bool    false   add the handout's ``clamp(L·R)^shininess lightColor ⊙ ks``
    fresnel          string  a5      ``a5`` (binary's R0), ``schlick`` (textbook R0), ``exact``
    reflection       bool    true    trace mirror rays (``-reflection_off`` = false)
    refraction       bool    true    trace refracted rays (``-refraction_off`` = false)
    tmin             float   0.001   tmin of secondary and shadow rays (``a5mi.spec.TMIN``)
    glossy_samples   int     1       cap on the glossy children of a camera hit (docs/EXTENSIONS.md E.4)
    dispersion       bool    false   wavelength per camera ray, Cauchy n(λ) (docs/EXTENSIONS.md E.10)
    subsurface       string  none    ``dipole`` / ``walk``: subsurface light of materials with ``sss_*``
                                     (docs/EXTENSIONS.md E.18, plugins/subsurface.py)
    bump             bool    false   bump / normal-mapped shading normal (``-bump``, docs/EXTENSIONS.md E.7)
    glossy           bool    true    false: no material has roughness > 0 (the E.4 lobe sampling is
                                     left out of the kernel; the converter says so for its scenes)
    aovs             string  ""      comma-separated AOV groups: ``normal`` (nx, ny, nz), ``depth``
                                     (t), ``class`` (class), ``counts`` (n_reflection, n_refraction,
                                     n_shadow)
    indirect         int     0       rays gathered at each diffuse hit (``-indirect``, EXTENSIONS E.15)
    medium           string  none    ``fog`` / ``volume``: a participating medium (EXTENSIONS E.8,
                                     E.9; ``medium_*`` parameters, plugins/media.py)
    mistakes         string  ""      comma-separated names of ``KERNEL_MISTAKES`` (docs/MISTAKES.md): render as
                                     a student with those mistakes would (empty: SPEC B.3)
    plane_<id>_*     ...             an exact infinite plane: ``_normal`` vector, ``_offset`` float,
                                     ``_bsdf`` BSDF, optional ``_mirror_normal`` (SPEC A.6,
                                     plugins/planes.py)
    ================ ======= ======= ==========================================================

    Per hit (``p = o + t d``, ``N`` the shading normal, never flipped toward the viewer)::

        colour = ambient ⊙ diffuseColor + Σ_lights S · max(L·N, 0) · lightColor ⊙ kd
               + specularColor ⊙ (R · trace(reflect(d, N)) + (1 - R) · trace(T))

    The mirror ray exists when ``|specularColor| > 0.001``; the refracted one when ``refractionIndex > 0``
    and Snell has a solution (inside/outside by the sign of d·N, then ``nt = 1`` or ``refractionIndex``);
    without it (or under total internal reflection) ``R = 1``. ``R = R0 + (1 - R0)(1 - c)^5`` with
    ``c = |d·N|`` if ``nt > n`` else ``|T·N|`` and ``R0 = ((nt-1)/(nt+1))²`` (``a5``, the binary) or
    ``((nt-n)/(nt+n))²`` (``schlick``); ``exact`` uses ``mi.fresnel``. With ``refraction = false`` the whole
    refraction branch is skipped (``R = 1``). Misses return ``scene.environment()`` for the ray's direction,
    black without one. Lights are the emitters with a delta flag and the ``a5_area`` emitters
    (plugins/kernel/lights.py: ``sample_direction`` gives ``L``, the arriving colour and the distance; stock
    ``directional`` reports ``2 max(R, |p - c|)`` for the scene's bounding sphere, always past every object,
    so its shadow test equals the binary's FLT_MAX; an area light is sampled ``samples`` times, E.2).

    ``sample()`` treats its ray as a camera ray (unit direction, tmin 0, index 1) and returns the colour,
    the ``active`` mask, and the AOVs asked for by ``aovs`` (none by default, so ``mi.render`` gives RGB):
    ``nx, ny, nz, t`` of the first hit (0 and +inf on a miss); ``class`` = 0 (the camera ray misses),
    1 (opaque: no node of the ray tree hits a material with ``refraction_index > 0``) or 2 (glass: some
    node does, the last level included); the ray counts.

    Dict form: ``{'type': 'a5_whitted', 'max_depth': 4, 'shadows': True, 'ambient': {'type': 'rgb',
    'value': [0.1, 0.1, 0.1]}}``.
    """

    def __init__(self, props: mi.Properties) -> None:
        super().__init__(props)
        max_depth = props.get("max_depth", 4)
        if isinstance(max_depth, bool) or not isinstance(max_depth, int) or max_depth < 0:
            raise ValueError(f"a5_whitted: 'max_depth' must be an integer >= 0, got {max_depth!r}")
        fresnel = props.get("fresnel", "a5")
        if fresnel not in FRESNEL_MODES:
            raise ValueError(f"a5_whitted: 'fresnel' must be one of {', '.join(FRESNEL_MODES)}, got {fresnel!r}")
        tmin = props.get("tmin", TMIN)
        if isinstance(tmin, bool) or not isinstance(tmin, (int, float)) or not 0.0 <= tmin < float("inf"):
            raise ValueError(f"a5_whitted: 'tmin' must be a finite number >= 0, got {tmin!r}")
        ambient = props.get("ambient", mi.ScalarColor3d(0.0))
        try:
            if isinstance(ambient, str):
                raise TypeError
            ambient_rgb = [float(ambient)] * 3 if isinstance(ambient, (int, float)) else [
                float(ambient[i]) for i in range(3)]
        except (TypeError, IndexError, ValueError):
            raise ValueError(f"a5_whitted: 'ambient' must be an rgb colour, got {ambient!r}") from None
        flags = {}
        for name, default in (("shadows", False), ("phong", False), ("reflection", True),
                              ("refraction", True), ("dispersion", False), ("bump", False), ("glossy", True)):
            value = props.get(name, default)
            if not isinstance(value, bool):
                raise ValueError(f"a5_whitted: '{name}' must be a boolean, got {value!r}")
            flags[name] = value
        self.max_depth = max_depth
        self.fresnel = fresnel
        self.tmin = float(tmin)
        self.ambient = ambient_rgb
        self.shadows = flags["shadows"]
        self.phong = flags["phong"]
        self.reflection = flags["reflection"]
        self.refraction = flags["refraction"]
        self.dispersion = flags["dispersion"]  # docs/EXTENSIONS.md E.10
        self.bump = flags["bump"]  # docs/EXTENSIONS.md E.7
        self.glossy = flags["glossy"]  # False: no glossy material (E.4), its lobe sampling stays out of the kernel
        aovs = props.get("aovs", "")
        groups = [g.strip() for g in aovs.split(",") if g.strip()] if isinstance(aovs, str) else None
        if groups is None or any(g not in AOV_CHANNELS for g in groups):
            raise ValueError(f"a5_whitted: 'aovs' must list groups of {', '.join(AOV_CHANNELS)}, got {aovs!r}")
        self.aovs = tuple(g for g in AOV_CHANNELS if g in groups)
        mistakes = props.get("mistakes", "")   # docs/MISTAKES.md
        names = [m.strip() for m in mistakes.split(",") if m.strip()] if isinstance(mistakes, str) else None
        if names is None or any(m not in KERNEL_MISTAKES for m in names):
            raise ValueError(f"a5_whitted: 'mistakes' must list names of {', '.join(KERNEL_MISTAKES)}, "
                             f"got {mistakes!r}")
        self.mistakes = tuple(sorted(set(names)))
        self.planes = planes_from_props(props)
        self._planes = plane_set(self.planes)
        glossy_samples = props.get("glossy_samples", 1)  # docs/EXTENSIONS.md E.4: cap on glossy children
        if isinstance(glossy_samples, bool) or not isinstance(glossy_samples, int) or glossy_samples < 1:
            raise ValueError(f"a5_whitted: 'glossy_samples' must be an integer >= 1, got {glossy_samples!r}")
        self.glossy_samples = glossy_samples
        indirect = props.get("indirect", 0)   # docs/EXTENSIONS.md E.15: gathered rays per diffuse hit
        if isinstance(indirect, bool) or not isinstance(indirect, int) or indirect < 0:
            raise ValueError(f"a5_whitted: 'indirect' must be an integer >= 0, got {indirect!r}")
        self.indirect = indirect
        self._medium = media.params_from_props(props)   # docs/EXTENSIONS.md E.8, E.9 (None: no medium)
        self.subsurface = subsurface.method_from_props(props)   # docs/EXTENSIONS.md E.18
        self._rules: dict[int, triangle_rule.RuleTable] = {}   # id(scene) -> its rule table (the last scene only)

    # ------------------------------------------------------------------ Mitsuba interface

    def aov_names(self) -> list[str]:
        return [name for g in self.aovs for name in AOV_CHANNELS[g]]

    def _rule_table(self, scene: mi.Scene) -> triangle_rule.RuleTable | None:
        """The scene's triangle-rule table (plugins/triangle_rule.py), kept while its buffers are unchanged:
        a cache of a value derived from the scene (recomputed when the scene or its buffers change), not state
        that changes what a call computes."""
        cached = self._rules.get(id(scene))
        table = triangle_rule.rule_table(scene, cached)
        self._rules = {id(scene): table} if table is not None else {}
        return table

    def trace(
        self, scene: mi.Scene, ray: mi.Ray3f, active: mi.Bool | bool = True, sampler: mi.Sampler | None = None,
        record: TreeRecorder | None = None, sample_pass: SamplePass | None = None, ray_log: RayLog | None = None,
    ) -> TreeResult:
        """SPEC B.3 for camera rays: ``(colour, normal, t, class, n_reflection, n_refraction, n_shadow)``.

        Parameter ``sample_pass`` (:class:`~.sampling.SamplePass`): which samples the lanes are (E.5); None: keys
        from ``sampler``. Parameter ``record`` (``a5mi trace``): fill this recorder with every node of each
        lane's ray tree (a kernel with the recording calls). Parameter ``ray_log`` (``a5mi bench``'s traversal
        floor): write every node ray and shadow ray the kernel casts into this
        :class:`~.kernel.raylog.RayLog` (a kernel with the logging calls; the colour is the same)."""
        data = SceneData(dr.opaque(mi.UInt32, depth_budget(self.max_depth, self.mistakes)),
                         dr.opaque(mi.Color3f, self.ambient), dr.opaque(mi.Float, self.tmin), lights_of(scene),
                         self._planes, self._rule_table(scene), self._medium)
        features = build_features(self, scene, data, record=record is not None, ray_log=ray_log is not None)
        width = _width(ray, active)
        # Every loop variable must be full width (a width-1 stack pointer makes lanes loop forever).
        o = mi.Point3f(ray.o) + dr.zeros(mi.Point3f, width)
        d = mi.Vector3f(ray.d) + dr.zeros(mi.Vector3f, width)
        rng = stochastic(sample_pass, sampler, width, self.glossy_samples)
        return trace_tree(scene, o, d, dr.full(mi.Bool, True, width) & active, data, rng, features, record, ray_log)

    def sample(
        self, scene: mi.Scene, sampler: mi.Sampler | None, ray: mi.Ray3f, medium: mi.Medium | None = None,
        active: mi.Bool | bool = True, sample_pass: SamplePass | None = None,
    ) -> tuple[mi.Color3f, mi.Bool, list[mi.Float]]:
        """Colour of one camera ray per lane, the ``active`` mask, and the AOVs of :meth:`aov_names`;
        ``sample_pass`` as in :meth:`trace` (Mitsuba's own ``mi.render`` passes none)."""
        color, n, t, cls, n_refl, n_refr, n_shadow = self.trace(scene, ray, active, sampler,
                                                                sample_pass=sample_pass)
        channels = {"normal": [n.x, n.y, n.z], "depth": [t], "class": [cls], "counts": [n_refl, n_refr, n_shadow]}
        aovs = [a for g in self.aovs for a in channels[g]]
        width = _width(ray, active)
        return color, dr.full(mi.Bool, True, width) & active, aovs

    def traverse(self, callback: mi.TraversalCallback) -> None:
        flags = int(mi.ParamFlags.NonDifferentiable)
        callback.put("max_depth", self.max_depth, flags)
        callback.put("shadows", self.shadows, flags)
        callback.put("ambient", mi.ScalarColor3f(self.ambient), flags)
        callback.put("phong", self.phong, flags)
        callback.put("fresnel", self.fresnel, flags)
        callback.put("reflection", self.reflection, flags)
        callback.put("refraction", self.refraction, flags)
        callback.put("tmin", self.tmin, flags)
        callback.put("aovs", ",".join(self.aovs), flags)
        callback.put("glossy_samples", self.glossy_samples, flags)
        callback.put("dispersion", self.dispersion, flags)
        callback.put("bump", self.bump, flags)
        callback.put("glossy", self.glossy, flags)
        callback.put("indirect", self.indirect, flags)
        callback.put("mistakes", ",".join(self.mistakes), flags)

    def to_string(self) -> str:
        return (
            f"A5WhittedIntegrator[max_depth={self.max_depth}, shadows={self.shadows}, "
            f"ambient={self.ambient}, phong={self.phong}, fresnel='{self.fresnel}', "
            f"reflection={self.reflection}, refraction={self.refraction}, tmin={self.tmin}, "
            f"aovs='{','.join(self.aovs)}', glossy_samples={self.glossy_samples}, "
            f"dispersion={self.dispersion}, bump={self.bump}, glossy={self.glossy}, "
            f"medium='{self._medium.kind if self._medium is not None else 'none'}', planes={len(self.planes)}, "
            f"mistakes='{','.join(self.mistakes)}']"
        )


def register() -> None:
    """Register ``a5_whitted`` with Mitsuba for the active variant."""
    mi.register_integrator("a5_whitted", lambda props: A5WhittedIntegrator(props))

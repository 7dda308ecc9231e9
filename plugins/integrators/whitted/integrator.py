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

from a5mi.plugins.integrators.base import A5Integrator, camera_rays, ray_width
from a5mi.plugins.integrators.whitted import subsurface
from a5mi.plugins.integrators.whitted.raytree import TreeResult, trace_tree
from a5mi.plugins.kernel.raylog import RayLog
from a5mi.plugins.kernel.record import TreeRecorder
from a5mi.plugins.media import medium as media
from a5mi.plugins.params import read_bool, read_int, read_names
from a5mi.plugins.sampling import SamplePass, stochastic
from a5mi.render.options import KERNEL_MISTAKES


class A5WhittedIntegrator(A5Integrator):
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
                                     (docs/EXTENSIONS.md E.18, plugins/integrators/whitted/subsurface.py)
    bump             bool    false   bump / normal-mapped shading normal (``-bump``, docs/EXTENSIONS.md E.7)
    glossy           bool    true    false: no material has roughness > 0 (the E.4 lobe sampling is
                                     left out of the kernel; the converter says so for its scenes)
    aovs             string  ""      comma-separated AOV groups: ``normal`` (nx, ny, nz), ``depth``
                                     (t), ``class`` (class), ``counts`` (n_reflection, n_refraction,
                                     n_shadow)
    indirect         int     0       rays gathered at each diffuse hit (``-indirect``, EXTENSIONS E.15)
    two_sided        bool    false   the light loop lights the face the ray sees (N turned toward the
                                     ray; ``-two_sided``, EXTENSIONS E.15); false: SPEC B.3's front face
    medium           string  none    ``fog`` / ``volume``: a participating medium (EXTENSIONS E.8,
                                     E.9; ``medium_*`` parameters, plugins/media/medium.py)
    mistakes         string  ""      comma-separated names of ``KERNEL_MISTAKES`` (docs/MISTAKES.md): render as
                                     a student with those mistakes would (empty: SPEC B.3)
    plane_<id>_*     ...             an exact infinite plane: ``_normal`` vector, ``_offset`` float,
                                     ``_bsdf`` BSDF, optional ``_mirror_normal`` (SPEC A.6,
                                     plugins/emulation/planes.py)
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

    name = "a5_whitted"
    aov_groups = ("normal", "depth", "class", "counts")
    has_media = True
    exposed = ("max_depth", "shadows", "ambient", "phong", "fresnel", "reflection", "refraction", "tmin", "aovs",
               "glossy_samples", "dispersion", "bump", "glossy", "indirect", "two_sided", "mistakes")

    def __init__(self, props: mi.Properties) -> None:
        super().__init__(props)   # the shared parameters (plugins/integrators/base.py)
        self.indirect = read_int(self.name, props, "indirect", 0, 0)   # E.15: gathered rays per diffuse hit
        self.two_sided = read_bool(self.name, props, "two_sided", False)   # E.15: both faces lit by the light loop
        # docs/MISTAKES.md: the kernel mistakes compiled in
        self.mistakes = tuple(sorted(read_names(self.name, props, "mistakes", KERNEL_MISTAKES, "names")))
        self._medium = media.params_from_props(props)   # docs/EXTENSIONS.md E.8, E.9 (None: no medium)
        self.subsurface = subsurface.method_from_props(props)   # docs/EXTENSIONS.md E.18

    # ------------------------------------------------------------------ Mitsuba interface

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
        data = self.scene_data(scene)
        features = self.features(scene, data, record=record is not None, ray_log=ray_log is not None)
        o, d, go = camera_rays(ray, active)
        rng = stochastic(sample_pass, sampler, dr.width(go), self.glossy_samples)
        return trace_tree(scene, o, d, go, data, rng, features, record, ray_log)

    def sample(
        self, scene: mi.Scene, sampler: mi.Sampler | None, ray: mi.Ray3f, medium: mi.Medium | None = None,
        active: mi.Bool | bool = True, sample_pass: SamplePass | None = None,
    ) -> tuple[mi.Color3f, mi.Bool, list[mi.Float]]:
        """Colour of one camera ray per lane, the ``active`` mask, and the AOVs of :meth:`aov_names`;
        ``sample_pass`` as in :meth:`trace` (Mitsuba's own ``mi.render`` passes none)."""
        r = self.trace(scene, ray, active, sampler, sample_pass=sample_pass)
        channels = {"normal": [r.n.x, r.n.y, r.n.z], "depth": [r.t], "class": [r.cls],
                    "counts": [r.n_reflection, r.n_refraction, r.n_shadow]}
        return r.color, dr.full(mi.Bool, True, ray_width(ray, active)) & active, self.aov_values(channels)

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

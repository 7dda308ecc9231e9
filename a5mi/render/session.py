"""Scene building and warm render sessions: description -> dict -> Mitsuba objects -> driver (SPEC B.1, B.5).

The caller's side of the driver. :func:`build_scene` is the one place a :class:`SceneDescription` becomes Mitsuba
objects (:func:`a5mi.converters.to_mitsuba.to_dict`, then ``mi.load_dict``); :func:`render` is one render of a
description (build, then :func:`a5mi.render.driver.render_scene`); the driver itself only renders loaded scenes.

One ``a5`` process pays ~0.5 s of fixed cost (interpreter, ``import mitsuba``, variant, plugin registration,
parse with file checks, scene build) besides the kernel. A :class:`RenderSession` (batch renders: ``a5mi
render`` with several scenes or ``--jobs``) pays the import and the variant once, and for each scene
description it keeps

* the loaded Mitsuba scene (``mi.load_dict`` of :func:`a5mi.converters.to_mitsuba.to_dict`): its shapes,
  materials and lights do not depend on the render options, only the integrator and the film do, and the
  driver traces its own SPEC B.2 camera rays, so the film is never read;
* one integrator per distinct plugin and :meth:`~a5mi.render.options.RenderOptions.integrator_params`
  (``-shadows``, ``-bounces``, ``-v``'s counts AOVs, ...), loaded alone from the scene dict's own
  ``integrator`` entry (ambient, the exact planes and their loaded BSDFs) with those parameters replaced, so
  a job renders with exactly the integrator a separate ``a5`` run would build (bit-identical images,
  tests/cli/test_batch.py).

Kernels: Dr.Jit's in-memory kernel cache lives as long as the process. Every per-scene value that enters
the render kernel is an opaque JIT value (camera basis, lights, marble, plane set, image atlas offsets), so
the second render of a scene, and the first render of another scene of the same kind (same shapes, plugins
and flags, other positions and colours), launch the cached kernel without compiling
(:attr:`a5mi.render.driver.RenderResult.kernels` counts the launches by source). What a repeated render still pays
is the Python trace of the integrator (it builds the kernel's IR before the hash is known; docs/SPEED.md says
why Dr.Jit's frozen functions do not replace it here), the camera rays and the buffer copies (the ``-jitter``
positions and the texture atlases are kept: :mod:`a5mi.render.tiles`, ``plugins/textures/imagedata.py``):
``a5mi bench`` measures the cost per extra render against its kernel + filter + write time.

At most ``max_scenes`` built scenes are kept (least recently used dropped first, and freed *before* the next
one is built), so a long job list has bounded memory. The default is one: while a scene is alive, the next
scene's plugins get new registry IDs and the vcall tables' offsets baked into the render kernel change, so
the next scene would compile its kernel again; freed first, the IDs are reused and the kernel is found in the
cache (``kernels["compiled"] == 0``, tests/cli/test_batch.py). (Mitsuba's own ``sphere`` bakes its
centre into the kernel: a moved sphere compiles again whatever the session does.) Nothing here prints or
writes a file; it returns data (:class:`~a5mi.render.driver.RenderResult`).
"""

from __future__ import annotations

import gc
import time
import weakref
from collections import OrderedDict
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from a5mi.platform.loading import load_dict
from a5mi.render.driver import Progress, RenderResult, render_scene
from a5mi.render.options import MARBLE_MISTAKES, RenderOptions

if TYPE_CHECKING:
    import mitsuba as mi

    from a5mi.converters.describe import SceneDescription, SceneWarning


def scene_dict(desc: SceneDescription, options: RenderOptions) -> dict[str, Any]:
    """The ``mi.load_dict`` dict of ``desc`` with ``a5_whitted`` set up by ``options``
    (:func:`a5mi.converters.to_mitsuba.to_dict`; no file is read here)."""
    from a5mi.converters.to_mitsuba import to_dict

    return to_dict(desc, options)


def build_scene(desc: SceneDescription, options: RenderOptions) -> mi.Scene:
    """The Mitsuba scene of ``desc``, its integrator ``a5_whitted`` with ``options``' parameters:
    ``load_dict(scene_dict(desc, options))`` (:func:`a5mi.platform.loading.load_dict`: built on the
    calling thread)."""
    return load_dict(scene_dict(desc, options))


def render(desc: SceneDescription, options: RenderOptions, *, progress: Progress | None = None) -> RenderResult:
    """Render a scene description as ``a5soln`` would (SPEC B.2, B.5): :func:`build_scene`, then
    :func:`a5mi.render.driver.render_scene` with ``desc.camera``; ``timings["build"]`` is the build's seconds.

    Needs an active JIT variant with the a5mi plugins registered (:func:`a5mi.runtime.variant.activate`).
    """
    t0 = time.perf_counter()
    mi_scene = build_scene(desc, options)
    t_build = time.perf_counter() - t0
    result = render_scene(mi_scene, desc.camera, options, progress=progress)
    result.timings["build"] = t_build
    return result


@dataclass
class _Built:
    """A scene description with its loaded Mitsuba scene, the scene dict's ``integrator`` entry (the
    template of the others) and the integrators made for it so far (by :func:`_integrator_key`)."""

    desc: SceneDescription
    scene: mi.Scene
    template: dict[str, Any]
    integrators: dict[str, mi.SamplingIntegrator] = field(default_factory=dict)


def _integrator_key(options: RenderOptions) -> str:
    return repr((options.plugin, sorted(options.integrator_params().items())))


class RenderSession:
    """Render many jobs in one process (module docstring). ``variant``: as ``a5 -variant`` (activated once,
    here; raises :class:`a5mi.runtime.variant.VariantError`). ``max_scenes``: built scenes kept at most."""

    def __init__(self, variant: str | None = None, *, max_scenes: int = 1) -> None:
        from a5mi.runtime import variant as variants

        if max_scenes < 1:
            raise ValueError(f"max_scenes must be >= 1, got {max_scenes}")
        self.variant = variants.activate(variant)
        self.max_scenes = max_scenes
        self._built: OrderedDict[tuple[int, tuple[str, ...]], _Built] = OrderedDict()
        #: scenes built (``mi.load_dict`` of a whole scene) and integrators loaded on their own, so far
        self.scenes_built = 0
        self.integrators_loaded = 0

    def _entry(self, desc: SceneDescription, options: RenderOptions) -> tuple[_Built, float]:
        """The cached scene of ``desc`` (built now if absent) and the seconds spent building."""
        key = (id(desc), options.of_layer(MARBLE_MISTAKES))   # docs/MISTAKES.md: marble mistakes live in the scene
        entry = self._built.get(key)
        if entry is not None and entry.desc is desc:
            self._built.move_to_end(key)
            return entry, 0.0
        t0 = time.perf_counter()
        if len(self._built) >= self.max_scenes:  # free first: the new scene's plugins then reuse the registry IDs
            _free(self._built.popitem(last=False)[1])
        scene, template, integ = self.build(desc, options)
        entry = _Built(desc, scene, template, {_integrator_key(options): integ})
        self.scenes_built += 1
        self._built[key] = entry
        return entry, time.perf_counter() - t0

    def build(self, desc: SceneDescription, options: RenderOptions
              ) -> tuple[mi.Scene, dict[str, Any], mi.SamplingIntegrator]:
        """``(Mitsuba scene, the scene dict's integrator entry, the scene's integrator)`` of ``desc``: one
        ``mi.load_dict`` of :func:`scene_dict` (a subclass may reuse objects of its earlier builds)."""
        whole = scene_dict(desc, options)
        own = options.integrator_params()   # the options' part; the template keeps the scene's (ambient, planes, ...)
        template = {k: v for k, v in whole["integrator"].items() if k not in own}
        scene = load_dict(whole)
        return scene, template, scene.integrator()

    def integrator(self, desc: SceneDescription, options: RenderOptions
                   ) -> tuple[mi.Scene, mi.SamplingIntegrator, float]:
        """``(mitsuba scene, a5_whitted integrator, build seconds)`` for ``desc`` rendered with ``options``:
        the scene built once per description, the integrator once per distinct set of its parameters."""
        entry, spent = self._entry(desc, options)
        ikey = _integrator_key(options)
        integ = entry.integrators.get(ikey)
        if integ is None:
            t0 = time.perf_counter()
            integ = load_dict({**entry.template, "type": options.plugin, **options.integrator_params()})
            entry.integrators[ikey] = integ
            self.integrators_loaded += 1
            spent += time.perf_counter() - t0
        return entry.scene, integ, spent

    def render(self, desc: SceneDescription, options: RenderOptions, *,
               progress: Progress | None = None) -> RenderResult:
        """:func:`render` of a scene description (:func:`a5mi.converters.describe.describe`) through the
        session's caches; ``timings["build"]`` is 0 when the scene and integrator were cached."""
        scene, integ, spent = self.integrator(desc, options)
        result = render_scene(scene, desc.camera, options, integrator=integ, progress=progress)
        result.timings["build"] = spent
        return result

    def forget(self, desc: SceneDescription) -> None:
        """Drop the built scene of ``desc`` (its kernels stay in Dr.Jit's cache)."""
        for key in [k for k in self._built if k[0] == id(desc)]:
            del self._built[key]


def _free(entry: _Built) -> None:
    """Drop ``entry``'s scene (module docstring: freed before the next build). Reference counting frees it when
    nothing else holds it; a full ``gc.collect()`` (0.04-0.06 s in a warm process) runs only when one of its
    Python plugins (the integrators, emitters, materials: weakly referenced here) outlives the drop, e.g. held
    by a reference cycle. The scene holds its integrator, so a dead integrator means a freed scene."""
    probes = []
    for obj in (entry.scene.integrator(), *entry.integrators.values(), *entry.scene.emitters(),
                *(shape.bsdf() for shape in entry.scene.shapes())):
        try:
            probes.append(weakref.ref(obj))
        except TypeError:   # a C++ plugin: not weakly referenceable
            pass
    obj = None
    entry.integrators.clear()
    del entry
    if not probes or any(probe() is not None for probe in probes):
        gc.collect()


def describe_file(path: str, *, bump: bool = False) -> tuple[SceneDescription, list[SceneWarning]]:
    """``(scene description, warnings)`` of a scene file: parse (SPEC A) + describe (every file it names read
    and checked once; ``bump``: with its bump and normal maps, EXTENSIONS E.7); warnings are ``(FileLoc,
    message)`` pairs. Raises the parser's positioned :class:`~a5mi.converters.errors.SceneError`."""
    from a5mi.converters.a5_parser import parse_file
    from a5mi.converters.describe import describe

    model = parse_file(path)
    desc = describe(model, bump=bump)
    return desc, [*model.warnings, *desc.warnings]


__all__ = ["RenderSession", "build_scene", "describe_file", "render", "scene_dict"]

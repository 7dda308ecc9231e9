"""A warm render session: Mitsuba loaded once, scenes built once, kernels reused (issue 20, batch renders).

One ``a5`` process pays ~0.5 s of fixed cost (interpreter, ``import mitsuba``, variant, plugin registration,
parse with file checks, scene build) besides the kernel. A :class:`RenderSession` pays the import and the
variant once, and for each scene description it keeps

* the loaded Mitsuba scene (``mi.load_dict`` of :func:`a5mi.converters.to_mitsuba.to_dict`): its shapes,
  materials and lights do not depend on the render options, only the integrator and the film do, and the
  driver traces its own SPEC B.2 camera rays, so the film is never read;
* one ``a5_whitted`` integrator per distinct :meth:`~a5mi.options.RenderOptions.integrator_params`
  (``-shadows``, ``-bounces``, ``-v``'s counts AOVs, ...), loaded alone from the scene dict's own
  ``integrator`` entry (ambient, the exact planes and their loaded BSDFs) with those parameters replaced, so
  a job renders with exactly the integrator a separate ``a5`` run would build (bit-identical images,
  tests/test_batch.py).

Kernels: Dr.Jit's in-memory kernel cache lives as long as the process. Every per-scene value that enters
the render kernel is an opaque JIT value (camera basis, lights, marble, plane set, image atlas offsets), so
the second render of a scene, and the first render of another scene of the same kind (same shapes, plugins
and flags, other positions and colours), launch the cached kernel without compiling
(:attr:`a5mi.driver.RenderResult.kernels` counts the launches by source). What a repeated render still pays
is the Python trace of the integrator (it builds the kernel's IR before the hash is known), the jitter draw,
the camera rays and the buffer copies: ``a5mi bench`` measures the cost per extra render against its
kernel + filter + write time.

At most ``max_scenes`` built scenes are kept (least recently used dropped first, and freed *before* the next
one is built), so a long job list has bounded memory. The default is one: while a scene is alive, the next
scene's plugins get new registry IDs and the vcall tables' offsets baked into the render kernel change, so
the next scene would compile its kernel again (measured, BENCHMARKS.md run E item 7); freed first, the IDs are
reused and the kernel is found in the cache. (Mitsuba's own ``sphere`` bakes its centre into the kernel: a
moved sphere compiles again whatever the session does.) The session never prints and never writes a file; it
returns data (:class:`~a5mi.driver.RenderResult`).
"""

from __future__ import annotations

import gc
import time
from collections import OrderedDict
from dataclasses import dataclass, field
from typing import Any

from a5mi.options import RenderOptions


@dataclass
class _Built:
    """A scene description with its loaded Mitsuba scene, the scene dict's ``integrator`` entry (the
    template of the others) and the integrators made for it so far (by :func:`_integrator_key`)."""

    desc: Any
    scene: Any
    template: dict[str, Any]
    integrators: dict[str, Any] = field(default_factory=dict)


def _integrator_key(options: RenderOptions) -> str:
    return repr(sorted(options.integrator_params().items()))


class RenderSession:
    """Render many jobs in one process (module docstring). ``variant``: as ``a5 -variant`` (activated once,
    here; raises :class:`a5mi.variant.VariantError`). ``max_scenes``: built scenes kept at most."""

    def __init__(self, variant: str | None = None, *, max_scenes: int = 1) -> None:
        from a5mi import variant as variants

        if max_scenes < 1:
            raise ValueError(f"max_scenes must be >= 1, got {max_scenes}")
        self.variant = variants.activate(variant)
        self.max_scenes = max_scenes
        self._built: OrderedDict[int, _Built] = OrderedDict()
        #: scenes built (``mi.load_dict`` of a whole scene) and integrators loaded on their own, so far
        self.scenes_built = 0
        self.integrators_loaded = 0

    def _entry(self, desc: Any, options: RenderOptions) -> tuple[_Built, float]:
        """The cached scene of ``desc`` (built now if absent) and the seconds spent building."""
        import mitsuba as mi

        from a5mi import interrupts
        from a5mi.converters.to_mitsuba import to_dict

        key = id(desc)
        entry = self._built.get(key)
        if entry is not None and entry.desc is desc:
            self._built.move_to_end(key)
            return entry, 0.0
        t0 = time.perf_counter()
        if len(self._built) >= self.max_scenes:  # free first: the new scene's plugins then reuse the registry IDs
            self._built.popitem(last=False)
            gc.collect()
        scene_dict = to_dict(desc, options)
        template = dict(scene_dict["integrator"])
        with interrupts.deferred():  # plugin constructors run inside Mitsuba's C++ loader
            scene = mi.load_dict(scene_dict)
        entry = _Built(desc, scene, template, {_integrator_key(options): scene.integrator()})
        self.scenes_built += 1
        self._built[key] = entry
        return entry, time.perf_counter() - t0

    def integrator(self, desc: Any, options: RenderOptions) -> tuple[Any, Any, float]:
        """``(mitsuba scene, a5_whitted integrator, build seconds)`` for ``desc`` rendered with ``options``:
        the scene built once per description, the integrator once per distinct set of its parameters."""
        import mitsuba as mi

        from a5mi import interrupts
        entry, spent = self._entry(desc, options)
        ikey = _integrator_key(options)
        integ = entry.integrators.get(ikey)
        if integ is None:
            t0 = time.perf_counter()
            with interrupts.deferred():
                integ = mi.load_dict({**entry.template, **options.integrator_params()})
            entry.integrators[ikey] = integ
            self.integrators_loaded += 1
            spent += time.perf_counter() - t0
        return entry.scene, integ, spent

    def render(self, desc: Any, options: RenderOptions, *, progress: Any = None) -> Any:
        """:func:`a5mi.driver.render` of a scene description (:func:`a5mi.converters.describe.describe`)
        through the session's caches; ``timings["build"]`` is 0 when the scene and integrator were cached."""
        from a5mi.driver import render_scene

        scene, integ, spent = self.integrator(desc, options)
        result = render_scene(scene, desc.camera, options, integrator=integ, progress=progress)
        result.timings["build"] = spent
        return result

    def forget(self, desc: Any) -> None:
        """Drop the built scene of ``desc`` (its kernels stay in Dr.Jit's cache)."""
        self._built.pop(id(desc), None)


def describe_file(path: str) -> tuple[Any, list[Any]]:
    """``(scene description, warnings)`` of a scene file: parse (SPEC A) + describe (every file it names read
    and checked once). Raises the parser's positioned :class:`~a5mi.converters.errors.SceneError`."""
    from a5mi.converters.a5_parser import parse_file
    from a5mi.converters.describe import describe

    model = parse_file(path)
    desc = describe(model)
    return desc, [*model.warnings, *desc.warnings]


__all__ = ["RenderSession", "describe_file"]

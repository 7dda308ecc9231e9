"""What the kernel reads off a loaded scene's emitters: its lights as gatherable arrays (SPEC A.3, B.3 light
loop; docs/EXTENSIONS.md E.1, E.2). A leaf of the kernel: no other kernel module is imported here."""

from __future__ import annotations

from typing import NamedTuple

import drjit as dr
import mitsuba as mi


class Lights(NamedTuple):
    """The scene's lights as gatherable arrays: ``emitters`` (pointers; one null entry when there are none),
    ``count`` (opaque), per light its sample count ``samples`` (1 for a delta light) and ``area`` (1 for an
    area light, E.2)."""

    emitters: mi.EmitterPtr
    count: mi.UInt32
    samples: mi.UInt32
    area: mi.UInt32


def area_samples(e: mi.Emitter) -> int | None:
    """The sample count of an ``a5_area`` emitter (its ``samples`` parameter), None for any other emitter."""
    samples = getattr(e, "samples", None)
    return None if samples is None else int(samples)


def is_light(e: mi.Emitter) -> bool:
    """A light of the light loop: a delta emitter (SPEC A.3, E.1) or an ``a5_area`` emitter (E.2)."""
    return mi.has_flag(e.flags(), mi.EmitterFlags.Delta) or area_samples(e) is not None


def has_area_lights(scene: mi.Scene) -> bool:
    """Whether the kernel needs E.2's blocks: some emitter is an ``a5_area`` light or sits on a shape."""
    return any(area_samples(e) is not None or e.get_shape() is not None for e in scene.emitters())


def lights_of(scene: mi.Scene) -> Lights:
    """The :class:`Lights` of ``scene``, in ``scene.emitters()`` order."""
    emitters = scene.emitters()
    idx = [i for i, e in enumerate(emitters) if is_light(e)]
    lights = [emitters[i] for i in idx]
    samples = mi.UInt32([1 if area_samples(e) is None else area_samples(e) for e in lights] or [1])
    area = mi.UInt32([0 if area_samples(e) is None else 1 for e in lights] or [0])
    if not idx:
        return Lights(dr.zeros(mi.EmitterPtr, 1), dr.opaque(mi.UInt32, 0), samples, area)
    ptrs = dr.gather(mi.EmitterPtr, scene.emitters_dr(), mi.UInt32(idx))
    dr.eval(ptrs)
    return Lights(ptrs, dr.opaque(mi.UInt32, len(idx)), samples, area)

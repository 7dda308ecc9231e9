"""The limits a render's options must keep together, one check for the command line and the live page.

Each flag's own range is its flag table's (``a5mi/commands/render.py``, the page's :data:`a5mi.view.controls.CONTROLS`);
these are the limits that involve several options (SPEC B.1, B.5 and docs/EXTENSIONS.md):

* the sample budget: ``W · H · k²`` render-buffer samples (``k = 3`` with ``-jitter``) at most :data:`MAX_SAMPLES`;
* ``-indirect N`` and ``-two_sided`` (E.15) are modes of the Whitted integrator; ``-indirect N`` keeps up to
  ``(N + 1) · bounces`` pending rays per camera ray: at most :data:`MAX_PENDING` (the kernel's per-lane stack);
* ``-filter`` without ``-jitter`` saves a ``W/3 x H/3`` image: ``W, H >= 3``;
* ``-crop``: a region of the saved image, of a mode that crops (:func:`a5mi.render.crop.refusal`);
* the memory: :func:`a5mi.platform.resources.render_bytes` plus :func:`a5mi.platform.resources.integrator_bytes`
  (photon maps and kd-trees, ppm statistics, irradiance records), and for a split render
  :func:`a5mi.platform.resources.split_bytes`, must fit in :func:`a5mi.platform.resources.available`.

A refusal is a :class:`a5mi.platform.errors.UsageError` of one line naming the flags in the ``-flag`` spelling both the
``a5`` command and the page show.
"""

from __future__ import annotations

from a5mi.platform import resources
from a5mi.platform.errors import UsageError
from a5mi.render import crop
from a5mi.render.options import RenderOptions
from a5mi.spec import JITTER_FACTOR

#: SPEC B.5: the most render-buffer samples one render may have.
MAX_SAMPLES = 1 << 28
#: docs/EXTENSIONS.md E.15: most pending rays per camera ray ``(N + 1) · bounces`` that ``-indirect N`` may keep
#: (the kernel's per-lane stack, plugins/kernel/pbr_gather.py ``stack_size``)
MAX_PENDING = 256


def check_combination(o: RenderOptions) -> None:
    """Raise :class:`UsageError` for the first multi-option limit (module docstring) ``o`` breaks, memory aside."""
    k = JITTER_FACTOR if o.jitter else 1
    samples = o.width * o.height * k * k
    if samples > MAX_SAMPLES:
        raise UsageError(f"-size {o.width} {o.height}{' with -jitter' if o.jitter else ''} is {samples} "
                         f"samples; the limit is {MAX_SAMPLES}")
    if o.indirect and o.integrator != "whitted":
        raise UsageError(f"-indirect is a mode of the whitted integrator, not of -integrator {o.integrator}")
    if o.two_sided and o.integrator != "whitted":
        raise UsageError(f"-two_sided is a mode of the whitted integrator (-integrator {o.integrator} lights "
                         "both faces already)")
    if o.indirect and (o.indirect + 1) * o.bounces > MAX_PENDING:
        pending = (o.indirect + 1) * o.bounces
        raise UsageError(f"-indirect {o.indirect} with -bounces {o.bounces} keeps up to {pending} pending rays per "
                         f"camera ray; the limit is {MAX_PENDING} (fewer rays or bounces)")
    if o.filter and not o.jitter and (o.width < 3 or o.height < 3):
        raise UsageError(f"-filter without -jitter saves a W/3 x H/3 image; -size {o.width} {o.height} is "
                         "too small")
    why = crop.refusal(o)
    if why is not None:
        raise UsageError(why)


def memory_need(o: RenderOptions, *, aovs: bool = False, workers: int | None = None) -> int:
    """Estimated peak bytes of rendering ``o`` (module docstring); ``workers``: local worker processes of a
    split render (0: a remote scheduler's), None: one process."""
    rw, rh = o.render_size
    render = resources.render_bytes(rw, rh, width=o.width, height=o.height, aovs=aovs, jitter=o.jitter,
                                    filtered=o.filter, tile_rays=o.tile_rays)
    extra = resources.integrator_bytes(o.integrator, rw * rh, photons=o.photons, caustic_photons=o.caustic_photons,
                                       photon_depth=o.photon_depth)
    if workers is None:
        return render + extra
    return resources.split_bytes(render, extra, rw * rh, workers)


def _what(o: RenderOptions, workers: int | None) -> str:
    words = f"-size {o.width} {o.height}{' with -jitter' if o.jitter else ''}"
    if o.integrator in ("photon", "ppm"):
        words += f" -integrator {o.integrator} -photons {o.photons} -caustic_photons {o.caustic_photons}"
    elif o.integrator == "irradiancecache":
        words += " -integrator irradiancecache"
    if workers:
        words += f" on {workers} workers"
    return words


def check_memory(o: RenderOptions, *, aovs: bool = False, workers: int | None = None, hint: str = "") -> None:
    """Raise :class:`UsageError` when :func:`memory_need` exceeds :func:`a5mi.platform.resources.available`:
    ``-size W H [-integrator photon -photons N -caustic_photons M] needs about X GB of memory; Y GB is available``."""
    need = memory_need(o, aovs=aovs, workers=workers)
    enough, have = resources.fits(need)
    if not enough:
        raise UsageError(f"{_what(o, workers)} needs about {resources.gb(need)} of memory; "
                         f"{resources.gb(have or 0)} is available{hint}")


def check_options(o: RenderOptions, *, aovs: bool = False, workers: int | None = None, hint: str = "") -> None:
    """:func:`check_combination` then :func:`check_memory`: every limit of the module docstring."""
    check_combination(o)
    check_memory(o, aovs=aovs, workers=workers, hint=hint)


__all__ = ["MAX_PENDING", "MAX_SAMPLES", "check_combination", "check_memory", "check_options", "memory_need"]

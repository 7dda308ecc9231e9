"""The engine's loop: take jobs, render or trace, publish the state (docs/VIEW.md).

:func:`run_engine` runs on the thread that owns Mitsuba until ``stop`` is set or a signal's
:class:`~a5mi.platform.interrupts.Interrupted` ends it (it waits for jobs in steps of :data:`WAIT_SECONDS` and calls
:func:`a5mi.platform.interrupts.check` between them). A render job reloads the scene when a watched file changed
(:mod:`a5mi.view.watcher`), renders (first the marked region at full quality, published pasted on the image
shown before, :mod:`a5mi.view.region`; then the one-ray preview where :func:`wants_preview` says the full image is
slow, the region pasted on it too), compares and publishes the new state and images (the PNGs and the pixel values of
:mod:`a5mi.view.pixels`). A diagnose job runs :func:`a5mi.view.pixels.diagnose_frame` on the current frame and
publishes its result as the state's ``diagnosis``. A scene error (the
positioned one-line ``FILE:LINE:COL: error: ...``) or another user error is published as ``error`` and the last
good images stay; an unexpected exception is published as an internal error and the loop goes on.
"""

from __future__ import annotations

import dataclasses
import threading
import time
from collections.abc import Callable
from functools import partial
from typing import Any

from a5mi.platform.errors import UserError
from a5mi.view.controls import describe_controls
from a5mi.view.engine import preview_options
from a5mi.view.pixels import ReferenceValues, diagnose_frame, is_float_image, render_values
from a5mi.view.region import paste, render_region, saved_size, why_not
from a5mi.view.watcher import snapshot

#: Seconds between two checks for a signal while no job waits.
WAIT_SECONDS = 0.25
#: The one-ray preview (:func:`~a5mi.view.engine.preview_options`) is shown before a full image only when the
#: last full render with the same options took longer than this many seconds, or there is none yet
#: (:func:`wants_preview`): the preview's own render and PNG (a W x H render, about a ninth of the full one's
#: samples) delay the full image, worth it only when the full image is slow to come.
PREVIEW_AFTER_SECONDS = 0.5
#: The state of a frame that a preview, or a frame not compared yet, leaves as the last comparison set it (the
#: page dims them meanwhile).
COMPARED = ("metrics", "reference_error", "has_reference", "has_diff", "compared")


class Superseded(Exception):
    """A newer render request arrived while a render was under way: the render stops at its next tile."""


def preemptible(hub: Any, jobs: Any) -> Callable[..., None]:
    """The progress callback of a render: forwards to ``hub.progress`` and raises :class:`Superseded` at a
    render or preview step when a newer request waits (``jobs.render_pending()``), so the loop starts the
    newest request instead of finishing a stale one."""
    def progress(stage: str, done: int, total: int, **extra: Any) -> None:
        hub.progress(stage, done, total, **extra)
        if stage in ("render", "preview") and done < total and jobs.render_pending():
            raise Superseded
    return progress


def error_line(exc: BaseException) -> str:
    """The one line of a user error as the command line prints it."""
    from a5mi.converters.errors import SceneError

    if isinstance(exc, SceneError):
        return str(exc) if exc.loc is not None else f"a5mi view: error: {exc.msg}"
    return f"a5mi view: error: {str(exc).splitlines()[0] if str(exc) else type(exc).__name__}"


def frame_state(engine: Any, frame: Any) -> dict[str, Any]:
    """The part of the page's state a rendered frame gives."""
    from a5mi.trace.core import pixel_grid

    compared = frame.metrics is not None or frame.reference_error is not None
    return {"frame": frame.version, "preview": frame.preview, "composite": frame.composite, "kernels": frame.kernels,
            "compared": frame.version if compared else None,
            "size": list(frame.size), "grid": list(pixel_grid(frame.options)),
            "render_size": list(frame.options.render_size), "metrics": frame.metrics,
            "reference_error": frame.reference_error, "has_reference": frame.reference_png is not None,
            "has_diff": frame.diff_png is not None, "seconds": frame.seconds,
            "controls": describe_controls(frame.options)}


def wants_preview(last_full: tuple[Any, float] | None, options: Any, after: float = PREVIEW_AFTER_SECONDS) -> bool:
    """Whether a render with ``options`` shows its preview first: ``last_full`` is ``(options, seconds)`` of the
    last full render (None before the first); yes when there is none with these options or it took longer than
    ``after`` seconds (:data:`PREVIEW_AFTER_SECONDS`)."""
    return last_full is None or last_full[0] != options or last_full[1] > after


def run_engine(engine: Any, hub: Any, jobs: Any, watcher: Any, options: Any, *,
               stop: threading.Event | None = None, log: Callable[[str], None] | None = None,
               preview: bool = True, preview_after: float = PREVIEW_AFTER_SECONDS) -> None:
    """Serve jobs (module docstring) starting with a render of ``options``. ``preview``: show the one-ray preview
    first where :func:`wants_preview` says so (``after=preview_after``); False: never (``--no-preview``)."""
    from a5mi.platform import interrupts

    stop = stop or threading.Event()
    current = options
    changes = 0
    last_full: tuple[Any, float] | None = None  # (options, seconds) of the last full render
    full_key: tuple[Any, ...] | None = None  # (loaded_at, options, version) of the last full frame
    shown: list[Any] = [None]  # the float image published last: a composite's base
    ref_values = ReferenceValues(engine.reference)
    hub.update(scene=engine.scene, controls=describe_controls(options), busy=True,
               reference_float=is_float_image(engine.reference),
               reference=("image" if engine.reference else "binary" if engine.binary else None),
               reference_name=engine.reference or (str(engine.binary.path) if engine.binary else None))
    jobs.render(options, reload=True)
    while not stop.is_set():
        job = jobs.next(WAIT_SECONDS)
        interrupts.check()
        if job is None:
            continue
        kind, arg = job
        if kind == "trace":
            x, y, fut = arg
            if fut.set_running_or_notify_cancel():
                try:
                    fut.set_result(_trace(engine, x, y))
                except Exception as exc:  # noqa: BLE001 - handed to the request, reported on the page
                    fut.set_exception(exc)
            continue
        if kind == "diagnose":
            _diagnose(engine, hub, arg)
            continue
        reload, wanted = arg
        current = wanted or current
        changes += reload
        hub.update(busy=True)
        t0 = time.monotonic()
        state: dict[str, Any] = {"busy": False, "error": None, "changes": changes, "preview": False, "comparing": False,
                                 "saved_at": jobs.taken_reload_at if reload else None}
        images: dict[str, Any] = {}
        try:
            parse = 0.0
            if reload or engine.desc is None:
                before = snapshot(engine.inputs)
                hub.progress("parse", 0, 1)
                try:
                    engine.load(current.bump)
                    watcher.watch(engine.inputs, before)
                except BaseException:
                    watcher.watch(engine.watch_on_error(), before)
                    raise
                parse = time.monotonic() - t0
            region, part = jobs.region, None
            state["region_note"] = None if region is None else why_not(current, region)
            if region is not None and state["region_note"] is None:  # the marked region first, at full quality
                hub.progress("region", 0, 1)
                part, spent = render_region(engine, current, region)
                image, base = paste(shown[0], part, region, saved_size(current))
                comp = engine.frame_of(current, image, composite={
                    "region": list(region), "base": "previous" if base == "base" else "blank", "seconds": spent})
                shown[0] = comp.image
                _publish_early(hub, engine, comp, state, {"parse": parse, "region": spent,
                                                          "total": time.monotonic() - t0})
                if jobs.render_pending():
                    continue
            if (part is not None and not reload and wanted is None and engine.frame is not None
                    and full_key == (engine.loaded_at, current, engine.frame.version)):
                frame = dataclasses.replace(engine.frame, version=engine.new_version())  # marked alone: the
                engine.frame = frame  # whole image is the last one's, unchanged
            else:
                frame, spent = _render_full(engine, hub, jobs, current, state, (parse, t0), (part, region, shown),
                                            preview and wants_preview(last_full, current, preview_after))
                if frame is None:  # a newer save or control: its render replaces this one's full image
                    continue
                last_full = (current, spent)
                shown[0] = frame.image
            full_key = (engine.loaded_at, current, frame.version)
            values = partial(render_values, frame.image)
            images = {"render": frame.render_png, "reference": frame.reference_png, "diff": frame.diff_png,
                      "values-render": values, "values-reference": (
                          None if frame.reference_levels is None else partial(ref_values.blob, frame.reference_levels))}
            state.update(frame_state(engine, frame), warnings=engine.warnings, options_ok=True, comparing=False)
            state["seconds"] = {"parse": parse, **frame.seconds, "total": time.monotonic() - t0}
        except Superseded:  # the newer request is the next job
            continue
        except UserError as exc:  # SceneError is a ValueError too: caught below
            state["error"] = error_line(exc)
        except ValueError as exc:
            from a5mi.converters.errors import SceneError

            if not isinstance(exc, SceneError):
                raise
            state["error"] = error_line(exc)
        except Exception as exc:  # noqa: BLE001 - the server goes on; the page shows the one line
            state["error"] = f"a5mi view: internal error: {type(exc).__name__}: {(str(exc).splitlines() or [''])[0]}"
        if state["error"] and log:
            log(state["error"])
        state["version"] = hub.state().get("version", 0) + 1
        state["watching"] = [str(p) for p in watcher.paths]
        state.setdefault("published_at", time.time())
        hub.update(images, **state)


def _render_full(engine: Any, hub: Any, jobs: Any, current: Any, state: dict[str, Any], times: tuple[float, float],
                 marked: tuple[Any, Any, list[Any]], quick_first: bool) -> tuple[Any, float]:
    """``(frame, seconds)``: the whole image of a render job (:func:`run_engine`; ``times``: its parse seconds and
    start) and the full render's seconds. The preview first when ``quick_first`` (``marked``: the region's
    full-quality pixels pasted on it where the sizes agree, and the image shown, set to it), then the full frame,
    published before its comparison when there is a reference, then compared; ``(None, 0)`` when a newer request
    waits after the preview."""
    parse, t0 = times
    part, region, shown_image = marked
    quick = preview_options(current) if quick_first else None
    if quick is not None:
        pv = engine.render(quick, progress=preemptible(hub, jobs), preview=True)
        image, base = (None, "blank") if part is None else paste(pv.image, part, region, saved_size(current))
        if base == "base":
            pv = engine.frame_of(quick, image, preview=True, kernels=pv.kernels, seconds=pv.seconds,
                                 composite={"region": list(region), "base": "preview"})
        shown_image[0] = pv.image
        _publish_early(hub, engine, pv, state, {"parse": parse, **pv.seconds, "total": time.monotonic() - t0},
                       controls=describe_controls(current))
        if jobs.render_pending():
            return None, 0.0
    t_full = time.monotonic()
    frame = engine.render(current, progress=preemptible(hub, jobs), compare=False)
    spent = time.monotonic() - t_full
    if engine.compares:  # the image first; its comparison follows (the page dims the last one meanwhile)
        state["published_at"] = time.time()  # (of the image, also in the comparison's state)
        _publish_early(hub, engine, frame, state, {"parse": parse, **frame.seconds, "total": time.monotonic() - t0},
                       published_at=state["published_at"], comparing=True)
        engine.compare(frame, hub.progress)
    return frame, spent


def _publish_early(hub: Any, engine: Any, frame: Any, state: dict[str, Any], seconds: dict[str, float],
                   **extra: Any) -> None:
    """Publish ``frame``'s image while its job goes on (the marked region's composite, the preview, the whole
    image before its comparison): the job's ``state`` with the frame's, but for the comparison's fields
    (:data:`COMPARED`: the last comparison stays until this one is made), busy, a new version; ``extra`` last."""
    shown = {k: v for k, v in frame_state(engine, frame).items() if k not in COMPARED}
    hub.update({"render": frame.render_png, "values-render": partial(render_values, frame.image)}, **{
        **state, **shown, "busy": True, "warnings": engine.warnings, "options_ok": True,
        "version": hub.state().get("version", 0) + 1, "published_at": time.time(), **extra, "seconds": seconds})


def _diagnose(engine: Any, hub: Any, image: str) -> None:
    """Run the diagnosis of the current frame's ``image`` and publish it as ``diagnosis``: ``status`` ``running``,
    then ``done`` (the diagnosis, :func:`a5mi.view.pixels.diagnose_frame`, and the ``frame`` it is of) or
    ``error`` (its one line); each stage of the diagnosis is a ``progress`` event ``diagnose: STAGE``."""
    hub.update(diagnosis={"status": "running", "image": image})
    frame = engine.frame.version if engine.frame is not None else None
    try:
        doc = diagnose_frame(engine, image, lambda text: hub.progress(f"diagnose: {text}", 0, 1))
        hub.update(diagnosis={"status": "done", "frame": frame, **doc})
    except UserError as exc:
        hub.update(diagnosis={"status": "error", "image": image, "error": error_line(exc)})
    except Exception as exc:  # noqa: BLE001 - the server goes on; the page shows the one line
        hub.update(diagnosis={"status": "error", "image": image, "error": f"a5mi view: internal error: "
                              f"{type(exc).__name__}: {(str(exc).splitlines() or [''])[0]}"})


def _trace(engine: Any, x: int, y: int) -> dict[str, Any]:
    """The trace of the image pixel ``(x, y)``: mapped to the pixel grid ``a5mi trace`` addresses (``-jitter``
    alone saves the 3W x 3H buffer: its pixel ``(x, y)`` belongs to grid pixel ``(x // 3, y // 3)``)."""
    from a5mi.trace.core import TraceError, pixel_grid

    frame = engine.frame
    if frame is None:
        raise UserError("nothing rendered yet")
    w, h = frame.size
    if not (0 <= x < w and 0 <= y < h):
        raise TraceError(f"pixel ({x}, {y}) is outside the {w}x{h} image")
    gw, gh = pixel_grid(frame.options)
    doc = engine.trace(x * gw // w, y * gh // h)
    doc["clicked"] = [x, y]
    return doc


__all__ = ["COMPARED", "PREVIEW_AFTER_SECONDS", "WAIT_SECONDS", "error_line", "frame_state", "run_engine",
           "wants_preview"]

"""Why a case lost points, in one line (``docs/GRADING.md`` "Causes").

:func:`cause_of` is the one place a record's cause is made; the card of ``report.html``, ``results.csv``,
``results.json``, the feedback files and Gradescope's ``results.json`` all show what it returns.

* ``match``: no cause (empty);
* ``wrong`` / ``close`` with the student's image, first the mistake of docs/MISTAKES.md that explains it
  (:func:`diagnosed`: ``a5mi diagnose`` on the image, verdict ``diagnosis``), e.g. ``mistake: no_shadows (SPEC
  B.3 S: S = 1 always, even with -shadows), explains 99.9 % of the difference (a5mi diagnose)``; only a Whitted
  render of at most :data:`DIAGNOSED_PIXELS` pixels is diagnosed (its cost: BENCHMARKS.md "Diagnosis", about 11 CPU
  seconds at 300x300, small renders first and a handful at full size);
* ``wrong`` / ``close`` that no catalogued mistake explains: the term of a5mi's ray tree (SPEC B.3, ``a5mi trace
  --diff``) that best accounts for the pixels furthest beyond the noise band (:func:`trace_culprit`): each of
  the :data:`WORST` worst pixels is traced, its terms ranked by :func:`a5mi.trace.report.explain` (the
  residual ``|student - clamp(reference + sign · term)|``), and the kind of term that is first at most pixels
  is named with its first pixel's label, e.g. ``the student lacks: all 15 shadow terms together, ... (4 of 5
  worst pixels)``;
* ``crash`` / ``no output`` of a program that needs files the sandbox does not show (the record's ``needs``,
  :func:`a5mi.grade.needs.missing_paths`): the ``--allow-read`` line that lets it start;
* ``wrong size``, ``unreadable``, ``no output``, ``timeout``, ``over memory``, ``over disk``, ``crash``: the
  record's detail, with the last line of stderr for a crash or a missing output.
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

from a5mi.grade.needs import allow_hint

#: Pixels traced to name a wrong image's cause (the worst beyond the noise band).
WORST = 5
#: Largest image (pixels) a cause is diagnosed for: the handout's 300x300 (a larger one is traced only).
DIAGNOSED_PIXELS = 300 * 300


def worst_pixels(student: np.ndarray, reference: np.ndarray, sigma: np.ndarray | None,
                 count: int = WORST) -> list[tuple[int, int]]:
    """``(x, y)`` (top-left) of the ``count`` pixels furthest beyond the noise band, ``max_c(|s - r| - (4
    sigma + 1))`` (``docs/GRADING.md`` "The verdict rule"), worst first; only pixels beyond it."""
    band = 4.0 * (sigma if sigma is not None else 0.0) + 1.0
    excess = (np.abs(student - reference) - band).max(axis=-1)
    order = np.argsort(-excess, axis=None, kind="stable")[:count]
    w = excess.shape[1]
    return [(int(k % w), int(k // w)) for k in order if excess.flat[k] > 0]


def trace_culprit(scene: str | Path, options: Any, student: np.ndarray, reference: np.ndarray,
                  sigma: np.ndarray | None) -> str:
    """The ray-tree term that best explains the worst pixels (module docstring), or why none was found.
    Needs a Whitted render (``options.integrator`` whitted) and the image at the reference's size."""
    from a5mi.render.session import RenderSession, describe_file
    from a5mi.trace import report
    from a5mi.trace.core import Tracer

    if getattr(options, "integrator", "whitted") not in (None, "whitted"):
        return ""
    pixels = worst_pixels(student, reference, sigma)
    if not pixels:
        return ""
    RenderSession(None, max_scenes=1)  # activates the variant and registers the plugins
    desc, _ = describe_file(str(scene))
    tracer = Tracer(desc, options)
    firsts: list[tuple[str, str]] = []
    for pt in tracer.pixels(pixels):
        ranked = report.explain(pt, student[pt.y, pt.x] / 255.0)
        if ranked:
            best = ranked[0][0]
            firsts.append((best.kind, f"{'the student adds' if best.sign > 0 else 'the student lacks'}: "
                                      f"{best.label}"))
    if not firsts:
        return f"no single term of the ray tree explains the {len(pixels)} worst pixels"
    kind, n = Counter(k for k, _ in firsts).most_common(1)[0]
    label = next(text for k, text in firsts if k == kind)
    return f"{label} ({n} of {len(pixels)} worst pixels)"


def diagnosed(scene: str | Path, options: Any, student: np.ndarray) -> str:
    """The docs/MISTAKES.md mistake(s) that explain ``student`` (levels 0..255, the reference's size), as one
    line (module docstring), or ``""`` when ``a5mi diagnose`` finds none (verdict ``match`` or ``unexplained``), the
    render is not Whitted's or the image has more than :data:`DIAGNOSED_PIXELS` pixels."""
    from a5mi.diagnose.rank import diagnose
    from a5mi.render.session import RenderSession, describe_file

    if options is None or getattr(options, "integrator", "whitted") not in (None, "whitted"):
        return ""
    if student.shape[0] * student.shape[1] > DIAGNOSED_PIXELS:
        return ""
    session = RenderSession(None, max_scenes=1)
    desc, _ = describe_file(str(scene))
    levels = np.clip(np.rint(np.asarray(student, dtype=np.float64)[..., :3]), 0, 255).astype(np.uint8)
    best = diagnose(levels, desc, options, session=session).best
    if best is None:
        return ""
    changes = "; ".join(f"SPEC {m.section}: {m.change}" for m in best.catalogue)
    return (f"mistake: {' + '.join(best.mistakes)} ({changes}), explains {100.0 * (best.explained or 0.0):.1f} % "
            f"of the difference (a5mi diagnose)")


def cause_of(record: dict[str, Any], *, scene: str | Path | None = None, options: Any = None,
             student: np.ndarray | None = None, reference: np.ndarray | None = None,
             sigma: np.ndarray | None = None) -> str:
    """One line saying why ``record`` (a grade record: ``verdict``, ``detail``, ``stderr_tail``) lost points
    (module docstring); ``""`` for a match. ``scene``, ``options`` and the images (levels) let a ``wrong`` /
    ``close`` image be diagnosed, else traced; a failure of the diagnosis falls back to the trace, a failure of
    the tracer is said in the line, never raised."""
    verdict = record.get("verdict", "error")
    detail = str(record.get("detail", ""))
    if verdict == "match":
        return ""
    if verdict in ("wrong", "close"):
        if scene is not None and student is not None and reference is not None:
            try:
                found = diagnosed(scene, options, student)
            except Exception:  # noqa: BLE001 - a cause is advice: a diagnosis failure falls back to the trace
                found = ""
            if found:
                return found
            try:
                found = trace_culprit(scene, options, student, reference, sigma)
            except Exception as exc:  # noqa: BLE001 - a cause is advice: a tracer failure must not lose the grade
                found = f"the ray-tree diagnosis failed ({type(exc).__name__}: {str(exc)[:120]})"
            if found:
                return found
        return "differs from the reference beyond the noise band: " + detail
    lines = [ln.strip() for ln in str(record.get("stderr_tail", "")).splitlines() if ln.strip()]
    if verdict in ("crash", "no output") and record.get("needs"):
        return f"{detail}: cannot start in the sandbox: {allow_hint(record['needs'])}"
    if verdict in ("crash", "no output") and lines:
        return f"{detail}: {lines[-1][:200]}"
    if verdict == "error":
        return f"grader error: {record.get('error', detail)}"
    return detail


__all__ = ["DIAGNOSED_PIXELS", "WORST", "cause_of", "diagnosed", "trace_culprit", "worst_pixels"]

"""Feedback where students read it: one plain-text and one Markdown file per student, and Gradescope's
``results.json`` (``docs/GRADING.md`` "Feedback files").

* ``feedback/STUDENT.txt`` and ``feedback/STUDENT.md`` (a safe file name, :func:`file_stem`): the total,
  then per case its verdict, points, the one-line cause (:func:`a5mi.grade.cause.cause_of`), the metrics
  once, and the commands that reproduce it (the case's a5 command line, run from the scenes folder; ``a5mi
  compare`` against the reference; for a wrong image ``a5mi trace --diff``); a failure shared by every case
  is said once at the top (:func:`same_failure`).
* ``gradescope/STUDENT/results.json``: the Gradescope autograder results format (Gradescope's "Autograder
  Specifications", "Output format"): top-level ``score`` (the sum of the tests' scores), ``output`` and
  ``tests``, one per case with ``name``, ``score``, ``max_score``, ``status`` (``passed`` for a match, else
  ``failed``), ``output`` (the same text as the feedback file's case) and ``visibility`` (``visible``).
"""

from __future__ import annotations

import re
import shlex
from collections.abc import Sequence
from typing import Any

from a5mi.grade.cases import Case

#: Gradescope's test visibility values and test statuses (Autograder Specifications, "Output format").
VISIBILITIES = ("hidden", "after_due_date", "after_published", "visible")
STATUSES = ("passed", "failed")


def file_stem(student: str) -> str:
    """A file name for ``student``: the name itself when it is only letters, digits, ``.``, ``_``, ``-`` (not
    starting with ``.``), else those characters with ``_`` for the others and 8 hex digits of its SHA-256."""
    import hashlib

    if re.fullmatch(r"[A-Za-z0-9_-][A-Za-z0-9._-]*", student):
        return student
    return re.sub(r"[^A-Za-z0-9._-]", "_", student).lstrip(".")[:64] + "-" + \
        hashlib.sha256(student.encode()).hexdigest()[:8]


def same_failure(records: Sequence[dict[str, Any]]) -> str:
    """``"every case: VERDICT: CAUSE"`` when a student's cases (two or more) all failed with one verdict and
    one cause (a wrapper that cannot start, a missing library); ``""`` otherwise."""
    if len(records) < 2:
        return ""
    keys = {(r.get("verdict", "error"), r.get("cause", "")) for r in records}
    if len(keys) != 1:
        return ""
    verdict, cause = next(iter(keys))
    if verdict in ("match", "close", "wrong"):
        return ""
    return f"every case: {verdict}: {cause}" if cause else f"every case: {verdict}"


def _metrics(rec: dict[str, Any]) -> str:
    m = rec.get("metrics") or {}
    if not m:
        return ""
    psnr = "inf" if m.get("psnr") in (None, "inf") else f"{float(m['psnr']):.1f}"
    flip = "" if m.get("flip") is None else f", FLIP {m['flip']:.4f}"
    return (f"{100 * m['beyond_noise']:.2f}% of pixels beyond noise, PSNR {psnr} dB, mean {m['mean_error']:.3f}/255, "
            f"{100 * m['share_over_2']:.2f}% > 2/255{flip}")


def _commands(case: Case, rec: dict[str, Any]) -> list[str]:
    """How to reproduce a case: the a5 command (from the scenes folder), the comparison, the ray-tree diff."""
    out = [f"./a5 {case.command}"]
    ref = f"reference/{case.name}.png"
    if rec.get("verdict") not in ("match", None) and rec.get("images", {}).get("submission"):
        out.append(f"a5mi compare {ref} {shlex.quote(case.output)} --flip")
        if rec.get("verdict") in ("wrong", "close"):
            flags = [a for a in case.argv]
            at = flags.index("-output")
            del flags[at:at + 2]
            out.append(f"a5mi trace --diff {shlex.quote(case.output)} {shlex.join(flags)}")
    return out


def case_text(case: Case, rec: dict[str, Any]) -> list[str]:
    """The lines of one case (verdict line, cause, metrics, commands) shared by every feedback format."""
    lines = [f"{case.name}: {rec.get('verdict', 'error')} ({float(rec.get('points', 0)):g} / {case.points:g})"]
    if rec.get("cause"):
        lines.append(f"  cause: {rec['cause']}")
    if _metrics(rec):
        lines.append(f"  metrics: {_metrics(rec)}")
    elif rec.get("detail") and rec.get("detail") != rec.get("cause"):
        lines.append(f"  detail: {rec['detail']}")
    lines += [f"  $ {c}" for c in _commands(case, rec)]
    return lines


def _records(student: str, cases: Sequence[Case], records: Sequence[dict[str, Any]]) -> list[tuple[Case, dict]]:
    by = {(r.get("student"), r.get("case")): r for r in records}
    return [(c, by.get((student, c.name), {"verdict": "error", "points": 0.0, "cause": "not graded"}))
            for c in cases]


def feedback_text(student: str, cases: Sequence[Case], records: Sequence[dict[str, Any]]) -> str:
    """The plain-text feedback of one student (module docstring)."""
    pairs = _records(student, cases, records)
    got, total = sum(float(r.get("points", 0)) for _, r in pairs), sum(c.points for c, _ in pairs)
    lines = [f"Assignment 5: {student}: {got:g} / {total:g}"]
    common = same_failure([r for _, r in pairs])
    if common:
        lines.append(common)
    lines.append("(commands run from the scenes folder; reference/ holds the reference images)")
    for c, r in pairs:
        lines += ["", *case_text(c, r)]
    return "\n".join(lines) + "\n"


def _md(text: str) -> str:
    return text.replace("|", "\\|").replace("<", "&lt;").replace(">", "&gt;")


def feedback_markdown(student: str, cases: Sequence[Case], records: Sequence[dict[str, Any]]) -> str:
    """The Markdown feedback of one student: a table of cases, then each case's cause and commands."""
    pairs = _records(student, cases, records)
    got, total = sum(float(r.get("points", 0)) for _, r in pairs), sum(c.points for c, _ in pairs)
    out = [f"# Assignment 5: {_md(student)}", "", f"**{got:g} / {total:g}**", ""]
    common = same_failure([r for _, r in pairs])
    if common:
        out += [f"> {_md(common)}", ""]
    out += ["| case | verdict | points | cause |", "| --- | --- | --- | --- |"]
    out += [f"| {_md(c.name)} | {_md(r.get('verdict', 'error'))} | {float(r.get('points', 0)):g} / {c.points:g} | "
            f"{_md(r.get('cause', ''))} |" for c, r in pairs]
    for c, r in pairs:
        out += ["", f"## {_md(c.name)}: {_md(r.get('verdict', 'error'))}", ""]
        if _metrics(r):
            out += [f"Metrics: {_metrics(r)}", ""]
        out += ["Reproduce (from the scenes folder):", "", "```sh", *_commands(c, r), "```"]
    return "\n".join(out) + "\n"


def gradescope_results(student: str, cases: Sequence[Case], records: Sequence[dict[str, Any]],
                       visibility: str = "visible") -> dict[str, Any]:
    """Gradescope's ``results.json`` of one student (module docstring)."""
    pairs = _records(student, cases, records)
    tests = [{"name": c.name, "score": float(r.get("points", 0.0)), "max_score": float(c.points),
              "status": "passed" if r.get("verdict") == "match" else "failed",
              "output": "\n".join(case_text(c, r)), "visibility": visibility} for c, r in pairs]
    common = same_failure([r for _, r in pairs])
    return {"score": sum(t["score"] for t in tests), "output": common or f"{len(tests)} cases graded by a5mi",
            "visibility": visibility, "tests": tests}


__all__ = ["STATUSES", "VISIBILITIES", "case_text", "feedback_markdown", "feedback_text", "file_stem",
           "gradescope_results", "same_failure"]

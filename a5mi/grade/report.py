"""The grading report: ``report.html`` (one offline page), ``results.csv`` and ``results.json``.

The page has no external resource (inline CSS and script; images are relative files under ``img/``): a class
summary table, student x case, with coloured verdicts, points and totals, sortable by clicking a column
header; then one section per student with, per case, reference | submission | FLIP heatmap | |diff| x8, the
one-line cause (:func:`a5mi.grade.cause.cause_of`), the metrics (once) or the verdict's detail, and the tail
of stderr; a failure shared by all of a student's cases is said once above them. The feedback files and
Gradescope's ``results.json`` (:mod:`a5mi.grade.feedback`) are written beside them. Every file is written
atomically.

PSNR of an image identical to its reference is infinite: it is written ``inf`` in the CSV and the string
``"inf"`` in the JSON (``float()`` reads both), never left empty or ``null``: an empty CSV cell and a JSON
``"metrics": null`` mean that no image was measured (``no output``, ``crash``, ...).
"""

from __future__ import annotations

import csv
import html
import io
import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from a5mi.grade.cases import Case
from a5mi.grade.cause import cause_of
from a5mi.grade.feedback import feedback_markdown, feedback_text, file_stem, gradescope_results, same_failure
from a5mi.platform.imageio import atomic_file

COLOURS = {"match": "#2e7d32", "close": "#9e9d24", "wrong": "#c62828", "wrong size": "#ad1457",
           "no output": "#616161", "unreadable": "#6d4c41", "crash": "#4a148c", "timeout": "#e65100",
           "over memory": "#1565c0", "over disk": "#00695c", "error": "#000000"}
CSV_FIELDS = ("student", "case", "verdict", "points", "max_points", "beyond_noise", "psnr", "mean_error",
              "share_over_2", "flip", "detail", "wall", "isolation", "cause")

_CSS = """body{font-family:sans-serif;margin:1.5em;color:#222}table{border-collapse:collapse}
td,th{border:1px solid #ccc;padding:3px 8px;text-align:center}th{background:#eee;cursor:pointer}
th.sorted-asc:after{content:" \\25B2"}th.sorted-desc:after{content:" \\25BC"}
.v{color:#fff;font-weight:bold;border-radius:3px;padding:1px 6px;white-space:nowrap}
.case{display:inline-block;vertical-align:top;margin:0 1.5em 1.5em 0}
.case img{width:150px;height:150px;object-fit:contain;image-rendering:pixelated;border:1px solid #999;
background:#333}.imgs{display:flex;gap:4px}.imgs figure{margin:0;font-size:11px;text-align:center}
pre{background:#f6f6f6;max-width:640px;max-height:10em;overflow:auto;font-size:11px;text-align:left}"""

_JS = """document.querySelectorAll('table.sortable th').forEach(function(th, col){
 th.addEventListener('click', function(){
  var table = th.closest('table'), body = table.tBodies[0], rows = Array.from(body.rows);
  var asc = !th.classList.contains('sorted-asc');
  table.querySelectorAll('th').forEach(function(h){h.classList.remove('sorted-asc','sorted-desc');});
  th.classList.add(asc ? 'sorted-asc' : 'sorted-desc');
  rows.sort(function(a, b){
   var x = a.cells[col].dataset.sort, y = b.cells[col].dataset.sort;
   var nx = parseFloat(x), ny = parseFloat(y);
   var c = (!isNaN(nx) && !isNaN(ny)) ? nx - ny : x.localeCompare(y);
   return asc ? c : -c;});
  rows.forEach(function(r){body.appendChild(r);});});});"""


def _verdict(rec: dict[str, Any]) -> str:
    return rec.get("verdict", "error")


def totals(records: Sequence[dict[str, Any]], students: Sequence[str]) -> dict[str, tuple[float, float]]:
    """student -> (points, max points)."""
    out = {s: (0.0, 0.0) for s in students}
    for r in records:
        p, m = out.get(r.get("student", ""), (0.0, 0.0))
        out[r.get("student", "")] = (p + float(r.get("points", 0.0)), m + float(r.get("max_points", 0.0)))
    return out


def _split_key(rec: dict[str, Any]) -> dict[str, Any]:
    if "student" not in rec:
        student, _, case = rec["key"].partition("/")
        rec = {**rec, "student": student, "case": case, "verdict": "error", "points": 0.0, "max_points": 0.0,
               "detail": rec.get("error", "grader error")}
    if "cause" not in rec:  # a grader error, or a record journaled before causes existed
        rec = {**rec, "cause": cause_of(rec)}
    return _inf_psnr(rec)


def _inf_psnr(rec: dict[str, Any]) -> dict[str, Any]:
    """``rec`` with an identical image's PSNR (``None`` or ``inf`` in measured metrics) as ``"inf"`` (module
    docstring)."""
    m = rec.get("metrics")
    if m and (m.get("psnr") is None or (isinstance(m["psnr"], float) and math.isinf(m["psnr"]))):
        rec = {**rec, "metrics": {**m, "psnr": "inf"}}
    return rec


def _psnr_text(psnr: Any) -> str:
    return "inf" if psnr is None or psnr == "inf" else format(float(psnr), ".1f")


def csv_text(records: Sequence[dict[str, Any]]) -> str:
    buf = io.StringIO()
    w = csv.DictWriter(buf, CSV_FIELDS, extrasaction="ignore", lineterminator="\n")
    w.writeheader()
    for r in records:
        r = _inf_psnr(r)
        row = {**r, **(r.get("metrics") or {})}
        w.writerow({k: ("" if row.get(k) is None else row.get(k)) for k in CSV_FIELDS})
    return buf.getvalue()


def _fmt(x: Any, spec: str) -> str:
    return "-" if x is None else format(x, spec)


def html_page(cases: Sequence[Case], students: Sequence[str], records: Sequence[dict[str, Any]],
              meta: dict[str, Any]) -> str:
    """The report page (module docstring)."""
    e = html.escape
    by = {(r["student"], r["case"]): r for r in records}
    tot = totals(records, students)
    head = "".join(f"<th>{e(c.name)}</th>" for c in cases)
    rows = []
    for s in students:
        cells = [f'<td data-sort="{e(s)}"><a href="#s-{e(s)}">{e(s)}</a></td>']
        for c in cases:
            r = by.get((s, c.name))
            v = "missing" if r is None else _verdict(r)
            rank = 99 if r is None else float(r.get("points", 0.0))
            pts = "" if r is None else f" {float(r.get('points', 0)):g}"
            cells.append(f'<td data-sort="{rank}" class="cell"><span class="v" style="background:'
                         f'{COLOURS.get(v, "#000")}">{e(v)}</span>{pts}</td>')
        p, m = tot[s]
        cells.append(f'<td data-sort="{p}">{p:g} / {m:g}</td>')
        rows.append(f'<tr data-student="{e(s)}">' + "".join(cells) + "</tr>")
    sections = []
    for s in students:
        blocks = []
        for c in cases:
            r = by.get((s, c.name))
            if r is None:
                continue
            imgs = [("reference", f"img/ref/{c.name}.png")]
            imgs += [(label, r["images"][k]) for k, label in (("submission", "submission"), ("flip", "FLIP"),
                                                              ("diff", "|diff| x8")) if k in r.get("images", {})]
            figs = "".join(f'<figure><img src="{e(src)}" alt="{e(label)}"><figcaption>{e(label)}</figcaption>'
                           f"</figure>" for label, src in imgs)
            m = r.get("metrics") or {}
            metrics = ("" if not m else
                       f"<br>beyond noise {100 * m['beyond_noise']:.2f}%, PSNR {_psnr_text(m['psnr'])} dB, mean "
                       f"{m['mean_error']:.3f}/255, &gt; 2/255 {100 * m['share_over_2']:.2f}%, FLIP "
                       f"{_fmt(m.get('flip'), '.4f')}")
            stderr = r.get("stderr_tail") or ""
            v = _verdict(r)
            cause = r.get("cause") or ""
            said = metrics[4:] if metrics else e(str(r.get("detail", "")))  # the metrics once, else the detail
            blocks.append(f'<div class="case" data-case="{e(c.name)}"><b>{e(c.name)}</b> <span class="v" '
                          f'style="background:{COLOURS.get(v, "#000")}">{e(v)}</span> '
                          f'{float(r.get("points", 0)):g}/{c.points:g}<div class="imgs">{figs}</div>'
                          + (f'<p class="cause"><b>cause:</b> {e(cause)}</p>' if cause else "")
                          + f'<small>{said}</small>'
                          + (f"<pre>{e(stderr[-2000:])}</pre>" if stderr else "") + "</div>")
        p, mx = tot[s]
        common = same_failure([by[s, c.name] for c in cases if (s, c.name) in by])
        note = f'<p class="common"><b>{e(common)}</b></p>' if common else ""
        sections.append(f'<section id="s-{e(s)}"><h3>{e(s)} &mdash; {p:g} / {mx:g}</h3>{note}{"".join(blocks)}'
                        f'</section>')
    n_match = sum(1 for r in records if _verdict(r) == "match")
    legend = " ".join(f'<span class="v" style="background:{col}">{e(v)}</span>' for v, col in COLOURS.items())
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>a5mi grade report</title><style>{_CSS}</style></head>
<body><h1>Assignment 5 grades</h1>
<p>{len(students)} students, {len(cases)} cases, {n_match} of {len(records)} cases match. Sandbox:
{e(str(meta.get("isolation", "")))}. Cases: {"; ".join(f"<code>{e(c.name)}</code>: <code>{e(c.command)}</code>"
                                                 f" ({c.points:g} pts)" for c in cases)}.</p>
<p>{legend}</p>
<table class="sortable" id="summary"><thead><tr><th>student</th>{head}<th>total</th></tr></thead>
<tbody>{"".join(rows)}</tbody></table>
{"".join(sections)}
<script>{_JS}</script></body></html>
"""


def write_all(report_dir: str | Path, cases: Sequence[Case], students: Sequence[str],
              records: Sequence[dict[str, Any]], meta: dict[str, Any]) -> dict[str, str]:
    """Write ``report.html``, ``results.csv``, ``results.json``, ``feedback/STUDENT.{txt,md}`` and
    ``gradescope/STUDENT/results.json``; returns their paths by kind."""
    d = Path(report_dir)
    recs = [_split_key(r) for r in records]
    tot = totals(recs, students)
    doc = {"cases": [{"name": c.name, "command": c.command, "points": c.points} for c in cases],
           "students": {s: {"points": p, "max_points": m} for s, (p, m) in tot.items()},
           "results": recs, **meta}
    files = {"html": d / "report.html", "csv": d / "results.csv", "json": d / "results.json"}
    with atomic_file(files["html"], "w") as f:
        f.write(html_page(cases, students, recs, meta))
    with atomic_file(files["csv"], "w") as f:
        f.write(csv_text(recs))
    with atomic_file(files["json"], "w") as f:
        f.write(json.dumps(doc, indent=1, default=lambda x: None if isinstance(x, float) and math.isinf(x)
                           else str(x)) + "\n")
    (d / "feedback").mkdir(exist_ok=True)
    for s in students:
        stem = file_stem(s)
        (d / "gradescope" / stem).mkdir(parents=True, exist_ok=True)
        for suffix, text in ((".txt", feedback_text(s, cases, recs)), (".md", feedback_markdown(s, cases, recs))):
            with atomic_file(d / "feedback" / f"{stem}{suffix}", "w") as f:
                f.write(text)
        with atomic_file(d / "gradescope" / stem / "results.json", "w") as f:
            f.write(json.dumps(gradescope_results(s, cases, recs), indent=1) + "\n")
    files["feedback"] = d / "feedback"
    files["gradescope"] = d / "gradescope"
    return {k: str(v) for k, v in files.items()}


__all__ = ["COLOURS", "CSV_FIELDS", "csv_text", "html_page", "totals", "write_all"]

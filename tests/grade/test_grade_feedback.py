"""Every lost point says why (docs/GRADING.md "Causes", "Feedback files", "What a program needs to start").

* a wrong image gets the mistake ``a5mi diagnose`` names (a render without ``-shadows`` on a scene with shadows:
  ``no_shadows``; tests/grade/test_cause.py: the ray-tree culprit when none explains it), once in the card, CSV,
  JSON, the feedback files and Gradescope's results.json; the card prints the metrics once;
* a pyenv-style wrapper (``exec VENV/bin/a5``, whose interpreter lives outside ``/usr``) cannot start in the
  sandbox: every case gets the one ``--allow-read`` line that lets it start, said once for the student, and
  with those paths allowed it matches;
* Gradescope's ``results.json`` is checked against the format of Gradescope's documentation ("Autograder
  Specifications", "Output format"), written out below as :func:`gradescope_problems`.
"""

from __future__ import annotations

import base64
import csv
import dataclasses
import json
import os
import shutil
from pathlib import Path
from typing import Any

import pytest

from a5mi.grade.cases import load_cases
from a5mi.grade.feedback import STATUSES, VISIBILITIES, same_failure
from a5mi.grade.references import build_reference, render_levels
from a5mi.grade.report import write_all
from a5mi.grade.run import Task, grade_one
from a5mi.platform.imageio import write_image

pytestmark = pytest.mark.unit  # the fast tier (`make check`): no Mitsuba, no child process

SIZE = 24
CASES = f"""
[[case]]
name = "cube"
command = "-input scene11_cube.txt -size {SIZE} {SIZE} -output cube.png -shadows -bounces 2"
points = 60

[[case]]
name = "sphere"
command = "-input scene10_sphere.txt -size {SIZE} {SIZE} -output sphere.png -shadows -bounces 2"
points = 40
"""


def gradescope_problems(doc: Any) -> list[str]:
    """What in ``doc`` breaks Gradescope's results.json format (its documentation, "Output format"): an object
    with ``score`` (a number; required unless every test has one) and optional ``execution_time`` (number),
    ``output`` (string), ``visibility`` and ``stdout_visibility`` (one of hidden, after_due_date,
    after_published, visible), ``extra_data`` (object) and ``tests``: a list of objects with optional ``score``,
    ``max_score`` (numbers), ``status`` (passed / failed), ``name``, ``number``, ``output`` (strings),
    ``output_format`` / ``name_format`` (text, html, simple_format, md, ansi), ``tags`` (list of strings),
    ``visibility``, ``extra_data``. Here every test must also have ``name``, ``score``, ``max_score``, ``output``
    and ``visibility``, and the top-level ``score`` must be the sum of the tests' scores."""
    bad: list[str] = []
    known = {"score", "execution_time", "output", "output_format", "test_output_format", "test_name_format",
             "visibility", "stdout_visibility", "extra_data", "tests", "leaderboard"}
    test_known = {"score", "max_score", "status", "name", "name_format", "number", "output", "output_format",
                  "tags", "visibility", "extra_data"}
    formats = ("text", "html", "simple_format", "md", "ansi")
    number = (int, float)
    if not isinstance(doc, dict):
        return ["not an object"]
    bad += [f"unknown top-level key {k}" for k in doc if k not in known]
    for k in ("score", "execution_time"):
        if k in doc and (not isinstance(doc[k], number) or isinstance(doc[k], bool)):
            bad.append(f"{k} is not a number")
    for k in ("visibility", "stdout_visibility"):
        if k in doc and doc[k] not in VISIBILITIES:
            bad.append(f"{k} {doc[k]!r}")
    if "output" in doc and not isinstance(doc["output"], str):
        bad.append("output is not a string")
    tests = doc.get("tests")
    if not isinstance(tests, list) or not tests:
        return [*bad, "no tests list"]
    for i, t in enumerate(tests):
        if not isinstance(t, dict):
            bad.append(f"test {i} is not an object")
            continue
        bad += [f"test {i}: unknown key {k}" for k in t if k not in test_known]
        for k in ("name", "score", "max_score", "output", "visibility"):
            if k not in t:
                bad.append(f"test {i}: no {k}")
        for k in ("score", "max_score"):
            if k in t and (not isinstance(t[k], number) or isinstance(t[k], bool)):
                bad.append(f"test {i}: {k} is not a number")
        for k in ("name", "output", "number"):
            if k in t and not isinstance(t[k], str):
                bad.append(f"test {i}: {k} is not a string")
        if t.get("visibility", "visible") not in VISIBILITIES:
            bad.append(f"test {i}: visibility {t['visibility']!r}")
        if t.get("status", "passed") not in STATUSES:
            bad.append(f"test {i}: status {t['status']!r}")
        for k in ("output_format", "name_format"):
            if t.get(k, "text") not in formats:
                bad.append(f"test {i}: {k} {t[k]!r}")
        if "score" in t and "max_score" in t and isinstance(t["score"], number) and t["score"] > t["max_score"]:
            bad.append(f"test {i}: score above max_score")
    if "score" not in doc and not all("score" in t for t in tests if isinstance(t, dict)):
        bad.append("no score, and not every test has one")
    scores = [t.get("score", 0) for t in tests if isinstance(t, dict)]
    if isinstance(doc.get("score"), number) and all(isinstance(x, number) for x in scores) and \
            abs(doc["score"] - sum(scores)) > 1e-9:
        bad.append("score is not the sum of the tests' scores")
    return bad


def test_the_schema_check_rejects_what_gradescope_would() -> None:
    good = {"score": 1.0, "tests": [{"name": "a", "score": 1.0, "max_score": 1.0, "output": "", "visibility":
                                     "visible"}]}
    assert gradescope_problems(good) == []
    assert gradescope_problems({**good, "score": "1"}) == ["score is not a number"]
    broken = {"score": 2.0, "tests": [{"name": "a", "score": 1.0, "max_score": 1.0, "output": "",
                                       "visibility": "public", "status": "ok"}]}
    assert gradescope_problems(broken) == ["test 0: visibility 'public'", "test 0: status 'ok'",
                                           "score is not the sum of the tests' scores"]


@pytest.fixture(scope="module")
def world(tmp_path_factory, scenes_dir):
    """Cases and references (rendered by a5mi at SIZE), a 'noshadows' image submission, a pyenv-style wrapper
    student whose interpreter is a copy of /bin/dash outside /usr, and a correct image for it to write."""
    from a5mi.commands.grade import _options_of

    root = tmp_path_factory.mktemp("fb")
    for d in ("subs", "work", "report", "pyenv/versions/3.11.7/bin", "venv/bin"):
        (root / d).mkdir(parents=True)
    (root / "cases.toml").write_text(CASES)
    cases = load_cases(root / "cases.toml", _options_of)
    refs = {}
    cwd = os.getcwd()
    for case in cases:
        refs[case.name] = build_reference(scenes_dir / case.scene, case.options, root / "cache")
        os.chdir(scenes_dir)
        try:
            lacking = render_levels(scenes_dir / case.scene, dataclasses.replace(case.options, shadows=False))
        finally:
            os.chdir(cwd)
        (root / "subs" / "noshadows").mkdir(exist_ok=True)
        write_image(root / "subs" / "noshadows" / case.output, (lacking + 0.5) / 255)
    interp = root / "pyenv" / "versions" / "3.11.7" / "bin" / "sh"
    shutil.copy2("/usr/bin/dash", interp)
    good = {c.name: base64.b64encode(Path(refs[c.name].image_path).read_bytes()).decode() for c in cases}
    venv_a5 = root / "venv" / "bin" / "a5"
    venv_a5.write_text(f"#!{interp}\nout=x\nwhile [ $# -gt 0 ]; do [ \"$1\" = -output ] && out=\"$2\"; shift; done\n"
                       f"case \"$out\" in cube.png) d={good['cube']};; *) d={good['sphere']};; esac\n"
                       "echo \"$d\" | base64 -d > \"$out\"\n")
    (root / "subs" / "pyenvwrap").mkdir()
    (root / "subs" / "pyenvwrap" / "a5").write_text(f"#!/bin/sh\nexec {venv_a5} \"$@\"\n")
    for p in (venv_a5, root / "subs" / "pyenvwrap" / "a5"):
        p.chmod(0o755)
    for p in [root, *root.rglob("*")]:
        if p.is_dir():
            p.chmod(0o755)
    return {"root": root, "cases": cases, "refs": refs, "scenes": scenes_dir,
            "prefixes": (str(root / "pyenv" / "versions" / "3.11.7"), str(root / "venv"))}


def _tasks(world: dict, student: str, read_only: tuple[str, ...] = ()) -> list[Task]:
    root = world["root"]
    return [Task(student, str(root / "subs" / student), c, str(world["scenes"]), world["refs"][c.name].image_path,
                 world["refs"][c.name].sigma_path, str(root / "work"), str(root / "report"), read_only=read_only,
                 flip=False) for c in world["cases"]]


def test_a_wrong_image_names_its_cause_once_everywhere(world) -> None:
    recs = [grade_one(t) for t in _tasks(world, "noshadows")]
    assert [r["verdict"] for r in recs] == ["wrong", "wrong"], recs
    for r in recs:
        assert r["cause"].startswith("mistake: no_shadows (SPEC B.3 S"), r   # a5mi diagnose names the mistake
    report = world["root"] / "report"
    files = write_all(report, world["cases"], ["noshadows"], recs, {"isolation": "bwrap"})
    page = Path(files["html"]).read_text()
    cards = page.split('<div class="case"')[1:]
    assert len(cards) == 2
    for card, r in zip(cards, recs, strict=True):
        assert card.count("beyond noise") == 1 and "cause:" in card  # the metrics once per card
        assert r["cause"].split(":")[0] in card
    rows = list(csv.DictReader(open(files["csv"])))
    assert [row["cause"] for row in rows] == [r["cause"] for r in recs]
    assert [r["cause"] for r in json.loads(Path(files["json"]).read_text())["results"]] == [r["cause"] for r in recs]
    text = (report / "feedback" / "noshadows.txt").read_text()
    md = (report / "feedback" / "noshadows.md").read_text()
    for r in recs:
        assert r["cause"] in text and r["cause"].replace("|", "\\|") in md
    assert "a5mi trace --diff cube.png -input scene11_cube.txt" in text and "./a5 -input scene11_cube.txt" in md
    gs = json.loads((report / "gradescope" / "noshadows" / "results.json").read_text())
    assert gradescope_problems(gs) == []
    assert [(t["name"], t["score"], t["max_score"]) for t in gs["tests"]] == [("cube", 0.0, 60.0),
                                                                               ("sphere", 0.0, 40.0)]
    assert all(r["cause"] in t["output"] for r, t in zip(recs, gs["tests"], strict=True))


def test_a_wrapper_whose_interpreter_is_outside_the_sandbox_is_named_once(world) -> None:
    recs = [grade_one(t) for t in _tasks(world, "pyenvwrap")]
    assert [r["verdict"] for r in recs] == ["crash", "crash"], recs
    pyenv, venv = world["prefixes"]
    line = f"add --allow-read {':'.join(sorted([pyenv, venv]))}"
    for r in recs:
        assert "exit status 127" in r["detail"] and line in r["cause"], r
    common = same_failure(recs)
    assert common.startswith("every case: crash: exit status 127") and line in common
    (world["root"] / "report2").mkdir()
    files = write_all(world["root"] / "report2", world["cases"], ["pyenvwrap"], recs, {"isolation": "bwrap"})
    page = Path(files["html"]).read_text()
    assert page.count("every case: crash") == 1
    assert (world["root"] / "report2" / "feedback" / "pyenvwrap.txt").read_text().count("every case") == 1
    gs = json.loads((world["root"] / "report2" / "gradescope" / "pyenvwrap" / "results.json").read_text())
    assert gradescope_problems(gs) == [] and gs["output"] == common
    allowed = [grade_one(t) for t in _tasks(world, "pyenvwrap", (pyenv, venv))]
    assert [r["verdict"] for r in allowed] == ["match", "match"], allowed
    assert all(r["cause"] == "" for r in allowed)

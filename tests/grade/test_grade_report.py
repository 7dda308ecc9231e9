"""a5mi.grade.report: the HTML page in a real headless Chromium (Debian ``chromium``, driven by Playwright),
plus the CSV and JSON files, from a synthetic class (no rendering)."""

from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from a5mi.grade.cases import make_case
from a5mi.grade.report import write_all
from a5mi.grade.verdict import VERDICTS, points_for
from a5mi.platform.imageio import write_image

CHROMIUM = shutil.which("chromium")
CASES = [make_case("-input scene10_sphere.txt -size 8 8 -output 10f.png", points=40),
         make_case("-input scene11_cube.txt -size 8 8 -output 11f.png", points=60)]


def _class(report: Path) -> tuple[list[str], list[dict]]:
    """One student per verdict (plus one with a <script> in its name and stderr, to prove escaping)."""
    rng = np.random.default_rng(0)
    (report / "img" / "ref").mkdir(parents=True)
    for c in CASES:
        write_image(report / "img" / "ref" / f"{c.name}.png", rng.uniform(0, 1, (8, 8, 3)))
    students, records = [], []
    for k, v in enumerate([*VERDICTS, "match"]):
        s = f"s{k:02d}-{v.replace(' ', '_')}" if k < len(VERDICTS) else "<script>x</script>"
        students.append(s)
        for c in CASES:
            images = {}
            if v in ("match", "close", "wrong"):
                (report / "img" / s).mkdir(parents=True, exist_ok=True)
                for kind in ("submission", "flip", "diff"):
                    write_image(report / "img" / s / f"{c.name}.{kind}.png", rng.uniform(0, 1, (8, 8, 3)))
                    images[kind] = f"img/{s}/{c.name}.{kind}.png"
            metrics = ({"beyond_noise": 0.01 * k, "psnr": None if v == "match" else 30.0 + k, "mean_error": 0.5,
                        "share_over_2": 0.1, "max_error": 9.0, "flip": 0.02} if images else None)
            records.append({"key": f"{s}/{c.name}", "student": s, "case": c.name, "verdict": v,
                            "points": points_for(v, c.points), "max_points": c.points, "detail": f"detail {v}",
                            "metrics": metrics, "images": images, "wall": 1.5, "isolation": "bwrap",
                            "stderr_tail": "</pre><script>window.__pwned = 1</script>" if s.startswith("<") else
                            ("Segmentation fault\n" if v == "crash" else "")})
    records.append({"key": "ghost/10f", "error": "KilledWorker: worker died 5 times"})
    students.append("ghost")
    return students, records


def test_csv_and_json(tmp_path) -> None:
    students, records = _class(tmp_path)
    files = write_all(tmp_path, CASES, students, records, {"isolation": "bwrap"})
    rows = list(csv.DictReader(open(files["csv"])))
    assert len(rows) == len(records)
    assert {r["verdict"] for r in rows} == {*VERDICTS, "error"}
    doc = json.loads(Path(files["json"]).read_text())
    assert doc["students"]["s00-match"] == {"points": 100.0, "max_points": 100.0}
    assert doc["students"]["s01-close"] == {"points": 50.0, "max_points": 100.0}
    assert doc["students"]["s02-wrong"]["points"] == 0.0
    assert doc["isolation"] == "bwrap" and [c["name"] for c in doc["cases"]] == ["10f", "11f"]


@pytest.mark.skipif(CHROMIUM is None, reason="chromium is installed by make setup")
def test_report_in_headless_chromium(tmp_path) -> None:
    from playwright.sync_api import sync_playwright

    students, records = _class(tmp_path)
    files = write_all(tmp_path, CASES, students, records, {"isolation": "bwrap"})
    errors: list[str] = []
    requests: list[str] = []
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=[
            "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking"])
        try:
            page = browser.new_page(viewport={"width": 1280, "height": 900})
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
            page.on("request", lambda r: requests.append(r.url))
            page.goto(Path(files["html"]).as_uri())
            page.wait_for_load_state("load")
            rows = page.locator("#summary tbody tr")
            assert rows.count() == len(students)
            shown = [rows.nth(i).get_attribute("data-student") for i in range(rows.count())]
            assert shown == students
            header = page.locator("#summary thead th").all_inner_texts()
            assert header == ["student", "10f", "11f", "total"]
            for v in VERDICTS:
                assert page.locator("#summary .v", has_text=v).count() >= 2, v
            broken = page.evaluate("Array.from(document.images).filter(i => !(i.complete && i.naturalWidth > 0))"
                                   ".map(i => i.src)")
            assert broken == []
            assert page.locator(".case").count() == 2 * (len(students) - 1) + 1  # ghost: one grader error
            assert page.evaluate("window.__pwned") is None  # a student's stderr / name cannot run script
            page.locator("#summary thead th", has_text="total").click()  # sort by total, ascending
            first = page.locator("#summary tbody tr").first.get_attribute("data-student")
            page.locator("#summary thead th", has_text="total").click()  # descending
            top = page.locator("#summary tbody tr").first.get_attribute("data-student")
            assert top in ("s00-match", "<script>x</script>") and first not in ("s00-match", "<script>x</script>")
            shot = tmp_path / "report.png"
            page.screenshot(path=str(shot), full_page=False)
            assert shot.stat().st_size > 10_000
        finally:
            browser.close()
    assert errors == []
    assert all(u.startswith("file://") for u in requests), requests  # works offline: no network fetch

"""``a5mi view`` on the course's test scenes: the time from saving the scene to the updated image in the browser,
per stage, and the README's screenshot.

    .venv/bin/python benchmarks/view_page.py [--saves N] [--baseline A5MI] [--rounds R] [--a5] [--shots DIR]
                                             [--modes plain,jitter-filter] [--this-args ARGS]
                                             [--region X0 X1 Y0 Y1] [SCENE ...]

For each scene (default: the handout's four test scenes) a copy of the scene file is served (the meshes and the
cube map linked from the course folder) by the real ``a5mi view`` command at 300 x 300, once with
``-shadows -bounces 4`` and once with the handout's ``-shadows -bounces 4 -jitter -filter`` against the course's
reference image, in headless Chromium (Playwright, ``/usr/bin/chromium``). Each save changes the scene's
``ambientLight`` (so the image really changes). The page stays warm: the first render of each run is not counted.

Times, from just before the write (``t0``):

* ``final``: to the ``load`` event of the save's full image on the page (the image ``a5`` writes for the flags);
* ``preview``: to the ``load`` event of its preview, where the page shows one (``-jitter``/``-filter``: one ray
  per pixel, labelled PREVIEW on the page, replaced by the full image);
* ``region``: with ``--region X0 X1 Y0 Y1`` (this checkout's server only: the region is marked on its page before
  the saves, docs/VIEW.md "Full quality first"), to the ``load`` event of the first image of the save that shows
  the region's full-quality pixels (its composite, else the preview with the region, else the full image);
* the stages of the full image, medians: ``watcher`` (``t0`` to the watcher's reload request), the engine's
  ``parse`` (parse + describe), ``build`` (Mitsuba objects), ``trace`` (the Python trace of the integrator and the
  rest of the tile loop), ``compile`` (Dr.Jit codegen + LLVM), ``execute`` (kernels), ``filter``, ``png``,
  ``compare`` (reference + metrics + heatmap: after the image, which the page shows first), ``engine`` (the
  render job's wall time, preview and comparison included), and ``delivery`` (the image's state published to
  its ``load``: server-sent event, fetch, PNG decode). Kernel
  launches compiled (not found in Dr.Jit's cache) are summed over the saves.

After the table, one line per row against ``--target`` (seconds from save to the full image, default 0.5: a one-ray
preview does not count): met or not, and where the ``final`` median goes: each stage of the full image (the
watcher's wait, parse, build, trace, compile, execute, filter, png, delivery) as its share of ``final``, largest
first; what the stages do not cover (the preview shown first, the state's publication) is ``other``.

``--this-args ARGS``: more ``a5mi view`` arguments for this checkout's server (``--no-preview``).
``--baseline A5MI`` runs another ``a5mi`` executable (an older checkout's) on its own copy of the scene at the same
time, the saves alternating between the two pages (``ABBA``...), so both are measured under the same load (its
stages are those it reports). ``--a5`` adds the
same render as one ``a5`` process (best of two). Prints one markdown row per scene, flags and code, with the
load average. ``--shots DIR`` saves ``view.png`` (scene10 with a traced pixel and a hovered node).
"""

from __future__ import annotations

import argparse
import os
import re
import shlex
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

CHROMIUM = "/usr/bin/chromium"
SCENES = ["scene06_bunny_1k", "scene10_sphere", "scene11_cube", "scene12_vase"]
MODES = {"plain": ["-shadows", "-bounces", "4"], "jitter-filter": ["-shadows", "-bounces", "4", "-jitter", "-filter"]}
STAGES = ("parse", "build", "trace", "compile", "execute", "filter", "png", "compare")
#: The benchmark's own record of the render image's load events (added after the page's handler, which sets the
#: dataset first).
RECORD_LOADS = """() => { window.__loads = []; const img = document.getElementById('render');
  img.addEventListener('load', () => window.__loads.push({frame: Number(img.dataset.frame),
    kind: img.dataset.kind || 'final', region: !!img.dataset.composite, t: Number(img.dataset.loadedAt)})); }"""


def start(a5mi: Path, scene: Path, flags: list[str], reference: Path | None,
          extra: list[str] | None = None) -> tuple[subprocess.Popen[str], str]:
    argv = [str(a5mi), "view", str(scene), "-size", "300", "300", *flags, *(extra or [])]
    if reference is not None:
        argv += ["--reference", str(reference)]
    proc = subprocess.Popen(argv, cwd=scene.parent, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    line = proc.stdout.readline()
    if not line.startswith("a5mi view: "):
        raise SystemExit(f"a5mi view did not start: {line!r}")
    return proc, line.split(": ", 1)[1].strip()


def stage(name: str, data: Path, tmp: Path) -> Path:
    folder = tmp / name
    folder.mkdir(parents=True, exist_ok=True)
    for entry in (data / "scenes").iterdir():
        if entry.suffix != ".txt" and not (folder / entry.name).exists():
            os.symlink(entry, folder / entry.name)
    shutil.copy(data / "scenes" / f"{name}.txt", folder / "scene.txt")
    return folder / "scene.txt"


def bump_ambient(scene: Path, k: int) -> None:
    text = scene.read_text()
    new = re.sub(r"(ambientLight\s+)([-\d.eE]+)", lambda m: f"{m.group(1)}{0.2 + 0.01 * (k % 2):g}", text, count=1)
    if new == text:
        new = text + "\n"
    with open(scene, "w") as f:
        f.write(new)


def wait_load(page: Any, after: int, kind: str) -> dict[str, Any]:  # a Playwright page
    """The first recorded load of a frame after ``after`` of ``kind`` (``final`` also matches an old page's)."""
    want = "l.kind !== 'preview' && l.kind !== 'region'" if kind == "final" else "l.kind === 'preview'"
    handle = page.wait_for_function(f"(n) => window.__loads.find(l => l.frame > n && {want})", arg=after,
                                    timeout=180_000)
    return handle.json_value()


def wait_idle(page: Any) -> None:
    """Until the page's status says the last render (and its comparison) is done."""
    page.wait_for_function("() => { const s = document.getElementById('status').textContent;"
                           " return s.startsWith('rendered') && !s.endsWith('...'); }", timeout=300_000)


def warm(page: Any) -> None:
    """Record the page's image loads and wait for its first render (not counted)."""
    page.evaluate(RECORD_LOADS)
    page.wait_for_selector("#render[data-frame]", timeout=300_000)
    wait_idle(page)


def mark(page: Any, region: list[int]) -> None:
    """Mark ``region`` on the page (``POST /api/region``, as a shift+drag does) and wait for its first render."""
    last = int(page.get_attribute("#render", "data-frame"))
    ok = page.evaluate("""(r) => fetch('/api/region' + location.search, {method: 'POST', body: JSON.stringify(
        {region: r}), headers: {'Content-Type': 'application/json'}}).then(x => x.ok)""", region)
    if not ok:
        raise SystemExit(f"a5mi view refused the region {region}")
    wait_load(page, last, "final")
    wait_idle(page)


def one_save(page: Any, scene: Path, k: int, marked: bool = False) -> dict[str, Any]:
    """Save ``scene`` (its ambient term changed) and time the page's update (module docstring); ``marked``: a
    region is marked (the ``region`` time)."""
    last = int(page.get_attribute("#render", "data-frame"))
    time.sleep(0.6)  # idle: the watcher's baseline is the last save
    t0 = time.time()
    bump_ambient(scene, k)
    final = wait_load(page, last, "final")
    loads = page.evaluate("window.__loads")
    preview = next((x for x in loads if x["frame"] > last and x["kind"] == "preview"), None)
    region = next((x for x in loads if x["frame"] > last and (x["region"] or x["kind"] == "final")), None)
    wait_idle(page)  # the comparison, which follows the image, is done: its stage is in the state
    state = page.evaluate("fetch('/api/state' + location.search).then(r => r.json())")
    sec = state.get("seconds") or {}
    row = {"final": final["t"] / 1000.0 - t0, "preview": preview["t"] / 1000.0 - t0 if preview else None,
           "region": region["t"] / 1000.0 - t0 if region and marked else None,
           "engine": sec.get("total"), "compiled": (state.get("kernels") or {}).get("compiled")}
    row.update({key: sec.get(key) for key in STAGES})
    if state.get("saved_at"):
        row["watcher"] = state["saved_at"] - t0
    if state.get("published_at"):
        row["delivery"] = final["t"] / 1000.0 - state["published_at"]
    return row


def a5_seconds(a5mi: Path, scene: Path, flags: list[str]) -> float:
    """Wall time of the same render as one ``a5`` process (the loop without the page), best of two."""
    best = float("inf")
    for _ in range(2):
        t0 = time.perf_counter()
        subprocess.run([str(a5mi.with_name("a5")), "-input", str(scene), "-size", "300", "300",
                        *flags, "-output", str(scene.with_name("a5.png"))], check=True, cwd=scene.parent)
        best = min(best, time.perf_counter() - t0)
    return best


def median(rows: list[dict[str, Any]], key: str) -> float | None:
    values = [r[key] for r in rows if r.get(key) is not None]
    return statistics.median(values) if values else None


def fmt(x: float | None) -> str:
    return "-" if x is None else f"{x:.3f}"


def row_line(name: str, flags: list[str], code: str, rows: list[dict[str, Any]], load: float,
             a5: float | None) -> str:
    finals = [r["final"] for r in rows]
    compiled = [r["compiled"] for r in rows if r.get("compiled") is not None]
    cells = [name, " ".join(flags), code, fmt(median(rows, "region")), fmt(median(rows, "preview")),
             f"{fmt(median(rows, 'final'))} ({fmt(min(finals))}-{fmt(max(finals))})",
             *(fmt(median(rows, k)) for k in ("watcher", *STAGES, "engine", "delivery")),
             str(sum(compiled)) if compiled else "-"]
    if a5 is not None:
        cells.append(f"{a5:.3f}")
    return "| " + " | ".join(cells) + f" | {load:.1f} |"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scenes", nargs="*", default=SCENES)
    ap.add_argument("--saves", type=int, default=8)
    ap.add_argument("--rounds", type=int, default=1, help="saves per code: saves x rounds")
    ap.add_argument("--baseline", type=Path, help="another a5mi executable, measured alternately")
    ap.add_argument("--modes", default=",".join(MODES))
    ap.add_argument("--a5", action="store_true", help="also time one a5 process per row")
    ap.add_argument("--shots", type=Path)
    ap.add_argument("--this-args", default="", help="more a5mi view arguments for this code (e.g. --no-preview)")
    ap.add_argument("--target", type=float, default=0.5, help="seconds from save to the full image (the goal)")
    ap.add_argument("--region", type=int, nargs=4, metavar=("X0", "X1", "Y0", "Y1"),
                    help="mark this region on this checkout's page: rendered first at full quality on each save")
    args = ap.parse_args()
    from playwright.sync_api import sync_playwright

    from a5mi import data_dir

    data = data_dir()
    codes = {"this": Path(sys.executable).with_name("a5mi")}
    if args.baseline:
        codes["baseline"] = args.baseline
    head = ["scene", "flags", "code", "region", "preview", "final (min-max)", "watcher", *STAGES, "engine", "delivery",
            "compiled"] + (["one a5"] if args.a5 else []) + ["load avg"]
    print("| " + " | ".join(head) + " |")
    print("|" + " --- |" * len(head))
    measured: list[tuple[str, list[str], str, list[dict[str, Any]]]] = []
    with tempfile.TemporaryDirectory() as tmp, sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=[
            "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking"])
        for name in args.scenes:
            for mode in args.modes.split(","):
                flags = MODES[mode]
                ref = data / "reference" / f"{name}.b4-jitter-filter.png" if mode == "jitter-filter" else None
                results: dict[str, list[dict[str, Any]]] = {c: [] for c in codes}
                loads: dict[str, list[float]] = {c: [] for c in codes}
                servers, pages, scenes = {}, {}, {}
                try:  # every code serves its own copy at once; their saves alternate (the same load for both)
                    for code in codes:
                        scenes[code] = stage(name, data, Path(tmp) / code)
                        servers[code] = start(codes[code], scenes[code], flags, ref,
                                              shlex.split(args.this_args) if code == "this" else None)
                        pages[code] = browser.new_page(viewport={"width": 1480, "height": 1000})
                        pages[code].goto(servers[code][1])
                    for code in codes:
                        warm(pages[code])
                    if args.region:
                        mark(pages["this"], args.region)
                    for k in range(args.saves * args.rounds):
                        for code in (list(codes) if k % 2 == 0 else list(reversed(codes))):
                            loads[code].append(os.getloadavg()[0])
                            results[code].append(one_save(pages[code], scenes[code], k,
                                                          bool(args.region) and code == "this"))
                    if args.shots and name == "scene10_sphere" and mode == "jitter-filter":
                        shoot(pages["this"], args.shots / "view.png")
                finally:
                    for code in servers:
                        pages[code].close()
                        servers[code][0].terminate()
                        servers[code][0].wait(timeout=30)
                for code in codes:
                    a5 = a5_seconds(codes[code], scenes[code], flags) if args.a5 else None
                    print(row_line(name, flags, code, results[code], statistics.mean(loads[code]), a5), flush=True)
                    measured.append((name, flags, code, results[code]))
        browser.close()
    print()
    for name, flags, code, rows in measured:
        print(where_it_goes(name, flags, code, rows, args.target))


def where_it_goes(name: str, flags: list[str], code: str, rows: list[dict[str, Any]], target: float) -> str:
    """One line: the ``final`` median against ``target`` and the stages' shares of it, largest first (module
    docstring)."""
    final = median(rows, "final") or 0.0
    parts = {k: median(rows, k) or 0.0 for k in ("watcher", "parse", "build", "trace", "compile", "execute",
                                                 "filter", "png", "delivery")}
    parts["other"] = max(0.0, final - sum(parts.values()))
    ranked = sorted(parts.items(), key=lambda kv: -kv[1])
    verdict = "met" if final <= target else "NOT met"
    return (f"{name} {' '.join(flags)} ({code}): save to image {final:.3f} s, target {target:.2f} s {verdict}; "
            + ", ".join(f"{k} {v:.3f} s ({100 * v / final:.0f}%)" for k, v in ranked if final > 0))


def shoot(page: Any, path: Path) -> None:  # a Playwright page
    box = page.locator("#render").bounding_box()
    page.mouse.click(box["x"] + 172.5, box["y"] + 150.5)
    page.wait_for_selector("#trace-sum", timeout=120_000)
    page.locator(".node").nth(2).dispatch_event("mouseenter")  # mark its hit point without scrolling
    height = 820
    while True:  # the top of the page, cut until the PNG is under 300 KB (the README's image stays small)
        page.screenshot(path=str(path), clip={"x": 0, "y": 0, "width": 1480, "height": height})
        if path.stat().st_size < 300_000 or height < 500:
            break
        height -= 40


if __name__ == "__main__":
    main()

"""``a5mi view`` on the course's test scenes: the time from saving the scene to the updated image in the browser,
and the README's screenshot.

    .venv/bin/python benchmarks/view_page.py [--saves N] [--shots DIR] [SCENE ...]

For each scene (default: the handout's four test scenes) a copy of the scene file is served (the meshes and the
cube map linked from the course folder) by the real ``a5mi view`` command at 300 x 300, once with
``-shadows -bounces 4`` and once with the handout's ``-shadows -bounces 4 -jitter -filter`` against the course's
reference image, in headless Chromium (Playwright, ``/usr/bin/chromium``). Each save changes the scene's
``ambientLight`` (so the image really changes) and the time is from just before the write to the ``load`` event
of the new image on the page (watcher poll, parse and describe, scene build, render, PNG, compare, the event,
the browser's fetch and decode). The page stays warm: the first render of each run is not counted. Prints one
markdown row per scene and mode: median, min and max of ``--saves`` saves, the engine's own stages (median), the
same render as one ``a5`` process (best of two, measured right after: the loop without the page) and its ratio
to the median, and the load average. ``--shots DIR`` saves ``view.png`` (scene10 with a traced pixel and a
hovered node).
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

CHROMIUM = "/usr/bin/chromium"
SCENES = ["scene06_bunny_1k", "scene10_sphere", "scene11_cube", "scene12_vase"]
MODES = {"plain": ["-shadows", "-bounces", "4"], "jitter-filter": ["-shadows", "-bounces", "4", "-jitter", "-filter"]}


def start(scene: Path, flags: list[str], reference: Path | None) -> tuple[subprocess.Popen[str], str]:
    argv = [str(Path(sys.executable).with_name("a5mi")), "view", str(scene), "-size", "300", "300", *flags]
    if reference is not None:
        argv += ["--reference", str(reference)]
    proc = subprocess.Popen(argv, cwd=scene.parent, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    line = proc.stdout.readline()
    if not line.startswith("a5mi view: "):
        raise SystemExit(f"a5mi view did not start: {line!r}")
    return proc, line.split(": ", 1)[1].strip()


def stage(name: str, data: Path, tmp: Path) -> Path:
    folder = tmp / name
    folder.mkdir()
    for entry in (data / "scenes").iterdir():
        if entry.suffix != ".txt":
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


def measure(page, scene: Path, saves: int) -> tuple[list[float], list[dict]]:  # noqa: ANN001
    page.wait_for_selector("#render[data-frame='1']", timeout=300_000)
    times, stages = [], []
    for k in range(saves):
        frame = int(page.get_attribute("#render", "data-frame")) + 1
        time.sleep(0.6)  # idle: the watcher's baseline is the last save
        t0 = time.time()
        bump_ambient(scene, k)
        page.wait_for_selector(f"#render[data-frame='{frame}']", timeout=120_000)
        times.append(int(page.get_attribute("#render", "data-loaded-at")) / 1000.0 - t0)
        stages.append(page.evaluate("fetch('/api/state' + location.search).then(r => r.json())")["seconds"])
    return times, stages


def a5_seconds(scene: Path, flags: list[str]) -> float:
    """Wall time of the same render as one ``a5`` process (the loop without the page), best of two."""
    best = float("inf")
    for _ in range(2):
        t0 = time.perf_counter()
        subprocess.run([str(Path(sys.executable).with_name("a5")), "-input", str(scene), "-size", "300", "300",
                        *flags, "-output", str(scene.with_name("a5.png"))], check=True, cwd=scene.parent)
        best = min(best, time.perf_counter() - t0)
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scenes", nargs="*", default=SCENES)
    ap.add_argument("--saves", type=int, default=8)
    ap.add_argument("--shots", type=Path)
    args = ap.parse_args()
    from playwright.sync_api import sync_playwright

    from a5mi import data_dir

    data = data_dir()
    print("| scene | flags | median | min | max | engine stages (median s) | one `a5` process | a5 / median | "
          "load average |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    with tempfile.TemporaryDirectory() as tmp, sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=[
            "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking"])
        for name in args.scenes:
            scene = stage(name, data, Path(tmp))
            for mode, flags in MODES.items():
                ref = data / "reference" / f"{name}.b4-jitter-filter.png" if mode == "jitter-filter" else None
                proc, url = start(scene, flags, ref)
                try:
                    page = browser.new_page(viewport={"width": 1480, "height": 1000})
                    page.goto(url)
                    load = os.getloadavg()[0]
                    times, stages = measure(page, scene, args.saves)
                    load = (load + os.getloadavg()[0]) / 2
                    a5 = a5_seconds(scene, flags)
                    keys = [k for k in ("render", "png", "compare", "total") if k in stages[0]]
                    st = ", ".join(f"{k} {statistics.median(s[k] for s in stages):.3f}" for k in keys)
                    med = statistics.median(times)
                    print(f"| {name} | {' '.join(flags)} | {med:.3f} s | {min(times):.3f} s | {max(times):.3f} s | "
                          f"{st} | {a5:.3f} s | {a5 / med:.1f}x | {load:.1f} |", flush=True)
                    if args.shots and name == "scene10_sphere" and mode == "jitter-filter":
                        shoot(page, args.shots / "view.png")
                    page.close()
                finally:
                    proc.terminate()
                    proc.wait(timeout=30)
        browser.close()


def shoot(page, path: Path) -> None:  # noqa: ANN001
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

"""The work estimate (docs/USAGE.md "Work estimate", a5mi/render/estimate.py): the bound holds against the
rays the kernels really cast and is within 100x of them; ``a5`` refuses, warns and reports progress as
documented."""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from helpers import TESTS

from a5mi.render import estimate as est
from a5mi.render.options import RenderOptions

PROJECT_SCENES = Path(__file__).resolve().parents[2] / "scenes"
A5 = str(Path(sys.executable).with_name("a5"))

#: A diffuse room (the shape of the scene that ran for 22 minutes): a sphere and two planes, a point light.
ROOM = (TESTS / "data" / "scenes" / "room.txt").read_text()
#: (line, column) of the room's first material: the diffuse one the refusal points at
ROOM_MATERIAL = (6, 5)

SMALL = {"width": 16, "height": 16}
#: (scene: "course/NAME", "project/NAME" or "room", options): each integrator and flag family
CASES: list[tuple[str, dict[str, Any]]] = [
    ("course/scene03_sphere.txt", {}),
    ("course/scene10_sphere.txt", {"shadows": True, "bounces": 4}),                      # mirror + refraction
    ("course/scene12_vase.txt", {"shadows": True, "bounces": 4}),
    ("course/scene11_cube.txt", {"shadows": True, "bounces": 4, "jitter": True}),
    ("course/scene10_sphere.txt", {"reflection": False, "bounces": 4}),
    ("project/ic_sky.txt", {"indirect": 4, "bounces": 2}),                               # E.15
    ("project/colour_bleeding.txt", {"indirect": 3, "bounces": 2, "shadows": True}),
    ("room", {"indirect": 2, "bounces": 3, "shadows": True}),
    ("project/glossy.txt", {"shadows": True, "spp": 2, "bounces": 2}),                   # E.4 glossy samples
    ("project/soft_shadows.txt", {"shadows": True, "spp": 2}),                           # E.2 area lights
    ("project/colour_bleeding.txt", {"integrator": "path", "bounces": 3, "spp": 2}),    # E.14
    ("project/ic_sky.txt", {"integrator": "path", "bounces": 6}),
    ("course/scene10_sphere.txt", {"integrator": "irradiancecache", "ic_samples": 64, "bounces": 2}),  # E.23
    ("project/ic_bleed.txt", {"integrator": "irradiancecache", "ic_samples": 64, "bounces": 2}),
    ("course/scene10_sphere.txt", {"integrator": "photon", "photons": 1000, "caustic_photons": 1000}),  # E.16
    ("course/scene10_sphere.txt", {"integrator": "photon", "photons": 1000, "caustic_photons": 1000,
                                   "final_gather": 4}),
    ("course/scene10_sphere.txt", {"integrator": "ppm", "photons": 1000, "caustic_photons": 1000, "spp": 2}),
]


def _scene(name: str, scenes_dir: Path, tmp_path: Path) -> Path:
    kind, _, file = name.partition("/")
    if kind == "room":
        path = tmp_path / "room.txt"
        path.write_text(ROOM)
        return path
    return (scenes_dir if kind == "course" else PROJECT_SCENES) / file


def test_tree_nodes_is_the_geometric_series() -> None:
    """``1 + k0 Σ_{i<B} k^i``: a glass tree (2 children) of 4 bounces has 31 nodes, a mirror chain B + 1."""
    assert est.tree_nodes(2, 2, 4) == 31
    assert est.tree_nodes(1, 1, 4) == 5
    assert est.tree_nodes(16, 2, 2) == 1 + 16 * 3
    assert est.tree_nodes(5, 5, 0) == 1
    assert est.hemisphere_rays(64) == 5 * 13 and est.hemisphere_rays(256) == 9 * 28


def _case_id(scene: str, flags: dict[str, Any]) -> str:
    return scene.split("/")[-1].removesuffix(".txt") + "".join(f"-{k}{v}" for k, v in flags.items())


@pytest.mark.parametrize(("scene", "flags"), CASES, ids=[_case_id(s, f) for s, f in CASES])
def test_bound_holds_and_is_within_100x(scene: str, flags: dict[str, Any], scenes_dir: Path, tmp_path: Path,
                                        variant: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """The rays cast, counted by the kernels' ``counts`` AOV (``-v``: camera, reflection, refraction, shadow),
    the irradiance cache's ``gather_rays`` and, for photon mapping, every photon ray, pilot ray and final-gather
    ray (counted where plugins/integrators/photon/trace.py and plugins/integrators/photon/integrator.py cast
    them): bound >= cast >= bound / 100."""
    from a5mi.plugins.integrators.photon import integrator as photon
    from a5mi.plugins.integrators.photon import trace as photon_trace
    from a5mi.render.session import describe_file, render

    photon_rays = [0]
    bounce = photon_trace._bounce
    pilot = photon.first_distance

    def counted_bounce(scene_: Any, data: Any, f: Any, o: Any, *rest: Any, **kw: Any) -> Any:
        photon_rays[0] += len(o)
        return bounce(scene_, data, f, o, *rest, **kw)

    def counted_pilot(scene_: Any, data: Any) -> Any:
        dist = pilot(scene_, data)

        def run(o: Any, d: Any) -> Any:
            photon_rays[0] += len(o)
            return dist(o, d)  # type: ignore[operator]
        return run

    gather = photon.A5PhotonIntegrator.gather

    def counted_gather(self: Any, scene_: Any, data: Any, f: Any, maps: Any, x: Any, *rest: Any) -> Any:
        photon_rays[0] += len(x) * self.final_gather  # the final gather's rays (E.16)
        return gather(self, scene_, data, f, maps, x, *rest)

    monkeypatch.setattr(photon.A5PhotonIntegrator, "gather", counted_gather)
    monkeypatch.setattr(photon_trace, "_bounce", counted_bounce)
    monkeypatch.setattr(photon, "first_distance", counted_pilot)
    desc, _ = describe_file(str(_scene(scene, scenes_dir, tmp_path)))
    options = RenderOptions(count_rays=True, seed=1, **{**SMALL, **flags})
    bound = est.estimate(desc, options)
    result = render(desc, options)
    rw, rh = options.render_size
    cast = rw * rh * options.spp + sum(result.ray_counts.values()) + photon_rays[0]
    cast += result.extras.get("irradiance_cache_stats", {}).get("gather_rays", 0)
    assert bound.camera_rays == rw * rh * options.spp
    assert bound.rays >= cast, (bound, cast)
    assert bound.rays <= 100 * cast, (bound.rays / cast, bound)


def test_course_scenes_with_the_handout_flags_are_not_warned(scenes_dir: Path) -> None:
    """``-size 300 300 -shadows -bounces 4 -jitter -filter`` on every course scene: under a minute at the
    assumed rate, so ``a5`` prints nothing new."""
    from a5mi.render.session import describe_file

    options = RenderOptions(width=300, height=300, shadows=True, bounces=4, jitter=True, filter=True)
    for path in sorted(scenes_dir.glob("scene*.txt")):
        desc, _ = describe_file(str(path))
        work = est.estimate(desc, options, rate=est.CONSERVATIVE_RATE)
        assert work.seconds < est.WARN_SECONDS, (path.name, est.summary(work))


def test_a_course_render_prints_nothing(scenes_dir: Path, tmp_path: Path) -> None:
    """The handout's command on scene10 (the largest course bound after scene13) with no rate measured yet:
    empty stderr, exit 0."""
    p = subprocess.run([A5, "-input", "scene10_sphere.txt", "-size", "300", "300", "-output", str(tmp_path / "o.png"),
                        "-shadows", "-bounces", "4", "-jitter", "-filter"], cwd=scenes_dir, capture_output=True,
                       text=True, env={**os.environ, "A5MI_CACHE_DIR": str(tmp_path / "cache")})
    assert (p.returncode, p.stderr) == (0, "")


def _a5(args: list[str], cwd: Path, cache: Path) -> tuple[subprocess.CompletedProcess[str], float]:
    """Run ``a5`` with its own cache folder; also its CPU seconds (user + system, from RUSAGE_CHILDREN)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    p = subprocess.run([A5, *args], cwd=cwd, capture_output=True, text=True,
                       env={**os.environ, "A5MI_CACHE_DIR": str(cache)})
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return p, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def test_the_room_command_is_refused_in_one_positioned_line_under_a_cpu_second(tmp_path: Path) -> None:
    """``a5 -input room.txt -size 48 48 -indirect 16 -spp 16 -shadows -bounces 8``: 16^8 rays per camera ray
    for 48 x 48 x 16 camera rays; refused at the diffuse material with the flags to change, exit 2, before
    Mitsuba starts (under a CPU second, the interpreter's start-up included), no image written."""
    (tmp_path / "room.txt").write_text(ROOM)
    p, cpu = _a5(["-input", "room.txt", "-size", "48", "48", "-indirect", "16", "-spp", "16", "-shadows",
                  "-bounces", "8", "-output", "o.png"], tmp_path, tmp_path / "cache")
    assert p.returncode == 2 and p.stdout == ""
    lines = p.stderr.splitlines()
    assert len(lines) == 1, p.stderr
    line, col = ROOM_MATERIAL
    assert lines[0].startswith(f"room.txt:{line}:{col}: error: this render may trace up to ")
    for flag in ("-bounces", "-indirect", "-spp", "-force"):
        assert flag in lines[0]
    # 48·48·16 camera rays, each 1 + 16 Σ_{i<8} 16^i nodes with one shadow ray each
    assert f"{48 * 48 * 16 * 2 * est.tree_nodes(16, 16, 8):.1e}".replace("e+", "e") in lines[0]
    assert not (tmp_path / "o.png").exists()
    assert cpu < 1.0, cpu


def _slow_machine(cache: Path, rate: float) -> None:
    cache.mkdir(parents=True, exist_ok=True)
    (cache / est.RATE_FILE).write_text(json.dumps({est._machine_key(): rate}))


def test_warning_over_a_minute_and_refusal_over_an_hour_with_the_rate_kept_in_the_cache(tmp_path: Path) -> None:
    """A kept rate of 100 rays/s: the 16 x 16 room with -shadows -bounces 0 (256 camera rays and their shadow
    rays) is 512 rays = 5.1 s: silent; -bounces 3 -indirect 2: 256 · 15 · 2 = 7680 rays = 77 s: one positioned
    warning, rendered (exit 0); -indirect 4 -bounces 4 -spp 16: 256 · 16 · 341 · 2 rays = 7.8 h: refused in
    one positioned line (exit 2, nothing written); with -spp 2 and -force (58 min): warned and rendered."""
    cache = tmp_path / "cache"
    _slow_machine(cache, 100.0)
    (tmp_path / "room.txt").write_text(ROOM)
    base = ["-input", "room.txt", "-size", "16", "16", "-shadows", "-output", "o.png"]
    p, _ = _a5(base + ["-bounces", "0"], tmp_path, cache)
    assert (p.returncode, p.stderr) == (0, "")
    p, _ = _a5(base + ["-bounces", "3", "-indirect", "2"], tmp_path, cache)
    assert p.returncode == 0 and (tmp_path / "o.png").exists()
    line, col = ROOM_MATERIAL
    assert p.stderr.splitlines() == [f"room.txt:{line}:{col}: warning: this render may trace up to 7680 rays, about "
                                     "77 s at 100 rays/s (measured on this machine): a ray tree of up to 15 nodes per "
                                     "camera ray, 2 children per hit with -indirect 2, -bounces 3, 1 shadow ray per "
                                     "node"], p.stderr
    warned = (tmp_path / "o.png").read_bytes()
    # the same render unwarned (no kept rate: 7680 rays at 2e6 rays/s) is one tile; warned with -v it was cut
    # into progress tiles (a5mi.render.estimate.progress_tile_rays): the same bytes
    p, _ = _a5(base + ["-bounces", "3", "-indirect", "2", "-v"], tmp_path, cache)
    assert p.returncode == 0 and ", 4 tiles), saved 16x16" in p.stderr, p.stderr
    assert (tmp_path / "o.png").read_bytes() == warned
    p, _ = _a5(base + ["-bounces", "3", "-indirect", "2"], tmp_path, tmp_path / "fresh")
    assert (p.returncode, p.stderr) == (0, "") and (tmp_path / "o.png").read_bytes() == warned
    (tmp_path / "o.png").unlink()
    refused = base + ["-bounces", "4", "-indirect", "4", "-spp", "16"]
    p, _ = _a5(refused, tmp_path, cache)
    assert p.returncode == 2 and len(p.stderr.splitlines()) == 1
    assert p.stderr.startswith(f"room.txt:{line}:{col}: error: ") and "about 7.8 h at 100 rays/s" in p.stderr
    assert not (tmp_path / "o.png").exists()
    p, _ = _a5(refused[:-2] + ["-spp", "2", "-force"], tmp_path, cache)  # forced (and kept small: 58 min)
    assert p.returncode == 0 and ": warning: " in p.stderr and (tmp_path / "o.png").exists()


def test_verbose_reports_the_estimate_and_keeps_the_rate(tmp_path: Path, scenes_dir: Path) -> None:
    """``-v``: the estimate before, the rays traced against it after; a render of over a million rays keeps
    its rate (counted rays over kernel time) for the next estimate."""
    cache = tmp_path / "cache"
    p, _ = _a5(["-input", "scene10_sphere.txt", "-size", "150", "150", "-jitter", "-shadows", "-bounces", "4",
                "-output", str(tmp_path / "o.png"), "-v"], scenes_dir, cache)
    assert p.returncode == 0, p.stderr
    lines = p.stderr.splitlines()
    assert lines[0].startswith("a5: estimate up to 1.9e7 rays, about ")
    assert lines[0].endswith(": a ray tree of up to 31 nodes per camera ray, 2 children per hit, -bounces 4, "
                             "2 shadow rays per node")
    traced = [x for x in lines if x.startswith("a5: traced ")]
    assert len(traced) == 1
    n = int(traced[0].split()[2])
    assert 450 * 450 < n < 1.9e7
    rate = est.measured_rate(cache / est.RATE_FILE)
    assert rate is not None and rate > 0


def test_record_rate_keeps_the_latest_and_skips_small_renders(tmp_path: Path) -> None:
    path = tmp_path / "c" / est.RATE_FILE
    assert est.measured_rate(path) is None
    assert est.record_rate(10, 1.0, path) is None and not path.exists()
    assert est.record_rate(4_000_000, 2.0, path) == 2e6
    assert est.measured_rate(path) == 2e6
    assert est.record_rate(3_000_000, 1.0, path) == 3e6 and est.measured_rate(path) == 3e6
    path.write_text("not json")
    assert est.measured_rate(path) is None


def test_duration_reads_as_the_user_would() -> None:
    assert [est.duration(s) for s in (45, 600, 3 * 3600, 40 * 86400, 3.2e8)] == \
        ["45 s", "10 min", "3.0 h", "40 days", "10 years"]


def test_a_batch_refuses_the_job_and_force_reaches_every_job(tmp_path: Path) -> None:
    """``a5mi render SCENE --output-dir``: the refused job is its one positioned line and the batch's exit 2;
    ``--force`` on the command line reaches the jobs."""
    cache = tmp_path / "cache"
    _slow_machine(cache, 100.0)
    (tmp_path / "room.txt").write_text(ROOM)
    (tmp_path / "out").mkdir()
    argv = [str(Path(sys.executable).with_name("a5mi")), "render", "room.txt", "--output-dir", "out", "--size", "16",
            "16", "--bounces", "4", "--indirect", "4", "--spp", "16"]
    env = {**os.environ, "A5MI_CACHE_DIR": str(cache)}
    p = subprocess.run(argv, cwd=tmp_path, capture_output=True, text=True, env=env)
    line, col = ROOM_MATERIAL
    assert p.returncode == 2 and p.stderr.splitlines()[0].startswith(f"room.txt:{line}:{col}: error: ")
    assert not (tmp_path / "out" / "room.png").exists()
    p = subprocess.run([*argv[:-1], "1", "--force"], cwd=tmp_path, capture_output=True, text=True, env=env)
    assert p.returncode == 0 and (tmp_path / "out" / "room.png").exists(), p.stderr


def test_the_estimate_points_at_what_makes_it_large(scenes_dir: Path, tmp_path: Path) -> None:
    """The element behind the bound: the diffuse material that multiplies with -indirect, the area light whose
    samples multiply the shadow rays, else the camera; and the flags named are the ones that lower it."""
    from a5mi.render.session import describe_file

    room, _ = describe_file(str(_scene("room", scenes_dir, tmp_path)))
    work = est.estimate(room, RenderOptions(indirect=3, bounces=2, shadows=True))
    assert (work.loc.line, work.loc.col) == ROOM_MATERIAL and work.hints == ("-bounces", "-indirect", "-size")
    assert work.per_camera_ray == est.tree_nodes(3, 3, 2) * 2
    soft, _ = describe_file(str(PROJECT_SCENES / "soft_shadows.txt"))
    work = est.estimate(soft, RenderOptions(shadows=True, spp=4))
    light = max(soft.lights, key=lambda x: getattr(x, "samples", 1))
    assert work.loc == light.loc and work.hints == ("the lights' samples", "-spp", "-size")
    plain = est.estimate(room, RenderOptions())
    assert plain.loc == room.camera.loc and plain.per_camera_ray == 1 and plain.hints == ("-size",)

"""Tests of ``a5mi bench``'s own logic: parsing, scene lookup, tables, ray replay bookkeeping,
child-process measurement. Never a timed assertion: only counts, shapes, exit codes and memory lower bounds."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from a5mi import bench
from a5mi.cli import run_a5mi

VERBOSE = """\
a5: llvm_ad_rgb, render 900x900 (810000 camera rays, 1 tiles), saved 300x300
a5: secondary rays reflection 2252268, refraction 1140699, shadow 5618298
a5: times parse 0.016 s, variant 0.177 s, build 0.308 s, compile 0.290 s, execute 0.604 s, render 0.780 s, \
jitter 0.076 s, filter 0.035 s, write 0.027 s, counts 0.500 s
a5: peak memory 328 MB
"""


def test_parse_verbose() -> None:
    stages, rays = bench.parse_verbose(VERBOSE)
    assert stages == {"parse": 0.016, "variant": 0.177, "build": 0.308, "compile": 0.290, "execute": 0.604,
                      "render": 0.780, "jitter": 0.076, "filter": 0.035, "write": 0.027, "counts": 0.5}
    assert rays == {"camera": 810000, "reflection": 2252268, "refraction": 1140699, "shadow": 5618298}
    assert bench.parse_verbose("a5: error: nothing\n") == ({}, {})


def test_startup_is_wall_minus_verbose_stages() -> None:
    stages, rays = bench.parse_verbose(VERBOSE)
    run = bench.ProcessRun(wall=2.0, peak_mb=1.0, returncode=0, stderr=VERBOSE, stages=stages, rays=rays)
    # parse + variant + build + render + filter + write + the -v count pass (compile/execute/jitter are inside
    # render)
    assert run.startup == pytest.approx(2.0 - (0.016 + 0.177 + 0.308 + 0.780 + 0.035 + 0.027 + 0.5))
    assert bench.ProcessRun(wall=1.0, peak_mb=1.0, returncode=0, stderr="").startup is None


def test_published_times_from_the_course_readme(a5_data: Path) -> None:
    found = bench.published_times((a5_data / "reference" / "README.md").read_text())
    assert found == bench.PUBLISHED_A5SOLN
    assert bench.load_published(a5_data) == bench.PUBLISHED_A5SOLN
    assert bench.load_published(a5_data / "no-such-folder") == bench.PUBLISHED_A5SOLN  # fallback copy


def test_scene_names_and_lookup(a5_data: Path) -> None:
    assert bench.scene_name("scenes/scene12_vase.txt") == "scene12_vase"
    assert bench.scene_name("extras/sibenik/s.txt") == "sibenik/s"
    assert bench.published_key("scene06_bunny_1k") == "scene06"
    assert bench.published_key("sibenik/s") is None
    default = bench.resolve_scenes([], a5_data)
    assert [p.relative_to(a5_data).as_posix() for p in default] == list(bench.SCENES)
    assert all(p.is_file() for p in default)
    assert bench.resolve_scenes(["scene10"], a5_data) == [a5_data / "scenes/scene10_sphere.txt"]
    assert bench.resolve_scenes(["sibenik"], a5_data) == [a5_data / "extras/sibenik/s.txt"]
    explicit = a5_data / "scenes" / "scene01_plane.txt"
    assert bench.resolve_scenes([str(explicit)], a5_data) == [explicit.resolve()]
    with pytest.raises(ValueError, match="unknown benchmark scene 'scene1'"):
        bench.resolve_scenes(["scene1"], a5_data)  # ambiguous: scene10..scene13


def test_format_table_is_aligned_markdown() -> None:
    text = bench.format_table(["scene", "s", "MB"], [["a", 0.5, 1289.4], ["longer name", None, 12.0]])
    lines = text.splitlines()
    assert len(lines) == 4
    assert len({len(line) for line in lines}) == 1  # every row padded to the same width
    assert lines[1].startswith("|---") and lines[1].endswith(":|")
    assert lines[2].split("|")[1:-1] == [" a           ", " 0.500 ", " 1289 "]
    assert lines[3].split("|")[1:-1] == [" longer name ", "     - ", " 12.0 "]


@given(st.lists(st.integers(0, 5), max_size=30))
def test_lane_repeat_and_rank_match_a_direct_loop(counts: list[int]) -> None:
    lanes = bench.lane_repeat(counts)
    expected = [i for i, c in enumerate(counts) for _ in range(c)]
    assert lanes.tolist() == expected
    ranks = [r for c in counts for r in range(c)]
    assert bench.rank_within_lane(lanes).tolist() == ranks


def test_lane_repeat_rounds_float_counts() -> None:
    assert bench.lane_repeat(np.array([1.0000001, 0.0, 2.9999998, -1.0], np.float32)).tolist() == [0, 2, 2, 2]


def test_run_process_measures_the_child_alone(tmp_path: Path) -> None:
    script = ("import sys, numpy as np; a = np.ones(200 * 2**20 // 8); sys.stderr.write('hello\\n'); "
              "sys.exit(3)")
    run = bench.run_process([sys.executable, "-c", script], cwd=tmp_path)
    assert run.returncode == 3
    assert run.stderr == "hello\n"
    assert run.peak_mb >= 200  # its own ru_maxrss, touched pages of the 200 MB array included
    assert run.wall > 0


def test08b_peak_memory_is_not_inherited_from_a_large_parent() -> None:
    ballast = np.ones(400 * 2**20 // 8)  # this process: >= 400 MB resident
    run = bench.run_process([sys.executable, "-c", "pass"])
    assert ballast.sum() > 0 and run.returncode == 0
    assert run.peak_mb < 200  # a bare interpreter, not this process's high-water mark


def test_run_process_kills_at_the_timeout() -> None:
    run = bench.run_process([sys.executable, "-c", "import time; time.sleep(60)"], timeout=0.5)
    assert run.returncode < 0  # killed by a signal


def test_cache_env_and_command() -> None:
    env = bench.cache_env("/tmp/x")
    assert env["DRJIT_CACHE_DIR"] == "/tmp/x"
    cmd = bench.a5_command()
    assert cmd[0].endswith("a5") or cmd[-2:] == ["-m", "a5mi"]
    assert bench.render_flags(300, 200, 4) == ["-size", "300", "200", "-shadows", "-bounces", "4", "-jitter",
                                               "-filter"]


def test_cpu_busy_is_a_fraction(tmp_path: Path) -> None:
    assert 0.0 <= bench.cpu_busy(0.05) <= 1.0
    assert bench.cpu_busy(0.0, stat=str(tmp_path / "missing")) == 0.0


def test_bad_arguments_exit_2(capsys: pytest.CaptureFixture[str]) -> None:
    assert run_a5mi(["bench", "--size", "0", "10"]) == 2
    assert run_a5mi(["bench", "no_such_scene"]) == 2
    assert run_a5mi(["bench", "--a5soln", "/no/such/binary", "scene10"]) == 2
    err = capsys.readouterr().err
    assert err.count("a5mi bench: error:") == 3


def _as_printed(v: float) -> Any:
    """``v`` within half a unit of the last digit :func:`a5mi.bench.report.format_table` prints (3 decimals
    below 10, 1 below 1000, none above): a ratio measured on a loaded machine may be printed coarser."""
    return pytest.approx(v, abs=0.0005 if abs(v) < 10 else 0.05 if abs(v) < 1000 else 0.5)


def test_floor_replays_the_render_ray_counts(
    variant: str, scenes_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The in-process pass casts exactly as many rays of each kind as the driver counts for the same render."""
    from a5mi.render.options import RenderOptions
    from a5mi.render.session import describe_file, render

    monkeypatch.chdir(scenes_dir)
    options = RenderOptions(width=20, height=20, bounces=4, shadows=True, jitter=True, filter=True)
    counted = render(describe_file("scene10_sphere.txt")[0], RenderOptions(
        width=20, height=20, bounces=4, shadows=True, jitter=True, filter=True, count_rays=True))
    result = bench.measure_in_process(Path("scene10_sphere.txt"), options, repeat=1)
    assert result.rays == {"camera": 60 * 60, **counted.ray_counts}
    assert result.rays["shadow"] > 0 and result.rays["reflection"] > 0 and result.rays["refraction"] > 0
    assert result.lights == 2
    # the floor traverses every logged ray: as many as the render cast, each kind timed
    assert result.logged == {"nodes": 3600 + result.rays["reflection"] + result.rays["refraction"],
                             "shadow": result.rays["shadow"]}
    assert set(result.floor) == {"camera", "secondary", "shadow"} and all(v > 0 for v in result.floor.values())
    assert set(result.floor_first_hits) == set(bench.RAY_KINDS)
    assert all(v > 0 for v in result.floor_first_hits.values())
    assert set(bench.STAGES) <= set(result.stages)
    text = bench.report([bench.SceneResult(name="scene10_sphere", path="x", inproc=result)], {}, {})
    header, _, row = text.split("Rays and the traversal floor")[1].split("\n\n")[1].splitlines()
    names = [c.strip() for c in header.strip("|").split("|")]
    cells = dict(zip(names, (c.strip() for c in row.strip("|").split("|")), strict=True))
    assert float(cells["kernel/floor"]) == _as_printed(result.kernel_execute / result.floor_total)
    assert float(cells["floor (first hits)"]) == _as_printed(sum(result.floor_first_hits.values()))


def test_report_has_the_process_stage_table() -> None:
    """The ``-v`` run's stages go into their own table; ``startup`` = wall - the seven reported stages (the
    six of the command and the -v count pass)."""
    stages, rays = bench.parse_verbose(VERBOSE)
    res = bench.SceneResult(name="scene10_sphere", path="x",
                            verbose=bench.ProcessRun(wall=2.0, peak_mb=1.0, returncode=0, stderr=VERBOSE,
                                                     stages=stages, rays=rays))
    text = bench.report([res], {}, {})
    table = text.split("Warm process by stage")[1].split("\n\n")[1]
    header, _, row = table.splitlines()
    cells = [c.strip() for c in row.strip("|").split("|")]
    names = [c.strip() for c in header.strip("|").split("|")]
    assert names == ["scene", "wall", "startup", *bench.VERBOSE_STAGES, "compile", "execute", "jitter"]
    assert float(cells[2]) == pytest.approx(2.0 - (0.016 + 0.177 + 0.308 + 0.780 + 0.035 + 0.027 + 0.5), abs=1e-3)
    assert cells[names.index("variant")] == "0.177" and cells[names.index("jitter")] == "0.076"
    assert cells[names.index("counts")] == "0.500"
    assert res.to_json()["verbose"]["startup"] == pytest.approx(0.157)
    assert "Warm process by stage" not in bench.report([bench.SceneResult(name="a", path="x")], {}, {})


def test_negative_verbose_runs_exit_2(capsys: pytest.CaptureFixture[str]) -> None:
    assert run_a5mi(["bench", "--verbose-runs", "-1", "scene10"]) == 2
    assert "a5mi bench: error:" in capsys.readouterr().err


@pytest.mark.parametrize(("argv", "settings"), [
    ([], bench.BenchSettings()),
    (["--size", "40", "30", "--bounces", "2", "--4k", "--no-stock", "--warm-runs", "3", "--timeout", "9"],
     bench.BenchSettings(test=bench.assignment_command(40, 30, 2), k4_scene="scene10",
                         parts=frozenset({"process", "inprocess"}), warm_runs=3, timeout=9.0)),
    (["--no-process", "--no-inprocess", "--no-stock", "--4k-scene", "scene12", "--repeat", "5"],
     bench.BenchSettings(repeat=5, parts=frozenset())),
])
def test_flags_become_the_settings(argv: list[str], settings: bench.BenchSettings, monkeypatch,
                                   capsys: pytest.CaptureFixture[str]) -> None:
    """The command's flags and their defaults are the settings the library measures with: the test command's
    options (-shadows -jitter -filter at -size and -bounces), the parts left out, the 4K scene only with --4k."""
    seen: list[bench.BenchSettings] = []
    monkeypatch.setattr(bench, "resolve_scenes", lambda scenes: [])
    monkeypatch.setattr(bench, "run_benchmark", lambda paths, s, log: seen.append(s) or
                        bench.BenchRun([], {}, {"flags": []}, 0.0))
    monkeypatch.setattr("a5mi.commands.bench.activate_variant", lambda variant: None)
    assert run_a5mi(["bench", *argv, "-q"]) == 0
    assert seen == [settings]
    assert (settings.test.shadows, settings.test.jitter, settings.test.filter) == (True, True, True)


# --------------------------------------------------------------------------------------------------------
# The kernel's ray-log mode (plugins/kernel/raylog.py), which the floor traverses
# --------------------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def logged(variant: str, scenes_dir: Path) -> dict[str, object]:
    """scene10 (two plane-set spheres, a plane, a cube; a point and a directional light) at 16x16 (48x48 camera
    rays): the counting kernel's colour and counts, then two ray-log launches of the same rays."""
    import contextlib

    import drjit as dr

    from a5mi.bench.floor import _camera_rays_for, _count_pass
    from a5mi.plugins.kernel.raylog import RayLog
    from a5mi.render.options import RenderOptions
    from a5mi.render.session import build_scene, describe_file

    with contextlib.chdir(scenes_dir):
        desc = describe_file("scene10_sphere.txt")[0]
        options = RenderOptions(width=16, height=16, bounces=4, shadows=True, jitter=True, count_rays=True)
        scene = build_scene(desc, options)
    rw, rh = options.render_size
    ray = _camera_rays_for(desc, rw, rh)
    dr.eval(ray)
    counts = _count_pass(scene, ray, rw * rh)
    integrator = scene.integrator()
    plain = integrator.trace(scene, ray, True)
    dr.eval(plain)
    out: dict[str, object] = {"counts": counts, "plain": [np.asarray(v) for v in plain], "ray": ray, "logs": []}
    for _ in range(2):
        log = RayLog(rw * rh + int(counts["reflection"].sum() + counts["refraction"].sum()),
                     int(counts["shadow"].sum()))
        res = integrator.trace(scene, ray, True, ray_log=log)
        dr.eval(res)
        out["logs"].append((log, [np.asarray(v) for v in res], *log.read()))  # type: ignore[attr-defined]
    return out


def test_ray_log_holds_every_ray_the_counts_aov_counts(logged: dict) -> None:
    from a5mi.plugins.kernel.raylog import NODE_FIELDS, SHADOW_FIELDS

    counts = logged["counts"]
    width = counts["shadow"].size
    log, _res, nodes, shadows = logged["logs"][0]
    assert tuple(nodes) == NODE_FIELDS and tuple(shadows) == SHADOW_FIELDS
    assert counts["shadow"].sum() > 0 and counts["refraction"].sum() > 0
    assert log.nodes == width + counts["reflection"].sum() + counts["refraction"].sum() == nodes["o"].shape[1]
    assert log.shadows == counts["shadow"].sum() == shadows["p"].shape[1]
    # per lane: node ordinals 0 .. 1 + n_reflection + n_refraction - 1, shadow ordinals 0 .. n_shadow - 1
    per_lane = np.bincount(nodes["lane"], minlength=width)
    assert per_lane.tolist() == (1 + counts["reflection"] + counts["refraction"]).astype(int).tolist()
    assert np.bincount(shadows["lane"], minlength=width).tolist() == counts["shadow"].astype(int).tolist()
    for fields, per in ((nodes, per_lane), (shadows, counts["shadow"].astype(int))):
        order = np.lexsort((fields["ordinal"], fields["lane"]))
        assert fields["ordinal"][order].tolist() == [k for c in per for k in range(c)]  # each once
    # the camera nodes are the camera rays themselves (tmin 0); secondary and shadow rays start at tmin
    cam = nodes["ordinal"] == 0
    ray = logged["ray"]
    lanes = nodes["lane"][cam]
    assert np.array_equal(nodes["o"][:, cam], np.asarray(ray.o)[:, lanes])
    assert np.array_equal(nodes["d"][:, cam], np.asarray(ray.d)[:, lanes])
    assert (nodes["tmin"][cam] == 0).all() and (nodes["tmin"][~cam] == np.float32(0.001)).all()
    assert (shadows["tmin"] == np.float32(0.001)).all() and (shadows["dist"] > shadows["tmin"]).all()
    assert 0 < shadows["far"].sum() < shadows["far"].size  # scene10: a directional and a point light


def test_ray_log_is_deterministic(logged: dict) -> None:
    """The entries (keyed by lane and ordinal) are the same in every launch; only the packets' order may vary
    with the threads."""
    def ordered(fields: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        order = np.lexsort((fields["ordinal"], fields["lane"]))
        return {k: v[..., order] for k, v in fields.items()}

    (_, _, n1, s1), (_, _, n2, s2) = logged["logs"]
    for a, b in ((n1, n2), (s1, s2)):
        a, b = ordered(a), ordered(b)
        assert a.keys() == b.keys()
        for k in a:
            assert a[k].tobytes() == b[k].tobytes(), k


def test_ray_log_mode_renders_the_same_bits(logged: dict) -> None:
    """The log mode's colour, normal, t, class and counts equal the plain kernel's, bit for bit."""
    for _log, res, _n, _s in logged["logs"]:
        for plain, with_log in zip(logged["plain"], res, strict=True):
            assert plain.tobytes() == with_log.tobytes()


def test_logged_floor_times_each_ray_kind_on_the_stock_scene(logged: dict, scenes_dir: Path) -> None:
    """The logged rays traverse the stock conversion, where scene10's spheres and plane are shapes."""
    import contextlib

    import mitsuba as mi

    from a5mi.bench.floor import logged_floor
    from a5mi.converters.a5_parser import parse_file
    from a5mi.converters.describe import describe
    from a5mi.converters.to_mitsuba import to_dict
    from a5mi.render.options import RenderOptions

    with contextlib.chdir(scenes_dir):
        model = parse_file("scene10_sphere.txt")
        stock = mi.load_dict(to_dict(describe(model, stock=True), RenderOptions(width=16, height=16), stock=True))
    assert len(stock.shapes()) == 4  # cube, two spheres, the plane's rectangle
    _log, _res, nodes, shadows = logged["logs"][0]
    floor = logged_floor(stock, nodes, shadows, repeat=1)
    assert set(floor) == {"camera", "secondary", "shadow"} and all(v > 0 for v in floor.values())

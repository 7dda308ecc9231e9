"""Batch renders: ``a5mi render`` with several scenes or ``--jobs`` in one process, through
:class:`a5mi.render.session.RenderSession`: images bit-identical to separate ``a5`` runs, a failing job reported in
one line without stopping the others, and kernels reused across scenes of the same kind."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np
import pytest

from a5mi import cli
from a5mi.platform.imageio import read_uint8

FLAGS = ["-size", "24", "24", "-shadows", "-bounces", "3", "-jitter", "-filter"]

SPHERES = """
PerspectiveCamera {{ center 0 1 8 direction 0 -0.1 -1 up 0 1 0 angle 30 }}
Lights {{ numLights 1 DirectionalLight {{ direction {light} color 0.9 0.9 0.9 }} }}
Background {{ color 0.1 0.2 0.3 ambientLight 0.2 0.2 0.2 }}
Materials {{ numMaterials 2
  PhongMaterial {{ diffuseColor {c1} specularColor 0.5 0.5 0.5 }}
  PhongMaterial {{ diffuseColor {c2} }} }}
Group {{ numObjects 3
  MaterialIndex 0 Sphere {{ center {p} radius 1 }}
  MaterialIndex 1 Sphere {{ center 1.5 0.5 -1 radius 0.8 }}
  MaterialIndex 1 Plane {{ normal 0 1 0 offset {off} }} }}
"""


def _scene(folder: Path, name: str, **values: str) -> Path:
    defaults = {"light": "-0.5 -0.3 -1", "c1": "1 0 0", "c2": "0 1 0", "p": "0 0 0", "off": "-1.2"}
    path = folder / name
    path.write_text(SPHERES.format(**{**defaults, **values}))
    return path


@pytest.fixture
def two_scenes(tmp_path: Path, scenes_dir: Path) -> list[Path]:
    """A course scene (meshes, marble) and a small scene of spheres and a plane, copied into tmp_path."""
    for name in ("scene11_cube.txt", "cube.obj"):
        shutil.copy(scenes_dir / name, tmp_path / name)
    (tmp_path / "tex").symlink_to(scenes_dir / "tex")
    return [tmp_path / "scene11_cube.txt", _scene(tmp_path, "spheres.txt")]


def test_batch_images_equal_separate_a5_runs(two_scenes: list[Path], tmp_path: Path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "batch").mkdir()
    assert cli.run_a5mi(["render", *map(str, two_scenes), "--output-dir", "batch", *FLAGS]) == 0
    for scene in two_scenes:
        assert cli.run(["-input", str(scene), "-output", f"{scene.stem}.png", *FLAGS]) == 0
        alone, batch = read_uint8(f"{scene.stem}.png"), read_uint8(f"batch/{scene.stem}.png")
        assert alone.shape == (24, 24, 3)
        assert np.array_equal(alone, batch), scene.name
        assert alone.std() > 0  # not a blank image


def test_jobs_with_several_flag_sets_equal_separate_runs(two_scenes: list[Path], tmp_path: Path,
                                                        monkeypatch) -> None:
    """One scene loaded once, its integrator swapped per flag set (shadows, bounces, -v's counts)."""
    monkeypatch.chdir(tmp_path)
    cube = two_scenes[0].name
    sets = [["-bounces", "0"], [], ["-reflection_off"], ["-phong"], ["-bounces", "0", "-v"]]
    lines = [" ".join(["-input", cube, "-output", f"j{k}.png", *extra]) for k, extra in enumerate(sets)]
    Path("jobs.txt").write_text("# one scene, several flag sets\n\n" + "\n".join(lines) + "\n")
    assert cli.run_a5mi(["render", "--jobs", "jobs.txt", *FLAGS]) == 0
    images = []
    for k, extra in enumerate(sets):
        assert cli.run(["-input", cube, "-output", f"a{k}.png", *FLAGS, *extra]) == 0
        images.append(read_uint8(f"j{k}.png"))
        assert np.array_equal(read_uint8(f"a{k}.png"), images[-1]), sets[k]
    assert not np.array_equal(images[0], images[1])  # the flag sets do change the image
    assert np.array_equal(images[0], images[4])  # -v adds a counting pass, not a different image


def test_a_failing_job_does_not_stop_the_others(two_scenes: list[Path], tmp_path: Path, monkeypatch,
                                               capfd) -> None:
    monkeypatch.chdir(tmp_path)
    cube, spheres = (p.name for p in two_scenes)
    Path("broken.txt").write_text("Group { numObjects 1 Sphere { center 0 0 } }\n")
    Path("jobs.txt").write_text("\n".join([
        f"-input {cube} -output ok1.png",
        "-input missing.txt -output m.png",
        f"-input {spheres} -output bad.png -size 0 4",
        f"-input {spheres} -output bad.xyz",
        "-input broken.txt -output b.png",
        f"-input {spheres} -output ok2.png -bounces 0",
    ]) + "\n")
    capfd.readouterr()
    assert cli.run_a5mi(["render", "--jobs", "jobs.txt", *FLAGS]) == 2
    err = capfd.readouterr().err.strip().splitlines()
    assert Path("ok1.png").is_file() and Path("ok2.png").is_file()
    assert sorted(os.listdir(".")) == sorted(["broken.txt", "cube.obj", "jobs.txt", "ok1.png", "ok2.png",
                                              "scene11_cube.txt", "spheres.txt", "tex"])  # nothing half-written
    assert len(err) == 5, err  # one line per failed job, then the count
    assert "missing.txt" in err[0] and "job 3 (jobs.txt:3" in err[1] and "-size" in err[1]
    assert "bad.xyz" in err[2] and err[3].startswith("broken.txt:1:")
    assert err[4] == "a5mi render: 2 of 6 jobs written" + err[4][len("a5mi render: 2 of 6 jobs written"):]
    assert "failed: job 2, 3, 4, 5" in err[4]


def test_whole_command_errors_render_nothing(two_scenes: list[Path], tmp_path: Path, monkeypatch, capfd) -> None:
    monkeypatch.chdir(tmp_path)
    cube, spheres = (p.name for p in two_scenes)
    assert cli.run_a5mi(["render", cube, spheres, *FLAGS]) == 2  # no --output-dir
    assert "--output-dir" in capfd.readouterr().err
    assert cli.run_a5mi(["render", cube, "--output-dir", ".", "-output", "x.png", *FLAGS]) == 2
    Path("jobs.txt").write_text(f"-input {cube} -output same.png\n-input {spheres} -output same.png\n")
    assert cli.run_a5mi(["render", "--jobs", "jobs.txt", *FLAGS]) == 2
    assert "same.png" in capfd.readouterr().err
    Path("jobs.txt").write_text("# nothing\n")
    assert cli.run_a5mi(["render", "--jobs", "jobs.txt"]) == 2
    assert not list(tmp_path.glob("*.png"))


def test_second_scene_of_the_same_kind_compiles_no_kernel(tmp_path: Path, variant: str) -> None:
    """Other light direction, colours and plane offset, same shapes and flags: the second scene's render
    launches only kernels already in this process's cache (dr.kernel_history, via RenderResult.kernels).
    (Mitsuba's own sphere bakes its centre into the kernel as a literal: moving a sphere compiles again.)"""
    from a5mi.render.options import RenderOptions
    from a5mi.render.session import RenderSession, describe_file

    session = RenderSession()
    options = RenderOptions(width=20, height=20, shadows=True, bounces=3, jitter=True, filter=True)
    first, _ = describe_file(str(_scene(tmp_path, "a.txt")))
    second, _ = describe_file(str(_scene(tmp_path, "b.txt", light="0.3 -0.6 -1", c1="0.2 0.3 1",
                                         c2="1 1 0", off="-1.5")))
    a = session.render(first, options)
    b = session.render(second, options)
    assert b.kernels["compiled"] == 0 and b.kernels["disk"] == 0 and b.kernels["memory"] > 0, b.kernels
    assert session.scenes_built == 2
    assert not np.array_equal(a.image, b.image)
    again = session.render(second, options)  # the cached scene: not built again, the same image
    assert session.scenes_built == 2 and again.timings["build"] == 0.0
    assert np.array_equal(again.image, b.image)
    back = session.render(first, options)  # one scene kept (max_scenes=1): built again, same kernels
    assert session.scenes_built == 3 and back.kernels["compiled"] == 0 and np.array_equal(back.image, a.image)


def test_bench_batch_ratio_and_table() -> None:
    """The bench's batch figures: ratio = median wall / median (kernel + filter + write), recompiles counted."""
    from a5mi.bench.batch import BatchScene
    from a5mi.bench.report import _batch_tables

    extra = [{"wall": w, "kernel": 0.2, "filter": 0.05, "write": 0.05, "trace_etc": 0.03, "compiled": c}
             for w, c in ((0.36, 0.0), (0.33, 1.0), (0.5, 0.0))]
    b = BatchScene("scene11_cube", first=0.9, extra=extra)
    assert b.median("wall") == 0.36 and abs(b.base - 0.3) < 1e-12 and abs(b.ratio - 1.2) < 1e-12
    assert b.recompiled == 1
    text = "\n".join(_batch_tables({"batch": [b]}))
    assert "| scene11_cube |" in text and "1.200" in text and "1/3" in text
    assert BatchScene("empty").ratio is None


MESHES = """
PerspectiveCamera {{ center 0 1 8 direction 0 -0.1 -1 up 0 1 0 angle 30 }}
Lights {{ numLights 1 PointLight {{ position {light} color 0.9 0.9 0.9 }} }}
Background {{ color 0.1 0.2 0.3 ambientLight 0.2 0.2 0.2 }}
Materials {{ numMaterials 2
  PhongMaterial {{ diffuseColor 1 0 0 specularColor 0.5 0.5 0.5 }}
  PhongMaterial {{ diffuseColor 0 1 0 }} }}
Group {{ numObjects 2
  MaterialIndex 0 Transform {{ Translate {t} TriangleMesh {{ obj_file cube.obj }} }}
  MaterialIndex 1 Plane {{ normal 0 1 0 offset -1.2 }} }}
"""


def test_mesh_scenes_of_the_same_kind_share_the_kernel_with_the_triangle_rule(tmp_path: Path, scenes_dir: Path,
                                                                               variant: str) -> None:
    """The binary's triangle test reads a per-scene table (plugins/emulation/triangle_rule.py) whose values and length
    are kernel inputs: another placement of the mesh and another light position launch the cached kernel;
    the images are those of separate ``a5`` runs. (Not the same kind, measured: another number of shapes,
    whose vcalls Mitsuba compiles per shape; and, in mesh scenes only, another *directional* light, which
    compiles again without the triangle rule too.)"""
    from a5mi.render.options import RenderOptions
    from a5mi.render.session import RenderSession, describe_file

    shutil.copy(scenes_dir / "cube.obj", tmp_path / "cube.obj")
    a_txt, b_txt = tmp_path / "a.txt", tmp_path / "b.txt"
    a_txt.write_text(MESHES.format(light="-2 3 4", t="0 0 0"))
    b_txt.write_text(MESHES.format(light="1 4 3", t="0.5 0.2 -1"))
    session = RenderSession()
    options = RenderOptions(width=20, height=20, shadows=True, bounces=3)
    a = session.render(describe_file(str(a_txt))[0], options)
    b = session.render(describe_file(str(b_txt))[0], options)
    assert b.kernels["compiled"] == 0 and b.kernels["disk"] == 0 and b.kernels["memory"] > 0, b.kernels
    from a5mi.platform.imageio import write_images

    for txt, result in ((a_txt, a), (b_txt, b)):
        out, ours = tmp_path / f"{txt.stem}.png", tmp_path / f"{txt.stem}.session.png"
        assert cli.run(["-input", str(txt), "-output", str(out), "-size", "20", "20", "-shadows",
                        "-bounces", "3"]) == 0
        write_images([(ours, result.image)])
        assert np.array_equal(read_uint8(out), read_uint8(ours))
    assert not np.array_equal(read_uint8(tmp_path / "a.png"), read_uint8(tmp_path / "b.png"))

"""The a5 / a5mi commands: flags (SPEC B.1), the error policy (issue 8), outputs written last and atomically.

Rendering is replaced by a stand-in ``driver.render`` (and ``variant.activate``) in most tests so they run
without a JIT; ``test_b1_real_render_*`` goes through the real converter, plugins and driver.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from a5mi import cli, driver, imageio
from a5mi.errors import UsageError


@pytest.fixture
def scene(scenes_dir: Path) -> str:
    return str(scenes_dir / "scene11_cube.txt")


@pytest.fixture
def fake_render(monkeypatch):
    """Stand-in for driver.render: a gradient image of the saved size, AOVs at render size."""
    calls: list[driver.RenderOptions] = []

    def render(scene_model, options, *, progress=None):
        calls.append(options)
        rw, rh = options.render_size
        color = np.zeros((rh, rw, 3), np.float32)
        color[..., 0] = np.linspace(0, 1, rw, dtype=np.float32)[None, :]
        image = driver.postprocess(color, filter=options.filter, kernel=options.kernel)
        if progress:
            progress(rw * rh, rw * rh)
        return driver.RenderResult(
            image=image, normals=np.full((rh, rw, 3), 0.5, np.float32) if options.normals else None,
            depth=np.full((rh, rw, 3), 0.25, np.float32) if options.depth else None,
            render_size=(rw, rh), camera_rays=rw * rh, tiles=1, timings={"render": 0.0},
        )

    monkeypatch.setattr(driver, "render", render)
    monkeypatch.setattr("a5mi.variant.activate", lambda requested=None: "stand-in")
    return calls


def _one_error_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert "Traceback" not in err
    return lines[0]


# ---------------------------------------------------------------- flags


def test_b1_flags_any_order_and_defaults() -> None:
    a = cli.parse_a5_args(["-output", "o.png", "-shadows", "-input", "s.txt", "-jittered"])
    assert (a.input, a.output, a.width, a.height, a.bounces) == ("s.txt", "o.png", 100, 100, 4)
    assert a.shadows and a.jitter and not a.filter and a.reflection and a.refraction
    b = cli.parse_a5_args(["-size", "60", "40", "-bounces", "0", "-input", "s.txt", "-output", "o.png",
                           "-depth", "1", "2.5", "d.png", "-normals", "n.png", "-reflection_off",
                           "-refraction_off", "-seed", "3", "-fresnel", "exact", "-kernel", "handout",
                           "-threads", "2", "-phong", "-variant", "llvm", "-filter", "-bounces", "2",
                           "-normals_mode", "quadrant"])
    assert (b.width, b.height, b.bounces, b.depth, b.depth_output, b.normals_output) == (
        60, 40, 2, (1.0, 2.5), "d.png", "n.png")
    assert not b.reflection and not b.refraction and b.filter and b.phong
    assert (b.seed, b.fresnel, b.kernel, b.threads, b.variant) == (3, "exact", "handout", 2, "llvm")
    assert b.aov_mode == "quadrant"


@pytest.mark.parametrize(
    "argv,message",
    [
        (["-input", "s.txt"], "missing -output IMG"),
        (["-input", "s.txt", "-output", "o.png", "--size", "3", "3"], "unknown flag '--size'"),
        (["-input", "s.txt", "-output=o.png"], "unknown flag '-output=o.png'"),
        (["-output", "o.png"], "missing -input SCENE.txt"),
        (["-input", "s.txt", "-output", "o.png", "-frobnicate"], "unknown flag '-frobnicate'"),
        (["-input", "s.txt", "-output", "o.png", "stray"], "unexpected argument 'stray'"),
        (["-input", "s.txt", "-output", "o.png", "-size", "0", "5"], "-size expects an integer in [1, 16384], found 0"),
        (["-input", "s.txt", "-output", "o.png", "-size", "99999", "5"], "found 99999"),
        (["-input", "s.txt", "-output", "o.png", "-size", "3x", "5"], "-size expects an integer, found '3x'"),
        (["-input", "s.txt", "-output", "o.png", "-size", "5"], "-size expects 2 values, found end of arguments"),
        (["-input", "s.txt", "-output", "o.png", "-bounces", "-1"], "-bounces expects an integer in [0, 64]"),
        (["-input", "s.txt", "-output", "o.png", "-depth", "nan", "1", "d.png"], "finite number"),
        (["-input", "s.txt", "-output", "o.png", "-fresnel", "fast"], "-fresnel expects one of a5, schlick, exact"),
        (["-input", "s.txt", "-output", "o.png", "-filter", "-size", "2", "9"], "too small"),
        (["-input", "s.txt", "-output", "o.png", "-jitter", "-size", "16384", "16384"], "the limit is 268435456"),
        (["-input", "s.txt", "-output", "o.png", "-normals_mode", "half"], "-normals_mode expects one of main"),
    ],
)
def test_b1_usage_errors(argv, message, capsys) -> None:
    with pytest.raises(UsageError, match=None) as info:
        cli.parse_a5_args(argv)
    assert message in str(info.value)
    assert cli.run(argv) == 2
    line = _one_error_line(capsys.readouterr().err)
    assert line.startswith("a5: error: ") and message in line


def test_b1_help(capsys) -> None:
    assert cli.run(["-h"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("usage: a5 -input") and "-jitter" in out


# ---------------------------------------------------------------- rendering with the stand-in


@pytest.mark.parametrize(
    "flags,size", [([], (30, 20)), (["-jitter"], (90, 60)), (["-filter"], (10, 6)), (["-jitter", "-filter"], (30, 20))]
)
def test_b5_output_sizes(tmp_path, scene, fake_render, flags, size) -> None:
    out = tmp_path / "o.png"
    assert cli.run(["-input", scene, "-size", "30", "20", "-output", str(out)] + flags) == 0
    img = imageio.read_image(out)
    assert (img.shape[1], img.shape[0]) == size


def test_b1_all_outputs_written(tmp_path, scene, fake_render, capsys) -> None:
    out, nrm, dep = tmp_path / "o.tga", tmp_path / "n.bmp", tmp_path / "d.exr"
    rc = cli.run(["-input", scene, "-output", str(out), "-normals", str(nrm), "-depth", "0", "5", str(dep),
                  "-size", "4", "4", "-jitter", "-v"])
    assert rc == 0
    assert imageio.read_image(out).shape == (12, 12, 3)
    assert np.all(imageio.read_image(nrm) == np.float32(127) / np.float32(255))
    assert np.all(imageio.read_image(dep) == 0.25)
    err = capsys.readouterr().err
    assert "peak memory" in err and "camera rays" in err
    opts = fake_render[0]
    assert opts.normals and opts.depth == (0.0, 5.0) and opts.jitter


def test_b1_outputs_checked_before_rendering(tmp_path, scene, fake_render, capsys) -> None:
    good = tmp_path / "o.png"
    for bad in (["-normals", str(tmp_path / "n.jpgx")], ["-depth", "0", "1", str(tmp_path / "no" / "d.png")]):
        assert cli.run(["-input", scene, "-output", str(good)] + bad) == 2
        assert "a5: error: " in _one_error_line(capsys.readouterr().err)
    assert fake_render == [] and not good.exists()


def test_b1_internal_error_keeps_old_outputs(tmp_path, scene, monkeypatch, capsys) -> None:
    out = tmp_path / "o.png"
    out.write_bytes(b"previous")

    def broken(*a, **kw):
        raise RuntimeError("kernel exploded\nsecond line")

    monkeypatch.setattr(driver, "render", broken)
    monkeypatch.setattr("a5mi.variant.activate", lambda requested=None: "stand-in")
    assert cli.run(["-input", scene, "-output", str(out)]) == 1
    line = _one_error_line(capsys.readouterr().err)
    assert line == "a5: internal error: RuntimeError: kernel exploded (re-run with --debug for the traceback)"
    assert out.read_bytes() == b"previous"
    assert cli.run(["-input", scene, "-output", str(out), "--debug"]) == 1
    assert "Traceback" in capsys.readouterr().err


def test_b1_scene_error_is_one_positioned_line(tmp_path, fake_render, capsys) -> None:
    bad = tmp_path / "bad.txt"
    bad.write_text("PerspectiveCamera {\n  center 0 0 oops\n}\n")
    out = tmp_path / "o.png"
    assert cli.run(["-input", str(bad), "-output", str(out)]) == 2
    line = _one_error_line(capsys.readouterr().err)
    assert line.startswith(f"{bad}:2:") and ": error: " in line
    assert not out.exists() and fake_render == []


def test_b1_missing_scene(tmp_path, fake_render, capsys) -> None:
    assert cli.run(["-input", str(tmp_path / "none.txt"), "-output", str(tmp_path / "o.png")]) == 2
    assert ": error: " in _one_error_line(capsys.readouterr().err)


def test_b1_syntax_errors_do_not_load_mitsuba(tmp_path) -> None:
    """Subprocess: the real command, a scene syntax error, exit 2, one line, and Mitsuba never imported."""
    bad = tmp_path / "bad.txt"
    bad.write_text("Group { numObjects 1x }")
    code = ("import sys; from a5mi.cli import run; rc = run(sys.argv[1:]); "
            "sys.stdout.write(str('mitsuba' in sys.modules)); sys.exit(rc)")
    p = subprocess.run([sys.executable, "-c", code, "-input", str(bad), "-output", str(tmp_path / "o.png")],
                       capture_output=True, text=True)
    assert p.returncode == 2 and p.stdout == "False"
    assert _one_error_line(p.stderr).startswith(f"{bad}:1:")
    assert not (tmp_path / "o.png").exists()


def test_b1_python_m_entry(tmp_path) -> None:
    p = subprocess.run([sys.executable, "-m", "a5mi", "-input", "x.txt"], capture_output=True, text=True)
    assert p.returncode == 2 and _one_error_line(p.stderr) == "a5: error: missing -output IMG"


# ---------------------------------------------------------------- a5mi


def test_a5mi_dispatch(tmp_path, scene, fake_render, capsys) -> None:
    assert cli.run_a5mi(["frob"]) == 2
    assert "unknown command 'frob'" in _one_error_line(capsys.readouterr().err)
    assert cli.run_a5mi([]) == 2 and "render" in capsys.readouterr().err  # usage after a mistake: stderr
    assert cli.run_a5mi(["-h"]) == 0
    listed = capsys.readouterr().out
    for name in cli.SUBCOMMANDS:
        assert f"  {name} " in listed
        assert cli.command(name).name == name  # every entry resolves to its Command
    out = tmp_path / "r.png"
    assert cli.run_a5mi(["render", "-input", scene, "-output", str(out), "-size", "7", "5"]) == 0
    assert imageio.read_image(out).shape == (5, 7, 3)


def test_a5mi_convert(tmp_path, scene, monkeypatch, capsys, variant) -> None:
    """Flag handling with a stand-in write_xml (the real one is exercised in test_a5mi_convert_real)."""
    written = []
    fake = type(sys)("a5mi.converters.to_xml")
    fake.write_xml = lambda desc, path, options=None, *, stock=False: written.append((desc, path, stock))
    monkeypatch.setitem(sys.modules, "a5mi.converters.to_xml", fake)
    assert cli.run_a5mi(["convert", scene, "-o", str(tmp_path / "s.xml"), "--stock"]) == 0
    (model, path, stock), = written
    assert path == str(tmp_path / "s.xml") and stock and model.camera.angle > 0
    assert "warning: stock conversion: the ambient term" in capsys.readouterr().err  # conversion warnings shown
    for argv, msg in [([scene], "missing -o OUT.xml"), (["-o", "x.xml"], "missing SCENE.txt"),
                      ([scene, "-o", "x.png"], "must end in .xml"), ([scene, "-o", "no/x.xml"], "does not exist")]:
        assert cli.run_a5mi(["convert"] + argv) == 2
        assert msg in _one_error_line(capsys.readouterr().err)


# ---------------------------------------------------------------- the real pipeline


def test_b1_real_render_small(tmp_path, scenes_dir, monkeypatch, variant, capsys) -> None:
    """scene11 at 30x20 -jitter -filter through the real converter, plugins and driver."""
    monkeypatch.chdir(scenes_dir)  # SPEC A.0: relative mesh paths resolve against the working directory
    out = tmp_path / "cube.png"
    rc = cli.run(["-input", "scene11_cube.txt", "-size", "30", "20", "-output", str(out), "-shadows", "-jitter",
                  "-filter", "-v"])
    err = capsys.readouterr().err
    assert rc == 0, err
    img = imageio.read_image(out)
    assert img.shape == (20, 30, 3) and img.max() > 0
    assert "peak memory" in err and "camera rays" in err


@pytest.mark.slow
@pytest.mark.parametrize("name", ["scene06_bunny_1k", "scene10_sphere", "scene11_cube", "scene12_vase"])
def test_b5_assignment_commands(tmp_path, scenes_dir, monkeypatch, variant, name) -> None:
    """The assignment's test command (README) writes a 300x300 PNG. (Fidelity against a5soln's renders is
    the fidelity harness's job, tests/test_reference.py.)"""
    monkeypatch.chdir(scenes_dir)
    out = tmp_path / f"{name}.png"
    rc = cli.run(["-input", f"{name}.txt", "-size", "300", "300", "-output", str(out), "-shadows", "-bounces", "4",
                  "-jitter", "-filter"])
    assert rc == 0
    img = imageio.read_image(out)
    assert img.shape == (300, 300, 3) and img.std() > 0.01  # a picture, not a constant


def test_a5mi_convert_real(tmp_path, scenes_dir, monkeypatch, variant) -> None:
    pytest.importorskip("a5mi.converters.to_xml")
    monkeypatch.chdir(scenes_dir)
    out = tmp_path / "cube.xml"
    assert cli.run_a5mi(["convert", "scene11_cube.txt", "-o", str(out)]) == 0
    text = out.read_text()
    assert text.lstrip().startswith("<") and "a5_whitted" in text

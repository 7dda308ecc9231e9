"""The a5 / a5mi commands: flags (SPEC B.1), the error policy (docs/CLI.md), outputs written last and atomically.

Rendering is replaced by a stand-in ``session.render`` (and ``variant.activate``) in most tests so they run
without a JIT; ``test_b1_real_render_*`` goes through the real converter, plugins and driver.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from a5mi import cli
from a5mi.platform import imageio
from a5mi.platform.errors import ExitStatus, UsageError
from a5mi.render import driver, session
from a5mi.render.filters import postprocess
from a5mi.render.options import RenderOptions


@pytest.fixture
def scene(scenes_dir: Path) -> str:
    return str(scenes_dir / "scene11_cube.txt")


@pytest.fixture
def fake_render(monkeypatch):
    """Stand-in for session.render: a gradient image of the saved size, AOVs at render size."""
    calls: list[RenderOptions] = []

    def render(scene_model, options, *, progress=None):
        calls.append(options)
        rw, rh = options.render_size
        color = np.zeros((rh, rw, 3), np.float32)
        color[..., 0] = np.linspace(0, 1, rw, dtype=np.float32)[None, :]
        image = postprocess(color, filter=options.filter, kernel=options.kernel)
        if progress:
            progress(rw * rh, rw * rh)
        return driver.RenderResult(
            image=image, normals=np.full((rh, rw, 3), 0.5, np.float32) if options.normals else None,
            depth=np.full((rh, rw, 3), 0.25, np.float32) if options.depth else None,
            render_size=(rw, rh), camera_rays=rw * rh, tiles=1, timings={"render": 0.0},
        )

    monkeypatch.setattr(session, "render", render)
    monkeypatch.setattr("a5mi.runtime.variant.activate", lambda requested=None: "stand-in")
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

    monkeypatch.setattr(session, "render", broken)
    monkeypatch.setattr("a5mi.runtime.variant.activate", lambda requested=None: "stand-in")
    assert cli.run(["-input", scene, "-output", str(out)]) == ExitStatus.SOFTWARE == 70
    line = _one_error_line(capsys.readouterr().err)
    assert line == "a5: internal error: RuntimeError: kernel exploded (re-run with --debug for the traceback)"
    assert out.read_bytes() == b"previous"
    assert cli.run(["-input", scene, "-output", str(out), "--debug"]) == ExitStatus.SOFTWARE
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
    assert cli.run_a5mi([]) == 2 and "render" in capsys.readouterr().err  # a usage error: on stderr
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
    fake.write_xml = lambda desc, path, options=None, *, stock=False, spp=None: written.append((desc, path, stock))
    fake.check_replaceable = lambda folder: None
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
    the fidelity harness's job, tests/fidelity/test_reference.py.)"""
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


# ---------------------------------------------------------------- the command layer


@pytest.mark.parametrize("name", ["a5", *cli.SUBCOMMANDS])
def test_every_command_has_help_with_one_line_per_flag(name: str, capsys) -> None:
    command = cli.command(name) if name != "a5" else __import__("a5mi.commands.render", fromlist=["A5"]).A5
    rc = cli.run(["-h"]) if name == "a5" else cli.run_a5mi([name, "--help"])
    out = capsys.readouterr().out
    assert rc == 0 and out.startswith(f"usage: {command.prog}")
    lines = out.splitlines()
    for flag in command.all_flags:
        spelled = [ln for ln in lines if ln.strip() and ln.split()[0].rstrip(",") == flag.names[0]]
        assert len(spelled) == 1, f"{name}: {flag.names[0]} should have exactly one help line"
        default = flag.default if not isinstance(flag.default, tuple) else flag.default[0]
        if flag.show_default and flag.nargs and default is not None:
            assert "(default: " in spelled[0], spelled[0]


def test_help_command_prints_that_commands_help(capsys) -> None:
    """``a5mi help convert`` is ``a5mi convert -h``; ``a5mi help`` alone is the top-level usage."""
    assert cli.run_a5mi(["help", "convert"]) == ExitStatus.OK
    via_help = capsys.readouterr().out
    assert cli.run_a5mi(["convert", "-h"]) == ExitStatus.OK
    assert via_help == capsys.readouterr().out and via_help.startswith("usage: a5mi convert ")
    assert cli.run_a5mi(["help"]) == ExitStatus.OK
    assert capsys.readouterr().out.startswith("usage: a5mi COMMAND")


def test_trace_offers_no_image_outputs(capsys) -> None:
    """trace writes no image: -h offers neither -output nor -normals / -depth / -normals_mode, and they are
    refused as unknown flags."""
    from a5mi.commands.trace import TRACE

    names = {n for f in TRACE.all_flags for n in f.names}
    assert names.isdisjoint({"-output", "--output", "-normals", "-depth", "-normals_mode"})
    assert {"-input", "-size", "-jitter", "-filter", "--pixel"} <= names
    assert cli.run_a5mi(["trace", "-h"]) == ExitStatus.OK
    assert "-output" not in capsys.readouterr().out
    assert cli.run_a5mi(["trace", "-input", "s.txt", "-pixel", "0", "0", "-output", "o.png"]) == ExitStatus.USAGE
    assert "unknown flag '-output'" in _one_error_line(capsys.readouterr().err)


def test_shared_flags_mean_one_thing(capsys) -> None:
    """--size is W H (<= MAX_SIZE) wherever it exists, --json a switch, --json-file a FILE (docs/CLI.md)."""
    from a5mi.spec import MAX_SIZE

    for name in ["a5", *cli.SUBCOMMANDS]:
        cmd = __import__("a5mi.commands.render", fromlist=["A5"]).A5 if name == "a5" else cli.command(name)
        for f in cmd.all_flags:
            if "--size" in f.names:
                assert (f.nargs, f.dests, f.metavar) == (2, ("width", "height"), "W H"), name
                f.convert("--size", ["1", str(MAX_SIZE)])
                with pytest.raises(UsageError):
                    f.convert("--size", ["1", str(MAX_SIZE + 1)])
            if "--json" in f.names:
                assert f.nargs == 0, name
            if "--json-file" in f.names:
                assert f.nargs == 1 and f.metavar == "FILE", name


def test_version_from_the_one_version_source(capsys) -> None:
    from importlib.metadata import version

    from a5mi import __version__

    assert version("a5mi") == __version__  # pyproject reads a5mi.__version__
    assert cli.run(["--version"]) == 0 and cli.run_a5mi(["--version"]) == 0
    assert cli.run_a5mi(["compare", "--version"]) == 0
    assert capsys.readouterr().out.split() == ["a5", __version__, "a5mi", __version__, "a5mi", "compare",
                                               __version__]


def test_gnu_flags_with_a5_aliases_and_errors_named_by_sub_command(capsys) -> None:
    from a5mi.commands.render import RENDER

    a = RENDER.parse(["--input=s.txt", "-output", "o.png", "--size", "7", "5", "--bounces=2", "-jitter"])
    assert (a.input, a.output, a.width, a.height, a.bounces, a.jitter) == ("s.txt", "o.png", 7, 5, 2, True)
    assert cli.run_a5mi(["render", "--input", "s.txt"]) == 2
    assert _one_error_line(capsys.readouterr().err) == "a5mi render: error: missing -output IMG"
    assert cli.run_a5mi(["render", "--shadows=yes", "--input", "s.txt", "--output", "o.png"]) == 2
    assert "a5mi render: error: --shadows takes no value" in _one_error_line(capsys.readouterr().err)
    assert cli.run(["-size", "1_0", "10", "-input", "s.txt", "-output", "o.png"]) == 2
    assert "-size expects an integer, found '1_0'" in _one_error_line(capsys.readouterr().err)


def test_render_options_come_from_the_flag_table_without_hand_copying() -> None:
    """Every RenderOptions field a flag can set is set by the flag of that name (one options object)."""
    import dataclasses

    from a5mi.commands.render import RENDER_FLAGS, render_options

    args = cli.parse_a5_args(["-input", "s.txt", "-output", "o.png", "-size", "6", "3", "-shadows", "-bounces", "7",
                              "-jitter", "-filter", "-seed", "5", "-phong", "-fresnel", "exact", "-kernel", "handout",
                              "-normals", "n.png", "-depth", "1", "2", "d.png", "-reflection_off", "-threads", "3",
                              "-normals_mode", "quadrant", "-v"])
    o = render_options(args)
    assert (o.width, o.height, o.bounces, o.seed, o.fresnel, o.kernel, o.threads, o.aov_mode) == (
        6, 3, 7, 5, "exact", "handout", 3, "quadrant")
    assert o.shadows and o.jitter and o.filter and o.phong and o.normals and o.count_rays and not o.reflection
    assert o.depth == (1.0, 2.0) and o.refraction
    fields = {f.name for f in dataclasses.fields(type(o))}
    dests = {d for f in RENDER_FLAGS for d in f.dests}
    assert fields - dests == {"normals", "count_rays", "tile_rays", "classes"}  # derived, or not a flag


@pytest.mark.parametrize("argv", [["-h"], ["--help"]])
def test_closed_pipe_is_quiet(argv) -> None:
    """``a5 -h | head -c 0``: the reader is gone before the help is written; no traceback, status 141."""
    p = subprocess.Popen([sys.executable, "-m", "a5mi", *argv], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    assert p.stdout is not None and p.stderr is not None
    p.stdout.close()
    err = p.stderr.read().decode()
    assert p.wait(timeout=60) == 141 and err == ""


def test_course_data_is_found_by_a5_data_then_the_documented_places(tmp_path, monkeypatch, capsys) -> None:
    import a5mi

    monkeypatch.setenv("A5_DATA", str(tmp_path / "nowhere"))
    assert a5mi.data_candidates() == [tmp_path / "nowhere"]
    for argv in (["fidelity"], ["bench", "--no-process", "--no-inprocess"]):
        assert cli.run_a5mi(argv) == 2
        line = _one_error_line(capsys.readouterr().err)
        assert "course data not found (looked in" in line and "set A5_DATA" in line, line
        assert line.endswith('(see docs/INSTALL.md "The course data")'), line
    (tmp_path / "shared" / "a5").mkdir(parents=True)
    (tmp_path / "shared" / "a5" / "SPEC.md").write_text("x")
    monkeypatch.delenv("A5_DATA")
    monkeypatch.chdir(tmp_path)
    assert (tmp_path / "shared" / "a5").resolve() in a5mi.data_candidates()
    if not (a5mi.PROJECT_ROOT.parent / "shared" / "a5" / "SPEC.md").is_file():
        assert a5mi.data_dir() == (tmp_path / "shared" / "a5").resolve()


def test_bash_completion_is_generated_from_the_flag_tables(tmp_path) -> None:
    script = tmp_path / "a5mi.bash"
    code = "from a5mi.cli import run_a5mi; raise SystemExit(run_a5mi(['completion', 'bash']))"
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    script.write_text(p.stdout)

    def complete(*words: str) -> list[str]:
        words_sh = " ".join(f"'{w}'" for w in words)
        out = subprocess.run(["bash", "-c", f"source {script}; COMP_WORDS=({words_sh}); COMP_CWORD={len(words) - 1}; "
                              "_a5mi_complete; printf '%s\\n' \"${COMPREPLY[@]}\""],
                             capture_output=True, text=True, check=True, cwd=tmp_path)
        return out.stdout.split()

    assert complete("a5mi", "comp") == ["compare", "completion"]
    assert complete("a5mi", "compare", "--th") == ["--threshold"]
    assert complete("a5", "-sha") == ["-shadows"]
    assert complete("a5", "--si") == []           # the a5 grammar has no GNU spellings
    assert complete("a5mi", "render", "--si") == ["--size"]


def test_verbose_times_the_plain_kernel_and_counts_rays_in_a_second_pass(tmp_path, scenes_dir, monkeypatch,
                                                                         variant, capsys) -> None:
    """-v must not change the timed kernel (counting is a different kernel), and a log that is not a
    terminal never gets a carriage-return progress bar."""
    seen: list[RenderOptions] = []
    real = session.render

    def spy(desc, options, **kw):
        seen.append(options)
        return real(desc, options, **kw)

    monkeypatch.setattr(session, "render", spy)
    monkeypatch.chdir(scenes_dir)
    out = tmp_path / "o.png"
    assert cli.run(["-input", "scene10_sphere.txt", "-size", "12", "12", "-output", str(out), "-shadows",
                    "-jitter", "-filter", "-v"]) == 0
    err = capsys.readouterr().err
    assert "\r" not in err and "secondary rays reflection" in err
    assert [o.count_rays for o in seen] == [False, True]  # the timed render, then the counting pass
    counted = real(session.describe_file("scene10_sphere.txt")[0], seen[1])
    assert f"reflection {counted.ray_counts['reflection']}," in err

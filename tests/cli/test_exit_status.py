"""The one exit-status policy (:class:`a5mi.platform.errors.ExitStatus`, docs/CLI.md "Exit status") for every command.

For ``a5`` and every sub-command of :data:`a5mi.cli.SUBCOMMANDS`, in process through the command layer's entry
functions (``cli.run`` / ``cli.run_a5mi``): ``-h`` is 0 and prints one ``Exit status:`` paragraph made from the
one table; an unknown flag is 2 with one line; a function the command calls raising ``RuntimeError`` is 70
with the one ``internal error`` line. The commands that give a verdict answer 1 for "differ / fail" and 0 for
"same / pass" (their libraries replaced by stand-ins returning chosen figures, so no JIT runs). ``grade`` and
``difftest`` are checked here for ``-h``, usage and internal errors only.
"""

from __future__ import annotations

import math
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest
from helpers import ROOT

from a5mi import cli
from a5mi.cli.app import EXIT_STATUS_TABLE, exit_status_help
from a5mi.compare import Metrics
from a5mi.platform.errors import ExitStatus, UserError

COMMANDS = ["a5", *cli.SUBCOMMANDS]


def _command(name: str) -> Any:
    from a5mi.commands.render import A5

    return A5 if name == "a5" else cli.command(name)


def _run(name: str, argv: list[str]) -> int:
    return cli.run(argv) if name == "a5" else cli.run_a5mi([name, *argv])


def _one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


def _metrics(psnr: float = math.inf, share_over: float = 0.0, max_error: float = 0.0) -> Metrics:
    return Metrics(psnr=psnr, mean_error=0.0, share_over=share_over, max_error=max_error, bbox=None, threshold=2.0,
                   width=4, height=4)


# ------------------------------------------------------------------------------------------ the table
def test_the_table_has_one_row_per_status_of_the_enum() -> None:
    """Every :class:`ExitStatus` value is a row of :data:`EXIT_STATUS_TABLE` (the signals as ``128+N``), in
    ascending order, and the table holds nothing else."""
    rows = [status for status, _ in EXIT_STATUS_TABLE]
    assert rows == ["0", "1", "2", "70", "128+N", "141"]
    for status in ExitStatus:
        assert str(int(status)) in rows or 128 < status < ExitStatus.BROKEN_PIPE, status
    assert (ExitStatus.OK, ExitStatus.DIFFER, ExitStatus.USAGE, ExitStatus.SOFTWARE) == (0, 1, 2, 70)
    assert ExitStatus.signal(2) == ExitStatus.INTERRUPTED == 130 and ExitStatus.BROKEN_PIPE == 128 + 13


def test_docs_cli_carries_the_table() -> None:
    """docs/CLI.md holds the table as Markdown, row for row as the command layer prints it."""
    text = (ROOT / "docs" / "CLI.md").read_text(encoding="utf-8")
    for status, meaning in EXIT_STATUS_TABLE:
        assert f"| {status} | {meaning} |" in text, (status, meaning)
    for name in cli.SUBCOMMANDS:
        assert f"| `a5mi {name}` |" in text, name


def test_a5mi_alone_and_unknown_command_are_usage_errors(capsys) -> None:
    assert cli.run_a5mi([]) == ExitStatus.USAGE
    assert "exit status" in capsys.readouterr().err
    assert cli.run_a5mi(["frob"]) == ExitStatus.USAGE
    assert _one_line(capsys.readouterr().err).startswith("a5mi: error: unknown command 'frob'")
    assert cli.run_a5mi(["help", "frob"]) == ExitStatus.USAGE
    assert cli.run_a5mi(["--help"]) == ExitStatus.OK
    out = capsys.readouterr().out
    for status, meaning in EXIT_STATUS_TABLE:
        assert f"  {status:<12}{meaning}" in out


# ------------------------------------------------------------------------------------------ -h and usage
@pytest.mark.parametrize("name", COMMANDS)
def test_help_is_0_with_one_exit_status_paragraph(name: str, capsys) -> None:
    cmd = _command(name)
    assert _run(name, ["-h"]) == ExitStatus.OK
    out = capsys.readouterr().out
    assert out.count("Exit status:") == 1 and out.lower().count("exit status") == 1, out
    paragraph = exit_status_help(cmd.exit_ok, cmd.exit_differ, cmd.exit_note)
    assert out.rstrip().endswith(paragraph), out
    assert ("; 1 " in paragraph.replace("\n", " ")) == (cmd.exit_differ is not None)
    for status, meaning in EXIT_STATUS_TABLE[2:]:
        assert f"{status} {meaning}" in " ".join(paragraph.split())


@pytest.mark.parametrize("name", COMMANDS)
def test_usage_error_is_2_with_one_line(name: str, capsys) -> None:
    assert _run(name, ["--no-such-flag"]) == ExitStatus.USAGE
    prog = "a5" if name == "a5" else f"a5mi {name}"
    assert _one_line(capsys.readouterr().err).startswith(f"{prog}: error: unknown flag '--no-such-flag'")


# ------------------------------------------------------------------------------------------ internal errors
def _internal_cases(tmp: Path, scene: str) -> dict[str, tuple[list[str], str]]:
    """Per command: an argument list that gets past the checks, and a function it calls (patched to raise)."""
    render = (["-input", scene, "-output", str(tmp / "o.png"), "-size", "4", "4"], "a5mi.commands.render.load_scene")
    return {
        "a5": render,
        "render": render,
        "convert": ([scene, "-o", str(tmp / "s.xml")], "a5mi.commands.convert.load_scene"),
        "compare": ([str(tmp / "a.png"), str(tmp / "b.png")], "a5mi.platform.imageio.read_levels"),
        "fidelity": ([], "a5mi.fidelity.cases"),
        "crosscheck": ([scene, "-o", str(tmp / "m.png")], "a5mi.commands.crosscheck.load_scene"),
        "converge": ([scene], "a5mi.commands.converge.load_scene"),
        "bench": (["--no-process", "--no-inprocess"], "a5mi.bench.resolve_scenes"),
        "grade": ([str(tmp / "subs"), "-o", str(tmp / "report")], "a5mi.commands.grade.settings_of"),
        "render-xml": ([str(tmp / "s.xml"), "-o", str(tmp / "o.png")], "a5mi.platform.imageio.check_output_path"),
        "completion": (["bash"], "a5mi.commands.completion.bash_script"),
        "difftest": (["--binary", str(tmp / "a5")], "a5mi.difftest.runner.check_binary"),
        "trace": (["-input", scene, "-size", "4", "4", "-pixel", "0", "0"], "a5mi.commands.trace.load_scene"),
        "animate": ([scene, "-o", str(tmp / "frames")], "a5mi.cli.app.load_scene"),
        "photons": ([scene, "-o", str(tmp / "m.png")], "a5mi.commands.photons.load_scene"),
        "view": ([scene, "-size", "4", "4"], "a5mi.commands.view.activate_variant"),
        "serve": (["--socket", str(tmp / "s.sock")], "a5mi.commands.serve._warm"),
        "simulate": (["smoke", "-o", str(tmp / "grids"), "--frames", "1"], "a5mi.simulate.smoke.write_frames"),
        "diagnose": ([str(tmp / "a.png"), "-input", scene, "-size", "4", "4"], "a5mi.platform.imageio.read_uint8"),
    }


def test_internal_cases_cover_every_command(tmp_path: Path) -> None:
    assert sorted(_internal_cases(tmp_path, "s.txt")) == sorted(COMMANDS)


def _raise(*args: object, **kwargs: object) -> Any:
    raise RuntimeError("induced failure")


@pytest.mark.parametrize("name", COMMANDS)
def test_internal_error_is_70_with_one_line(name: str, tmp_path: Path, scenes_dir: Path, monkeypatch,
                                            capsys) -> None:
    monkeypatch.chdir(tmp_path)
    argv, target = _internal_cases(tmp_path, str(scenes_dir / "scene11_cube.txt"))[name]
    monkeypatch.setattr(target, _raise)
    assert _run(name, argv) == ExitStatus.SOFTWARE == 70
    prog = "a5" if name == "a5" else f"a5mi {name}"
    assert _one_line(capsys.readouterr().err) == (f"{prog}: internal error: RuntimeError: induced failure (re-run "
                                                  "with --debug for the traceback)")


def test_console_script_exits_with_the_status(tmp_path: Path) -> None:
    """The ``a5mi`` console script (:mod:`a5mi.entry`) exits with the command layer's status, 70 included."""
    code = ("import sys, a5mi.platform.imageio as io\n"
            "def boom(*a, **k): raise RuntimeError('induced failure')\n"
            "io.read_levels = boom\n"
            "sys.argv = ['a5mi', 'compare', 'a.png', 'b.png']\n"
            "from a5mi.entry import a5mi\n"
            "a5mi()\n")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path, timeout=120)
    assert p.returncode == 70 and _one_line(p.stderr).startswith("a5mi compare: internal error: RuntimeError")


# ------------------------------------------------------------------------------------------ batches
def test_render_batch_ends_with_its_worst_failure(tmp_path: Path, monkeypatch, capsys) -> None:
    """A batch whose jobs fail by a user error ends with 2; one internal error among them makes it 70."""
    def load(path: str, *args: object, **kwargs: object) -> Any:
        if path.endswith("bad.txt"):
            raise UserError(f"cannot read '{path}': no such file")
        raise RuntimeError("induced failure")

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr("a5mi.commands.render.load_scene", load)
    session = SimpleNamespace(variant="stand-in", render=_raise)
    monkeypatch.setattr("a5mi.cli.batch._session", lambda holder, args: session)
    (tmp_path / "jobs.txt").write_text("-input bad.txt -output b.png\n-input bad.txt -output c.png\n")
    assert cli.run_a5mi(["render", "--jobs", "jobs.txt", "-size", "4", "4"]) == ExitStatus.USAGE
    (tmp_path / "jobs.txt").write_text("-input bad.txt -output b.png\n-input bug.txt -output c.png\n")
    assert cli.run_a5mi(["render", "--jobs", "jobs.txt", "-size", "4", "4"]) == ExitStatus.SOFTWARE
    err = capsys.readouterr().err
    assert "job 2 (jobs.txt:2, bug.txt): internal error: RuntimeError: induced failure" in err


# ------------------------------------------------------------------------------------------ verdicts
def test_compare_same_0_differ_1(tmp_path: Path) -> None:
    from a5mi.platform.imageio import write_image

    a = np.full((6, 6, 3), 100.5 / 255)
    b = a.copy()
    b[:3] += 20 / 255
    write_image(tmp_path / "a.png", a)
    write_image(tmp_path / "b.png", b)
    same = ["compare", str(tmp_path / "a.png"), str(tmp_path / "a.png")]
    assert cli.run_a5mi(same) == ExitStatus.OK
    assert cli.run_a5mi(["compare", str(tmp_path / "a.png"), str(tmp_path / "b.png")]) == ExitStatus.DIFFER


def _pair(a: str, b: str, region: str, max_error: float) -> Any:
    from a5mi.crosscheck import PairReport

    return PairReport(a, b, region, 16, _metrics(math.inf if max_error == 0 else 40.0, 0.0, max_error), 0.0)


@pytest.mark.parametrize(("pairs", "status"), [
    ([("a5", "schlick", "other", 0.0), ("a5", "schlick", "glass", 9.0), ("exact", "path", "other", 30.0)],
     ExitStatus.OK),
    ([("a5", "schlick", "other", 0.0), ("schlick", "exact", "other", 1.0)], ExitStatus.DIFFER),
])
def test_crosscheck_fresnel_modes_off_glass(pairs: list[tuple[str, str, str, float]], status: int, tmp_path: Path,
                                            monkeypatch, capsys) -> None:
    """0 when the Fresnel modes agree bit for bit off glass (whatever path and the glass pixels show), 1 not."""
    import a5mi.crosscheck as xc

    result = SimpleNamespace(pairs=[_pair(*p) for p in pairs])
    monkeypatch.setattr("a5mi.commands.crosscheck.load_scene", lambda *a, **k: "scene")
    monkeypatch.setattr("a5mi.commands.crosscheck.activate_variant", lambda *a: "stand-in")
    monkeypatch.setattr(xc, "crosscheck", lambda desc, options: result)
    monkeypatch.setattr(xc, "write_montage", lambda r, out: None)
    monkeypatch.setattr(xc, "table", lambda r: "the table")
    assert cli.run_a5mi(["crosscheck", "s.txt", "-o", str(tmp_path / "m.png")]) == status
    err = capsys.readouterr().err
    assert ("check failed: schlick and exact differ" in err) == (status == ExitStatus.DIFFER)


def _fidelity(monkeypatch, metrics: list[Metrics]) -> None:
    from a5mi import fidelity

    names = [f"scene{k}.b4" for k in range(len(metrics))]
    by_name = dict(zip(names, metrics, strict=True))
    monkeypatch.setattr(fidelity, "cases", lambda: iter(names))
    monkeypatch.setattr(fidelity, "measure", lambda case: (by_name[case], None, None))
    monkeypatch.setattr(fidelity, "table", lambda rows: "the table")
    monkeypatch.setattr("a5mi.commands.fidelity.activate_variant", lambda *a: "stand-in")


def test_fidelity_floor(a5_data: Path, monkeypatch, capsys) -> None:
    """0 when every image reaches the floor (60 dB, < 0.1% of pixels > 2/255), 1 when one does not."""
    _fidelity(monkeypatch, [_metrics(), _metrics(75.0, 0.0005)])
    assert cli.run_a5mi(["fidelity"]) == ExitStatus.OK
    _fidelity(monkeypatch, [_metrics(), _metrics(55.0, 0.0005)])
    assert cli.run_a5mi(["fidelity"]) == ExitStatus.DIFFER
    assert "scene1.b4: PSNR 55.0 dB" in capsys.readouterr().err
    assert cli.run_a5mi(["fidelity", "--min-psnr", "50"]) == ExitStatus.OK
    _fidelity(monkeypatch, [_metrics(75.0, 0.001)])  # the share ceiling is exclusive
    assert cli.run_a5mi(["fidelity"]) == ExitStatus.DIFFER
    assert cli.run_a5mi(["fidelity", "--max-share", "2"]) == ExitStatus.USAGE


@pytest.mark.parametrize(("failed", "status"), [(False, ExitStatus.OK), (True, ExitStatus.DIFFER)])
def test_bench_a_failed_measurement_is_1(failed: bool, status: int, monkeypatch, capsys) -> None:
    run = SimpleNamespace(failed=failed, report=lambda: "the report", to_json=lambda: "{}")
    monkeypatch.setattr("a5mi.bench.resolve_scenes", lambda scenes: [])
    monkeypatch.setattr("a5mi.bench.run_benchmark", lambda paths, settings, log: run)
    assert cli.run_a5mi(["bench", "--no-inprocess", "--no-process"]) == status
    assert capsys.readouterr().out.strip() == "the report"
    assert cli.run_a5mi(["bench", "--no-inprocess", "--no-process", "--json"]) == status
    assert capsys.readouterr().out.strip() == "{}"


@pytest.mark.parametrize(("missing", "status"), [([], ExitStatus.OK), ([1], ExitStatus.DIFFER)])
def test_animate_missing_frames_is_1(missing: list[int], status: int, tmp_path: Path, monkeypatch) -> None:
    from a5mi.animate import batch
    from a5mi.animate import frames as framefiles

    outcome = batch.Outcome(rendered=[0, 1][: 2 - len(missing)], wall_s=1.0,
                            errors=[f"frames-1-1: {m}" for m in missing])
    monkeypatch.setattr("a5mi.cli.app.load_scene", lambda *a, **k: "scene")
    monkeypatch.setattr("a5mi.converters.a5_parser.parse_file",
                        lambda path: SimpleNamespace(animation=SimpleNamespace(frames=2, fps=2)))
    monkeypatch.setattr("a5mi.commands.animate.activate_variant", lambda *a: "stand-in")
    monkeypatch.setattr(batch, "render_animation", lambda *a, **k: outcome)
    monkeypatch.setattr(framefiles, "missing_frames", lambda out, frames: list(missing))
    assert cli.run_a5mi(["animate", "s.txt", "-o", str(tmp_path / "frames")]) == status


def _verdicts() -> dict[str, Callable[..., None]]:
    return {"compare": test_compare_same_0_differ_1, "crosscheck": test_crosscheck_fresnel_modes_off_glass,
            "fidelity": test_fidelity_floor, "bench": test_bench_a_failed_measurement_is_1,
            "animate": test_animate_missing_frames_is_1}


def test_every_command_that_gives_a_verdict_is_tested_for_it() -> None:
    """The commands whose ``-h`` promises a 1 are exactly those with a verdict test here (grade's verdict is
    tested with the grader, difftest's in test_difftest_campaign.py, diagnose's in
    tests/diagnose/test_diagnose.py::test_cli_exit_status_and_output)."""
    promised = {name for name in COMMANDS if _command(name).exit_differ is not None}
    assert promised - {"grade", "difftest", "diagnose"} == set(_verdicts())

"""``a5mi difftest`` (docs/DIFFTEST.md) without the sample solution: the "other binary" is a5 itself with one option
changed (``-fresnel schlick``), a real executable run the way a5soln is (sandboxed, in its own folder).

Physics of the chosen difference (README "Cross-check"): ``-fresnel a5`` and ``schlick`` agree wherever no
refracted ray leaves glass, so a scene is identical under both until a glass object is seen with at least
2 bounces (in and out); the minimiser must isolate that glass object.
"""

from __future__ import annotations

import math
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from a5mi.converters.a5_parser import parse_file
from a5mi.converters.describe import describe
from a5mi.difftest import campaign
from a5mi.difftest.generate import Flags, GenScene, Obj, random_scene
from a5mi.difftest.minimise import candidates, minimise
from a5mi.difftest.runner import Binary, check_binary, compare_scene, run_binary, stage

CAMERA = "PerspectiveCamera {\n  center 0 1 8\n  direction 0 -0.1 -1\n  up 0 1 0\n  angle 40\n}"
LIGHTS = ("  PointLight {\n    position 3 5 4\n    color 0.8 0.8 0.8\n  }",
          "  DirectionalLight {\n    direction -0.3 -1 -0.5\n    color 0.4 0.4 0.4\n  }")
MATERIALS = (("  Material {\n    diffuseColor 0.8 0.3 0.2\n  }", ()),
             ("  Material {\n    diffuseColor 0.1 0.1 0.1\n    specularColor 0.9 0.9 0.9\n"
              "    refractionIndex 1.5\n  }", ()),
             ("  Material {\n    diffuseColor 0.2 0.6 0.9\n  }", ()))


def _wrapper(tmp_path: Path) -> Path:
    """An executable ``a5`` that always adds ``-fresnel schlick`` and traces its AOV images with the sample
    solution's quadrant rays, as the compared ones are by default (a Python script run by this venv)."""
    (tmp_path / "bin").mkdir(mode=0o755, exist_ok=True)
    exe = tmp_path / "bin" / "a5schlick"
    exe.write_text(f"#!{sys.executable}\nimport sys\nfrom a5mi.cli import run\n"
                   "sys.exit(run(sys.argv[1:] + ['-fresnel', 'schlick', '-normals_mode', 'quadrant']))\n")
    exe.chmod(0o755)
    return exe


def _a5mi() -> str:
    exe = shutil.which("a5mi", path=str(Path(sys.executable).parent))
    assert exe is not None
    return exe


def _glass_scene() -> GenScene:
    objects = (Obj(0, "Sphere {\n  center -1.6 0 0\n  radius 0.7\n}"),
               Obj(1, "Transform {\nTranslate 0.4 0 0.5\nSphere {\n  center 0 0 0\n  radius 0.8\n}\n}"),
               Obj(0, "Plane {\n  normal 0 1 0.05\n  offset -1\n}"),
               Obj(0, "Triangle {\n  vertex0 1.2 -0.5 -1\n  vertex1 2.4 -0.5 -1\n  vertex2 1.8 1 -1\n}"))
    return GenScene(CAMERA, LIGHTS, "Background {\n  color 0.3 0.3 0.5\n  ambientLight 0.1 0.1 0.1\n}",
                    MATERIALS, objects, Flags(size=32, shadows=True, bounces=4))


def test_random_scenes_are_reproducible_and_valid(a5_data: Path, tmp_path: Path) -> None:
    """The same (seed, index) gives the same text; 40 scenes all parse and describe (every file they name
    exists), and together they use every kind of primitive, light, transform and material feature."""
    assert random_scene(3, 5).text() == random_scene(3, 5).text()
    assert random_scene(3, 5).text() != random_scene(3, 6).text()
    seen = ""
    for i in range(40):
        s = random_scene(9, i, campaign.scene_size(9, i, 100))
        folder = tmp_path / f"s{i}"
        folder.mkdir()
        desc = describe(parse_file(stage(s, folder, a5_data / "scenes")))
        assert desc.shapes and 90 <= s.flags.size <= 110
        seen += s.text() + " ".join(s.flags.argv())
    for word in ("Sphere", "Plane", "Triangle", "TriangleMesh", "Transform", "Matrix4f", "Rotate {", "XRotate",
                 "UniformScale", "Scale", "DirectionalLight", "PointLight", "falloff", "Noise", "texture",
                 "refractionIndex", "cubeMap", "PhongMaterial", "-jitter", "-filter", "-shadows"):
        assert word in seen, word


def test_candidates_drop_unused_materials_and_renumber() -> None:
    s = _glass_scene()
    dropped = [c for c in candidates(s) if len(c.materials) == 2]
    assert len(dropped) == 1  # material 2 is the only unused one
    assert [o.material for o in dropped[0].objects] == [0, 1, 0, 0]
    assert any(c.flags.bounces == 0 for c in candidates(s))


@pytest.mark.slow
def test_minimiser_isolates_the_glass_object(variant: str, a5_data: Path, tmp_path: Path) -> None:
    """With a5 vs a5 -fresnel schlick, the 4-object scene differs (glass, 4 bounces); without the glass
    sphere it is identical; minimised it is the glass sphere alone, its material alone, no shadows, and 2
    bounces (the least that takes a refracted ray out of the glass)."""
    from a5mi import PROJECT_ROOT

    # the sandboxed wrapper sees its interpreter and a5mi's sources (``--allow-read``)
    other = Binary(check_binary(_wrapper(tmp_path)), (sys.prefix, sys.base_prefix, str(PROJECT_ROOT)))
    data = a5_data / "scenes"
    scene = _glass_scene()
    first = compare_scene(scene, other, data)
    assert first.status == "ok" and first.psnr < 60
    no_glass = GenScene(scene.camera, scene.lights, scene.background, scene.materials,
                        tuple(o for o in scene.objects if o.material != 1), scene.flags)
    assert math.isinf(compare_scene(no_glass, other, data).psnr)
    mini = minimise(scene, lambda s: compare_scene(s, other, data), 60.0, first=first)
    assert len(mini.scene.objects) == 1 and "radius 0.8" in mini.scene.objects[0].text
    assert len(mini.scene.materials) == 1 and "refractionIndex" in mini.scene.materials[0][0]
    assert mini.scene.flags.bounces == 2 and not mini.scene.flags.shadows
    assert mini.outcome.psnr < 60
    out = campaign.write_reproducer(tmp_path / "repro", "scene_000.min", mini.scene, data)
    assert parse_file(out).objects and (tmp_path / "repro" / "scene_000.min.cmd").read_text().startswith("a5 ")


def test_cli_reports_a_table_and_json(a5_data: Path, tmp_path: Path) -> None:
    """``a5mi difftest --binary a5 --count 2``: a5 against itself is identical on every scene."""
    a5 = shutil.which("a5", path=str(Path(sys.executable).parent))
    assert a5 is not None
    report = tmp_path / "r.json"
    from a5mi import PROJECT_ROOT

    allow = ":".join((sys.prefix, sys.base_prefix, str(PROJECT_ROOT)))  # what the a5 script needs to start
    proc = subprocess.run([_a5mi(), "difftest", "--binary", a5, "--count", "2", "--allow-read", allow,
                           "--mean-size", "40", "--seed", "4", "--json-file", str(report), "--aovs", "main"],
                          capture_output=True, text=True, timeout=300, check=False)
    assert proc.returncode == 0, proc.stderr
    assert "| scene | size |" in proc.stdout and "2 scenes (seed 4)" in proc.stdout
    import json

    data = json.loads(report.read_text())
    assert [s["psnr"] for s in data["scenes"]] == ["inf", "inf"] and data["summary"]["identical"] == 2
    assert [(s["normals_psnr"], s["depth_psnr"]) for s in data["scenes"]] == [("inf", "inf")] * 2
    assert data["summary"]["normals_identical"] == data["summary"]["depth_identical"] == 2
    assert data["summary"]["median_psnr"] == "inf" and data["passed"] is True
    assert "median PSNR inf dB" in proc.stdout


def test_missing_binary_is_a_user_error(tmp_path: Path) -> None:
    proc = subprocess.run([_a5mi(), "difftest", "--binary", str(tmp_path / "nope")],
                          capture_output=True, text=True, timeout=120, check=False)
    assert proc.returncode == 2 and proc.stderr.strip() == f"a5mi difftest: error: --binary: '{tmp_path / 'nope'}' " \
                                                          "is not a file"


@pytest.mark.skipif(shutil.which("bwrap") is None, reason="bubblewrap is installed by make setup")
def test_the_binary_is_unprivileged_and_confined_like_a_graded_program(tmp_path: Path) -> None:
    """The same probe as tests/sandbox/test_grade_sandbox.py, as ``--binary``: no secret, no capability, no user
    namespace, no remount, no write outside, no network (it ran as root with every capability before)."""
    import json
    import os
    import socket

    from hostile import check_confined, confinement_probe

    outside = tmp_path / "outside"
    outside.mkdir()
    outside.chmod(0o777)
    listener = socket.socket()
    listener.bind(("127.0.0.1", 0))
    listener.listen(1)
    (tmp_path / "bin").mkdir()
    exe = tmp_path / "bin" / "probe"
    exe.write_text(confinement_probe(outside, listener.getsockname()[1]).replace(
        "print(json.dumps(res))", "print(json.dumps(res), file=open('res.json', 'w'))\nraise SystemExit(4)"))
    exe.chmod(0o755)
    for p in (tmp_path, tmp_path / "bin"):
        p.chmod(0o755)
    folder = tmp_path / "run"
    folder.mkdir()
    img, status = run_binary(exe, folder, [], timeout=20)
    assert img is None and status.startswith("binary failed"), status
    res = json.loads((folder / "res.json").read_text())
    check_confined(res, listener)
    assert not (outside / "pwned").exists() and os.stat(folder / "res.json").st_uid != 0
    listener.close()


@pytest.mark.skipif(shutil.which("bwrap") is None, reason="bubblewrap is installed by make setup")
def test_the_binary_runs_sandboxed_with_a_time_limit(tmp_path: Path) -> None:
    """The other executable cannot write outside its folder (the project is read-only, /tmp is private),
    has no network, and is stopped at the time limit."""
    escape = tmp_path / "escaped"
    (tmp_path / "bin").mkdir()
    exe = tmp_path / "bin" / "evil"
    exe.write_text(f"#!{sys.executable}\nimport socket, sys, time\n"
                   f"for p in ({str(escape)!r}, {str(Path.cwd() / 'escaped')!r}):\n"
                   "    try: open(p, 'w').write('x')\n    except OSError: pass\n"
                   "try:\n    socket.create_connection(('1.1.1.1', 80), timeout=2); print('net', file=sys.stderr)\n"
                   "except OSError: pass\n"
                   "if 'sleep' in sys.argv: time.sleep(30)\nsys.exit(3)\n")
    for p in (exe.parent, tmp_path):
        p.chmod(0o755)
    exe.chmod(0o755)
    folder = tmp_path / "run"
    folder.mkdir()
    binary = Binary(exe, (sys.prefix, sys.base_prefix))  # the interpreter of its #! line
    img, status = run_binary(binary, folder, [], timeout=20)
    assert (img, status) == (None, "binary failed: exit 3")
    assert not escape.exists() and not (Path.cwd() / "escaped").exists()
    assert run_binary(binary, folder, ["sleep"], timeout=1) == (None, "timeout")


def test_no_sandbox_reaches_the_runner(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """``--no-sandbox`` (``Binary.require_sandbox`` off) lets a binary run without bubblewrap; with it on, the
    runner refuses (A5MI_NO_BWRAP=1 stands in for a machine without bubblewrap)."""
    import tempfile

    from a5mi.sandbox.records import SandboxUnavailable

    monkeypatch.setenv("A5MI_NO_BWRAP", "1")
    # the binary runs as a fresh unprivileged uid: its folder must be reachable (pytest's tmp_path is 0700)
    base = Path(tempfile.mkdtemp(prefix="a5mi-nosandbox-"))
    try:
        base.chmod(0o755)
        script = base / "bin" / "a5"
        script.parent.mkdir(mode=0o755)
        script.write_text("#!/bin/sh\nexit 3\n")
        script.chmod(0o755)
        folder = base / "run"
        folder.mkdir(mode=0o777)
        folder.chmod(0o777)
        (folder / "scene.txt").write_text("")
        with pytest.raises(SandboxUnavailable):
            run_binary(Binary(script, (), True), folder, [], timeout=10)
        levels, why = run_binary(Binary(script, (), False), folder, [], timeout=10)
        assert levels is None and "3" in why, why
    finally:
        shutil.rmtree(base, ignore_errors=True)


def test_a_jittered_unfiltered_scene_is_compared_at_three_times_the_size(variant: str, a5_data: Path,
                                                                           tmp_path: Path) -> None:
    """``-jitter`` without ``-filter`` writes the 3W x 3H render (SPEC B.5): the binary's image is decoded and
    compared, not refused as too large (a5 against itself: identical)."""
    from a5mi import PROJECT_ROOT

    (tmp_path / "bin").mkdir(mode=0o755)
    exe = tmp_path / "bin" / "a5plain"
    exe.write_text(f"#!{sys.executable}\nimport sys\nfrom a5mi.cli import run\nsys.exit(run(sys.argv[1:]))\n")
    exe.chmod(0o755)
    other = Binary(check_binary(exe), (sys.prefix, sys.base_prefix, str(PROJECT_ROOT)))
    s = _glass_scene()
    scene = GenScene(s.camera, s.lights, s.background, s.materials, s.objects[:1],
                     Flags(size=24, bounces=0, jitter=True))
    out = compare_scene(scene, other, a5_data / "scenes", aovs="main")
    assert out.status == "ok" and math.isinf(out.worst) and [n for n, _ in out.aovs] == ["normals", "depth"]
    assert all(m.width == 72 for _, m in out.aovs)   # the AOVs at the 3x render buffer too (SPEC B.6)


def _plain(tmp_path: Path, extra: list[str]) -> Binary:
    """a5 with ``extra`` flags appended, as a sandboxed executable."""
    from a5mi import PROJECT_ROOT

    (tmp_path / "bin").mkdir(mode=0o755, exist_ok=True)
    exe = tmp_path / "bin" / "a5extra"
    exe.write_text(f"#!{sys.executable}\nimport sys\nfrom a5mi.cli import run\n"
                   f"sys.exit(run(sys.argv[1:] + {extra!r}))\n")
    exe.chmod(0o755)
    return Binary(check_binary(exe), (sys.prefix, sys.base_prefix, str(PROJECT_ROOT)))


def test_aov_images_are_compared_and_decide_the_scene(variant: str, a5_data: Path, tmp_path: Path) -> None:
    """The other renderer's ``-normals`` / ``-depth`` images are compared with a5mi's traced by the same rays
    (SPEC B.6): a5 with quadrant AOV rays against ``--aovs quadrant`` is identical in all three images; against
    ``--aovs main`` the main image is still identical but the two AOV images differ (the quadrant is the view's
    top-right quarter magnified 2x), and the scene fails on them (``worst``), also in the campaign."""
    s = _glass_scene()
    scene = GenScene(s.camera, s.lights, s.background, s.materials, s.objects, Flags(size=24, bounces=1))
    other = _plain(tmp_path, ["-normals_mode", "quadrant"])
    data = a5_data / "scenes"
    same = compare_scene(scene, other, data, aovs="quadrant")
    assert same.status == "ok" and math.isinf(same.worst)
    mixed = compare_scene(scene, other, data, aovs="main")
    assert math.isinf(mixed.psnr) and mixed.aov_psnr("normals") < 30 and mixed.aov_psnr("depth") < 30
    assert mixed.worst == min(mixed.aov_psnr("normals"), mixed.aov_psnr("depth"))
    row = campaign.Row(0, scene, mixed)
    assert campaign.below(row, 50.0) and not campaign.passed([row], 50.0)
    line = campaign.table_line(row)
    assert line.startswith("| 0 | 24 |") and line.count("|") == campaign.TABLE_HEAD.splitlines()[0].count("|")
    only_main = compare_scene(scene, other, data, aovs="none")
    assert only_main.aovs == () and math.isinf(only_main.worst)


def test_an_other_renderer_without_aov_images_fails_the_run(variant: str, a5_data: Path, tmp_path: Path) -> None:
    """A binary that does not write the AOV images (here: a5 given a ``-normals`` path it refuses) is a failed
    run: the comparison has no metrics."""
    other = _plain(tmp_path, ["-normals", "/dev/null/x.png"])  # a refused -normals path: a5 stops with 2
    s = _glass_scene()
    scene = GenScene(s.camera, s.lights, s.background, s.materials, s.objects[:1], Flags(size=16, bounces=0))
    out = compare_scene(scene, other, a5_data / "scenes")
    assert out.metrics is None and out.status.startswith("binary failed"), out.status

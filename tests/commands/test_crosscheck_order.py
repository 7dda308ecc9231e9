"""``a5mi crosscheck`` (docs/CROSSCHECK.md): its mistakes in the order a user fixes them: a missing scene is
reported before a missing output folder; with the scene there, the folder is."""

from __future__ import annotations

from pathlib import Path

import pytest

from a5mi.cli import run_a5mi


def test_a_missing_scene_is_named_before_a_missing_output_folder(tmp_path: Path,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    missing = tmp_path / "nope.txt"
    assert run_a5mi(["crosscheck", str(missing), "-o", "/no/such/dir/m.png"]) == 2
    assert capsys.readouterr().err.strip() == f"{missing}:1:1: error: cannot read scene file: No such file or directory"
    scene = tmp_path / "s.txt"
    scene.write_text("PerspectiveCamera { center 0 0 5 direction 0 0 -1 up 0 1 0 angle 30 }\n"
                     "Materials { numMaterials 1 Material { diffuseColor 1 0 0 } }\n"
                     "Group { numObjects 1 MaterialIndex 0 Sphere { center 0 0 0 radius 1 } }\n")
    assert run_a5mi(["crosscheck", str(scene), "-o", "/no/such/dir/m.png"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.endswith("/no/such/dir/m.png: output folder '/no/such/dir' does not exist"), err

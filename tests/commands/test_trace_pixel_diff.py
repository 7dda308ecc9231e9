"""``a5mi trace -pixel X Y --diff STUDENT.png`` (docs/TRACE.md): the pixel asked for is explained, never
silently replaced by the worst pixels; ``--worst`` goes with ``--diff`` alone. The project's own kind of scene,
written here (no course data)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from a5mi.cli import run_a5mi

SCENE = """PerspectiveCamera { center 0 0 6 direction 0 0 -1 up 0 1 0 angle 40 }
Lights { numLights 1 PointLight { position 2 3 4 color 1 1 1 } }
Background { color 0.2 0.2 0.3 ambientLight 0.1 0.1 0.1 }
Materials { numMaterials 2 Material { diffuseColor 0.8 0.3 0.2 specularColor 0.3 0.3 0.3 }
 Material { diffuseColor 0.6 0.6 0.6 } }
Group { numObjects 2 MaterialIndex 0 Sphere { center 0 0 0 radius 1.2 }
 MaterialIndex 1 Plane { normal 0 1 0 offset -1.2 } }
"""
FLAGS = ["-size", "16", "16", "-shadows"]


def _a5mi(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    capsys.readouterr()
    rc = run_a5mi(argv)
    out, err = capsys.readouterr()
    return rc, out, err


@pytest.fixture
def student(tmp_path: Path, variant: str) -> tuple[str, Path]:
    """The scene and a 'student' image: the reference render with pixel (8, 7) (top-left) 40 levels off."""
    from a5mi.platform.imageio import read_levels, write_image

    scene = tmp_path / "s.txt"
    scene.write_text(SCENE)
    image = tmp_path / "student.png"
    assert run_a5mi(["render", "-input", str(scene), *FLAGS, "-output", str(image)]) == 0
    levels = read_levels(image)
    levels[7, 8] = np.where(levels[7, 8] > 127, levels[7, 8] - 40, levels[7, 8] + 40)
    write_image(image, levels.astype(np.uint8))
    return str(scene), image


def test_the_pixel_asked_for_is_explained(student: tuple[str, Path], capsys: pytest.CaptureFixture[str]) -> None:
    scene, image = student
    rc, out, _ = _a5mi(["trace", "-input", scene, *FLAGS, "--diff", str(image)], capsys)
    assert rc == 0 and out.startswith("pixel (8, 7) (top-left)") and out.count("(top-left)") == 1
    rc, out, _ = _a5mi(["trace", "-input", scene, *FLAGS, "-pixel", "3", "12", "--diff", str(image)], capsys)
    lines = out.splitlines()
    assert rc == 0 and lines[0].startswith("pixel (3, 12) (top-left)") and out.count("(top-left)") == 1, out
    assert lines[1] == "  within the noise threshold (2/255): nothing to explain"
    rc, out, _ = _a5mi(["trace", "-input", scene, *FLAGS, "-pixel", "8", "8", "--origin", "bottom-left",
                        "--diff", str(image)], capsys)
    assert rc == 0 and out.startswith("pixel (8, 7) (top-left)") and out.splitlines()[1].startswith("  look at: ")


def test_worst_goes_with_diff_alone(student: tuple[str, Path], capsys: pytest.CaptureFixture[str]) -> None:
    scene, image = student
    for extra in (["-pixel", "8", "7", "--diff", str(image), "--worst", "2"], ["-pixel", "8", "7", "--worst", "2"]):
        rc, out, err = _a5mi(["trace", "-input", scene, *FLAGS, *extra], capsys)
        assert (rc, out) == (2, "") and err.strip() == ("a5mi trace: error: --worst goes with --diff alone (with "
                                                        "-pixel X Y, --diff explains that pixel)"), err

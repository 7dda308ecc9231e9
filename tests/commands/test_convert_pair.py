"""docs/USAGE.md "a5mi compare and a5mi convert": ``a5mi convert`` then ``a5mi render-xml`` is the image of the
same ``a5`` command without ``-jitter``/``-filter``, bit for bit (the project's own scene, no course data); the
two SPEC B.5 flags are refused in one line that says why."""

from __future__ import annotations

from pathlib import Path

import pytest

from a5mi.cli import run, run_a5mi

SCENES = Path(__file__).resolve().parents[2] / "scenes"


def test_render_xml_of_the_converted_scene_is_the_a5_image(variant: str, tmp_path: Path,
                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    from a5mi.platform.imageio import read_levels

    monkeypatch.chdir(SCENES)
    flags = ["-size", "24", "24", "-shadows", "-bounces", "4"]
    assert run(["-input", "demo.txt", *flags, "-output", str(tmp_path / "a5.png")]) == 0
    assert run_a5mi(["convert", "demo.txt", "-o", str(tmp_path / "demo.xml"), *flags]) == 0
    assert run_a5mi(["render-xml", str(tmp_path / "demo.xml"), "-o", str(tmp_path / "xml.png")]) == 0
    assert (read_levels(tmp_path / "a5.png") == read_levels(tmp_path / "xml.png")).all()


@pytest.mark.parametrize("flag", ["-jitter", "-filter", "--jitter"])
def test_jitter_and_filter_are_refused_with_the_reason(flag: str, tmp_path: Path,
                                                       capsys: pytest.CaptureFixture[str]) -> None:
    assert run_a5mi(["convert", str(SCENES / "demo.txt"), "-o", str(tmp_path / "d.xml"), flag]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("a5mi convert: error: -jitter and -filter are not part of a Mitsuba scene: SPEC B.5"), err
    assert "docs/USAGE.md" in err and not list(tmp_path.iterdir())

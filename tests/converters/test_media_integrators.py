"""Fog and Volume (docs/EXTENSIONS.md E.8, E.9) are rendered by ``a5_whitted`` only: with another ``-integrator``
the scene is one positioned line at the block and exit 2, not an internal error from inside Mitsuba's parser;
``convert --stock`` of a Fog with ``g`` writes the stock ``hg`` phase function."""

from __future__ import annotations

from pathlib import Path

import pytest

FOG_SCENE = """PerspectiveCamera {
    center 0 0 5
    direction 0 0 -1
    up 0 1 0
    angle 30
}
Lights {
    numLights 1
    PointLight { position 0 2 2 color 1 1 1 }
}
Background { color 0.1 0.1 0.1 ambientLight 0 0 0 }
BLOCK
Materials {
    numMaterials 1
    Material { diffuseColor 0.5 0.5 0.5 }
}
Group {
    numObjects 1
    MaterialIndex 0
    Sphere { center 0 0 0 radius 1 }
}
"""
FOG = "Fog { color 0.9 0.9 0.9 density 0.2 steps 4 g 0.3 }"
VOLUME = "Volume { grid g.vol density 1 min -1 -1 -1 max 1 1 1 }"


@pytest.mark.parametrize("integrator", ["path", "photon", "ppm", "irradiancecache"])
@pytest.mark.parametrize("block", [FOG, VOLUME])
def test_media_with_another_integrator_are_a_positioned_error(tmp_path: Path, capsys, variant, integrator: str,  # noqa: ANN001
                                                              block: str) -> None:
    import numpy as np

    from a5mi.cli import run
    from a5mi.converters.volgrid import write_vol

    write_vol(tmp_path / "g.vol", np.ones((2, 2, 2), np.float32))
    (tmp_path / "s.txt").write_text(FOG_SCENE.replace("BLOCK", block))
    status = run(["-input", str(tmp_path / "s.txt"), "-output", str(tmp_path / "o.png"), "-size", "8", "8",
                  "-integrator", integrator])
    err = capsys.readouterr().err.strip().splitlines()
    kind = block.split()[0]
    assert status == 2 and len(err) == 1, err
    assert err[0] == (f"{tmp_path / 's.txt'}:12:1: error: {kind} is rendered by -integrator whitted only "
                      f"(docs/EXTENSIONS.md E.8, E.9); -integrator {integrator} has no participating media")
    assert not (tmp_path / "o.png").exists()


def test_whitted_still_renders_the_fog(tmp_path: Path, variant) -> None:  # noqa: ANN001
    from a5mi.cli import run
    from a5mi.platform.imageio import read_levels

    (tmp_path / "s.txt").write_text(FOG_SCENE.replace("BLOCK", FOG))
    assert run(["-input", str(tmp_path / "s.txt"), "-output", str(tmp_path / "o.png"), "-size", "8", "8"]) == 0
    assert read_levels(tmp_path / "o.png").shape == (8, 8, 3)


def test_convert_stock_writes_the_hg_phase(tmp_path: Path) -> None:
    import xml.etree.ElementTree as ET

    from a5mi.cli import run_a5mi

    (tmp_path / "s.txt").write_text(FOG_SCENE.replace("BLOCK", FOG))
    assert run_a5mi(["convert", "--stock", str(tmp_path / "s.txt"), "-o", str(tmp_path / "s.xml")]) == 0
    phase = ET.parse(tmp_path / "s.xml").getroot().find(".//medium/phase")
    assert phase is not None and phase.get("type") == "hg"
    assert phase.find("float").attrib == {"name": "g", "value": "0.3"}

"""A dispersive render's colour is never negative (a5mi/render/driver.py ``_result``): E.10's spectral weight has
negative lobes, so a pixel that sees a narrow band of wavelengths can average out of the sRGB gamut; it is
clipped at 0 in float images as quantisation clips it in 8-bit ones (docs/EXTENSIONS.md E.10). Other renders
stay linear in their colours, negative ones included (tests/commands/test_faults_cli.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

SCENE = """PerspectiveCamera { center 0 0 5 direction 0 0 -1 up 0 1 0 angle 30 }
Lights { numLights 1 PointLight { position 1 2 3 color 1 1 1 } }
Background { color 0.2 0.3 0.4 ambientLight 0.1 0.1 0.1 }
Materials { numMaterials 2
 Material { diffuseColor 0 0 0 specularColor 1 1 1 refractionIndex dispersion 1 1e-30 }
 Material { diffuseColor 0.8 0.8 0.8 }
}
Group { numObjects 2 MaterialIndex 0 Sphere { center 0 0 0 radius 1 } MaterialIndex 1 Plane { normal 0 1 0 offset -1 } }
"""


def test_a_dispersive_render_writes_no_negative_colour(tmp_path: Path, variant) -> None:  # noqa: ANN001
    from a5mi.cli import run
    from a5mi.platform.imageio import quantize, read_image, read_levels

    (tmp_path / "s.txt").write_text(SCENE)
    for out in ("o.exr", "o.png"):
        assert run(["-input", str(tmp_path / "s.txt"), "-output", str(tmp_path / out), "-size", "16", "16",
                    "-shadows", "-bounces", "4"]) == 0
    exr = read_image(tmp_path / "o.exr")
    assert np.isfinite(exr).all() and exr.min() == 0.0, exr.min()
    # the 8-bit image is the float one quantised (SPEC B.1's truncation): clipping at 0 first changed nothing there
    png = read_levels(tmp_path / "o.png")
    assert np.array_equal(png, quantize(exr).astype(np.float64))

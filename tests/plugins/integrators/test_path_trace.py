"""``a5mi trace`` of ``-integrator path`` and ``-indirect N`` pixels (a5mi/trace/paths.py, EXTENSIONS E.14, E.15):
each sample is the render's pass of that pixel, a path's vertices add up to its value, and the samples' mean is
the rendered pixel."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

SCENE = """
PerspectiveCamera { center 0 1 6 direction 0 -0.2 -1 up 0 1 0 angle 35 }
Lights { numLights 2
  DirectionalLight { direction -0.3 -1 -0.4 color 0.8 0.8 0.8 }
  AreaLight { corner -0.5 2.5 -0.5 edge1 1 0 0 edge2 0 0 1 color 2 2 2 samples 2 }
}
Background { color 0.3 0.4 0.6 ambientLight 0 0 0 }
Materials { numMaterials 3
  PhongMaterial { diffuseColor 0.7 0.7 0.7 }
  PhongMaterial { diffuseColor 0.1 0.1 0.1 specularColor 0.9 0.9 0.9 refractionIndex 1.5 }
  PhongMaterial { diffuseColor 0.8 0.3 0.2 specularColor 0.2 0.2 0.2 }
}
Group { numObjects 3
  MaterialIndex 0 Plane { normal 0 1 0 offset -1 }
  MaterialIndex 1 Sphere { center -0.6 0 0 radius 0.8 }
  MaterialIndex 2 Sphere { center 0.9 -0.3 -0.5 radius 0.7 }
}
"""


def _tracer(mi: Any, **options: Any) -> Any:
    from a5mi.converters.a5_parser import parse_text
    from a5mi.converters.describe import describe
    from a5mi.render.options import RenderOptions
    from a5mi.trace.core import Tracer

    return Tracer(describe(parse_text(SCENE)), RenderOptions(width=12, height=12, **options))


@pytest.mark.parametrize(("x", "y"), [(4, 6), (7, 8), (6, 1)])
def test_path_samples_sum_to_the_rendered_pixel(mi: Any, x: int, y: int) -> None:
    from a5mi.trace.paths import format_pixel, trace_pixel

    tracer = _tracer(mi, integrator="path", spp=6, bounces=3, seed=7)
    pp = trace_pixel(tracer, x, y)
    assert len(pp.samples) == 6
    for s in pp.samples:
        total = np.sum([np.add(v.emitted, v.nee) for v in s.vertices], axis=0) if s.vertices else np.zeros(3)
        np.testing.assert_allclose(total, s.value, rtol=1e-5, atol=1e-6)
        assert s.vertices and s.vertices[0].beta == (1.0, 1.0, 1.0)
    assert pp.error <= 1e-5 * max(1.0, max(pp.rendered))
    text = format_pixel(pp)
    assert f"pixel ({x}, {y})" in text and "sample 5" in text


def test_path_vertices_name_objects_and_lobes(mi: Any) -> None:
    from a5mi.trace.paths import trace_pixel

    pp = trace_pixel(_tracer(mi, integrator="path", spp=8, bounces=4), 4, 6)
    kinds = {v.obj.kind for s in pp.samples for v in s.vertices if v.obj is not None}
    lobes = {v.lobe for s in pp.samples for v in s.vertices}
    assert kinds and kinds <= {"Sphere", "Plane"}
    assert lobes <= {"end", "diffuse", "mirror", "refraction", "absorbed"} and "diffuse" in lobes | {"refraction"}


def test_indirect_samples_mean_is_the_rendered_pixel(mi: Any) -> None:
    from a5mi.trace.paths import trace_pixel

    pp = trace_pixel(_tracer(mi, indirect=2, spp=4, bounces=2, shadows=True), 6, 8)
    assert pp.mode == "indirect" and len(pp.samples) == 4 and not pp.samples[0].vertices
    assert pp.error <= 1e-5 * max(1.0, max(pp.rendered))


def test_cli_json(tmp_path: Path) -> None:
    scene = tmp_path / "s.txt"
    scene.write_text(SCENE)
    a5mi = [str(Path(sys.executable).parent / "a5mi")]
    p = subprocess.run([*a5mi, "trace", "-input", str(scene), "-size", "10", "10",
                        "-pixel", "5", "6", "-integrator", "path", "-spp", "3", "--json"],
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    out = json.loads(p.stdout)
    assert out["mode"] == "path" and len(out["samples"]) == 3 and out["error"] < 1e-5
    assert all("vertices" in s for s in out["samples"])
    bad = subprocess.run([*a5mi, "trace", "-input", str(scene), "-size", "10", "10",
                          "-pixel", "5", "6", "-integrator", "path", "-jitter"],
                         capture_output=True, text=True, timeout=300)
    assert bad.returncode == 2 and "-jitter" in bad.stderr

"""``-indirect N`` (docs/EXTENSIONS.md E.15): distribution ray tracing of indirect light in ``a5_whitted``.

The check of the issue: on a diffuse-only scene without ambient light, lit by its background (the environment,
which Whitted's light loop never counts), ``-indirect N -bounces B`` equals ``-integrator path -bounces B−1``
in mean (E.15: Whitted's last level gathers nothing, the path's last vertex still samples the environment).
(A scene without lights has its ambient forced to 1, SPEC A.1: a black point light keeps it at 0.)
Seeded; per-pixel sigma from the passes (conservative: stratified), thresholds 5 sigma on the image mean and
3 sigma on >= 99% of the pixels.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from path_helpers import a5_passes, load

SCENE = """
PerspectiveCamera { center 0 1.5 7 direction 0 -0.25 -1 up 0 1 0 angle 35 }
Lights { numLights 1 PointLight { position 0 10 0 color 0 0 0 } }
Background { color 0.6 0.7 0.9 ambientLight 0 0 0 }
Materials { numMaterials 3
  PhongMaterial { diffuseColor 0.75 0.75 0.75 }
  PhongMaterial { diffuseColor 0.8 0.2 0.15 }
  PhongMaterial { diffuseColor 0.2 0.7 0.25 }
}
Group { numObjects 3
  MaterialIndex 0
  Plane { normal 0 1 0 offset -1 }
  MaterialIndex 1
  Sphere { center -1.1 0 0 radius 1 }
  MaterialIndex 2
  Sphere { center 1.1 0 0 radius 1 }
}
"""


def test_indirect_equals_path_in_mean(mi: Any) -> None:
    size, spp, n = 16, 16, 3
    desc, scene, _ = load(mi, SCENE, bounces=3, indirect=n, spp=spp)
    a, sa = a5_passes(mi, scene, scene.integrator(), desc.camera, size, size, spp, seed=1)
    pdesc, pscene, _ = load(mi, SCENE, integrator="path", bounces=2, spp=spp)
    b, sb = a5_passes(mi, pscene, pscene.integrator(), pdesc.camera, size, size, 4 * spp, seed=2)
    sigma = math.sqrt(float(np.sum(sa ** 2) + np.sum(sb ** 2))) / a.size
    assert abs(float(a.mean() - b.mean())) <= 5 * sigma, (a.mean(), b.mean(), sigma)
    z = (a.mean(axis=2) - b.mean(axis=2)) / np.maximum(np.sqrt((sa ** 2 + sb ** 2).mean(axis=2)), 1e-9)
    assert float(np.mean(np.abs(z) <= 3.0)) >= 0.99, float(np.abs(z).max())


def test_indirect_brightens_and_stays_off_by_default(mi: Any) -> None:
    """Without -indirect the environment lights nothing (black spheres and plane, SPEC B.3); with it they
    show the sky. The dict of a course render carries no ``indirect`` key."""
    from a5mi.render.options import RenderOptions

    assert "indirect" not in RenderOptions().integrator_params()
    assert RenderOptions(indirect=2).integrator_params()["indirect"] == 2
    assert "indirect" not in RenderOptions(integrator="path", indirect=2).integrator_params()
    desc, scene, _ = load(mi, SCENE, bounces=2)
    off, _ = a5_passes(mi, scene, scene.integrator(), desc.camera, 8, 8, 1)
    desc, scene, _ = load(mi, SCENE, bounces=2, indirect=2)
    on, _ = a5_passes(mi, scene, scene.integrator(), desc.camera, 8, 8, 2)
    surface = off.max(axis=2) == 0.0
    assert surface.sum() > 20 and np.all(on[surface].max(axis=1) > 0.0)


def test_gathered_rays_skip_the_area_light_the_light_loop_counted(mi: Any) -> None:
    """An area light above a diffuse floor (no background): the light loop (E.2) lights the floor; a gathered
    ray that hits the light adds no emission, so -indirect adds only light after two bounces: with a single
    floor (nothing else to bounce off) the image is the same as without -indirect, up to the E.2 samples."""
    text = """
PerspectiveCamera { center 0 3 6 direction 0 -0.5 -1 up 0 1 0 angle 40 }
Lights { numLights 1 AreaLight { corner -0.5 2 -0.5 edge1 1 0 0 edge2 0 0 1 color 1 1 1 samples 4 } }
Background { color 0 0 0 ambientLight 0 0 0 }
Materials { numMaterials 1 PhongMaterial { diffuseColor 0.8 0.8 0.8 } }
Group { numObjects 1 MaterialIndex 0 Plane { normal 0 1 0 offset 0 } }
"""
    desc, scene, _ = load(mi, text, bounces=2, shadows=True)
    off, _ = a5_passes(mi, scene, scene.integrator(), desc.camera, 8, 8, 2, seed=5)
    desc, scene, _ = load(mi, text, bounces=2, shadows=True, indirect=2)
    on, _ = a5_passes(mi, scene, scene.integrator(), desc.camera, 8, 8, 2, seed=5)
    np.testing.assert_allclose(on, off, rtol=1e-5, atol=1e-6)


@pytest.mark.parametrize(("argv", "message"), [
    (["-indirect", "100", "-bounces", "10"], "the limit is 256"),
    (["-indirect", "2", "-integrator", "path"], "mode of the whitted integrator"),
])
def test_cli_refuses_what_the_kernel_cannot_hold(tmp_path: Any, argv: list[str], message: str) -> None:
    """A user error, one line, exit status 2, before anything is rendered."""
    import subprocess
    import sys
    from pathlib import Path

    scene = tmp_path / "s.txt"
    scene.write_text(SCENE)
    a5 = str(Path(sys.executable).parent / "a5")
    p = subprocess.run([a5, "-input", str(scene), "-output", str(tmp_path / "o.png"), "-size", "4", "4", *argv],
                       capture_output=True, text=True, timeout=120)
    assert p.returncode == 2 and message in p.stderr and len(p.stderr.strip().splitlines()) == 1, p.stderr

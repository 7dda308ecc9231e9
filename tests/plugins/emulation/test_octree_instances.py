"""The octree node table past one mesh: instances of one OBJ share their nodes (plugins/emulation/octree_leaves.py).

The node table (the sample solution's octree replayed per shadow ray with a zero direction component) holds at
most ``MAX_NODES`` nodes over a scene's meshes; past it the per-face reach masks decide, which over-shadow. Two
bunny_1k instances have the same object-space triangles and so the same octree: the second instance points at
the first's nodes. (Under the earlier leaf table, 2 x 1,179,163 leaf references, this sharing was what kept
them within its budget.)

Golden: tests/data/two_bunnies_a5soln.png is ``a5soln -input bunnies.txt -size 48 48 -shadows -output b.bmp``
of :data:`SCENE` (two bunny_1k under a light straight down), converted to PNG losslessly. Before the sharing
a5mi was 32.2 dB from it (5 pixels of over-shadowed floor; 28.4 dB at 80 x 80).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from a5mi.converters.a5_parser import parse_text
from a5mi.converters.describe import describe
from a5mi.platform.imageio import quantize, read_uint8
from a5mi.render.options import RenderOptions
from a5mi.render.session import render

SCENE = """PerspectiveCamera { center 0 3 7 direction 0 -0.4 -1 up 0 1 0 angle 40 }
Lights { numLights 1 DirectionalLight { direction 0 -1 0 color 0.9 0.9 0.9 } }
Background { color 0.1 0.1 0.2 ambientLight 0.1 0.1 0.1 }
Materials { numMaterials 2 Material { diffuseColor 0.9 0.9 0.9 } Material { diffuseColor 0.8 0.3 0.2 } }
Group { numObjects 3
 MaterialIndex 0 Plane { normal 0 1 0 offset -0.6 }
 MaterialIndex 1 Transform { Translate -1 0 0 ZRotate 30 UniformScale 8 Translate 0 -0.1 0
   TriangleMesh { obj_file bunny_1k.obj } }
 MaterialIndex 1 Transform { Translate 1.2 0 0 XRotate 20 UniformScale 8 Translate 0 -0.1 0
   TriangleMesh { obj_file bunny_1k.obj } }
}
"""


def test_two_bunnies_are_the_sample_solutions(variant: str, scenes_dir: Path) -> None:
    model = parse_text(SCENE, str(scenes_dir / "bunnies.txt"))
    img = quantize(render(describe(model), RenderOptions(width=48, height=48, shadows=True)).image)[..., :3]
    golden = read_uint8(Path(__file__).parents[2] / "data" / "two_bunnies_a5soln.png")
    np.testing.assert_array_equal(img, golden)


def _mesh(seed: int, n: int = 3000) -> np.ndarray:
    rng = np.random.default_rng(seed)
    centre = rng.random((n, 1, 3)).astype(np.float32)
    return (centre + 0.02 * rng.standard_normal((n, 3, 3))).astype(np.float32)


def test_identical_meshes_share_their_nodes(variant: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """``build([t, t])`` holds ``t``'s nodes once, both meshes' roots pointing at them; with the budget
    between one and two copies' nodes it is still built, while two different meshes of that size are
    refused."""
    from a5mi.plugins.emulation import octree_leaves

    t = _mesh(1)
    one, two = octree_leaves.build([t]), octree_leaves.build([t, t])
    assert one is not None and two is not None
    assert dr_len(two.child) == dr_len(one.child) > 1
    assert np.asarray(two.root).tolist() == [0, 0]
    small = _mesh(2, 7)                                  # 7 triangles: the root is a leaf, 1 node
    monkeypatch.setattr(octree_leaves, "MAX_NODES", 1)   # one copy fits, two do not
    assert octree_leaves.build([small, small]) is not None
    assert octree_leaves.build([small, (small + np.float32(1e-3)).astype(np.float32)]) is None


def dr_len(a: object) -> int:
    return len(np.asarray(a))

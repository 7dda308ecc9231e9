"""Different meshes past the earlier leaf-reference budget of the octree replay (plugins/emulation/octree_leaves.py).

Shadow rays with an exactly zero direction component follow the sample solution's octree traversal per ray
(SPEC A.6). The earlier table listed, per face, the paths of the leaves holding it: at most 2,000,000 such
(leaf, face) references over a scene's distinct meshes, past which the per-face reach masks decided and
over-shadowed. scenes/octree_budget.txt holds three of the project's own meshes (scenes/make_assets.py,
scenes/make_tube.py) under ``Transform``s, lit straight down (``direction 0 -1 0``): column.obj alone needs
2,233,808 references (most in level-9 leaves), the three 2,301,520. The node table needs 570,075 nodes (2.2 MiB
in the kernel, where the references took 17.6 MiB) and lists no level-9 leaf.

Golden: tests/data/a5soln/octree_budget.png, ``a5soln -input octree_budget.txt -size 64 64 -output
OUT/octree_budget.bmp -shadows`` run in ``scenes/`` (tests/data/a5soln/README.md). Before the node table a5mi
was 22.6 dB from it (23.2 dB at 100 x 100: floor pixels in the column's and the cylinder's shadows).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from a5mi.converters.a5_parser import parse_text
from a5mi.converters.describe import describe
from a5mi.converters.obj import load_obj
from a5mi.platform.imageio import quantize, read_uint8
from a5mi.render.options import RenderOptions
from a5mi.render.session import render

ROOT = Path(__file__).resolve().parents[3]
SCENE = ROOT / "scenes" / "octree_budget.txt"


def test_different_meshes_past_the_old_budget_are_the_sample_solutions(variant: str,
                                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(SCENE.parent)       # relative mesh paths, as a5soln was run (SPEC A.0)
    model = parse_text(SCENE.read_text(), str(SCENE))
    img = quantize(render(describe(model), RenderOptions(width=64, height=64, shadows=True)).image)[..., :3]
    golden = read_uint8(ROOT / "tests" / "data" / "a5soln" / "octree_budget.png")
    np.testing.assert_array_equal(img, golden)


def test_the_scenes_meshes_are_one_node_table(variant: str) -> None:
    """The three meshes' table is built (the budget is on nodes, :data:`MAX_NODES`), with one root per mesh,
    in row order, each a split node."""
    from a5mi.plugins.emulation import octree_leaves

    meshes = []
    for name in ("column.obj", "cylinder.obj", "icosphere.obj"):
        mesh = load_obj(SCENE.parent / "meshes" / name)
        meshes.append(np.asarray(mesh.vertices, dtype=np.float32)[np.asarray(mesh.faces)])
    table = octree_leaves.build(meshes)
    assert table is not None
    child, root = np.asarray(table.child), np.asarray(table.root)
    assert len(child) == 570_075 < octree_leaves.MAX_NODES
    assert root[0] == 0 and (np.diff(root) > 0).all() and (child[root] > 0).all()

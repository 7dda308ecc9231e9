"""The octree emulation (``converters/octree.py``, "Bounds") stays bounded in time and memory on any mesh
(SPEC A.6 meshes): coincident, crossing and sliver faces, which make ``a5soln``'s own octree split down to
level 9 (more than 7 faces in every node there), are either solved exactly by the pruned traversal or,
over the budget, marked as reached by every pattern with one warning at the mesh's ``obj_file``; ``a5mi
convert`` (with and without ``--stock``) and a render finish on them."""

from __future__ import annotations

import os
import resource
import subprocess
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np
import pytest

from a5mi.converters import octree
from a5mi.converters.a5_parser import parse_text
from a5mi.converters.describe import describe
from a5mi.converters.obj import load_obj

#: Every pattern slot that a direction can produce (sign bits only on the finite axes).
USED = [s for s in range(48) if not ((s % 8) & ((s // 8) + 1))]
#: Seconds and traced bytes any one mask computation below may take (the budget costs ~10 s at most).
SECONDS, BYTES = 20.0, 300 << 20


def coincident(n: int) -> tuple[np.ndarray, np.ndarray]:
    """One triangle repeated ``n`` times."""
    return np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), np.tile([[0, 1, 2]], (n, 1))


def crossing(n: int, w: float = 1e-3) -> tuple[np.ndarray, np.ndarray]:
    """``n`` thin triangles through the origin at angles ``k·pi/n`` in the xy plane, ``2w`` wide in z."""
    v = []
    for k in range(n):
        c, s = np.cos(np.pi * k / n), np.sin(np.pi * k / n)
        v += [[c, s, 0], [-c, -s, w], [-c, -s, -w]]
    return np.array(v), np.arange(3 * n).reshape(n, 3)


def star(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """``n`` needle triangles through (nearly) one point in random 3D directions."""
    rng = np.random.default_rng(seed)
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    v = np.stack([d, -d, -d + rng.normal(size=(n, 3)) * 1e-3], axis=1).reshape(-1, 3)
    return v, np.arange(3 * n).reshape(n, 3)


def slivers(n: int) -> tuple[np.ndarray, np.ndarray]:
    """``n`` zero-width and near-zero-width triangles sharing the edge (0,0,0)-(1,e,0)."""
    v = []
    for k in range(n):
        e = 1e-7 * k
        v += [[0, 0, 0], [1, 1e-6 + e, 0], [1, e, 0]]
    return np.array(v, float), np.arange(3 * n).reshape(n, 3)


def grid_copies(n: int, k: int = 20) -> tuple[np.ndarray, np.ndarray]:
    """``n`` coincident copies of a ``k x k`` grid of 2k² triangles in the unit square (z = 0)."""
    xs = np.linspace(0, 1, k + 1)
    x, y = np.meshgrid(xs, xs)
    v = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], 1)
    q = []
    for i in range(k):
        for j in range(k):
            a = i * (k + 1) + j
            q += [[a, a + 1, a + k + 2], [a, a + k + 2, a + k + 1]]
    return v, np.tile(np.array(q), (n, 1))


def _bits(masks: np.ndarray) -> np.ndarray:
    return masks[:, 0].astype(np.int64) | (masks[:, 1].astype(np.int64) << 24)


def _bounded(v: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, bool]:
    """``_compute_masks`` within :data:`SECONDS` of CPU time and :data:`BYTES` (numpy allocations are traced)."""
    tracemalloc.start()
    t = time.process_time()  # CPU seconds of this process: a busy machine does not stretch them
    try:
        masks, exact = octree._compute_masks(v, f)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    dt = time.process_time() - t
    assert dt < SECONDS and peak < BYTES, (dt, peak)
    assert masks.shape == (len(f), 2) and masks.dtype == np.float32
    return masks, exact


@pytest.mark.parametrize(("n", "solved"), [(8, True), (9, True), (1000, True), (100_000, False)])
def test_coincident_faces(n: int, solved: bool) -> None:
    """8 copies used to split 8^9 nodes. Identical faces lie in the same leaves, so they get identical
    masks; the triangle spans its whole (flat) box, so every leaf holds all copies and every pattern, which
    always reaches some leaf, reaches all of them. 10^5 copies need 0.8 M references per split: over the
    budget, every bit is set."""
    masks, exact = _bounded(*coincident(n))
    assert exact == solved
    assert (_bits(masks) == (sum(1 << s for s in USED) if solved else (1 << 48) - 1)).all()


@pytest.mark.parametrize(("mesh", "solved"), [(crossing(16), True), (crossing(64, 1e-6), True),
                                               (star(16, 1), True), (star(100, 2), True), (slivers(16), True),
                                               (slivers(100), True), (slivers(300), False)],
                         ids=["cross16", "cross64", "star16", "star100", "sliver16", "sliver100", "sliver300"])
def test_crossing_and_sliver_faces_are_bounded(mesh: tuple[np.ndarray, np.ndarray], solved: bool) -> None:
    """Valid geometry whose faces overlap at one point or edge (16 crossing faces took 61 s and 816 MB):
    solved exactly, every face reached by some pattern (each touches the point or edge where the tree is
    deepest), or, for 300 slivers, over the budget with every bit set."""
    masks, exact = _bounded(*mesh)
    assert exact == solved
    assert (_bits(masks) != 0).all() if solved else (_bits(masks) == (1 << 48) - 1).all()


def test_over_the_budget_every_face_is_reached() -> None:
    """30 coincident copies of an 800-face grid need more than ``MAX_REFS`` references: every bit set; 8
    copies stay within the budget and are solved exactly."""
    masks, exact = octree._compute_masks(*grid_copies(30))
    assert not exact
    assert (_bits(masks) == (1 << 48) - 1).all()
    masks, exact = octree._compute_masks(*grid_copies(8))
    assert exact


def test_a_small_budget_falls_back_on_a_course_mesh(scenes_dir: Path) -> None:
    """The states and nodes budgets are enforced as well as the references budget; the default one leaves
    the course meshes exact (their masks are checked against the traversal in test_octree_rule.py)."""
    mesh = load_obj(scenes_dir / "diamond.obj")
    exact_masks, exact = octree._compute_masks(mesh.vertices, mesh.faces)
    assert exact and (_bits(exact_masks) != (1 << 48) - 1).any()
    for refs, states, nodes in ((10**9, 50, 10**9), (100, 10**9, 10**9), (10**9, 10**9, 100)):
        masks, exact = octree._compute_masks(mesh.vertices, mesh.faces, refs, states, nodes)
        assert not exact and (_bits(masks) == (1 << 48) - 1).all()


@pytest.mark.parametrize("name", ["cube.obj", "diamond.obj", "bunny_200.obj", "bunny_1k.obj", "vase.obj"])
def test_course_meshes_are_well_within_the_budget(scenes_dir: Path, name: str) -> None:
    """At most a quarter of either budget, so the fallback never touches the course meshes."""
    mesh = load_obj(scenes_dir / name)
    root = octree.build(mesh.vertices, mesh.faces)
    for zmask in range(1, 7):
        for neg in range(8):
            if not neg & zmask:
                octree.reachable_trigs(root, zmask, neg)
    tree = root.tree
    assert tree.refs < octree.MAX_REFS / 4 and tree.states < octree.MAX_STATES / 4
    assert tree.nodes < octree.MAX_NODES / 4


def _write_obj(path: Path, v: np.ndarray, f: np.ndarray) -> None:
    lines = [f"v {x!r} {y!r} {z!r}" for x, y, z in v.tolist()] + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in f]
    path.write_text("\n".join(lines) + "\n")


def _scene(*objs: str) -> str:
    """One material, the meshes named by ``objs`` untransformed, all on line 5."""
    meshes = " ".join(f"MaterialIndex 0 TriangleMesh {{ obj_file {obj} }}" for obj in objs)
    return f"""PerspectiveCamera {{ center 0.3 0.3 5 direction 0 0 -1 up 0 1 0 angle 30 }}
Lights {{ numLights 1 DirectionalLight {{ direction 0 0 -1 color 1 1 1 }} }}
Background {{ color 0 0 0 ambientLight 0 0 0 }}
Materials {{ numMaterials 1 PhongMaterial {{ diffuseColor 1 0 0 }} }}
Group {{ numObjects {len(objs)} {meshes} }}
"""


def test_the_fallback_warns_once_at_the_obj_file(tmp_path: Path, monkeypatch) -> None:
    """One warning per OBJ file however often it is placed, at its ``obj_file`` value; again when the
    fallback is read back from the cache; none for an exact mesh and none with ``stock`` (no masks)."""
    monkeypatch.setenv("A5MI_CACHE_DIR", str(tmp_path / "cache"))
    _write_obj(tmp_path / "grid.obj", *grid_copies(30))
    _write_obj(tmp_path / "same.obj", *coincident(8))
    text = _scene("grid.obj", "grid.obj")
    col = text.splitlines()[4].index("grid.obj") + 1
    for _ in range(2):  # computed, then from the cache
        desc = describe(parse_text(text, str(tmp_path / "s.txt")))
        hits = [(loc, msg) for loc, msg in desc.warnings if "octree" in msg]
        assert len(hits) == 1 and (hits[0][0].line, hits[0][0].col) == (5, col), hits
    assert not [m for _, m in describe(parse_text(text, str(tmp_path / "s.txt")), stock=True).warnings if "octree" in m]
    assert not [m for _, m in describe(parse_text(_scene("same.obj"), str(tmp_path / "s.txt"))).warnings
                if "octree" in m]


@pytest.mark.parametrize("stock", [False, True], ids=["a5", "stock"])
def test_convert_finishes_on_degenerate_meshes(tmp_path: Path, stock: bool, a5_data: Path) -> None:
    """``a5mi convert`` on 8 copies of one triangle (it used to hang, also with ``--stock``) and on the
    over-budget grid: exit 0 well within the time bound, the fallback warned once without ``--stock``."""
    _write_obj(tmp_path / "same.obj", *coincident(8))
    _write_obj(tmp_path / "grid.obj", *grid_copies(30))
    (tmp_path / "s.txt").write_text(_scene("same.obj", "grid.obj"))
    env = dict(os.environ, A5_DATA=str(a5_data), A5MI_CACHE_DIR=str(tmp_path / "cache"))
    code = "import sys; from a5mi.entry import a5mi; sys.argv[0] = 'a5mi'; a5mi()"
    cmd = [sys.executable, "-c", code, "convert", str(tmp_path / "s.txt"), "-o", str(tmp_path / "s.xml")]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    p = subprocess.run(cmd + (["--stock"] if stock else []), capture_output=True, text=True, env=env, timeout=600)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    assert p.returncode == 0, p.stderr
    assert (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime) < 60  # CPU seconds
    assert (tmp_path / "s.xml").is_file()
    assert p.stderr.count("too degenerate for the sample solution's octree") == (0 if stock else 1), p.stderr

"""Shadows of a triangle mesh as the binary's octree casts them (converters/octree.py,
plugins/emulation/octree_rule.py).

Measured against a5soln (diamond.obj above a sphere, one directional light): with ``direction 0 -1 0.3``
the shadow ray direction ``L = -normalize(direction)`` has ``L_x = -0.0`` and the binary's octree never
reaches the untransformed mesh, so the sphere is lit everywhere; with ``direction 0.001 -1 0.3`` the diamond
shadows it. a5mi renders both probes identically to a5soln (0/255 difference). Here the expectations are
computed per pixel from the B.2 camera rays: the sphere's analytic hit and Lambert term, and the mesh's
shadow from an exact ray test against the mesh alone.
"""

from __future__ import annotations

import numpy as np
import pytest
from helpers import TESTS

from a5mi.converters import octree
from a5mi.converters.a5_parser import parse_text
from a5mi.converters.describe import describe
from a5mi.converters.obj import load_obj
from a5mi.platform.imageio import quantize
from a5mi.render.options import RenderOptions
from a5mi.render.session import render

N = 64


def _scene(direction: str, wrap: bool = False) -> str:
    mesh = "TriangleMesh { obj_file diamond.obj }"
    if wrap:
        mesh = f"Transform {{ {mesh} }}"
    return f"""PerspectiveCamera {{ center 0 0 10 direction 0 0 -1 up 0 1 0 angle 30 }}
Lights {{ numLights 1 DirectionalLight {{ direction {direction} color 1 1 1 }} }}
Background {{ color 0.2 0.2 0.2 ambientLight 0.1 0.1 0.1 }}
Materials {{ numMaterials 2 Material {{ diffuseColor 0.5 0.5 0.5 }} Material {{ diffuseColor 1 0.2 0.2 }} }}
Group {{ numObjects 2 MaterialIndex 0 {mesh}
 MaterialIndex 1 Sphere {{ center 0 -3 0 radius 1.5 }} }}
"""


def _expected(model, scenes_dir, direction: tuple[float, float, float]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(sphere pixel mask, lit-by-the-exact-test mask, Lambert levels if lit) for the B.2 rays."""
    import mitsuba as mi

    from a5mi.plugins.sensors.camera import camera_rays

    jj, ii = np.meshgrid(np.arange(N), np.arange(N), indexing="ij")
    c = model.camera
    ray = camera_rays(c.center, c.direction, c.up, c.angle, mi.Float(ii.ravel()), mi.Float(jj.ravel()), N, N)
    o, d = np.array(ray.o, dtype=np.float64).T, np.array(ray.d, dtype=np.float64).T
    mesh = load_obj(scenes_dir / "diamond.obj")
    only_mesh = mi.load_dict({"type": "scene", "m": _mi_mesh(mesh)})
    t_mesh = np.array(only_mesh.ray_intersect(ray).t, dtype=np.float64)
    centre, r = np.array([0.0, -3, 0]), 1.5
    oc = o - centre
    b = np.sum(oc * d, axis=1)
    disc = b * b - (np.sum(oc * oc, axis=1) - r * r)
    t_s = np.where(disc >= 0, -b - np.sqrt(np.maximum(disc, 0)), np.inf)
    sphere = (t_s > 0) & (t_s < t_mesh)
    p = o + np.where(sphere, t_s, 0)[:, None] * d
    nrm = (p - centre) / r
    L = -np.asarray(direction) / np.linalg.norm(direction)
    shadow = mi.Ray3f(mi.Point3f((p + 1e-3 * L).astype(np.float32).T), mi.Vector3f(*[float(x) for x in L]))
    lit = ~np.array(only_mesh.ray_test(shadow))
    lam = 0.1 * np.array([1, 0.2, 0.2]) + np.maximum(nrm @ L, 0)[:, None] * np.array([1, 0.2, 0.2])
    return sphere, lit, np.clip((lam * 255).astype(int), 0, 255)


def _mi_mesh(obj) -> object:
    from a5mi.converters.geometry import mesh_from_obj
    from a5mi.converters.to_mitsuba import make_mesh

    return make_mesh("m", mesh_from_obj(obj, np.eye(4)))


def _render(text: str, scenes_dir) -> tuple[object, np.ndarray]:
    model = parse_text(text, str(scenes_dir / "probe.txt"))
    img = quantize(render(describe(model), RenderOptions(width=N, height=N, shadows=True, bounces=0)).image)
    return model, img[::-1].reshape(-1, 3).astype(int)


def test_minus_zero_direction_the_binary_sees_no_mesh(variant: str, scenes_dir) -> None:
    """``direction 0 -1 0.3``: L_x = -0.0, so the untransformed diamond casts no shadow (every sphere pixel is
    the unshadowed Lambert value), although an exact test says it would shadow many of them."""
    model, img = _render(_scene("0 -1 0.3"), scenes_dir)
    sphere, lit_exact, lam = _expected(model, scenes_dir, (0, -1, 0.3))
    assert (~lit_exact & sphere).sum() > 50  # the region the exact test shadows
    err = np.abs(img[sphere] - lam[sphere]).max(axis=1)
    assert err.max() <= 1


def test_nonzero_direction_the_mesh_shadows_as_an_exact_test_says(variant: str, scenes_dir) -> None:
    """``direction 0.001 -1 0.3`` (no zero component): the shadow is the exact one."""
    model, img = _render(_scene("0.001 -1 0.3"), scenes_dir)
    sphere, lit, lam = _expected(model, scenes_dir, (0.001, -1, 0.3))
    ambient = np.clip((0.1 * np.array([1, 0.2, 0.2]) * 255).astype(int), 0, 255)
    expect = np.where(lit[:, None], lam, ambient)
    bad = np.abs(img[sphere] - expect[sphere]).max(axis=1) > 1
    assert (~lit & sphere).sum() > 50 and bad.sum() <= 2  # shadow-edge pixels may differ in the last bits


def test_reach_masks_of_one_leaf_reach_every_triangle() -> None:
    """A mesh of <= 7 triangles is one leaf: every pattern reaches every triangle."""
    cube = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    small = octree.reach_masks(cube, np.array([[0, 1, 2], [0, 1, 3], [0, 2, 3]]))
    used = [s for s in range(48) if not ((s % 8) & ((s // 8) + 1))]  # sign bits only on finite axes
    assert len(used) == 3 * 4 + 3 * 2
    assert all(int(w[0]) | (int(w[1]) << 24) == sum(1 << s for s in used) for w in small)


@pytest.mark.course_data
def test_reach_masks_follow_the_traversal() -> None:
    """For the diamond (110 triangles) a +0 x component reaches only triangles touching the lowest-x leaves
    (all of them within the lower x half of the box), and the same ones whatever the signs of y and z."""
    from pathlib import Path

    from a5mi import data_dir

    mesh = load_obj(Path(data_dir()) / "scenes" / "diamond.obj")
    words = octree.reach_masks(mesh.vertices, mesh.faces)
    bits = words[:, 0].astype(np.int64) | (words[:, 1].astype(np.int64) << 24)
    x_slots = [(0 * 8) + neg for neg in (0, 2, 4, 6)]
    reach = [(bits >> s) & 1 for s in x_slots]
    assert all(np.array_equal(reach[0], r) for r in reach) and 0 < reach[0].sum() < len(mesh.faces)
    tri = mesh.vertices[mesh.faces]
    lo, hi = mesh.vertices[:, 0].min(), mesh.vertices[:, 0].max()
    assert (tri[reach[0] == 1, :, 0].min(axis=1) <= (lo + hi) / 2).all()


def test_reach_masks_are_cached_by_mesh_content(tmp_path, monkeypatch, a5_data) -> None:
    """The masks are computed once per mesh and read back from the cache folder: equal to a fresh
    computation, found without running the traversal again, keyed by the mesh's content (another mesh
    gets its own file), and recomputed when the file is damaged or does not fit."""
    mesh = load_obj(a5_data / "scenes" / "diamond.obj")
    fresh = octree.reach_masks(mesh.vertices, mesh.faces, folder=False)
    assert not list(tmp_path.iterdir())
    first = octree.reach_masks(mesh.vertices, mesh.faces, folder=tmp_path)
    files = list((tmp_path / "octree").glob("*.npy"))
    assert len(files) == 1 and np.array_equal(first, fresh) and first.dtype == np.float32

    def no_traversal(*_args):
        raise AssertionError("the traversal ran although the masks are cached")

    monkeypatch.setattr(octree, "_compute_masks", no_traversal)
    assert np.array_equal(octree.reach_masks(mesh.vertices, mesh.faces, folder=tmp_path), fresh)
    monkeypatch.undo()
    moved = mesh.vertices + [0.0, 0.0, 1e-3]
    octree.reach_masks(moved, mesh.faces, folder=tmp_path)
    assert len(list((tmp_path / "octree").glob("*.npy"))) == 2
    for damage in (b"", b"garbage", files[0].read_bytes()[:-4] + b"\0\0\0\0"):
        files[0].write_bytes(damage)
        assert np.array_equal(octree.reach_masks(mesh.vertices, mesh.faces, folder=tmp_path), fresh)
        words = np.load(files[0])  # rewritten: the mask words, the exact flag, the CRC
        assert np.array_equal(words[:-2].reshape(-1, 2), fresh.astype(np.uint32)) and words[-2] == 1


def test_reach_masks_without_a_writable_cache_are_computed(tmp_path) -> None:
    """A cache folder that cannot be created (a file stands in its way) only means no cache."""
    blocker = tmp_path / "cache"
    blocker.write_text("not a folder")
    cube = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    faces = np.array([[0, 1, 2], [0, 1, 3]])
    assert np.array_equal(octree.reach_masks(cube, faces, folder=blocker),
                          octree.reach_masks(cube, faces, folder=False))


def _low_leaves(node: octree._Node, child_ok) -> set[int]:
    if node.is_leaf:
        return {int(t) for t in node.trigs}
    return set().union(*(_low_leaves(c, child_ok) for i, c in enumerate(node.children) if child_ok(i)))


@pytest.mark.parametrize(("zmask", "child_ok"), [(1, lambda i: not i & 4), (2, lambda i: not i & 2),
                                                 (3, lambda i: not i & 6)])
def test_reach_equals_the_low_side_leaves(zmask: int, child_ok) -> None:
    """Derived by hand from octree.cpp: with d_x = +0 (t_x0 = -inf, NaN midpoints) ``first_node`` never sets
    the x bit and ``new_node`` never steps in x, so the traversal reaches exactly the leaves on the low-x side
    at every level (likewise y; with x and y both +0 it steps in z only, in the low-x, low-y column). The
    symbolic traversal must find exactly those leaves' triangles, on a random mesh deep enough to split."""
    rng = np.random.default_rng(zmask)
    v = rng.uniform(-1, 1, (300, 3))
    f = rng.integers(0, 300, (400, 3))
    root = octree.build(v, f)
    got = octree.reachable_trigs(root, zmask, 0)
    want = _low_leaves(octree.build(v, f), child_ok)
    assert got == want and 0 < len(got) < 400


def test_node_table_is_the_binarys_octree(a5_data) -> None:
    """plugins/emulation/octree_leaves.py builds the octree a level at a time as a node table (first child's
    index, 0 for a leaf); its nodes are those of the node-by-node builder of converters/octree.py (the binary's
    split rule) on the course's diamond: the same root box, every node a leaf exactly where that one's is,
    children in the same order."""
    from a5mi.plugins.emulation.octree_leaves import mesh_nodes

    mesh = load_obj(a5_data / "scenes" / "diamond.obj")
    v, f = np.asarray(mesh.vertices, dtype=np.float32), np.asarray(mesh.faces, dtype=np.int64)
    mn, mx, child = mesh_nodes(v[f])
    root = octree.build(v, f)
    assert np.array_equal(mn, root.mn) and np.array_equal(mx, root.mx)
    stack, visited, levels = [(root, 0)], 0, set()
    while stack:
        node, index = stack.pop()
        visited += 1
        levels.add(node.level)
        assert (child[index] == 0) == node.is_leaf, (index, node.level)
        if not node.is_leaf:
            stack += [(kid, int(child[index]) + i) for i, kid in enumerate(node.children)]
    assert visited == len(child) > 1000
    assert max(levels) == octree.MAX_LEVEL + 1       # down to the level-9 leaves


def test_shadow_rays_follow_the_binarys_traversal_per_ray(variant: str, scenes_dir) -> None:
    """A light straight down (``direction 0 -1 0``: the object-space shadow direction of a mesh under
    ``ZRotate 30`` has z = +0.0) over the vase: the binary's traversal of each shadow ray reaches only some of
    the leaves the reach masks allow, and leaves a patch lit that the masks shadowed (25.1 dB from a5soln before
    the per-ray replay, plugins/emulation/octree_leaves.py). Golden: tests/data/octree_shadow_a5soln.png is
    ``a5soln -input vase.txt -size 64 64 -shadows -output vase.bmp`` of this scene, converted to PNG losslessly."""

    from a5mi.platform.imageio import read_uint8

    text = ("PerspectiveCamera { center 0.3 2.5 2.5 direction -0.1 -1 -1 up 0 1 0 angle 35 }\n"
            "Lights { numLights 1 DirectionalLight { direction 0 -1 0 color 0.9 0.9 0.9 } }\n"
            "Background { color 0.1 0.1 0.2 ambientLight 0.1 0.1 0.1 }\n"
            "Materials { numMaterials 2 Material { diffuseColor 0.9 0.9 0.9 } Material { diffuseColor 0.8 0.3 0.2 } }\n"
            "Group { numObjects 2 MaterialIndex 0 Plane { normal 0 1 0 offset -0.6 }\n"
            " MaterialIndex 1 Transform { ZRotate 30 Scale 0.4 0.4 0.4 TriangleMesh { obj_file vase.obj } } }\n")
    model = parse_text(text, str(scenes_dir / "vase_shadow.txt"))
    img = quantize(render(describe(model), RenderOptions(width=N, height=N, shadows=True)).image).astype(int)
    golden = read_uint8(TESTS / "data" / "octree_shadow_a5soln.png").astype(int)
    assert np.array_equal(img, golden)

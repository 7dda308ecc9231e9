"""SPEC A.6: the OBJ subset (v, vt, f a b c, f a/ta b/tb c/tc) and the >120-vertex smooth-normal rule."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from a5mi.converters.errors import FileLoc, SceneSemanticError
from a5mi.converters.obj import face_normals, load_obj, uses_smooth_normals, vertex_normals

pytestmark = pytest.mark.unit  # the fast tier (`make check`): no Mitsuba, no child process


def _write(tmp_path: Path, text: str, name: str = "m.obj") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def test_a6_plain_faces_are_one_based_and_short_lines_comments_skipped(tmp_path: Path) -> None:
    p = _write(tmp_path, "# comment f 9 9 9\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\ns 1\nf 1 2 3\nf\n")
    mesh = load_obj(p)
    assert mesh.vertices.tolist() == [[0, 0, 0], [1, 0, 0], [0, 1, 0]]
    assert mesh.faces.tolist() == [[0, 1, 2]]
    assert mesh.texcoords is None and mesh.face_texcoords is None


def test_a6_texture_pairs(tmp_path: Path) -> None:
    p = _write(tmp_path, "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0.5 1\nf 1/3 2/1 3/2\n")
    mesh = load_obj(p)
    assert mesh.face_texcoords is not None and mesh.face_texcoords.tolist() == [[2, 0, 1]]
    assert mesh.texcoords is not None and mesh.texcoords[2].tolist() == [0.5, 1.0]


def test_a6_v_vt_vn_is_misread_like_the_starter(tmp_path: Path) -> None:
    """``f 1/1/1 2/2/2 3/3/3`` -> numbers 1 1 1 2 2 2 3 3 3 -> pairs (1,1) (1,2) (2,2)."""
    p = _write(tmp_path, "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nf 1/1/1 2/2/2 3/3/3\n")
    mesh = load_obj(p)
    assert mesh.faces.tolist() == [[0, 0, 1]]
    assert mesh.face_texcoords is not None and mesh.face_texcoords.tolist() == [[0, 1, 1]]
    assert "v/vt/vn" in mesh.warnings[0][1]


def test_a6_quad_keeps_its_first_triangle(tmp_path: Path) -> None:
    mesh = load_obj(_write(tmp_path, "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n"))
    assert mesh.faces.tolist() == [[0, 1, 2]]
    assert mesh.warnings[0][0] == FileLoc(str(tmp_path / "m.obj"), 5, 1)


@pytest.mark.parametrize(("text", "message"), [
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1  2 4\n",
     "5:8: error: face index 4 out of range: expected 1 to 3 (3 vertices)"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3/2\n",
     "5:13: error: texture coordinate index 2 out of range: expected 1 to 1 (1 'vt' lines)"),
])
def test_a6_face_index_out_of_range_is_an_error_at_the_obj_position(tmp_path: Path, text: str, message: str) -> None:
    p = _write(tmp_path, text)
    with pytest.raises(SceneSemanticError) as e:
        load_obj(p)
    assert str(e.value) == f"{p}:{message}"


def test_a6_nan_vertex_and_bad_numbers_are_errors(tmp_path: Path) -> None:
    p = _write(tmp_path, "v 0 0 0\nv 1 nan 0\n")
    with pytest.raises(SceneSemanticError) as e:
        load_obj(p)
    assert str(e.value) == f"{p}:2:5: error: expected a finite number in a vertex coordinate, found 'nan'"
    p = _write(tmp_path, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 x 3\n")
    with pytest.raises(SceneSemanticError, match=r":4:5: error: expected a face index, found 'x'"):
        load_obj(p)


def test_a6_missing_mesh_and_mesh_without_faces(tmp_path: Path) -> None:
    loc = FileLoc("s.txt", 3, 9)
    with pytest.raises(SceneSemanticError) as e:
        load_obj(tmp_path / "nope.obj", loc)
    assert str(e.value).startswith("s.txt:3:9: error: cannot read mesh file")
    with pytest.raises(SceneSemanticError, match="expected at least one 'f' face"):
        load_obj(_write(tmp_path, "v 0 0 0\n"), loc)


def _fan(n_vertices: int) -> tuple[np.ndarray, np.ndarray]:
    """A flat fan in z = 0 plus one apex vertex: ``n_vertices`` vertices in all."""
    ring = n_vertices - 1
    a = np.linspace(0, 2 * math.pi, ring, endpoint=False)
    v = np.concatenate([np.stack([np.cos(a), np.sin(a), np.zeros(ring)], 1), [[0, 0, 1.0]]])
    f = np.array([[i, (i + 1) % ring, ring] for i in range(ring)])
    return v, f


def test_a6_normal_rule_flat_at_120_vertices_smooth_at_121() -> None:
    v120, f120 = _fan(120)
    assert vertex_normals(v120, f120) is None
    assert not uses_smooth_normals(120) and uses_smooth_normals(121)
    v121, f121 = _fan(121)
    n = vertex_normals(v121, f121)
    assert n is not None and n.shape == (121, 3)
    # The apex (a cone tip over a regular ring) gets the axis direction, by symmetry.
    assert np.allclose(n[120], [0, 0, 1], atol=1e-12)
    assert np.allclose(np.linalg.norm(n, axis=1), 1.0)
    # Options: force either way; the 2015 threshold.
    assert vertex_normals(v120, f120, "smooth") is not None and vertex_normals(v121, f121, "flat") is None
    assert vertex_normals(v121, f121, smooth_threshold=500) is None


def test_a6_smooth_normals_are_area_weighted() -> None:
    """Vertex 0 shared by a big triangle in z=0 (area 2) and a small one in x=0 (area 1/2):
    n0 = normalize((0,0,4) + (1,0,0)) (cross products are twice the areas), not the unit-weighted mean."""
    v = np.array([[0, 0, 0], [2, 0, 0], [0, 2, 0], [0, 1, 0], [0, 0, 1.0]])
    f = np.array([[0, 1, 2], [0, 3, 4]])
    assert face_normals(v, f).tolist() == [[0, 0, 4], [1, 0, 0]]
    n = vertex_normals(v, f, "smooth")
    assert n is not None
    assert np.allclose(n[0], np.array([1, 0, 4]) / math.sqrt(17))
    assert np.allclose(n[1], [0, 0, 1]) and np.allclose(n[4], [1, 0, 0])


@pytest.mark.parametrize("name,n_vertices,smooth", [
    ("cube.obj", 8, False), ("diamond.obj", 57, False), ("bunny_200.obj", 102, False),
    ("bunny_1k.obj", 502, True), ("vase.obj", 1922, True),
])
def test_a6_shipped_meshes_follow_the_table(scenes_dir: Path, name: str, n_vertices: int, smooth: bool) -> None:
    mesh = load_obj(scenes_dir / name)
    assert len(mesh.vertices) == n_vertices
    assert (vertex_normals(mesh.vertices, mesh.faces) is not None) == smooth


def test_a6_shipped_textured_mesh(scenes_dir: Path) -> None:
    mesh = load_obj(scenes_dir / "tex" / "c1.obj")
    assert (len(mesh.vertices), len(mesh.faces)) == (8, 12)
    assert mesh.texcoords is not None and mesh.texcoords.shape == (24, 2)
    assert mesh.face_texcoords is not None and mesh.face_texcoords[0].tolist() == [0, 1, 2]
    assert mesh.faces[0].tolist() == [4, 0, 3]

"""Meshes in: STL and PLY faces beside the vertices the point readers give (issue 25)."""

from __future__ import annotations

import numpy as np
import pytest
from plyfile import PlyData, PlyElement

from rough_viewer.cli import main
from rough_viewer.io import load_points
from rough_viewer.io.formats.mesh import check_mesh, load_mesh
from rough_viewer.io.formats.stl import read_stl, read_stl_mesh
from rough_viewer.vocabulary import InputError

# a 3 x 3 grid of vertices, 8 triangles, z = x y
GRID = np.array([[x, y, x * y] for y in range(3) for x in range(3)], dtype=float)
TRIS = np.array([[0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 4],
                 [3, 4, 7], [3, 7, 6], [4, 5, 8], [4, 8, 7]])


def write_ascii_stl(path, vertices, faces):
    lines = ["solid test"]
    for f in faces:
        lines += ["facet normal 0 0 1", " outer loop"]
        lines += [f"  vertex {float(vertices[i, 0])!r} {float(vertices[i, 1])!r} {float(vertices[i, 2])!r}" for i in f]
        lines += [" endloop", "endfacet"]
    lines.append("endsolid test")
    path.write_text("\n".join(lines) + "\n")


def write_binary_stl(path, vertices, faces):
    rec = np.zeros(len(faces), dtype=[("normal", "<f4", (3,)), ("v", "<f4", (3, 3)),
                                      ("attr", "<u2")])
    rec["v"] = vertices[faces]
    with open(path, "wb") as fh:
        fh.write(b"\0" * 80 + np.uint32(len(faces)).tobytes())
        fh.write(rec.tobytes())


def triangles_as_sets(vertices, faces):
    """Each triangle as the frozenset of its corners (order and index free)."""
    return {frozenset(map(tuple, vertices[f].round(9))) for f in faces}


@pytest.mark.parametrize("writer", [write_ascii_stl, write_binary_stl])
def test_stl_mesh_has_every_triangle_and_the_point_readers_vertices(tmp_path, writer):
    path = tmp_path / "grid.stl"
    writer(path, GRID, TRIS)
    vertices, faces = read_stl_mesh(path)
    assert faces.shape == (8, 3) and vertices.shape == (9, 3)
    assert triangles_as_sets(vertices, faces) == triangles_as_sets(GRID, TRIS)
    # the same triangles in the file's order and winding
    np.testing.assert_array_equal(vertices[faces], GRID[TRIS])
    # the point reader's output is unchanged: each vertex once, in the same order
    cloud = read_stl(path)
    np.testing.assert_array_equal(cloud.xyz(), vertices)


def test_stl_triangle_with_a_non_finite_corner_is_dropped(tmp_path):
    bad = GRID.copy()
    bad[8, 2] = np.nan
    path = tmp_path / "nan.stl"
    write_ascii_stl(path, bad, TRIS)
    _, faces = read_stl_mesh(path)
    assert faces.shape[0] == 6  # the two triangles at vertex 8 are gone


@pytest.mark.parametrize("text", [False, True])
def test_ply_faces_triangles_and_a_quad_fan(tmp_path, text):
    vertex = np.array([tuple(v) for v in GRID], dtype=[("x", "f8"), ("y", "f8"), ("z", "f8")])
    faces = np.empty(3, dtype=[("vertex_indices", "O")])
    faces["vertex_indices"][0] = np.array([0, 1, 4], dtype=np.int32)
    faces["vertex_indices"][1] = np.array([1, 2, 5, 4], dtype=np.int32)  # a quad
    faces["vertex_indices"][2] = np.array([4, 5, 9], dtype=np.int32)  # index 9 does not exist
    path = tmp_path / "mesh.ply"
    PlyData([PlyElement.describe(vertex, "vertex"), PlyElement.describe(faces, "face")],
            text=text).write(str(path))
    mesh = load_mesh(path)
    np.testing.assert_array_equal(mesh.vertices, GRID)
    np.testing.assert_array_equal(mesh.faces, [[0, 1, 4], [1, 2, 5], [1, 5, 4]])
    # the point reader still reads the vertices alone
    np.testing.assert_array_equal(load_points(path).xyz(), GRID)


def test_ply_of_triangles_only_reads_fast_path_and_units(tmp_path):
    vertex = np.array([tuple(v) for v in GRID], dtype=[("x", "f4"), ("y", "f4"), ("z", "f4")])
    faces = np.empty(len(TRIS), dtype=[("vertex_indices", "i4", (3,))])
    faces["vertex_indices"] = TRIS
    path = tmp_path / "tri.ply"
    PlyData([PlyElement.describe(vertex, "vertex"), PlyElement.describe(faces, "face")],
            text=False).write(str(path))
    mesh = load_mesh(path, units="mm")
    np.testing.assert_allclose(mesh.vertices, GRID * 1e-3)
    np.testing.assert_array_equal(mesh.faces, TRIS)
    assert mesh.source_unit == "mm" and mesh.source == str(path)


def test_files_without_faces_have_no_mesh(tmp_path):
    vertex = np.array([tuple(v) for v in GRID], dtype=[("x", "f8"), ("y", "f8"), ("z", "f8")])
    ply = tmp_path / "points.ply"
    PlyData([PlyElement.describe(vertex, "vertex")]).write(str(ply))
    xyz = tmp_path / "points.xyz"
    np.savetxt(xyz, GRID)
    assert load_mesh(ply) is None and load_mesh(xyz) is None


def test_bad_meshes_are_one_line_errors(tmp_path):
    with pytest.raises(InputError, match="no triangles"):
        check_mesh(GRID, np.empty((0, 3), dtype=int))
    with pytest.raises(InputError, match="does not exist"):
        check_mesh(GRID, [[0, 1, 9]])
    with pytest.raises(InputError, match="file not found"):
        load_mesh(tmp_path / "missing.stl")
    path = tmp_path / "broken.stl"
    path.write_bytes(b"\x00\x01garbage")
    with pytest.raises(InputError, match="not an STL file"):
        load_mesh(path)


def test_directions_command_reads_the_stl_faces(tmp_path, capsys):
    """The command measures the file's own triangles (``mesh`` in its text)."""
    path = tmp_path / "grid.stl"
    write_ascii_stl(path, GRID, TRIS)
    out = tmp_path / "d.csv"
    assert main(["directions", str(path), "--step", "90", "--out", str(out),
                 "--spacing", "0.5", "--half-width", "0.5"]) == 0
    assert "8 triangles of the file's mesh" in capsys.readouterr().out


def test_a_crop_of_the_vertices_keeps_the_triangles_of_kept_corners():
    """``kept`` against brute force on the 3 x 3 grid: the triangles all of whose
    corners are kept, as corner sets, over the kept vertices in their order."""
    mesh = check_mesh(GRID, TRIS)
    keep = GRID[:, 0] <= 1.0  # the left two columns: 6 vertices, 4 triangles
    got = mesh.kept(keep)
    want = [f for f in TRIS if all(keep[i] for i in f)]
    assert got is not None and got.n_faces == len(want) == 4
    np.testing.assert_array_equal(got.vertices, GRID[keep])
    assert triangles_as_sets(got.vertices, got.faces) == triangles_as_sets(GRID, np.array(want))
    assert mesh.kept(GRID[:, 0] == 0.0) is None  # a line of vertices: no triangle
    with pytest.raises(ValueError, match="cannot crop a mesh of 9 vertices") as bug:
        mesh.kept(np.ones(4, dtype=bool))
    assert type(bug.value) is ValueError  # the caller's mistake, not the user's


@pytest.mark.parametrize("byte_order", ["<", ">", "="])
def test_ply_faces_after_other_elements_and_with_more_properties(tmp_path, byte_order):
    """An element before the vertices, a face property beside the lists, either byte
    order and ASCII ("="): the faces as plyfile (the writer here) wrote them."""
    rng = np.random.default_rng(4)
    vertex = np.array([(*v, k) for k, v in enumerate(GRID)], dtype=[("x", "f4"), ("y", "f4"), ("z", "f4"),
                                                       ("w", "u1")])
    meta = np.array([(1.5, 7), (2.5, 8)], dtype=[("a", "f8"), ("b", "i2")])
    faces = np.empty(len(TRIS) + 1, dtype=[("flag", "u1"), ("vertex_index", "O")])
    for k, f in enumerate(TRIS):
        faces[k] = (rng.integers(0, 9), np.asarray(f, dtype=np.uint32))
    faces[len(TRIS)] = (1, np.array([0, 1, 2, 5, 4], dtype=np.uint32))  # a pentagon: 3 triangles
    path = tmp_path / "more.ply"
    PlyData([PlyElement.describe(meta, "meta"), PlyElement.describe(vertex, "vertex"),
             PlyElement.describe(faces, "face", val_types={"vertex_index": "uint32"})],
            text=byte_order == "=", byte_order=byte_order if byte_order != "=" else "<"
            ).write(str(path))
    mesh = load_mesh(path)
    np.testing.assert_array_equal(mesh.vertices, GRID.astype(np.float32))
    want = np.vstack([TRIS, [[0, 1, 2], [0, 2, 5], [0, 5, 4]]])
    np.testing.assert_array_equal(mesh.faces, want)


def test_a_ply_ending_inside_its_faces_is_one_line(tmp_path):
    vertex = np.array([tuple(v) for v in GRID], dtype=[("x", "f8"), ("y", "f8"), ("z", "f8")])
    faces = np.empty(2, dtype=[("vertex_indices", "O")])
    faces["vertex_indices"][0] = np.array([0, 1, 4, 3], dtype=np.int32)
    faces["vertex_indices"][1] = np.array([1, 2, 5], dtype=np.int32)
    path = tmp_path / "cut.ply"
    PlyData([PlyElement.describe(vertex, "vertex"), PlyElement.describe(faces, "face")]
            ).write(str(path))
    path.write_bytes(path.read_bytes()[:-6])
    with pytest.raises(InputError, match="PLY file is truncated"):
        load_mesh(path)

"""The file readers on bad files: PLY and OBJ through the checking readers (equal to VTK's on
every valid file, a ValueError naming the problem on a truncated or malformed one), empty files
of every kind, meshio's exits, and the command line's handling of both. The crash cases run in a
subprocess (isolated.py): VTK 9.1's vtkPLYReader segfaulted or aborted on them."""

import glob
import os

import numpy as np
import pytest
import pyvista as pv
from vtkmodules.util.numpy_support import vtk_to_numpy
from vtkmodules.vtkIOGeometry import vtkOBJReader
from vtkmodules.vtkIOPLY import vtkPLYReader

import matrixtree
from matrixtree import cli, scenes
from isolated import outcome

DATA = scenes.data_dir()
MESHES = sorted(glob.glob(os.path.join(DATA, "meshes", "*.ply")) + glob.glob(os.path.join(DATA, "meshes", "*.obj"))
                + [os.path.join(DATA, "scenes", "utah_hand", "hand_00.obj"),
                   os.path.join(DATA, "scenes", "utah_ben", "ben_00.obj"),
                   os.path.join(DATA, "animated", "horse_poses", "horse-01.obj")])


def arrays(pd):
    """Points (float64) and the polygon connectivity (offsets, ids) of a polydata."""
    polys = pd.GetPolys()
    return (vtk_to_numpy(pd.GetPoints().GetData()).astype(np.float64),
            vtk_to_numpy(polys.GetOffsetsArray()).astype(np.int64),
            vtk_to_numpy(polys.GetConnectivityArray()).astype(np.int64))


def read_ply(path):
    from matrixtree._readers import read_ply

    return read_ply(path)


def read_obj(path):
    from matrixtree._readers import read_obj

    return read_obj(path)


def vtk_read(path):
    r = vtkPLYReader() if path.endswith(".ply") else vtkOBJReader()
    r.SetFileName(path)
    r.Update()
    return r.GetOutput()


def assert_same_mesh(ours, theirs):
    for a, b in zip(arrays(ours), arrays(theirs)):
        np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("path", MESHES, ids=os.path.basename)
def test_checking_readers_give_vtks_mesh_on_the_shared_meshes(path):
    """The triangles read_mesh hands on equal those of VTK's reader through the same filters."""
    assert os.path.exists(path), path
    from matrixtree.core import _triangulated

    ours = matrixtree.read_mesh(path)
    theirs = _triangulated(vtk_read(path), merge_points=path.endswith(".obj"))
    assert ours.GetNumberOfPolys() > 1000
    assert_same_mesh(ours, theirs)


def mixed_polygons():
    """Triangles and quads, so that PLY face lists differ in length (the record-by-record path)."""
    plane = pv.Plane(i_resolution=7, j_resolution=5).triangulate()
    quads = pv.Plane(center=(0, 0, 1), i_resolution=3, j_resolution=4)
    return (plane + quads).clean()


@pytest.mark.parametrize("binary", [True, False])
@pytest.mark.parametrize("mesh", ["triangles", "mixed"])
def test_ply_reader_equals_vtks_on_written_files(tmp_path, binary, mesh):
    pd = pv.Sphere(theta_resolution=9, phi_resolution=7) if mesh == "triangles" else mixed_polygons()
    path = str(tmp_path / "m.ply")
    pd.save(path, binary=binary)
    assert_same_mesh(read_ply(path), vtk_read(path))


def test_ply_reader_reads_big_endian_doubles_and_extra_properties(tmp_path):
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0000000001]])
    faces = [(3, 0, 1, 2), (4, 0, 1, 3, 2)]
    head = ("ply\nformat binary_big_endian 1.0\ncomment doubles\nelement vertex 4\nproperty double x\n"
            "property double y\nproperty double z\nproperty uchar red\nelement face 2\n"
            "property list uchar uint vertex_indices\nproperty float quality\nend_header\n").encode()
    body = b"".join(p.astype(">f8").tobytes() + b"\x07" for p in pts)
    for f in faces:
        body += np.uint8(f[0]).tobytes() + np.array(f[1:], ">u4").tobytes() + np.float32(0.5).astype(">f4").tobytes()
    path = tmp_path / "be.ply"
    path.write_bytes(head + body)
    pd = read_ply(str(path))
    got_pts, off, conn = arrays(pd)
    np.testing.assert_array_equal(got_pts, pts)  # doubles kept, not rounded to float
    assert list(off) == [0, 3, 7] and list(conn) == [0, 1, 2, 0, 1, 3, 2]


def subprocess_read_mesh(path):
    return outcome(f"""
        import matrixtree
        try:
            m = matrixtree.read_mesh({str(path)!r})
            print("read", m.GetNumberOfPolys())
        except ValueError as e:
            print("ValueError", e)
    """, timeout=120)


def test_truncated_ascii_ply_is_an_error_not_a_crash(tmp_path):
    """Half of bunny.ply's bytes (ASCII), on which VTK 9.1's vtkPLYReader segfaults: a ValueError."""
    src = open(os.path.join(DATA, "meshes", "bunny.ply"), "rb").read()
    path = tmp_path / "half.ply"
    path.write_bytes(src[:len(src) // 2])
    got = subprocess_read_mesh(path)
    assert got.startswith("ValueError") and "truncated or damaged file" in got, got


def test_truncated_binary_ply_is_an_error_not_a_crash(tmp_path):
    """A binary PLY cut at 75%, on which vtkPLYReader aborts with "double free": a ValueError."""
    src = open(os.path.join(DATA, "meshes", "lucy.ply"), "rb").read()
    path = tmp_path / "cut.ply"
    path.write_bytes(src[:3 * len(src) // 4])
    got = subprocess_read_mesh(path)
    assert got.startswith("ValueError") and "'face' record" in got and "past the end of the file" in got, got


def test_ply_declaring_a_billion_faces_is_an_error_not_a_crash(tmp_path):
    src = open(os.path.join(DATA, "meshes", "lucy.ply"), "rb").read()
    path = tmp_path / "huge.ply"
    path.write_bytes(src.replace(b"element face 99970", b"element face 1000000000", 1))
    got = subprocess_read_mesh(path)
    assert got.startswith("ValueError") and "declares 1000000000 'face' elements" in got, got


@pytest.mark.parametrize("binary", [True, False])
def test_every_truncation_of_a_ply_is_read_or_refused(tmp_path, binary):
    """Cut at 40 points through the file: a whole mesh, or a ValueError naming the damage."""
    path = str(tmp_path / "m.ply")
    mixed_polygons().save(path, binary=binary)
    src = open(path, "rb").read()
    full = read_ply(path).GetNumberOfPolys()
    for cut in np.linspace(0, len(src) - 1, 40).astype(int):
        with open(path, "wb") as f:
            f.write(src[:cut])
        try:
            assert read_ply(path).GetNumberOfPolys() == full  # ASCII may lose only trailing blanks
        except ValueError as e:
            assert str(path) in str(e)


@pytest.mark.parametrize("face,match", [
    ("f 1 2 999", r"line 4: the face index 999 is out of range: 3 vertices are defined before it"),
    ("f 1 2 -4", r"line 4: the face index -4 is out of range"),
    ("f 0 1 2", r"line 4: face index 0 is invalid \(OBJ indices start at 1\)"),
    ("f 1 2 x", r"line 4: a face corner is not an index"),
])
def test_obj_face_index_out_of_range_is_an_error(tmp_path, face, match):
    """`f 1 2 999`, whose vertex vtkOBJReader reads from out-of-bounds memory: a ValueError."""
    path = tmp_path / "bad.obj"
    path.write_text(f"v 0 0 0\nv 1 0 0\nv 0 1 0\n{face}\n")
    with pytest.raises(ValueError, match=match):
        matrixtree.read_mesh(str(path))


def test_obj_negative_indices_count_back_from_the_last_vertex(tmp_path):
    path = tmp_path / "rel.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\nv 5 5 5\nv 6 5 5\nf 1/1/1 -1//2 -2\n")
    pts, off, conn = arrays(read_obj(str(path)))
    assert list(off) == [0, 3, 6] and list(conn) == [0, 1, 2, 0, 4, 3]
    assert pts[4].tolist() == [6, 5, 5]


@pytest.mark.parametrize("name", ["m.ply", "m.obj", "m.stl", "m.vtp", "m.vtk"])
def test_empty_mesh_files_are_an_error(tmp_path, name):
    (tmp_path / name).write_bytes(b"")
    with pytest.raises(ValueError, match="file is empty"):
        matrixtree.read_mesh(str(tmp_path / name))


@pytest.mark.parametrize("name", ["g.su2", "g.vtu", "g.vtk", "g.ex2", "g.msh"])
def test_empty_grid_files_are_an_error_not_an_exit(tmp_path, name):
    """meshio's SU2 reader calls sys.exit() on an empty file: a ValueError, the process goes on."""
    (tmp_path / name).write_bytes(b"")
    with pytest.raises(ValueError, match="file is empty"):
        matrixtree.read_grid(str(tmp_path / name))


@pytest.mark.parametrize("name", ["v.mhd", "v.vtk", "v.vti", "v.nii", "v.slc"])
def test_empty_volume_files_are_an_error(tmp_path, name):
    (tmp_path / name).write_bytes(b"")
    with pytest.raises(ValueError, match="file is empty"):
        matrixtree.read_volume(str(tmp_path / name))


def test_meshio_failures_become_value_errors(tmp_path):
    path = tmp_path / "junk.msh"
    path.write_text("$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 5 1 5\n3 1 0 5\n1\n")
    with pytest.raises(ValueError, match="meshio could not read it"):
        matrixtree.read_grid(str(path))
    path = tmp_path / "junk.su2"  # the same damage in SU2, read by the checking reader
    path.write_text("NDIME= 3\nNELEM= 5\n10 0 1 2\n")
    with pytest.raises(ValueError, match="junk.su2: NELEM= declares 5 elements, but only 1 element lines follow"):
        matrixtree.read_grid(str(path))


def test_cli_reports_an_empty_grid_and_exits_2(tmp_path, capsys):
    (tmp_path / "g.su2").write_bytes(b"")
    np.save(tmp_path / "p.npy", np.zeros((3, 3)))
    assert cli.main(["locate", str(tmp_path / "g.su2"), str(tmp_path / "p.npy"), "--out", str(tmp_path)]) == 2
    assert "the grid file is empty" in capsys.readouterr().err


def test_cli_reports_a_truncated_mesh_and_exits_2(tmp_path):
    src = open(os.path.join(DATA, "meshes", "bunny.ply"), "rb").read()
    (tmp_path / "half.ply").write_bytes(src[:len(src) // 2])
    got = outcome(f"""
        import sys
        from matrixtree import cli
        print("rc", cli.main(["render", {str(tmp_path / "half.ply")!r}, "--size", "8", "8", "--out", {str(tmp_path)!r}]))
    """)
    assert got == "rc 2", got


def test_cli_takes_options_before_the_file_argument(tmp_path):
    bunny = os.path.join(DATA, "meshes", "bunny.ply")
    assert cli.main(["render", "--size", "24", "16", "--methods", "octree", "--out", str(tmp_path), bunny]) == 0
    assert (tmp_path / "bunny_octree.png").exists()
    assert cli.main(["--out", str(tmp_path / "b"), "render", "--methods", "kdtree", bunny, "--size", "24", "16"]) == 0
    assert (tmp_path / "b" / "bunny_kdtree.png").exists()


# ---------------------------------------------------------------------------------------------
# PLY triangle strips, OFF, SU2: the files users meet that VTK 9.1 or meshio misread or refuse
# ---------------------------------------------------------------------------------------------
def strip_grid(nx, ny):
    """Points of an nx x ny grid of unit squares in z = 0, and its rows as triangle strips (one
    list per row), every strip's first triangle counter-clockwise seen from +z."""
    ii, jj = np.meshgrid(np.arange(nx + 1), np.arange(ny + 1), indexing="xy")
    pts = np.column_stack([ii.ravel(), jj.ravel(), np.zeros(ii.size)]).astype(np.float64)
    top = lambda j, i: (j + 1) * (nx + 1) + i  # noqa: E731
    strips = [[v for i in range(nx + 1) for v in (top(j, i), j * (nx + 1) + i)] for j in range(ny)]
    return pts, strips


def triangle_normals_and_area(pd):
    p, off, conn = arrays(pd)
    assert np.all(np.diff(off) == 3)
    t = p[conn.reshape(-1, 3)]
    n = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
    return n, 0.5 * np.linalg.norm(n, axis=1).sum()


def write_strips_ply(path, pts, records, binary):
    head = (f"ply\nformat {'binary_little_endian' if binary else 'ascii'} 1.0\nelement vertex {len(pts)}\n"
            "property float x\nproperty float y\nproperty float z\n"
            f"element tristrips {len(records)}\nproperty list int int vertex_indices\nend_header\n").encode()
    if binary:
        body = pts.astype("<f4").tobytes() + b"".join(np.array([len(r)] + list(r), "<i4").tobytes() for r in records)
    else:
        body = ("".join(f"{x} {y} {z}\n" for x, y, z in pts)
                + "".join(" ".join(map(str, [len(r)] + list(r))) + "\n" for r in records)).encode()
    path.write_bytes(head + body)


@pytest.mark.parametrize("binary", [True, False])
def test_ply_triangle_strips_are_read_as_triangles(tmp_path, binary):
    """A 5 x 3 grid of unit squares as strips: one record per row, then the same rows joined into
    one record with -1 between strips: 30 triangles, all facing +z, of total area 15."""
    pts, strips = strip_grid(5, 3)
    for records in (strips, [sum(([-1] + s for s in strips[1:]), strips[0])]):
        path = tmp_path / "strips.ply"
        write_strips_ply(path, pts, records, binary)
        pd = read_ply(str(path))
        normals, area = triangle_normals_and_area(pd)
        assert pd.GetNumberOfPolys() == 30
        assert area == pytest.approx(15.0)
        assert np.all(normals[:, 2] > 0) and np.allclose(normals[:, :2], 0)
        mesh = matrixtree.read_mesh(str(path))  # the public reader: no more "holds no polygons"
        assert mesh.GetNumberOfPolys() == 30


def test_ply_strips_equal_vtks_strip_decomposition(tmp_path):
    """Strips joined by repeated vertices (degenerate triangles), as stripifiers write them: the
    triangles equal vtkTriangleFilter's decomposition of the same strips, less its triangles that
    repeat a vertex."""
    from vtkmodules.vtkCommonDataModel import vtkCellArray, vtkPolyData
    from vtkmodules.vtkFiltersCore import vtkTriangleFilter

    pts, strips = strip_grid(4, 2)
    joined = strips[0] + [strips[0][-1], strips[1][0]] + strips[1]
    path = tmp_path / "joined.ply"
    write_strips_ply(path, pts, [joined], binary=False)
    ca = vtkCellArray()
    ca.InsertNextCell(len(joined), joined)
    src = vtkPolyData()
    src.SetPoints(read_ply(str(path)).GetPoints())
    src.SetStrips(ca)
    tf = vtkTriangleFilter()
    tf.SetInputData(src)
    tf.Update()
    want = arrays(tf.GetOutput())[2].reshape(-1, 3)
    want = want[(want[:, 0] != want[:, 1]) & (want[:, 1] != want[:, 2]) & (want[:, 0] != want[:, 2])]
    got = arrays(read_ply(str(path)))[2].reshape(-1, 3)
    np.testing.assert_array_equal(got, want)
    assert len(got) == 16


def test_ply_strip_index_out_of_range_is_an_error(tmp_path):
    path = tmp_path / "bad.ply"
    write_strips_ply(path, np.eye(3), [[0, 1, 2, 7]], binary=False)
    with pytest.raises(ValueError, match=r"bad.ply: tristrips record 0 refers to vertex 7.0, but the file has 3"):
        read_ply(str(path))


def off_text(pd, key="OFF", comments=True, counts_on_header=False, newline="\n"):
    """``pd`` (points, polygons) as OFF text with header ``key``, the extra per-vertex values the
    key announces (ST: texture, C: colour, N: normal), a colour after every face, comments."""
    p, off, conn = arrays(pd)
    faces = np.split(conn, off[1:-1])
    head = f"{key} {len(p)} {len(faces)} 0" if counts_on_header else f"{key}\n# counts follow\n{len(p)} {len(faces)} 0"
    lines = ["# written by the test", head] if comments else [head]
    for x, y, z in p:
        extra = (" 0 0 1" if "N" in key else "") + (" 0.5 0.5 0.5 1" if "C" in key else "") + \
            (" 0.25 0.75" if key.startswith("ST") else "")
        lines.append(f"{x!r} {y!r} {z!r}{extra}" + ("  # a vertex" if comments else ""))
    lines += [f"{len(f)} " + " ".join(map(str, f)) + " 255 0 0" for f in faces]
    return newline.join(lines) + newline


@pytest.mark.parametrize("key", ["OFF", "COFF", "NOFF", "CNOFF", "STOFF", "STCNOFF"])
@pytest.mark.parametrize("newline", ["\n", "\r\n"])
def test_off_reader_reads_the_written_polygons(tmp_path, key, newline):
    from matrixtree._readers import read_off

    src = mixed_polygons()
    path = tmp_path / "m.off"
    path.write_bytes(off_text(src, key, newline=newline).encode())
    for a, b in zip(arrays(read_off(str(path))), arrays(src)):
        np.testing.assert_array_equal(a, b)


def test_off_with_counts_on_the_header_line_and_n_dimension(tmp_path):
    from matrixtree._readers import read_off

    src = pv.Sphere(theta_resolution=6, phi_resolution=5)
    (tmp_path / "a.off").write_text(off_text(src, counts_on_header=True, comments=False))
    text = off_text(src, comments=False).replace("OFF\n", "nOFF\n3\n", 1)
    (tmp_path / "b.off").write_text(text)
    for name in ("a.off", "b.off"):
        for a, b in zip(arrays(read_off(str(tmp_path / name))), arrays(src)):
            np.testing.assert_array_equal(a, b)
    mesh = matrixtree.read_mesh(str(tmp_path / "a.off"))  # the public reader, triangulated
    assert mesh.GetNumberOfPolys() == src.triangulate().n_cells


#: a damaged OFF file's text -> the error's words
BAD_OFF = {
    "binary": ("OFF BINARY\n", r"binary OFF is not supported"),
    "4-D": ("4OFF\n1 0 0\n0 0 0 1\n", r"4-D vertices"),
    "n-D": ("nOFF\n4\n1 0 0\n0 0 0 0\n", r"dimension '4'"),
    "not OFF": ("PLY\n", r"not an OFF file"),
    "truncated": ("OFF\n3 1\n0 0 0\n1 0 0\n", r"declares 3 vertices and 1 faces, but only 2 data lines follow"),
    "bad index": ("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n", r"line 6: face 0 refers to vertex 3, but the file has 3"),
    "bad number": ("OFF\n3 1 0\n0 0 0\n1 x 0\n0 1 0\n3 0 1 2\n", r"line 4: a vertex needs three numbers"),
    "short face": ("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n4 0 1 2\n", r"line 6: the face lists 4 vertices but holds 3"),
    "bad counts": ("OFF\nthree 1 0\n", r"line 2: expected the counts"),
}


@pytest.mark.parametrize("case", sorted(BAD_OFF))
def test_bad_off_files_are_errors_naming_the_line(tmp_path, case):
    text, match = BAD_OFF[case]
    path = tmp_path / "bad.off"
    path.write_text(text)
    with pytest.raises(ValueError, match=match) as e:
        matrixtree.read_mesh(str(path))
    assert str(path) in str(e.value)


def su2_text(grid, newline="\n", zones=None):
    """``grid`` (a pyvista UnstructuredGrid of linear cells) in SU2's native format, with its
    surface as one marker; ``zones``: several such grids as one multi-zone file."""
    def zone(g):
        p = np.asarray(g.points)
        lines = ["NDIME= 3", f"NELEM= {g.n_cells}"]
        for k in range(g.n_cells):
            cell = g.get_cell(k)
            lines.append(f"{int(cell.type)} " + " ".join(map(str, cell.point_ids)) + f" {k}")
        lines.append(f"NPOIN= {len(p)}")
        lines += [f"{x!r} {y!r} {z!r} {k}" for k, (x, y, z) in enumerate(p)]
        surf = g.extract_surface(pass_pointid=True)
        ids = np.asarray(surf.point_data["vtkOriginalPointIds"])
        faces = surf.irregular_faces
        lines += ["NMARK= 1", "MARKER_TAG= wall", f"MARKER_ELEMS= {len(faces)}"]
        lines += [f"{5 if len(f) == 3 else 9} " + " ".join(str(ids[i]) for i in f) for f in faces]
        return lines

    if zones is None:
        lines = ["% a test grid"] + zone(grid)
    else:
        lines = [f"NZONE= {len(zones)}"]
        for k, g in enumerate(zones, start=1):
            lines += [f"IZONE= {k}"] + zone(g)
    return newline.join(lines) + newline


def small_grid(shift=0.0):
    """A 2 x 2 x 1 box of hexahedra with two wedges on one of them (22 points, 6 cells)."""
    x, y, z = np.meshgrid([0.0, 1, 2], [0.0, 1, 2], [0.0, 1], indexing="ij")
    lattice = np.column_stack([x.ravel(order="F"), y.ravel(order="F"), z.ravel(order="F")])  # id = i + 3j + 9k
    top = np.array([[0, 0, 2], [1, 0, 2], [0, 1, 2], [1, 1, 2]], float)  # ids 18..21

    def at(i, j, k):
        return i + 3 * j + 9 * k

    hexes = [[at(i, j, 0), at(i + 1, j, 0), at(i + 1, j + 1, 0), at(i, j + 1, 0),
              at(i, j, 1), at(i + 1, j, 1), at(i + 1, j + 1, 1), at(i, j + 1, 1)] for j in range(2) for i in range(2)]
    wedges = [[at(0, 0, 1), at(1, 0, 1), at(0, 1, 1), 18, 19, 20], [at(1, 0, 1), at(1, 1, 1), at(0, 1, 1), 19, 21, 20]]
    g = pv.UnstructuredGrid({pv.CellType.HEXAHEDRON: np.array(hexes), pv.CellType.WEDGE: np.array(wedges)},
                            np.vstack([lattice, top]))
    g.points += np.array([shift, 0.0, 0.0])
    return g


def grid_arrays(g):
    return [vtk_to_numpy(a) for a in (g.GetPoints().GetData(), g.GetCells().GetOffsetsArray(),
                                      g.GetCells().GetConnectivityArray(), g.GetCellTypesArray())]


def meshio_grid(path, volume_only=True):
    from matrixtree.grids import read_grid_here

    return read_grid_here(str(path), "1" if volume_only else "0")  # meshio's SU2 reader


SHARED_SU2 = sorted(glob.glob(os.path.join(DATA, "cfd", "*.su2")))


@pytest.mark.parametrize("path", SHARED_SU2, ids=os.path.basename)
def test_su2_reader_equals_meshio_on_the_shared_grids(path):
    """The same points and cells; with the markers' faces (volume_only=False) meshio groups the
    cells by type, so the cells are compared as sorted (type, point ids) rows."""
    ours = matrixtree.read_grid(path)
    assert ours.GetNumberOfCells() > 10000
    for a, b in zip(grid_arrays(ours), grid_arrays(meshio_grid(path))):
        np.testing.assert_array_equal(a, b)

    def sorted_cells(g):
        _, off, conn, types = grid_arrays(g)
        return sorted((int(t), tuple(c)) for t, c in zip(types, np.split(conn, off[1:-1])))

    ours = matrixtree.read_grid(path, volume_only=False)
    assert ours.GetNumberOfCells() > ours.GetNumberOfPoints() // 10 + 10000
    assert sorted_cells(ours) == sorted_cells(meshio_grid(path, volume_only=False))


@pytest.mark.parametrize("newline", ["\r\n", "\r"])
def test_su2_with_crlf_or_cr_line_ends_reads_as_with_lf(tmp_path, newline):
    g = small_grid()
    (tmp_path / "lf.su2").write_bytes(su2_text(g).encode())
    (tmp_path / "crlf.su2").write_bytes(su2_text(g, newline).encode())
    want = grid_arrays(meshio_grid(tmp_path / "lf.su2"))
    assert want[3].tolist().count(12) == 4 and 13 in want[3]
    for a, b in zip(grid_arrays(matrixtree.read_grid(str(tmp_path / "crlf.su2"))), want):
        np.testing.assert_array_equal(a, b)


def test_two_zone_su2_keeps_each_zone_on_its_own_points(tmp_path):
    """Zone 2 is zone 1 moved by +10 in x; both number their points from 0. Every cell of the
    merged grid must lie in its own zone's box, and zone=k must equal zone k read alone."""
    z1, z2 = small_grid(), small_grid(10.0)
    path = tmp_path / "two.su2"
    path.write_text(su2_text(None, zones=[z1, z2]))
    g = pv.wrap(matrixtree.read_grid(str(path)))
    assert g.n_points == z1.n_points + z2.n_points and g.n_cells == z1.n_cells + z2.n_cells
    zone = np.asarray(g.cell_data["zone"])
    centers = np.asarray(g.cell_centers().points)
    np.testing.assert_array_equal(zone, np.repeat([1, 2], [z1.n_cells, z2.n_cells]))
    assert np.all(centers[zone == 1, 0] < 2) and np.all(centers[zone == 2, 0] > 10)
    np.testing.assert_allclose(g.volume, z1.volume + z2.volume)
    for k, z in ((1, z1), (2, z2)):
        (tmp_path / f"z{k}.su2").write_text(su2_text(z))
        for a, b in zip(grid_arrays(matrixtree.read_grid(str(path), zone=k)),
                        grid_arrays(matrixtree.read_grid(str(tmp_path / f"z{k}.su2")))):
            np.testing.assert_array_equal(a, b)
    with pytest.raises(ValueError, match=r"two.su2: zone=3, but the file's zones are \[1, 2\]"):
        matrixtree.read_grid(str(path), zone=3)


@pytest.mark.parametrize("edit,match", [
    (lambda t: t.replace("\n12 ", "\n112 ", 1), r"line 3: element type 112 is a degree-2 hexahedron of SU2's high-order"),
    (lambda t: t.replace("\n12 ", "\n24 ", 1), r"line 3: unknown SU2 element type 24"),
    (lambda t: t.replace("NELEM= 6", "NELEM= 7"), r"NELEM= declares 7 elements, but only 6 element lines follow"),
    (lambda t: t.replace("NELEM= 6", "NELEM= 5"), r"line 8: a data line where a keyword"),
    (lambda t: t.replace("\n12 0 1 4 3", "\n12 0 1 4 99", 1), r"element 0 of the section at line 2 refers to point 99"),
    (lambda t: t.replace("NDIME= 3", "NDIME= 4"), r"line 1: NDIME= 4"),
    (lambda t: t.replace("NPOIN= ", "NPOIN= x"), r"NPOIN= needs a count"),
    (lambda t: t.replace("\n0.0 0.0 0.0 0", "\n0.0 zero 0.0 0", 1), r"a point needs 3 coordinates"),
])
def test_bad_su2_files_are_errors_naming_the_line(tmp_path, edit, match):
    text = su2_text(small_grid()).replace("% a test grid\n", "")
    path = tmp_path / "bad.su2"
    path.write_text(edit(text))
    assert edit(text) != text
    with pytest.raises(ValueError, match=match) as e:
        matrixtree.read_grid(str(path))
    assert str(path) in str(e.value)


def test_cli_locates_in_one_zone_of_a_two_zone_su2(tmp_path, capsys):
    path = tmp_path / "two.su2"
    path.write_text(su2_text(None, zones=[small_grid(), small_grid(10.0)]))
    np.save(tmp_path / "p.npy", np.array([[0.5, 0.5, 0.5], [10.5, 0.5, 0.5]]))
    for zone, inside in (("1", [True, False]), ("2", [False, True])):
        out = tmp_path / f"z{zone}"
        assert cli.main(["locate", str(path), str(tmp_path / "p.npy"), "--zone", zone, "--out", str(out)]) == 0
        assert ((np.load(out / "p_located.npz")["cell_ids"] >= 0) == inside).all()

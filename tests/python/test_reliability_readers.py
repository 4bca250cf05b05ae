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
    path = tmp_path / "junk.su2"
    path.write_text("NDIME= 3\nNELEM= 5\n10 0 1 2\n")
    with pytest.raises(ValueError, match="meshio could not read it"):
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

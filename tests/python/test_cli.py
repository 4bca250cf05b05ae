"""The command line (python -m matrixtree): the main job's demo, render, frames and locate."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest

import matrixtree
from matrixtree import cli, scenes

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def test_demo_writes_table_and_pictures(tmp_path, capsys):
    rc = cli.main(["demo", "--frames", "2", "--resolution", "0.2", "--size", "48", "32", "--out", str(tmp_path)])
    assert rc == 0
    out = capsys.readouterr().out
    assert "SAH kd-tree, stack" in out and "matrix octree" in out
    rows = json.load(open(tmp_path / "demo_table.json"))
    assert [r["method"] for r in rows] == list(cli.METHODS)
    for r in rows:
        assert r["frames"] == 2 and r["build_ms"] > 0 and r["render_ms"] > 0
        assert r["node_visits_per_ray"] > 0 and r["triangle_tests_per_ray"] > 0
        for suffix in ("", "_node_visits", "_triangle_tests"):
            assert (tmp_path / f"demo_{r['method']}{suffix}.png").stat().st_size > 100
    # every method sees the same scene: the SAH renders equal the octree's pixel for pixel on
    # the first frame's colour, up to edge ties
    from PIL import Image

    a = np.asarray(Image.open(tmp_path / "demo_octree.png"))
    b = np.asarray(Image.open(tmp_path / "demo_sah-stack.png"))
    assert np.mean(np.any(a != b, axis=2)) < 0.01


def test_render_and_frames_on_files(tmp_path):
    horse = os.path.join(scenes.data_dir(), "animated", "horse_poses")
    assert cli.main(["frames", horse, "--size", "40", "30", "--methods", "octree,sah-stack",
                     "--out", str(tmp_path)]) == 0
    rows = json.load(open(tmp_path / "horse_poses_table.json"))
    assert rows[0]["frames"] == len([f for f in os.listdir(horse) if f.endswith(".obj")])
    bunny = os.path.join(scenes.data_dir(), "meshes", "bunny.ply")
    assert cli.main(["render", bunny, "--size", "40", "30", "--methods", "kdtree", "--out", str(tmp_path)]) == 0
    assert (tmp_path / "bunny_kdtree.png").exists()


def test_locate_file_of_points_matches_locator(tmp_path):
    grid_path = os.path.join(scenes.data_dir(), "cfd", "pipe_flow_tets.vtu")
    grid = matrixtree.read_grid(grid_path)
    rng = np.random.default_rng(3)
    b = np.array(grid.GetBounds()).reshape(3, 2)
    pts = b[:, 0] + rng.random((2000, 3)) * (b[:, 1] - b[:, 0])
    np.save(tmp_path / "pts.npy", pts)
    np.savetxt(tmp_path / "pts.csv", pts, delimiter=",")
    assert cli.main(["locate", grid_path, str(tmp_path / "pts.npy"), "--out", str(tmp_path)]) == 0
    assert cli.main(["locate", grid_path, str(tmp_path / "pts.csv"), "--out", str(tmp_path / "csv")]) == 0
    got = np.load(tmp_path / "pts_cells.npy")
    np.testing.assert_array_equal(np.load(tmp_path / "csv" / "pts_cells.npy"), got)
    from vtkmodules.vtkCommonDataModel import vtkCellLocator

    ref = vtkCellLocator()
    ref.SetDataSet(grid)
    ref.BuildLocator()
    want = np.array([ref.FindCell(p) for p in pts])
    assert np.array_equal(got >= 0, want >= 0)
    assert np.sum(got >= 0) > 100


def test_bad_arguments_give_errors_not_tracebacks(tmp_path, capsys):
    assert cli.main(["render", str(tmp_path / "missing.ply"), "--out", str(tmp_path)]) == 2
    assert "error:" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        cli.main(["demo", "--methods", "bvh"])


def test_module_entry_point_runs():
    r = subprocess.run([sys.executable, "-m", "matrixtree", "--help"], capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 0 and "demo" in r.stdout


def test_locate_refuses_to_overwrite_results_without_force(tmp_path, capsys):
    grid_path = os.path.join(scenes.data_dir(), "cfd", "pipe_flow_tets.vtu")
    np.save(tmp_path / "pts.npy", np.zeros((4, 3)))
    (tmp_path / "out").mkdir()
    np.save(tmp_path / "out" / "pts_cells.npy", np.arange(3))
    args = ["locate", grid_path, str(tmp_path / "pts.npy"), "--out", str(tmp_path / "out")]
    assert cli.main(args) == 2
    assert "pts_cells.npy exist: pass --force to overwrite" in capsys.readouterr().err
    np.testing.assert_array_equal(np.load(tmp_path / "out" / "pts_cells.npy"), np.arange(3))
    assert cli.main(args + ["--force"]) == 0
    assert np.load(tmp_path / "out" / "pts_cells.npy").shape == (4,)


@pytest.mark.parametrize("command,names", [("render", ["file"]), ("locate", ["grid", "points", "--zone", "--force"]),
                                           ("frames", ["folder"]), ("demo", ["--resolution"])])
def test_every_subcommand_has_its_own_help(command, names, capsys):
    with pytest.raises(SystemExit) as e:
        cli.main([command, "--help"])
    out = capsys.readouterr().out
    assert e.value.code == 0 and f"python -m matrixtree {command}" in out
    assert all(n in out for n in names)


def test_render_takes_a_volume_grid_and_draws_its_surface(tmp_path):
    grid_path = os.path.join(scenes.data_dir(), "cfd", "brick_hex.su2")
    assert cli.main(["render", grid_path, "--size", "24", "16", "--methods", "octree", "--out", str(tmp_path)]) == 0
    rows = json.load(open(tmp_path / "brick_hex_table.json"))
    from vtkmodules.vtkFiltersGeometry import vtkGeometryFilter

    surface = vtkGeometryFilter()
    surface.SetInputData(matrixtree.read_grid(grid_path))
    surface.Update()
    quads = surface.GetOutput().GetNumberOfPolys()
    assert quads > 1000 and rows[0]["triangles"] == 2 * quads  # each boundary quad as two triangles


@pytest.mark.parametrize("fmt", ["vtp", "npz"])
def test_locate_writes_fields_interpolated_at_the_points(tmp_path, fmt):
    """A linear point field on tetrahedra is interpolated exactly; a cell field is the containing
    cell's; points outside get the mask 0."""
    import pyvista as pv

    grid = pv.ImageData(dimensions=(5, 4, 3), spacing=(0.5, 0.5, 0.5)).triangulate()
    grid.point_data["f"] = grid.points @ np.array([1.0, -2.0, 3.0])
    grid.cell_data["c"] = np.arange(grid.n_cells, dtype=float)
    grid.save(tmp_path / "g.vtu")
    rng = np.random.default_rng(5)
    pts = np.vstack([rng.uniform([0, 0, 0], [2, 1.5, 1], size=(50, 3)), [[5.0, 5.0, 5.0]]])
    np.save(tmp_path / "p.npy", pts)
    assert cli.main(["locate", str(tmp_path / "g.vtu"), str(tmp_path / "p.npy"), "--fields", fmt,
                     "--out", str(tmp_path / "o")]) == 0
    path = tmp_path / "o" / f"p_fields.{fmt}"
    if fmt == "vtp":
        got = pv.read(path)
        arrays = {k: np.asarray(got.point_data[k]) for k in got.point_data.keys()}
        np.testing.assert_allclose(got.points, pts)
    else:
        arrays = dict(np.load(path))
        np.testing.assert_array_equal(arrays["points"], pts)
    cells = np.load(tmp_path / "o" / "p_cells.npy")
    np.testing.assert_array_equal(arrays["cell_id"], cells)
    assert list(arrays["vtkValidPointMask"]) == [1] * 50 + [0]
    np.testing.assert_allclose(arrays["f"][:50], pts[:50] @ np.array([1.0, -2.0, 3.0]), atol=1e-12)
    np.testing.assert_array_equal(arrays["c"][:50], cells[:50])
    assert cli.main(["locate", str(tmp_path / "g.vtu"), str(tmp_path / "p.npy"), "--fields", fmt,
                     "--out", str(tmp_path / "o")]) == 2  # results there: refused


def test_render_ray_casts_a_volume_file(tmp_path):
    """The picture equals matrixtree.render_volume's image of the same volume."""
    from PIL import Image

    path = os.path.join(scenes.data_dir(), "volumes", "ironProt.vtk")
    assert cli.main(["render", path, "--size", "40", "32", "--threads", "1", "--out", str(tmp_path)]) == 0
    got = np.asarray(Image.open(tmp_path / "ironProt_volume.png"))
    want = matrixtree.render_volume(matrixtree.read_volume(path), size=(40, 32), threads=1)
    assert got.shape == (32, 40, 3) and got.max() > 50
    assert np.abs(got.astype(int) - np.clip(want[..., :3] * 255 + 0.5, 0, 255).astype(int)).max() <= 1

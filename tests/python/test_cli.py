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
    assert cli.main(["locate", grid_path, str(tmp_path / "pts.csv"), "--out", str(tmp_path), "--overwrite"]) == 0
    res = np.load(tmp_path / "pts_located.npz")
    got = res["cell_ids"]
    from vtkmodules.vtkCommonDataModel import vtkCellLocator

    ref = vtkCellLocator()
    ref.SetDataSet(grid)
    ref.BuildLocator()
    want = np.array([ref.FindCell(p) for p in pts])
    assert np.array_equal(got >= 0, want >= 0)
    assert np.sum(got >= 0) > 100
    np.testing.assert_allclose(res["points"], pts, rtol=1e-15)
    # every point field of the grid, interpolated with the located cell's weights
    names = [grid.GetPointData().GetArrayName(i) for i in range(grid.GetPointData().GetNumberOfArrays())]
    assert names and all(f"point_data/{n}" in res.files for n in names)
    probed = matrixtree.probe(grid, pts)
    for n in names + ["vtkValidPointMask"]:
        np.testing.assert_array_equal(res[f"point_data/{n}"], np.asarray(probed.point_data[n]))
    np.testing.assert_array_equal(res["point_data/vtkValidPointMask"], (got >= 0).astype(np.int8))


def test_locate_writes_point_clouds_and_never_overwrites_silently(tmp_path, capsys):
    import pyvista as pv

    grid_path = os.path.join(scenes.data_dir(), "cfd", "pipe_flow_tets.vtu")
    grid = matrixtree.read_grid(grid_path)
    c = np.array(grid.GetCenter())
    pts = c + np.random.default_rng(5).normal(scale=0.01, size=(300, 3))
    np.save(tmp_path / "p.npy", pts)
    probed = matrixtree.probe(grid, pts)
    for ext in (".vtp", ".vtu"):
        out = str(tmp_path / f"r{ext}")
        assert cli.main(["locate", grid_path, str(tmp_path / "p.npy"), "--output", out]) == 0
        cloud = pv.read(out)
        assert cloud.n_points == len(pts)
        for n in probed.point_data.keys():
            np.testing.assert_array_equal(np.asarray(cloud.point_data[n]), np.asarray(probed.point_data[n]))
        assert np.sum(np.asarray(cloud.point_data["cell_id"]) >= 0) == np.sum(probed.point_data["vtkValidPointMask"])
        before = os.path.getmtime(out), os.path.getsize(out)
        assert cli.main(["locate", grid_path, str(tmp_path / "p.npy"), "--output", out]) == 2
        assert "exists; pass --overwrite" in capsys.readouterr().err
        assert (os.path.getmtime(out), os.path.getsize(out)) == before
    assert cli.main(["locate", grid_path, str(tmp_path / "p.npy"), "--output", str(tmp_path / "r.csv")]) == 2
    assert "write .npz, .vtp or .vtu" in capsys.readouterr().err


def test_render_of_a_volume_is_render_volumes_image(tmp_path):
    from PIL import Image

    path = os.path.join(scenes.data_dir(), "volumes", "ironProt.vtk")  # legacy STRUCTURED_POINTS
    assert cli.file_kind(path) == "volume"
    assert cli.main(["render", path, "--size", "40", "32", "--out", str(tmp_path)]) == 0
    got = np.asarray(Image.open(tmp_path / "ironProt_volume.png"))
    rgba = matrixtree.render_volume(matrixtree.read_volume(path), size=(40, 32))
    want = np.clip(rgba[..., :3] * 255.0 + 0.5, 0, 255).astype(np.uint8)
    assert got.shape == (32, 40, 3) and np.array_equal(got, want) and got.max() > 0


def test_render_of_a_grid_renders_its_boundary_surface(tmp_path):
    from vtkmodules.vtkFiltersGeometry import vtkDataSetSurfaceFilter

    path = os.path.join(scenes.data_dir(), "cfd", "pipe_lumen_tets.vtu")
    assert cli.file_kind(path) == "grid"
    assert cli.main(["render", path, "--size", "40", "30", "--methods", "octree,sah-stack",
                     "--out", str(tmp_path)]) == 0
    rows = json.load(open(tmp_path / "pipe_lumen_tets_table.json"))
    surf = vtkDataSetSurfaceFilter()
    surf.SetInputData(matrixtree.read_grid(path))
    surf.Update()
    # a tetrahedral grid's boundary: one triangle per boundary face
    assert rows[0]["triangles"] == surf.GetOutput().GetNumberOfPolys() > 100
    assert (tmp_path / "pipe_lumen_tets_octree.png").stat().st_size > 100
    legacy = tmp_path / "rect.vtk"
    legacy.write_text("# vtk DataFile Version 3.0\nr\nASCII\nDATASET RECTILINEAR_GRID\nDIMENSIONS 1 1 1\n")
    assert cli.main(["render", str(legacy), "--out", str(tmp_path)]) == 2


def test_every_command_has_its_own_help():
    for cmd in cli.COMMANDS:
        r = subprocess.run([sys.executable, "-m", "matrixtree", cmd, "--help"], capture_output=True, text=True,
                           cwd=ROOT)
        assert r.returncode == 0 and f"python -m matrixtree {cmd}" in r.stdout and "--out" in r.stdout
    r = subprocess.run([sys.executable, "-m", "matrixtree", "locate", "--help"], capture_output=True, text=True,
                       cwd=ROOT)
    assert "--overwrite" in r.stdout and "--frames" not in r.stdout


def test_bad_arguments_give_errors_not_tracebacks(tmp_path, capsys):
    assert cli.main(["render", str(tmp_path / "missing.ply"), "--out", str(tmp_path)]) == 2
    assert "error:" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        cli.main(["demo", "--methods", "bvh"])


def test_module_entry_point_runs():
    r = subprocess.run([sys.executable, "-m", "matrixtree", "--help"], capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 0 and "demo" in r.stdout

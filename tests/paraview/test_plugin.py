"""The ParaView plugin (ParaView 5.11, its VTK 9.2) against VTK's own answers.

Point location: ResampleWithDataset with the matrix-tree locator against the same filter with
VTK's static locator, on the shipped CFD grids, in one process and under ``mpirun -np 2``. VTK's
FindCell accepts a point up to its 1e-3 parametric tolerance outside a cell, so a point near a
face is accepted by two cells, and each locator may answer with either (VTK's static locator's
pick follows its bins' sort order). The tests require bit-equal values everywhere else, and check
with VTK 9.1's EvaluatePosition (this process) that every point where the two differ is such a
point. The casters and the tree representation run the engine both builds share: their outputs
must equal the VTK 9.1 build's (matrixtree.render, render_volume, tree_mesh) exactly.
"""

import json
import os

import numpy as np
from vtkmodules.vtkCommonCore import mutable
from vtkmodules.vtkCommonDataModel import vtkGenericCell, vtkStaticCellLocator
from vtkmodules.vtkCommonCore import vtkIdList

import matrixtree
from pvtools import run_pvbatch

DATA = matrixtree.scenes.data_dir()


def test_plugin_loads_and_registers_its_proxies(tmp_path):
    out = tmp_path / "proxies.json"
    run_pvbatch("proxies", out)
    got = json.load(open(out))
    assert "Matrix Tree Cell Locator" in got["cell_locators"]
    assert "Static Cell Locator" in got["cell_locators"]  # VTK's stay listed
    assert all(got["filters"].values()), got["filters"]


def _accepting_cells(grid, points):
    """How many cells of `grid` VTK (this process: 9.1) accepts each point in: EvaluatePosition
    returns 1 (inside, within its tolerance). Candidates: the cells whose bounds come within a
    hundredth of the largest cell of the point (farther than VTK's tolerance reaches)."""
    loc = vtkStaticCellLocator()
    loc.SetDataSet(grid)
    loc.BuildLocator()
    reach = 1e-2 * max(np.sqrt(grid.GetCell(c).GetLength2()) for c in range(0, grid.GetNumberOfCells(), 97))
    cell, ids = vtkGenericCell(), vtkIdList()
    closest, pcoords, weights = [0.0] * 3, [0.0] * 3, [0.0] * 27
    sub, dist2 = mutable(0), mutable(0.0)
    counts = []
    for x in points:
        loc.FindCellsWithinBounds([x[0] - reach, x[0] + reach, x[1] - reach, x[1] + reach,
                                   x[2] - reach, x[2] + reach], ids)
        n = 0
        for k in range(ids.GetNumberOfIds()):
            grid.GetCell(ids.GetId(k), cell)
            n += cell.EvaluatePosition(list(x), closest, sub, pcoords, dist2, weights) == 1
        counts.append(n)
    return np.array(counts)


def _check_resample(npz, grids):
    res = np.load(npz)
    for name, (_, field, _, grid, p) in grids.items():
        ms, vs = res[f"{name}|static|mask"], res[f"{name}|static|value"]
        mm, vm = res[f"{name}|matrixtree|mask"], res[f"{name}|matrixtree|value"]
        assert np.array_equal(res[f"{name}|matrixtree|points"], p), f"{name}: the points came back reordered"
        assert ms.sum() > 0.3 * len(p), f"{name}: too few points inside the grid to test anything"
        differ = (ms != mm) | ((ms == 1) & (vs != vm))
        assert differ.mean() < 0.01, f"{name}: {differ.sum()} of {len(p)} points differ"
        # Every difference is a point VTK's tolerance lets into two cells (both locators then
        # answer with a cell VTK accepts), or one VTK's static locator misses although VTK
        # accepts it (a point past a cell's bounds, inside its tolerance); never a point the
        # matrix tree misses.
        idx = np.flatnonzero(differ)
        accepted = _accepting_cells(grid, p[idx])
        both = (ms[idx] == 1) & (mm[idx] == 1)
        assert np.all(accepted[both] >= 2), f"{name}: points with one accepting cell got different values"
        assert not np.any((ms[idx] == 1) & (mm[idx] == 0)), f"{name}: the matrix tree missed points VTK found"
        assert np.all(accepted[(ms[idx] == 0) & (mm[idx] == 1)] >= 1)
        # The field is continuous: two cells accepting one point interpolate nearly alike (seen: 1e-5
    # of the range at most).
        span = np.ptp(vs[ms == 1])
        assert np.all(np.abs(vs[idx][both] - vm[idx][both]) <= 1e-4 * span), f"{name}: values far apart"


def test_resample_with_dataset_matches_vtk_locator(tmp_path, cfd_grids):
    out = tmp_path / "resample.npz"
    args = [v for path, field, points, _, _ in cfd_grids.values() for v in (path, field, points)]
    run_pvbatch("resample", out, *args)
    assert int(np.load(out)["ranks"]) == 1
    _check_resample(out, cfd_grids)


def test_resample_with_dataset_matches_vtk_locator_on_two_ranks(tmp_path, cfd_grids):
    out = tmp_path / "resample_mpi.npz"
    args = [v for path, field, points, _, _ in cfd_grids.values() for v in (path, field, points)]
    run_pvbatch("resample", out, *args, ranks=2)
    assert int(np.load(out)["ranks"]) == 2
    _check_resample(out, cfd_grids)


def _hausdorff(a, b):
    d = np.sqrt(((np.asarray(a)[:, None, :] - np.asarray(b)[None, :, :]) ** 2).sum(-1))
    return max(d.min(axis=1).max(), d.min(axis=0).max())


def test_stream_tracer_uses_the_chosen_locator(tmp_path, cfd_grids):
    out = tmp_path / "stream.json"
    run_pvbatch("stream", out, cfd_grids["pipe_flow_tets.vtu"][0], "Velocity")
    got = json.load(open(out))
    assert got["default_locator"] == "MatrixTreeCellLocator" and got["locators_built"] == 1
    # With VTK's static locator as the class, the plugin's tracer is ParaView's, point for point.
    assert got["static"] == got["paraview"] and len(got["paraview"]) == 40
    # With the matrix tree the velocities differ only at points VTK accepts in two cells (~1e-5
    # of the speed): integration carries that on, so lines stay close without being identical.
    close = [s for s in got["paraview"] if s in got["matrixtree"]
             and got["matrixtree"][s]["reason"] == got["paraview"][s]["reason"]
             and _hausdorff(got["matrixtree"][s]["points"], got["paraview"][s]["points"]) < 1e-2 * got["diagonal"]]
    assert len(close) >= 0.8 * len(got["paraview"]), f"only {len(close)} of 40 streamlines agree"


def test_probe_location_with_cell_locator(tmp_path, cfd_grids):
    path, field, _, grid, _ = cfd_grids["disk_out_ref.vtu"]
    # Cell centroids: inside exactly one cell, so every locator finds the same one.
    centres = []
    for c in range(0, grid.GetNumberOfCells(), grid.GetNumberOfCells() // 5):
        ids = grid.GetCell(c).GetPoints()
        centres.append(np.mean([ids.GetPoint(k) for k in range(ids.GetNumberOfPoints())], axis=0))
    out = tmp_path / "probe.json"
    run_pvbatch("probe", out, path, field, *np.ravel(centres))
    rows = json.load(open(out))
    assert len(rows) == len(centres)
    for r in rows:
        assert r["locator"] == "MatrixTreeCellLocator"
        assert r["matrixtree"] == r["paraview"] and r["paraview"] != [0.0]


def test_casters_and_representation_equal_the_vtk91_build(tmp_path):
    mesh = os.path.join(DATA, "meshes", "bunny.ply")
    volume_path = os.path.join(DATA, "volumes", "ironProt.vtk")
    size = (96, 72)
    volume = matrixtree.read_volume(volume_path)
    ctf, otf = matrixtree.default_transfer_functions(volume)
    cam = matrixtree.frame_camera(volume)
    sp = volume.GetSpacing()
    vsettings = {"Position": list(cam.GetPosition()), "FocalPoint": list(cam.GetFocalPoint()),
                 "ViewUp": list(cam.GetViewUp()), "ViewAngle": cam.GetViewAngle(),
                 "SampleDistance": 0.5 * min(sp), "ScalarOpacityUnitDistance": float(np.mean(sp))}
    color = [[ctf.GetNodeValue(i, v) and v for v in [[0.0] * 6]][0] for i in range(ctf.GetSize())]
    opacity = [[otf.GetNodeValue(i, v) and v for v in [[0.0] * 4]][0] for i in range(otf.GetSize())]
    settings = tmp_path / "settings.json"
    json.dump({"size": size, "volume": vsettings, "color": color, "opacity": opacity}, open(settings, "w"))
    out = tmp_path / "casters.npz"
    run_pvbatch("casters", out, mesh, volume_path, settings)
    got = np.load(out)

    boxes = matrixtree.tree_mesh(matrixtree.read_mesh(mesh))
    assert np.array_equal(got["rep_level"], boxes.cell_data["level"])
    assert np.array_equal(got["rep_cell_count"], boxes.cell_data["cell_count"])
    assert np.array_equal(got["rep_points"], boxes.points)

    img = matrixtree.render(matrixtree.read_mesh(mesh), size=size)
    assert np.array_equal(got["rgb"].reshape(size[1], size[0], 3)[::-1], img["rgb"])
    assert np.array_equal(got["depth"].reshape(size[1], size[0])[::-1], img["depth"])
    assert (got["cell_id"] >= 0).sum() > 0.1 * size[0] * size[1]

    ref = matrixtree.render_volume(volume, size=size, camera=cam, color=ctf, opacity=otf,
                                   sample_distance=vsettings["SampleDistance"],
                                   opacity_unit_distance=vsettings["ScalarOpacityUnitDistance"])
    rgba = got["rgba"].reshape(size[1], size[0], 4)[::-1]
    assert ref[..., 3].max() > 0.5
    assert np.array_equal(rgba, ref)

"""FindCell with the engine's cell evaluation (EngineCellEvaluation on, the default) against the
same locator handing every candidate to VTK's EvaluatePosition (off): on all six CFD grids, the
same cell id, pcoords and weights bit for bit, and the generic cell filled as vtkDataSet::GetCell
fills it, for random points in and around the grid and the hard ones (grid vertices, edge
midpoints, face centres, points just inside and just outside faces and vertices at VTK's
tolerances, points outside the grid, NaN). The engine's evaluation itself is compared with VTK's
EvaluatePosition pair by pair in tests/cpp/test_cell_eval.cpp (five of the grids: the C++ tests
have no Exodus reader, so disk_out_ref is covered here)."""

import math
import os

import numpy as np
import pytest
from vtkmodules.util.numpy_support import numpy_to_vtk, vtk_to_numpy
from vtkmodules.vtkCommonCore import vtkDoubleArray, vtkIdTypeArray, vtkPoints
from vtkmodules.vtkCommonDataModel import vtkGenericCell

import matrixtree
from matrixtree import scenes
from matrixtree_vtk import vtkMatrixTreeLocator

CFD = os.path.join(scenes.data_dir(), "cfd")
GRIDS = ["pipe_flow_tets.vtu", "pipe_lumen_tets.vtu", "brick_tets.su2", "brick_pyra.su2", "brick_prism.su2",
         "brick_hex.su2", "disk_out_ref.ex2"]


def hard_points(ds, n_cells, seed):
    """Points where the answer is delicate: grid vertices, cell centres, edge midpoints, face
    centres, and points moved from a cell's centre towards (and past) a vertex or a face centre
    by factors around VTK's tolerances; plus random points in the grid's box grown by 10%."""
    rng = np.random.default_rng(seed)
    pts = vtk_to_numpy(ds.GetPoints().GetData()).astype(np.float64)
    out = [pts[rng.integers(0, len(pts), n_cells)]]
    factors = np.array([0.5, 0.999, 0.999999, 1.0, 1.000001, 1.0005, 1.001, 1.0015, 1.01, 1.3])
    for c in rng.integers(0, ds.GetNumberOfCells(), n_cells):
        cell = ds.GetCell(int(c))
        ids = [cell.GetPointId(k) for k in range(cell.GetNumberOfPoints())]
        p = pts[ids]
        centre = p.mean(axis=0)
        out.append(centre[None])
        out.append(0.5 * (p[0] + p[1])[None])
        for f in range(cell.GetNumberOfFaces()):
            face = cell.GetFace(f)
            fc = pts[[face.GetPointId(k) for k in range(face.GetNumberOfPoints())]].mean(axis=0)
            out.append(centre + factors[:, None] * (fc - centre))
        v = p[rng.integers(0, len(p))]
        out.append(centre + factors[:, None] * (v - centre))
    b = np.array(ds.GetBounds()).reshape(3, 2)
    ext = b[:, 1] - b[:, 0]
    out.append(b[:, 0] - 0.1 * ext + rng.random((20 * n_cells, 3)) * ext * 1.2)
    return np.vstack(out)


def build(ds, engine):
    loc = vtkMatrixTreeLocator()
    loc.SetDataSet(ds)
    loc.SetEngineCellEvaluation(engine)
    loc.BuildLocator()
    return loc


@pytest.fixture(scope="module", params=GRIDS)
def grid(request):
    return request.param, matrixtree.read_grid(os.path.join(CFD, request.param))


def test_find_cell_equals_vtk_evaluation(grid):
    name, ds = grid
    loc = build(ds, True)
    gc_engine, gc_vtk, ref = vtkGenericCell(), vtkGenericCell(), vtkGenericCell()
    points = hard_points(ds, 300, seed=sum(name.encode()))
    found = 0
    for p in points:
        x = [float(v) for v in p]
        pc_e, w_e = [0.0] * 3, [0.0] * 8
        pc_v, w_v = [0.0] * 3, [0.0] * 8
        loc.SetEngineCellEvaluation(True)
        a = loc.FindCell(x, 0.0, gc_engine, pc_e, w_e)
        loc.SetEngineCellEvaluation(False)
        b = loc.FindCell(x, 0.0, gc_vtk, pc_v, w_v)
        assert a == b, f"{name}: x = {x!r}: engine {a}, VTK {b}"
        if a < 0:
            continue
        found += 1
        n = gc_vtk.GetNumberOfPoints()
        assert pc_e == pc_v, f"{name}: x = {x!r}: pcoords {pc_e} vs VTK {pc_v}"
        assert w_e[:n] == w_v[:n], f"{name}: x = {x!r}: weights {w_e[:n]} vs VTK {w_v[:n]}"
        # The cell handed back is the found cell as GetCell gives it (callers read its point ids).
        ds.GetCell(a, ref)
        assert gc_engine.GetCellType() == ref.GetCellType()
        assert [gc_engine.GetPointId(k) for k in range(n)] == [ref.GetPointId(k) for k in range(n)]
        assert [gc_engine.GetPoints().GetPoint(k) for k in range(n)] == \
            [ref.GetPoints().GetPoint(k) for k in range(n)]
    assert found > len(points) // 4
    # NaN and infinite coordinates: no cell, no crash, either way.
    for x in ([math.nan, 0.0, 0.0], [math.inf, math.inf, math.inf]):
        for engine in (True, False):
            loc.SetEngineCellEvaluation(engine)
            assert loc.FindCell(x, 0.0, gc_engine, [0.0] * 3, [0.0] * 8) == -1


def test_find_cells_equals_vtk_evaluation(grid):
    """The batched FindCells (OpenMP, every thread with its own cell) gives the same arrays."""
    name, ds = grid
    pts = hard_points(ds, 2000, seed=7)
    vp = vtkPoints()
    vp.SetData(numpy_to_vtk(pts, deep=True))
    out = {}
    for engine in (True, False):
        loc = build(ds, engine)
        ids, pc, w = vtkIdTypeArray(), vtkDoubleArray(), vtkDoubleArray()
        loc.FindCells(vp, ids, pc, w)
        out[engine] = [vtk_to_numpy(a).copy() for a in (ids, pc, w)]
    for a, b in zip(out[True], out[False]):
        np.testing.assert_array_equal(a, b, err_msg=name)
    assert (out[True][0] >= 0).sum() > len(pts) // 4


def test_setting_is_copied_and_printed():
    a, b = vtkMatrixTreeLocator(), vtkMatrixTreeLocator()
    assert a.GetEngineCellEvaluation()
    a.EngineCellEvaluationOff()
    b.CopySettings(a)
    assert not b.GetEngineCellEvaluation()
    assert "EngineCellEvaluation: Off" in str(b)

"""Batched, thread-parallel locator calls (FindCells, IntersectSegments, FindClosestPoints) and
the numpy front end matrixtree.CellLocator, against the one-point calls and vtkCellLocator."""

import os

import numpy as np
import pytest
from vtkmodules.vtkCommonCore import reference
from vtkmodules.vtkCommonDataModel import vtkCellLocator, vtkGenericCell

import matrixtree
from matrixtree import scenes
from matrixtree.locator import CellLocator

from seeded import random_points

DATA = scenes.data_dir()


@pytest.fixture(scope="module")
def pipe():
    return matrixtree.read_grid(os.path.join(DATA, "cfd", "pipe_flow_tets.vtu"))


def test_locate_equals_find_cell_and_vtk(pipe):
    loc = CellLocator(pipe, threads=2)
    p = random_points(pipe, 20000, seed=4)
    ids, pc, w = loc.locate(p, return_pcoords=True, return_weights=True)
    assert (ids >= 0).sum() > 10000
    # The one-point call, on a subset (a Python loop is slow).
    gc, pc1, w1 = vtkGenericCell(), [0.0] * 3, [0.0] * 8
    ref = vtkCellLocator()
    ref.SetDataSet(pipe)
    ref.BuildLocator()
    for i in range(0, len(p), 10):
        a = loc.vtk_locator.FindCell(list(p[i]), 0.0, gc, pc1, w1)
        assert a == ids[i]
        if a >= 0:
            assert np.array_equal(pc1, pc[i]) and np.array_equal(w1[:4], w[i, :4])
        assert (ref.FindCell(list(p[i])) < 0) == (a < 0)
    assert np.allclose(w[ids >= 0].sum(axis=1), 1.0)
    assert np.all(w[ids < 0] == 0)


def test_trace_equals_intersect_with_line():
    mesh = matrixtree.read_mesh(os.path.join(DATA, "meshes", "bunny.ply"))
    loc = CellLocator(mesh, tree="kdtree")
    rng = np.random.default_rng(8)
    o = random_points(mesh, 2000, seed=8, grow=0.0)
    d = rng.normal(size=(2000, 3))
    d *= 0.3 / np.linalg.norm(d, axis=1)[:, None]
    t, ids, x = loc.trace(o, d)
    assert (ids >= 0).sum() > 200
    assert np.all(np.isinf(t[ids < 0])) and np.all(np.isnan(x[ids < 0]))
    ref = vtkCellLocator()
    ref.SetDataSet(mesh)
    ref.BuildLocator()
    gc = vtkGenericCell()
    for i in range(0, 2000, 4):
        tt, xx, pc, sub, cid = reference(0.0), [0.0] * 3, [0.0] * 3, reference(0), reference(0)
        hit = loc.vtk_locator.IntersectWithLine(list(o[i]), list(o[i] + d[i]), 0.0, tt, xx, pc, sub, cid, gc)
        assert bool(hit) == (ids[i] >= 0)
        if hit:
            assert int(cid) == ids[i] and float(tt) == t[i] and np.array_equal(xx, x[i])
        rhit = ref.IntersectWithLine(list(o[i]), list(o[i] + d[i]), 0.0, tt, xx, pc, sub, cid, gc)
        assert bool(rhit) == (ids[i] >= 0)
        if rhit:
            assert abs(float(tt) - t[i]) <= 1e-9
    t2, ids2, _ = loc.trace(o, ends=o + d)
    assert np.array_equal(ids, ids2) and np.array_equal(t, t2)


def test_closest_points_equal_one_point_calls():
    mesh = matrixtree.read_mesh(os.path.join(DATA, "scenes", "utah_hand", "hand_00.obj"))
    loc = CellLocator(mesh)
    p = random_points(mesh, 600, seed=3, grow=0.3)
    cp, ids, d2 = loc.closest_points(p)
    ref = vtkCellLocator()
    ref.SetDataSet(mesh)
    ref.BuildLocator()
    gc = vtkGenericCell()
    for i in range(0, len(p), 3):
        c, cid, sub, dd = [0.0] * 3, reference(0), reference(0), reference(0.0)
        ref.FindClosestPoint(list(p[i]), c, gc, cid, sub, dd)
        assert abs(float(dd) - d2[i]) <= 1e-12 * max(1.0, float(dd))
        assert np.isclose(np.sum((cp[i] - p[i]) ** 2), d2[i], rtol=1e-9, atol=1e-15)


def test_bad_input_is_an_error_not_a_crash(pipe):
    loc = CellLocator(pipe)
    with pytest.raises(ValueError):
        loc.locate(np.zeros((4, 2)))
    with pytest.raises(ValueError):
        loc.trace(np.zeros((3, 3)))
    with pytest.raises(ValueError):
        loc.trace(np.zeros((3, 3)), ends=np.zeros((2, 3)))
    with pytest.raises(TypeError):
        CellLocator(np.zeros((3, 3)))
    assert loc.locate(np.zeros((0, 3))).shape == (0,)
    # The VTK call reports mismatched arrays through vtkErrorMacro and leaves empty outputs.
    from vtkmodules.util.numpy_support import numpy_to_vtk
    from vtkmodules.vtkCommonCore import vtkDoubleArray, vtkIdTypeArray, vtkObject
    t, ids = vtkDoubleArray(), vtkIdTypeArray()
    vtkObject.GlobalWarningDisplayOff()
    try:
        loc.vtk_locator.IntersectSegments(numpy_to_vtk(np.zeros((3, 3))), numpy_to_vtk(np.zeros((2, 3))), 0.0, t, ids)
    finally:
        vtkObject.GlobalWarningDisplayOn()
    assert t.GetNumberOfTuples() == 0 and ids.GetNumberOfTuples() == 0

"""vtkMatrixTreeRepresentation: the tree as voxels, with node counts checked by brute force."""

import os

import numpy as np
import pytest
from vtkmodules.util.numpy_support import vtk_to_numpy
from vtkmodules.vtkCommonDataModel import vtkCellLocator, vtkUnstructuredGrid

import matrixtree
from matrixtree import scenes
from matrixtree_vtk import vtkMatrixTreeLocator, vtkMatrixTreeRepresentation

DATA = scenes.data_dir()


@pytest.fixture(scope="module")
def disk():
    return matrixtree.read_grid(os.path.join(DATA, "cfd", "disk_out_ref.ex2"))


@pytest.fixture(scope="module")
def bunny():
    return matrixtree.read_mesh(os.path.join(DATA, "meshes", "bunny.ply"))


def run(ds, **settings):
    f = vtkMatrixTreeRepresentation()
    f.SetInputData(ds)
    for k, v in settings.items():
        getattr(f, "Set" + k)(v)
    f.Update()
    out = f.GetOutput()
    cd = out.GetCellData()
    boxes = vtk_to_numpy(out.GetPoints().GetData()).reshape(-1, 8, 3) if out.GetNumberOfPoints() else np.zeros((0, 8, 3))
    return (out, vtk_to_numpy(cd.GetArray("level")), vtk_to_numpy(cd.GetArray("occupancy")),
            vtk_to_numpy(cd.GetArray("cell_count")), boxes.min(axis=1), boxes.max(axis=1))


def cell_bounds(ds):
    """(cells, 3, 2) bounds from the points and the cell array, vectorized."""
    ca = ds.GetCells() if ds.IsA("vtkUnstructuredGrid") else ds.GetPolys()
    assert ca.GetNumberOfCells() == ds.GetNumberOfCells()
    off = vtk_to_numpy(ca.GetOffsetsArray())
    pts = vtk_to_numpy(ds.GetPoints().GetData())[vtk_to_numpy(ca.GetConnectivityArray())]
    lo, hi = np.minimum.reduceat(pts, off[:-1]), np.maximum.reduceat(pts, off[:-1])
    return np.stack([lo, hi], axis=2)


def bbox_counts(cb, lo, hi, eps):
    """Cells whose bounding box meets each node box shrunk (-eps) / grown (+eps): brute force."""
    out = []
    for a, b in zip(lo, hi):
        out.append(np.all((cb[:, :, 0] <= (b + eps)) & (cb[:, :, 1] >= (a - eps)), axis=1).sum())
    return np.array(out)


@pytest.mark.parametrize("tree", [0, 1])
def test_bounding_box_counts_equal_brute_force(disk, tree):
    out, level, occ, count, lo, hi = run(disk, TreeType=tree, ExactOverlap=False)
    H = int(out.GetFieldData().GetArray("tree_height").GetValue(0))
    assert H >= 3 and level.min() == 0 and level.max() == H
    assert out.GetCellType(0) == 11  # VTK_VOXEL
    cb = cell_bounds(disk)
    eps = 1e-9 * np.ptp(cb[:, :, 1]) * 10
    rng = np.random.default_rng(3)
    pick = np.unique(np.concatenate([np.flatnonzero(level < H), rng.choice(np.flatnonzero(level == H), 400)]))
    shrunk = bbox_counts(cb, lo[pick], hi[pick], -eps)
    grown = bbox_counts(cb, lo[pick], hi[pick], eps)
    assert np.all(shrunk <= count[pick]) and np.all(count[pick] <= grown)
    assert count[level == 0][0] == disk.GetNumberOfCells()
    # Leaves exist only with cells; their counts sum to the references of the locator.
    assert np.all(count[level == H] > 0) and np.all(occ[level == H] == 1.0)


def test_occupancy_counts_children_and_nodes_nest(disk):
    out, level, occ, count, lo, hi = run(disk, TreeType=0)
    H = level.max()
    for l in range(H):
        parents, kids = np.flatnonzero(level == l), np.flatnonzero(level == l + 1)
        centres = 0.5 * (lo[kids] + hi[kids])
        # Children per parent by containment of their centres; occupancy = present / possible.
        n = [(np.all((centres > lo[p]) & (centres < hi[p]), axis=1)).sum() for p in parents]
        split = np.round((hi[parents[0]] - lo[parents[0]]) / (hi[kids[0]] - lo[kids[0]])).prod()
        assert np.allclose(occ[parents], np.array(n) / split)
        assert sum(n) == len(kids)


def test_exact_counts_bracketed_on_surface(bunny):
    loc = vtkMatrixTreeLocator()
    loc.SetDataSet(bunny)
    loc.BuildLocator()
    f = vtkMatrixTreeRepresentation()
    f.SetInputData(bunny)
    f.SetLocator(loc)  # borrowed: its tree is reused
    f.Update()
    out = f.GetOutput()
    level = vtk_to_numpy(out.GetCellData().GetArray("level"))
    count = vtk_to_numpy(out.GetCellData().GetArray("cell_count"))
    assert level.min() == 0 and level.max() == loc.GetTreeHeight()
    assert count[level == level.max()].sum() == loc.GetNumberOfReferences()
    assert (level == level.max()).sum() == loc.GetNumberOfLeaves()
    # Exact (triangle/box) counts never exceed the bounding-box counts of the same tree.
    _, blevel, _, bcount, blo, _ = run(bunny, Height=loc.GetTreeHeight(), ExactOverlap=False)
    pts = vtk_to_numpy(out.GetPoints().GetData()).reshape(-1, 8, 3).min(axis=1)
    key = {tuple(np.round(p, 12)) + (l,): c for p, l, c in zip(blo, blevel, bcount)}
    assert all(c <= key[tuple(np.round(p, 12)) + (l,)] for p, l, c in zip(pts, level, count))


def test_exact_leaf_counts_hold_the_cells_containing_points(disk):
    out, level, occ, count, lo, hi = run(disk, MinLevel=99, MaxLevel=-1)  # leaves only
    assert np.all(level == level.max())
    ref = vtkCellLocator()
    ref.SetDataSet(disk)
    ref.BuildLocator()
    b = np.array(disk.GetBounds()).reshape(3, 2)
    p = b[:, 0] + np.random.default_rng(7).random((3000, 3)) * (b[:, 1] - b[:, 0])
    cells = {}
    for x in p:
        c = ref.FindCell(list(x))
        if c >= 0:
            leaf = np.flatnonzero(np.all((x >= lo) & (x <= hi), axis=1))
            assert len(leaf) >= 1  # a point in a cell lies in an existing leaf
            cells.setdefault(int(leaf[0]), set()).add(c)
    assert len(cells) > 100
    assert all(count[k] >= len(v) for k, v in cells.items())


def test_level_range_and_edge_cases(disk):
    out, level, *_ = run(disk, MinLevel=1, MaxLevel=2)
    assert set(level) == {1, 2}
    f = vtkMatrixTreeRepresentation()
    f.SetInputData(vtkUnstructuredGrid())
    f.Update()
    assert f.GetOutput().GetNumberOfCells() == 0
    f = vtkMatrixTreeRepresentation()
    f.SetInputData(disk)
    f.SetBlockSize(3)
    f.Update()  # VTK reports the bad block size as an error; no crash, empty output
    assert f.GetOutput().GetNumberOfCells() == 0

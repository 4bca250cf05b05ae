"""vtkMatrixTreeLocator's build paths: the cell and point arrays taken from the data set directly
(polygon meshes, float and double points read in place) give the locator the generic path gives."""

import os

import numpy as np
import pytest
from vtkmodules.util.numpy_support import numpy_to_vtk
from vtkmodules.vtkCommonCore import vtkPoints
from vtkmodules.vtkCommonDataModel import vtkCellArray, vtkPolyData, vtkUnstructuredGrid
from vtkmodules.vtkFiltersCore import vtkAppendFilter

import matrixtree
from matrixtree import scenes
from matrixtree_vtk import vtkMatrixTreeLocator


def mixed_polygons() -> vtkPolyData:
    """The bunny's triangles, with every third pair merged into a quad's worth of points and
    every seventh triangle grown into a pentagon (new points off its plane), so that triangles,
    quads and polygons are all present in one polygon-only polydata."""
    mesh = matrixtree.read_mesh(os.path.join(scenes.data_dir(), "meshes", "bunny.ply"))
    pts = np.array([mesh.GetPoint(i) for i in range(mesh.GetNumberOfPoints())])
    polys = mesh.GetPolys()
    from vtkmodules.util.numpy_support import vtk_to_numpy
    off, conn = vtk_to_numpy(polys.GetOffsetsArray()), vtk_to_numpy(polys.GetConnectivityArray())
    tris = conn.reshape(-1, 3)
    extra, cells = [], []
    for t, (a, b, c) in enumerate(tris[:20000]):
        if t % 3 == 0:  # a quad: the triangle plus the point mirrored across its edge b-c
            extra.append(pts[b] + pts[c] - pts[a])
            cells.append([a, b, len(pts) + len(extra) - 1, c])
        elif t % 7 == 0:  # a pentagon, slightly off the triangle's plane
            centre = (pts[a] + pts[b] + pts[c]) / 3
            extra.append(pts[b] + 0.3 * (pts[b] - centre))
            extra.append(pts[c] + 0.3 * (pts[c] - centre) + 1e-4)
            n = len(pts) + len(extra)
            cells.append([a, b, n - 2, n - 1, c])
        else:
            cells.append([a, b, c])
    allpts = np.vstack([pts, np.array(extra)])
    out = vtkPolyData()
    p = vtkPoints()
    p.SetData(numpy_to_vtk(allpts.astype(np.float32), deep=True))
    out.SetPoints(p)
    ca = vtkCellArray()
    for c in cells:
        ca.InsertNextCell(len(c), [int(x) for x in c])
    out.SetPolys(ca)
    return out


def as_grid(pd: vtkPolyData) -> vtkUnstructuredGrid:
    """The same cells, ids and types as an unstructured grid (its cell types come from VTK)."""
    app = vtkAppendFilter()
    app.AddInputData(pd)
    app.Update()
    return app.GetOutput()


def locator(ds, **settings):
    loc = vtkMatrixTreeLocator()
    loc.SetDataSet(ds)
    loc.SetNumberOfThreads(1)
    for k, v in settings.items():
        getattr(loc, "Set" + k)(v)
    loc.BuildLocator()
    return loc


def cell_centres(ds, step):
    out = []
    for c in range(0, ds.GetNumberOfCells(), step):
        cell = ds.GetCell(c)
        out.append(np.mean([cell.GetPoints().GetPoint(k) for k in range(cell.GetNumberOfPoints())], axis=0))
    return np.array(out)


@pytest.mark.parametrize("tree", [0, 1])
def test_polygon_mesh_copy_equals_the_grid_path(tree):
    pd = mixed_polygons()
    types = {pd.GetCellType(c) for c in range(pd.GetNumberOfCells())}
    assert types == {5, 7, 9}, types  # triangles, polygons, quads
    ug = as_grid(pd)
    a, b = locator(pd, TreeType=tree), locator(ug, TreeType=tree)
    assert a.GetTreeHeight() == b.GetTreeHeight()
    assert a.GetNumberOfLeaves() == b.GetNumberOfLeaves()
    assert a.GetNumberOfReferences() == b.GetNumberOfReferences()
    for x in cell_centres(pd, 37):
        assert a.FindCell(list(x)) == b.FindCell(list(x))


@pytest.mark.parametrize("dtype", [np.float32, np.float64, np.int32])
def test_points_read_in_place_or_copied_give_the_same_locator(dtype):
    """Float and double point arrays are read in place, others copied: same tree, same answers,
    and the locator still answers after the data set's points are replaced (it keeps the array
    it read) until it is rebuilt."""
    grid = matrixtree.read_grid(os.path.join(scenes.data_dir(), "cfd", "brick_hex.su2"))
    ref = locator(grid)
    pts = np.array([grid.GetPoint(i) for i in range(grid.GetNumberOfPoints())])
    scale = 1000.0 if dtype == np.int32 else 1.0  # integer coordinates: the grid in mm
    g = vtkUnstructuredGrid()
    g.DeepCopy(grid)
    p = vtkPoints()
    p.SetData(numpy_to_vtk((pts * scale).astype(dtype), deep=True))
    g.SetPoints(p)
    loc = locator(g)
    if dtype != np.int32:
        assert loc.GetNumberOfReferences() == ref.GetNumberOfReferences()
    probe = cell_centres(g, 11)
    before = [loc.FindCell(list(x)) for x in probe]
    assert all(c >= 0 for c in before)
    q = vtkPoints()
    q.SetData(numpy_to_vtk((pts * scale + 1e6).astype(np.float64), deep=True))
    g.SetPoints(q)  # the old array stays alive in the locator
    loc.UseExistingSearchStructureOn()
    assert [loc.FindCell(list(x)) for x in probe] == before

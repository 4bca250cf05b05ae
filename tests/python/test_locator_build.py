"""vtkMatrixTreeLocator's build paths: the cell and point arrays taken from the data set directly
(polygon meshes, float and double points read in place) give the locator the generic path gives."""

import os

import numpy as np
import pytest
from vtkmodules.util.numpy_support import numpy_to_vtk, vtk_to_numpy
from vtkmodules.vtkCommonCore import (VTK_ID_TYPE, reference, vtkDoubleArray, vtkIdList, vtkIdTypeArray,
                                      vtkPoints)
from vtkmodules.vtkCommonDataModel import (VTK_TETRA, vtkCellArray, vtkGenericCell, vtkPolyData,
                                           vtkUnstructuredGrid)
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


def answers(loc, ds, seed):
    """FindCells, IntersectSegments (tolerance 0 and > 0), FindClosestPoint and
    FindCellsWithinBounds of loc on seeded probes of ds."""
    rng = np.random.default_rng(seed)
    b = np.array(ds.GetBounds()).reshape(3, 2)
    diag = float(np.linalg.norm(b[:, 1] - b[:, 0]))
    x = b[:, 0] + rng.random((3000, 3)) * (b[:, 1] - b[:, 0])
    x = np.vstack([x, cell_centres(ds, 13)])
    p = vtkPoints()
    p.SetData(numpy_to_vtk(x, deep=True))
    ids, pc, w = vtkIdTypeArray(), vtkDoubleArray(), vtkDoubleArray()
    loc.FindCells(p, ids, pc, w)
    out = [vtk_to_numpy(ids).copy(), vtk_to_numpy(pc).copy(), vtk_to_numpy(w).copy()]
    u = rng.normal(size=(1500, 3))
    x2 = x[:1500] + 0.2 * diag * u / np.linalg.norm(u, axis=1)[:, None]
    for tol in (0.0, 1e-3 * diag):
        t, c = vtkDoubleArray(), vtkIdTypeArray()
        loc.IntersectSegments(numpy_to_vtk(x[:1500], deep=True), numpy_to_vtk(x2, deep=True), tol, t, c)
        out += [vtk_to_numpy(t).copy(), vtk_to_numpy(c).copy()]
    gc = vtkGenericCell()
    for q in x[:200]:
        cp, cid, sub, d2 = [0.0] * 3, reference(0), reference(0), reference(0.0)
        loc.FindClosestPoint(list(q), cp, gc, cid, sub, d2)
        out.append(np.array(cp + [int(cid), float(d2)]))
        lst = vtkIdList()
        r = 0.03 * diag
        loc.FindCellsWithinBounds([q[0] - r, q[0] + r, q[1] - r, q[1] + r, q[2] - r, q[2] + r], lst)
        out.append(np.array([lst.GetId(k) for k in range(lst.GetNumberOfIds())]))
    return out


def integer_grids():
    """Grids with integer coordinates: brick_hex in units of 1e-3 (hexahedra only), the mixed
    polygons of mixed_polygons() scaled by 1e4 (triangles, quads, polygons) as polydata and as
    an unstructured grid."""
    grid = matrixtree.read_grid(os.path.join(scenes.data_dir(), "cfd", "brick_hex.su2"))
    out = []
    for ds, scale in ((grid, 1000.0), (mixed_polygons(), 1e4)):
        pts = vtk_to_numpy(ds.GetPoints().GetData()).astype(np.float64)
        g = ds.NewInstance()
        g.DeepCopy(ds)
        p = vtkPoints()
        p.SetData(numpy_to_vtk(np.round(pts * scale), deep=True))
        g.SetPoints(p)
        out.append(g)
    out.append(as_grid(out[1]))
    return out


def test_viewed_cell_arrays_outlive_set_cells():
    """The locator keeps the cell arrays it reads: after SetCells() on the grid it answers as
    before (UseExistingSearchStructure), and a rebuild reads the new cells."""
    grid = matrixtree.read_grid(os.path.join(scenes.data_dir(), "cfd", "brick_tets.su2"))
    g = vtkUnstructuredGrid()
    g.DeepCopy(grid)
    loc = locator(g)
    probe = cell_centres(g, 7)
    before = [loc.FindCell(list(x)) for x in probe]
    assert all(c >= 0 for c in before)
    # The same tetrahedra in reverse order, in new arrays (the old ones lose the grid's reference).
    n = g.GetNumberOfCells()
    conn = vtk_to_numpy(g.GetCells().GetConnectivityArray()).reshape(n, 4)[::-1].copy()
    ca = vtkCellArray()
    ca.SetData(numpy_to_vtk(np.arange(0, 4 * n + 1, 4, dtype=np.int64), deep=True, array_type=VTK_ID_TYPE),
               numpy_to_vtk(conn.ravel().astype(np.int64), deep=True, array_type=VTK_ID_TYPE))
    g.SetCells(VTK_TETRA, ca)
    loc.UseExistingSearchStructureOn()
    assert [loc.FindCell(list(x)) for x in probe] == before
    loc.UseExistingSearchStructureOff()
    loc.BuildLocator()
    assert [loc.FindCell(list(x)) for x in probe] == [n - 1 - c for c in before]


def test_cache_cell_bounds_keeps_24_bytes_per_cell_and_the_answers():
    """CacheCellBounds (off by default) keeps the cells' float bounds after the build: 24 bytes per
    cell more, the same answers (the queries that read bounds compute the same floats without)."""
    ds = integer_grids()[0]
    off = locator(ds)
    assert not off.GetCacheCellBounds()
    on = locator(ds, CacheCellBounds=True)
    assert on.GetMemorySize() == off.GetMemorySize() + 24 * ds.GetNumberOfCells()
    for a, b in zip(answers(on, ds, 5), answers(off, ds, 5)):
        np.testing.assert_array_equal(a, b)


def test_automatic_height_rule_follows_the_cell_dimension():
    """LeafScale and MaxCandidates 0 (the defaults) are 4 and 3 on a surface (no 3-D cell) and 1
    and 16 on a volume grid or a mix with a 3-D cell; values set are used as given. The surface
    rule gives the shallower tree (fewer references per triangle), and the answers stay VTK's."""
    bunny = matrixtree.read_mesh(os.path.join(scenes.data_dir(), "meshes", "bunny.ply"))
    surf = locator(bunny)
    assert (surf.GetLeafScale(), surf.GetMaxCandidates()) == (0.0, 0.0)
    assert (surf.GetLeafScaleUsed(), surf.GetMaxCandidatesUsed()) == (4.0, 3.0)
    vol_rule = locator(bunny, LeafScale=1.0, MaxCandidates=16.0)
    assert (vol_rule.GetLeafScaleUsed(), vol_rule.GetMaxCandidatesUsed()) == (1.0, 16.0)
    assert surf.GetTreeHeight() < vol_rule.GetTreeHeight()
    refs_per_tri = surf.GetNumberOfReferences() / bunny.GetNumberOfCells()
    assert refs_per_tri < 0.5 * vol_rule.GetNumberOfReferences() / bunny.GetNumberOfCells()
    # The same ray answers as vtkCellLocator's on the shallow tree.
    from vtkmodules.vtkCommonDataModel import vtkCellLocator
    ref = vtkCellLocator()
    ref.SetDataSet(bunny)
    ref.BuildLocator()
    b = bunny.GetBounds()
    rng = np.random.default_rng(4)
    gc = vtkGenericCell()
    hits = 0
    for _ in range(300):
        p1 = [rng.uniform(b[2 * a], b[2 * a + 1]) for a in range(3)]
        p2 = [p1[a] + rng.uniform(-1, 1) * (b[2 * a + 1] - b[2 * a]) for a in range(3)]
        got = []
        for loc in (surf, ref):
            t, x, pc, sub, cid = reference(0.0), [0.0] * 3, [0.0] * 3, reference(0), reference(0)
            hit = loc.IntersectWithLine(p1, p2, 0.0, t, x, pc, sub, cid, gc)
            got.append((hit, float(t), int(cid)))
        assert got[0][0] == got[1][0]
        if got[0][0]:
            hits += 1
            assert abs(got[0][1] - got[1][1]) <= 1e-9
    assert hits > 30
    # A volume grid, and a volume grid with surface cells appended: the volume rule.
    tets = matrixtree.read_grid(os.path.join(scenes.data_dir(), "cfd", "brick_tets.su2"))
    vol = locator(tets)
    assert (vol.GetLeafScaleUsed(), vol.GetMaxCandidatesUsed()) == (1.0, 16.0)
    app = vtkAppendFilter()
    app.AddInputData(bunny)
    app.AddInputData(tets)
    app.Update()
    mixed = locator(app.GetOutput())
    assert (mixed.GetLeafScaleUsed(), mixed.GetMaxCandidatesUsed()) == (1.0, 16.0)


def test_freed_build_arrays_are_kept_for_reuse_and_released_on_request():
    """The builds' large arrays go back to a per-process cache of mappings, not to the system:
    a rebuild after FreeSearchStructure reuses them (same tree, same answers), and
    ReleaseCachedMemory hands them all back."""
    if os.environ.get("MATRIXTREE_MAP_CACHE") == "0":
        pytest.skip("MATRIXTREE_MAP_CACHE=0")
    grid = matrixtree.read_grid(os.path.join(scenes.data_dir(), "cfd", "pipe_flow_tets.vtu"))
    vtkMatrixTreeLocator.ReleaseCachedMemory()
    assert vtkMatrixTreeLocator.GetCachedMemorySize() == 0
    loc = vtkMatrixTreeLocator()
    loc.SetDataSet(grid)
    loc.BuildLocator()
    refs, leaves, size = loc.GetNumberOfReferences(), loc.GetNumberOfLeaves(), loc.GetMemorySize()
    pts = np.random.default_rng(5).random((2000, 3))
    b = np.array(grid.GetBounds()).reshape(3, 2)
    pts = b[:, 0] + pts * (b[:, 1] - b[:, 0])
    gc, pc, w = vtkGenericCell(), [0.0] * 3, [0.0] * 8
    before = [loc.FindCell(list(p), 0.0, gc, pc, w) for p in pts]
    loc.FreeSearchStructure()
    kept = vtkMatrixTreeLocator.GetCachedMemorySize()
    assert kept >= 2 * 1024 * 1024, "the tree's arrays of 2 MiB and up were kept"
    loc.BuildLocator()
    assert vtkMatrixTreeLocator.GetCachedMemorySize() < kept, "the rebuild took mappings back"
    assert (loc.GetNumberOfReferences(), loc.GetNumberOfLeaves(), loc.GetMemorySize()) == (refs, leaves, size)
    assert [loc.FindCell(list(p), 0.0, gc, pc, w) for p in pts] == before
    still = vtkMatrixTreeLocator.GetCachedMemorySize()
    assert vtkMatrixTreeLocator.ReleaseCachedMemory() == still
    assert vtkMatrixTreeLocator.GetCachedMemorySize() == 0
    assert loc.FindCell(list(pts[0]), 0.0, gc, pc, w) == before[0], "the live tree is untouched"


def test_python_cached_memory_functions_report_and_release():
    """matrixtree.cached_memory / release_cached_memory: the locator's static calls, for scripts
    (a CellLocator rebuilt over a moving grid, then memory handed back)."""
    if os.environ.get("MATRIXTREE_MAP_CACHE") == "0":
        pytest.skip("MATRIXTREE_MAP_CACHE=0")
    grid = matrixtree.read_grid(os.path.join(scenes.data_dir(), "cfd", "pipe_flow_tets.vtu"))
    matrixtree.release_cached_memory()
    loc = matrixtree.CellLocator(grid)
    pts = np.asarray([grid.GetCell(c).GetPoints().GetPoint(0) for c in range(0, 1000, 10)])
    first = loc.locate(pts)
    del loc
    kept = matrixtree.cached_memory()
    assert kept > 0, "the deleted locator's large arrays were kept"
    again = matrixtree.CellLocator(grid).locate(pts)
    assert np.array_equal(first, again)
    left = matrixtree.cached_memory()
    assert matrixtree.release_cached_memory() == left
    assert matrixtree.cached_memory() == 0

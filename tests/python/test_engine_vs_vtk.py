"""The engine extension (matrixtree_engine, what ``pip install .`` builds) against the VTK module
(matrixtree_vtk, built against Debian's VTK): both paths must give the same answers, bit for bit.

Runs in the project's .venv, where both are built (skipped where the VTK module is not, e.g. in
the isolated pip environment: pip's VTK and Debian's must never load in one process). Both are
one algorithm (mtree::vtk91::LocatorCore: the same tree, the same candidates in the same order,
the same fast decisions); what those leave open the VTK module asks of VTK's own cells and the
engine of its transcription of VTK 9.1's cells (mtree/vtk91/cell_mirror.h), which gives VTK's
answer.
"""

from __future__ import annotations

import os

import numpy as np
import pytest

pytest.importorskip("matrixtree_vtk")
engine = pytest.importorskip("matrixtree_engine")

import matrixtree  # noqa: E402
from vtkmodules.util.numpy_support import vtk_to_numpy  # noqa: E402
from vtkmodules.vtkCommonCore import vtkIdList, vtkPoints  # noqa: E402
from vtkmodules.vtkCommonDataModel import vtkPolyData, vtkUnstructuredGrid  # noqa: E402
from vtkmodules.vtkFiltersCore import vtkTriangleFilter  # noqa: E402
from vtkmodules.vtkFiltersGeometry import vtkDataSetSurfaceFilter  # noqa: E402

from test_engine import closest_on_triangles  # noqa: E402

DATA = matrixtree.scenes.data_dir()


def need(path):
    if not os.path.exists(path):
        pytest.skip(f"{path} not found (shared data)")
    return path


def cell_arrays(ds):
    """points, offsets, connectivity and types of a grid or a polygon-only surface."""
    pts = vtk_to_numpy(ds.GetPoints().GetData()).astype(np.float64)
    if isinstance(ds, vtkUnstructuredGrid):
        ca = ds.GetCells()
        types = vtk_to_numpy(ds.GetCellTypesArray()).astype(np.uint8)
    else:
        assert isinstance(ds, vtkPolyData) and ds.GetNumberOfCells() == ds.GetNumberOfPolys()
        ca = ds.GetPolys()
    off = vtk_to_numpy(ca.GetOffsetsArray()).astype(np.int64)
    conn = vtk_to_numpy(ca.GetConnectivityArray()).astype(np.int64)
    if not isinstance(ds, vtkUnstructuredGrid):
        size = np.diff(off)
        types = np.where(size == 3, 5, np.where(size == 4, 9, 7)).astype(np.uint8)
    return pts, off, conn, types


def both_locators(ds, **kw):
    return engine.CellLocator(*cell_arrays(ds), **kw), matrixtree.CellLocator(ds, **kw)


def random_points(ds, n, seed, grow=0.05):
    b = np.array(ds.GetBounds()).reshape(3, 2)
    pad = grow * (b[:, 1] - b[:, 0])
    return np.random.default_rng(seed).uniform(b[:, 0] - pad, b[:, 1] + pad, (n, 3))


def assert_same_locate(eng, ref, x, min_found):
    """Both locators' FindCell answers for points x: the same cells, pcoords and weights, bit for
    bit, with more than min_found points in a cell."""
    ids, pc, w = eng.find_cells(x, pcoords=True, weights=True)
    rids, rpc, rw = ref.locate(x, return_pcoords=True, return_weights=True)
    assert (ids >= 0).sum() > min_found
    np.testing.assert_array_equal(ids, rids)
    np.testing.assert_array_equal(pc, rpc)
    np.testing.assert_array_equal(w, rw[:, :w.shape[1]])


def assert_same_first_hits(eng, ref, p1, p2, min_hits=None):
    """Both locators' first hits of the segments p1 -> p2: the same cells, t and points, bit for
    bit (with min_hits: more than that many segments hit)."""
    t, ids, x = eng.first_hits(p1, p2)
    rt, rids, rx = ref.trace(p1, ends=p2)
    if min_hits is not None:
        assert (ids >= 0).sum() > min_hits
    np.testing.assert_array_equal(ids, rids)
    np.testing.assert_array_equal(t, rt)
    np.testing.assert_array_equal(x, rx)


def assert_same_closest(eng, ref, q):
    """Both locators' closest points of q: the same cells, squared distances and points, bit for
    bit. Returns the squared distances."""
    cp, cid, d2 = eng.closest_points(q)
    rcp, rcid, rd2 = ref.closest_points(q)
    np.testing.assert_array_equal(cid, rcid)
    np.testing.assert_array_equal(d2, rd2)
    np.testing.assert_array_equal(cp, rcp)
    return d2


GRIDS = ["cfd/brick_tets.su2", "cfd/brick_hex.su2", "cfd/brick_prism.su2", "cfd/brick_pyra.su2",
         "cfd/pipe_flow_tets.vtu"]


@pytest.fixture(scope="module", params=GRIDS)
def grid(request):
    return matrixtree.read_grid(need(os.path.join(DATA, request.param)))


def test_locate_gives_the_vtk_modules_cells_and_weights(grid):
    eng, ref = both_locators(grid)
    assert eng.stats()["height"] == ref.vtk_locator.GetTreeHeight()
    assert eng.stats()["references"] == ref.vtk_locator.GetNumberOfReferences()
    assert_same_locate(eng, ref, random_points(grid, 20000, seed=7), min_found=1000)


def test_segments_and_closest_points_match_on_a_grid(grid):
    eng, ref = both_locators(grid)
    p1 = random_points(grid, 300, seed=8, grow=0.3)
    p2 = random_points(grid, 300, seed=9, grow=0.3)
    assert_same_first_hits(eng, ref, p1, p2, min_hits=50)
    q = random_points(grid, 300, seed=10, grow=0.5)
    d2 = assert_same_closest(eng, ref, q)
    inside = d2 == 0
    np.testing.assert_array_equal(d2[inside], 0)
    # Outside, the closest point is on the grid's boundary: where VTK's closest point of a cell is
    # exact (tetrahedra; hexahedra whose faces are planar and parallel in pairs, as these bricks'
    # are) the distance is the nearest of the boundary faces' triangles. (VTK's wedges and
    # pyramids clamp pcoords into a box, which may land short of the cell's nearest point: there
    # the two paths agree with each other above, not with the exact distance.)
    if set(np.unique(vtk_to_numpy(grid.GetCellTypesArray()))) <= {10, 12}:
        surf = vtkDataSetSurfaceFilter()
        surf.SetInputData(grid)
        tri = vtkTriangleFilter()
        tri.SetInputConnection(surf.GetOutputPort())
        tri.Update()
        spts, soff, sconn, _ = cell_arrays(tri.GetOutput())
        faces = spts[sconn.reshape(-1, 3)]
        exact = np.array([((closest_on_triangles(p[None], faces[:, 0], faces[:, 1], faces[:, 2])[0] - p) ** 2)
                          .sum(-1).min() for p in q[~inside]])
        np.testing.assert_allclose(d2[~inside], exact, rtol=1e-9, atol=1e-15)


def test_all_hits_and_bounds_queries_match_on_a_grid(grid):
    eng, ref = both_locators(grid)
    rng = np.random.default_rng(21)
    for _ in range(20):
        p1, p2 = random_points(grid, 2, seed=int(rng.integers(1 << 30)), grow=0.3)
        off, ta, ia, xa = eng.all_hits(p1[None], p2[None])
        pts, lst = vtkPoints(), vtkIdList()
        pts.SetDataTypeToDouble()  # the hit points unrounded
        n = ref.vtk_locator.IntersectWithLine(list(p1), list(p2), pts, lst)
        assert n == off[1]
        np.testing.assert_array_equal(ia, [lst.GetId(i) for i in range(n)])
        np.testing.assert_array_equal(xa, np.array([pts.GetPoint(i) for i in range(n)]).reshape(-1, 3))
        along = eng.cells_along_segment(list(p1), list(p2), 1e-3)
        ref.vtk_locator.FindCellsAlongLine(list(p1), list(p2), 1e-3, lst)
        np.testing.assert_array_equal(along, [lst.GetId(i) for i in range(lst.GetNumberOfIds())])
        lo, hi = np.minimum(p1, p2), np.maximum(p1, p2)
        box = [lo[0], hi[0], lo[1], hi[1], lo[2], hi[2]]
        within = eng.cells_within_bounds(box)
        ref.vtk_locator.FindCellsWithinBounds(box, lst)
        np.testing.assert_array_equal(within, [lst.GetId(i) for i in range(lst.GetNumberOfIds())])


@pytest.fixture(scope="module")
def bunny():
    return matrixtree.read_mesh(need(os.path.join(DATA, "meshes", "bunny.ply")))


def test_surface_locator_matches_on_the_bunny(bunny):
    eng, ref = both_locators(bunny)
    assert eng.stats()["height"] == ref.vtk_locator.GetTreeHeight()
    q = random_points(bunny, 2000, seed=11, grow=0.2)
    assert_same_closest(eng, ref, q)
    p1 = random_points(bunny, 2000, seed=12, grow=0.5)
    p2 = random_points(bunny, 2000, seed=13, grow=0.5)
    assert_same_first_hits(eng, ref, p1, p2)
    # Points near the surface (on random triangles, moved off them by up to ~1e-3 of the
    # diagonal): in a leaf, most project into some triangle there.
    pts, off, conn, _ = cell_arrays(bunny)
    rng = np.random.default_rng(15)
    tris = pts[conn.reshape(-1, 3)][rng.integers(0, len(off) - 1, 5000)]
    diag = np.linalg.norm(np.ptp(pts, axis=0))
    x = np.einsum("nk,nka->na", rng.dirichlet([1, 1, 1], 5000), tris) + \
        rng.normal(scale=1e-3 * diag, size=(5000, 3))
    assert_same_locate(eng, ref, x, min_found=100)


def test_surface_tree_rays_and_render_equal_the_vtk_modules(bunny):
    pts, off, conn, _ = cell_arrays(bunny)
    empty = np.zeros(0, np.int64)
    st = engine.SurfaceTree(pts, off, conn, empty, empty, 0, tree="kdtree")
    mt = matrixtree.MatrixTree(bunny, tree="kdtree")
    assert st.stats()["height"] == mt.stats()["height"]
    assert st.stats()["references"] == mt.stats()["references"]
    rng = np.random.default_rng(14)
    b = np.array(bunny.GetBounds()).reshape(3, 2)
    o = rng.uniform(b[:, 0], b[:, 1], (3000, 3)) + rng.normal(size=(3000, 3)) * 0.1
    d = rng.normal(size=(3000, 3))
    t, cells, visits, tests = st.intersect(o, d)
    rt, rcells = mt.intersect(o, d)
    np.testing.assert_array_equal(cells, rcells)
    np.testing.assert_array_equal(t, rt)
    assert visits == mt.last_query_counters["node_visits"] and tests == mt.last_query_counters["triangle_tests"]
    cam = [(0.1, 0.25, 0.45), (-0.02, 0.1, 0.0), (0.0, 1.0, 0.0), 30.0]
    img = st.render(96, 64, eye=cam[0], target=cam[1], up=cam[2], view_angle=cam[3], counters=True)
    ref = matrixtree.render(bunny, size=(96, 64), tree="kdtree", camera=cam, leaf_scale=2.0, counters=True)
    np.testing.assert_array_equal(img["rgb"][::-1], ref["rgb"])
    np.testing.assert_array_equal(img["node_visits"][::-1], ref["node_visits"])
    assert img["hits"] == ref["hits"] > 0


def test_tree_nodes_equal_tree_mesh(bunny):
    pts, off, conn, types = cell_arrays(bunny)
    nodes = engine.CellLocator(pts, off, conn, types).nodes()
    boxes = matrixtree.tree_mesh(bunny)
    np.testing.assert_array_equal(nodes["level"], boxes.cell_data["level"])
    np.testing.assert_array_equal(nodes["count"], boxes.cell_data["cell_count"])
    np.testing.assert_allclose(nodes["occupancy"], boxes.cell_data["occupancy"])
    corners = boxes.points.reshape(-1, 8, 3)
    np.testing.assert_allclose(nodes["lo"], corners.min(axis=1))
    np.testing.assert_allclose(nodes["hi"], corners.max(axis=1))


def test_volume_render_equals_the_vtk_modules():
    im = matrixtree.read_volume(need(os.path.join(DATA, "volumes", "ironProt.vtk")))
    ctf, otf = matrixtree.default_transfer_functions(im)
    scalars = vtk_to_numpy(im.GetPointData().GetScalars())
    lo, hi = float(scalars.min()), float(scalars.max())
    n = 4096  # vtkMatrixTreeVolumeRayCaster's default TableSize
    rgb, alpha = np.zeros(3 * n, np.float32), np.zeros(n, np.float32)
    ctf.GetTable(lo, hi, n, rgb)
    otf.GetTable(lo, hi, n, alpha)
    table = np.ascontiguousarray(np.column_stack([rgb.reshape(n, 3), alpha]), np.float32)
    spacing = np.array(im.GetSpacing())
    vol = engine.Volume(np.ascontiguousarray(scalars), list(im.GetDimensions()), table, lo, hi,
                        unit_distance=float(spacing.mean()))
    cam = matrixtree.frame_camera(im)
    img, st = vol.render(80, 60, position=cam.GetPosition(), focal_point=cam.GetFocalPoint(), view_up=cam.GetViewUp(),
                         view_angle=cam.GetViewAngle(), origin=im.GetOrigin(), spacing=im.GetSpacing(),
                         sample_distance=0.5 * spacing.min())
    ref = matrixtree.render_volume(im, size=(80, 60), camera=cam, color=ctf, opacity=otf)
    np.testing.assert_array_equal(img[::-1], ref)
    assert img[..., 3].max() > 0.1


def test_engine_volume_renderer_equals_the_vtk_one_frame_after_frame():
    """matrixtree._engine.VolumeRenderer (the pip path) against matrixtree.VolumeRenderer: the same
    images bit for bit (float scalars: the same 16-bit quantisation), the engine volume kept across
    a camera move and built again after an opacity change; an extent not starting at 0 is placed
    by it on both."""
    from vtkmodules.vtkCommonDataModel import vtkImageData

    from matrixtree import _engine

    x, y, z = np.mgrid[-1:1:30j, -1:1:26j, -1:1:22j]
    field = (np.exp(-3 * (x ** 2 + y ** 2 + (z - 0.1) ** 2)) + 0.05 * np.sin(9 * x * z)).astype(np.float32)
    im = vtkImageData()
    im.SetExtent(5, 34, -3, 22, 11, 32)
    im.SetSpacing(0.5, 0.7, 0.6)
    im.SetOrigin(-2.0, 1.0, 0.5)
    from vtkmodules.util.numpy_support import numpy_to_vtk
    im.GetPointData().SetScalars(numpy_to_vtk(field.transpose(2, 1, 0).ravel(), deep=True))
    ctf, otf = matrixtree.default_transfer_functions(im)
    ours, eng = matrixtree.VolumeRenderer(im, color=ctf, opacity=otf), _engine.VolumeRenderer(im, color=ctf, opacity=otf)
    cam = matrixtree.frame_camera(im)
    for step in range(3):
        if step == 1:
            cam.Azimuth(25)
        if step == 2:
            otf.AddPoint(0.5, 0.2)
        a, sa = ours.render(camera=cam, size=(40, 36), return_stats=True)
        b, sb = eng.render(camera=cam, size=(40, 36), return_stats=True)
        np.testing.assert_array_equal(a, b)
        assert sa["rebuilt"] == sb["rebuilt"] == (step != 1)
        assert sa["storage"] == sb["storage"] == "uint16"
        assert sa["quantization_step"] == sb["quantization_step"] > 0
        assert a[..., 3].max() > 0.1

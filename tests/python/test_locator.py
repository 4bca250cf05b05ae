"""vtkMatrixTreeLocator against VTK's own locators on the real CFD grids and meshes."""

import os

import numpy as np
import pytest
from vtkmodules.util.numpy_support import numpy_to_vtk, vtk_to_numpy
from vtkmodules.vtkCommonCore import vtkIdList, vtkPoints, reference
from vtkmodules.vtkCommonDataModel import vtkCellLocator, vtkGenericCell, vtkPolyData

import matrixtree
from matrixtree import scenes
from matrixtree_vtk import vtkMatrixTreeLocator

from seeded import random_points, start_and_direction

CFD = os.path.join(scenes.data_dir(), "cfd")
GRIDS = ["pipe_flow_tets.vtu", "brick_tets.su2", "brick_pyra.su2", "brick_prism.su2", "brick_hex.su2",
         "disk_out_ref.ex2"]


def build(cls, ds, **settings):
    loc = cls()
    loc.SetDataSet(ds)
    for k, v in settings.items():
        getattr(loc, "Set" + k)(v)
    loc.BuildLocator()
    return loc


def contains(ds, cell_id, p):
    cell = ds.GetCell(int(cell_id))
    cp, pc, w = [0.0] * 3, [0.0] * 3, [0.0] * cell.GetNumberOfPoints()
    return cell.EvaluatePosition(list(p), cp, reference(0), pc, reference(0.0), w) == 1


@pytest.mark.parametrize("grid", GRIDS)
@pytest.mark.parametrize("tree,exact", [(0, False), (1, False), (0, True)])
def test_find_cell_agrees_with_vtk_cell_locator(grid, tree, exact):
    """Both overlap modes: bounding boxes (the default) and the separating-axis test."""
    ds = matrixtree.read_grid(os.path.join(CFD, grid))
    ours = build(vtkMatrixTreeLocator, ds, TreeType=tree, ExactOverlap=exact)
    ref = build(vtkCellLocator, ds)
    gc = vtkGenericCell()
    pc, w = [0.0] * 3, [0.0] * 8
    disagreements = 0
    found = 0
    for p in random_points(ds, 4000, seed=11):
        a = ours.FindCell(list(p), 0.0, gc, pc, w)
        b = ref.FindCell(list(p), 0.0, gc, pc, w)
        found += b >= 0
        # -1 only when VTK finds nothing; otherwise a cell that really contains the point.
        if (a < 0) != (b < 0) or (a >= 0 and a != b and not contains(ds, a, p)):
            disagreements += 1
    assert found > 500
    assert disagreements == 0


@pytest.mark.parametrize("grid", GRIDS)
def test_find_cell_fills_the_generic_cell_as_vtk_does(grid):
    """FindCell fills the generic cell from the locator's own copy of the cells (not through
    vtkDataSet::GetCell): type, point ids, coordinates, pcoords and weights must be VTK's, bit for
    bit, for every cell type of the six grids (float and double points)."""
    ds = matrixtree.read_grid(os.path.join(CFD, grid))
    ours = build(vtkMatrixTreeLocator, ds)
    ref = vtkGenericCell()
    gc = vtkGenericCell()
    checked = 0
    for p in random_points(ds, 3000, seed=23, grow=0.0):
        pc, w = [0.0] * 3, [0.0] * 8
        cid = ours.FindCell(list(p), 0.0, gc, pc, w)
        if cid < 0:
            continue
        ds.GetCell(cid, ref)
        n = ref.GetNumberOfPoints()
        assert gc.GetCellType() == ref.GetCellType()
        assert [gc.GetPointId(k) for k in range(n)] == [ref.GetPointId(k) for k in range(n)]
        assert [gc.GetPoints().GetPoint(k) for k in range(n)] == [ref.GetPoints().GetPoint(k) for k in range(n)]
        cp, rpc, rw = [0.0] * 3, [0.0] * 3, [0.0] * n
        assert ref.EvaluatePosition(list(p), cp, reference(0), rpc, reference(0.0), rw) == 1
        assert pc == rpc and w[:n] == rw
        checked += 1
    assert checked > 500


def test_probe_filter_with_prototype_matches_vtk():
    """vtkProbeFilter calls NewInstance() on the prototype: the defaults must work."""
    from vtkmodules.vtkFiltersCore import vtkProbeFilter

    ds = matrixtree.read_grid(os.path.join(CFD, "pipe_flow_tets.vtu"))
    pts = vtkPoints()
    pts.SetData(numpy_to_vtk(random_points(ds, 100000, seed=5, grow=0.0), deep=True))
    probe_pd = vtkPolyData()
    probe_pd.SetPoints(pts)
    out = {}
    # vtkCellLocator is the reference: it returns the lowest-id cell that contains the point, as
    # we do. (vtkStaticCellLocator differs from both at ~0.5% of the points, where its bucket
    # holds another cell that VTK's parametric tolerance also accepts.)
    for name, proto in (("ours", vtkMatrixTreeLocator()), ("vtk", vtkCellLocator())):
        pf = vtkProbeFilter()
        pf.SetInputData(probe_pd)
        pf.SetSourceData(ds)
        pf.SetCellLocatorPrototype(proto)
        pf.Update()
        o = pf.GetOutput().GetPointData()
        out[name] = (vtk_to_numpy(o.GetArray("vtkValidPointMask")).copy(),
                     vtk_to_numpy(o.GetArray("Velocity")).copy())
    mask_ours, vel_ours = out["ours"]
    mask_vtk, vel_vtk = out["vtk"]
    assert mask_vtk.sum() > 10000
    assert np.array_equal(mask_ours, mask_vtk)
    assert np.array_equal(vel_ours, vel_vtk)


@pytest.mark.parametrize("grid", GRIDS)
@pytest.mark.parametrize("exact", [False, True])
def test_rays_in_grids_match_vtk_cell_locator(grid, exact):
    """First hits of segments in the volume grids, at tolerance 0 and above: the same t as
    vtkCellLocator (the cell may differ only where two cells are hit at the same t, as on a shared
    face). Segments start inside the grid (the first hit is the exit of the start cell), outside
    it, and at cell vertices; this is what guards the pre-VTK rejection test (segment_filter.h).
    Both overlap modes (bounding boxes, the default, and exact)."""
    ds = matrixtree.read_grid(os.path.join(CFD, grid))
    ours = build(vtkMatrixTreeLocator, ds, ExactOverlap=exact)
    ref = build(vtkCellLocator, ds)
    b = np.array(ds.GetBounds()).reshape(3, 2)
    diag = float(np.linalg.norm(b[:, 1] - b[:, 0]))
    rng = np.random.default_rng(3)
    gc = vtkGenericCell()
    pts = vtk_to_numpy(ds.GetPoints().GetData())
    mismatches = hits = 0
    n = 600
    for i in range(n):
        if i % 3 == 2:  # from a grid vertex
            p1 = pts[rng.integers(len(pts))].astype(float)
        else:
            p1 = random_points(ds, 1, seed=int(rng.integers(1 << 30)), grow=0.1 * (i % 3))[0]
        u = rng.normal(size=3)
        p2 = p1 + u / np.linalg.norm(u) * 0.1 * diag
        tol = (0.0, 1e-6 * diag, 1e-3 * diag)[i % 3]
        res = []
        for loc in (ours, ref):
            t, x, pc, sub, cid = reference(0.0), [0.0] * 3, [0.0] * 3, reference(0), reference(0)
            ok = loc.IntersectWithLine(list(p1), list(p2), tol, t, x, pc, sub, cid, gc)
            res.append((ok, float(t), int(cid)))
        (oa, ta, ca), (ob, tb, cb) = res
        hits += ob
        if oa != ob or (ob and ca != cb and abs(ta - tb) > 1e-9 * max(1.0, abs(tb))):
            mismatches += 1
    assert hits > n // 3
    assert mismatches == 0


@pytest.mark.parametrize("tree,exact", [(0, False), (1, False), (0, True)])
def test_rays_match_vtk_cell_locator(tree, exact):
    mesh = matrixtree.read_mesh(os.path.join(scenes.data_dir(), "meshes", "bunny.ply"))
    ours = build(vtkMatrixTreeLocator, mesh, TreeType=tree, ExactOverlap=exact)
    ref = build(vtkCellLocator, mesh)
    b = np.array(mesh.GetBounds()).reshape(3, 2)
    rng = np.random.default_rng(2)
    gc = vtkGenericCell()
    mismatches = hits = 0
    for _ in range(1500):
        p1, u = start_and_direction(rng, b)
        p2 = p1 + u / np.linalg.norm(u) * 0.3
        res = []
        for loc in (ours, ref):
            t, x, pc, sub, cid = reference(0.0), [0.0] * 3, [0.0] * 3, reference(0), reference(0)
            ok = loc.IntersectWithLine(list(p1), list(p2), 0.0, t, x, pc, sub, cid, gc)
            res.append((ok, float(t), int(cid)))
        (oa, ta, ca), (ob, tb, cb) = res
        hits += ob
        if oa != ob or (ob and ca != cb and abs(ta - tb) > 1e-9 * max(1.0, abs(tb))):
            mismatches += 1
    assert hits > 200
    assert mismatches == 0


def test_closest_points_match_vtk():
    mesh = matrixtree.read_mesh(os.path.join(scenes.data_dir(), "scenes", "utah_hand", "hand_00.obj"))
    ours = build(vtkMatrixTreeLocator, mesh)
    ref = build(vtkCellLocator, mesh)
    gc = vtkGenericCell()
    for p in random_points(mesh, 400, seed=9, grow=0.3):
        d = []
        for loc in (ours, ref):
            cp, cid, sub, d2 = [0.0] * 3, reference(0), reference(0), reference(0.0)
            loc.FindClosestPoint(list(p), cp, gc, cid, sub, d2)
            d.append(float(d2))
        assert abs(d[0] - d[1]) <= 1e-12 * max(1.0, d[1])
    # Within a radius: nothing found beyond it, the same answer inside it.
    p = random_points(mesh, 1, seed=1, grow=0.0)[0]
    cp, cid, sub, d2, inside = [0.0] * 3, reference(0), reference(0), reference(0.0), reference(0)
    assert ours.FindClosestPointWithinRadius(list(p), 1e-9, cp, gc, cid, sub, d2, inside) in (0, 1)


def test_cells_within_bounds_and_along_line_match_brute_force():
    ds = matrixtree.read_grid(os.path.join(CFD, "brick_tets.su2"))
    ours = build(vtkMatrixTreeLocator, ds)
    bounds = np.array([[ds.GetCell(i).GetBounds() for i in range(ds.GetNumberOfCells())]]).reshape(-1, 6)
    q = [0.3, 0.8, 0.2, 0.5, -0.1, 0.2]
    ids = vtkIdList()
    ours.FindCellsWithinBounds(q, ids)
    got = sorted(ids.GetId(i) for i in range(ids.GetNumberOfIds()))
    want = np.nonzero((bounds[:, 0] <= q[1]) & (bounds[:, 1] >= q[0]) & (bounds[:, 2] <= q[3]) &
                      (bounds[:, 3] >= q[2]) & (bounds[:, 4] <= q[5]) & (bounds[:, 5] >= q[4]))[0]
    assert got == list(want)
    # Along a line: every cell the segment really crosses is listed.
    p1, p2 = [0.05, 0.1, -0.2], [1.9, 0.9, 0.2]
    ours.FindCellsAlongLine(p1, p2, 0.0, ids)
    along = {ids.GetId(i) for i in range(ids.GetNumberOfIds())}
    crossed = set()
    for i in range(ds.GetNumberOfCells()):
        t, x, pc, sub = reference(0.0), [0.0] * 3, [0.0] * 3, reference(0)
        if ds.GetCell(i).IntersectWithLine(p1, p2, 0.0, t, x, pc, sub):
            crossed.add(i)
    assert crossed and crossed <= along


def test_all_hits_sorted_and_representation():
    mesh = matrixtree.read_mesh(os.path.join(scenes.data_dir(), "meshes", "bunny.ply"))
    ours = build(vtkMatrixTreeLocator, mesh)
    b = np.array(mesh.GetBounds()).reshape(3, 2)
    p1 = [b[0, 0] - 0.01, (b[1, 0] + b[1, 1]) / 2, (b[2, 0] + b[2, 1]) / 2]
    p2 = [b[0, 1] + 0.01, p1[1], p1[2]]
    pts, ids = vtkPoints(), vtkIdList()
    n = ours.IntersectWithLine(p1, p2, pts, ids)
    assert n >= 2 and n % 2 == 0  # a closed surface is entered and left
    xs = [pts.GetPoint(i)[0] for i in range(n)]
    assert xs == sorted(xs)
    rep = vtkPolyData()
    ours.GenerateRepresentation(-1, rep)
    assert rep.GetNumberOfCells() == 6 * ours.GetNumberOfLeaves()
    counts = vtk_to_numpy(rep.GetCellData().GetArray("NumberOfCells"))
    assert counts.sum() == 6 * ours.GetNumberOfReferences()


@pytest.mark.parametrize("grid", ["meshes/bunny.ply", "brick_tets.su2"])
def test_all_hits_are_every_cell_vtk_hits(grid):
    """IntersectWithLine(p1, p2, points, cellIds): every cell whose own VTK IntersectWithLine at
    tol 0 reports a hit, once, sorted by t (ties by id), with VTK's hit point to the bit. The
    reference: vtkCellLocator's cells along the segment (a superset, tolerance 1e-6 of the
    diagonal), each asked of VTK."""
    if grid.startswith("meshes/"):
        ds = matrixtree.read_mesh(os.path.join(scenes.data_dir(), grid))
    else:
        ds = matrixtree.read_grid(os.path.join(CFD, grid))
    ours = build(vtkMatrixTreeLocator, ds)
    ref = build(vtkCellLocator, ds)
    b = np.array(ds.GetBounds()).reshape(3, 2)
    diag = float(np.linalg.norm(b[:, 1] - b[:, 0]))
    rng = np.random.default_rng(17)
    gc = vtkGenericCell()
    total = 0
    for i in range(120):
        p1, u = start_and_direction(rng, b)
        p2 = p1 + u / np.linalg.norm(u) * diag * (0.05, 0.3)[i % 2]
        pts, ids = vtkPoints(), vtkIdList()
        pts.SetDataTypeToDouble()  # the hit points unrounded
        n = ours.IntersectWithLine(list(p1), list(p2), pts, ids)
        got = [(ids.GetId(k), pts.GetPoint(k)) for k in range(n)]
        cand = vtkIdList()
        ref.FindCellsAlongLine(list(p1), list(p2), 1e-6 * diag, cand)
        want = []
        for k in range(cand.GetNumberOfIds()):
            cid = cand.GetId(k)
            ds.GetCell(cid, gc)
            t, x, pc, sub = reference(0.0), [0.0] * 3, [0.0] * 3, reference(0)
            if gc.IntersectWithLine(list(p1), list(p2), 0.0, t, x, pc, sub):
                want.append((float(t), cid, tuple(x)))
        want.sort(key=lambda h: (h[0], h[1]))
        assert got == [(cid, x) for _, cid, x in want], i
        total += n
    assert total > 20


def test_rebuild_only_when_needed():
    ds = matrixtree.read_grid(os.path.join(CFD, "brick_hex.su2"))
    loc = build(vtkMatrixTreeLocator, ds)
    t0 = loc.GetBuildTime()
    loc.BuildLocator()
    assert loc.GetBuildTime() == t0
    ds.Modified()
    loc.BuildLocator()
    assert loc.GetBuildTime() > t0
    loc.UseExistingSearchStructureOn()
    t1 = loc.GetBuildTime()
    ds.Modified()
    loc.BuildLocator()
    assert loc.GetBuildTime() == t1
    loc.FreeSearchStructure()
    assert loc.FindCell([0.5, 0.5, 0.0]) >= 0  # rebuilt lazily on the next query


def test_stream_tracer_matches_vtk_cell_locator():
    """vtkStreamTracer through vtkCellLocatorInterpolatedVelocityField with our locator as the
    prototype traces the same streamlines as with vtkCellLocator, point for point."""
    from vtkmodules.vtkFiltersFlowPaths import vtkCellLocatorInterpolatedVelocityField, vtkStreamTracer
    from vtkmodules.vtkFiltersSources import vtkLineSource

    ds = matrixtree.read_grid(os.path.join(CFD, "pipe_flow_tets.vtu"))
    ds.GetPointData().SetActiveVectors("Velocity")
    seeds = vtkLineSource()
    seeds.SetPoint1(-1.5, 0, 2)
    seeds.SetPoint2(1.5, 0, 2)
    seeds.SetResolution(24)
    lines = {}
    for name, proto in (("ours", vtkMatrixTreeLocator()), ("vtk", vtkCellLocator())):
        field = vtkCellLocatorInterpolatedVelocityField()
        field.SetCellLocatorPrototype(proto)
        st = vtkStreamTracer()
        st.SetInputData(ds)
        st.SetSourceConnection(seeds.GetOutputPort())
        st.SetInterpolatorPrototype(field)
        st.SetMaximumPropagation(60)
        st.SetIntegrationDirectionToBoth()
        st.Update()
        out = st.GetOutput()
        lines[name] = (out.GetNumberOfLines(), vtk_to_numpy(out.GetPoints().GetData()).copy())
    assert lines["vtk"][0] == 50 and len(lines["vtk"][1]) > 5000
    assert lines["ours"][0] == lines["vtk"][0]
    assert np.array_equal(lines["ours"][1], lines["vtk"][1])


def cell_bounds(ds):
    """Per-cell (lo, hi) bounds of an unstructured grid, from its points and connectivity."""
    cells = ds.GetCells()
    off = vtk_to_numpy(cells.GetOffsetsArray()).astype(np.int64)
    conn = vtk_to_numpy(cells.GetConnectivityArray()).astype(np.int64)
    p = vtk_to_numpy(ds.GetPoints().GetData()).astype(float)[conn]
    return np.minimum.reduceat(p, off[:-1], axis=0), np.maximum.reduceat(p, off[:-1], axis=0)


def brute_first_hit(ds, lo, hi, p1, p2, tol, gc, pad):
    """VTK's first hit of the segment over every cell whose bounds (grown by tol + pad) it
    crosses: each cell's own vtkCell::IntersectWithLine, no locator. (hit, t)."""
    d = p2 - p1
    t0, t1 = np.zeros(len(lo)), np.ones(len(lo))
    with np.errstate(divide="ignore", invalid="ignore"):
        for a in range(3):
            if d[a] == 0:
                out = (p1[a] < lo[:, a] - tol - pad) | (p1[a] > hi[:, a] + tol + pad)
                t1[out] = -1.0
                continue
            ta = (lo[:, a] - tol - pad - p1[a]) / d[a]
            tb = (hi[:, a] + tol + pad - p1[a]) / d[a]
            t0 = np.maximum(t0, np.minimum(ta, tb))
            t1 = np.minimum(t1, np.maximum(ta, tb))
    best = None
    for c in np.nonzero(t0 <= t1)[0]:
        ds.GetCell(int(c), gc)
        t, x, pc, sub = reference(0.0), [0.0] * 3, [0.0] * 3, reference(0)
        if gc.IntersectWithLine(list(p1), list(p2), tol, t, x, pc, sub) and (best is None or float(t) < best):
            best = float(t)
    return best is not None, best


@pytest.mark.parametrize("grid", GRIDS)
def test_rays_equal_brute_force_vtk(grid):
    """First hits at tol 0 (and some at tol > 0) equal the smallest t VTK reports over every
    cell whose bounds the segment crosses — no locator in the reference. This guards the ray
    queries' per-leaf test on the quantized boxes (a cell skipped in one leaf must be found in
    the leaf where the segment hits it), so a third of the segments start at leaf corners and
    run along leaf faces, edges and diagonals, where round-off decides which leaf holds a point;
    the rest start inside the grid, outside it and at grid vertices."""
    ds = matrixtree.read_grid(os.path.join(CFD, grid))
    ours = build(vtkMatrixTreeLocator, ds)
    lo, hi = cell_bounds(ds)
    b = np.array(ds.GetBounds()).reshape(3, 2)
    diag = float(np.linalg.norm(b[:, 1] - b[:, 0]))
    rep = vtkPolyData()
    ours.GenerateRepresentation(ours.GetTreeHeight(), rep)
    corners = vtk_to_numpy(rep.GetPoints().GetData()).astype(float)
    leaf = np.abs(corners[1] - corners[0]).max()  # a leaf's x extent (points 0, 1 differ in x)
    pts = vtk_to_numpy(ds.GetPoints().GetData()).astype(float)
    rng = np.random.default_rng(17)
    gc, gc2 = vtkGenericCell(), vtkGenericCell()
    n = 300 if ds.GetNumberOfCells() > 100000 else 700
    hits = mismatches = 0
    bad = []
    for i in range(n):
        kind = i % 6
        u = rng.normal(size=3)
        if kind == 0:
            p1 = random_points(ds, 1, seed=int(rng.integers(1 << 30)), grow=0.0)[0]
        elif kind == 1:
            p1 = random_points(ds, 1, seed=int(rng.integers(1 << 30)), grow=0.2)[0]
        elif kind == 2:
            p1 = pts[rng.integers(len(pts))].copy()
        else:
            p1 = corners[rng.integers(len(corners))].copy()
            if kind == 4:  # along a leaf face or edge: some direction components zero
                u[rng.random(3) < 0.5] = 0.0
                if not u.any():
                    u[rng.integers(3)] = 1.0
            elif kind == 5:  # along a face or space diagonal of the leaves
                u = np.sign(rng.normal(size=3)) * (rng.random(3) < 0.7)
                if not u.any():
                    u[0] = 1.0
        p2 = p1 + u / np.linalg.norm(u) * (0.05 * diag if kind < 3 else 2.5 * leaf)
        tol = 0.0 if i % 5 else 1e-6 * diag
        ok, t = brute_first_hit(ds, lo, hi, p1, p2, tol, gc, 1e-9 * diag)
        to, x, pc, sub, cid = reference(0.0), [0.0] * 3, [0.0] * 3, reference(0), reference(0)
        oa = ours.IntersectWithLine(list(p1), list(p2), tol, to, x, pc, sub, cid, gc2)
        hits += ok
        if bool(oa) != ok or (ok and abs(float(to) - t) > 1e-9 * max(1.0, abs(t))):
            mismatches += 1
            bad.append((kind, tol, list(p1), list(p2), ok, t, oa, float(to)))
            continue
        if ok:  # the cell handed back is our cell, as GetCell gives it, and VTK hits it at our t
            ds.GetCell(int(cid), gc)
            assert gc2.GetCellType() == gc.GetCellType()
            assert [gc2.GetPointId(k) for k in range(gc2.GetNumberOfPoints())] == \
                [gc.GetPointId(k) for k in range(gc.GetNumberOfPoints())]
            assert np.array_equal(vtk_to_numpy(gc2.GetPoints().GetData()), vtk_to_numpy(gc.GetPoints().GetData()))
            tc = reference(0.0)
            assert gc.IntersectWithLine(list(p1), list(p2), tol, tc, x, pc, sub)
            assert float(tc) == float(to)
    assert hits > n // 4
    assert mismatches == 0, bad[:5]


@pytest.mark.parametrize("grid", ["brick_hex.su2", "disk_out_ref.ex2", "brick_prism.su2", "brick_pyra.su2",
                                  "brick_tets.su2", "pipe_flow_tets.vtu", "meshes/bunny.ply", "meshes/lucy.ply"])
def test_ray_hit_values_are_vtks_own(grid):
    """At tol 0, a hit's t, x, pcoords and subId are exactly what VTK's IntersectWithLine of the
    returned cell gives (bit for bit): the hexahedra, wedges and tetrahedra whose hit face is
    certain are answered by that one face's test (CertainFaceHit), and the surfaces' triangles by
    the triangle's, both recomputed in VTK 9.1's arithmetic (mtree/vtk91/face_hit.h); neither may
    differ from VTK's whole cell.
    Segments of random directions and lengths from points inside the grid and around it, some
    nearly parallel to a coordinate plane (grazing the faces of axis-aligned cells)."""
    if grid.startswith("meshes/"):
        ds = matrixtree.read_mesh(os.path.join(scenes.data_dir(), grid))
    else:
        ds = matrixtree.read_grid(os.path.join(CFD, grid))
    ours = build(vtkMatrixTreeLocator, ds)
    b = np.array(ds.GetBounds()).reshape(3, 2)
    diag = float(np.linalg.norm(b[:, 1] - b[:, 0]))
    rng = np.random.default_rng(29)
    gc, gc2 = vtkGenericCell(), vtkGenericCell()
    n = 3000
    hits = 0
    for i in range(n):
        p1 = random_points(ds, 1, seed=int(rng.integers(1 << 30)), grow=0.1 * (i % 2))[0]
        u = rng.normal(size=3)
        if i % 4 == 3:
            u[rng.integers(3)] *= 1e-3
        p2 = p1 + u / np.linalg.norm(u) * diag * (0.01, 0.1, 0.5)[i % 3]
        t, x, pc, sub, cid = reference(0.0), [0.0] * 3, [0.0] * 3, reference(-7), reference(-1)
        if not ours.IntersectWithLine(list(p1), list(p2), 0.0, t, x, pc, sub, cid, gc):
            continue
        hits += 1
        ds.GetCell(int(cid), gc2)
        t2, x2, pc2, sub2 = reference(0.0), [0.0] * 3, [0.0] * 3, reference(-7)
        assert gc2.IntersectWithLine(list(p1), list(p2), 0.0, t2, x2, pc2, sub2)
        assert (float(t), x, pc, int(sub)) == (float(t2), x2, pc2, int(sub2)), (i, list(p1), list(p2), int(cid))
    assert hits > (n // 10 if grid.startswith("meshes/") else n // 2)

"""matrixtree.filters (the pyvista-style surface, and the mesh.matrixtree accessor where pyvista
has accessors) against analytic answers, brute force and VTK's own filters (vtkProbeFilter,
vtkCellLocator, vtkOBBTree through pyvista's methods).

Runs in both environments: the project's .venv (the VTK module answers) and the pip
environment (the engine extension answers), so it needs no VTK C++ class of this project.
"""

from __future__ import annotations

import numpy as np
import pytest
import pyvista as pv
from vtkmodules.vtkCommonCore import vtkVersion

import matrixtree
from matrixtree import filters

from test_engine import closest_on_triangles

HEX, WEDGE, PYRAMID, TETRA, QUADRATIC_TETRA = 12, 13, 14, 10, 24
LINEAR = np.array([1.0, -2.0, 0.5])


def mixed_grid(n=3):
    """The unit cube as n^3 lattice hexahedra, each kept whole or split into 2 wedges, 6 pyramids
    (apex at its centre) or 6 tetrahedra (round-robin). Cell data ``parent``: the lattice
    hexahedron each cell lies in (i * n + j) * n + k; point data ``f`` and ``v``: linear fields, ``i``: an integer one."""
    g = np.linspace(0.0, 1.0, n + 1)
    pts = [np.stack(np.meshgrid(g, g, g, indexing="ij"), axis=-1).reshape(-1, 3)]
    idx = lambda i, j, k: (i * (n + 1) + j) * (n + 1) + k  # noqa: E731
    cells, types, parent = [], [], []
    extra = len(pts[0])
    for i in range(n):
        for j in range(n):
            for k in range(n):
                h = [idx(i, j, k), idx(i + 1, j, k), idx(i + 1, j + 1, k), idx(i, j + 1, k),
                     idx(i, j, k + 1), idx(i + 1, j, k + 1), idx(i + 1, j + 1, k + 1), idx(i, j + 1, k + 1)]
                p = (i * n + j) * n + k
                kind = p % 4
                if kind == 0:
                    new = [(HEX, h)]
                elif kind == 1:
                    new = [(WEDGE, [h[0], h[1], h[3], h[4], h[5], h[7]]), (WEDGE, [h[1], h[2], h[3], h[5], h[6], h[7]])]
                elif kind == 2:
                    pts.append(np.array([[(i + 0.5) / n, (j + 0.5) / n, (k + 0.5) / n]]))
                    c = extra
                    extra += 1
                    # The hexahedron's faces seen from its centre (VTK's base order: its normal
                    # points to the apex).
                    faces = [[0, 1, 2, 3], [7, 6, 5, 4], [4, 5, 1, 0], [5, 6, 2, 1], [6, 7, 3, 2], [7, 4, 0, 3]]
                    new = [(PYRAMID, [h[f[0]], h[f[1]], h[f[2]], h[f[3]], c]) for f in faces]
                else:
                    paths = [(1, 2), (1, 5), (3, 2), (3, 7), (4, 5), (4, 7)]
                    new = [(TETRA, [h[0], h[a], h[b], h[6]]) for a, b in paths]
                for t, c in new:
                    cells += [len(c)] + list(c)
                    types.append(t)
                    parent.append(p)
    grid = pv.UnstructuredGrid(np.array(cells), np.array(types, np.uint8), np.vstack(pts))
    grid.point_data["f"] = grid.points @ LINEAR + 3.0
    grid.point_data["v"] = np.column_stack([grid.points[:, 0], 2 * grid.points[:, 1], np.ones(grid.n_points)])
    grid.point_data["i"] = np.round(30 * grid.points[:, 2]).astype(np.int32)   # 30 z is integral at every point
    grid.cell_data["parent"] = np.array(parent, np.int64)
    return grid


def off_faces(x, n, margin=2e-3):
    """Whether each point lies at least ``margin`` lattice cells from every lattice plane (which
    decide the ``parent`` of the cell containing it): beyond the 1e-3 parametric tolerance with
    which VTK's cells accept points just outside them."""
    u = x * n
    return np.all(np.abs(u - np.round(u)) > margin, axis=1)


def vtk_probe(source, points):
    """vtkProbeFilter (VTK's own, with vtkCellLocator) of ``source``'s arrays at ``points``."""
    from vtkmodules.vtkCommonDataModel import vtkCellLocator
    from vtkmodules.vtkFiltersCore import vtkProbeFilter

    probe = vtkProbeFilter()
    probe.SetInputData(pv.PolyData(points))
    probe.SetSourceData(source)
    # VTK 9.7 names the setter SetCellLocator; 9.1 has SetCellLocatorPrototype only.
    (getattr(probe, "SetCellLocator", None) or probe.SetCellLocatorPrototype)(vtkCellLocator())
    probe.Update()
    return pv.wrap(probe.GetOutput())


@pytest.fixture(scope="module")
def grid():
    return mixed_grid()


def test_containing_cell_scalar_for_one_point_array_for_many(grid):
    x = np.random.default_rng(0).uniform(-0.2, 1.2, (3000, 3))
    ids = matrixtree.find_containing_cell(grid, x)
    assert ids.shape == (3000,) and ids.dtype == np.int64
    parent = np.asarray(grid.cell_data["parent"])
    inside = off_faces(x, 3) & np.all((x > 0) & (x < 1), axis=1)
    outside = np.any((x < -1e-3) | (x > 1 + 1e-3), axis=1)
    cube = np.floor(x * 3).astype(int)
    assert (ids[inside] >= 0).all() and (ids[outside] == -1).all()
    np.testing.assert_array_equal(parent[ids[inside]], ((cube[:, 0] * 3 + cube[:, 1]) * 3 + cube[:, 2])[inside])
    one = matrixtree.find_containing_cell(grid, x[np.argmax(inside)])
    assert isinstance(one, int) and one == ids[np.argmax(inside)]
    assert matrixtree.find_containing_cell(grid, [5.0, 5.0, 5.0]) == -1
    two = matrixtree.find_containing_cell(grid, x[:1])
    assert isinstance(two, np.ndarray) and two.shape == (1,)


def test_closest_cell_equals_vtks_cell_locator():
    sphere = pv.Sphere(theta_resolution=24, phi_resolution=16)
    x = np.random.default_rng(1).normal(size=(400, 3))
    ids, closest = matrixtree.find_closest_cell(sphere, x, return_closest_point=True)
    ref_ids, ref_closest = sphere.find_closest_cell(x, return_closest_point=True)   # vtkCellLocator
    d = np.linalg.norm(closest - x, axis=1)
    ref_d = np.linalg.norm(ref_closest - x, axis=1)
    np.testing.assert_allclose(d, ref_d, rtol=1e-6, atol=1e-9)
    # Where the closest point is a shared vertex or edge either cell is right: it lies on ours.
    tri = np.asarray(sphere.points, dtype=np.float64)[sphere.regular_faces[ids]]
    on = closest_on_triangles(closest, tri[:, 0], tri[:, 1], tri[:, 2])[np.arange(len(x)), np.arange(len(x))]
    np.testing.assert_allclose(on, closest, atol=1e-12)
    # Where it lies inside one triangle (barycentric coordinates all > 1e-6), that is VTK's cell too.
    e1, e2, r = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0], closest - tri[:, 0]
    d11, d12, d22 = (e1 * e1).sum(1), (e1 * e2).sum(1), (e2 * e2).sum(1)
    r1, r2 = (r * e1).sum(1), (r * e2).sum(1)
    den = d11 * d22 - d12 * d12
    b1, b2 = (d22 * r1 - d12 * r2) / den, (d11 * r2 - d12 * r1) / den
    interior = (b1 > 1e-6) & (b2 > 1e-6) & (1 - b1 - b2 > 1e-6)
    assert interior.sum() > 20
    np.testing.assert_array_equal(ids[interior], ref_ids[interior])
    one, cp = matrixtree.find_closest_cell(sphere, [0.0, 0.0, 2.0], return_closest_point=True)
    assert isinstance(one, int) and cp.shape == (3,)
    assert matrixtree.find_closest_cell(sphere, [0.0, 0.0, 2.0]) == one


def test_cells_within_bounds_and_along_line_match_brute_force(grid):
    cells = [grid.get_cell(i) for i in range(grid.n_cells)]
    lo = np.array([c.bounds[0::2] for c in cells])
    hi = np.array([c.bounds[1::2] for c in cells])
    box = [0.2, 0.55, 0.1, 0.4, 0.6, 0.95]
    b = np.array(box)
    expect = np.flatnonzero(np.all((lo <= b[1::2]) & (hi >= b[0::2]), axis=1))
    np.testing.assert_array_equal(matrixtree.find_cells_within_bounds(grid, box), expect)
    # A slanted segment, and one parallel to z (axes it runs along: inside the slab or not at all).
    for p1, p2 in (([-0.2, 0.13, 0.37], [1.3, 0.71, 0.52]), ([0.4, 0.55, -1.0], [0.4, 0.55, 2.0])):
        p1, p2 = np.array(p1), np.array(p2)
        d = p2 - p1
        with np.errstate(divide="ignore", invalid="ignore"):
            t0, t1 = (lo - p1) / d, (hi - p1) / d
        near = np.where(d == 0, np.where((p1 >= lo) & (p1 <= hi), -np.inf, np.inf), np.minimum(t0, t1))
        far = np.where(d == 0, np.where((p1 >= lo) & (p1 <= hi), np.inf, -np.inf), np.maximum(t0, t1))
        expect = np.flatnonzero(np.maximum(near.max(axis=1), 0) <= np.minimum(far.min(axis=1), 1))
        assert 0 < len(expect) < grid.n_cells
        np.testing.assert_array_equal(matrixtree.find_cells_along_line(grid, p1, p2), expect)


def test_probe_interpolates_point_and_cell_data_of_every_linear_cell(grid):
    x = np.random.default_rng(2).uniform(-0.1, 1.1, (4000, 3))
    out = matrixtree.probe(grid, x)
    assert isinstance(out, pv.PolyData) and out.n_points == len(x)
    mask = np.asarray(out.point_data["vtkValidPointMask"])
    inside = off_faces(x, 3) & np.all((x > 0) & (x < 1), axis=1)
    outside = np.any((x < -1e-3) | (x > 1 + 1e-3), axis=1)
    assert mask.dtype == np.int8 and (mask[inside] == 1).all() and (mask[outside] == 0).all()
    found = mask == 1
    # Linear fields are reproduced exactly by every isoparametric cell; cell data is the cell's.
    np.testing.assert_allclose(out.point_data["f"][found], x[found] @ LINEAR + 3.0, atol=1e-9)
    np.testing.assert_allclose(out.point_data["v"][found],
                               np.column_stack([x[:, 0], 2 * x[:, 1], np.ones(len(x))])[found], atol=1e-9)
    cube = np.floor(x * 3).astype(int)
    np.testing.assert_array_equal(out.point_data["parent"][inside],
                                  ((cube[:, 0] * 3 + cube[:, 1]) * 3 + cube[:, 2])[inside])
    # Integer arrays round half away from zero, as VTK interpolates them.
    np.testing.assert_array_equal(out.point_data["i"][found], np.floor(30 * x[found, 2] + 0.5).astype(np.int32))
    assert out.point_data["i"].dtype == np.int32
    # Outside every cell: zeros, as vtkProbeFilter.
    assert not out.point_data["f"][~found].any() and not out.point_data["parent"][~found].any()
    # VTK's own probe agrees wherever the point is clearly inside or outside.
    ref = vtk_probe(grid, x)
    sure = inside | outside
    np.testing.assert_array_equal(ref.point_data["vtkValidPointMask"][sure], mask[sure])
    for name in ("f", "v", "parent"):
        np.testing.assert_allclose(out.point_data[name][sure], ref.point_data[name][sure], atol=1e-9)


def test_sample_keeps_the_targets_geometry_and_own_arrays(grid):
    plane = pv.Plane(center=(0.5, 0.5, 0.4), direction=(0.2, 0.1, 1.0), i_size=1.4, j_size=1.4,
                     i_resolution=30, j_resolution=30)
    plane.point_data["own"] = np.arange(plane.n_points)
    plane.cell_data["own_cell"] = np.arange(plane.n_cells)
    out = matrixtree.sample(plane, grid)
    assert type(out) is pv.PolyData and out.n_points == plane.n_points and out.n_cells == plane.n_cells
    np.testing.assert_array_equal(out.points, plane.points)
    assert "own" in out.point_data and "own_cell" in out.cell_data and "parent" in out.point_data
    found = out.point_data["vtkValidPointMask"] == 1
    assert 0.3 < found.mean() < 1.0
    np.testing.assert_allclose(out.point_data["f"][found], np.asarray(plane.points)[found] @ LINEAR + 3.0, atol=1e-6)
    bare = matrixtree.sample(plane, grid, pass_point_data=False, pass_cell_data=False)
    assert "own" not in bare.point_data and "own_cell" not in bare.cell_data and "f" in bare.point_data
    assert "own" in plane.point_data                      # the input is not changed


def test_probe_surfaces_and_images():
    # 2-D cells: points in the plane of a quad mesh; voxels: an image's cells.
    plane = pv.Plane(i_resolution=7, j_resolution=5)      # quads in z = 0, [-0.5, 0.5]^2
    plane.point_data["g"] = plane.points[:, 0] * 2 - plane.points[:, 1]
    rng = np.random.default_rng(3)
    x = np.column_stack([rng.uniform(-0.6, 0.6, 500), rng.uniform(-0.6, 0.6, 500), np.zeros(500)])
    out = matrixtree.probe(plane, x)
    inside = np.all(np.abs(x[:, :2]) < 0.5 - 1e-9, axis=1)
    np.testing.assert_array_equal(out.point_data["vtkValidPointMask"] == 1, inside)
    np.testing.assert_allclose(out.point_data["g"][inside], (2 * x[:, 0] - x[:, 1])[inside], atol=1e-9)
    image = pv.ImageData(dimensions=(5, 4, 3), spacing=(0.5, 1.0, 2.0), origin=(1, 2, 3))
    image.point_data["h"] = image.points @ [1.0, 1.0, 1.0]
    image.cell_data["c"] = np.arange(image.n_cells, dtype=np.float32)
    y = rng.uniform([1, 2, 3], [3, 5, 7], (800, 3))
    out = matrixtree.probe(image, y)
    assert (out.point_data["vtkValidPointMask"] == 1).all()
    np.testing.assert_allclose(out.point_data["h"], y.sum(axis=1), atol=1e-9)
    ijk = np.floor((y - [1, 2, 3]) / [0.5, 1.0, 2.0]).astype(int)
    np.testing.assert_array_equal(out.point_data["c"], ijk[:, 0] + 4 * (ijk[:, 1] + 3 * ijk[:, 2]))
    assert out.point_data["c"].dtype == np.float32


def test_probe_of_quadratic_cells_equals_vtks_probe():
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    mids = np.array([(pts[a] + pts[b]) / 2 for a, b in [(0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3)]])
    tet = pv.UnstructuredGrid(np.array([10, *range(10)]), np.array([QUADRATIC_TETRA], np.uint8), np.vstack([pts, mids]))
    tet.point_data["q"] = tet.points[:, 0] ** 2 + tet.points[:, 1]
    x = np.array([[0.1, 0.2, 0.3], [0.2, 0.2, 0.2], [0.9, 0.9, 0.9]])
    # Both extensions answer as VTK 9.1: the VTK module asks VTK's cells, the engine its VTK 9.1
    # cell mirror. Newer VTKs' probe filters differ (VTK 9.7 calls (0.9, 0.9, 0.9) valid).
    out = matrixtree.probe(tet, x)
    ref = vtk_probe(tet, x)
    np.testing.assert_array_equal(out.point_data["vtkValidPointMask"], [1, 1, 0])
    assert out.point_data["q"][2] == 0
    if vtkVersion.GetVTKMajorVersion() == 9 and vtkVersion.GetVTKMinorVersion() == 1:  # the mirror's VTK
        np.testing.assert_array_equal(ref.point_data["vtkValidPointMask"], [1, 1, 0])
        np.testing.assert_allclose(out.point_data["q"], ref.point_data["q"], atol=1e-12)
    np.testing.assert_allclose(out.point_data["q"][:2], x[:2, 0] ** 2 + x[:2, 1], atol=1e-4)  # VTK's Newton tolerance


def test_ray_trace_equals_pyvistas_obb_tree():
    sphere = pv.Sphere(theta_resolution=40, phi_resolution=30)
    rng = np.random.default_rng(4)
    for _ in range(20):
        a, b = rng.uniform(-1, 1, 3), rng.uniform(-1, 1, 3)
        pts, cells = matrixtree.ray_trace(sphere, a, b)
        ref_pts, ref_cells = sphere.ray_trace(a, b)      # vtkOBBTree
        assert pts.shape == ref_pts.shape
        order = np.argsort(np.linalg.norm(ref_pts - a, axis=1))
        np.testing.assert_allclose(pts, ref_pts[order], atol=1e-9)
        np.testing.assert_array_equal(cells, np.asarray(ref_cells)[order])
    p, c = matrixtree.ray_trace(sphere, [0, 0, 0], [1, 0, 0], first_point=True)
    rp, rc = sphere.ray_trace([0, 0, 0], [1, 0, 0], first_point=True)
    np.testing.assert_allclose(p, rp, atol=1e-9)
    assert p.shape == (3,) and isinstance(c, int)
    p, c = matrixtree.ray_trace(sphere, [2, 2, 2], [3, 3, 3], first_point=True)
    assert p.shape == (0, 3) and c.shape == (0,)


def test_multi_ray_trace_matches_brute_force():
    sphere = pv.Sphere(theta_resolution=32, phi_resolution=24).triangulate()
    tris = np.asarray(sphere.points)[sphere.regular_faces]
    rng = np.random.default_rng(5)
    o = rng.uniform(-1.5, 1.5, (300, 3))
    d = rng.normal(size=(300, 3))
    e1, e2 = tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]
    p = np.cross(d[:, None], e2[None])
    det = (e1[None] * p).sum(-1)
    s = o[:, None] - tris[None, :, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        u = (s * p).sum(-1) / det
        q = np.cross(s, e1[None])
        v = (d[:, None] * q).sum(-1) / det
        t = (e2[None] * q).sum(-1) / det
    hit = (det != 0) & (u >= 0) & (v >= 0) & (u + v <= 1) & (t >= 0)
    points, rays, cells = matrixtree.multi_ray_trace(sphere, o, d)
    counts = np.bincount(rays, minlength=len(o))
    # Rays through a shared edge may count a triangle the brute force rounds out: compare away from edges.
    assert (np.abs(counts - hit.sum(axis=1)) <= 1).all() and (counts == hit.sum(axis=1)).mean() > 0.97
    assert (np.diff(rays) >= 0).all()
    first_p, first_r, first_c = matrixtree.multi_ray_trace(sphere, o, d, first_point=True)
    tb = np.where(hit, t, np.inf)
    any_hit = np.isfinite(tb.min(axis=1))
    np.testing.assert_array_equal(first_r, np.flatnonzero(any_hit))
    np.testing.assert_allclose(first_p, o[any_hit] + d[any_hit] * tb.min(axis=1)[any_hit, None], atol=1e-9)
    np.testing.assert_array_equal(first_c, tb.argmin(axis=1)[any_hit])


def test_progress_bar_batches_give_the_same_answers(grid, monkeypatch):
    x = np.random.default_rng(6).uniform(-0.1, 1.1, (1000, 3))
    whole = matrixtree.probe(grid, x)
    rays = matrixtree.multi_ray_trace(grid, x[:300], np.ones((300, 3)))
    monkeypatch.setattr(filters, "CHUNK", 64)
    batched = matrixtree.probe(grid, x, progress_bar=True)
    for name in ("f", "parent", "vtkValidPointMask"):
        np.testing.assert_array_equal(batched.point_data[name], whole.point_data[name])
    for a, b in zip(matrixtree.multi_ray_trace(grid, x[:300], np.ones((300, 3)), progress_bar=True), rays):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(matrixtree.find_containing_cell(grid, x, progress_bar=True),
                                  matrixtree.find_containing_cell(grid, x))


def test_results_go_straight_to_add_mesh(grid):
    plotter = pv.Plotter(off_screen=True)
    out = matrixtree.probe(grid, np.random.default_rng(7).uniform(0, 1, (50, 3)))
    plotter.add_mesh(out, scalars="f", show_scalar_bar=False)
    points, _ = matrixtree.ray_trace(grid, [-1, 0.5, 0.5], [2, 0.5, 0.5])
    plotter.add_mesh(points)                               # an (n, 3) array is a point cloud
    plotter.add_mesh(matrixtree.tree_mesh(grid, levels=-1), style="wireframe")
    assert len(plotter.meshes) == 3                        # (pyvista 0.49 adds a scalar bar actor too)
    plotter.close()


def test_a_locator_given_must_be_over_the_mesh(grid):
    other = mixed_grid(2)
    with pytest.raises(ValueError, match="built over this mesh"):
        matrixtree.probe(grid, [[0.5, 0.5, 0.5]], locator=matrixtree.CellLocator(other))
    loc = matrixtree.CellLocator(grid)
    assert matrixtree.find_containing_cell(grid, [0.5, 0.5, 0.5], locator=loc) >= 0 and loc.builds == 1


@pytest.mark.skipif(not filters.HAS_ACCESSOR, reason=f"pyvista {pv.__version__} has no dataset accessors (0.48+)")
def test_accessor_keeps_one_locator_and_equals_the_functions(grid):
    x = np.random.default_rng(8).uniform(-0.1, 1.1, (500, 3))
    acc = grid.matrixtree
    assert acc is grid.matrixtree and acc.locator is acc.locator
    np.testing.assert_array_equal(acc.find_containing_cell(x), matrixtree.find_containing_cell(grid, x))
    out = acc.probe(x)
    np.testing.assert_array_equal(out.point_data["f"], matrixtree.probe(grid, x).point_data["f"])
    plane = pv.Plane(center=(0.5, 0.5, 0.5), i_resolution=8, j_resolution=8)
    np.testing.assert_array_equal(plane.matrixtree.sample(grid).point_data["f"],
                                  matrixtree.sample(plane, grid).point_data["f"])
    assert grid.matrixtree.locator.builds == 1            # sample reused the target's locator
    sphere = pv.Sphere()
    np.testing.assert_array_equal(sphere.matrixtree.ray_trace([0, 0, -1], [0, 0, 1])[1],
                                  matrixtree.ray_trace(sphere, [0, 0, -1], [0, 0, 1])[1])

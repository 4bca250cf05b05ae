"""The engine extension (matrixtree_engine) against brute force, with numpy alone.

These run wherever the extension is built: in the project's .venv (scripts/setup.sh builds it
into build/engine-python) and in the isolated pip environment (``pip install .``), where no
VTK C++ library exists. Every reference here is computed from the cells' definitions over all
cells (barycentric coordinates, affine inverses, point-triangle distances, Moller-Trumbore),
never from the locator's own tree.
"""

from __future__ import annotations

import numpy as np
import pytest

engine = pytest.importorskip("matrixtree_engine")

VTK_TRIANGLE, VTK_QUAD, VTK_TETRA, VTK_HEXAHEDRON, VTK_WEDGE = 5, 9, 10, 12, 13
TOL = 1e-3  # VTK's parametric tolerance for tetrahedra


# ---- generated meshes ------------------------------------------------------------------------

def grid_points(n, jitter=0.0, seed=0):
    """(n+1)^3 lattice points of the unit cube, interior points moved by up to jitter cells."""
    g = np.linspace(0.0, 1.0, n + 1)
    x, y, z = np.meshgrid(g, g, g, indexing="ij")
    pts = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    if jitter:
        rng = np.random.default_rng(seed)
        inner = np.all((pts > 0) & (pts < 1), axis=1)
        pts[inner] += rng.uniform(-jitter, jitter, (inner.sum(), 3)) / n
    return pts


def lattice_index(n):
    def idx(i, j, k):
        return (i * (n + 1) + j) * (n + 1) + k
    return idx


def tet_grid(n, jitter=0.0):
    """Six tetrahedra per lattice cube (Freudenthal's split: conforming, positive volumes)."""
    pts = grid_points(n, jitter)
    idx = lattice_index(n)
    i, j, k = (a.ravel() for a in np.meshgrid(*(np.arange(n),) * 3, indexing="ij"))
    corner = lambda di, dj, dk: idx(i + di, j + dj, k + dk)
    v000, v111 = corner(0, 0, 0), corner(1, 1, 1)
    paths = [((1, 0, 0), (1, 1, 0)), ((1, 0, 0), (1, 0, 1)), ((0, 1, 0), (1, 1, 0)),
             ((0, 1, 0), (0, 1, 1)), ((0, 0, 1), (1, 0, 1)), ((0, 0, 1), (0, 1, 1))]
    tets = np.concatenate([np.stack([v000, corner(*a), corner(*b), v111], axis=1) for a, b in paths])
    return pts, tets


def hex_grid(n, matrix=None, shift=(0.0, 0.0, 0.0)):
    """n^3 hexahedra of the unit cube mapped by x -> matrix @ x + shift (parallelepipeds)."""
    pts = grid_points(n)
    idx = lattice_index(n)
    i, j, k = (a.ravel() for a in np.meshgrid(*(np.arange(n),) * 3, indexing="ij"))
    # VTK's hexahedron order: the bottom face counter-clockwise, then the top face.
    hexes = np.stack([idx(i, j, k), idx(i + 1, j, k), idx(i + 1, j + 1, k), idx(i, j + 1, k),
                      idx(i, j, k + 1), idx(i + 1, j, k + 1), idx(i + 1, j + 1, k + 1), idx(i, j + 1, k + 1)], axis=1)
    m = np.eye(3) if matrix is None else np.asarray(matrix, float)
    return pts @ m.T + np.asarray(shift), hexes, m


def sphere_surface(n_theta=24, n_phi=16, radius=1.0, center=(0.0, 0.0, 0.0)):
    """A closed triangulated sphere: poles plus latitude rings."""
    phi = np.linspace(0, np.pi, n_phi + 1)[1:-1]
    theta = np.linspace(0, 2 * np.pi, n_theta, endpoint=False)
    ring = np.stack([np.outer(np.sin(phi), np.cos(theta)).ravel(), np.outer(np.sin(phi), np.sin(theta)).ravel(),
                     np.repeat(np.cos(phi), n_theta)], axis=1)
    pts = np.vstack([[0, 0, 1], ring, [0, 0, -1]]) * radius + np.asarray(center)
    top, bottom = 0, len(pts) - 1
    r = lambda a, t: 1 + a * n_theta + t % n_theta
    tris = []
    for t in range(n_theta):
        tris.append([top, r(0, t), r(0, t + 1)])
        tris.append([bottom, r(n_phi - 2, t + 1), r(n_phi - 2, t)])
        for a in range(n_phi - 2):
            tris.append([r(a, t), r(a + 1, t), r(a + 1, t + 1)])
            tris.append([r(a, t), r(a + 1, t + 1), r(a, t + 1)])
    return pts, np.array(tris, dtype=np.int64)


def single_type(cells, vtk_type):
    cells = np.asarray(cells, dtype=np.int64)
    n, k = cells.shape
    return (np.arange(0, n * k + 1, k, dtype=np.int64), cells.ravel(),
            np.full(n, vtk_type, dtype=np.uint8))


def locator(pts, cells, vtk_type, **kw):
    off, conn, types = single_type(cells, vtk_type)
    return engine.CellLocator(pts, off, conn, types, **kw)


def surface_tree(pts, tris, cls=None, **kw):
    off = np.arange(0, 3 * len(tris) + 1, 3, dtype=np.int64)
    empty = np.zeros(0, dtype=np.int64)
    return (cls or engine.SurfaceTree)(pts, off, tris.ravel(), empty, empty, 0, **kw)


# ---- brute-force references ------------------------------------------------------------------

def tet_barycentrics(pts, tets, x):
    """(m, t, 4) barycentric coordinates of every point in every tetrahedron (VTK's weight order)."""
    p = pts[tets]                                        # (t, 4, 3)
    m = np.stack([p[:, 1] - p[:, 0], p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]], axis=2)  # columns
    inv = np.linalg.inv(m)                               # (t, 3, 3)
    r = x[:, None, :] - p[None, :, 0, :]                 # (m, t, 3)
    b = np.einsum("tij,mtj->mti", inv, r)
    return np.concatenate([1 - b.sum(axis=2, keepdims=True), b], axis=2)


def closest_on_triangles(x, a, b, c):
    """Closest point on each triangle (a, b, c: (t, 3)) to each point x (m, 3): (m, t, 3)."""
    x = x[:, None, :]
    ab, ac, ap = b - a, c - a, x - a
    d1, d2 = (ab * ap).sum(-1), (ac * ap).sum(-1)
    bp = x - b
    d3, d4 = (ab * bp).sum(-1), (ac * bp).sum(-1)
    cp = x - c
    d5, d6 = (ab * cp).sum(-1), (ac * cp).sum(-1)
    vc, vb, va = d1 * d4 - d3 * d2, d5 * d2 - d1 * d6, d3 * d6 - d5 * d4
    with np.errstate(divide="ignore", invalid="ignore"):
        denom = va + vb + vc
        out = a + ab * (vb / denom)[..., None] + ac * (vc / denom)[..., None]
        edge_bc = b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)))[..., None]
        edge_ac = a + ac * (d2 / (d2 - d6))[..., None]
        edge_ab = a + ab * (d1 / (d1 - d3))[..., None]
    out = np.where(((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0))[..., None], edge_bc, out)
    out = np.where(((vb <= 0) & (d2 >= 0) & (d6 <= 0))[..., None], edge_ac, out)
    out = np.where(((d6 >= 0) & (d5 <= d6))[..., None], np.broadcast_to(c, out.shape), out)
    out = np.where(((vc <= 0) & (d1 >= 0) & (d3 <= 0))[..., None], edge_ab, out)
    out = np.where(((d3 >= 0) & (d4 <= d3))[..., None], np.broadcast_to(b, out.shape), out)
    out = np.where(((d1 <= 0) & (d2 <= 0))[..., None], np.broadcast_to(a, out.shape), out)
    return out


def ray_triangles(o, d, a, b, c):
    """Moller-Trumbore of every ray (m, 3) with every triangle (t, 3): t (m, t), inf on a miss."""
    e1, e2 = b - a, c - a
    p = np.cross(d[:, None, :], e2[None])
    det = (e1[None] * p).sum(-1)
    s = o[:, None, :] - a[None]
    with np.errstate(divide="ignore", invalid="ignore"):
        u = (s * p).sum(-1) / det
        q = np.cross(s, e1[None])
        v = (d[:, None, :] * q).sum(-1) / det
        t = (e2[None] * q).sum(-1) / det
    ok = (det != 0) & (u >= 0) & (v >= 0) & (u + v <= 1) & (t >= 0)
    return np.where(ok, t, np.inf)


# ---- cell location ---------------------------------------------------------------------------

@pytest.mark.parametrize("tree", ["octree", "kdtree"])
def test_locate_tetrahedra_matches_brute_force(tree):
    pts, tets = tet_grid(6, jitter=0.25)
    loc = locator(pts, tets, VTK_TETRA, tree=tree)
    rng = np.random.default_rng(1)
    x = rng.uniform(-0.1, 1.1, (3000, 3))
    ids, pc, w = loc.find_cells(x, pcoords=True, weights=True)
    assert ids.dtype == np.int64 and w.shape == (len(x), 4) and pc.shape == (len(x), 3)
    bary = tet_barycentrics(pts, tets, x)
    inside = np.all((bary >= -TOL) & (bary <= 1 + TOL), axis=2)    # VTK's acceptance
    clearly = np.all(bary > 1e-6, axis=2)                            # strictly inside one cell
    found = ids >= 0
    # Every found cell contains its point, with that cell's barycentric weights.
    assert inside[found, ids[found]].all()
    np.testing.assert_allclose(w[found], bary[found, ids[found]], atol=1e-12)
    np.testing.assert_allclose(pc[found], bary[found, ids[found]][:, 1:], atol=1e-12)
    # A point strictly inside a cell is found; where only one cell accepts it, in that cell
    # (near a face a neighbour accepts it too, within VTK's tolerance, and the first in the
    # leaf's order answers, as in VTK's locators; outside the mesh, only cells whose box holds
    # the point are asked, as in VTK's).
    assert found[clearly.any(axis=1)].all()
    one = (inside.sum(axis=1) == 1) & np.all((x >= 0) & (x <= 1), axis=1)
    np.testing.assert_array_equal(ids[one], inside[one].argmax(axis=1))
    # Outside every cell's tolerance: -1 with zero weights.
    none = ~inside.any(axis=1)
    assert (ids[none] == -1).all() and not w[none].any()
    assert none.sum() > 100 and one.sum() > 1000


def test_locate_parallelepipeds_matches_affine_inverse():
    m = [[1.0, 0.3, 0.0], [0.0, 0.8, 0.2], [0.1, 0.0, 1.2]]
    pts, hexes, mat = hex_grid(5, matrix=m, shift=(2.0, -1.0, 0.5))
    loc = locator(pts, hexes, VTK_HEXAHEDRON)
    rng = np.random.default_rng(2)
    u = rng.uniform(-0.05, 1.05, (2000, 3))                     # reference coordinates
    x = u @ mat.T + np.array([2.0, -1.0, 0.5])
    ids, pc, w = loc.find_cells(x, pcoords=True, weights=True)
    cell = np.floor(u * 5).astype(int)
    inside = np.all((u > 1e-9) & (u < 1 - 1e-9), axis=1) & np.all(np.abs(u * 5 - np.round(u * 5)) > 1e-6, axis=1)
    expect = (cell[:, 0] * 5 + cell[:, 1]) * 5 + cell[:, 2]
    np.testing.assert_array_equal(ids[inside], expect[inside])
    r, s, t = (u[inside] * 5 - cell[inside]).T
    np.testing.assert_allclose(pc[inside], np.stack([r, s, t], axis=1), atol=1e-9)
    tri = np.stack([(1 - r) * (1 - s) * (1 - t), r * (1 - s) * (1 - t), r * s * (1 - t), (1 - r) * s * (1 - t),
                    (1 - r) * (1 - s) * t, r * (1 - s) * t, r * s * t, (1 - r) * s * t], axis=1)
    np.testing.assert_allclose(w[inside], tri, atol=1e-9)
    outside = np.any((u < -1e-6) | (u > 1 + 1e-6), axis=1)
    assert (ids[outside] == -1).all()


def test_mixed_cells_and_weights_interpolate_linear_fields():
    """Tetrahedra, hexahedra and wedges in one grid: weights reproduce a linear field exactly."""
    pts, hexes, _ = hex_grid(3)
    # Split every other hexahedron into two wedges, and some into six tetrahedra's worth of four.
    conn, types = [], []
    for c, h in enumerate(hexes):
        if c % 3 == 0:
            conn += [[h[0], h[1], h[3], h[4], h[5], h[7]], [h[1], h[2], h[3], h[5], h[6], h[7]]]
            types += [VTK_WEDGE, VTK_WEDGE]
        else:
            conn.append(list(h))
            types.append(VTK_HEXAHEDRON)
    off = np.cumsum([0] + [len(c) for c in conn]).astype(np.int64)
    flat = np.concatenate([np.asarray(c, dtype=np.int64) for c in conn])
    loc = engine.CellLocator(pts, off, flat, np.asarray(types, np.uint8))
    assert loc.max_cell_points == 8
    x = np.random.default_rng(3).uniform(0.01, 0.99, (1500, 3))
    ids, _, w = loc.find_cells(x, weights=True)
    assert (ids >= 0).all()
    field = pts @ np.array([1.0, -2.0, 0.5]) + 3.0
    values = np.array([field[flat[off[c]:off[c + 1]]] @ w[i, :off[c + 1] - off[c]] for i, c in enumerate(ids)])
    np.testing.assert_allclose(values, x @ np.array([1.0, -2.0, 0.5]) + 3.0, atol=1e-9)
    # The unused weight columns of wedges are zero.
    wedge = np.asarray(types)[ids] == VTK_WEDGE
    assert not w[wedge, 6:].any()


def test_unsupported_and_bad_cells_are_refused():
    pts, tets = tet_grid(1)
    off, conn, types = single_type(tets, VTK_TETRA)
    bad = types.copy()
    bad[2] = 24  # VTK_QUADRATIC_TETRA
    with pytest.raises(ValueError, match="cell 2 is a cell type 24"):
        engine.CellLocator(pts, off, conn, bad)
    conn_bad = conn.copy()
    conn_bad[5] = len(pts) + 7
    with pytest.raises(ValueError):
        engine.CellLocator(pts, off, conn_bad, types)
    with pytest.raises(ValueError, match="offsets"):
        engine.CellLocator(pts, off[:-1], conn, types)
    pts_nan = pts.copy()
    pts_nan[0, 1] = np.nan
    with pytest.raises(ValueError, match="non-finite"):
        engine.CellLocator(pts_nan, off, conn, types)
    with pytest.raises(ValueError, match="tree"):
        engine.CellLocator(pts, off, conn, types, tree="bsp")


def test_empty_locator_and_nonfinite_queries_answer_nothing():
    loc = engine.CellLocator(np.zeros((0, 3)), np.zeros(1, np.int64), np.zeros(0, np.int64), np.zeros(0, np.uint8))
    ids, _, _ = loc.find_cells(np.zeros((3, 3)))
    assert (ids == -1).all()
    cp, cid, d2 = loc.closest_points(np.zeros((1, 3)))
    assert cid[0] == -1 and np.isinf(d2[0]) and np.isnan(cp).all()
    pts, tets = tet_grid(2)
    loc = locator(pts, tets, VTK_TETRA)
    ids, _, _ = loc.find_cells(np.array([[np.nan, 0.5, 0.5], [np.inf, 0, 0]]))
    assert (ids == -1).all()
    t, hid, _ = loc.first_hits(np.array([[np.nan, 0, 0]]), np.ones((1, 3)))
    assert hid[0] == -1 and np.isinf(t[0])


# ---- segments, closest points, bounds --------------------------------------------------------

def test_first_and_all_hits_on_a_surface_match_brute_force():
    pts, tris = sphere_surface()
    loc = locator(pts, tris, VTK_TRIANGLE)
    rng = np.random.default_rng(4)
    p1 = rng.uniform(-2, 2, (400, 3))
    p2 = rng.uniform(-2, 2, (400, 3))
    t, ids, x = loc.first_hits(p1, p2)
    a, b, c = (pts[tris[:, k]] for k in range(3))
    tb = ray_triangles(p1, p2 - p1, a, b, c)
    tb[tb > 1] = np.inf
    best = tb.min(axis=1)
    hit = np.isfinite(best)
    np.testing.assert_array_equal(ids >= 0, hit)
    np.testing.assert_allclose(t[hit], best[hit], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(x[hit], p1[hit] + (p2 - p1)[hit] * best[hit, None], atol=1e-9)
    assert np.isnan(x[~hit]).all() and (ids[~hit] == -1).all()
    # all hits: every crossed triangle once, sorted by t (rays across a shared edge may count a
    # triangle the brute force rounds out, so compare the counts away from edges)
    off, ta, ia, xa = loc.all_hits(p1, p2)
    counts = np.diff(off)
    expect = np.isfinite(tb).sum(axis=1)
    assert (np.abs(counts - expect) <= 1).all() and (counts == expect).mean() > 0.98
    for i in range(len(p1)):
        seg = ta[off[i]:off[i + 1]]
        assert (np.diff(seg) >= 0).all()
        if counts[i]:
            assert seg[0] == t[i] and ia[off[i]] == ids[i]


def test_segments_through_tetrahedra_hit_the_first_boundary_face():
    pts, tets = tet_grid(3)
    loc = locator(pts, tets, VTK_TETRA)
    # From outside the unit cube straight in: the first hit is the cube's face.
    p1 = np.array([[-1.0, 0.3, 0.4], [0.25, 2.0, 0.6], [0.5, 0.5, -3.0]])
    p2 = np.array([[2.0, 0.3, 0.4], [0.25, -1.0, 0.6], [0.5, 0.5, 3.0]])
    t, ids, x = loc.first_hits(p1, p2)
    np.testing.assert_allclose(x, [[0.0, 0.3, 0.4], [0.25, 1.0, 0.6], [0.5, 0.5, 0.0]], atol=1e-12)
    bary = tet_barycentrics(pts, tets, x)
    assert np.all(np.abs(bary[np.arange(3), ids]).min(axis=1) < 1e-9)  # on a face of the hit cell
    assert np.all(bary[np.arange(3), ids] > -1e-9)


def test_closest_points_match_brute_force():
    pts, tris = sphere_surface(center=(0.5, 0.2, -0.1))
    loc = locator(pts, tris, VTK_TRIANGLE)
    x = np.random.default_rng(5).normal(size=(500, 3)) * 1.5
    cp, ids, d2 = loc.closest_points(x)
    a, b, c = (pts[tris[:, k]] for k in range(3))
    allcp = closest_on_triangles(x, a, b, c)
    alld2 = ((allcp - x[:, None, :]) ** 2).sum(-1)
    np.testing.assert_allclose(d2, alld2.min(axis=1), rtol=1e-9, atol=1e-14)
    np.testing.assert_allclose(((cp - x) ** 2).sum(1), d2, rtol=1e-9, atol=1e-14)
    np.testing.assert_allclose(alld2[np.arange(len(x)), ids], d2, rtol=1e-9, atol=1e-14)
    # within a radius: nothing farther
    cpr, idr, d2r = loc.closest_points(x, radius=0.3)
    near = d2 <= 0.09
    np.testing.assert_array_equal(idr[near], ids[near])
    assert (idr[~near] == -1).all() and np.isinf(d2r[~near]).all()


def test_closest_points_in_and_around_a_volume_mesh():
    pts, tets = tet_grid(3)
    loc = locator(pts, tets, VTK_TETRA)
    x = np.array([[0.3, 0.4, 0.5], [1.5, 0.5, 0.5], [-1.0, -1.0, 0.5], [0.5, 2.0, 3.0]])
    cp, ids, d2 = loc.closest_points(x)
    expect = np.clip(x, 0, 1)  # the closest point of the unit cube
    np.testing.assert_allclose(cp, expect, atol=1e-12)
    np.testing.assert_allclose(d2, ((x - expect) ** 2).sum(1), atol=1e-12)
    assert ids[0] >= 0 and np.all(tet_barycentrics(pts, tets, x[:1])[0, ids[0]] >= -TOL)


def test_cells_within_bounds_and_along_a_line_match_brute_force():
    pts, tets = tet_grid(5, jitter=0.2)
    loc = locator(pts, tets, VTK_TETRA)
    lo, hi = pts[tets].min(axis=1), pts[tets].max(axis=1)
    box = (0.2, 0.45, 0.1, 0.3, 0.6, 0.9)
    got = loc.cells_within_bounds(box)
    b = np.array(box)
    expect = np.flatnonzero(np.all((lo <= b[1::2]) & (hi >= b[0::2]), axis=1))
    np.testing.assert_array_equal(got, expect)
    p1, p2 = np.array([-0.2, 0.13, 0.37]), np.array([1.3, 0.71, 0.52])
    got = loc.cells_along_segment(p1, p2)
    d = p2 - p1
    with np.errstate(divide="ignore", invalid="ignore"):
        t0, t1 = (lo - p1) / d, (hi - p1) / d
    tin = np.maximum(np.minimum(t0, t1).max(axis=1), 0)
    tout = np.minimum(np.maximum(t0, t1).min(axis=1), 1)
    np.testing.assert_array_equal(got, np.flatnonzero(tin <= tout))


# ---- surfaces: rays and renders --------------------------------------------------------------

@pytest.mark.parametrize("tree", ["octree", "kdtree", "sah"])
def test_surface_rays_match_brute_force(tree):
    pts, tris = sphere_surface(40, 30)
    st = surface_tree(pts, tris, engine.SahTree) if tree == "sah" else surface_tree(pts, tris, tree=tree)
    rng = np.random.default_rng(6)
    o = rng.uniform(-3, 3, (500, 3))
    d = rng.normal(size=(500, 3))
    t, cells, visits, tests = st.intersect(o, d)
    a, b, c = (pts[tris[:, k]] for k in range(3))
    tb = ray_triangles(o, d, a, b, c)
    hit = np.isfinite(tb.min(axis=1))
    np.testing.assert_array_equal(cells >= 0, hit)
    np.testing.assert_allclose(t[hit], tb.min(axis=1)[hit], rtol=1e-9)
    np.testing.assert_array_equal(cells[hit], tb.argmin(axis=1)[hit])
    assert visits > 0 and 0 < tests < len(o) * len(tris)


def test_render_matrix_tree_and_sah_see_the_same_picture():
    pts, tris = sphere_surface(48, 32)
    cam = dict(width=64, height=48, eye=[0.5, 0.8, 4.0], target=[0, 0, 0], up=[0, 1, 0], view_angle=35.0)
    mt = surface_tree(pts, tris).render(**cam, counters=True)
    sah = surface_tree(pts, tris, engine.SahTree).render(**cam, counters=True)
    assert mt["rgb"].shape == (48, 64, 3) and mt["rgb"].dtype == np.uint8
    np.testing.assert_array_equal(mt["cell"], sah["cell"])
    np.testing.assert_array_equal(mt["depth"], sah["depth"])
    np.testing.assert_array_equal(mt["rgb"], sah["rgb"])
    hits = mt["cell"] >= 0
    assert mt["hits"] == hits.sum() > 0.2 * hits.size and not hits.all()
    # Distance to the unit sphere from the eye, along the pixel's ray: |e + t d| = 1.
    assert np.isfinite(mt["depth"][hits]).all() and np.isinf(mt["depth"][~hits]).all()
    assert mt["total_node_visits"] == mt["node_visits"].sum()


def test_surface_of_polygons_and_strips_keeps_cell_ids():
    # A quad (cell 4 after 4 verts/lines), then a strip of 3 triangles (cell 5).
    pts = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0],
                    [0, 0, 1], [1, 0, 1], [0, 1, 1], [1, 1, 1], [0, 2, 1]], float)
    st = engine.SurfaceTree(pts, np.array([0, 4]), np.array([0, 1, 2, 3]), np.array([0, 5]),
                            np.array([4, 5, 6, 7, 8]), 4)
    np.testing.assert_array_equal(st.cell_of_triangle, [4, 4, 5, 5, 5])
    t, cells, _, _ = st.intersect(np.array([[0.5, 0.5, 2.0], [0.6, 0.4, -1.0], [0.2, 1.7, 2.0]]),
                                  np.array([[0, 0, -1.0], [0, 0, 1.0], [0, 0, -1.0]]))
    np.testing.assert_array_equal(cells, [5, 4, 5])
    np.testing.assert_allclose(t, [1.0, 1.0, 1.0])
    with pytest.raises(ValueError, match="point 9"):
        engine.SurfaceTree(pts, np.array([0, 3]), np.array([0, 1, 9]), np.zeros(0, np.int64),
                           np.zeros(0, np.int64))


def test_tree_nodes_count_the_cells_below_them():
    pts, tets = tet_grid(4)
    loc = locator(pts, tets, VTK_TETRA)
    st = loc.stats()
    h = st["height"]
    nodes = loc.nodes()
    level = nodes["level"]
    assert sorted(set(level)) == list(range(h + 1))
    assert nodes["count"][level == 0].tolist() == [len(tets)]
    leaves = level == h
    assert nodes["count"][leaves].sum() == st["references"] and leaves.sum() == st["leaves"]
    assert (nodes["occupancy"][leaves] == 1).all() and (nodes["occupancy"] > 0).all()
    # every cell's centroid lies in a leaf box that counts it... as a box of its level
    cen = pts[tets].mean(axis=1)
    inside = np.all((cen[:, None, :] >= nodes["lo"][leaves][None]) & (cen[:, None, :] <= nodes["hi"][leaves][None]),
                    axis=2)
    assert inside.any(axis=1).all()
    only = loc.nodes(h, h)
    assert (only["level"] == h).all() and len(only["level"]) == leaves.sum()


# ---- volumes ---------------------------------------------------------------------------------

def uniform_table(alpha, n=256):
    t = np.ones((n, 4), np.float32)
    t[:, 3] = alpha
    return t


def test_volume_render_of_a_uniform_slab_is_beer_lambert():
    """Parallel rays through a uniform 10-unit-thick slab: 1 - (1 - a)^(10 / unit)."""
    vals = np.ones(11 ** 3, np.float32)
    vol = engine.Volume(vals, [11, 11, 11], uniform_table(0.2), 0.0, 2.0, unit_distance=1.0)
    img, st = vol.render(32, 32, position=[5, 5, 50], focal_point=[5, 5, 5], view_up=[0, 1, 0], parallel=True,
                         parallel_scale=2.0, origin=[0, 0, 0], spacing=[1, 1, 1], sample_distance=0.05,
                         early_termination=1.0)
    assert img.shape == (32, 32, 4) and img.dtype == np.float32
    expect = 1 - 0.8 ** 10
    np.testing.assert_allclose(img[..., 3], expect, rtol=0.01)
    np.testing.assert_allclose(img[..., 0], img[..., 3], rtol=1e-5)   # white, premultiplied
    assert st["samples"] > 0


def test_volume_sparse_dense_and_skipping_agree():
    x, y, z = np.mgrid[-1:1:33j, -1:1:33j, -1:1:33j]
    ball = np.clip(1 - np.sqrt(x ** 2 + y ** 2 + z ** 2), 0, None).astype(np.float32)
    flat = np.ascontiguousarray(ball.transpose(2, 1, 0)).ravel()   # x fastest
    table = uniform_table(0.0)
    table[:, 3] = np.linspace(0, 0.5, 256) ** 2
    cam = dict(position=[40, 30, 70], focal_point=[16, 16, 16], view_up=[0, 1, 0], origin=[0, 0, 0],
               spacing=[1, 1, 1], sample_distance=0.5)
    images = []
    for sparse in (True, False):
        vol = engine.Volume(flat, [33, 33, 33], table, 0.0, 1.0, sparse=sparse)
        for skipping in (True, False):
            images.append(vol.render(40, 30, empty_space_skipping=skipping, **cam)[0])
        if sparse:
            s = vol.stats()
            assert s["blocks_allocated"] < s["blocks_dense"]
    for im in images[1:]:
        np.testing.assert_array_equal(im, images[0])
    assert images[0][..., 3].max() > 0.1 and images[0][0, 0, 3] == 0


def test_volume_refuses_bad_input():
    with pytest.raises(ValueError, match="nx \\* ny \\* nz"):
        engine.Volume(np.zeros(10, np.float32), [2, 2, 2], uniform_table(0.1), 0, 1)
    with pytest.raises(ValueError, match="numeric"):
        engine.Volume(np.zeros(8, np.complex64), [2, 2, 2], uniform_table(0.1), 0, 1)
    vol = engine.Volume(np.arange(8, dtype=np.uint8), [2, 2, 2], uniform_table(0.1), 0, 7)
    with pytest.raises(ValueError):
        vol.render(8, 8, position=[0, 0, 5], focal_point=[0, 0, 0], view_up=[0, 1, 0], origin=[0, 0, 0],
                   spacing=[0, 1, 1], sample_distance=0.5)

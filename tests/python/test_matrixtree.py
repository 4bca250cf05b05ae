"""Tests of the matrixtree package on real data, against brute force and analytic answers."""

import math
import os

import numpy as np
import pytest

import matrixtree
from matrixtree import scenes

DATA = scenes.data_dir()
BUNNY = os.path.join(DATA, "meshes", "bunny.ply")
HAND = os.path.join(DATA, "scenes", "utah_hand", "hand_00.obj")


def triangles(mesh):
    from vtkmodules.util.numpy_support import vtk_to_numpy

    pts = vtk_to_numpy(mesh.GetPoints().GetData()).astype(np.float64)
    conn = vtk_to_numpy(mesh.GetPolys().GetConnectivityArray()).reshape(-1, 3)
    return pts[conn]  # (T, 3, 3)


def brute_force_first_hit(tris, o, d):
    """Möller–Trumbore over all triangles, vectorised over triangles, one ray at a time."""
    a, b, c = tris[:, 0], tris[:, 1], tris[:, 2]
    e1, e2 = b - a, c - a
    out_t = np.full(len(o), np.inf)
    out_id = np.full(len(o), -1)
    for r in range(len(o)):
        p = np.cross(d[r], e2)
        det = np.einsum("ij,ij->i", e1, p)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / det
            s = o[r] - a
            u = np.einsum("ij,ij->i", s, p) * inv
            q = np.cross(s, e1)
            v = (q @ d[r]) * inv
            t = np.einsum("ij,ij->i", e2, q) * inv
        ok = (det != 0) & (u >= 0) & (u <= 1) & (v >= 0) & (u + v <= 1) & (t >= 0)
        if ok.any():
            ids = np.nonzero(ok)[0]
            k = ids[np.argmin(t[ids])]
            out_t[r], out_id[r] = t[k], k
    return out_t, out_id


def seeded_rays(mesh, n, seed):
    b = np.array(mesh.GetBounds()).reshape(3, 2)
    lo, hi = b[:, 0], b[:, 1]
    rng = np.random.default_rng(seed)
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    o = (lo + hi) / 2 + u * np.linalg.norm(hi - lo)
    return o, lo + rng.random((n, 3)) * (hi - lo) - o


@pytest.mark.parametrize("path", [BUNNY, HAND])
@pytest.mark.parametrize("kind", ["octree", "kdtree"])
def test_first_hits_equal_brute_force(path, kind):
    mesh = matrixtree.read_mesh(path)
    tree = matrixtree.MatrixTree(mesh, tree=kind)
    o, d = seeded_rays(mesh, 300, seed=3)
    t, cell = tree.intersect(o, d)
    bt, bid = brute_force_first_hit(triangles(mesh), o, d)
    assert np.array_equal(np.isfinite(t), np.isfinite(bt))
    hit = np.isfinite(bt)
    assert hit.sum() > 100  # the rays were aimed into the box: most must hit
    same = (cell[hit] == bid[hit]) | (np.abs(t[hit] - bt[hit]) <= 1e-9 * np.maximum(1, np.abs(bt[hit])))
    assert same.all()
    assert tree.last_query_counters["triangle_tests"] > 0


def test_find_leaves_point_lies_in_its_node():
    mesh = matrixtree.read_mesh(BUNNY)
    tree = matrixtree.MatrixTree(mesh)
    s = tree.stats()
    b = np.array(mesh.GetBounds()).reshape(3, 2)
    rng = np.random.default_rng(1)
    p = b[:, 0] + rng.random((20000, 3)) * (b[:, 1] - b[:, 0])
    res = tree.find_leaves(p)
    assert res.shape == (20000, 5)
    assert (res[:, 0] >= 1).all() and (res[:, 0] <= s["height"]).all()
    assert res[:, 4].any() and not res[:, 4].all()
    # Every point lies in the node returned for it, whatever its level.
    root = np.array(s["root_bounds"]).reshape(3, 2)
    dims = np.array(s["level_dims"])[res[:, 0]]  # nodes per axis at each point's level
    cell = (root[:, 1] - root[:, 0]) / dims
    lo = root[:, 0] + res[:, 1:4] * cell
    assert ((p >= lo - 1e-12) & (p <= lo + cell + 1e-12)).all()
    # Existing leaves are bottom-level nodes.
    assert (res[res[:, 4] == 1, 0] == s["height"]).all()
    outside = tree.find_leaves(b[:, 1] + 1.0)
    assert outside[0, 0] == -1


def test_rebuild_only_when_mesh_changes():
    from vtkmodules.util.numpy_support import numpy_to_vtk, vtk_to_numpy

    mesh = scenes.default_scene(resolution=0.25)
    first = matrixtree.render(mesh, size=(32, 32))
    again = matrixtree.render(mesh, size=(32, 32), caster=first["caster"])
    assert first["rebuilt"] and not again["rebuilt"]
    pts = vtk_to_numpy(mesh.GetPoints().GetData()).astype(np.float64) * 1.01
    mesh.GetPoints().SetData(numpy_to_vtk(pts, deep=True))
    moved = matrixtree.render(mesh, size=(32, 32), caster=first["caster"])
    assert moved["rebuilt"]


def test_render_sphere_matches_analytic_disc():
    from vtkmodules.vtkFiltersSources import vtkSphereSource

    s = vtkSphereSource()
    s.SetRadius(1.0)
    s.SetThetaResolution(256)
    s.SetPhiResolution(256)
    s.Update()
    dist, fov, w = 6.0, 30.0, 200
    img = matrixtree.render(s.GetOutput(), size=(w, w), camera=[(0, 0, dist), (0, 0, 0), (0, 1, 0), fov],
                            counters=True)
    hit = np.isfinite(img["depth"])
    # Projected disc: the sphere subtends a cone of half-angle asin(r / dist).
    half = math.tan(math.asin(1.0 / dist)) / math.tan(math.radians(fov / 2)) * w / 2
    assert abs(hit.sum() / (math.pi * half**2) - 1) < 0.02
    # Centre pixel: t = dist - r, to the tessellation's accuracy.
    assert abs(img["depth"][w // 2, w // 2] - (dist - 1.0)) < 2e-3
    assert (img["node_visits"][hit] > 0).all()


def test_bad_input_errors():
    mesh = matrixtree.read_mesh(HAND)
    with pytest.raises(ValueError, match="tree must be one of"):
        matrixtree.MatrixTree(mesh, tree="bvh")
    with pytest.raises(ValueError, match="block_size"):
        matrixtree.MatrixTree(mesh, block_size=3)
    tree = matrixtree.MatrixTree(mesh)
    with pytest.raises(ValueError, match=r"shape \(N, 3\)"):
        tree.intersect(np.zeros((4, 2)), np.zeros((4, 2)))
    with pytest.raises(FileNotFoundError):
        matrixtree.read_mesh("/nonexistent/mesh.ply")
    # NaN coordinates: a clear error, not a crash.
    from vtkmodules.util.numpy_support import numpy_to_vtk, vtk_to_numpy

    bad = matrixtree.read_mesh(HAND)
    pts = vtk_to_numpy(bad.GetPoints().GetData()).astype(np.float64)
    pts[5, 1] = np.nan
    bad.GetPoints().SetData(numpy_to_vtk(pts, deep=True))
    with pytest.raises(RuntimeError, match="non-finite"):
        matrixtree.MatrixTree(bad)
    # NaN rays miss instead of hanging.
    t, c = tree.intersect([[np.nan, 0, 0]], [[1, 0, 0]])
    assert np.isinf(t[0]) and c[0] == -1


def test_empty_mesh_misses_everything():
    from vtkmodules.vtkCommonDataModel import vtkPolyData
    from vtkmodules.vtkCommonCore import vtkPoints

    pd = vtkPolyData()
    pd.SetPoints(vtkPoints())
    tree = matrixtree.MatrixTree(pd)
    t, c = tree.intersect([[0, 0, 0]], [[1, 0, 0]])
    assert np.isinf(t[0]) and c[0] == -1
    assert tree.find_leaves([[0, 0, 0]])[0, 0] == -1


# ---------------------------------------------------------------------------------------------
# The SAH kd-tree baseline through the same ray caster, and time_frames
# ---------------------------------------------------------------------------------------------
def _same_hits(a, b):
    """Pixels where two renders see a different first hit: a different depth beyond round-off
    (a different triangle at the same depth is an edge tie, not an error)."""
    da, db = a["depth"].astype(np.float64), b["depth"].astype(np.float64)
    both_inf = np.isinf(da) & np.isinf(db)
    fin = np.isfinite(da) & np.isfinite(db)
    close = np.zeros_like(fin)
    close[fin] = np.abs(da[fin] - db[fin]) <= 1e-5 * np.maximum(1.0, np.abs(db[fin]))
    return int(np.sum(~(both_inf | close)))


@pytest.mark.parametrize("traversal", ["stack", "shortstack", "restart"])
def test_sah_baseline_sees_what_the_matrix_tree_sees(traversal):
    bunny = matrixtree.read_mesh(os.path.join(scenes.data_dir(), "meshes", "bunny.ply"))
    ref = matrixtree.render(bunny, size=(96, 80), tree="octree")
    for test in ("moller-trumbore", "watertight"):
        sah = matrixtree.render(bunny, size=(96, 80), tree="sah", traversal=traversal, triangle_test=test,
                                counters=True)
        assert _same_hits(sah, ref) == 0
        assert sah["hits"] == ref["hits"] > 1000
        # same shading wherever the hits agree (shadow rays included): at most a pixel or two
        # differs by a shadow ray grazing an edge
        assert np.sum(np.any(sah["rgb"] != ref["rgb"], axis=2)) <= 3
        assert sah["triangle_tests_per_ray"] > 0 and sah["node_visits_per_ray"] > 0


def test_sah_caster_rebuilds_only_when_points_move():
    mesh = scenes.default_scene(resolution=0.2)
    img = matrixtree.render(mesh, size=(32, 32), tree="sah")
    rc = img["caster"]
    again = matrixtree.render(mesh, size=(32, 32), tree="sah", traversal="restart", caster=rc)
    assert img["rebuilt"] and not again["rebuilt"]
    mesh.GetPoints().Modified()
    mesh.Modified()
    third = matrixtree.render(mesh, size=(32, 32), tree="sah", caster=rc)
    assert third["rebuilt"]
    with pytest.raises(ValueError, match="traversal"):
        matrixtree.render(mesh, tree="sah", traversal="queue")
    with pytest.raises(ValueError, match="CPU only"):
        matrixtree.render(mesh, tree="sah", backend="opencl")


def test_time_frames_rebuilds_every_frame_and_matches_single_renders():
    frames = [scenes.default_scene(0.2, time=t) for t in (0.0, 0.25, 0.5)]
    rows = matrixtree.time_frames(frames, methods=("octree", "sah-stack", "sah-restart"), size=(40, 30),
                                  progress=False, keep_images=True)
    assert [r["method"] for r in rows] == ["octree", "sah-stack", "sah-restart"]
    for r in rows:
        assert r["frames"] == 3 and len(r["build_ms_frames"]) == 3
        assert all(b > 0 for b in r["build_ms_frames"]), r
    # the two SAH rows share each frame's build
    assert rows[1]["build_ms_frames"] == rows[2]["build_ms_frames"]
    # first frame equals a stand-alone render of frame 0
    single = matrixtree.render(frames[0], size=(40, 30), tree="octree", leaf_scale=1.0)
    assert np.array_equal(rows[0]["first_frame"]["rgb"], single["rgb"])
    with pytest.raises(ValueError, match="connectivity"):
        matrixtree.time_frames([frames[0], scenes.default_scene(0.3)], progress=False)
    with pytest.raises(ValueError, match="unknown method"):
        matrixtree.time_frames(frames, methods=("bvh",), progress=False)


def test_tree_mesh_boxes_cover_every_triangle():
    bunny = matrixtree.read_mesh(os.path.join(scenes.data_dir(), "meshes", "bunny.ply"))
    everything = matrixtree.tree_mesh(bunny)
    h = int(everything.field_data["tree_height"][0])
    assert sorted(set(everything.cell_data["level"])) == list(range(h + 1))
    root = everything.extract_cells(np.flatnonzero(everything.cell_data["level"] == 0))
    assert root.n_cells == 1 and int(root.cell_data["cell_count"][0]) == bunny.GetNumberOfPolys()
    leaves = matrixtree.tree_mesh(bunny, levels=-1)
    assert set(leaves.cell_data["level"]) == {h} and np.all(leaves.cell_data["cell_count"] >= 1)
    # brute force: every triangle's centroid lies in (the closed box of) some leaf
    from vtkmodules.util.numpy_support import vtk_to_numpy

    pts = vtk_to_numpy(bunny.GetPoints().GetData())
    tri = vtk_to_numpy(bunny.GetPolys().GetConnectivityArray()).reshape(-1, 3)
    cent = pts[tri].mean(axis=1)
    lo = np.array([leaves.get_cell(i).bounds[0::2] for i in range(leaves.n_cells)])
    hi = np.array([leaves.get_cell(i).bounds[1::2] for i in range(leaves.n_cells)])
    sample = cent[:: max(1, len(cent) // 2000)]
    inside = np.array([np.any(np.all((c >= lo - 1e-12) & (c <= hi + 1e-12), axis=1)) for c in sample])
    assert inside.all()
    one = matrixtree.tree_mesh(bunny, tree="kdtree", levels=(1, 2))
    assert set(one.cell_data["level"]) <= {1, 2} and one.n_cells > 0
    with pytest.raises(ValueError, match="levels"):
        matrixtree.tree_mesh(bunny, levels=(3, 1))
    with pytest.raises(TypeError):
        matrixtree.tree_mesh(42)


# ---------------------------------------------------------------------------------------------
# The paper's other trees (§4: implicit general kd-tree, implicit BSP tree; §7: hybrid) through
# the same classes. The BSP build is slow (seconds per 10^4 triangles): it runs on the hand.
# ---------------------------------------------------------------------------------------------
OTHER_TREES = [(BUNNY, "implicit-kd"), (BUNNY, "hybrid"), (HAND, "implicit-kd"), (HAND, "bsp"), (HAND, "hybrid")]
# The engine extension (pip's VTK) builds the matrix trees only; it names the VTK module for these.
needs_vtk_module = pytest.mark.skipif(matrixtree.EXTENSION != "matrixtree_vtk",
                                      reason="the split-plane and hybrid trees need the VTK module")


@needs_vtk_module
@pytest.mark.parametrize("path, kind", OTHER_TREES)
def test_other_trees_first_hits_equal_brute_force(path, kind):
    test_first_hits_equal_brute_force(path, kind)


@needs_vtk_module
@pytest.mark.parametrize("path, kind", OTHER_TREES)
def test_other_trees_render_what_the_octree_renders(path, kind):
    mesh = matrixtree.read_mesh(path)
    ref = matrixtree.render(mesh, size=(96, 80), tree="octree")
    img = matrixtree.render(mesh, size=(96, 80), tree=kind, counters=True)
    assert _same_hits(img, ref) == 0
    assert img["hits"] == ref["hits"] > 1000
    assert np.sum(np.any(img["rgb"] != ref["rgb"], axis=2)) <= 3
    assert img["node_visits_per_ray"] > 0 and img["triangle_tests_per_ray"] > 0
    assert img["caster"].GetTree().GetTreeTypeAsString() == kind


@needs_vtk_module
@pytest.mark.parametrize("kind", ["implicit-kd", "bsp", "hybrid"])
def test_other_trees_stats_and_find_leaves(kind):
    mesh = matrixtree.read_mesh(HAND)
    tree = matrixtree.MatrixTree(mesh, tree=kind)
    s = tree.stats()
    assert s["tree"] == kind and s["triangles"] == 15855
    assert s["nodes"] > s["leaves"] > 0 and s["references"] >= s["triangles"]
    assert s["bytes"] > 4 * s["references"]
    assert len(s["level_bytes"]) == s["height"] + 1 and sum(s["level_bytes"]) < s["bytes"]
    if kind == "hybrid":
        assert "pointer_tree_bytes" not in s
        assert list(s["phases_ms"])[-1] == "leaf kd-trees"
    else:
        # the same tree with 8-byte pointer nodes and the same 4-byte triangle indices
        assert s["pointer_tree_bytes"] >= 8 * s["nodes"] + 4 * s["triangles"]
    # A point of a triangle lies in an existing leaf; a point outside the root box in none.
    rng = np.random.default_rng(7)
    tris = triangles(tree.mesh)
    pick = tris[rng.integers(0, len(tris), 3000)]
    uv = rng.random((3000, 2))
    uv[uv.sum(axis=1) > 1] = 1 - uv[uv.sum(axis=1) > 1]
    p = pick[:, 0] + uv[:, :1] * (pick[:, 1] - pick[:, 0]) + uv[:, 1:] * (pick[:, 2] - pick[:, 0])
    res = tree.find_leaves(p)
    assert (res[:, 4] == 1).all() and (res[:, 0] >= 0).all() and (res[:, 0] <= s["height"]).all()
    root = np.array(s["root_bounds"]).reshape(3, 2)
    assert tree.find_leaves(root[:, 1] + 1.0)[0, 0] == -1


@pytest.mark.skipif(matrixtree.EXTENSION == "matrixtree_vtk", reason="the engine extension's answer")
@pytest.mark.parametrize("kind", ["implicit-kd", "bsp", "hybrid"])
def test_engine_extension_names_the_vtk_module_for_other_trees(kind):
    mesh = matrixtree.read_mesh(HAND)
    for call in (lambda: matrixtree.MatrixTree(mesh, tree=kind), lambda: matrixtree.render(mesh, tree=kind),
                 lambda: matrixtree.tree_mesh(mesh, tree=kind)):
        with pytest.raises(ValueError, match="needs the VTK module"):
            call()


@needs_vtk_module
def test_other_trees_bad_settings():
    mesh = matrixtree.read_mesh(HAND)
    with pytest.raises(ValueError, match="no OpenCL walk"):
        matrixtree.MatrixTree(mesh, tree="hybrid", backend="opencl")
    with pytest.raises(ValueError, match="CPU only"):
        matrixtree.render(mesh, tree="hybrid", backend="opencl")
    with pytest.raises(ValueError, match="tree must be one of"):
        matrixtree.render(mesh, tree="bvh")
    with pytest.raises(ValueError, match="levels=-1"):
        matrixtree.tree_mesh(mesh, tree="implicit-kd", levels=-1)


@needs_vtk_module
def test_tree_mesh_draws_split_planes_in_their_cells():
    mesh = matrixtree.read_mesh(HAND)
    root = np.array(matrixtree.MatrixTree(mesh, tree="implicit-kd").stats()["root_bounds"]).reshape(3, 2)
    pad = 1e-9 * np.linalg.norm(root[:, 1] - root[:, 0])
    for kind, directions in (("implicit-kd", {0, 1, 2}), ("bsp", set(range(13)))):
        planes = matrixtree.tree_mesh(mesh, tree=kind, levels=(0, 5))
        level = np.asarray(planes.cell_data["level"])
        assert set(level) == set(range(6)) and np.sum(level == 0) == 1  # one root plane
        assert np.all(np.bincount(level) <= 2 ** np.arange(6))  # at most 2^l nodes at level l
        d = set(int(v) for v in planes.cell_data["direction"])
        assert d <= directions and len(d) > 1
        pts = np.asarray(planes.points)
        assert np.all((pts >= root[:, 0] - pad) & (pts <= root[:, 1] + pad))
    bsp = matrixtree.tree_mesh(mesh, tree="bsp", levels=(0, 8))
    assert np.any(np.asarray(bsp.cell_data["direction"]) > 2)  # planes off the axes
    hybrid = matrixtree.tree_mesh(mesh, tree="hybrid")
    h = int(hybrid.field_data["tree_height"][0])
    boxes = np.asarray(hybrid.cell_data["direction"]) == -1
    level = np.asarray(hybrid.cell_data["level"])
    assert boxes.any() and (~boxes).any()
    assert set(level[boxes]) == set(range(h + 1)) and np.all(level[~boxes] >= h)
    leaves = matrixtree.tree_mesh(mesh, tree="hybrid", levels=-1)
    assert set(leaves.cell_data["level"]) == {h} and set(leaves.cell_data["direction"]) == {-1}
    assert leaves.n_cells == np.sum(boxes & (level == h))

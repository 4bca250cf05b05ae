"""The package's two paths give the same answers: the VTK module's (``matrixtree.CellLocator``,
``MatrixTree``, ``render``, ``tree_mesh``, ``render_volume`` in the project's .venv) and the
engine extension's (``matrixtree._engine``: what the same names are in pip's environment).

Runs where both are built (the .venv); skipped elsewhere. Where the engine decides a point the
VTK arithmetic leaves uncertain (within ~1e-9 of a cell's acceptance limit) it may pick the
neighbour: such points are compared by containment, as in test_engine_vs_vtk.py.
"""

from __future__ import annotations

import os

import numpy as np
import pytest

pytest.importorskip("matrixtree_vtk")

import pyvista as pv  # noqa: E402

import matrixtree  # noqa: E402
from matrixtree import _engine  # noqa: E402

DATA = matrixtree.scenes.data_dir()


def need(path):
    if not os.path.exists(path):
        pytest.skip(f"{path} not found (shared data)")
    return path


def test_the_vtk_module_answers_in_this_environment():
    assert matrixtree.EXTENSION == "matrixtree_vtk"
    assert matrixtree.CellLocator is not _engine.CellLocator and matrixtree.render is not _engine.render


@pytest.fixture(scope="module")
def pipe():
    return pv.wrap(matrixtree.read_grid(need(os.path.join(DATA, "cfd", "pipe_flow_tets.vtu"))))


@pytest.fixture(scope="module")
def bunny():
    return pv.wrap(matrixtree.read_mesh(need(os.path.join(DATA, "meshes", "bunny.ply"))))


def random_points(ds, n, seed, grow=0.05):
    b = np.array(ds.bounds).reshape(3, 2)
    pad = grow * (b[:, 1] - b[:, 0])
    return np.random.default_rng(seed).uniform(b[:, 0] - pad, b[:, 1] + pad, (n, 3))


def test_cell_locator_queries_agree(pipe):
    vtk_loc, eng_loc = matrixtree.CellLocator(pipe), _engine.CellLocator(pipe)
    x = random_points(pipe, 20000, seed=1)
    ids, w = vtk_loc.locate(x, return_weights=True)
    eids, ew = eng_loc.locate(x, return_weights=True)
    same = ids == eids
    assert same.mean() > 0.9995 and (ids >= 0).sum() > 5000
    assert ((ids >= 0) == (eids >= 0)).all()
    np.testing.assert_allclose(ew[same], w[same][:, :ew.shape[1]], atol=1e-9)
    p1, p2 = random_points(pipe, 300, seed=2, grow=0.3), random_points(pipe, 300, seed=3, grow=0.3)
    t, tid, tx = vtk_loc.trace(p1, ends=p2)
    et, etid, etx = eng_loc.trace(p1, ends=p2)
    np.testing.assert_array_equal(tid >= 0, etid >= 0)
    np.testing.assert_allclose(et[tid >= 0], t[tid >= 0], atol=1e-9)
    off, at, aid, ax = vtk_loc.trace_all(p1[:100], ends=p2[:100])
    eoff, eat, eaid, eax = eng_loc.trace_all(p1[:100], ends=p2[:100])
    assert (np.abs(np.diff(off) - np.diff(eoff)) <= 1).all() and (np.diff(off) == np.diff(eoff)).mean() > 0.9
    box = list(np.array(pipe.bounds) * [1, 0.5, 1, 0.5, 1, 0.3])
    np.testing.assert_array_equal(vtk_loc.cells_within_bounds(box), eng_loc.cells_within_bounds(box))
    np.testing.assert_array_equal(vtk_loc.cells_along_line(p1[0], p2[0]), eng_loc.cells_along_line(p1[0], p2[0]))
    q = random_points(pipe, 300, seed=4, grow=0.5)
    _, _, d2 = vtk_loc.closest_points(q)
    _, _, ed2 = eng_loc.closest_points(q)
    np.testing.assert_allclose(ed2[d2 == 0], 0)


def test_surface_cell_queries_agree_on_the_bunny(bunny):
    vtk_loc, eng_loc = matrixtree.CellLocator(bunny), _engine.CellLocator(bunny)
    p1, p2 = random_points(bunny, 500, seed=5, grow=0.5), random_points(bunny, 500, seed=6, grow=0.5)
    off, t, ids, x = vtk_loc.trace_all(p1, ends=p2)
    eoff, et, eids, ex = eng_loc.trace_all(p1, ends=p2)
    np.testing.assert_array_equal(off, eoff)
    np.testing.assert_array_equal(ids, eids)
    np.testing.assert_allclose(et, t, atol=1e-9)
    np.testing.assert_allclose(ex, x, atol=1e-12)
    q = random_points(bunny, 1000, seed=7, grow=0.2)
    np.testing.assert_allclose(eng_loc.closest_points(q)[2], vtk_loc.closest_points(q)[2], rtol=1e-9, atol=1e-18)


def test_matrix_tree_and_renders_agree(bunny):
    for kind in ("octree", "kdtree"):
        a, b = matrixtree.MatrixTree(bunny, tree=kind), _engine.MatrixTree(bunny, tree=kind)
        sa, sb = a.stats(), b.stats()
        for key in ("tree", "height", "triangles", "leaves", "references", "bytes", "leaf_triangle_bytes",
                    "level_blocks", "leaf_dims", "level_dims"):
            assert sa[key] == sb[key], key
        np.testing.assert_allclose(sb["root_bounds"], sa["root_bounds"])
        o = random_points(bunny, 2000, seed=8, grow=0.3)
        d = np.random.default_rng(9).normal(size=(2000, 3))
        ta, ca = a.intersect(o, d)
        tb, cb = b.intersect(o, d)
        np.testing.assert_array_equal(ca, cb)
        np.testing.assert_array_equal(ta, tb)
        assert a.last_query_counters == b.last_query_counters
        np.testing.assert_array_equal(a.find_leaves(o), b.find_leaves(o))
    for tree, traversal in (("octree", "stack"), ("kdtree", "stack"), ("sah", "restart")):
        for camera in (None, [(0.1, 0.25, 0.45), (-0.02, 0.1, 0.0), (0.0, 1.0, 0.0), 35.0]):
            for counters in (True, False):
                kw = dict(size=(64, 48), tree=tree, traversal=traversal, camera=camera, counters=counters)
                ra, rb = matrixtree.render(bunny, **kw), _engine.render(bunny, **kw)
                for key in ("rgb", "depth") + (("node_visits", "triangle_tests") if counters else ()):
                    np.testing.assert_array_equal(ra[key], rb[key], err_msg=f"{tree} {key} camera {camera}")
                assert ra["hits"] == rb["hits"] > 100 and ra["rays"] == rb["rays"]
                assert (ra["node_visits"] is None) == (rb["node_visits"] is None) == (not counters)
                assert (rb["node_visits_per_ray"] is None) == (not counters)


def test_render_caster_rebuilds_on_the_same_changes(bunny):
    mesh = bunny.copy(deep=True)
    first = _engine.render(mesh, size=(16, 16))
    again = _engine.render(mesh, size=(16, 16), caster=first["caster"])
    assert first["rebuilt"] and not again["rebuilt"]
    mesh.points = mesh.points * 1.01
    assert _engine.render(mesh, size=(16, 16), caster=first["caster"])["rebuilt"]
    assert _engine.render(mesh, size=(16, 16), caster=first["caster"], tree="kdtree")["rebuilt"]
    with pytest.raises(TypeError, match="caster"):
        _engine.render(mesh, size=(16, 16), caster=matrixtree.render(mesh, size=(8, 8))["caster"])


def test_tree_mesh_agrees(pipe, bunny):
    for mesh, kw in ((bunny, {}), (pipe, dict(tree="kdtree", levels=(1, 3))), (pipe, dict(levels=-1))):
        a, b = matrixtree.tree_mesh(mesh, **kw), _engine.tree_mesh(mesh, **kw)
        assert a.n_cells == b.n_cells > 0
        np.testing.assert_array_equal(a.points, b.points)
        np.testing.assert_array_equal(a.cell_connectivity, b.cell_connectivity)
        for name in ("level", "occupancy", "cell_count"):
            np.testing.assert_array_equal(a.cell_data[name], b.cell_data[name])
            assert a.cell_data[name].dtype == b.cell_data[name].dtype
        assert int(a.field_data["tree_height"][0]) == int(b.field_data["tree_height"][0])


@pytest.mark.parametrize("name", ["ironProt.vtk", "headsq.mhd"])
def test_volume_renders_agree(name):
    im = matrixtree.read_volume(need(os.path.join(DATA, "volumes", name)))
    for kw in (dict(), dict(shade=True, image_sample_distance=2.0), dict(double_precision=True)):
        a, sa = matrixtree.render_volume(im, size=(72, 56), return_stats=True, **kw)
        b, sb = _engine.render_volume(im, size=(72, 56), return_stats=True, **kw)
        np.testing.assert_array_equal(a, b)
        for key in ("samples", "skips", "blocks_allocated", "blocks_dense", "bytes", "storage", "levels"):
            assert sa[key] == sb[key], key


def test_engine_path_refuses_what_it_cannot_do(bunny):
    for call in (lambda: _engine.CellLocator(bunny, backend="opencl"),
                 lambda: _engine.MatrixTree(bunny, backend="opencl"),
                 lambda: _engine.render(bunny, size=(8, 8), backend="opencl"),
                 lambda: _engine.render_volume(np.ones((4, 4, 4)), size=(8, 8), backend="opencl")):
        with pytest.raises(RuntimeError, match="needs the VTK module"):
            call()

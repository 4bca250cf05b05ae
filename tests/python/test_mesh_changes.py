"""A locator notices that its mesh changed and answers for the mesh as it is now: points moved
(through pyvista, through a plain numpy view VTK cannot see, by SetPoints), cells replaced,
Modified() called; and it does not rebuild when nothing changed.

Runs in both environments (the VTK module's and the engine extension's locators). The reference
for every answer is a locator built fresh over a copy of the changed mesh, and brute force.
"""

from __future__ import annotations

import numpy as np
import pyvista as pv
from vtkmodules.util.numpy_support import vtk_to_numpy

import matrixtree

from test_engine import closest_on_triangles


def tets(n=4):
    return pv.ImageData(dimensions=(n + 1,) * 3, spacing=(1.0 / n,) * 3).triangulate()


def fresh_answers(mesh, x):
    return matrixtree.CellLocator(mesh.copy(deep=True)).locate(x)


def test_points_moved_in_place_through_a_numpy_view_are_seen():
    grid = tets()
    loc = matrixtree.CellLocator(grid)
    x = np.random.default_rng(0).uniform(0, 1, (2000, 3))
    before = loc.locate(x)
    assert loc.locate(x) is not None and loc.builds == 1           # no change: no rebuild
    view = vtk_to_numpy(grid.GetPoints().GetData())                 # VTK cannot see writes here
    view += [2.0, 0.0, 0.0]
    after = loc.locate(x)
    assert loc.builds == 2
    assert (before >= 0).all() and (after == -1).all()              # the mesh left the points behind
    np.testing.assert_array_equal(loc.locate(x + [2.0, 0, 0]), fresh_answers(grid, x + [2.0, 0, 0]))


def test_points_set_through_pyvista_and_set_points_are_seen():
    grid = tets()
    loc = matrixtree.CellLocator(grid)
    x = np.random.default_rng(1).uniform(-0.5, 1.5, (2000, 3))
    grid.points = grid.points * 1.5 - 0.25                          # a new array through pyvista
    np.testing.assert_array_equal(loc.locate(x), fresh_answers(grid, x))
    grid.points[:, 2] *= 0.5                                        # pyvista_ndarray write: Modified()
    np.testing.assert_array_equal(loc.locate(x), fresh_answers(grid, x))
    assert loc.builds == 3
    t, cells, pts = loc.trace(x[:50], ends=x[50:100])
    rt, rcells, rpts = matrixtree.CellLocator(grid.copy(deep=True)).trace(x[:50], ends=x[50:100])
    np.testing.assert_array_equal(cells, rcells)


def test_cells_replaced_are_seen():
    surf = pv.Plane(i_resolution=4, j_resolution=4).triangulate()   # 32 triangles in z = 0
    loc = matrixtree.CellLocator(surf)
    q = np.array([[0.1, 0.1, 0.2], [-0.3, 0.2, -0.1]])
    _, ids, d2 = loc.closest_points(q)
    np.testing.assert_allclose(d2, [0.04, 0.01])
    keep = surf.regular_faces[:4]                                   # four triangles near (-0.5, -0.5)
    surf.faces = np.hstack([np.full((4, 1), 3), keep]).ravel()
    cp, ids, d2 = loc.closest_points(q)
    assert loc.builds == 2 and (ids < 4).all()
    a, b, c = (np.asarray(surf.points, dtype=np.float64)[keep[:, k]] for k in range(3))
    expect = ((closest_on_triangles(q, a, b, c) - q[:, None, :]) ** 2).sum(-1).min(axis=1)   # brute force
    np.testing.assert_allclose(d2, expect, rtol=1e-9, atol=1e-12)
    assert expect[1] > 0.02                                          # the answer did change


def test_modified_alone_rebuilds_and_nothing_else_does():
    grid = tets(2)
    loc = matrixtree.CellLocator(grid)
    x = np.full((1, 3), 0.3)
    for _ in range(3):
        loc.locate(x)
        loc.closest_points(x)
        loc.cells_within_bounds([0, 1, 0, 1, 0, 1])
    assert loc.builds == 1
    grid.Modified()
    loc.locate(x)
    assert loc.builds == 2


def test_matrix_tree_rays_follow_the_moving_mesh():
    sphere = pv.Sphere(theta_resolution=24, phi_resolution=16)
    tree = matrixtree.MatrixTree(sphere)
    o, d = np.array([[0.0, 0.0, 3.0]]), np.array([[0.0, 0.0, -1.0]])
    t0, _ = tree.intersect(o, d)
    view = vtk_to_numpy(sphere.GetPoints().GetData())
    view[:, 2] += 1.0                                                # moved up by 1, no Modified()
    t1, c1 = tree.intersect(o, d)
    np.testing.assert_allclose(t1, t0 - 1.0, atol=1e-12)
    rt, rc = matrixtree.MatrixTree(sphere.copy(deep=True)).intersect(o, d)
    np.testing.assert_array_equal(c1, rc)
    leaves = tree.find_leaves([[0.0, 0.0, 1.4]])
    assert leaves[0, 0] >= 0                                        # inside the moved tree's root box


def test_filters_follow_a_changing_mesh():
    grid = tets()
    grid.point_data["f"] = grid.points[:, 0].copy()
    loc = matrixtree.CellLocator(grid)
    x = np.array([[0.5, 0.5, 0.5], [1.5, 0.5, 0.5]])
    first = matrixtree.probe(grid, x, locator=loc)
    np.testing.assert_array_equal(first.point_data["vtkValidPointMask"], [1, 0])
    grid.points = grid.points + [1.0, 0.0, 0.0]
    second = matrixtree.probe(grid, x, locator=loc)
    np.testing.assert_array_equal(second.point_data["vtkValidPointMask"], [0, 1])
    np.testing.assert_allclose(second.point_data["f"], [0.0, 0.5], atol=1e-12)   # f moved with the points

"""Bad input at the Python boundary: every setting out of range is refused with its valid range,
a failed build makes every query raise the build's reason, coordinates outside the supported range
are refused with that range (and inside it answers scale exactly), non-finite query points get
documented answers, and nothing hangs or crashes (the crash and hang cases run in a subprocess:
see isolated.py). docs/reliability.md lists these cases with their results."""


import numpy as np
import pytest
import pyvista as pv
from vtkmodules.util.numpy_support import numpy_to_vtk
from vtkmodules.vtkCommonDataModel import vtkCellLocator, vtkImageData
from vtkmodules.vtkFiltersGeneral import vtkDataSetTriangleFilter
from vtkmodules.vtkImagingCore import vtkRTAnalyticSource

import matrixtree
from extensions import needs_vtk_module
from isolated import outcome


def tet_grid(n=4):
    """Tetrahedra of a regular n^3-cell image (double coordinates)."""
    src = vtkRTAnalyticSource()
    src.SetWholeExtent(0, n, 0, n, 0, n)
    tets = vtkDataSetTriangleFilter()
    tets.SetInputConnection(src.GetOutputPort())
    tets.Update()
    g = pv.wrap(tets.GetOutput())
    g.points = g.points.astype(np.float64)
    return g


def sphere():
    s = pv.Sphere(theta_resolution=24, phi_resolution=24)
    s.points = s.points.astype(np.float64)
    return s


# --------------------------------------------------------------------------------------------
# Settings out of range
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("kw,match", [
    (dict(height=-1), r"height must be an integer in \[0, 63\]"),
    (dict(height=2.5), r"height must be an integer"),
    (dict(leaf_scale=0), r"leaf_scale must be a finite number in \[0.001, 1000\]"),
    (dict(leaf_scale=float("nan")), r"leaf_scale"),
    (dict(threads=-1), r"threads must be an integer in \[0, 4096\]"),
])
def test_matrix_tree_settings_out_of_range_are_refused(kw, match):
    with pytest.raises(ValueError, match=match):
        matrixtree.MatrixTree(sphere(), **kw)


@pytest.mark.parametrize("kw,match", [
    (dict(height=-1), r"height must be an integer in \[0, 63\]"),
    (dict(leaf_scale=0), r"leaf_scale"),
    (dict(threads=-2), r"threads"),
    (dict(size=(0, 10)), r"width\) must be an integer in \[1, 16384\]"),
    (dict(camera=[[np.nan, 0, 3], [0, 0, 0], [0, 1, 0]]), r"camera position must be three finite numbers"),
    (dict(camera=[[0, 0, 3], [0, 0, 3], [0, 1, 0]]), r"equals the focal point"),
    (dict(camera=[[0, 0, 3], [0, 0, 0], [0, 1, 0], 0.0]), r"view angle must be a finite number in \[0.01, 179\]"),
])
def test_render_settings_out_of_range_are_refused(kw, match):
    with pytest.raises(ValueError, match=match):
        matrixtree.render(sphere(), **{"size": (8, 8), **kw})


def test_render_view_up_along_the_view_is_replaced_not_refused():
    """The engine substitutes another up vector (documented): the sphere is still seen."""
    img = matrixtree.render(sphere(), size=(16, 16), camera=[[0, 0, 3], [0, 0, 0], [0, 0, 1]])
    assert img["hits"] > 0


def test_render_size_beyond_the_limit_is_refused_up_front():
    """A size past 16384 per side is refused before any work (a silent clamp would render minutes
    at 16384^2 and give an image of the wrong shape)."""
    got = outcome("""
        import time, pyvista as pv, matrixtree
        t0 = time.perf_counter()
        try:
            matrixtree.render(pv.Sphere(), size=(100000, 100000))
            print("rendered")
        except ValueError as e:
            print(f"{time.perf_counter() - t0:.1f} s:", e)
    """, timeout=60)
    assert "must be an integer in [1, 16384], got 100000" in got and float(got.split()[0]) < 5, got


def test_render_size_beyond_available_memory_is_refused(monkeypatch):
    from matrixtree import _checks

    monkeypatch.setattr(_checks, "available_memory", lambda: 1 << 20)  # 1 MiB free
    with pytest.raises(ValueError, match=r"GiB of memory is available"):
        matrixtree.render(sphere(), size=(1000, 1000))
    with pytest.raises(ValueError, match=r"GiB of memory is available"):
        matrixtree.render_volume(np.random.default_rng(0).random((4, 4, 4)), size=(1000, 1000))


def ball(n=12):
    x, y, z = np.mgrid[-1:1:n * 1j, -1:1:n * 1j, -1:1:n * 1j]
    return (1.0 - np.sqrt(x**2 + y**2 + z**2)).clip(0)


@pytest.mark.parametrize("kw,match", [
    (dict(early_termination=-1), r"early_termination must be a finite number in \[0, 1\]"),
    (dict(early_termination=float("nan")), r"early_termination"),
    (dict(opacity_unit_distance=-1), r"opacity_unit_distance must be a finite number in \(0, inf\)"),
    (dict(opacity_unit_distance=0.0), r"opacity_unit_distance"),
    (dict(image_sample_distance=0.5), r"image_sample_distance must be a finite number in \[1, 32\]"),
    (dict(threads=-1), r"threads"),
])
def test_render_volume_settings_out_of_range_are_refused(kw, match):
    with pytest.raises(ValueError, match=match):
        matrixtree.render_volume(ball(), size=(8, 8), **kw)


def test_render_volume_degenerate_cameras_are_refused():
    cam = matrixtree.frame_camera(ball())
    cam.SetPosition(*cam.GetFocalPoint())
    with pytest.raises(ValueError, match="equals the focal point"):
        matrixtree.render_volume(ball(), size=(8, 8), camera=cam)
    cam = matrixtree.frame_camera(ball())
    d = np.subtract(cam.GetFocalPoint(), cam.GetPosition())
    cam.SetViewUp(*d)
    with pytest.raises(ValueError, match="along the view direction"):
        matrixtree.render_volume(ball(), size=(8, 8), camera=cam)


@pytest.mark.parametrize("sd,message", [
    (-1, "sample_distance must be a finite number in (0, inf) (world units), got -1.0"),
    (0.0, "sample_distance must be a finite number in (0, inf) (world units), got 0.0"),
    (1e-9, "sample_distance 1e-09 asks for 5.2e+09 samples across the volume's diagonal (5.19615); at most 2^20 per "
           "ray are supported: use sample_distance >= 4.96e-06"),
])
def test_sample_distance_out_of_range_is_refused_not_a_hang(sd, message):
    """A distance <= 0, or one asking for more than 2^20 samples per ray, is refused at once (a clamp
    to 1e-9 would render for hours)."""
    got = outcome("""
        import sys, numpy as np, matrixtree
        try:
            matrixtree.render_volume(np.random.default_rng(0).random((4, 4, 4)), size=(8, 8),
                                     sample_distance=float(sys.argv[1]))
            print("rendered")
        except ValueError as e:
            print("ValueError", e)
    """, timeout=60, args=[sd])
    assert got == "ValueError " + message, got


@needs_vtk_module
def test_vtk_volume_caster_refuses_zero_sample_distance_at_once():
    """The VTK class keeps the value it is given (no clamp to 1e-9) and its RequestData refuses it."""
    from matrixtree_vtk import vtkMatrixTreeVolumeRayCaster

    assert outcome("""
        import time, numpy as np
        from vtkmodules.util.numpy_support import numpy_to_vtk
        from vtkmodules.vtkCommonDataModel import vtkImageData
        from matrixtree_vtk import vtkMatrixTreeVolumeRayCaster
        from matrixtree._util import VtkErrors
        im = vtkImageData(); im.SetDimensions(4, 4, 4)
        im.GetPointData().SetScalars(numpy_to_vtk(np.random.default_rng(0).random(64), deep=True))
        c = vtkMatrixTreeVolumeRayCaster(); c.SetInputData(im); c.SetImageSize(8, 8); c.SetSampleDistance(0)
        with VtkErrors(c) as errors:
            c.Update()
        print(c.GetSampleDistance(), errors.last)
    """, timeout=60).startswith("0.0 SampleDistance 0 must be finite and > 0")
    c = vtkMatrixTreeVolumeRayCaster()
    c.SetSampleDistance(-1.0)
    assert c.GetSampleDistance() == -1.0


def short_scalars_image(n, count):
    im = vtkImageData()
    im.SetDimensions(n, n, n)
    im.GetPointData().SetScalars(numpy_to_vtk(np.arange(count, dtype=np.float32), deep=True))
    return im


@pytest.mark.parametrize("n", [4, 64])
def test_volume_with_fewer_scalars_than_points_is_refused(n):
    """10 scalars for 4^3 points rendered garbage, for 64^3 overflowed the heap (ASan)."""
    with pytest.raises(ValueError, match=f"10 values for {n}x{n}x{n} = {n**3} points"):
        matrixtree.render_volume(short_scalars_image(n, 10), size=(8, 8))


@needs_vtk_module
def test_vtk_volume_caster_refuses_fewer_scalars_than_points():
    assert outcome("""
        import numpy as np
        from vtkmodules.util.numpy_support import numpy_to_vtk
        from vtkmodules.vtkCommonDataModel import vtkImageData
        from matrixtree_vtk import vtkMatrixTreeVolumeRayCaster
        from matrixtree._util import VtkErrors
        im = vtkImageData(); im.SetDimensions(64, 64, 64)
        im.GetPointData().SetScalars(numpy_to_vtk(np.arange(10, dtype=np.float32), deep=True))
        c = vtkMatrixTreeVolumeRayCaster(); c.SetInputData(im); c.SetImageSize(8, 8)
        with VtkErrors(c) as errors:
            c.Update()
        print(errors.last)
    """, timeout=60).startswith("The input scalars hold 10 values for 64x64x64 = 262144 points")


# --------------------------------------------------------------------------------------------
# Failed builds
# --------------------------------------------------------------------------------------------
def test_cell_locator_build_failure_is_raised_by_the_constructor():
    g = tet_grid()
    g.points[3] = np.nan
    with pytest.raises(RuntimeError, match=r"point 3 has the coordinate nan \(non-finite"):
        matrixtree.CellLocator(g)


@needs_vtk_module
def test_every_query_of_a_failed_locator_raises_the_build_error():
    """A locator whose rebuild fails (here: a height whose leaf level needs 2^68 bytes) raises
    that reason from every query, trace and closest_points included (never empty arrays)."""
    loc = matrixtree.CellLocator(tet_grid())
    loc.vtk_locator.SetHeight(25)
    reason = r"height 25 needs a 2\^68-byte pointer matrix"
    with pytest.raises(RuntimeError, match=reason):
        loc.locate([[0.5, 0.5, 0.5]] * 3)
    with pytest.raises(RuntimeError, match=reason):
        loc.trace([[0.5, 0.5, 0.5]] * 3, [[1, 0, 0]] * 3)
    with pytest.raises(RuntimeError, match=reason):
        loc.closest_points([[0.5, 0.5, 0.5]] * 3)


@needs_vtk_module
def test_every_query_of_a_failed_matrix_tree_raises_the_build_error():
    with pytest.raises(RuntimeError, match=r"height 25 needs a 2\^68-byte pointer matrix.*lower the height"):
        matrixtree.MatrixTree(sphere(), height=25)
    tree = matrixtree.MatrixTree(sphere())
    tree.vtk_tree.SetHeight(25)
    reason = r"height 25 needs a 2\^68-byte pointer matrix"
    with pytest.raises(RuntimeError, match=reason):
        tree.build()
    with pytest.raises(RuntimeError, match=reason):
        tree.intersect([[0, 0, 3]], [[0, 0, -1]])
    with pytest.raises(RuntimeError, match=reason):
        tree.find_leaves([[0, 0, 0]])


# --------------------------------------------------------------------------------------------
# Coordinates and query points
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("scale,reason", [(s, r"beyond the supported range \[-1e30, 1e30\]") for s in (1e39, 1e100, 1e120, 1e300)]
                         + [(s, r"the points span only .* at least 1e-30 is supported") for s in (1e-160, 1e-200, 1e-300)])
def test_coordinates_out_of_range_are_refused_with_the_real_reason(scale, reason):
    """Coordinates beyond 1e30, or a point set spanning less than 1e-30, are refused with the
    supported range, not as "non-finite" and not answered (rays at 1e100-1e120 would return t = inf
    and wrong cells; below 1e-30 across rays would miss everything and closest points go wrong)."""
    g = tet_grid()
    g.points = g.points * scale
    with pytest.raises(RuntimeError, match=reason):
        matrixtree.CellLocator(g)
    s = sphere()
    s.points = s.points * scale
    with pytest.raises(RuntimeError, match=reason):
        matrixtree.MatrixTree(s)
    with pytest.raises(RuntimeError, match=reason):
        matrixtree.render(s, size=(8, 8))


@pytest.mark.parametrize("scale", [1e-28, 1e-12, 1e12, 1e28])
def test_answers_scale_exactly_inside_the_supported_range(scale):
    """Scaling by a power of ten scales every answer: cell ids equal, t equal, d2 by scale^2."""
    rng = np.random.default_rng(5)
    g = tet_grid()
    q = rng.uniform(-10.5, 10.5, (300, 3))
    ref = matrixtree.CellLocator(g).locate(q)
    gs = g.copy()
    gs.points = g.points * scale
    np.testing.assert_array_equal(matrixtree.CellLocator(gs).locate(q * scale), ref)
    s = sphere()
    o = rng.uniform(-2, 2, (300, 3))
    d = -o + rng.uniform(-0.3, 0.3, (300, 3))
    t0, c0 = matrixtree.MatrixTree(s).intersect(o, d)
    _, _, d20 = matrixtree.CellLocator(s).closest_points(o)
    ss = s.copy()
    ss.points = s.points * scale
    t1, c1 = matrixtree.MatrixTree(ss).intersect(o * scale, d * scale)
    assert np.mean(c1 == c0) > 0.99 and np.sum(c0 >= 0) > 100
    same = (c1 == c0) & (c0 >= 0)
    np.testing.assert_allclose(t1[same], t0[same], rtol=1e-9)
    _, _, d21 = matrixtree.CellLocator(ss).closest_points(o * scale)
    np.testing.assert_allclose(d21 / scale**2, d20, rtol=1e-9)


def test_non_finite_query_points_get_documented_answers():
    """A non-finite query point is in no cell and has no closest point: id -1, d2 = inf, point NaN."""
    loc = matrixtree.CellLocator(tet_grid())
    bad = [[0.0, np.inf, 0.0], [np.nan, 0.0, 0.0], [-np.inf, 1.0, 1.0]]
    cp, ids, d2 = loc.closest_points(bad + [[0.5, 0.5, 0.5]])
    assert list(ids[:3]) == [-1, -1, -1] and np.all(np.isnan(cp[:3])) and np.all(np.isinf(d2[:3]))
    assert ids[3] >= 0 and d2[3] == 0.0
    assert list(loc.locate(bad)) == [-1, -1, -1]
    t, ids, x = loc.trace(bad, [[1, 0, 0]] * 3)
    assert list(ids) == [-1, -1, -1] and np.all(np.isinf(t)) and np.all(np.isnan(x))
    tree = matrixtree.MatrixTree(sphere())
    t, ids = tree.intersect([[0, 0, 3], [0, 0, 3], [np.nan, 0, 3]], [[0, 0, 0], [np.inf, 0, -1], [0, 0, -1]])
    assert list(ids) == [-1, -1, -1] and np.all(np.isinf(t))


def test_query_settings_out_of_range_are_refused():
    loc = matrixtree.CellLocator(tet_grid())
    with pytest.raises(ValueError, match=r"tolerance must be a finite number in \[0, inf\)"):
        loc.trace([[0, 0, 0]], [[1, 0, 0]], tolerance=-1)
    with pytest.raises(ValueError, match=r"tolerance"):
        loc.trace([[0, 0, 0]], [[1, 0, 0]], tolerance=np.nan)
    with pytest.raises(ValueError, match=r"length must be a finite number in \(0, inf\)"):
        loc.trace([[0, 0, 0]], [[1, 0, 0]], length=0)
    with pytest.raises(ValueError, match=r"t_max must be >= 0"):
        matrixtree.MatrixTree(sphere()).intersect([[0, 0, 3]], [[0, 0, -1]], t_max=np.nan)


def test_locate_no_points_with_weights_gives_empty_arrays():
    """locate on a (0, 3) array with return_weights=True gives empty arrays of the right shapes."""
    loc = matrixtree.CellLocator(tet_grid())
    ids, pc, w = loc.locate(np.zeros((0, 3)), return_pcoords=True, return_weights=True)
    assert ids.shape == (0,) and pc.shape == (0, 3) and w.shape == (0, 4)


def test_points_near_a_line_cell_of_a_3d_grid_are_in_no_cell_as_in_vtk():
    """A point near (not on) a VTK_LINE lies in no cell, as vtkCellLocator says; on it, in the line."""
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [2, 0, 0], [3, 0, 0]], float)
    g = pv.UnstructuredGrid(np.array([4, 0, 1, 2, 3, 2, 4, 5]), np.array([10, 3], np.uint8), pts)
    q = np.array([[2.5, d, 0.0] for d in (0.0, 1e-12, 1e-6, 1e-3, 0.01, 0.1)] + [[0.2, 0.2, 0.2]])
    ref = vtkCellLocator()
    ref.SetDataSet(g)
    ref.BuildLocator()
    want = [ref.FindCell(list(p)) for p in q]
    assert want == [1, -1, -1, -1, -1, -1, 0]
    assert list(matrixtree.CellLocator(g).locate(q)) == want

"""The ``backend="opencl"`` switch against the CPU engine (the reference): the same tree, the
same first hits and located leaves, the same picture; ``render_volume`` gives the CPU's image
on real 8/16-bit volumes and on float input; clear errors for a bad backend name and for no
device. The device comparisons are skipped, with the reason, when there is no OpenCL platform."""

import ctypes
import ctypes.util
import os

import numpy as np
import pytest

import matrixtree
from matrixtree import scenes

from seeded import random_points

BUNNY = os.path.join(scenes.data_dir(), "meshes", "bunny.ply")
HAND = os.path.join(scenes.data_dir(), "scenes", "utah_hand", "hand_00.obj")


def _opencl_platforms() -> tuple[int, str]:
    name = ctypes.util.find_library("OpenCL") or "libOpenCL.so.1"
    try:
        lib = ctypes.CDLL(name)
    except OSError as e:
        return 0, f"no OpenCL ICD loader ({e})"
    n = ctypes.c_uint(0)
    err = lib.clGetPlatformIDs(0, None, ctypes.byref(n))
    if err != 0 or n.value == 0:
        return 0, f"no OpenCL platform (clGetPlatformIDs returned {err})"
    return n.value, ""


_N, _WHY = _opencl_platforms()
needs_device = pytest.mark.skipif(_N == 0, reason=f"no OpenCL device: {_WHY}")
PIPE = os.path.join(scenes.data_dir(), "cfd", "pipe_flow_tets.vtu")


@pytest.mark.parametrize("call", [
    lambda: matrixtree.MatrixTree(matrixtree.read_mesh(BUNNY), backend="cuda"),
    lambda: matrixtree.render_volume(np.ones((4, 4, 4), np.float32), size=(8, 8), backend="cuda"),
    lambda: matrixtree.CellLocator(matrixtree.read_grid(PIPE), backend="cuda"),
], ids=["MatrixTree", "render_volume", "CellLocator"])
def test_bad_backend_name_is_a_value_error(call):
    with pytest.raises(ValueError, match="backend must be 'cpu' or 'opencl'"):
        call()


@pytest.fixture(scope="module")
def bunny():
    return matrixtree.read_mesh(BUNNY)


@pytest.fixture(scope="module")
def pipe():
    return matrixtree.read_grid(PIPE)


@needs_device
@pytest.mark.parametrize("kind", ["octree", "kdtree"])
def test_opencl_tree_and_queries_equal_the_cpu_engine(bunny, kind):
    cpu = matrixtree.MatrixTree(bunny, tree=kind)
    gpu = matrixtree.MatrixTree(bunny, tree=kind, backend="opencl")
    sc, sg = cpu.stats(), gpu.stats()
    assert sg["backend"] == "opencl" and sg["device"]
    for key in ("height", "leaves", "references", "level_blocks", "level_dims", "root_bounds"):
        assert sc[key] == sg[key], key
    # The CPU build keeps the leaf triangles for its ray queries; the device build does not.
    assert sc["leaf_triangle_bytes"] >= 72 * sc["references"] and sg["leaf_triangle_bytes"] == 0
    assert sc["bytes"] - sc["leaf_triangle_bytes"] == sg["bytes"]
    rng = np.random.default_rng(5)
    lo, hi = np.array(sc["root_bounds"][0::2]), np.array(sc["root_bounds"][1::2])
    centre = 0.5 * (lo + hi)
    targets = lo + rng.random((3000, 3)) * (hi - lo)
    dirs = rng.normal(size=(3000, 3))
    origins = centre - 2.0 * np.linalg.norm(hi - lo) * dirs / np.linalg.norm(dirs, axis=1)[:, None]
    d = targets - origins
    tc, cc = cpu.intersect(origins, d)
    tg, cg = gpu.intersect(origins, d)
    np.testing.assert_array_equal(cc, cg)
    hit = np.isfinite(tc)
    assert hit.sum() > 500
    np.testing.assert_allclose(tg[hit], tc[hit], rtol=1e-6, atol=0)
    pts = lo - 0.05 * (hi - lo) + rng.random((5000, 3)) * 1.1 * (hi - lo)
    np.testing.assert_array_equal(cpu.find_leaves(pts), gpu.find_leaves(pts))


@needs_device
def test_opencl_render_matches_cpu_render(bunny):
    a = matrixtree.render(bunny, size=(96, 72))
    b = matrixtree.render(bunny, size=(96, 72), backend="opencl")
    assert a["rgb"].shape == b["rgb"].shape
    # Same primary hits; shadow rays differ only in their parametrisation (see the ray caster).
    same = np.mean(np.all(a["rgb"] == b["rgb"], axis=2))
    assert same > 0.99, same


@needs_device
@pytest.mark.parametrize("tree", ["octree", "implicit-kd"])
def test_watertight_on_the_opencl_backend_is_refused(bunny, tree):
    """The device kernels have the Moller-Trumbore test only: asking for watertight there is an
    error, never a render that silently lets rays through shared edges."""
    with pytest.raises(RuntimeError, match="only the Moller-Trumbore"):
        matrixtree.render(bunny, size=(16, 16), tree=tree, backend="opencl", triangle_test="watertight")
    assert matrixtree.render(bunny, size=(16, 16), tree=tree, backend="cpu", triangle_test="watertight")["rgb"].any()


@needs_device
@pytest.mark.parametrize("path, kind", [(BUNNY, "implicit-kd"), (HAND, "bsp")])
def test_opencl_split_tree_rays_equal_the_cpu_walk(path, kind):
    # The split trees are built on the CPU; the device traces them with the stackless walk.
    mesh = matrixtree.read_mesh(path)
    cpu = matrixtree.MatrixTree(mesh, tree=kind)
    dev = matrixtree.MatrixTree(mesh, tree=kind, backend="opencl")
    for key in ("height", "leaves", "references", "nodes", "bytes", "pointer_tree_bytes"):
        assert cpu.stats()[key] == dev.stats()[key], key
    lo, hi = np.array(cpu.stats()["root_bounds"][0::2]), np.array(cpu.stats()["root_bounds"][1::2])
    rng = np.random.default_rng(11)
    targets = lo + rng.random((3000, 3)) * (hi - lo)
    dirs = rng.normal(size=(3000, 3))
    origins = 0.5 * (lo + hi) - 2.0 * np.linalg.norm(hi - lo) * dirs / np.linalg.norm(dirs, axis=1)[:, None]
    tc, cc = cpu.intersect(origins, targets - origins)
    tg, cg = dev.intersect(origins, targets - origins)
    np.testing.assert_array_equal(cc, cg)
    hit = np.isfinite(tc)
    assert hit.sum() > 500
    np.testing.assert_allclose(tg[hit], tc[hit], rtol=1e-6, atol=0)
    a = matrixtree.render(mesh, size=(64, 48), tree=kind)
    b = matrixtree.render(mesh, size=(64, 48), tree=kind, backend="opencl")
    assert np.mean(np.all(a["rgb"] == b["rgb"], axis=2)) > 0.99


# ----------------------------------------------------------------------------- volume rendering
VOLUMES = os.path.join(scenes.data_dir(), "volumes")


def test_render_volume_opencl_with_no_matching_device_raises():
    # A selector that matches no device fails the way a machine without OpenCL does (the next
    # test removes the platforms altogether): a RuntimeError that says what to do, no crash.
    with pytest.raises(RuntimeError, match="opencl backend.*backend='cpu'"):
        matrixtree.render_volume(np.ones((6, 6, 6), np.float32), size=(8, 8), backend="opencl",
                                 device="no-such-opencl-device-xyz")


def _opencl_error_without_any_platform(setup: str, call: str, after: str = "") -> str:
    """Runs ``setup``, ``call`` and ``after`` in a fresh Python whose OCL_ICD_VENDORS is an empty
    folder, so that the ICD loader finds no OpenCL platform at all. ``call`` must raise a
    RuntimeError naming the opencl backend, and the process must end normally (no crash);
    returns what it printed."""
    import subprocess
    import sys
    import tempfile

    code = f"{setup}\ntry:\n    {call}\nexcept RuntimeError as e:\n    print('RuntimeError:', e)\n{after}\n"
    with tempfile.TemporaryDirectory() as empty:
        env = dict(os.environ, OCL_ICD_VENDORS=empty)
        r = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "RuntimeError:" in r.stdout and "opencl backend" in r.stdout, r.stdout + r.stderr[-2000:]
    return r.stdout


def test_render_volume_opencl_without_any_platform_raises():
    _opencl_error_without_any_platform(
        "import numpy as np, matrixtree",
        "matrixtree.render_volume(np.ones((6, 6, 6), np.float32), size=(8, 8), backend='opencl')")


@needs_device
@pytest.mark.parametrize("name, storage", [("headsq.mhd", "uint16"), ("ironProt.vtk", "uint8"),
                                           ("HeadMRVolume.mhd", "uint8")])
def test_render_volume_opencl_equals_cpu_on_real_volumes(name, storage):
    im = matrixtree.read_volume(os.path.join(VOLUMES, name))
    cam = matrixtree.frame_camera(im, azimuth=40, elevation=25)
    for shade, tol in ((False, 1e-5), (True, 1e-4)):  # shaded: OpenCL's float sqrt/div/pow, a few ulp
        a, sa = matrixtree.render_volume(im, size=(64, 56), camera=cam, shade=shade, return_stats=True)
        b, sb = matrixtree.render_volume(im, size=(64, 56), camera=cam, shade=shade, backend="opencl",
                                         return_stats=True)
        assert sa["storage"] == sb["storage"] == storage
        assert sb["backend"] == "opencl" and sb["device"]
        assert a[..., 3].mean() > 0.02, "the image should show the volume"
        assert np.abs(a - b).max() <= tol, (name, shade, np.abs(a - b).max())
        assert sa["samples"] == sb["samples"]


@needs_device
def test_render_volume_opencl_equals_cpu_on_float_input():
    # Non-integer floats: quantised into 16-bit bricks (the default table is 16x coarser than a
    # step), and in float blocks where the table is finer (TableSize 65536); double accumulation too.
    from vtkmodules.util.numpy_support import numpy_to_vtk, vtk_to_numpy
    from vtkmodules.vtkCommonDataModel import vtkImageData
    from matrixtree_vtk import vtkMatrixTreeVolumeRayCaster

    x, y, z = np.mgrid[-1:1:33j, -1:1:29j, -1:1:41j]
    field = (np.exp(-4 * (x ** 2 + (y - 0.2) ** 2 + z ** 2)) + 0.3 * np.sin(5 * x * y)).astype(np.float32)
    for double in (False, True):
        a, sa = matrixtree.render_volume(field, size=(48, 40), double_precision=double, return_stats=True)
        b = matrixtree.render_volume(field, size=(48, 40), double_precision=double, backend="opencl")
        assert sa["storage"] == "uint16"
        assert a[..., 3].mean() > 0.02
        assert np.abs(a - b).max() <= 1e-5
    im = vtkImageData()
    im.SetDimensions(*field.shape)
    im.GetPointData().SetScalars(numpy_to_vtk(field.transpose(2, 1, 0).ravel(), deep=True))
    ctf, otf = matrixtree.default_transfer_functions(im)
    images = []
    for backend in ("cpu", "opencl"):
        c = vtkMatrixTreeVolumeRayCaster()
        c.SetInputData(im)
        c.SetColorTransferFunction(ctf)
        c.SetScalarOpacity(otf)
        c.SetTableSize(65536)
        c.SetImageSize(48, 40)
        c.SetCamera(matrixtree.frame_camera(im))
        if backend == "opencl":
            c.SetBackendToOpenCL()
        c.Update()
        assert c.GetVoxelStorage() == 0 and c.GetQuantizationStep() == 0
        images.append(vtk_to_numpy(c.GetOutput().GetPointData().GetArray("RGBAFloat")))
    assert images[0][:, 3].mean() > 0.02
    assert np.abs(images[0] - images[1]).max() <= 1e-5


# ----------------------------------------------------------------------------- cell location
@needs_device
@pytest.mark.parametrize("tree", ["octree", "kdtree"])
def test_cell_locator_opencl_locate_equals_cpu(pipe, tree):
    p = random_points(pipe, 100000, seed=11)
    # Points on shared faces and at vertices: several cells contain them; the first in the
    # leaf's order must win on both backends.
    conn = pipe.GetCells().GetConnectivityArray()
    from vtkmodules.util.numpy_support import vtk_to_numpy
    tets = vtk_to_numpy(conn).reshape(-1, 4)
    xyz = vtk_to_numpy(pipe.GetPoints().GetData())
    pick = np.random.default_rng(12).integers(0, len(tets), 3000)
    faces = xyz[tets[pick, :3]].mean(axis=1)
    p = np.vstack([p, faces, xyz[tets[pick[:1000], 3]]])
    cpu = matrixtree.CellLocator(pipe, tree=tree)
    gpu = matrixtree.CellLocator(pipe, tree=tree, backend="opencl")
    ic, pc, wc = cpu.locate(p, return_pcoords=True, return_weights=True)
    ig, pg, wg = gpu.locate(p, return_pcoords=True, return_weights=True)
    assert (ic >= 0).sum() > 40000
    np.testing.assert_array_equal(ic, ig)
    assert np.abs(pc - pg).max() <= 1e-12 and np.abs(wc - wg).max() <= 1e-12
    np.testing.assert_array_equal(gpu.locate(p), ic)  # ids only, the device copy reused
    vl = gpu.vtk_locator
    assert vl.GetNumberOfOpenCLUploads() == 1 and vl.GetLastNumberOfUnconfirmedCells() == 0
    assert vl.GetOpenCLDeviceName() and "kernel" in vl.GetLastFindCellsPhases()
    assert "backend opencl" in repr(gpu)


def test_cell_locator_opencl_with_no_matching_device_raises(pipe):
    loc = matrixtree.CellLocator(pipe, backend="opencl", device="no-such-opencl-device-xyz")
    with pytest.raises(RuntimeError, match="opencl backend.*backend='cpu'"):
        loc.locate([[0.0, 0.0, 0.0]])


def test_cell_locator_opencl_without_any_platform_raises():
    out = _opencl_error_without_any_platform(
        f"import matrixtree\ng = matrixtree.read_grid({PIPE!r})\nloc = matrixtree.CellLocator(g, backend='opencl')",
        "loc.locate([[0.0, 0.0, 0.0]])",
        "print('cpu:', matrixtree.CellLocator(g).locate([[0.0, 0.0, 0.0]]).shape)")
    assert "cpu: (1,)" in out


@needs_device
def test_a_failed_device_selector_is_forgotten(bunny):
    """vtkMatrixTree and vtkMatrixTreeVolumeRayCaster on OPENCL: a selector that matches no device
    fails with an error and leaves no device held (no name); the default selector afterwards
    builds and renders on the device again, as the CPU does."""
    from matrixtree_vtk import vtkMatrixTree
    from vtkmodules.util.numpy_support import numpy_to_vtk
    from vtkmodules.vtkCommonCore import vtkIntArray

    tree = vtkMatrixTree()
    tree.SetDataSet(bunny)
    tree.SetBackendToOpenCL()
    assert tree.Build()
    device = tree.GetOpenCLDeviceName()
    assert device
    tree.SetOpenCLDevice("no device has this name")
    tree.GlobalWarningDisplayOff()
    try:
        assert not tree.Build()
    finally:
        tree.GlobalWarningDisplayOn()
    assert tree.GetOpenCLDeviceName() == ""
    tree.SetOpenCLDevice(None)
    assert tree.Build() and tree.GetOpenCLDeviceName() == device
    points = numpy_to_vtk(np.array(bunny.GetPoints().GetData())[:500].copy(), deep=True)
    on_device, on_cpu = vtkIntArray(), vtkIntArray()
    tree.FindLeaves(points, on_device)
    tree.SetBackendToCPU()
    tree.FindLeaves(points, on_cpu)
    assert np.array_equal(np.array(on_device), np.array(on_cpu))

    from matrixtree_vtk import vtkMatrixTreeVolumeRayCaster
    from vtkmodules.util.numpy_support import vtk_to_numpy

    image = matrixtree.volume._as_image(np.arange(8 * 9 * 10, dtype=np.uint8).reshape(8, 9, 10), None, None)
    caster = vtkMatrixTreeVolumeRayCaster()
    caster.SetInputData(image)
    caster.SetImageSize(24, 20)
    caster.SetCamera(matrixtree.frame_camera(image))

    def frame():
        caster.Update()
        a = caster.GetOutput().GetPointData().GetArray("RGBAFloat")
        return None if a is None else vtk_to_numpy(a).copy()

    cpu = frame()
    caster.SetBackendToOpenCL()
    assert np.abs(frame() - cpu).max() <= 1e-5 and caster.GetOpenCLDeviceName() == device
    caster.SetOpenCLDevice("no device has this name")
    caster.GlobalWarningDisplayOff()
    try:
        assert frame() is None
    finally:
        caster.GlobalWarningDisplayOn()
    assert caster.GetOpenCLDeviceName() == ""
    caster.SetOpenCLDevice(None)
    assert np.abs(frame() - cpu).max() <= 1e-5 and caster.GetOpenCLDeviceName() == device

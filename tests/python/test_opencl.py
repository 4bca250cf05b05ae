"""The ``backend="opencl"`` switch against the CPU engine (the reference): the same tree, the
same first hits and located leaves, the same picture; a clear error for a bad backend name.
Skipped, with the reason, when the machine has no OpenCL platform."""

import ctypes
import ctypes.util
import os

import numpy as np
import pytest

import matrixtree
from matrixtree import scenes

BUNNY = os.path.join(scenes.data_dir(), "meshes", "bunny.ply")


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


@pytest.fixture(scope="module")
def bunny():
    return matrixtree.read_mesh(BUNNY)


def test_bad_backend_name_is_a_value_error(bunny):
    with pytest.raises(ValueError, match="backend must be 'cpu' or 'opencl'"):
        matrixtree.MatrixTree(bunny, backend="cuda")


@needs_device
@pytest.mark.parametrize("kind", ["octree", "kdtree"])
def test_opencl_tree_and_queries_equal_the_cpu_engine(bunny, kind):
    cpu = matrixtree.MatrixTree(bunny, tree=kind)
    gpu = matrixtree.MatrixTree(bunny, tree=kind, backend="opencl")
    sc, sg = cpu.stats(), gpu.stats()
    assert sg["backend"] == "opencl" and sg["device"]
    for key in ("height", "leaves", "references", "bytes", "level_blocks", "level_dims", "root_bounds"):
        assert sc[key] == sg[key], key
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

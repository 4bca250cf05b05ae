"""Vectorized cell location, segment intersection and closest points on a mesh.

A numpy front end to ``vtkMatrixTreeLocator``: one call answers a whole array of points or
segments, OpenMP-parallel in C++ (never a Python loop per point). Answers equal the locator's
one-point calls, which match VTK's own locators. ``backend="opencl"`` moves point location
(``locate``) onto an OpenCL device, with the same answers.

Where the VTK module does not import, ``CellLocator``, ``cached_memory`` and
``release_cached_memory`` are the engine extension's (``matrixtree._engine``, bound at the end of
this module; CPU only, linear cells), with the same arguments and answers.
"""

from __future__ import annotations

import numpy as np
from vtkmodules.util.numpy_support import numpy_to_vtk, vtk_to_numpy
from vtkmodules.vtkCommonCore import vtkDoubleArray, vtkIdList, vtkIdTypeArray, vtkPoints
from vtkmodules.vtkCommonDataModel import vtkDataSet

from matrixtree._backend import VTK_MODULE

if VTK_MODULE:
    from matrixtree_vtk import vtkMatrixTreeLocator

from matrixtree import _checks, _meshstate
from matrixtree._util import VtkErrors, bounds6, check_backend, points3, segments, tree_type, vtk_points

__all__ = ["CellLocator", "cached_memory", "release_cached_memory"]


def cached_memory() -> int:
    """Bytes of freed tree arrays the process keeps for the next build.

    Every matrix tree (``CellLocator``, ``MatrixTree``) holds its large arrays (2 MiB and up) in
    memory mappings; freed ones are kept, at most 16 and 512 MiB, so that a rebuild (a deforming
    mesh every frame) writes into pages the process already has. ``MATRIXTREE_MAP_CACHE=0`` in
    the environment keeps none.

    >>> import matrixtree
    >>> matrixtree.release_cached_memory() >= 0 and matrixtree.cached_memory() == 0
    True
    """
    return int(vtkMatrixTreeLocator.GetCachedMemorySize())


def release_cached_memory() -> int:
    """Hands every kept mapping (see ``cached_memory``) back to the system; returns its bytes."""
    return int(vtkMatrixTreeLocator.ReleaseCachedMemory())


def _segment_meets_boxes(a, b, lo, hi) -> np.ndarray:
    """Whether the segment a -> b meets each box [lo, hi] (the slab test, closed boxes)."""
    d = b - a
    with np.errstate(divide="ignore", invalid="ignore"):
        t0, t1 = (lo - a) / d, (hi - a) / d
    near, far = np.minimum(t0, t1), np.maximum(t0, t1)
    # An axis the segment runs parallel to: inside the slab for all t, or for none.
    par = d == 0
    inside = (a >= lo) & (a <= hi)
    near = np.where(par, np.where(inside, -np.inf, np.inf), near)
    far = np.where(par, np.where(inside, np.inf, -np.inf), far)
    return np.maximum(near.max(axis=1), 0.0) <= np.minimum(far.min(axis=1), 1.0)


class CellLocator(_meshstate.RebuildOnChange):
    """Point location, ray (segment) casting and closest points on the cells of a mesh.

    Parameters
    ----------
    dataset : vtkDataSet or pyvista.DataSet
        The mesh: an unstructured grid (tetrahedra, hexahedra, wedges, pyramids, voxels,
        mixed or quadratic cells) or a surface (polydata).
    tree : {"octree", "kdtree"}, default: "octree"
        The matrix tree used.
    height : int, default: 0
        Levels below the root; 0 chooses it from the cell sizes.
    threads : int, default: 0
        OpenMP threads for the build and the batched queries; 0 uses all.
    backend : {"cpu", "opencl"}, default: "cpu"
        Where :meth:`locate` finds the points' cells. ``"opencl"``: a kernel on an OpenCL device
        does the leaf search and the candidate scan (deciding tetrahedra itself), the host
        finishes what the kernel leaves to VTK; the tree is built on the CPU and copied to the
        device once per build. Cell ids are identical to ``"cpu"``, pcoords and weights equal.
        Without an OpenCL device ``locate`` raises RuntimeError (no silent fallback).
        The other queries always run on the CPU.
    device : str, optional
        OpenCL device selector (``backend="opencl"`` only): ``"P:D"`` (platform P, device D), a
        device number, or part of a device name; default: ``$MATRIXTREE_OPENCL_DEVICE``, else the
        first GPU, else the first device.

    Raises
    ------
    ValueError
        A setting out of its range (``height`` 0..63, ``threads`` 0..4096), an unknown ``tree``
        or ``backend``, or a data set without cells.
    RuntimeError
        The build failed; the message is the engine's reason: a coordinate that is NaN, inf or
        beyond +-1e30, points spanning less than 1e-30, a cell referring to a missing point, or a
        ``height`` whose leaf level would need more than 1 GiB. Should a later rebuild fail (the
        data set changed), every query raises RuntimeError
        with that same reason.

    Notes
    -----
    Every query first checks whether the data set changed since the tree was built (points
    moved, even in place through a numpy view; cells or points replaced; ``Modified()`` called:
    see ``matrixtree._meshstate``) and rebuilds the tree if so; ``builds`` counts the builds.
    Query points (and segment ends) that are NaN or infinite are not an error: such a point
    lies in no cell (-1), a segment through one hits nothing, and it has no closest point
    (cell -1, point NaN, squared distance inf).

    See Also
    --------
    matrixtree_vtk.vtkMatrixTreeLocator : the VTK class underneath (``.vtk_locator``).

    Examples
    --------
    >>> import numpy as np
    >>> from vtkmodules.vtkImagingCore import vtkRTAnalyticSource
    >>> from vtkmodules.vtkFiltersGeneral import vtkDataSetTriangleFilter
    >>> src = vtkRTAnalyticSource(); src.SetWholeExtent(0, 4, 0, 4, 0, 4)
    >>> tets = vtkDataSetTriangleFilter(); tets.SetInputConnection(src.GetOutputPort()); _ = tets.Update()
    >>> loc = CellLocator(tets.GetOutput())
    >>> ids = loc.locate([[0.5, 0.5, 0.5], [100.0, 0.0, 0.0]])
    >>> bool(ids[0] >= 0), int(ids[1])
    (True, -1)
    """

    def __init__(self, dataset: vtkDataSet, tree: str = "octree", height: int = 0, threads: int = 0,
                 backend: str = "cpu", device: str | None = None):
        if not isinstance(dataset, vtkDataSet):
            raise TypeError(f"dataset must be a vtkDataSet (or a pyvista mesh), got {type(dataset).__name__}")
        tree_id = tree_type(tree)
        check_backend(backend)
        height = _checks.integer(height, "height", 0, 63, "levels below the root, 0 = automatic")
        threads = _checks.threads(threads)
        if dataset.GetNumberOfCells() == 0:
            raise ValueError("dataset has no cells")
        self.dataset = dataset
        self.vtk_locator = vtkMatrixTreeLocator()
        self.vtk_locator.SetTreeType(tree_id)
        self.vtk_locator.SetHeight(height)
        self.vtk_locator.SetNumberOfThreads(threads)
        if backend == "opencl":
            self.vtk_locator.SetBackendToOpenCL()
            if device is not None:
                self.vtk_locator.SetOpenCLDevice(str(device))
        self.backend = backend
        self.vtk_locator.SetDataSet(dataset)
        self.builds = 0
        self._build()

    def _build_tree(self) -> None:
        with VtkErrors(self.vtk_locator) as errors:
            self.vtk_locator.ForceBuildLocator()
        errors.raise_last(RuntimeError)

    def _query(self, method, *args) -> None:
        """Call ``vtk_locator.<method>(*args)`` on a tree that matches the data set; RuntimeError
        with VTK's message if it reports an error (a failed build: every query then raises its
        reason)."""
        self._sync()
        with VtkErrors(self.vtk_locator) as errors:
            getattr(self.vtk_locator, method)(*args)
        opencl = self.backend == "opencl" and method == "FindCells"
        errors.raise_last(RuntimeError, " [CellLocator: backend='cpu' needs no OpenCL]" if opencl else "")

    def locate(self, points, *, return_pcoords: bool = False, return_weights: bool = False):
        """The cell containing each point (VTK's FindCell), or -1.

        Parameters
        ----------
        points : array_like, shape (n, 3)
            Query points.
        return_pcoords : bool, default: False
            Also return the parametric coordinates in the cell, shape (n, 3).
        return_weights : bool, default: False
            Also return the interpolation weights, shape (n, max cell size): weight ``j``
            belongs to point ``j`` of the cell; unused entries and misses are 0.

        Returns
        -------
        numpy.ndarray or tuple of numpy.ndarray
            Cell ids (int64), followed by the optional arrays.

        Raises
        ------
        RuntimeError
            ``backend="opencl"`` with no OpenCL device (or none matching ``device``), or a build
            without OpenCL; the message says why.

        Examples
        --------
        >>> from vtkmodules.vtkImagingCore import vtkRTAnalyticSource
        >>> from vtkmodules.vtkFiltersGeneral import vtkDataSetTriangleFilter
        >>> src = vtkRTAnalyticSource(); src.SetWholeExtent(0, 4, 0, 4, 0, 4)
        >>> tets = vtkDataSetTriangleFilter(); tets.SetInputConnection(src.GetOutputPort()); _ = tets.Update()
        >>> ids, w = CellLocator(tets.GetOutput()).locate([[0.1, 0.2, 0.1]], return_weights=True)
        >>> bool(ids[0] >= 0), round(float(w[0].sum()), 12)
        (True, 1.0)
        """
        p = points3(points, "points")
        ids = vtkIdTypeArray()
        pc = vtkDoubleArray() if return_pcoords else None
        w = vtkDoubleArray() if return_weights else None
        self._query("FindCells", vtk_points(p), ids, pc, w)
        out = [vtk_to_numpy(ids).astype(np.int64, copy=True)]
        if return_pcoords:
            out.append(vtk_to_numpy(pc).reshape(-1, 3).copy())
        if return_weights:
            out.append(vtk_to_numpy(w).reshape(len(p), w.GetNumberOfComponents()).copy())
        return out[0] if len(out) == 1 else tuple(out)

    def trace(self, origins, directions=None, *, ends=None, length: float = 1.0, tolerance: float = 0.0):
        """First hit of each segment with the cells (VTK's IntersectWithLine).

        Each segment runs from ``origins[i]`` to ``ends[i]``, or to
        ``origins[i] + length * directions[i]`` when ``ends`` is not given.

        Parameters
        ----------
        origins : array_like, shape (n, 3)
            Segment starts.
        directions : array_like, shape (n, 3), optional
            Segment directions (not normalized: scaled by ``length``).
        ends : array_like, shape (n, 3), optional
            Segment ends, instead of ``directions``.
        length : float, default: 1.0
            Scale of ``directions``.
        tolerance : float, default: 0.0
            VTK's intersection tolerance: finite, >= 0.

        Returns
        -------
        t : numpy.ndarray
            Hit parameter along each segment in [0, 1]; ``inf`` on a miss.
        cell_ids : numpy.ndarray
            Hit cell, -1 on a miss.
        points : numpy.ndarray, shape (n, 3)
            Hit points; NaN on a miss.

        Examples
        --------
        >>> from vtkmodules.vtkFiltersSources import vtkSphereSource
        >>> s = vtkSphereSource(); s.SetThetaResolution(64); s.SetPhiResolution(64); _ = s.Update()
        >>> t, ids, x = CellLocator(s.GetOutput()).trace([[0, 0, 0], [2, 2, 2]], [[1, 0, 0], [1, 0, 0]])
        >>> bool(abs(x[0, 0] - 0.5) < 1e-2), bool(ids[1] == -1 and np.isinf(t[1]))
        (True, True)
        """
        o, e = segments(origins, directions, ends, length)
        tolerance = _checks.real(tolerance, "tolerance", 0.0)
        t, ids, x = vtkDoubleArray(), vtkIdTypeArray(), vtkDoubleArray()
        self._query("IntersectSegments", numpy_to_vtk(o, deep=True), numpy_to_vtk(e, deep=True), tolerance,
                    t, ids, x)
        return (vtk_to_numpy(t).copy(), vtk_to_numpy(ids).astype(np.int64, copy=True),
                vtk_to_numpy(x).reshape(-1, 3).copy())

    def closest_points(self, points):
        """The closest point on the cells to each query point (VTK's FindClosestPoint).

        Parameters
        ----------
        points : array_like, shape (n, 3)
            Query points.

        Returns
        -------
        closest : numpy.ndarray, shape (n, 3)
            Closest points.
        cell_ids : numpy.ndarray
            The cell each closest point lies on; -1 for a NaN or infinite query point.
        dist2 : numpy.ndarray
            Squared distances (inf where the cell is -1; the closest point is NaN there).

        Examples
        --------
        >>> from vtkmodules.vtkFiltersSources import vtkPlaneSource
        >>> plane = vtkPlaneSource(); plane.SetResolution(4, 4); _ = plane.Update()  # z = 0, |x|, |y| <= 0.5
        >>> cp, ids, d2 = CellLocator(plane.GetOutput()).closest_points([[0.1, 0.2, 3.0]])
        >>> bool(np.allclose(cp[0], [0.1, 0.2, 0.0])), float(d2[0])
        (True, 9.0)
        """
        p = points3(points, "points")
        cp, ids, d2 = vtkDoubleArray(), vtkIdTypeArray(), vtkDoubleArray()
        self._query("FindClosestPoints", vtk_points(p), cp, ids, d2)
        return (vtk_to_numpy(cp).reshape(-1, 3).copy(), vtk_to_numpy(ids).astype(np.int64, copy=True),
                vtk_to_numpy(d2).copy())

    def trace_all(self, origins, directions=None, *, ends=None, length: float = 1.0):
        """Every cell each segment meets, sorted along it (VTK's ``IntersectWithLine`` with a point
        and an id list; tolerance 0).

        Parameters
        ----------
        origins, directions, ends, length
            The segments, as in :meth:`trace`.

        Returns
        -------
        offsets : numpy.ndarray, shape (n + 1,)
            Segment ``i``'s hits are entries ``offsets[i]:offsets[i + 1]`` of the arrays below.
        t : numpy.ndarray
            Hit parameters along their segments, in [0, 1], ascending per segment.
        cell_ids : numpy.ndarray
            The cells hit, each once per segment (at its first meeting).
        points : numpy.ndarray, shape (offsets[-1], 3)
            Hit points.

        Examples
        --------
        >>> from vtkmodules.vtkFiltersSources import vtkSphereSource
        >>> s = vtkSphereSource(); s.SetThetaResolution(32); s.SetPhiResolution(32); _ = s.Update()
        >>> off, t, ids, x = CellLocator(s.GetOutput()).trace_all([[-2, 0.01, 0.02]], ends=[[2, 0.01, 0.02]])
        >>> off.tolist(), bool(x[0, 0] < 0 < x[1, 0])
        ([0, 2], True)
        """
        o, e = segments(origins, directions, ends, length)
        self._sync()
        # The VTK class answers one segment per call; the engine extension's path batches them.
        hit_points, hit_ids = vtkPoints(), vtkIdList()
        hit_points.SetDataTypeToDouble()
        counts, ids, xs = np.zeros(len(o), np.int64), [], []
        for i in range(len(o)):
            self.vtk_locator.IntersectWithLine(o[i], e[i], hit_points, hit_ids)
            counts[i] = hit_ids.GetNumberOfIds()
            if counts[i]:
                ids.append([hit_ids.GetId(k) for k in range(counts[i])])
                xs.append(vtk_to_numpy(hit_points.GetData()).astype(np.float64))
        offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        ids = np.concatenate(ids).astype(np.int64) if ids else np.zeros(0, np.int64)
        x = np.concatenate(xs).reshape(-1, 3) if xs else np.zeros((0, 3))
        seg = np.repeat(np.arange(len(o)), counts)
        d = e[seg] - o[seg]
        with np.errstate(invalid="ignore", divide="ignore"):
            t = np.einsum("ij,ij->i", x - o[seg], d) / np.einsum("ij,ij->i", d, d)
        return offsets, t, ids, x

    def cells_within_bounds(self, bounds) -> np.ndarray:
        """The cells whose bounding boxes meet ``bounds`` (VTK's ``FindCellsWithinBounds``),
        ascending.

        Parameters
        ----------
        bounds : sequence of 6 float
            ``(xmin, xmax, ymin, ymax, zmin, zmax)``.

        Returns
        -------
        numpy.ndarray of int64

        Examples
        --------
        >>> from vtkmodules.vtkFiltersSources import vtkPlaneSource
        >>> plane = vtkPlaneSource(); plane.SetResolution(4, 4); _ = plane.Update()   # 16 squares
        >>> CellLocator(plane.GetOutput()).cells_within_bounds([-0.5, -0.3, -0.5, -0.3, -1, 1]).tolist()
        [0]
        """
        b = bounds6(bounds)
        self._sync()
        out = vtkIdList()
        self.vtk_locator.FindCellsWithinBounds(b, out)
        return np.sort(np.array([out.GetId(k) for k in range(out.GetNumberOfIds())], dtype=np.int64))

    def cells_along_line(self, pointa, pointb, tolerance: float = 0.0) -> np.ndarray:
        """The cells whose bounding boxes (grown by ``tolerance``) the segment from ``pointa``
        to ``pointb`` crosses (VTK's ``FindCellsAlongLine``), ascending.

        Examples
        --------
        >>> from vtkmodules.vtkFiltersSources import vtkPlaneSource
        >>> plane = vtkPlaneSource(); plane.SetResolution(4, 4); _ = plane.Update()   # 16 squares
        >>> CellLocator(plane.GetOutput()).cells_along_line([-0.4, -0.4, -1], [-0.4, -0.4, 1]).tolist()
        [0]
        """
        a, b = points3(pointa, "pointa")[0], points3(pointb, "pointb")[0]
        tol = _checks.real(tolerance, "tolerance", 0.0)
        self._sync()
        # The VTK class lists the cells of the leaves the segment crosses (without a tolerance);
        # the answer is those of them whose boxes, grown by the tolerance, the segment crosses.
        out = vtkIdList()
        if tol > 0:
            box = np.column_stack([np.minimum(a, b) - tol, np.maximum(a, b) + tol]).ravel()
            self.vtk_locator.FindCellsWithinBounds(box.tolist(), out)
        else:
            self.vtk_locator.FindCellsAlongLine(a, b, 0.0, out)
        ids = np.sort(np.array([out.GetId(k) for k in range(out.GetNumberOfIds())], dtype=np.int64))
        box = [0.0] * 6
        lo, hi = np.empty((len(ids), 3)), np.empty((len(ids), 3))
        for k, c in enumerate(ids):
            self.dataset.GetCellBounds(int(c), box)
            lo[k], hi[k] = box[0::2], box[1::2]
        return ids[_segment_meets_boxes(a, b, lo - tol, hi + tol)]

    def __repr__(self) -> str:
        tree = "kdtree" if self.vtk_locator.GetTreeType() == 1 else "octree"
        return (f"CellLocator({self.dataset.GetClassName()}, {self.dataset.GetNumberOfCells()} cells, {tree}, "
                f"height {self.vtk_locator.GetTreeHeight()}, {self.vtk_locator.GetMemorySize()} bytes, "
                f"backend {self.backend})")


if not VTK_MODULE:  # the engine extension answers (matrixtree._backend): one path per process
    from matrixtree import _engine  # noqa: E402

    for _name in ("CellLocator", "cached_memory", "release_cached_memory"):
        _engine.adopt_docs(globals()[_name], getattr(_engine, _name))
    from matrixtree._engine import CellLocator, cached_memory, release_cached_memory  # noqa: E402, F811

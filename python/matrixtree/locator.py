"""Vectorized cell location, segment intersection and closest points on a mesh.

A numpy front end to ``vtkMatrixTreeLocator``: one call answers a whole array of points or
segments, OpenMP-parallel in C++ (never a Python loop per point). Answers equal the locator's
one-point calls, which match VTK's own locators. ``backend="opencl"`` moves point location
(``locate``) onto an OpenCL device, with the same answers.
"""

from __future__ import annotations

import numpy as np
from vtkmodules.util.numpy_support import numpy_to_vtk, vtk_to_numpy
from vtkmodules.vtkCommonCore import vtkDoubleArray, vtkIdTypeArray
from vtkmodules.vtkCommonDataModel import vtkDataSet

from matrixtree_vtk import vtkMatrixTreeLocator

from matrixtree import _checks
from matrixtree._util import VtkErrors, check_backend, points3, tree_type, vtk_points

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


class CellLocator:
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
        ``trace`` and ``closest_points`` always run on the CPU.
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
        data set changed, then ``vtk_locator.BuildLocator()``), every query raises RuntimeError
        with that same reason.

    Notes
    -----
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
    >>> tets = vtkDataSetTriangleFilter(); tets.SetInputConnection(src.GetOutputPort()); tets.Update()
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
        with VtkErrors(self.vtk_locator) as errors:
            self.vtk_locator.BuildLocator()
        errors.raise_last(RuntimeError)

    def _query(self, method, *args) -> None:
        """Call ``vtk_locator.<method>(*args)``; RuntimeError with VTK's message if it reports an
        error (a failed build: every query then raises its reason)."""
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
        >>> tets = vtkDataSetTriangleFilter(); tets.SetInputConnection(src.GetOutputPort()); tets.Update()
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
        >>> s = vtkSphereSource(); s.SetThetaResolution(64); s.SetPhiResolution(64); s.Update()
        >>> t, ids, x = CellLocator(s.GetOutput()).trace([[0, 0, 0], [2, 2, 2]], [[1, 0, 0], [1, 0, 0]])
        >>> bool(abs(x[0, 0] - 0.5) < 1e-2), bool(ids[1] == -1 and np.isinf(t[1]))
        (True, True)
        """
        o = points3(origins, "origins")
        if (directions is None) == (ends is None):
            raise ValueError("give exactly one of directions and ends")
        tolerance = _checks.real(tolerance, "tolerance", 0.0)
        if ends is not None:
            e = points3(ends, "ends")
        else:
            e = o + _checks.real(length, "length", 0.0, lo_open=True) * points3(directions, "directions")
        if e.shape != o.shape:
            raise ValueError(f"origins {o.shape} and ends/directions {e.shape} differ in shape")
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
        >>> plane = vtkPlaneSource(); plane.SetResolution(4, 4); plane.Update()  # z = 0, |x|, |y| <= 0.5
        >>> cp, ids, d2 = CellLocator(plane.GetOutput()).closest_points([[0.1, 0.2, 3.0]])
        >>> bool(np.allclose(cp[0], [0.1, 0.2, 0.0])), float(d2[0])
        (True, 9.0)
        """
        p = points3(points, "points")
        cp, ids, d2 = vtkDoubleArray(), vtkIdTypeArray(), vtkDoubleArray()
        self._query("FindClosestPoints", vtk_points(p), cp, ids, d2)
        return (vtk_to_numpy(cp).reshape(-1, 3).copy(), vtk_to_numpy(ids).astype(np.int64, copy=True),
                vtk_to_numpy(d2).copy())

    def __repr__(self) -> str:
        tree = "kdtree" if self.vtk_locator.GetTreeType() == 1 else "octree"
        return (f"CellLocator({self.dataset.GetClassName()}, {self.dataset.GetNumberOfCells()} cells, {tree}, "
                f"height {self.vtk_locator.GetTreeHeight()}, {self.vtk_locator.GetMemorySize()} bytes, "
                f"backend {self.backend})")

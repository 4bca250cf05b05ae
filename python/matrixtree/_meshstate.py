"""Whether a data set changed since a tree was built over it.

A tree answers for the points and cells it was built over. The locators keep the data set's
fingerprint from their build and compare it before every query (``CellLocator``,
``MatrixTree``, the pyvista filters): a different one means the mesh changed and the tree is
rebuilt first.

The fingerprint holds what is cheap to read and catches every change seen in practice:

- the data set's modification time, which VTK raises on ``Modified()`` and on every setter
  (``SetPoints``, ``SetCells``, ``SetPolys``, pyvista's ``mesh.points = ...``, writes through a
  ``pyvista_ndarray``); ``vtkPointSet``, ``vtkPolyData`` and ``vtkUnstructuredGrid`` include their
  points' and cell arrays' times in it;
- the point and cell counts, and the address, shape and type of the point and cell arrays (an
  array replaced by another);
- a CRC-32 of the point coordinates, so that points moved in place through a plain numpy view
  (``vtk_to_numpy``), which VTK cannot see, count as a change too. It reads the coordinates once
  (24 bytes a point), about as fast as copying them.

Cell arrays edited in place through a plain numpy view without ``Modified()`` are not seen:
call ``Modified()`` on the data set after such an edit.

Not public API.
"""

from __future__ import annotations

import zlib

import numpy as np
from vtkmodules.util.numpy_support import vtk_to_numpy

from matrixtree._cellarrays import cell_types_array


def _array_key(arr) -> tuple:
    """Address, shape and type of a VTK data array (or None)."""
    if arr is None:
        return (None,)
    a = vtk_to_numpy(arr)
    address = a.__array_interface__["data"][0] if a.size else 0  # an empty array's view is new each time
    return (address, a.shape, a.dtype.str)


def _cell_arrays(ds):
    """The vtkCellArrays that hold the data set's cells (none for structured data sets)."""
    if ds.IsA("vtkPolyData"):
        return [ds.GetVerts(), ds.GetLines(), ds.GetPolys(), ds.GetStrips()]
    if ds.IsA("vtkUnstructuredGrid"):
        return [ds.GetCells()]
    return []


def fingerprint(ds) -> tuple:
    """A value that differs whenever ``ds``'s points or cells changed (see the module docstring)."""
    key = [ds.GetMTime(), ds.GetNumberOfPoints(), ds.GetNumberOfCells()]
    points = ds.GetPoints() if ds.IsA("vtkPointSet") else None
    data = points.GetData() if points is not None else None
    if data is not None:
        coords = np.ascontiguousarray(vtk_to_numpy(data))
        key += [_array_key(data), zlib.crc32(coords)]
    for cells in _cell_arrays(ds):
        if cells is not None:
            key += [_array_key(cells.GetOffsetsArray()), _array_key(cells.GetConnectivityArray())]
    if ds.IsA("vtkUnstructuredGrid"):
        key.append(_array_key(cell_types_array(ds)))
    return tuple(key)


class RebuildOnChange:
    """Mixin of the cell locators: ``_build()`` builds the tree (the class's ``_build_tree()``) and
    keeps the data set's fingerprint from just before it; ``_sync()``, called first by every query,
    rebuilds if the fingerprint changed since. ``builds`` counts the builds."""

    def _build(self) -> None:
        state = fingerprint(self.dataset)
        self._build_tree()
        self._state = state
        self.builds += 1

    def _sync(self) -> None:
        """Rebuild first if the data set changed since the last build."""
        if fingerprint(self.dataset) != self._state:
            self._build()

"""A data set's cells as flat arrays: points, offsets, connectivity and VTK cell types.

What the engine extension takes (``matrixtree._engine``) and what interpolation over located
cells reads (``matrixtree.filters``): the cells in the data set's own order, so that cell ids and
weight columns are the data set's (a vtkPolyData's cells run verts, lines, polys, strips).

Not public API.
"""

from __future__ import annotations

import numpy as np
from vtkmodules.util.numpy_support import vtk_to_numpy
from vtkmodules.vtkCommonCore import vtkVersion

# VTK cell type codes of a vtkPolyData's cells, by the number of points of the cell.
_VERTEX, _POLY_VERTEX, _LINE, _POLY_LINE, _TRIANGLE, _STRIP, _POLYGON, _QUAD = 1, 2, 3, 4, 5, 6, 7, 9


# VTK 9.6 turned vtkUnstructuredGrid::GetCellTypes() into the types array's getter (and
# deprecated GetCellTypesArray); before, GetCellTypes filled a vtkCellTypes argument.
_TYPES_GETTER = ("GetCellTypes" if (vtkVersion.GetVTKMajorVersion(), vtkVersion.GetVTKMinorVersion()) >= (9, 6)
                 else "GetCellTypesArray")


def cell_types_array(ug):
    """A vtkUnstructuredGrid's cell types array (vtkUnsignedCharArray, or None), in any VTK."""
    return getattr(ug, _TYPES_GETTER)()


def _offsets_connectivity(cells):
    """A vtkCellArray's offsets and connectivity as int64 arrays (empty for None)."""
    if cells is None:
        return np.zeros(1, np.int64), np.zeros(0, np.int64)
    off = vtk_to_numpy(cells.GetOffsetsArray()).astype(np.int64)
    conn = vtk_to_numpy(cells.GetConnectivityArray()).astype(np.int64)
    return (off if len(off) else np.zeros(1, np.int64)), conn


def points_of(ds) -> np.ndarray:
    """The data set's points as an (n, 3) float64 array ((0, 3) for none)."""
    pts = ds.GetPoints()
    if pts is None or pts.GetData() is None:
        return np.zeros((0, 3))
    return np.ascontiguousarray(vtk_to_numpy(pts.GetData()), dtype=np.float64).reshape(-1, 3)


def _polydata_types(kind: int, size: np.ndarray) -> np.ndarray:
    """The VTK cell types of a vtkPolyData's verts (0), lines (1), polys (2) or strips (3), as
    vtkPolyData::GetCellType reports them from the cells' sizes."""
    if kind == 0:
        return np.where(size == 1, _VERTEX, _POLY_VERTEX).astype(np.uint8)
    if kind == 1:
        return np.where(size == 2, _LINE, _POLY_LINE).astype(np.uint8)
    if kind == 2:
        return np.select([size == 3, size == 4], [_TRIANGLE, _QUAD], _POLYGON).astype(np.uint8)
    return np.full(len(size), _STRIP, np.uint8)


def cell_arrays(ds):
    """Points (n, 3) float64, offsets and connectivity (int64) and VTK cell types (uint8) of the
    cells of any data set, in its cell order (a vtkPolyData's: verts, lines, polys, strips)."""
    if ds.IsA("vtkPolyData"):
        offsets, conn, types, base = [np.zeros(1, np.int64)], [], [], 0
        for kind, cells in enumerate((ds.GetVerts(), ds.GetLines(), ds.GetPolys(), ds.GetStrips())):
            off, c = _offsets_connectivity(cells)
            types.append(_polydata_types(kind, np.diff(off)))
            offsets.append(off[1:] + base)
            conn.append(c)
            base += len(c)
        return (points_of(ds), np.concatenate(offsets), np.concatenate(conn),
                np.concatenate(types) if types else np.zeros(0, np.uint8))
    if not ds.IsA("vtkUnstructuredGrid"):
        import pyvista as pv

        ds = pv.wrap(ds).cast_to_unstructured_grid()
    off, conn = _offsets_connectivity(ds.GetCells() if ds.GetNumberOfCells() else None)
    types = cell_types_array(ds)
    types = vtk_to_numpy(types).astype(np.uint8) if types is not None else np.zeros(0, np.uint8)
    return points_of(ds), off, conn, types


def surface_arrays(pd):
    """Points, the polys' and the strips' offsets and connectivity, and the cell id of the
    first polygon (after the verts and lines) of a vtkPolyData, as engine.SurfaceTree takes them."""
    poly_off, poly_conn = _offsets_connectivity(pd.GetPolys())
    strip_off, strip_conn = _offsets_connectivity(pd.GetStrips())
    return (points_of(pd), poly_off, poly_conn, strip_off, strip_conn,
            pd.GetNumberOfVerts() + pd.GetNumberOfLines())

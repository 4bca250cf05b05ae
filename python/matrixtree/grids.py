"""Reading volume grids (unstructured CFD meshes) into ``vtkUnstructuredGrid``."""

from __future__ import annotations

import os

import numpy as np
from vtkmodules.util.numpy_support import numpy_to_vtk, numpy_to_vtkIdTypeArray
from vtkmodules.vtkCommonDataModel import vtkCellArray, vtkUnstructuredGrid

from matrixtree._readers import check_not_empty
from matrixtree._util import VtkErrors, existing_file, run_reader, vtk_points

# meshio cell type -> (VTK cell type, points per cell)
_MESHIO_TO_VTK = {"tetra": (10, 4), "hexahedron": (12, 8), "wedge": (13, 6), "pyramid": (14, 5),
                  "triangle": (5, 3), "quad": (9, 4), "tetra10": (24, 10), "hexahedron20": (25, 20)}
_VOLUME = {10, 12, 13, 14, 24, 25}


def read_grid(path: str | os.PathLike, volume_only: bool = True) -> vtkUnstructuredGrid:
    """Read an unstructured grid: ``.vtu`` and legacy ``.vtk`` through VTK, Exodus II (``.ex2``,
    ``.exo``) through ``vtkExodusIIReader`` (first block set, merged), anything else (SU2,
    Gmsh, ...) through meshio.

    Parameters
    ----------
    path : str or os.PathLike
    volume_only : bool, default: True
        Keep only 3-D cells (SU2 files also carry their boundary faces as markers).

    Returns
    -------
    vtkUnstructuredGrid

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    ValueError
        The file is empty, the reader reports an error (the message is the reader's) or crashes,
        runs out of memory or time on it (the readers run in a child process, see
        ``matrixtree._sandbox``), the file holds no supported cells, or a cell refers to a point
        the file does not have.

    Examples
    --------
    >>> import os, matrixtree
    >>> g = matrixtree.read_grid(os.path.join(matrixtree.scenes.data_dir(), "cfd", "brick_hex.su2"))
    >>> g.GetNumberOfCells()
    14079
    """
    from matrixtree import _sandbox

    path = existing_file(path, "grid")
    check_not_empty(path, "grid")
    ext = os.path.splitext(path)[1].lower()
    what = {".vtu": "vtkXMLUnstructuredGridReader", ".ex2": "vtkExodusIIReader", ".exo": "vtkExodusIIReader",
            ".e": "vtkExodusIIReader"}.get(ext, "meshio")
    grid = _sandbox.read("matrixtree.grids.read_grid_here", path, what, "1" if volume_only else "0")
    _sandbox.check_cells(grid, path)
    return grid


def read_grid_here(path: str, volume_only: str = "1") -> vtkUnstructuredGrid:
    """:func:`read_grid`'s reading itself, in this process (matrixtree._sandbox runs it in a child);
    ``volume_only`` as ``"1"`` or ``"0"``."""
    volume_only = volume_only != "0"
    ext = os.path.splitext(path)[1].lower()
    if ext == ".vtu":
        return run_reader(path, "vtkIOXML.vtkXMLUnstructuredGridReader")
    if ext in (".ex2", ".exo", ".e"):
        from vtkmodules.vtkFiltersCore import vtkAppendFilter as Append
        from vtkmodules.vtkIOExodus import vtkExodusIIReader

        r = vtkExodusIIReader()
        r.SetFileName(path)
        r.UpdateInformation()
        for i in range(r.GetNumberOfObjects(r.ELEM_BLOCK)):
            r.SetObjectStatus(r.ELEM_BLOCK, i, 1)
        for i in range(r.GetNumberOfPointResultArrays()):
            r.SetPointResultArrayStatus(r.GetPointResultArrayName(i), 1)
        with VtkErrors(r) as errors:
            r.Update()
        if errors.messages:
            raise ValueError(f"{path}: {errors.last}")
        app = Append()
        app.MergePointsOn()
        mb = r.GetOutput()
        it = mb.NewIterator()
        it.InitTraversal()
        while not it.IsDoneWithTraversal():
            app.AddInputData(it.GetCurrentDataObject())
            it.GoToNextItem()
        app.Update()
        out = vtkUnstructuredGrid()
        out.ShallowCopy(app.GetOutput())
        return out
    import contextlib
    import io
    import logging

    import meshio

    # meshio warns line by line about SU2 marker sections it skips: thousands of lines.
    sink = io.StringIO()
    level = logging.getLogger().level
    logging.getLogger().setLevel(logging.ERROR)
    try:
        with contextlib.redirect_stdout(sink), contextlib.redirect_stderr(sink):
            m = meshio.read(path)
    except (Exception, SystemExit) as e:  # meshio's readers call sys.exit() on some bad files
        why = str(e) or type(e).__name__
        raise ValueError(f"{path}: meshio could not read it: {why}") from None
    finally:
        logging.getLogger().setLevel(level)
    pts = np.ascontiguousarray(np.asarray(m.points, dtype=np.float64))
    if pts.ndim != 2 or pts.shape[1] not in (2, 3):
        raise ValueError(f"{path}: expected 2-D or 3-D points, got an array of shape {pts.shape}")
    if pts.shape[1] == 2:
        pts = np.hstack([pts, np.zeros((len(pts), 1))])
    types, conn, offsets = [], [], [0]
    for block in m.cells:
        if block.type not in _MESHIO_TO_VTK:
            continue
        vtype, npc = _MESHIO_TO_VTK[block.type]
        if volume_only and vtype not in _VOLUME:
            continue
        data = np.asarray(block.data, dtype=np.int64).reshape(-1, npc)
        bad = data[(data < 0) | (data >= len(pts))]
        if bad.size:
            raise ValueError(f"{path}: a {block.type} cell refers to point {int(bad[0])}, but the file has "
                             f"{len(pts)} points")
        types.append(np.full(len(data), vtype, dtype=np.uint8))
        conn.append(data.ravel())
        offsets.append(np.full(len(data), npc, dtype=np.int64))
    if not types:
        raise ValueError(f"{path} holds no supported cells")
    types = np.concatenate(types)
    conn = np.concatenate(conn)
    off = np.concatenate([np.zeros(1, np.int64), np.cumsum(np.concatenate(offsets[1:]))])
    cells = vtkCellArray()
    cells.SetData(numpy_to_vtkIdTypeArray(off, deep=True), numpy_to_vtkIdTypeArray(conn, deep=True))
    g = vtkUnstructuredGrid()
    g.SetPoints(vtk_points(pts))
    g.SetCells(numpy_to_vtk(types, deep=True, array_type=3), cells)  # 3 = VTK_UNSIGNED_CHAR
    return g

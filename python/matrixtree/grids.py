"""Reading volume grids (unstructured CFD meshes) into ``vtkUnstructuredGrid``."""

from __future__ import annotations

import os

import numpy as np
from vtkmodules.vtkCommonDataModel import vtkUnstructuredGrid

from matrixtree._readers import VOLUME_TYPES, check_not_empty, read_su2, unstructured_grid
from matrixtree._util import VtkErrors, existing_file, run_reader

# meshio cell type -> (VTK cell type, points per cell)
_MESHIO_TO_VTK = {"tetra": (10, 4), "hexahedron": (12, 8), "wedge": (13, 6), "pyramid": (14, 5),
                  "triangle": (5, 3), "quad": (9, 4), "tetra10": (24, 10), "hexahedron20": (25, 20)}


def read_grid(path: str | os.PathLike, volume_only: bool = True, zone: int | None = None) -> vtkUnstructuredGrid:
    """Read an unstructured grid: ``.vtu`` and legacy ``.vtk`` through VTK, Exodus II (``.ex2``,
    ``.exo``) through ``vtkExodusIIReader`` (first block set, merged), SU2 (``.su2``, ASCII)
    through the checking reader of ``matrixtree._readers``, anything else (Gmsh, ...) through
    meshio.

    Parameters
    ----------
    path : str or os.PathLike
    volume_only : bool, default: True
        Keep only 3-D cells (SU2 files also carry their boundary faces as markers).
    zone : int, optional
        SU2 only. A multi-zone SU2 file (``NZONE=``) is read, by default, as one grid holding
        every zone: each zone's points after the previous zone's, its cells' point ids shifted to
        match, and a cell array ``zone`` with each cell's ``IZONE`` number. ``zone=k`` reads
        zone ``k`` alone. SU2's high-order (FEM) elements are refused with a ValueError naming
        the line; only linear elements are read.

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
        ``matrixtree._sandbox``), the file holds no supported cells, a cell refers to a point
        the file does not have, or ``zone`` is given for a file that is not SU2 or names a zone
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
    if ext == ".su2":  # pure Python and numpy: nothing that can crash, so in this process
        return read_su2(path, zone=zone, volume_only=volume_only)
    if zone is not None:
        raise ValueError(f"{path}: zone= applies to SU2 files only")
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

    # meshio's readers print warnings line by line (thousands for some formats).
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
        if volume_only and vtype not in VOLUME_TYPES:
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
    return unstructured_grid(pts, np.concatenate(types), np.concatenate(offsets[1:]), np.concatenate(conn))

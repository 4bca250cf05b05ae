"""Reading files with readers that trust them, in a child process.

VTK 9.1's readers (XML, legacy, STL, MetaImage, NIfTI, SLC, Exodus) and meshio were written for
valid files: on damaged ones tests/fuzz/fuzz_readers.py found them segfaulting, aborting on
std::bad_alloc, or allocating and looping for minutes. So a reader function runs in a child
interpreter, under a memory limit (the memory available now) and a time limit
(``$MATRIXTREE_READ_TIMEOUT`` seconds, default 600); the child writes what it read to a VTK XML
file (raw binary, uncompressed) that this process reads back. A crash, a reader error, the memory
or the time limit become a ValueError naming the file and what happened. What comes back is only
what a VTK writer could write, and :func:`check_cells` then checks every cell's point ids before
any VTK filter touches them.

Not public API.
"""

from __future__ import annotations

import importlib
import os
import signal
import subprocess
import sys
import tempfile

import numpy as np
from vtkmodules.util.numpy_support import vtk_to_numpy

from matrixtree._cellarrays import cell_types_array

_WRITERS = {"vtkPolyData": ("vtkXMLPolyDataWriter", "vtkXMLPolyDataReader", ".vtp"),
            "vtkUnstructuredGrid": ("vtkXMLUnstructuredGridWriter", "vtkXMLUnstructuredGridReader", ".vtu"),
            "vtkImageData": ("vtkXMLImageDataWriter", "vtkXMLImageDataReader", ".vti"),
            "vtkStructuredPoints": ("vtkXMLImageDataWriter", "vtkXMLImageDataReader", ".vti")}
_READER_ERROR = 3  # the child's exit status when the reader reported an error (message on stdout)


def timeout() -> float:
    return float(os.environ.get("MATRIXTREE_READ_TIMEOUT", "600"))


def _limit_memory() -> None:  # runs in the child before exec
    import resource

    from matrixtree._checks import available_memory

    have = available_memory()
    if have:
        limit = max(have, 2 << 30)  # address space: the interpreter and VTK map ~1 GiB of their own
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))


def read(function: str, path: str, what: str, *args):
    """``function(path, *args)`` (a ``"module.name"`` returning a VTK data set; ``args`` as
    strings) run in a child process; its result, read back. ValueError if the child fails in any
    way, naming ``what`` read (``"vtkPLYReader"``, ``"meshio"``)."""
    with tempfile.TemporaryDirectory(prefix="matrixtree_read_") as tmp:
        out = os.path.join(tmp, "data")
        cmd = [sys.executable, "-m", "matrixtree._sandbox", function, path, out, *map(str, args)]
        try:
            p = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout(), preexec_fn=_limit_memory)
        except subprocess.TimeoutExpired:
            raise ValueError(f"{path}: reading it took longer than {timeout():g} s (a damaged file, or one declaring "
                             "far more data than it holds; $MATRIXTREE_READ_TIMEOUT sets the limit)") from None
        if p.returncode == _READER_ERROR:
            raise ValueError(f"{path}: {p.stdout.strip()}")
        if p.returncode != 0:
            if p.returncode < 0:
                how = f"crashed ({signal.Signals(-p.returncode).name})"
            elif "MemoryError" in p.stderr or "bad_alloc" in p.stderr:
                how = "ran out of memory"
            else:
                how = f"failed (exit status {p.returncode}: {p.stderr.strip()[-300:]})"
            raise ValueError(f"{path}: {what} {how} reading this file: it is damaged, or not in the format its "
                             "name says")
        kind, ext = p.stdout.split()
        reader_name = _WRITERS[kind][1]
        reader = getattr(importlib.import_module("vtkmodules.vtkIOXML"), reader_name)()
        reader.SetFileName(out + ext)
        reader.Update()
        return reader.GetOutput()


def check_cells(ds, path: str) -> None:
    """ValueError unless every cell array of ``ds`` (a polydata's verts, lines, polys and strips;
    an unstructured grid's cells, types and polyhedron faces) is consistent and refers only to
    existing points: VTK's filters index points by these ids unchecked."""
    n = ds.GetNumberOfPoints()
    arrays = []
    if ds.IsA("vtkPolyData"):
        arrays = [("vertex", ds.GetVerts()), ("line", ds.GetLines()), ("polygon", ds.GetPolys()),
                  ("strip", ds.GetStrips())]
    elif ds.IsA("vtkUnstructuredGrid"):
        arrays = [("cell", ds.GetCells())]
        types = cell_types_array(ds)
        if ds.GetCells() is not None and (types is None or types.GetNumberOfTuples() != ds.GetNumberOfCells()):
            raise ValueError(f"{path}: the grid has {ds.GetNumberOfCells()} cells but "
                             f"{0 if types is None else types.GetNumberOfTuples()} cell types")
    for what, cells in arrays:
        if cells is None or cells.GetNumberOfCells() == 0:
            continue
        _check_cell_array(cells, n, what, "points", path)
    if not ds.IsA("vtkUnstructuredGrid"):
        return
    if hasattr(ds, "GetFaces"):  # VTK < 9.4: one id stream per polyhedron
        faces = ds.GetFaces()
        if faces is not None and faces.GetNumberOfTuples():
            _check_faces(vtk_to_numpy(faces).astype(np.int64), vtk_to_numpy(ds.GetFaceLocations()).astype(np.int64),
                         n, path)
        return
    faces, locations = ds.GetPolyhedronFaces(), ds.GetPolyhedronFaceLocations()  # VTK >= 9.4: two cell arrays
    if faces is not None and faces.GetNumberOfCells():
        _check_cell_array(faces, n, "polyhedron face", "points", path)
        if locations is not None:
            _check_cell_array(locations, faces.GetNumberOfCells(), "polyhedron", "faces", path)


def _check_cell_array(cells, n: int, what: str, items: str, path: str) -> None:
    """ValueError unless ``cells`` (a vtkCellArray) has consistent offsets and every id in [0, n)."""
    off = vtk_to_numpy(cells.GetOffsetsArray()).astype(np.int64)
    conn = vtk_to_numpy(cells.GetConnectivityArray()).astype(np.int64)
    if off[0] != 0 or off[-1] != len(conn) or np.any(np.diff(off) < 0):
        raise ValueError(f"{path}: the {what} offsets are inconsistent (damaged file)")
    bad = np.flatnonzero((conn < 0) | (conn >= n))
    if bad.size:
        cell = int(np.searchsorted(off, bad[0], side="right")) - 1
        raise ValueError(f"{path}: {what} {cell} refers to {items[:-1]} {int(conn[bad[0]])}, but there are {n} {items}")


def _check_faces(stream: np.ndarray, locations: np.ndarray, n: int, path: str) -> None:
    """A polyhedron face stream: per polyhedron (location >= 0) nfaces, then per face npts and ids."""
    for cell, at in enumerate(locations):
        if at < 0:
            continue
        if at >= len(stream) or stream[at] < 0:
            raise ValueError(f"{path}: polyhedron {cell}'s faces lie outside the face stream (damaged file)")
        k = at + 1
        for _ in range(int(stream[at])):
            if k >= len(stream) or stream[k] < 0 or k + 1 + stream[k] > len(stream):
                raise ValueError(f"{path}: polyhedron {cell}'s faces run past the face stream (damaged file)")
            ids = stream[k + 1:k + 1 + stream[k]]
            if np.any((ids < 0) | (ids >= n)):
                raise ValueError(f"{path}: a face of polyhedron {cell} refers to a point beyond the {n} points")
            k += 1 + int(stream[k])


def _child(function: str, path: str, out: str, *args) -> int:
    import logging

    from vtkmodules.vtkCommonCore import vtkObject

    logging.disable(logging.CRITICAL)
    vtkObject.GlobalWarningDisplayOff()  # the parent reports; VTK's own printing only duplicates it
    module, name = function.rsplit(".", 1)
    try:
        data = getattr(importlib.import_module(module), name)(path, *args)
    except ValueError as e:
        print(str(e).replace(f"{path}: ", "", 1))
        return _READER_ERROR
    kind = next((k for k in _WRITERS if data.IsA(k)), None)
    if kind is None:
        print(f"the reader returned a {data.GetClassName()}, which cannot be passed on")
        return _READER_ERROR
    writer_name, _, ext = _WRITERS[kind]
    writer = getattr(importlib.import_module("vtkmodules.vtkIOXML"), writer_name)()
    writer.SetInputData(data)
    writer.SetFileName(out + ext)
    writer.SetDataModeToAppended()
    writer.EncodeAppendedDataOff()
    writer.SetCompressorTypeToNone()
    if not writer.Write():
        print("the data read could not be passed on (writing it failed)")
        return _READER_ERROR
    print(kind, ext)
    return 0


if __name__ == "__main__":
    sys.exit(_child(*sys.argv[1:]))

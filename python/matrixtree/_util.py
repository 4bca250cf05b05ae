"""Private helpers of the matrixtree modules: argument checks, numpy to VTK conversion, file
readers picked by extension, and VTK error messages turned into Python exceptions.

Not public API: the public functions and classes re-export nothing from here.
"""

from __future__ import annotations

import importlib
import os

import numpy as np
from vtkmodules.util.misc import calldata_type
from vtkmodules.util.numpy_support import numpy_to_vtk
from vtkmodules.vtkCommonCore import VTK_STRING, vtkPoints

from matrixtree import _checks

TREES = {"octree": 0, "kdtree": 1}
# vtkMatrixTree's TreeType: the matrix trees and the split-plane / hybrid trees (docs/trees.md).
RAY_TREES = {"octree": 0, "kdtree": 1, "implicit-kd": 2, "bsp": 3, "hybrid": 4}
SPLIT_TREES = ("implicit-kd", "bsp")
BACKENDS = ("cpu", "opencl")


def tree_type(tree: str, trees: dict = TREES) -> int:
    """The VTK classes' TreeType value of a name of ``trees`` (default: ``"octree"`` or
    ``"kdtree"``, the cell locator's); ValueError otherwise."""
    try:
        return trees[tree]
    except (KeyError, TypeError):
        raise ValueError(f"tree must be one of {sorted(trees)}, got {tree!r}") from None


def check_backend(backend: str) -> str:
    """``backend`` itself if it is ``"cpu"`` or ``"opencl"``; ValueError otherwise."""
    if backend not in BACKENDS:
        raise ValueError(f"backend must be 'cpu' or 'opencl', got {backend!r}")
    return backend


def points3(a, name: str) -> np.ndarray:
    """``a`` as a C-contiguous float64 array of shape (N, 3); a single point becomes (1, 3).

    ValueError, naming the argument ``name``, for any other shape.
    """
    try:
        arr = np.ascontiguousarray(np.asarray(a, dtype=np.float64))
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be an (N, 3) array of numbers") from None
    if arr.ndim == 1 and arr.size == 3:
        arr = arr.reshape(1, 3)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ValueError(f"{name} must have shape (N, 3), got {arr.shape}")
    return arr


def segments(origins, directions, ends, length: float):
    """Segment starts and ends as (N, 3) arrays: ``origins`` to ``ends``, or to
    ``origins + length * directions`` (exactly one of the two; ValueError otherwise)."""
    o = points3(origins, "origins")
    if (directions is None) == (ends is None):
        raise ValueError("give exactly one of directions and ends")
    if ends is not None:
        e = points3(ends, "ends")
    else:
        e = o + _checks.real(length, "length", 0.0, lo_open=True) * points3(directions, "directions")
    if e.shape != o.shape:
        raise ValueError(f"origins {o.shape} and ends/directions {e.shape} differ in shape")
    return o, np.ascontiguousarray(e)


def bounds6(bounds) -> list:
    """``(xmin, xmax, ymin, ymax, zmin, zmax)`` as six floats; ValueError otherwise."""
    try:
        b = np.asarray(bounds, dtype=np.float64).ravel()
    except (TypeError, ValueError):
        b = np.zeros(0)
    if b.shape != (6,) or np.isnan(b).any():
        raise ValueError(f"bounds must be (xmin, xmax, ymin, ymax, zmin, zmax), got {bounds!r}")
    return b.tolist()


def vtk_points(arr: np.ndarray) -> vtkPoints:
    """A ``vtkPoints`` holding a copy of an (N, 3) array (its dtype kept: float64 stays double)."""
    pts = vtkPoints()
    pts.SetData(numpy_to_vtk(np.ascontiguousarray(arr), deep=True))
    return pts


def existing_file(path, kind: str) -> str:
    """``path`` as a str; FileNotFoundError saying ``no such <kind> file`` if it does not exist."""
    path = os.fspath(path)
    if not os.path.exists(path):
        raise FileNotFoundError(f"no such {kind} file: {path}")
    return path


def run_reader(path: str, name: str):
    """Run the VTK reader ``name`` (``"module.Class"`` under ``vtkmodules``, imported now) on
    ``path`` in this process and return its output; ValueError with the reader's message if it
    reports an error. Untrusted files go through :func:`read_by_extension` instead."""
    module, cls = name.rsplit(".", 1)
    reader = getattr(importlib.import_module("vtkmodules." + module), cls)()
    reader.SetFileName(path)
    with VtkErrors(reader) as errors:
        reader.Update()
    if errors.messages:
        raise ValueError(f"{path}: {errors.last}")
    return reader.GetOutput()


def read_by_extension(path: str, readers: dict, unsupported: str):
    """Run the reader that ``readers`` names for the end of ``path`` (see :func:`run_reader`) in
    a child process (matrixtree._sandbox: VTK's readers crash on damaged files), and check the
    cells it read.

    ``readers`` maps lower-case file endings (``".ply"``, ``".nii.gz"``) to reader names; a path
    with none of them raises ValueError with the message ``unsupported``, before any reading.
    """
    from matrixtree import _sandbox

    low = path.lower()
    for ending, name in readers.items():
        if low.endswith(ending):
            out = _sandbox.read("matrixtree._util.run_reader", path, name.rsplit(".", 1)[1], name)
            _sandbox.check_cells(out, path)
            return out
    raise ValueError(unsupported)


class VtkErrors:
    """Collects the ``vtkErrorMacro`` messages one VTK object reports while the block runs.

    ``with VtkErrors(obj) as errors: obj.Update()``; afterwards ``errors.messages`` holds each
    message without VTK's ``ERROR: In file, line N`` and ``vtkClass (0x...): `` prefixes, and
    ``errors.last`` the last one (or None). The observer is removed when the block ends.
    """

    def __init__(self, obj):
        self.obj = obj
        self.messages: list[str] = []
        self._tag = None

    @property
    def last(self) -> str | None:
        return self.messages[-1] if self.messages else None

    def __enter__(self) -> "VtkErrors":
        @calldata_type(VTK_STRING)
        def on_error(_obj, _event, message):
            lines = [ln.strip() for ln in str(message).strip().splitlines()]
            if lines and lines[0].startswith("ERROR: In "):  # "ERROR: In file, line N"
                lines = lines[1:]
            text = " ".join(ln for ln in lines if ln)
            self.messages.append(text.split("): ", 1)[1] if text.startswith("vtk") and "): " in text else text)

        self._tag = self.obj.AddObserver("ErrorEvent", on_error)
        return self

    def __exit__(self, *exc) -> None:
        self.obj.RemoveObserver(self._tag)

    def raise_last(self, exc: type = RuntimeError, hint: str = "") -> None:
        """Raise ``exc(last message + hint)`` if the block reported an error."""
        if self.messages:
            raise exc(self.last + hint)

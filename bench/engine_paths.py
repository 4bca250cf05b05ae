#!/usr/bin/env python3
"""The two Python paths to one tree: the engine extension (matrixtree_engine, what ``pip install .``
builds, no VTK) against the VTK module (matrixtree_vtk's vtkMatrixTreeLocator through
matrixtree.CellLocator), same grid, same seeded points and segments, in the project's .venv.

    .venv/bin/python bench/engine_paths.py [--grid FILE ...] [--points N] [--segments N]
                                           [--repeats R] [--threads T] [--json OUT]

JSON (default out/engine_paths.json): machine, load average, settings, and per grid and query the
rows of the table.

Per grid and query (build, locate with weights, first hit of segments, closest points): the two
paths run alternately, R times each (the order flips every repetition), and the table gives each
path's median wall time and the median of the per-repetition ratios engine / VTK module (below 1:
the engine path is faster). Both include their Python-side conversions (numpy in, numpy out), as
a caller sees them. With no --grid: every CFD grid in ../shared/data/cfd and the bunny.
"""

from __future__ import annotations

import argparse
import glob
import os
import statistics
import time

import numpy as np

from _common import machine, read_any, table, write_outputs
import matrixtree
import matrixtree_engine
from vtkmodules.util.numpy_support import vtk_to_numpy
from vtkmodules.vtkCommonDataModel import vtkUnstructuredGrid


def cell_arrays(ds):
    """points, offsets, connectivity, types of a grid or of a polygon-only surface."""
    pts = vtk_to_numpy(ds.GetPoints().GetData()).astype(np.float64)
    ca = ds.GetCells() if isinstance(ds, vtkUnstructuredGrid) else ds.GetPolys()
    off = vtk_to_numpy(ca.GetOffsetsArray()).astype(np.int64)
    conn = vtk_to_numpy(ca.GetConnectivityArray()).astype(np.int64)
    if isinstance(ds, vtkUnstructuredGrid):
        types = vtk_to_numpy(ds.GetCellTypesArray()).astype(np.uint8)
    else:
        size = np.diff(off)
        types = np.where(size == 3, 5, np.where(size == 4, 9, 7)).astype(np.uint8)
    return pts, off, conn, types


def paired(fa, fb, repeats):
    """Alternate fa and fb (order flipped each repetition): medians of each and of ta / tb."""
    ta, tb = [], []
    for r in range(repeats):
        for f, out in ((fa, ta), (fb, tb)) if r % 2 == 0 else ((fb, tb), (fa, ta)):
            t0 = time.perf_counter()
            f()
            out.append((time.perf_counter() - t0) * 1e3)
    return statistics.median(ta), statistics.median(tb), statistics.median(a / b for a, b in zip(ta, tb))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--grid", nargs="*")
    ap.add_argument("--points", type=int, default=200000)
    ap.add_argument("--segments", type=int, default=20000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--threads", type=int, default=0)
    ap.add_argument("--json", default=os.path.join("out", "engine_paths.json"))
    a = ap.parse_args()
    data = matrixtree.scenes.data_dir()
    grids = a.grid or sorted(glob.glob(os.path.join(data, "cfd", "*.su2"))) + \
        sorted(glob.glob(os.path.join(data, "cfd", "*.vtu"))) + [os.path.join(data, "meshes", "bunny.ply")]
    rows = []
    for path in grids:
        ds = read_any(path)
        arrays = cell_arrays(ds)
        b = np.array(ds.GetBounds()).reshape(3, 2)
        rng = np.random.default_rng(1)
        x = rng.uniform(b[:, 0], b[:, 1], (a.points, 3))
        p1 = rng.uniform(b[:, 0], b[:, 1], (a.segments, 3))
        p2 = p1 + rng.normal(size=(a.segments, 3)) * 0.25 * np.linalg.norm(b[:, 1] - b[:, 0])
        q = rng.uniform(b[:, 0], b[:, 1], (a.segments, 3))
        eng = matrixtree_engine.CellLocator(*arrays, threads=a.threads)
        ref = matrixtree.CellLocator(ds, threads=a.threads)
        queries = {
            "build": (lambda: matrixtree_engine.CellLocator(*arrays, threads=a.threads),
                      lambda: matrixtree.CellLocator(ds, threads=a.threads)),
            "locate+weights": (lambda: eng.find_cells(x, weights=True),
                               lambda: ref.locate(x, return_weights=True)),
            "first hits": (lambda: eng.first_hits(p1, p2), lambda: ref.trace(p1, ends=p2)),
            "closest points": (lambda: eng.closest_points(q), lambda: ref.closest_points(q)),
        }
        for name, (fe, fv) in queries.items():
            te, tv, ratio = paired(fe, fv, a.repeats)
            rows.append({"grid": os.path.basename(path), "cells": ds.GetNumberOfCells(), "query": name,
                         "engine_ms": te, "vtk_module_ms": tv, "ratio_engine_over_vtk": ratio})
        print(table(rows[-len(queries):], ["grid", "cells", "query", "engine_ms", "vtk_module_ms",
                                           "ratio_engine_over_vtk"]), flush=True)
    os.makedirs(os.path.dirname(a.json) or ".", exist_ok=True)
    write_outputs(a.json, {"machine": machine(), "load": os.getloadavg(), "points": a.points,
                           "segments": a.segments, "repeats": a.repeats, "threads": a.threads, "rows": rows},
                  None, rows, [])


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Memory of vtkMatrixTreeLocator next to vtkStaticCellLocator's, per grid or mesh, and the query
cost of reading the cell arrays in place.

    .venv/bin/python bench/locator_memory.py [--grid FILE ...] [--meshes] [--all] [--build-dir DIR]
                                             [--ab ROUNDS] [--points N] [--rays N] [--json OUT]

Grids and meshes are chosen and read as bench/locator_phases.py does (no --grid: every CFD grid;
surfaces as triangle polydata). Per data set and locator (matrix-octree with each CellStorage,
vtkStaticCellLocator), built once on one thread:
- bytes: GetMemorySize() (ours); static_est: vtkStaticCellLocator's estimate from its layout
  (bench/locator_phases.py's static_bytes, as the C++ driver computes it);
- held: what the build left allocated, measured with glibc's mallinfo2 (bytes in use after the
  build minus before it): everything the locator holds, counted or not.
With --ab ROUNDS: FindCells (--points uniform points in the bounds) and IntersectSegments
(--rays segments, tolerance 0) of two locators in the same process, CELLS_COPIED and
CELLS_IN_PLACE, alternated ROUNDS times and timed by the thread's CPU time; the columns are the
medians of copied/in-place time (below 1: in place is slower) and their quartiles.
"""

from __future__ import annotations

import argparse
import ctypes
import gc
import glob
import os
import statistics
import sys
import time


def parse() -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--grid", action="append")
    p.add_argument("--meshes", action="store_true")
    p.add_argument("--all", action="store_true")
    p.add_argument("--build-dir", default=None)
    p.add_argument("--ab", type=int, default=0, help="rounds of the in-place/copied query comparison (0: none)")
    p.add_argument("--points", type=int, default=100000)
    p.add_argument("--rays", type=int, default=5000)
    p.add_argument("--json", default=None)
    return p.parse_args()


class _MallInfo2(ctypes.Structure):
    _fields_ = [(n, ctypes.c_size_t) for n in
                ("arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks", "fsmblks", "uordblks", "fordblks",
                 "keepcost")]


def malloc_in_use() -> int:
    libc = ctypes.CDLL("libc.so.6")
    libc.mallinfo2.restype = _MallInfo2
    m = libc.mallinfo2()
    return int(m.uordblks + m.hblkhd)


def main() -> int:
    a = parse()
    bd = a.build_dir or os.environ.get("MATRIXTREE_BUILD_DIR")
    if bd:
        sys.path.insert(0, os.path.join(os.path.abspath(bd), "python"))
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    import numpy as np
    from _common import check_build_dir, table, write_json
    check_build_dir(bd)
    from locator_phases import read_any, static_bytes
    from matrixtree import scenes
    from matrixtree_vtk import vtkMatrixTreeLocator
    from vtkmodules.util.numpy_support import numpy_to_vtk
    from vtkmodules.vtkCommonCore import vtkDoubleArray, vtkIdTypeArray, vtkPoints, vtkSMPTools
    from vtkmodules.vtkCommonDataModel import vtkStaticCellLocator
    vtkSMPTools.Initialize(1)

    folders = ["cfd", "meshes"] if a.all else (["meshes"] if a.meshes else ["cfd"])
    paths = a.grid or sorted(p for f in folders for p in glob.glob(os.path.join(scenes.data_dir(), f, "*.*"))
                             if not p.endswith(".txt"))
    storages = [("automatic", vtkMatrixTreeLocator.CELLS_AUTOMATIC),
                ("in place", vtkMatrixTreeLocator.CELLS_IN_PLACE),
                ("copied", vtkMatrixTreeLocator.CELLS_COPIED)]
    rows = []
    for path in paths:
        ds = read_any(path)
        name = os.path.basename(path)

        def held(make):
            gc.collect()
            before = malloc_in_use()
            loc = make()
            gc.collect()
            return loc, malloc_in_use() - before

        def matrix(storage):
            loc = vtkMatrixTreeLocator()
            loc.SetDataSet(ds)
            loc.SetNumberOfThreads(1)
            loc.SetCellStorage(storage)
            loc.BuildLocator()
            return loc

        def static():
            st = vtkStaticCellLocator()
            st.SetDataSet(ds)
            st.BuildLocator()
            return st

        st, st_held = held(static)
        st_est = static_bytes(ds, st)
        del st
        locs = {}
        for label, storage in storages:
            loc, h = held(lambda: matrix(storage))
            rows.append({"grid": name, "cells": ds.GetNumberOfCells(), "locator": "matrix-octree " + label,
                         "bytes": loc.GetMemorySize(), "held": h, "static_est": st_est, "static_held": st_held,
                         "bytes_ratio": round(loc.GetMemorySize() / st_est, 3), "held_ratio": round(h / st_held, 3)})
            locs[label] = loc
        if a.ab > 0:
            rng = np.random.default_rng(1)
            b = np.array(ds.GetBounds()).reshape(3, 2)
            x = b[:, 0] + rng.random((a.points, 3)) * (b[:, 1] - b[:, 0])
            pts = vtkPoints()
            pts.SetData(numpy_to_vtk(x, deep=True))
            d = rng.normal(size=(a.rays, 3))
            d /= np.linalg.norm(d, axis=1)[:, None]
            p1 = numpy_to_vtk(x[:a.rays].copy(), deep=True)
            p2 = numpy_to_vtk(x[:a.rays] + 0.5 * np.linalg.norm(b[:, 1] - b[:, 0]) * d, deep=True)
            ids = vtkIdTypeArray()

            def find(loc):
                t0 = time.thread_time()
                loc.FindCells(pts, ids)
                return time.thread_time() - t0

            def rays(loc):
                t, c = vtkDoubleArray(), vtkIdTypeArray()
                t0 = time.thread_time()
                loc.IntersectSegments(p1, p2, 0.0, t, c)
                return time.thread_time() - t0

            for loc in locs.values():
                loc.SetNumberOfThreads(1)
            inplace, copied = locs["in place"], locs["copied"]
            fr, rr = [], []
            for r in range(a.ab):
                order = (inplace, copied) if r % 2 == 0 else (copied, inplace)
                tf = {id(loc): find(loc) for loc in order}
                tr = {id(loc): rays(loc) for loc in order}
                fr.append(tf[id(copied)] / tf[id(inplace)])
                rr.append(tr[id(copied)] / tr[id(inplace)])
            q = lambda v, p: round(float(np.percentile(v, p)), 3)  # noqa: E731
            rows[-1].update({"findcell_copied_over_in_place": q(fr, 50), "findcell_q1": q(fr, 25),
                             "findcell_q3": q(fr, 75), "rays_copied_over_in_place": q(rr, 50), "rays_q1": q(rr, 25),
                             "rays_q3": q(rr, 75)})
        del locs
    cols = ["grid", "cells", "locator", "bytes", "held", "static_est", "static_held", "bytes_ratio", "held_ratio"]
    if a.ab > 0:
        cols += ["findcell_copied_over_in_place", "findcell_q1", "findcell_q3", "rays_copied_over_in_place",
                 "rays_q1", "rays_q3"]
    print(table(rows, cols))
    if a.json:
        write_json(a.json, rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())

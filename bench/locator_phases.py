#!/usr/bin/env python3
"""Build phases of vtkMatrixTreeLocator next to vtkStaticCellLocator's build, per grid or mesh.

    .venv/bin/python bench/locator_phases.py [--grid FILE] [--meshes] [--all] [--repeats N]
                                             [--build-dir DIR] [--threads T] [--locator NAME]
                                             [--stat median|min] [--json OUT]

With no --grid it runs every CFD grid in ../shared/data/cfd (--meshes: every surface mesh in
../shared/data/meshes instead, --all: both). A --grid that is a surface (.ply, .obj, .stl, .vtp)
is read with matrixtree.read_mesh, as bench/locators.py does (a triangle vtkPolyData), anything
else with matrixtree.read_grid. --locator (repeatable) keeps only the named configurations
(matrix-octree, matrix-kdtree, matrix-octree-exact). Every locator is built N times
(default 3, FreeSearchStructure in between) with --threads build threads (default 0: the
locator's own rule, one per 1024 cells); every phase of GetBuildPhases() and the total are
the median over the N builds, as is vtkStaticCellLocator's build (--stat min: the fastest of
the N instead, per phase; on a loaded machine a multi-threaded build waits for its second thread
at every parallel region, and the minimum drops most of those waits). The 1-minute load average
is printed with every grid: on a shared machine compare ratios taken in the same run.
--static-threads N runs vtkStaticCellLocator's build (vtkSMPTools) on N threads; by default it
uses VTK's default, as bench/locators.py does (TBB: all cores here, while --threads 1 builds the
matrix trees on one). --build-dir (or $MATRIXTREE_BUILD_DIR) picks the build tree whose python/matrixtree_vtk is
imported (default: the one the .venv's .pth names, build/).
Columns: bytes (GetMemorySize), static_bytes (vtkStaticCellLocator's, estimated from its layout
as bench/cpp/locators_bench.cxx does: VTK 9.1 reports none) and bytes_ratio, references and
references per cell, the tree height.
"""

from __future__ import annotations

import argparse
import glob
import os
import statistics
import sys
import time


def parse() -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--grid", action="append")
    p.add_argument("--meshes", action="store_true", help="the surface meshes instead of the CFD grids")
    p.add_argument("--all", action="store_true", help="the CFD grids and the surface meshes")
    p.add_argument("--locator", action="append",
                   choices=("matrix-octree", "matrix-kdtree", "matrix-octree-exact"))
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--build-dir", default=None)
    p.add_argument("--threads", type=int, default=0,
                   help="SetNumberOfThreads of the matrix locators (default 0: the locator's rule)")
    p.add_argument("--static-threads", type=int, default=0,
                   help="vtkSMPTools threads of vtkStaticCellLocator's build (default 0: VTK's default, as "
                        "bench/locators.py runs it; 1 compares one thread with one thread)")
    p.add_argument("--stat", choices=("median", "min"), default="median",
                   help="statistic over the repeats of every build time and phase (default median)")
    p.add_argument("--json", default=None)
    return p.parse_args()


def static_bytes(ds, st) -> int:
    """vtkStaticCellLocator's memory, estimated from its layout (vtkStaticCellLocator.cxx) as the
    C++ driver does: 6 doubles of bounds per cell, one (cell, bin) fragment of two ids per bin a
    cell's bounds touch, one offset per bin."""
    import numpy as np
    from vtkmodules.util.numpy_support import vtk_to_numpy
    div = list(st.GetDivisions())
    id_bytes = 8 if st.GetLargeIds() else 4
    sb = ds.GetBounds()
    pts = vtk_to_numpy(ds.GetPoints().GetData()).astype(np.float64)
    cells = ds.GetPolys() if hasattr(ds, "GetPolys") else ds.GetCells()
    off = vtk_to_numpy(cells.GetOffsetsArray())
    conn = vtk_to_numpy(cells.GetConnectivityArray())
    seg = off[:-1]
    lo = np.minimum.reduceat(pts[conn], seg, axis=0)
    hi = np.maximum.reduceat(pts[conn], seg, axis=0)
    k = np.ones(len(seg), dtype=np.int64)
    for a in range(3):
        h = (sb[2 * a + 1] - sb[2 * a]) / div[a]

        def bin_of(v):
            i = ((v - sb[2 * a]) / h).astype(np.int64) if h > 0 else np.zeros(len(v), np.int64)
            return np.clip(i, 0, div[a] - 1)
        k *= bin_of(hi[:, a]) - bin_of(lo[:, a]) + 1
    return int(48 * len(seg) + 2 * id_bytes * int(k.sum()) + id_bytes * (div[0] * div[1] * div[2] + 1))


def main() -> int:
    a = parse()
    bd = a.build_dir or os.environ.get("MATRIXTREE_BUILD_DIR")
    if bd:  # before anything imports matrixtree_vtk
        sys.path.insert(0, os.path.join(os.path.abspath(bd), "python"))
    from _common import check_build_dir, print_rows, read_any
    check_build_dir(bd)
    import matrixtree
    from matrixtree import scenes
    from matrixtree_vtk import vtkMatrixTreeLocator
    from vtkmodules.vtkCommonDataModel import vtkStaticCellLocator
    from vtkmodules.vtkCommonCore import vtkSMPTools
    if a.static_threads > 0:
        vtkSMPTools.Initialize(a.static_threads)

    folders = ["cfd", "meshes"] if a.all else (["meshes"] if a.meshes else ["cfd"])
    paths = a.grid or sorted(p for f in folders for p in glob.glob(os.path.join(scenes.data_dir(), f, "*.*"))
                             if not p.endswith(".txt"))
    configs = [("matrix-octree", 0, False), ("matrix-kdtree", 1, False), ("matrix-octree-exact", 0, True)]
    if a.locator:
        configs = [c for c in configs if c[0] in a.locator]
    stat = statistics.median if a.stat == "median" else min
    rows = []
    for path in paths:
        ds = read_any(path)
        load = os.getloadavg()[0]

        def timed(build):
            t0 = time.perf_counter()
            build()
            return (time.perf_counter() - t0) * 1e3

        st = vtkStaticCellLocator()
        st.SetDataSet(ds)

        def build_static():
            st.FreeSearchStructure()
            st.Modified()
            st.BuildLocator()

        static_ms = stat([timed(build_static) for _ in range(a.repeats)])
        st_bytes = static_bytes(ds, st)
        for name, kind, exact in configs:
            loc = vtkMatrixTreeLocator()
            loc.SetDataSet(ds)
            loc.SetTreeType(kind)
            loc.SetExactOverlap(exact)
            loc.SetNumberOfThreads(a.threads)
            phases: dict[str, list] = {}
            calls = []
            for _ in range(a.repeats):
                loc.FreeSearchStructure()
                loc.Modified()
                calls.append(timed(loc.BuildLocator))
                for item in loc.GetBuildPhases().split(";"):
                    key, ms = item.strip().rsplit(" ", 1)
                    phases.setdefault(key, []).append(float(ms))
            row = {"grid": os.path.basename(path), "cells": ds.GetNumberOfCells(), "locator": name,
                   "load1": round(load, 2),
                   "static_threads": vtkSMPTools.GetEstimatedNumberOfThreads(),
                   "height": loc.GetTreeHeight(), "references": loc.GetNumberOfReferences(),
                   "refs_per_cell": loc.GetNumberOfReferences() / max(1, ds.GetNumberOfCells()),
                   "bytes": loc.GetMemorySize(), "static_bytes": st_bytes,
                   "bytes_ratio": loc.GetMemorySize() / st_bytes, "static_ms": static_ms,
                   "build_ms": stat(calls)}
            row["ratio_vs_static"] = row["build_ms"] / static_ms
            row.update({k: stat(v) for k, v in phases.items()})
            rows.append(row)
    print_rows(rows, a.json)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

#!/usr/bin/env python3
"""Memory of vtkMatrixTreeLocator next to vtkStaticCellLocator's, per grid or mesh.

    .venv/bin/python bench/locator_memory.py [--grid FILE ...] [--meshes] [--all] [--build-dir DIR]
                                             [--json OUT]

Grids and meshes are chosen and read as bench/locator_phases.py does (no --grid: every CFD grid;
surfaces as triangle polydata). Per data set and locator (matrix-octree, vtkStaticCellLocator),
built once on one thread:
- bytes: GetMemorySize() (ours); static_est: vtkStaticCellLocator's estimate from its layout
  (bench/locator_phases.py's static_bytes, as the C++ driver computes it);
- held: what the build left allocated, measured with glibc's mallinfo2 (bytes in use after the
  build minus before it): everything the locator holds, counted or not.
The locator reads the cell arrays in place or copies them as vtkMatrixTreeLocatorTuning's
CellStorage says (C++ only); build/bin/locator_ab GRID cells=in_place cells=copied compares the
two, and its table prints each one's GetMemorySize().
"""

from __future__ import annotations

import argparse
import ctypes
import gc
import glob
import os
import sys


def parse() -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--grid", action="append")
    p.add_argument("--meshes", action="store_true")
    p.add_argument("--all", action="store_true")
    p.add_argument("--build-dir", default=None)
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
    from _common import check_build_dir, read_any, table, write_json
    check_build_dir(bd)
    from locator_phases import static_bytes
    from matrixtree import scenes
    from matrixtree_vtk import vtkMatrixTreeLocator
    from vtkmodules.vtkCommonCore import vtkSMPTools
    from vtkmodules.vtkCommonDataModel import vtkStaticCellLocator
    vtkSMPTools.Initialize(1)

    folders = ["cfd", "meshes"] if a.all else (["meshes"] if a.meshes else ["cfd"])
    paths = a.grid or sorted(p for f in folders for p in glob.glob(os.path.join(scenes.data_dir(), f, "*.*"))
                             if not p.endswith(".txt"))
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

        def matrix():
            loc = vtkMatrixTreeLocator()
            loc.SetDataSet(ds)
            loc.SetNumberOfThreads(1)
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
        loc, h = held(matrix)
        rows.append({"grid": name, "cells": ds.GetNumberOfCells(), "locator": "matrix-octree",
                     "bytes": loc.GetMemorySize(), "held": h, "static_est": st_est, "static_held": st_held,
                     "bytes_ratio": round(loc.GetMemorySize() / st_est, 3), "held_ratio": round(h / st_held, 3)})
        del loc
    cols = ["grid", "cells", "locator", "bytes", "held", "static_est", "static_held", "bytes_ratio", "held_ratio"]
    print(table(rows, cols))
    if a.json:
        write_json(a.json, rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())

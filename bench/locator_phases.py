#!/usr/bin/env python3
"""Build phases of vtkMatrixTreeLocator next to vtkStaticCellLocator's build, per grid.

    .venv/bin/python bench/locator_phases.py [--grid FILE] [--repeats N] [--build-dir DIR]
                                             [--sort radix|counting|both] [--json OUT]

With no --grid it runs every CFD grid in ../shared/data/cfd. Every locator is built N times
(default 3, FreeSearchStructure in between) with --threads build threads (default 0: the
locator's own rule, one per 32768 cells); every phase of GetBuildPhases() and the total are
the median over the N builds, as is vtkStaticCellLocator's build. The 1-minute load average is
printed with every grid: on a shared machine compare ratios taken in the same run.
--build-dir (or $MATRIXTREE_BUILD_DIR) picks the build tree whose python/matrixtree_vtk is
imported (default: the one the .venv's .pth names, build/).
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
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--build-dir", default=None)
    p.add_argument("--sort", choices=("radix", "counting", "both", "default"), default="default",
                   help="locator build sort (default: the locator's default)")
    p.add_argument("--threads", type=int, default=0,
                   help="SetNumberOfThreads of the matrix locators (default 0: the locator's rule)")
    p.add_argument("--json", default=None)
    return p.parse_args()


def main() -> int:
    a = parse()
    bd = a.build_dir or os.environ.get("MATRIXTREE_BUILD_DIR")
    if bd:  # before anything imports matrixtree_vtk
        sys.path.insert(0, os.path.join(os.path.abspath(bd), "python"))
    from _common import table, write_json
    import matrixtree
    from matrixtree import scenes
    from matrixtree_vtk import vtkMatrixTreeLocator
    from vtkmodules.vtkCommonDataModel import vtkStaticCellLocator

    paths = a.grid or sorted(p for p in glob.glob(os.path.join(scenes.data_dir(), "cfd", "*.*"))
                             if not p.endswith(".txt"))
    sorts = {"default": [None], "radix": ["radix"], "counting": ["counting"],
             "both": ["radix", "counting"]}[a.sort]
    configs = [("matrix-octree", 0, True), ("matrix-kdtree", 1, True), ("matrix-octree-bbox", 0, False)]
    rows = []
    for path in paths:
        ds = matrixtree.read_grid(path)
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

        static_ms = statistics.median(timed(build_static) for _ in range(a.repeats))
        for name, kind, exact in configs:
            for sort in sorts:
                loc = vtkMatrixTreeLocator()
                loc.SetDataSet(ds)
                loc.SetTreeType(kind)
                loc.SetExactOverlap(exact)
                loc.SetNumberOfThreads(a.threads)
                if sort is not None:
                    loc.SetBuildSort(loc.RADIX if sort == "radix" else loc.COUNTING)
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
                       "strategy": sort or "default", "load1": round(load, 2),
                       "bytes": loc.GetMemorySize(), "static_ms": static_ms,
                       "build_ms": statistics.median(calls)}
                row["ratio_vs_static"] = row["build_ms"] / static_ms
                row.update({k: statistics.median(v) for k, v in phases.items()})
                rows.append(row)
    keys = []
    for r in rows:
        keys += [k for k in r if k not in keys]
    print(table(rows, keys))
    if a.json:
        write_json(a.json, rows)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

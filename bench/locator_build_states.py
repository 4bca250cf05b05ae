#!/usr/bin/env python3
"""A locator's build time depends on what the process did before it: the first build in a fresh
process, the builds right after it, and builds repeated in a warm process. This program times all
three for vtkMatrixTreeLocator (default, bounding-box overlap; and exact overlap) and
vtkStaticCellLocator, each locator alone in a fresh process (no other locator's heap):

    .venv/bin/python bench/locator_build_states.py [--grid FILE ...] [--processes N] [--builds B]
                                                   [--build-dir DIR] [--json OUT]

Each process reads the grid, then builds its one locator B times (default 8), each after
FreeSearchStructure. Per process: first (the first build), cold3 (the median of the first 3:
bench/locators.py's build_ms) and steady (the median of builds 2..B). N processes per locator
and grid (default 3), the locators' order alternating; the table gives each measure's median
over the N and the ratio to vtkStaticCellLocator's. With no --grid: every CFD grid and mesh in
../shared/data (surfaces read as bench/locators.py reads them). --build-dir (or
$MATRIXTREE_BUILD_DIR) picks the build tree whose python/matrixtree_vtk is imported.

--together A,B,...: instead, one process per grid builds the named locators one after the other
in that order, --builds times each, and prints every build time: how a locator's builds change
when another locator ran before it in the same process.
"""

from __future__ import annotations

import argparse
import glob
import json
import os
import statistics
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
LOCATORS = ("vtkStaticCellLocator", "matrix-octree", "matrix-octree-exact")
MEASURES = ("first", "cold3", "steady")


def child(build_dir: str, path: str, names: str, builds: int) -> None:
    """One process, the comma-separated locators in order: prints each one's build times (ms),
    a JSON list per locator."""
    if build_dir:
        sys.path.insert(0, os.path.join(os.path.abspath(build_dir), "python"))
    sys.path.insert(0, HERE)
    from _common import check_build_dir, read_any
    from vtkmodules.vtkCommonDataModel import vtkStaticCellLocator

    check_build_dir(build_dir)
    ds = read_any(path)
    for name in names.split(","):
        if name == "vtkStaticCellLocator":
            loc = vtkStaticCellLocator()
        elif name in ("matrix-octree", "matrix-octree-exact"):
            from matrixtree_vtk import vtkMatrixTreeLocator

            loc = vtkMatrixTreeLocator()
            loc.SetExactOverlap(name == "matrix-octree-exact")
        else:
            raise SystemExit(f"unknown locator {name!r}: one of {', '.join(LOCATORS)}")
        loc.SetDataSet(ds)
        times = []
        for _ in range(builds):
            loc.FreeSearchStructure()
            loc.Modified()
            t0 = time.perf_counter()
            loc.BuildLocator()
            times.append((time.perf_counter() - t0) * 1e3)
        print(json.dumps(times))
        del loc


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--grid", action="append")
    p.add_argument("--processes", type=int, default=3)
    p.add_argument("--builds", type=int, default=8)
    p.add_argument("--build-dir", default=os.environ.get("MATRIXTREE_BUILD_DIR"))
    p.add_argument("--json", default=None)
    p.add_argument("--together", default=None, help="comma-separated locators built in one process, in order")
    p.add_argument("--child", nargs=2, help=argparse.SUPPRESS)
    a = p.parse_args()
    if a.builds < 3:
        p.error("--builds must be at least 3")
    if a.child:
        child(a.build_dir or "", a.child[0], a.child[1], a.builds)
        return 0
    sys.path.insert(0, HERE)
    from _common import print_rows
    from matrixtree import scenes

    d = scenes.data_dir()
    paths = a.grid or sorted(glob.glob(os.path.join(d, "cfd", "*.*")) + glob.glob(os.path.join(d, "meshes", "*.*")))
    paths = [x for x in paths if not x.endswith(".txt")]

    def run(path: str, names: str) -> list:
        cmd = [sys.executable, os.path.abspath(__file__), "--builds", str(a.builds), "--child", path, names]
        if a.build_dir:
            cmd[2:2] = ["--build-dir", a.build_dir]
        out = subprocess.run(cmd, capture_output=True, text=True, check=True).stdout
        return [json.loads(line) for line in out.splitlines()]

    if a.together:
        names = a.together.split(",")
        rows = []
        for path in paths:
            for name, t in zip(names, run(path, a.together)):
                rows.append({"grid": os.path.basename(path), "order": a.together, "locator": name,
                             "builds_ms": " ".join(f"{x:.2f}" for x in t)})
        print_rows(rows, a.json)
        return 0
    samples = {}
    for rep in range(a.processes):
        for path in paths:
            for name in LOCATORS if rep % 2 == 0 else LOCATORS[::-1]:
                t = run(path, name)[0]
                s = samples.setdefault((path, name), {m: [] for m in MEASURES})
                s["first"].append(t[0])
                s["cold3"].append(statistics.median(t[:3]))
                s["steady"].append(statistics.median(t[1:]))
    rows = []
    for path in paths:
        ref = {m: statistics.median(samples[(path, LOCATORS[0])][m]) for m in MEASURES}
        for name in LOCATORS:
            row = {"grid": os.path.basename(path), "locator": name}
            for m in MEASURES:
                v = statistics.median(samples[(path, name)][m])
                row[m + "_ms"] = round(v, 3)
                row[m + "_ratio"] = round(v / ref[m], 3)
            rows.append(row)
    print_rows(rows, a.json)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

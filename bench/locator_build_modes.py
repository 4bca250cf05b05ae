#!/usr/bin/env python3
"""Build time of vtkMatrixTreeLocator and vtkStaticCellLocator in the three ways a build happens,
each locator in its own fresh process, the two alternated, so that neither inherits memory the
other freed (in one process the second locator reuses the heap the first one returned and
builds faster for it: bench/locator_build_states.py --together shows by how much).

    .venv/bin/python bench/locator_build_modes.py [--grid FILE ...] [--rounds N] [--repeats N]
                                                   [--build-dir DIR] [--json OUT]

Modes, per process (one locator, one grid, read before the clock starts):
  cold      the first BuildLocator() of the process: memory new to it, threads started;
  free      BuildLocator() after FreeSearchStructure() and Modified(), min and median of --repeats;
  rebuild   BuildLocator() after the points moved (scaled about the centre by 1 + 1e-3 k), no
            FreeSearchStructure: a deforming mesh's cost per frame; min and median.
faults: minor page faults per build in the free and rebuild modes (getrusage, the process's
own count around the loop). --rounds N (default 3) runs N processes per locator and grid,
alternated, and reports each column's median over the rounds. With no --grid: every CFD grid
in ../shared/data/cfd. Ratios are ours / vtkStaticCellLocator's for the same mode.
"""

from __future__ import annotations

import argparse
import glob
import json
import os
import statistics
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

CHILD = r"""
import json, os, resource, statistics, sys, time
bd, path, name, repeats = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])
if bd:
    sys.path.insert(0, os.path.join(os.path.abspath(bd), "python"))
import matrixtree
from vtkmodules.vtkCommonDataModel import vtkStaticCellLocator
from vtkmodules.vtkCommonCore import vtkPoints
ext = os.path.splitext(path)[1].lower()
ds = matrixtree.read_mesh(path) if ext in (".ply", ".obj", ".stl", ".vtp") else matrixtree.read_grid(path)
if name == "matrix-octree":
    from matrixtree_vtk import vtkMatrixTreeLocator
    loc = vtkMatrixTreeLocator()
else:
    loc = vtkStaticCellLocator()
loc.SetDataSet(ds)

def faults():
    return resource.getrusage(resource.RUSAGE_SELF).ru_minflt

def timed():
    t0 = time.perf_counter()
    loc.BuildLocator()
    return (time.perf_counter() - t0) * 1e3

out = {"cold_ms": timed()}
f0 = faults()
free = []
for _ in range(repeats):
    loc.FreeSearchStructure()
    ds.Modified()
    free.append(timed())
out["free_faults"] = (faults() - f0) / repeats
pts = ds.GetPoints()
orig = vtkPoints()
orig.DeepCopy(pts)
b = ds.GetBounds()
c = [0.5 * (b[0] + b[1]), 0.5 * (b[2] + b[3]), 0.5 * (b[4] + b[5])]
import numpy as np
from vtkmodules.util.numpy_support import vtk_to_numpy
base = vtk_to_numpy(orig.GetData()).astype(np.float64)
view = vtk_to_numpy(pts.GetData())
rebuild = []
f0 = faults()
for k in range(repeats):
    s = 1.0 + 1e-3 * (k + 1)
    view[:] = np.asarray(c) + s * (base - np.asarray(c))
    pts.Modified()
    ds.Modified()
    rebuild.append(timed())
out["rebuild_faults"] = (faults() - f0) / repeats
out.update(free_min_ms=min(free), free_median_ms=statistics.median(free),
           rebuild_min_ms=min(rebuild), rebuild_median_ms=statistics.median(rebuild))
print(json.dumps(out))
"""

LOCATORS = ("matrix-octree", "vtkStaticCellLocator")
MODES = ("cold_ms", "free_min_ms", "free_median_ms", "rebuild_min_ms", "rebuild_median_ms", "free_faults",
         "rebuild_faults")


def parse() -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    p.add_argument("--grid", action="append", help="grid or mesh file (repeatable); default: every CFD grid")
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--repeats", type=int, default=9)
    p.add_argument("--build-dir", default=None)
    p.add_argument("--json", default=None)
    return p.parse_args()


def main() -> int:
    a = parse()
    if a.rounds < 1 or a.repeats < 1:
        raise SystemExit("--rounds and --repeats must be at least 1")
    from _common import print_rows
    from matrixtree import scenes
    bd = a.build_dir or os.environ.get("MATRIXTREE_BUILD_DIR") or ""
    paths = a.grid or sorted(p for p in glob.glob(os.path.join(scenes.data_dir(), "cfd", "*.*"))
                             if not p.endswith(".txt"))
    rows = []
    for path in paths:
        runs = {name: [] for name in LOCATORS}
        for r in range(a.rounds):
            for name in (LOCATORS if r % 2 == 0 else LOCATORS[::-1]):
                res = subprocess.run([sys.executable, "-c", CHILD, bd, path, name, str(a.repeats)],
                                     capture_output=True, text=True)
                if res.returncode != 0:
                    raise SystemExit(f"{name} on {path} failed:\n{res.stderr[-2000:]}")
                runs[name].append(json.loads(res.stdout.strip().splitlines()[-1]))
        load = os.getloadavg()[0]
        med = {name: {k: statistics.median(x[k] for x in runs[name]) for k in MODES} for name in LOCATORS}
        for name in LOCATORS:
            row = {"grid": os.path.basename(path), "locator": name, "rounds": a.rounds, "repeats": a.repeats,
                   "load1": round(load, 2)}
            row.update({k: round(v, 3) for k, v in med[name].items()})
            for k in ("cold_ms", "free_min_ms", "rebuild_min_ms"):
                row[k.replace("_ms", "_ratio")] = round(med[name][k] / med["vtkStaticCellLocator"][k], 3)
            rows.append(row)
        print(f"{os.path.basename(path)}: done", file=sys.stderr)
    print_rows(rows, a.json)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

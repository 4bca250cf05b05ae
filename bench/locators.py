#!/usr/bin/env python3
"""Cell-locator benchmark: vtkMatrixTreeLocator (octree, kd-tree) against vtkStaticCellLocator,
vtkCellLocator, vtkCellTreeLocator and vtkModifiedBSPTree, same grid, same seeded points and
segments, one process per grid (the C++ driver build/bin/locators_bench; a Python loop per
point would measure Python, not the locators).

    .venv/bin/python bench/locators.py [--grid FILE] [--points N] [--rays N] [--json OUT] [--markdown MD]
                                       [--build-dir DIR] [--backend cpu|opencl|all]
                                       [--generated small|bench [--big]] [--locators A,B,...]

With no --grid it runs every CFD grid in ../shared/data/cfd and every mesh in
../shared/data/meshes. --generated SET runs bench/gridgen.py's grids of that set instead
(every nonlinear VTK cell type, curved; graded boundary layers; written once to --grid-dir,
default out/grids/SET), --big adds the 5M-cell boundary layer (out/grids/big). --locators limits
the rows to those locators (vtkStaticCellLocator is always run: the ratios are to it; keep
vtkCellLocator for the disagreements). JSON rows: grid, cells, locator, build_ms (median of 3, each after
FreeSearchStructure), build_first_ms (the first of those 3), rebuild_ms (median of 3 BuildLocator
calls after the points moved, without FreeSearchStructure: a deforming mesh's cost per frame),
all three measured with each locator alone in a fresh process (--build-repeats such processes per
locator, alternating the locators' order, median; default 1): built in the shared process after
other locators, a locator inherits their heap and builds faster (bench/locator_build_states.py
--together shows by how much). The shared process's values are kept as build_ms_shared, build_first_ms_shared, rebuild_ms_shared.
bytes (ours:
GetMemorySize, everything the locator holds; vtkStaticCellLocator: estimated from its layout,
VTK 9.1 reports none; the other VTK locators: -1), findcell_pts_per_s_1thread (findcell_pts_per_cpu_s_1thread: the same loop timed by its
thread's CPU time), findcell_pts_per_s_all,
rays_per_s (segments of a quarter of the diagonal from random points, first hit; rays_per_cpu_s the
same loop timed by its thread's CPU time), findcell_paired_ratio_vs_static and
rays_paired_ratio_vs_static with their quartiles _q1 and _q3 (the one-thread loops run
interleaved, slice by slice, across the locators: the median of vtkStaticCellLocator's CPU time
over this locator's on the same slice, back to back; see bench/cpp/locators_bench.cxx), disagreements
(FindCell answers that do not contain the point, or -1 where vtkCellLocator found a cell),
reference_misses (a containing cell where vtkCellLocator found none), ray_disagreements_vs_static
(hit against miss, or first-hit t more than 1e-9 apart). Matrix-tree rows also carry batch_pts_per_s (the batched FindCells, ids only,
all threads). --backend opencl|all adds the row matrix-octree-opencl (vtkMatrixTreeLocator with
Backend OPENCL; "opencl" drops the CPU matrix rows): its findcell_pts_per_s_* are the batched
FindCells with 1 and all host threads, with device, first_call_ms (upload and, with a cold
PoCL cache, the kernel compile) and its first_call_phases, phases (upload/points/kernel/download/host ms of the last call)
and differs_from_cpu (ids that differ from matrix-octree's, expected 0).
"""

from __future__ import annotations

import argparse
import glob
import json
import os
import statistics
import subprocess
import tempfile

from _common import ROOT, machine, require_driver, table, write_outputs
import matrixtree
from matrixtree import scenes

def driver(build_dir: str | None) -> str:
    """The C++ driver: --build-dir, else $MATRIXTREE_BUILD_DIR, else build/ (scripts/setup.sh)."""
    d = build_dir or os.environ.get("MATRIXTREE_BUILD_DIR") or os.path.join(ROOT, "build")
    return os.path.join(d, "bin", "locators_bench")


def as_vtk_file(path: str, tmp: str) -> str:
    """The driver reads .vtu/.vtp: convert anything else (SU2, Exodus, PLY, OBJ)."""
    ext = os.path.splitext(path)[1].lower()
    if ext in (".vtu", ".vtp"):
        return path
    name = os.path.splitext(os.path.basename(path))[0]
    if ext in (".ply", ".obj", ".stl", ".vtk"):
        from vtkmodules.vtkIOXML import vtkXMLPolyDataWriter as W
        ds, out = matrixtree.read_mesh(path), os.path.join(tmp, name + ".vtp")
    else:
        from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridWriter as W
        ds, out = matrixtree.read_grid(path), os.path.join(tmp, name + ".vtu")
    w = W()
    w.SetFileName(out)
    w.SetInputData(ds)
    w.Write()
    return out


BUILD_KEYS = ("build_ms", "build_first_ms", "rebuild_ms")


def isolate_builds(exe: str, grid_file: str, threads: int, rows: list, repeats: int) -> None:
    """Times each CPU locator's builds alone in a fresh process (no points, no rays), `repeats`
    processes per locator in alternating order; the medians replace build_ms, build_first_ms and
    rebuild_ms, the shared process's values move to *_shared. The OpenCL row builds on the CPU:
    it takes matrix-octree's values."""
    names = [r["locator"] for r in rows if r.get("backend", "cpu") == "cpu"]
    samples = {n: {k: [] for k in BUILD_KEYS} for n in names}
    for rep in range(max(1, repeats)):
        for n in (names if rep % 2 == 0 else names[::-1]):
            out = subprocess.run([exe, grid_file, "0", "0", str(threads), "0", n, "cpu"],
                                 capture_output=True, text=True, check=True).stdout
            for line in out.splitlines():
                r = json.loads(line)
                for k in BUILD_KEYS:
                    samples[r["locator"]][k].append(r.get(k, -1))
    for r in rows:
        src = samples.get(r["locator"] if r.get("backend", "cpu") == "cpu" else "matrix-octree")
        for k in BUILD_KEYS:
            r[k + "_shared"] = r.get(k, -1)
            if src and src[k]:
                r[k] = statistics.median(src[k])


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--grid", action="append")
    p.add_argument("--points", type=int, default=100000)
    p.add_argument("--rays", type=int, default=10000)
    p.add_argument("--threads", type=int, default=os.cpu_count())
    p.add_argument("--json", default="out/bench_locators.json")
    p.add_argument("--markdown", default=None)
    p.add_argument("--backend", choices=("cpu", "opencl", "all"), default="cpu",
                   help="matrix-tree FindCells backend rows (default: cpu)")
    p.add_argument("--build-dir", default=None, help="build tree holding bin/locators_bench (default: "
                   "$MATRIXTREE_BUILD_DIR or build/)")
    p.add_argument("--build-repeats", type=int, default=1,
                   help="fresh processes per locator and grid that time its builds alone (median; default 1)")
    p.add_argument("--generated", choices=("small", "bench"), default=None,
                   help="bench/gridgen.py's grids of this set instead of the shipped ones")
    p.add_argument("--big", action="store_true", help="add bench/gridgen.py's 5M-cell grid")
    p.add_argument("--grid-dir", default=os.path.join(ROOT, "out", "grids"),
                   help="where generated grids are written and reused (default out/grids)")
    p.add_argument("--locators", default="", help="comma-separated locator names (default: all)")
    a = p.parse_args()
    exe = require_driver(driver(a.build_dir))
    only = a.locators
    if only and "vtkStaticCellLocator" not in only.split(","):
        only += ",vtkStaticCellLocator"
    if a.generated or a.big:
        import gridgen
        paths = gridgen.generate(os.path.join(a.grid_dir, a.generated), a.generated) if a.generated else []
        if a.big:
            paths += gridgen.generate(os.path.join(a.grid_dir, "big"), "big")
    else:
        d = scenes.data_dir()
        paths = a.grid or sorted(glob.glob(os.path.join(d, "cfd", "*.*")) + glob.glob(os.path.join(d, "meshes", "*.*")))
    paths = [x for x in paths if not x.endswith(".txt")]
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        try:
            from tqdm import tqdm
            it = tqdm(paths, desc="grids", unit="grid")
        except ImportError:
            it = paths
        for path in it:
            f = as_vtk_file(path, tmp)
            out = subprocess.run([exe, f, str(a.points), str(a.rays), str(a.threads), "0", only, a.backend],
                                 capture_output=True, text=True, check=True).stdout
            grid_rows = [json.loads(line) for line in out.splitlines()]
            for r in grid_rows:
                r["grid"] = os.path.basename(path)
            isolate_builds(exe, f, a.threads, grid_rows, a.build_repeats)
            rows += grid_rows
    # Ratios to vtkStaticCellLocator, VTK's fastest, same run.
    for r in rows:
        s = next(x for x in rows if x["grid"] == r["grid"] and x["locator"] == "vtkStaticCellLocator")
        r["findcell_speedup_vs_static"] = r["findcell_pts_per_s_1thread"] / s["findcell_pts_per_s_1thread"]
        r["rays_speedup_vs_static"] = r["rays_per_s"] / s["rays_per_s"]
        # The same from thread CPU time: robust on a machine shared with other work.
        if r.get("rays_per_cpu_s") and s.get("rays_per_cpu_s"):
            r["rays_cpu_speedup_vs_static"] = r["rays_per_cpu_s"] / s["rays_per_cpu_s"]
        if r.get("findcell_pts_per_cpu_s_1thread") and s.get("findcell_pts_per_cpu_s_1thread"):
            r["findcell_cpu_speedup_vs_static"] = (r["findcell_pts_per_cpu_s_1thread"] /
                                                   s["findcell_pts_per_cpu_s_1thread"])
        # The paired ratios (slice by slice, back to back): what the targets table reads.
        for q in ("findcell", "rays"):
            if r.get(f"{q}_paired_ratio_vs_static", -1) > 0:
                r[f"{q}_paired_speedup_vs_static"] = r[f"{q}_paired_ratio_vs_static"]
        r["build_ratio_vs_static"] = r["build_ms"] / s["build_ms"]
        if r.get("build_first_ms", -1) > 0 and s.get("build_first_ms", -1) > 0:
            r["build_first_ratio_vs_static"] = r["build_first_ms"] / s["build_first_ms"]
        if r.get("build_ms_shared", -1) > 0 and s.get("build_ms_shared", -1) > 0:
            r["build_shared_ratio_vs_static"] = r["build_ms_shared"] / s["build_ms_shared"]
        if r.get("rebuild_ms", -1) > 0 and s.get("rebuild_ms", -1) > 0:
            r["rebuild_ratio_vs_static"] = r["rebuild_ms"] / s["rebuild_ms"]
        r["bytes_ratio_vs_static"] = r["bytes"] / s["bytes"] if r["bytes"] > 0 and s["bytes"] > 0 else -1
        r["machine"] = machine()
    cols = ["grid", "cells", "locator", "backend", "device", "build_ms", "build_first_ms", "rebuild_ms", "bytes", "findcell_pts_per_s_1thread",
            "findcell_pts_per_cpu_s_1thread", "findcell_pts_per_s_all", "batch_pts_per_s", "rays_per_s", "rays_per_cpu_s", "disagreements", "reference_misses", "ray_disagreements_vs_static",
            "differs_from_cpu", "findcell_speedup_vs_static", "findcell_cpu_speedup_vs_static", "findcell_paired_speedup_vs_static",
            "rays_speedup_vs_static", "rays_cpu_speedup_vs_static", "rays_paired_speedup_vs_static",
            "build_ratio_vs_static", "build_first_ratio_vs_static", "build_shared_ratio_vs_static",
            "rebuild_ratio_vs_static", "bytes_ratio_vs_static"]
    print(table(rows, cols))
    write_outputs(a.json, rows, a.markdown, rows, cols)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

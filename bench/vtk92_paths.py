"""What the locator's VTK 9.1-only fast paths are worth: the same queries through the VTK 9.1
build (build/, Debian's VTK, the paths on) and the ParaView plugin's build (build-paraview/,
ParaView's VTK 9.2, where the guards turn them off and every face/cell test is VTK's own).

The paths guarded to 9.1 serve the ray queries (IntersectWithLine: the recomputed vtkTriangle /
vtkQuad face tests, the quad split, the certain-face hits of hexahedra, wedges and tetrahedra);
FindCell's engine evaluation is not guarded (VTK 9.2's EvaluatePosition gives the same bits on
the shipped grids: tests/paraview). Per data set and build: CPU seconds per million queries (one
thread, process_time, median of --repeats) for segments (IntersectSegments) and points
(FindCells), and whether the two builds' answers are identical.

    .venv/bin/python bench/vtk92_paths.py --json out/vtk92_paths.json --md docs/bench_vtk92.md

The driver converts the grids to .vtu (meshio reads SU2 only on the 9.1 side), runs the worker
once in .venv/bin/python and once in pvbatch, and compares.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
SETS = {"brick_hex.su2": "cfd", "brick_prism.su2": "cfd", "pipe_flow_tets.vtu": "cfd", "bunny.ply": "meshes"}


def worker(folder: str, out: str, segments: int, repeats: int) -> None:
    """Runs in either build's Python: the queries on every data set in `folder`, timings and answers."""
    import time

    import numpy as np
    from vtkmodules.util.numpy_support import numpy_to_vtk, vtk_to_numpy
    from vtkmodules.vtkCommonCore import vtkDoubleArray, vtkIdTypeArray, vtkPoints, vtkVersion
    from vtkmodules.vtkIOPLY import vtkPLYReader
    from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridReader

    from matrixtree_vtk import vtkMatrixTreeLocator

    result = {"vtk": vtkVersion.GetVTKVersion(), "sets": {}}
    arrays = {}
    for name in sorted(os.listdir(folder)):
        reader = vtkPLYReader() if name.endswith(".ply") else vtkXMLUnstructuredGridReader()
        reader.SetFileName(os.path.join(folder, name))
        reader.Update()
        ds = reader.GetOutput()
        loc = vtkMatrixTreeLocator()
        loc.SetNumberOfThreads(1)
        loc.SetDataSet(ds)
        loc.BuildLocator()
        b = np.array(ds.GetBounds())
        lo, hi = b[0::2], b[1::2]
        rng = np.random.default_rng(5)
        a = lo + (hi - lo) * rng.random((segments, 3))
        e = lo + (hi - lo) * rng.random((segments, 3))
        pts = vtkPoints()
        pts.SetData(numpy_to_vtk(a, deep=True))
        va, ve = numpy_to_vtk(a, deep=True), numpy_to_vtk(e, deep=True)
        t, ids, x = vtkDoubleArray(), vtkIdTypeArray(), vtkDoubleArray()
        cells = vtkIdTypeArray()
        seg_s, pt_s = [], []
        for _ in range(repeats):  # interleaved: segments, points, segments, ...
            c0 = time.process_time()
            loc.IntersectSegments(va, ve, 0.0, t, ids, x)
            seg_s.append(time.process_time() - c0)
            c0 = time.process_time()
            loc.FindCells(pts, cells, None, None)
            pt_s.append(time.process_time() - c0)
        result["sets"][name] = {"segment_s_per_m": float(np.median(seg_s)) / segments * 1e6,
                                "point_s_per_m": float(np.median(pt_s)) / segments * 1e6,
                                "hits": int((vtk_to_numpy(ids) >= 0).sum())}
        arrays[f"{name}|t"] = vtk_to_numpy(t).copy()
        arrays[f"{name}|ids"] = vtk_to_numpy(ids).copy()
        arrays[f"{name}|cells"] = vtk_to_numpy(cells).copy()
    np.savez(out + ".npz", **arrays)
    with open(out, "w") as f:
        json.dump(result, f)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--segments", type=int, default=100_000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--json", default=os.path.join(ROOT, "out", "vtk92_paths.json"))
    ap.add_argument("--md")
    ap.add_argument("--worker", nargs=2, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        worker(args.worker[0], args.worker[1], args.segments, args.repeats)
        return
    import numpy as np
    from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridWriter

    sys.path.insert(0, HERE)
    import matrixtree
    from _common import machine, markdown, table, write_json

    folder = tempfile.mkdtemp()
    for name, sub in SETS.items():
        path = os.path.join(matrixtree.scenes.data_dir(), sub, name)
        if name.endswith(".ply"):
            os.symlink(path, os.path.join(folder, name))
            continue
        w = vtkXMLUnstructuredGridWriter()
        w.SetFileName(os.path.join(folder, os.path.splitext(name)[0] + ".vtu"))
        w.SetInputData(matrixtree.read_grid(path))
        w.Write()
    runs = {}
    env92 = dict(os.environ, PYTHONPATH=os.pathsep.join([
        os.path.join(ROOT, "build-paraview", "python3-paraview", "usr", "lib", "python3", "dist-packages"),
        os.path.join(ROOT, "build-paraview", "lib", "python3.11", "site-packages")]))
    for label, cmd, env in [("9.1 (build/)", [sys.executable], None), ("9.2 (build-paraview/)", ["pvbatch"], env92)]:
        out = os.path.join(folder, label.split()[0] + ".json")
        subprocess.run(cmd + [os.path.abspath(__file__), "--segments", str(args.segments), "--repeats",
                              str(args.repeats), "--worker", folder, out], check=True, env=env,
                       stdout=subprocess.DEVNULL)
        runs[label] = (json.load(open(out)), np.load(out + ".npz"))
    (l91, (r91, a91)), (l92, (r92, a92)) = runs.items()
    rows = []
    for name in sorted(r91["sets"]):
        s91, s92 = r91["sets"][name], r92["sets"][name]
        rows.append({"data": name, "segments_91_s_per_m": s91["segment_s_per_m"],
                     "segments_92_s_per_m": s92["segment_s_per_m"],
                     "segments_92_over_91": s92["segment_s_per_m"] / s91["segment_s_per_m"],
                     "points_91_s_per_m": s91["point_s_per_m"], "points_92_s_per_m": s92["point_s_per_m"],
                     "hits": s91["hits"],
                     "same_hits": bool(np.array_equal(a91[f"{name}|ids"], a92[f"{name}|ids"])
                                       and np.array_equal(a91[f"{name}|t"], a92[f"{name}|t"])),
                     "same_cells": bool(np.array_equal(a91[f"{name}|cells"], a92[f"{name}|cells"]))})
    cols = list(rows[0])
    print(f"VTK {r91['vtk']} vs {r92['vtk']}, {args.segments} queries, 1 thread, CPU s per million")
    print(table(rows, cols))
    load = os.getloadavg()
    write_json(args.json, {"machine": machine(), "load": load, "args": vars(args), "rows": rows})
    if args.md:
        with open(args.md, "w") as f:
            f.write(f"Command: `.venv/bin/python bench/vtk92_paths.py --md {os.path.relpath(args.md, ROOT)}` "
                    f"(VTK {r91['vtk']} vs {r92['vtk']}; {args.segments} queries; one thread; CPU seconds per "
                    f"million, median of {args.repeats}; load average {load[0]:.1f}).\n\n")
            f.write(markdown(rows, cols) + "\n")


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Build benchmark of the matrix trees (paper §5.1), with VTK's own locators built in the same run.

    .venv/bin/python bench/build.py [--scene FILE] [--repeats N] [--json OUT] [--markdown MD]
                                    [--backend cpu|opencl|all] [--device SELECTOR]

With no --scene it runs every mesh in ../shared/data/meshes and the Utah Hand and Ben scenes.
For each scene and tree (matrix octree, matrix kd-tree; exact and bounding-box overlap) it
prints the per-phase build times (median of N builds), the tree height, leaves, references and
bytes per triangle, and the triangle tests per ray of 20,000 seeded rays (the accuracy side of
the exact/bounding-box trade). VTK's vtkStaticCellLocator, vtkCellTreeLocator and
vtkModifiedBSPTree are built on the same polydata for scale (build time only).

--backend opencl (or all) also builds every tree with the OpenCL kernels (device from --device,
else $MATRIXTREE_OPENCL_DEVICE, else the first one): rows gain `backend`, `device`, the device
time of every kernel (median over the builds, from OpenCL profiling events), `ratio_to_cpu`
(OpenCL build time / OpenMP build time of the same tree, same run) and `mismatches` against the
CPU engine: differing tree statistics (height, leaves, references, bytes, blocks per level),
differing first-hit cells of the 20,000 rays and differing located leaves of 20,000 points.
"""

from __future__ import annotations

import argparse
import itertools
import os
import statistics

import numpy as np

from _common import default_scene_paths, load, machine, median_time_ms, table, write_outputs
import matrixtree


def seeded_rays(mesh, n: int, seed: int = 7):
    b = np.array(mesh.GetBounds()).reshape(3, 2)
    lo, hi = b[:, 0], b[:, 1]
    c, ext = (lo + hi) / 2, (hi - lo)
    rng = np.random.default_rng(seed)
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    o = c + u * np.linalg.norm(ext)
    target = lo + rng.random((n, 3)) * ext
    return o, target - o


def vtk_peer_rows(mesh, name, repeats):
    from vtkmodules.vtkCommonDataModel import vtkStaticCellLocator
    from vtkmodules.vtkFiltersGeneral import vtkCellTreeLocator
    from vtkmodules.vtkFiltersFlowPaths import vtkModifiedBSPTree

    rows = []
    for cls in (vtkStaticCellLocator, vtkCellTreeLocator, vtkModifiedBSPTree):
        def go():
            loc = cls()
            loc.SetDataSet(mesh)
            loc.LazyEvaluationOff()  # VTK 9.1's vtkModifiedBSPTree otherwise defers the build
            loc.BuildLocator()
        ms, _ = median_time_ms(go, max(1, repeats // 3))
        rows.append({"scene": name, "tree": cls.__name__, "overlap": "-", "triangles": mesh.GetNumberOfPolys(),
                     "build_ms": ms})
    return rows


_SAME_KEYS = ("height", "leaves", "references", "bytes", "level_blocks", "level_dims", "root_bounds")


def kernel_times(tree) -> dict:
    t = tree.vtk_tree
    return {t.GetOpenCLKernelName(i): t.GetOpenCLKernelTime(i) for i in range(t.GetNumberOfOpenCLKernels())}


def mismatches(ref, tree, o, d, pts) -> int:
    """Differences against the CPU engine's tree: statistics, first-hit cells, located leaves."""
    a, b = ref.stats(), tree.stats()
    bad = sum(a[k] != b[k] for k in _SAME_KEYS)
    bad += int(np.sum(ref.intersect(o, d)[1] != tree.intersect(o, d)[1]))
    bad += int(np.sum(np.any(ref.find_leaves(pts) != tree.find_leaves(pts), axis=1)))
    return bad


def run_scene(path: str, repeats: int, peers: bool, backends=("cpu",), device=None, threads=0):
    name = os.path.splitext(os.path.basename(path))[0]
    mesh = load(path)
    n = mesh.GetNumberOfPolys()
    o, d = seeded_rays(mesh, 20000)
    b = np.array(mesh.GetBounds()).reshape(3, 2)
    pts = b[:, 0] + np.random.default_rng(3).random((20000, 3)) * (b[:, 1] - b[:, 0])
    rows = []
    refs = {}  # the CPU engine's tree per (kind, exact): the reference of the OpenCL rows
    for kind in ("octree", "kdtree"):
        for exact, backend in itertools.product((True, False), backends):
            tree = matrixtree.MatrixTree(mesh, tree=kind, exact=exact, backend=backend, device=device,
                                         threads=threads)
            stats, kernels = [], []
            for _ in range(repeats):
                tree.build()
                stats.append(tree.stats())
                kernels.append(kernel_times(tree))
            build = statistics.median(s["build_ms"] for s in stats)
            phases = {k: statistics.median(s["phases_ms"][k] for s in stats) for k in stats[0]["phases_ms"]}
            s = stats[0]
            tree.intersect(o, d)
            q = tree.last_query_counters
            row = {
                "scene": name, "tree": f"matrix-{kind}", "overlap": "exact" if exact else "bbox",
                "backend": backend, "device": s["device"] if backend == "opencl" else "openmp",
                "triangles": n, "height": s["height"], "leaf_dims": s["leaf_dims"], "leaves": s["leaves"],
                "references": s["references"], "refs_per_tri": s["references"] / n,
                "build_ms": build, "build_ms_all": [round(x["build_ms"], 3) for x in stats],
                "phases_ms": phases, "bytes": s["bytes"], "bytes_per_tri": s["bytes"] / n,
                "level_bytes": s["level_bytes"], "level_blocks": s["level_blocks"],
                "node_visits_per_ray": q["node_visits"] / len(o), "tri_tests_per_ray": q["triangle_tests"] / len(o),
                "threads": threads or os.cpu_count(),
            }
            if backend == "cpu":
                refs[kind, exact] = tree
            else:
                if (kind, exact) not in refs:
                    refs[kind, exact] = matrixtree.MatrixTree(mesh, tree=kind, exact=exact)
                row["mismatches"] = mismatches(refs[kind, exact], tree, o, d, pts)
                row["kernels_ms"] = {k: statistics.median(kt.get(k, 0.0) for kt in kernels) for k in kernels[0]}
                cpu_row = next((r for r in rows if r["tree"] == row["tree"] and r["overlap"] == row["overlap"]
                                and r["backend"] == "cpu"), None)
                if cpu_row:
                    row["ratio_to_cpu"] = build / cpu_row["build_ms"]
            rows.append(row)
    if peers:
        rows += vtk_peer_rows(mesh, name, repeats)
    return rows


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--scene", action="append", help="mesh file (repeatable); default: all real meshes")
    p.add_argument("--repeats", type=int, default=9, help="builds per tree; the median is reported (default 9)")
    p.add_argument("--json", default="out/bench_build.json")
    p.add_argument("--markdown", default=None, help="also write the table as markdown here")
    p.add_argument("--no-peers", action="store_true", help="skip VTK's locators")
    p.add_argument("--backend", choices=("cpu", "opencl", "all"), default="cpu",
                   help="build on the OpenMP engine, with the OpenCL kernels, or both (default cpu)")
    p.add_argument("--threads", type=int, default=0,
                   help="OpenMP threads of the CPU builds (default 0 = all; 1 gives stable times on a busy machine)")
    p.add_argument("--device", default=None, help="OpenCL device: 'P:D', a number, or part of its name")
    a = p.parse_args()
    backends = ("cpu", "opencl") if a.backend == "all" else (a.backend,)
    paths = a.scene or list(default_scene_paths().values())
    if not paths:
        p.error("no scenes: pass --scene FILE or provide ../shared/data")
    rows = []
    try:
        from tqdm import tqdm
        it = tqdm(paths, desc="scenes", unit="scene")
    except ImportError:
        it = paths
    for path in it:
        rows += run_scene(path, a.repeats, not a.no_peers, backends, a.device, a.threads)
    phase_names = list(next(r for r in rows if "phases_ms" in r)["phases_ms"])
    flat = []
    for r in rows:
        f = dict(r)
        for k in phase_names:
            if "phases_ms" in r:
                f[k] = r["phases_ms"][k]
        flat.append(f)
    # Phases in first-seen order over all rows (the OpenCL rows add upload and download).
    phase_names = list(dict.fromkeys(k for r in rows if "phases_ms" in r for k in r["phases_ms"]))
    for f in flat:
        for k in phase_names:
            if "phases_ms" in f:
                f[k] = f["phases_ms"].get(k, "")
    cols = ["scene", "tree", "overlap", "backend", "triangles", "height", "build_ms"] + phase_names + [
        "refs_per_tri", "bytes_per_tri", "tri_tests_per_ray"]
    if "opencl" in backends:
        cols += ["ratio_to_cpu", "mismatches"]
        for f in flat:
            f.setdefault("ratio_to_cpu", "")
            f.setdefault("mismatches", "")
    print(table(flat, cols))
    cl_rows = [r for r in rows if r.get("backend") == "opencl"]
    if cl_rows:
        print(f"\nOpenCL device: {cl_rows[0]['device']}")
        print("per-kernel device time (ms, median of the builds; share of the summed kernel time):")
        names = list(dict.fromkeys(k for r in cl_rows for k in r["kernels_ms"]))
        ktab = []
        for r in cl_rows:
            total = sum(r["kernels_ms"].values()) or 1.0
            k = {"scene": r["scene"], "tree": r["tree"], "overlap": r["overlap"], "build_ms": r["build_ms"],
                 "ratio_to_cpu": r.get("ratio_to_cpu", ""), "mismatches": r["mismatches"]}
            for name in names:
                v = r["kernels_ms"].get(name, 0.0)
                k[name] = f"{v:.2f} ({100 * v / total:.0f}%)"
            ktab.append(k)
        print(table(ktab, ["scene", "tree", "overlap", "build_ms", "ratio_to_cpu", "mismatches"] + names))
    # Ratios: VTK's locators over our octree, same scene, same run.
    print("\nbuild-time ratio peer / matrix-octree (exact), same run:")
    for scene in dict.fromkeys(r["scene"] for r in rows):
        ours = next(r for r in rows if r["scene"] == scene and r["tree"] == "matrix-octree" and r["overlap"] == "exact")
        if not any(r["scene"] == scene and r["overlap"] == "-" for r in rows):
            continue
        peers = [r for r in rows if r["scene"] == scene and r["overlap"] == "-"]
        print(f"  {scene:14s} " + "  ".join(f"{r['tree']} {r['build_ms'] / ours['build_ms']:.1f}x" for r in peers))
    for r in rows:
        r["machine"] = machine()
    write_outputs(a.json, rows, a.markdown, flat, cols)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

#!/usr/bin/env python3
"""Build benchmark of the matrix trees (paper §5.1), with VTK's own locators built in the same run.

    .venv/bin/python bench/build.py [--scene FILE] [--repeats N] [--json OUT] [--markdown MD]

With no --scene it runs every mesh in ../shared/data/meshes and the Utah Hand and Ben scenes.
For each scene and tree (matrix octree, matrix kd-tree; exact and bounding-box overlap) it
prints the per-phase build times (median of N builds), the tree height, leaves, references and
bytes per triangle, and the triangle tests per ray of 20,000 seeded rays (the accuracy side of
the exact/bounding-box trade). VTK's vtkStaticCellLocator, vtkCellTreeLocator and
vtkModifiedBSPTree are built on the same polydata for scale (build time only).
"""

from __future__ import annotations

import argparse
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


def run_scene(path: str, repeats: int, peers: bool):
    name = os.path.splitext(os.path.basename(path))[0]
    mesh = load(path)
    n = mesh.GetNumberOfPolys()
    o, d = seeded_rays(mesh, 20000)
    rows = []
    for kind in ("octree", "kdtree"):
        for exact in (True, False):
            tree = matrixtree.MatrixTree(mesh, tree=kind, exact=exact)
            stats = []
            for _ in range(repeats):
                tree.build()
                stats.append(tree.stats())
            build = statistics.median(s["build_ms"] for s in stats)
            phases = {k: statistics.median(s["phases_ms"][k] for s in stats) for k in stats[0]["phases_ms"]}
            s = stats[0]
            tree.intersect(o, d)
            q = tree.last_query_counters
            rows.append({
                "scene": name, "tree": f"matrix-{kind}", "overlap": "exact" if exact else "bbox",
                "triangles": n, "height": s["height"], "leaf_dims": s["leaf_dims"], "leaves": s["leaves"],
                "references": s["references"], "refs_per_tri": s["references"] / n,
                "build_ms": build, "build_ms_all": [round(x["build_ms"], 3) for x in stats],
                "phases_ms": phases, "bytes": s["bytes"], "bytes_per_tri": s["bytes"] / n,
                "level_bytes": s["level_bytes"], "level_blocks": s["level_blocks"],
                "node_visits_per_ray": q["node_visits"] / len(o), "tri_tests_per_ray": q["triangle_tests"] / len(o),
                "threads": os.cpu_count(),
            })
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
    a = p.parse_args()
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
        rows += run_scene(path, a.repeats, not a.no_peers)
    phase_names = list(next(r for r in rows if "phases_ms" in r)["phases_ms"])
    flat = []
    for r in rows:
        f = dict(r)
        for k in phase_names:
            if "phases_ms" in r:
                f[k] = r["phases_ms"][k]
        flat.append(f)
    cols = ["scene", "tree", "overlap", "triangles", "height", "build_ms"] + phase_names + [
        "refs_per_tri", "bytes_per_tri", "tri_tests_per_ray"]
    print(table(flat, cols))
    # Ratios: VTK's locators over our octree, same scene, same run.
    print("\nbuild-time ratio peer / matrix-octree (exact), same run:")
    for scene in dict.fromkeys(r["scene"] for r in rows):
        ours = next(r for r in rows if r["scene"] == scene and r["tree"] == "matrix-octree" and r["overlap"] == "exact")
        peers = [r for r in rows if r["scene"] == scene and r["overlap"] == "-"]
        print(f"  {scene:14s} " + "  ".join(f"{r['tree']} {r['build_ms'] / ours['build_ms']:.1f}x" for r in peers))
    for r in rows:
        r["machine"] = machine()
    write_outputs(a.json, rows, a.markdown, flat, cols)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

#!/usr/bin/env python3
"""Is the automatic tree height close to the best fixed height? A sweep on the real meshes.

    .venv/bin/python bench/height.py [--scene FILE] [--size W H] [--json OUT] [--markdown MD]

For every scene and tree kind, renders one image (primary + shadow rays, automatic camera)
with the automatic height and with every fixed height around it, and reports the render time,
build time, node visits and triangle tests per ray. The automatic rule (engine
chooseHeight(): the shallowest level whose nodes are at most leafScale = 2 median triangle
extents wide) is judged by render_ms(auto) / render_ms(best fixed), in one run.
"""

from __future__ import annotations

import argparse
import os

from _common import default_scene_paths, load, machine, table, write_outputs
import matrixtree
from matrixtree_vtk import vtkMatrixTreeRayCaster


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--scene", action="append")
    p.add_argument("--size", nargs=2, type=int, default=[400, 400])
    p.add_argument("--repeats", type=int, default=3, help="renders per height; the fastest counts")
    p.add_argument("--json", default="out/bench_height.json")
    p.add_argument("--markdown", default=None)
    p.add_argument("--leaf-scale", type=float, default=2.0, help="leafScale of the automatic rule (default 2)")
    p.add_argument("--builds", type=int, default=5, help="builds per height; the median counts (default 5)")
    a = p.parse_args()
    paths = a.scene or list(default_scene_paths().values())
    rows, summary = [], []
    try:
        from tqdm import tqdm
        paths_it = tqdm(paths, desc="scenes", unit="scene")
    except ImportError:
        paths_it = paths
    for path in paths_it:
        name = os.path.splitext(os.path.basename(path))[0]
        mesh = load(path)
        for kind in ("octree", "kdtree"):
            auto_h = matrixtree.MatrixTree(mesh, tree=kind, leaf_scale=a.leaf_scale).stats()["height"]
            span = 3 if kind == "octree" else 7
            heights = [0] + [h for h in range(max(1, auto_h - span), auto_h + span + 1)]
            res = {}
            caster = vtkMatrixTreeRayCaster()
            caster.GetTree().SetLeafScale(a.leaf_scale)
            for h in heights:
                best = None
                for _ in range(a.repeats):
                    img = matrixtree.render(mesh, size=a.size, tree=kind, height=h, caster=caster)
                    caster = img["caster"]
                    if best is None or img["render_ms"] < best["render_ms"]:
                        best = img
                # The timed renders run without counters; one more, untimed, counts.
                counted = matrixtree.render(mesh, size=a.size, tree=kind, height=h, caster=caster, counters=True)
                tree = caster.GetTree()
                tree.SetLeafScale(a.leaf_scale)
                builds = []
                for _ in range(a.builds):  # median of warm rebuilds, as in a per-frame rebuild
                    tree.Build()
                    builds.append(tree.GetBuildTime())
                builds.sort()
                r = {"leaf_scale": a.leaf_scale, "scene": name, "tree": kind, "height_setting": "auto" if h == 0 else h,
                     "height": tree.GetTreeHeight(), "triangles": mesh.GetNumberOfPolys(),
                     "render_ms": best["render_ms"], "build_ms": builds[len(builds) // 2],
                     "bytes": tree.GetMemorySize(),
                     "node_visits_per_ray": counted["node_visits_per_ray"],
                     "tri_tests_per_ray": counted["triangle_tests_per_ray"]}
                rows.append(r)
                res[h] = r
            fixed = {h: r for h, r in res.items() if h != 0}
            best_h = min(fixed, key=lambda h: fixed[h]["render_ms"])
            best_total = min(fixed, key=lambda h: fixed[h]["render_ms"] + fixed[h]["build_ms"])
            auto = res[0]
            summary.append({"leaf_scale": a.leaf_scale, "scene": name, "tree": kind, "auto_height": auto["height"], "best_height": best_h,
                            "render_ms_auto": auto["render_ms"], "render_ms_best": fixed[best_h]["render_ms"],
                            "render_ratio_auto_to_best": auto["render_ms"] / fixed[best_h]["render_ms"],
                            "best_height_build_plus_render": best_total,
                            "total_ratio_auto_to_best": (auto["render_ms"] + auto["build_ms"]) /
                            (fixed[best_total]["render_ms"] + fixed[best_total]["build_ms"])})
    cols = ["scene", "tree", "height_setting", "height", "build_ms", "render_ms", "node_visits_per_ray",
            "tri_tests_per_ray", "bytes"]
    print(table(rows, cols))
    scols = ["scene", "tree", "auto_height", "best_height", "render_ms_auto", "render_ms_best",
             "render_ratio_auto_to_best", "best_height_build_plus_render", "total_ratio_auto_to_best"]
    print("\n" + table(summary, scols))
    for r in rows + summary:
        r["machine"] = machine()
        r["image"] = a.size
    write_outputs(a.json, {"sweep": rows, "summary": summary}, a.markdown, summary, scols)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

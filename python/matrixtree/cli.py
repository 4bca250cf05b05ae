"""Command line: ``python -m matrixtree [demo|render FILE] [options]``.

``demo`` (the default, no arguments, no downloads) generates the default scene, builds a matrix
octree and a regular matrix kd-tree over it with the §5.1 parallel build, prints the build
phases and times, ray casts an image (primary + shadow rays) through each, and writes the
picture and the per-pixel node-visit and triangle-test heat maps into the output folder.
``render FILE`` does the same for a mesh file of yours.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import matrixtree
from matrixtree import scenes


def _table(rows, cols):
    widths = [max(len(c), *(len(str(r[c])) for r in rows)) for c in cols]
    line = "  ".join(c.rjust(w) for c, w in zip(cols, widths))
    out = [line, "  ".join("-" * w for w in widths)]
    for r in rows:
        out.append("  ".join(str(r[c]).rjust(w) for c, w in zip(cols, widths)))
    return "\n".join(out)


def run(mesh, name: str, out_dir: str, size, camera, trees, height: int, threads: int) -> dict:
    os.makedirs(out_dir, exist_ok=True)
    n = mesh.GetNumberOfPolys()
    print(f"scene {name}: {n:,} triangles, image {size[0]}x{size[1]}, primary + shadow rays")
    rows, outputs = [], {}
    for kind in trees:
        tree = matrixtree.MatrixTree(mesh, tree=kind, height=height, threads=threads)
        builds = [tree.build().stats() for _ in range(5)]  # median of 5 builds
        builds.sort(key=lambda s: s["build_ms"])
        s = builds[len(builds) // 2]
        phases = "  ".join(f"{k} {v:.2f}" for k, v in s["phases_ms"].items())
        print(f"\n{kind}: height {s['height']}, leaf grid {'x'.join(map(str, s['leaf_dims']))}, "
              f"{s['leaves']:,} leaves, {s['references']:,} references, {s['bytes'] / 1e6:.2f} MB")
        print(f"  build {s['build_ms']:.2f} ms (median of 5) = {phases}")
        img = matrixtree.render(mesh, size=size, tree=kind, height=height, camera=camera, threads=threads)
        base = os.path.join(out_dir, f"{name}_{kind}")
        files = [matrixtree.save_rgb(img["rgb"], base + ".png"),
                 matrixtree.save_heatmap(img["node_visits"], base + "_node_visits.png", vmax=100),
                 matrixtree.save_heatmap(img["triangle_tests"], base + "_triangle_tests.png", vmax=250)]
        print(f"  render {img['render_ms']:.1f} ms, {img['rays'] / img['render_ms'] / 1e3:.2f} M rays/s, "
              f"{img['node_visits_per_ray']:.1f} node visits and {img['triangle_tests_per_ray']:.1f} "
              f"triangle tests per ray")
        print("  wrote " + ", ".join(files))
        rows.append({"tree": kind, "triangles": n, "height": s["height"], "build_ms": round(s["build_ms"], 2),
                     "render_ms": round(img["render_ms"], 1), "rays": img["rays"],
                     "node_visits_per_ray": round(img["node_visits_per_ray"], 2),
                     "tri_tests_per_ray": round(img["triangle_tests_per_ray"], 2),
                     "bytes": s["bytes"], "phases_ms": s["phases_ms"]})
        outputs[kind] = files
    cols = ["tree", "triangles", "height", "build_ms", "render_ms", "node_visits_per_ray", "tri_tests_per_ray", "bytes"]
    print("\n" + _table(rows, cols))
    with open(os.path.join(out_dir, f"{name}.json"), "w") as f:
        json.dump(rows, f, indent=1)
    print(f"\ntable written to {os.path.join(out_dir, name + '.json')}")
    return {"rows": rows, "files": outputs}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m matrixtree", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("command", nargs="?", default="demo", choices=["demo", "render"])
    p.add_argument("file", nargs="?", help="mesh file for 'render' (.ply .obj .stl .vtp .vtk)")
    p.add_argument("--out", default="out", help="output folder (default: out)")
    p.add_argument("--size", nargs=2, type=int, default=[800, 800], metavar=("W", "H"))
    p.add_argument("--tree", choices=["octree", "kdtree", "both"], default="both")
    p.add_argument("--height", type=int, default=0, help="tree height, 0 = automatic (default)")
    p.add_argument("--threads", type=int, default=0, help="OpenMP threads, 0 = all (default)")
    a = p.parse_args(argv)
    trees = ["octree", "kdtree"] if a.tree == "both" else [a.tree]
    t0 = time.time()
    if a.command == "demo":
        mesh = scenes.default_scene()
        run(mesh, "demo", a.out, a.size, scenes.DEFAULT_CAMERA, trees, a.height, a.threads)
    else:
        if not a.file:
            p.error("render needs a mesh FILE")
        try:
            mesh = matrixtree.read_mesh(a.file)
        except (OSError, ValueError) as e:
            print(f"error: {e}", file=sys.stderr)
            return 2
        name = os.path.splitext(os.path.basename(a.file))[0]
        run(mesh, name, a.out, a.size, None, trees, a.height, a.threads)
    print(f"done in {time.time() - t0:.1f} s")
    return 0

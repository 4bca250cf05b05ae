"""The paper's implicit general kd-trees and BSP trees (§4) and hybrid matrix/SAH tree (§7), measured.

For every shipped mesh (../shared/data: the five meshes and the two Utah scenes), one run of
build/bin/trees_bench on one thread with the CPU clock: bytes of the implicit kd-tree against the
pointer SAH tree with the same splits for every block shape, per level, and for lower depth limits;
render time, node visits and triangle tests of every tree and traversal (matrix octree and kd-tree,
pointer SAH, implicit kd, implicit BSP, hybrid), with their build times and their mismatches against
the brute force on sampled pixels; with --opencl, the stackless kernel against the CPU, pixel by
pixel. Tables are printed per mesh and written as markdown (--md) and JSON (--json).

    .venv/bin/python bench/trees.py                                  # all seven meshes
    .venv/bin/python bench/trees.py --scene bunny --opencl           # one, plus the PoCL kernel
    .venv/bin/python bench/trees.py --md docs/trees_tables.md --json out/bench_trees.json
    xvfb-run -a .venv/bin/python bench/trees.py --pictures docs/images    # the split-plane pictures
    .venv/bin/python bench/trees.py --summary out/bench_trees.json      # docs/trees.md's tables
    xvfb-run -a .venv/bin/python bench/trees.py --product --scene utah_hand   # through matrixtree.render

Cameras are bench/rays.py's (fit_camera, its per-scene views) at --size (default 512 x 512).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

from _common import ROOT, machine, markdown, table  # noqa: F401  (sys.path set up there)
import rays  # the scene loading, camera fitting and scene file of bench/rays.py

BIN = os.path.join(os.environ.get("MATRIXTREE_BUILD", os.path.join(ROOT, "build")), "bin", "trees_bench")
SCENES = ["utah_hand", "utah_ben", "bunny", "horse", "lucy", "nefertiti", "turbineblade"]

STORAGE_COLS = ["tree", "layout", "nodes", "implicit_bytes_per_node", "implicit_node_MiB", "pointer_node_MiB",
                "node_bytes_ratio", "implicit_total_MiB", "pointer_total_MiB"]
LEVEL_COLS = ["level", "nodes", "empty_leaves", "block", "fill", "KiB", "fill_b8", "KiB_b8", "pointer_tree_KiB"]
DEPTH_COLS = ["max_depth", "depth", "nodes", "sah_cost", "pointer_node_MiB", "implicit_node_MiB", "node_bytes_ratio",
              "sah_stack_render_cpu_ms", "implicit_backtrack_render_cpu_ms", "mismatches_sah", "mismatches_implicit"]
RENDER_COLS = ["method", "traversal", "layout", "build_cpu_ms", "convert_cpu_ms", "render_cpu_ms",
               "render_vs_sah_stack", "node_visits_per_ray", "tri_tests_per_ray", "leaves_per_ray", "MiB",
               "mismatches_vs_brute_force", "rays_checked"]
PRODUCT_COLS = ["tree", "build_cpu_ms", "render_cpu_ms", "render_vs_octree", "node_visits_per_ray",
                "triangle_tests_per_ray", "hits", "pixels_differing_from_octree", "MiB", "pointer_tree_MiB"]
CL_COLS = ["method", "traversal", "device", "render_wall_ms", "pixels", "hit_mismatches_vs_cpu",
           "shading_mismatches_vs_cpu", "node_visits_cpu", "node_visits_device", "mismatches_vs_brute_force"]


def _mib(b):
    return b / 1048576.0


def tables(res: dict) -> dict:
    """The rows of each table of one scene's result, with derived columns."""
    storage = []
    for r in res["storage"]:
        storage.append(dict(r, implicit_node_MiB=_mib(r["implicit_node_bytes"]),
                            pointer_node_MiB=_mib(r["pointer_node_bytes"]),
                            implicit_total_MiB=_mib(r["implicit_total_bytes"]),
                            pointer_total_MiB=_mib(r["pointer_total_bytes"])))
    levels = [dict(r, block="x".join(str(1 << b) for b in r["log_block"]), KiB=r["bytes"] / 1024.0,
                   KiB_b8=r["bytes_b8"] / 1024.0, pointer_tree_KiB=r["pointer_tree_bytes"] / 1024.0)
              for r in res["levels"]]
    depths = [dict(r, pointer_node_MiB=_mib(r["pointer_node_bytes"]), implicit_node_MiB=_mib(r["implicit_node_bytes"]))
              for r in res["depths"]]
    base = next((r["render_cpu_ms"] for r in res["render"]
                 if r["method"] == "sah-pointer" and r["traversal"] == "stack"), None)
    render = [dict(r, MiB=_mib(r["bytes"]), render_vs_sah_stack=(r["render_cpu_ms"] / base if base else None))
              for r in res["render"]]
    return {"storage": storage, "levels": levels, "depths": depths, "render": render, "opencl": res["opencl"]}


def print_scene(name: str, res: dict, out) -> None:
    t = tables(res)
    sah = res["sah"]
    out(f"\n## {name} ({res['triangles']:,} triangles, {res['width']}x{res['height']}, one thread, CPU clock)\n")
    out(f"SAH tree: {sah['nodes']:,} nodes, depth {sah['depth']}, SAH cost {sah['sah_cost']:.1f}, "
        f"build {sah['build_cpu_ms']:.0f} ms.\n")
    out("Storage (node bytes; total adds 4 bytes per triangle reference):\n")
    out(markdown(t["storage"], STORAGE_COLS))
    out("\nImplicit kd-tree, per level (block shape of least bytes; `_b8`: the same level with 8^3 blocks):\n")
    out(markdown(t["levels"], LEVEL_COLS))
    out("\nLower SAH depth limits (pointer vs implicit, same splits):\n")
    out(markdown(t["depths"], DEPTH_COLS))
    out("\nRender (primary + shadow rays):\n")
    out(markdown(t["render"], RENDER_COLS))
    if t["opencl"]:
        out("\nStackless kernel on the OpenCL device vs the CPU backtrack render:\n")
        out(markdown(t["opencl"], CL_COLS))


def run_scene(spec: str, args) -> tuple[str, dict]:
    name, tris, frames = rays.load_scene(spec, 1)
    cam = rays.fit_camera(name, frames, args.size)
    with tempfile.TemporaryDirectory() as tmp:
        scene = os.path.join(tmp, "scene.bin")
        out = os.path.join(tmp, "out.json")
        rays.write_scene_file(scene, tris, frames[:1], cam)
        cmd = [BIN, scene, out, "--samples", str(args.samples), "--blocks", args.blocks,
               "--render-blocks", args.render_blocks, "--depths", args.depths, "--hybrid-scales", args.hybrid_scales,
               "--hybrid-depths", args.hybrid_depths, "--bsp-bonus", str(args.bsp_bonus), "--bsp-bins",
               str(args.bsp_bins)]
        if args.skip_bsp:
            cmd.append("--skip-bsp")
        if args.opencl:
            cmd += ["--opencl"] + (["--device", args.device] if args.device else [])
        print(f"[{name}] {' '.join(cmd[3:])}", file=sys.stderr)
        t0 = time.time()
        subprocess.run(cmd, check=True, env=dict(os.environ, OMP_NUM_THREADS="1"))
        with open(out) as f:
            res = json.load(f)
        res["wall_s"] = time.time() - t0
    res["scene"] = name
    return name, res


def summary(results: dict) -> str:
    """The cross-mesh tables of docs/trees.md from a --json result: one row per mesh."""
    storage, render, bsp, hybrid, cl = [], [], [], [], []
    for name, res in results["scenes"].items():
        st = {(r["tree"], r["layout"]): r for r in res["storage"]}
        rd = {(r["method"], r["traversal"], r["layout"]): r for r in res["render"]}
        sah = rd[("sah-pointer", "stack", "pointer")]
        kd = {t: rd[("implicit-kd", t, "per-level")] for t in ("stack", "restart", "backtrack")}
        ratio = {k: st[("kd", k)]["node_bytes_ratio"] for k in ("per-level", "1^3", "2^3", "4^3", "8^3", "32^3")}
        depth12 = next((d for d in res["depths"] if d["max_depth"] == 12), None)
        storage.append({"mesh": name, "sah_nodes": sah["nodes"], "pointer_node_MiB": _mib(8 * sah["nodes"]),
                        "implicit_node_MiB": _mib(st[("kd", "per-level")]["implicit_node_bytes"]),
                        "per_level": ratio["per-level"], "B=1": ratio["1^3"], "B=2": ratio["2^3"],
                        "B=4": ratio["4^3"], "B=8": ratio["8^3"], "B=32": ratio["32^3"],
                        "depth_12": depth12["node_bytes_ratio"] if depth12 else None,
                        "complete_tree": st[("kd-complete", "per-level")]["node_bytes_ratio"],
                        "bsp_per_level": st[("bsp-13", "per-level")]["node_bytes_ratio"]
                        if ("bsp-13", "per-level") in st else None})
        row = {"mesh": name, "sah_stack_ms": sah["render_cpu_ms"],
               "sah_restart_x": rd[("sah-pointer", "restart", "pointer")]["render_cpu_ms"] / sah["render_cpu_ms"]}
        for t, r in kd.items():
            row[f"implicit_{t}_x"] = r["render_cpu_ms"] / sah["render_cpu_ms"]
        row.update({"visits_stack": sah["node_visits_per_ray"], "visits_backtrack": kd["backtrack"]["node_visits_per_ray"],
                    "tests": sah["tri_tests_per_ray"], "sah_build_ms": sah["build_cpu_ms"],
                    "convert_ms": kd["stack"]["convert_cpu_ms"],
                    "mismatches": sum(r["mismatches_vs_brute_force"] for r in res["render"])})
        render.append(row)
        if ("bsp-13", "stack", "per-level") in rd:
            b13, b3 = rd[("bsp-13", "stack", "per-level")], rd[("bsp-3", "backtrack", "per-level")]
            b13b = rd[("bsp-13", "backtrack", "per-level")]
            bsp.append({"mesh": name, "bsp13_stack_ms": b13["render_cpu_ms"],
                        "vs_implicit_kd_stack": b13["render_cpu_ms"] / kd["stack"]["render_cpu_ms"],
                        "bsp13_backtrack_ms": b13b["render_cpu_ms"],
                        "bsp3_backtrack_ms": b3["render_cpu_ms"],
                        "tests_bsp13": b13["tri_tests_per_ray"], "tests_bsp3": b3["tri_tests_per_ray"],
                        "tests_sah": sah["tri_tests_per_ray"], "visits_bsp13": b13["node_visits_per_ray"],
                        "diagonal_share": res["bsp"]["diagonal_splits"] / max(1, res["bsp"]["diagonal_splits"]
                                                                              + res["bsp"]["axis_splits"]),
                        "bsp13_build_ms": b13["build_cpu_ms"], "bsp3_build_ms": b3["build_cpu_ms"],
                        "bsp13_MiB": _mib(b13["bytes"])})
        octree = rd[("matrix-octree", "matrix", "")]
        for r in res["render"]:
            if r["method"] != "hybrid":
                continue
            hybrid.append({"mesh": name, "layout": r["layout"], "octree_build_ms": octree["build_cpu_ms"],
                           "hybrid_build_ms": r["build_cpu_ms"], "kd_part_ms": r["convert_cpu_ms"],
                           "sah_build_ms": sah["build_cpu_ms"], "octree_ms": octree["render_cpu_ms"],
                           "hybrid_ms": r["render_cpu_ms"], "sah_stack_ms": sah["render_cpu_ms"],
                           "hybrid_vs_octree": r["render_cpu_ms"] / octree["render_cpu_ms"],
                           "hybrid_vs_sah": r["render_cpu_ms"] / sah["render_cpu_ms"],
                           "tests_octree": octree["tri_tests_per_ray"], "tests_hybrid": r["tri_tests_per_ray"],
                           "MiB_octree": _mib(octree["bytes"]), "MiB_hybrid": _mib(r["bytes"])})
        for r in res["opencl"]:
            cl.append({"mesh": name, "tree": r["method"], "pixels": r["pixels"],
                       "hit_mismatches_vs_cpu": r["hit_mismatches_vs_cpu"],
                       "shading_mismatches_vs_cpu": r["shading_mismatches_vs_cpu"],
                       "visits_equal": r["node_visits_cpu"] == r["node_visits_device"],
                       "mismatches_vs_brute_force": r["mismatches_vs_brute_force"],
                       "device_wall_ms": r["render_wall_ms"]})

    def cols(rows):
        return list(rows[0]) if rows else []

    parts = ["Storage: implicit kd node bytes / pointer SAH node bytes (same splits), per layout; "
             "`depth_12`: the SAH tree cut at depth 12; `complete_tree`: a median-split kd-tree.\n",
             markdown(storage, cols(storage)),
             "\nRender (one thread, CPU ms; `_x`: time / the pointer SAH tree's stack traversal):\n",
             markdown(render, cols(render)),
             "\nBSP (13 directions) against the kd-trees:\n", markdown(bsp, cols(bsp)),
             "\nHybrid against the matrix octree and the SAH tree:\n", markdown(hybrid, cols(hybrid)),
             "\nStackless kernel on the OpenCL device against the CPU (every pixel):\n", markdown(cl, cols(cl))]
    return "\n".join(parts)


def pictures(spec: str, out_dir: str, size, levels: int) -> list:
    """The implicit kd-tree's, the BSP tree's and the hybrid's split planes (levels <= `levels`)
    within their cells, over the mesh, as PNGs (pyvista off screen; run under xvfb-run)."""
    import numpy as np
    import pyvista as pv

    name, tris, frames = rays.load_scene(spec, 1)
    cam = rays.fit_camera(name, frames, size)
    os.makedirs(out_dir, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        scene = os.path.join(tmp, "scene.bin")
        rays.write_scene_file(scene, tris, frames[:1], cam)
        subprocess.run([BIN, scene, os.path.join(tmp, "out.json"), "--samples", "0", "--blocks", "0", "--depths", "",
                        "--hybrid-scales", "4", "--hybrid-depths", "8", "--planes", tmp, "--plane-levels", str(levels)],
                       check=True, env=dict(os.environ, OMP_NUM_THREADS="1"), stderr=subprocess.DEVNULL)
        faces = np.hstack([np.full((len(tris), 1), 3), tris]).astype(np.int64).ravel()
        mesh = pv.PolyData(frames[0], faces)
        written = []
        for kind, title in (("kd", "implicit general kd-tree"), ("bsp", "implicit BSP tree (26-DOP planes)"),
                            ("hybrid", "hybrid: matrix leaves + per-leaf kd-trees")):
            planes = pv.read(os.path.join(tmp, f"{kind}_planes.vtk"))
            pl = pv.Plotter(off_screen=True, window_size=list(size))
            pl.add_mesh(mesh, color="#d9d2c0")
            if kind == "hybrid":  # the kd-trees' first two levels: deeper ones hide the mesh
                planes = planes.threshold(value=(0, 1), scalars="level")
                boxes = pv.read(os.path.join(tmp, "hybrid_leaves.vtk"))
                pl.add_mesh(boxes, style="wireframe", color="#3060a0", line_width=0.6, opacity=0.35)
            pl.add_mesh(planes, scalars="level", cmap="viridis", opacity=0.35, show_scalar_bar=True,
                        scalar_bar_args={"title": "level"})
            shown = 1 if kind == "hybrid" else levels
            pl.add_text(f"{title}, levels 0-{shown}", font_size=9)
            pl.camera_position = [tuple(cam["eye"]), tuple(cam["target"]), tuple(cam["up"])]
            path = os.path.join(out_dir, f"trees_{kind}.png")
            pl.screenshot(path)
            pl.close()
            written.append(path)
    return written


def product(spec: str, size, trees) -> list:
    """Every tree through the product path (matrixtree.render: vtkMatrixTreeRayCaster and
    vtkMatrixTree, one thread), CPU clock of the process: the first render (build + render), then
    a second one with the same caster (no rebuild) for the render time, then a third, untimed one
    with counters for the node visits and triangle tests. Pixels whose first hit
    differs from the octree's image are counted (0 expected)."""
    import matrixtree

    import numpy as np
    from vtkmodules.util.numpy_support import numpy_to_vtk, numpy_to_vtkIdTypeArray
    from vtkmodules.vtkCommonCore import vtkPoints
    from vtkmodules.vtkCommonDataModel import vtkCellArray, vtkPolyData

    name, tris, frames = rays.load_scene(spec, 1)  # the triangles trees_bench renders
    pts = vtkPoints()
    pts.SetData(numpy_to_vtk(np.ascontiguousarray(frames[0], dtype=np.float64), deep=True))
    cells = vtkCellArray()
    cells.SetData(numpy_to_vtkIdTypeArray(np.arange(0, 3 * len(tris) + 1, 3, dtype=np.int64), deep=True),
                  numpy_to_vtkIdTypeArray(np.ascontiguousarray(tris, dtype=np.int64).ravel(), deep=True))
    mesh = vtkPolyData()
    mesh.SetPoints(pts)
    mesh.SetPolys(cells)
    cam = rays.fit_camera(name, frames, size)
    camera = [tuple(cam["eye"]), tuple(cam["target"]), tuple(cam["up"]), cam["fovy"]]
    rows, ref = [], None
    for tree in trees:
        t0 = time.process_time()
        first = matrixtree.render(mesh, size=tuple(size), tree=tree, camera=camera, threads=1)
        t1 = time.process_time()
        img = matrixtree.render(mesh, size=tuple(size), tree=tree, camera=camera, threads=1, caster=first["caster"])
        t2 = time.process_time()
        counted = matrixtree.render(mesh, size=tuple(size), tree=tree, camera=camera, threads=1,
                                    caster=first["caster"], counters=True)  # untimed: the counts only
        assert first["rebuilt"] and not img["rebuilt"] and not counted["rebuilt"]
        if ref is None:
            ref = img
        da, db = img["depth"].astype(float), ref["depth"].astype(float)
        with np.errstate(invalid="ignore"):  # inf - inf where both miss
            same = (np.isinf(da) & np.isinf(db)) | (np.abs(da - db) <= 1e-5 * np.maximum(1.0, np.abs(db)))
        t = first["caster"].GetTree()
        rows.append({"mesh": name, "tree": tree, "build_cpu_ms": 1e3 * ((t1 - t0) - (t2 - t1)),
                     "render_cpu_ms": 1e3 * (t2 - t1), "node_visits_per_ray": counted["node_visits_per_ray"],
                     "triangle_tests_per_ray": counted["triangle_tests_per_ray"], "hits": img["hits"],
                     "pixels_differing_from_octree": int(np.sum(~same)),
                     "MiB": _mib(t.GetMemorySize()) if tree != "sah" else None,
                     "pointer_tree_MiB": _mib(t.GetPointerTreeMemorySize()) if tree in ("implicit-kd", "bsp") else None})
    base = rows[0]["render_cpu_ms"]
    for r in rows:
        r["render_vs_octree"] = r["render_cpu_ms"] / base
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", action="append", help=f"scene name or mesh file (repeatable; default: {SCENES})")
    ap.add_argument("--size", type=int, nargs=2, default=(512, 512), metavar=("W", "H"))
    ap.add_argument("--samples", type=int, default=2000, help="pixels checked against the brute force")
    ap.add_argument("--blocks", default="0,1,2,4,8,16,32", help="block edges of the storage table (0 = per level)")
    ap.add_argument("--render-blocks", default="0", help="layouts of the implicit kd-tree that are rendered")
    ap.add_argument("--depths", default="8,12,16,20,24", help="lower SAH depth limits")
    ap.add_argument("--bsp-bonus", type=float, default=1.0, help="empty bonus of the BSP build")
    ap.add_argument("--bsp-bins", type=int, default=16, help="bins of the BSP build")
    ap.add_argument("--hybrid-scales", default="4,8", help="matrix leaf scales of the hybrid")
    ap.add_argument("--hybrid-depths", default="8", help="kd depth limits of the hybrid")
    ap.add_argument("--skip-bsp", action="store_true", help="leave out the BSP trees (their build is slow)")
    ap.add_argument("--opencl", action="store_true", help="also run the stackless kernel on an OpenCL device")
    ap.add_argument("--device", default="", help="OpenCL device selector (see ocl::Context::create)")
    ap.add_argument("--json", default=os.path.join(ROOT, "out", "bench_trees.json"))
    ap.add_argument("--md", help="write the markdown tables here (e.g. docs/trees_tables.md)")
    ap.add_argument("--pictures", help="only write the pictures of the split planes into this folder "
                    "(e.g. docs/images; run under xvfb-run -a)")
    ap.add_argument("--picture-levels", type=int, default=7, help="deepest level of planes drawn")
    ap.add_argument("--product", action="store_true", help="only render every tree through matrixtree.render "
                    "(the VTK classes; run under xvfb-run -a) and write its table to --json")
    ap.add_argument("--product-trees", default="octree,kdtree,implicit-kd,bsp,hybrid,sah",
                    help="trees of --product (the first is the reference)")
    ap.add_argument("--summary", metavar="JSON", help="only print docs/trees.md's cross-mesh tables from a --json result")
    args = ap.parse_args(argv)
    if args.summary:
        with open(args.summary) as f:
            print(summary(json.load(f)))
        return 0
    if not os.path.exists(BIN):
        raise SystemExit(f"{BIN} not found: build the project first (cmake --build build)")
    if args.product:
        load = os.getloadavg()
        rows = []
        for spec in args.scene or ["utah_hand"]:
            rows += product(spec, args.size, args.product_trees.split(","))
        print(f"Through matrixtree.render, one thread, CPU clock, {args.size[0]}x{args.size[1]}, "
              f"load average at start {load[0]:.1f}:\n")
        print(markdown(rows, ["mesh"] + PRODUCT_COLS))
        os.makedirs(os.path.dirname(os.path.abspath(args.json)) or ".", exist_ok=True)
        with open(args.json, "w") as f:
            json.dump({"machine": machine(), "load_at_start": load[0], "size": list(args.size), "product": rows}, f,
                      indent=1)
        print(f"\nwrote {args.json}")
        return 0
    if args.pictures:
        for path in pictures((args.scene or ["utah_hand"])[0], args.pictures, args.size, args.picture_levels):
            print(f"wrote {path}")
        return 0
    specs = args.scene or SCENES
    results, lines = {}, []
    load = os.getloadavg()
    header = (f"# bench/trees.py\n\nCommand: `.venv/bin/python bench/trees.py {' '.join(argv or sys.argv[1:])}`  \n"
              f"Machine: {machine()}, load average at start {load[0]:.1f}.\n")
    lines.append(header)
    for spec in specs:
        name, res = run_scene(spec, args)
        results[name] = res
        print_scene(name, res, lambda s: (print(s), lines.append(s)))
    os.makedirs(os.path.dirname(os.path.abspath(args.json)) or ".", exist_ok=True)
    with open(args.json, "w") as f:
        json.dump({"machine": machine(), "load_at_start": load[0], "size": list(args.size), "scenes": results}, f,
                  indent=1)
    print(f"\nwrote {args.json}")
    if args.md:
        with open(args.md, "w") as f:
            f.write("\n".join(lines) + "\n")
        print(f"wrote {args.md}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Command line: ``python -m matrixtree [demo|render|frames|locate] ...``.

``demo`` (the default: no arguments, no downloads) animates the generated default scene (a wavy
floor, a turning torus knot, a ring of spheres: about 200k triangles), rebuilds every tree every
frame and renders it (primary + one shadow ray per hit, 800x800) with the matrix octree, the
regular matrix kd-tree and the SAH kd-tree baseline with a stack, a short stack and KD-Restart,
then prints a table like the paper's Table 1 (build and render ms per frame, node visits and
triangle tests per ray) and writes the first frame's pictures and heat maps and the table into
the output folder (``out/`` by default).

``render FILE``        the same comparison on one mesh file of yours (one frame), or on the
                       boundary surface of a volume grid file (``--zone`` picks an SU2 zone);
                       a scalar volume (``.mhd``, ``.nii``, ``.vti``, ``.slc``, legacy ``.vtk``
                       structured points) is ray cast instead (``matrixtree.render_volume``,
                       default transfer functions) into ``NAME_volume.png``.
``frames FOLDER``      a folder of meshes with the same connectivity, one frame per file.
``locate GRID POINTS`` locate the points of a file (``.npy``, ``.csv``/``.txt`` with x y z per
                       line, or any mesh/grid file's points) in an unstructured grid (``.vtu``,
                       ``.vtk``, Exodus, SU2...); writes the cell ids (and weights) as ``.npy``
                       and, with ``--fields vtp|npz``, the grid's point and cell data
                       interpolated at the points (``matrixtree.probe``) with the cell ids and
                       ``vtkValidPointMask``; refuses to overwrite existing results unless
                       ``--force``.

``python -m matrixtree SUBCOMMAND --help`` lists each subcommand's arguments.
"""

from __future__ import annotations

import argparse
import glob
import json
import os
import sys
import time

import numpy as np

import matrixtree
from matrixtree import scenes

METHODS = ("octree", "kdtree", "sah-stack", "sah-shortstack", "sah-restart")
LABELS = {"octree": "matrix octree", "kdtree": "matrix kd-tree", "sah-stack": "SAH kd-tree, stack",
          "sah-shortstack": "SAH kd-tree, short stack (3)", "sah-restart": "SAH kd-tree, KD-Restart"}


def _table(rows, cols):
    def fmt(v):
        return f"{v:.2f}" if isinstance(v, float) else str(v)

    widths = [max(len(c), *(len(fmt(r[c])) for r in rows)) for c in cols]
    out = ["  ".join(c.rjust(w) for c, w in zip(cols, widths)), "  ".join("-" * w for w in widths)]
    for r in rows:
        out.append("  ".join(fmt(r[c]).rjust(w) for c, w in zip(cols, widths)))
    return "\n".join(out)


def compare(frames, name: str, out_dir: str, size, camera, threads: int, methods=METHODS) -> list:
    """Rebuild + render every frame with every method, print the Table-1 style table, write the
    first frame's render and heat maps per method, and the table as JSON and markdown."""
    os.makedirs(out_dir, exist_ok=True)
    rows = matrixtree.time_frames(frames, methods=methods, size=size, camera=camera, threads=threads,
                                  keep_images=True)
    base = next((r for r in rows if r["method"] == "sah-stack"), None)
    files = []
    for r in rows:
        r["label"] = LABELS[r["method"]]
        if base:
            r["render_x_vs_sah_stack"] = base["render_ms"] / r["render_ms"]
            r["frame_x_vs_sah_stack"] = base["frame_ms"] / r["frame_ms"]
        img = r.pop("first_frame")
        stem = os.path.join(out_dir, f"{name}_{r['method']}")
        files += [matrixtree.save_rgb(img["rgb"], stem + ".png"),
                  matrixtree.save_heatmap(img["node_visits"], stem + "_node_visits.png", vmax=100),
                  matrixtree.save_heatmap(img["triangle_tests"], stem + "_triangle_tests.png", vmax=100)]
    cols = ["label", "build_ms", "render_ms", "frame_ms", "node_visits_per_ray", "triangle_tests_per_ray"]
    if base:
        cols += ["render_x_vs_sah_stack", "frame_x_vs_sah_stack"]
    n, nt = rows[0]["frames"], rows[0]["triangles"]
    print(f"\n{name}: {nt:,} triangles, {n} frame(s), {size[0]}x{size[1]} pixels, primary + shadow rays; "
          "times are means per frame (every tree rebuilt every frame)")
    print(_table(rows, cols))
    table_json = os.path.join(out_dir, f"{name}_table.json")
    with open(table_json, "w") as f:
        json.dump([{k: v for k, v in r.items()} for r in rows], f, indent=1)
    table_md = os.path.join(out_dir, f"{name}_table.md")
    with open(table_md, "w") as f:
        f.write("| " + " | ".join(cols) + " |\n|" + "---|" * len(cols) + "\n")
        for r in rows:
            f.write("| " + " | ".join(f"{r[c]:.2f}" if isinstance(r[c], float) else str(r[c]) for c in cols)
                    + " |\n")
    print(f"\nwrote {table_json}, {table_md} and {len(files)} pictures in {out_dir}/ "
          f"(e.g. {os.path.basename(files[0])}, {os.path.basename(files[1])})")
    return rows


def _read_points(path: str) -> np.ndarray:
    ext = os.path.splitext(path)[1].lower()
    if ext == ".npy":
        pts = np.load(path)
    elif ext in (".csv", ".txt", ".xyz"):
        pts = np.loadtxt(path, delimiter="," if ext == ".csv" else None, ndmin=2)
    else:
        from vtkmodules.util.numpy_support import vtk_to_numpy

        ds = matrixtree.read_grid(path) if ext not in (".ply", ".obj", ".off", ".stl", ".vtp") else matrixtree.read_mesh(path)
        pts = vtk_to_numpy(ds.GetPoints().GetData())
    pts = np.asarray(pts, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] < 3:
        raise ValueError(f"{path}: expected N x 3 coordinates, got shape {pts.shape}")
    return pts[:, :3]


_HELP = {
    "demo": "the generated animated scene (the default: no arguments, no downloads)",
    "render": "the comparison on one mesh file (.ply .obj .off .stl .vtp .vtk) or the boundary surface "
              "of a volume grid file (.vtu .su2 .ex2 ...); a scalar volume (.mhd .mha .nii .nii.gz .slc .vti, "
              ".vtk structured points) is ray cast into NAME_volume.png",
    "frames": "a folder of meshes with the same connectivity, one frame per file",
    "locate": "locate the points of a file in an unstructured grid; writes the cell ids and weights (.npy) "
              "and, with --fields, the grid's fields interpolated at the points (.vtp or .npz)",
}
_GRID_EXTENSIONS = (".vtu", ".su2", ".ex2", ".exo", ".e", ".msh", ".inp", ".mesh")
_VOLUME_EXTENSIONS = (".mhd", ".mha", ".nii", ".nii.gz", ".slc", ".vti")


def _is_volume(path: str) -> bool:
    """A scalar-volume file: by its ending, or a legacy .vtk file whose header declares
    STRUCTURED_POINTS (legacy .vtk also holds meshes)."""
    low = path.lower()
    if low.endswith(_VOLUME_EXTENSIONS):
        return True
    if low.endswith(".vtk") and os.path.isfile(path):
        with open(path, "rb") as f:
            return b"STRUCTURED_POINTS" in f.read(1024)
    return False


def render_volume_file(path: str, out_dir: str, size, threads: int) -> str:
    """Ray casts the volume at ``path`` (default camera and transfer functions) over black and
    writes ``NAME_volume.png`` into ``out_dir``; returns its path."""
    volume = matrixtree.read_volume(path)
    t1 = time.perf_counter()
    rgba = matrixtree.render_volume(volume, size=tuple(size), threads=threads)
    ms = 1e3 * (time.perf_counter() - t1)
    name = os.path.basename(path).split(".")[0]
    png = matrixtree.save_rgb(np.clip(rgba[..., :3] * 255.0 + 0.5, 0, 255), os.path.join(out_dir, f"{name}_volume.png"))
    dims = volume.GetDimensions()
    print(f"{name}: {dims[0]}x{dims[1]}x{dims[2]} voxels, {size[0]}x{size[1]} pixels, {ms:.1f} ms; wrote {png}")
    return png


def _parser() -> argparse.ArgumentParser:
    """The parser: every option may stand before or after the subcommand (an option after it
    wins), each subcommand has its own ``--help``."""
    def options(q, top: bool):
        d = (lambda v: v) if top else (lambda v: argparse.SUPPRESS)
        q.add_argument("--out", default=d("out"), help="output folder (default: out)")
        q.add_argument("--size", nargs=2, type=int, default=d([800, 800]), metavar=("W", "H"),
                       help="render size in pixels (default 800 800)")
        q.add_argument("--threads", type=int, default=d(0), help="OpenMP threads, 0 = all (default)")
        q.add_argument("--methods", default=d(",".join(METHODS)),
                       help=f"comma-separated subset of {','.join(METHODS)}")
        q.add_argument("--frames", type=int, default=d(8), help="demo: frames of the animation (default 8)")
        q.add_argument("--resolution", type=float, default=d(1.0),
                       help="demo: scene tessellation (1.0 = about 200k triangles; 0.3 = 20k)")
        q.add_argument("--tree", choices=["octree", "kdtree"], default=d("octree"), help="locate: tree kind")
        q.add_argument("--zone", type=int, default=d(None),
                       help="locate, render: the zone of a multi-zone SU2 grid (default: all zones as one grid)")
        q.add_argument("--fields", choices=["vtp", "npz"], default=d(None),
                       help="locate: also write the grid's fields interpolated at the points, as a point "
                            "cloud (.vtp) or named arrays (.npz)")
        q.add_argument("--force", action="store_true", default=d(False),
                       help="locate: overwrite result files that exist (default: refuse)")

    p = argparse.ArgumentParser(prog="python -m matrixtree", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    options(p, top=True)
    sub = p.add_subparsers(dest="command", metavar="{demo,render,frames,locate}")
    args = {"demo": [], "render": [("file", "mesh or grid file")], "frames": [("folder", "folder of mesh files")],
            "locate": [("grid", "unstructured grid file (.vtu .vtk .su2 .ex2, Gmsh ...)"),
                       ("points", ".npy, .csv/.txt/.xyz (x y z per line), or a mesh/grid file's points")]}
    for name, positionals in args.items():
        q = sub.add_parser(name, help=_HELP[name], description=_HELP[name])
        for arg, what in positionals:
            q.add_argument(arg, help=what)
        options(q, top=False)
    return p


def _results(stem: str, fields: str | None, force: bool) -> list:
    """locate's result files for ``stem`` (cells, weights, fields or None); ValueError naming
    those that exist unless ``force``."""
    files = [stem + "_cells.npy", stem + "_weights.npy", f"{stem}_fields.{fields}" if fields else None]
    there = [f for f in files if f and os.path.exists(f)]
    if there and not force:
        raise ValueError(f"{', '.join(there)} exist: pass --force to overwrite, or choose another --out")
    return files


def main(argv=None) -> int:
    p = _parser()
    a = p.parse_args(argv)
    a.command = a.command or "demo"
    methods = tuple(m for m in a.methods.split(",") if m)
    bad = [m for m in methods if m not in METHODS]
    if bad:
        p.error(f"unknown method(s) {bad}; choose from {','.join(METHODS)}")
    t0 = time.time()
    try:
        if a.command == "demo":
            if a.frames < 1:
                p.error("--frames must be >= 1")
            print(f"generating {a.frames} frames of the default scene (resolution {a.resolution})")
            frames = [scenes.default_scene(a.resolution, time=f / a.frames) for f in range(a.frames)]
            compare(frames, "demo", a.out, a.size, scenes.DEFAULT_CAMERA, a.threads, methods)
        elif a.command == "render" and _is_volume(a.file):
            render_volume_file(a.file, a.out, a.size, a.threads)
        elif a.command == "render":
            if a.file.lower().endswith(_GRID_EXTENSIONS):
                from vtkmodules.vtkFiltersGeometry import vtkGeometryFilter

                from matrixtree.core import _triangulated

                surface = vtkGeometryFilter()
                surface.SetInputData(matrixtree.read_grid(a.file, zone=a.zone))
                surface.Update()
                mesh = _triangulated(surface.GetOutput(), merge_points=False)
            else:
                mesh = matrixtree.read_mesh(a.file)
            name = os.path.splitext(os.path.basename(a.file))[0]
            compare([mesh], name, a.out, a.size, None, a.threads, methods)
        elif a.command == "frames":
            if not os.path.isdir(a.folder):
                p.error("frames needs one FOLDER of mesh files with the same connectivity")
            files = sorted(f for ext in ("ply", "obj", "off", "stl", "vtp", "vtk")
                           for f in glob.glob(os.path.join(a.folder, f"*.{ext}")))
            if not files:
                p.error(f"{a.folder} holds no mesh files (.ply .obj .off .stl .vtp .vtk)")
            print(f"reading {len(files)} frames from {a.folder}")
            frames = [matrixtree.read_mesh(f) for f in files]
            name = os.path.basename(os.path.normpath(a.folder))
            compare(frames, name, a.out, a.size, None, a.threads, methods)
        else:
            stem = os.path.join(a.out, os.path.splitext(os.path.basename(a.points))[0])
            cells_file, weights_file, fields_file = _results(stem, a.fields, a.force)
            grid = matrixtree.read_grid(a.grid, zone=a.zone)
            pts = _read_points(a.points)
            loc = matrixtree.CellLocator(grid, tree=a.tree, threads=a.threads)
            t1 = time.perf_counter()
            cells, weights = loc.locate(pts, return_weights=True)
            ms = 1e3 * (time.perf_counter() - t1)
            os.makedirs(a.out, exist_ok=True)
            np.save(cells_file, cells)
            np.save(weights_file, weights)
            found = int(np.sum(cells >= 0))
            print(f"{len(pts):,} points in {grid.GetNumberOfCells():,} cells: {found:,} inside, "
                  f"{len(pts) - found:,} outside (-1); {ms:.1f} ms ({len(pts) / max(ms, 1e-9) / 1e3:.2f} M points/s)")
            if fields_file:
                probed = matrixtree.probe(grid, pts, locator=loc)
                probed.point_data["cell_id"] = cells
                if a.fields == "vtp":
                    probed.save(fields_file)
                else:
                    np.savez(fields_file, points=pts, **{k: np.asarray(probed.point_data[k]) for k in probed.point_data.keys()})
                print(f"wrote {fields_file}: {', '.join(probed.point_data.keys())}")
            print(f"wrote {cells_file} and {weights_file}")
    except (OSError, ValueError, RuntimeError, MemoryError) as e:
        print(f"error: {e or type(e).__name__}", file=sys.stderr)
        return 2
    print(f"done in {time.time() - t0:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())

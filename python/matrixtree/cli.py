"""Command line: ``python -m matrixtree [demo|render|frames|locate] ...``; ``COMMAND --help``
describes each.

``demo`` (the default: no arguments, no downloads) animates the generated default scene (a wavy
floor, a turning torus knot, a ring of spheres: about 200k triangles), rebuilds every tree every
frame and renders it (primary + one shadow ray per hit, 800x800) with the matrix octree, the
regular matrix kd-tree and the SAH kd-tree baseline with a stack, a short stack and KD-Restart,
then prints a table like the paper's Table 1 (build and render ms per frame, node visits and
triangle tests per ray) and writes the first frame's pictures and heat maps and the table into
the output folder (``out/`` by default).

``render FILE``        a mesh (.ply .obj .off .stl .vtp): the same comparison (one frame); a volume
                       grid (.vtu, Exodus, SU2 (``--zone``), Gmsh...): the same on its boundary surface; a
                       volume (.mhd .mha .nii .nii.gz .slc .vti): a volume rendering. A legacy
                       .vtk file is whichever its DATASET line says.
``frames FOLDER``      a folder of meshes with the same connectivity, one frame per file.
``locate GRID POINTS`` locate the points of a file (``.npy``, ``.csv``/``.txt`` with x y z per
                       line, or any mesh/grid file's points) in an unstructured grid and
                       interpolate the grid's point and cell data there; writes ``.npz``,
                       ``.vtp`` or ``.vtu`` (``--output``), never over an existing file unless
                       ``--overwrite``.
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
from matrixtree import filters, scenes

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

        ds = matrixtree.read_grid(path) if ext not in (".ply", ".obj", ".stl", ".vtp") else matrixtree.read_mesh(path)
        pts = vtk_to_numpy(ds.GetPoints().GetData())
    pts = np.asarray(pts, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] < 3:
        raise ValueError(f"{path}: expected N x 3 coordinates, got shape {pts.shape}")
    return pts[:, :3]


COMMANDS = ("demo", "render", "frames", "locate")
_VOLUME_EXTS = (".mhd", ".mha", ".nii", ".nii.gz", ".slc", ".vti")
_MESH_EXTS = (".ply", ".obj", ".off", ".stl", ".vtp")
_LOCATE_FORMATS = (".npz", ".vtp", ".vtu")


def _extension(path: str) -> str:
    low = path.lower()
    return ".nii.gz" if low.endswith(".nii.gz") else os.path.splitext(low)[1]


def file_kind(path: str) -> str:
    """``"mesh"``, ``"grid"`` or ``"volume"``: what :func:`main`'s ``render`` makes of ``path``
    (by its extension; a legacy ``.vtk`` file by its DATASET line). ValueError for a legacy file
    of another data set type."""
    ext = _extension(path)
    if ext in _VOLUME_EXTS:
        return "volume"
    if ext in _MESH_EXTS:
        return "mesh"
    if ext != ".vtk":
        return "grid"
    with open(path, "rb") as f:
        header = f.read(4096).decode("latin-1").splitlines()
    dataset = next((ln.split()[1].upper() for ln in header[:8] if ln.upper().startswith("DATASET") and
                    len(ln.split()) > 1), None)
    kinds = {"POLYDATA": "mesh", "UNSTRUCTURED_GRID": "grid", "STRUCTURED_POINTS": "volume"}
    if dataset not in kinds:
        raise ValueError(f"{path}: a legacy VTK file of data set type {dataset or 'unknown'}; render reads "
                         "POLYDATA (a mesh), UNSTRUCTURED_GRID (a grid's surface) or STRUCTURED_POINTS (a volume)")
    return kinds[dataset]


def grid_surface(grid):
    """The boundary surface of an unstructured grid as triangles (nonlinear faces subdivided once)."""
    from vtkmodules.vtkFiltersCore import vtkTriangleFilter
    from vtkmodules.vtkFiltersGeometry import vtkDataSetSurfaceFilter

    surf = vtkDataSetSurfaceFilter()
    surf.SetInputData(grid)
    surf.SetNonlinearSubdivisionLevel(1)
    tri = vtkTriangleFilter()
    tri.SetInputConnection(surf.GetOutputPort())
    tri.PassVertsOff()
    tri.PassLinesOff()
    tri.Update()
    if tri.GetOutput().GetNumberOfPolys() == 0:
        raise ValueError("the grid has no boundary faces to render")
    return tri.GetOutput()


def _render_volume_file(path: str, out_dir: str, size, threads: int) -> None:
    image = matrixtree.read_volume(path)
    rgba, st = matrixtree.render_volume(image, size=tuple(size), threads=threads, return_stats=True)
    name = os.path.basename(path)[: -len(_extension(path))]
    png = os.path.join(out_dir, f"{name}_volume.png")
    matrixtree.save_rgb(np.clip(rgba[..., :3] * 255.0 + 0.5, 0, 255).astype(np.uint8), png)
    dims = "x".join(str(d) for d in image.GetDimensions())
    print(f"{name}: {dims} voxels, {size[0]}x{size[1]} pixels: build {st['build_ms']:.1f} ms, render "
          f"{st['render_ms']:.1f} ms; {st['blocks_allocated']:,} of {st['blocks_dense']:,} blocks stored")
    print(f"wrote {png}")


def _locate_output(a, points_path: str) -> str:
    """Where ``locate`` writes: ``--output`` or ``OUT/<points name>_located.npz``; ValueError for
    another format, or an existing file without ``--overwrite``."""
    out = a.output or os.path.join(a.out, os.path.splitext(os.path.basename(points_path))[0] + "_located.npz")
    if _extension(out) not in _LOCATE_FORMATS:
        raise ValueError(f"--output {out}: write .npz, .vtp or .vtu")
    if os.path.exists(out) and not a.overwrite:
        raise ValueError(f"{out} exists; pass --overwrite to replace it")
    return out


def _locate(a) -> None:
    """``locate GRID POINTS``: cell ids, interpolation weights and the grid's fields at the points."""
    import pyvista as pv

    out = _locate_output(a, a.points)
    grid = matrixtree.read_grid(a.grid, zone=a.zone)
    pts = _read_points(a.points)
    loc = matrixtree.CellLocator(grid, tree=a.tree, threads=a.threads)
    t1 = time.perf_counter()
    cells, weights = loc.locate(pts, return_weights=True)
    ms = 1e3 * (time.perf_counter() - t1)
    # the grid's point and cell data at the points, from the cells and weights just found
    fields, valid = filters._interpolate_located(grid, cells, weights)
    fields[filters.VALID_MASK] = valid
    os.makedirs(os.path.dirname(os.path.abspath(out)), exist_ok=True)
    if _extension(out) == ".npz":
        np.savez(out, points=pts, cell_ids=cells, weights=weights, **{f"point_data/{k}": v for k, v in fields.items()})
    else:
        cloud = pv.PolyData(pts) if _extension(out) == ".vtp" else pv.PolyData(pts).cast_to_unstructured_grid()
        for k, v in fields.items():
            cloud.point_data[k] = v
        cloud.point_data["cell_id"] = cells
        cloud.save(out)
    found = int(np.sum(cells >= 0))
    print(f"{len(pts):,} points in {grid.GetNumberOfCells():,} cells: {found:,} inside, "
          f"{len(pts) - found:,} outside (-1); {ms:.1f} ms ({len(pts) / max(ms, 1e-9) / 1e3:.2f} M points/s)")
    names = [k for k in fields if k != filters.VALID_MASK]
    print(f"wrote {out}: cell ids, weights" + (f", fields {', '.join(names)}" if names else "") +
          " and vtkValidPointMask")


_COMMON_DEFAULTS = {"out": "out", "size": [800, 800], "threads": 0}


def _parser() -> argparse.ArgumentParser:
    # The options every command takes, accepted before the command too (SUPPRESS: a subparser's
    # default does not overwrite a value given before the command).
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--out", default=argparse.SUPPRESS, help="output folder (default: out)")
    common.add_argument("--size", nargs=2, type=int, default=argparse.SUPPRESS, metavar=("W", "H"),
                        help="image size in pixels (default: 800 800)")
    common.add_argument("--threads", type=int, default=argparse.SUPPRESS, help="threads, 0 = all (default)")
    methods = argparse.ArgumentParser(add_help=False)
    methods.add_argument("--methods", default=",".join(METHODS),
                         help=f"comma-separated subset of {','.join(METHODS)} (default: all)")
    p = argparse.ArgumentParser(prog="python -m matrixtree", description=__doc__, parents=[common],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    d = sub.add_parser("demo", parents=[common, methods], help="the animated default scene, every method (default)",
                       description="Animate the generated default scene, rebuild every tree every frame, render it "
                                   "with every method and print the Table-1 style comparison.")
    d.add_argument("--frames", type=int, default=8, help="frames of the animation (default 8)")
    d.add_argument("--resolution", type=float, default=1.0,
                   help="scene tessellation (1.0 = about 200k triangles; 0.3 = 20k)")
    r = sub.add_parser("render", parents=[common, methods], help="a mesh, a grid's surface or a volume",
                       description="A mesh (.ply .obj .off .stl .vtp): every method on it, one frame. A volume grid "
                                   "(.vtu, Exodus .exo/.e/.ex2, SU2, Gmsh, ...): the same on its boundary surface. "
                                   "A volume (.mhd .mha .nii .nii.gz .slc .vti): a volume rendering with the default "
                                   "transfer functions. A legacy .vtk file: whichever its DATASET line says.")
    r.add_argument("file", metavar="FILE")
    f = sub.add_parser("frames", parents=[common, methods], help="a folder of meshes, one frame per file",
                       description="Every method on a folder of meshes with the same connectivity (.ply .obj .stl "
                                   ".vtp .vtk), one frame per file in name order, every tree rebuilt every frame.")
    f.add_argument("folder", metavar="FOLDER")
    loc = sub.add_parser("locate", parents=[common], help="locate points in a grid, interpolate its fields",
                         description="Locate each point of POINTS (.npy, .csv or .txt with x y z per line, or a "
                                     "mesh/grid file's points) in the unstructured grid GRID and interpolate the "
                                     "grid's point data (and take its cell data) there. Writes the points, cell ids "
                                     "(-1 outside), interpolation weights, every field and vtkValidPointMask.")
    loc.add_argument("grid", metavar="GRID")
    loc.add_argument("points", metavar="POINTS")
    for q in (r, loc):
        q.add_argument("--zone", type=int, default=None,
                       help="the zone of a multi-zone SU2 grid (default: every zone, as one grid)")
    loc.add_argument("--tree", choices=["octree", "kdtree"], default="octree", help="tree kind (default octree)")
    loc.add_argument("--output", metavar="FILE",
                     help="result file: .npz (arrays points, cell_ids, weights, point_data/<name>), .vtp or .vtu "
                          "(a point cloud with the fields and cell_id); default OUT/<POINTS name>_located.npz")
    loc.add_argument("--overwrite", action="store_true", help="replace an existing result file")
    return p


def main(argv=None) -> int:
    p = _parser()
    argv = list(sys.argv[1:] if argv is None else argv)
    if not any(a in COMMANDS for a in argv) and not any(a in ("-h", "--help") for a in argv):
        argv.insert(0, "demo")  # no command: the demo (options before it are its options)
    a = p.parse_args(argv)
    for key, value in _COMMON_DEFAULTS.items():  # not set_defaults: the parents share these actions
        if not hasattr(a, key):
            setattr(a, key, value)
    methods = tuple(m for m in getattr(a, "methods", "").split(",") if m)
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
        elif a.command == "render":
            path = os.fspath(a.file)
            if not os.path.isfile(path):
                raise FileNotFoundError(f"{path}: no such file")
            kind = file_kind(path)
            if kind == "volume":
                _render_volume_file(path, a.out, a.size, a.threads)
            else:
                mesh = (matrixtree.read_mesh(path) if kind == "mesh" else
                        grid_surface(matrixtree.read_grid(path, zone=a.zone)))
                name = os.path.basename(path)[: -len(_extension(path)) or None]
                compare([mesh], name, a.out, a.size, None, a.threads, methods)
        elif a.command == "frames":
            if not os.path.isdir(a.folder):
                p.error("frames needs one FOLDER of mesh files with the same connectivity")
            files = sorted(f for ext in ("ply", "obj", "stl", "vtp", "vtk")
                           for f in glob.glob(os.path.join(a.folder, f"*.{ext}")))
            if not files:
                p.error(f"{a.folder} holds no mesh files (.ply .obj .stl .vtp .vtk)")
            print(f"reading {len(files)} frames from {a.folder}")
            frames = [matrixtree.read_mesh(f) for f in files]
            name = os.path.basename(os.path.normpath(a.folder))
            compare(frames, name, a.out, a.size, None, a.threads, methods)
        else:
            _locate(a)
    except (OSError, ValueError, RuntimeError, MemoryError) as e:
        print(f"error: {e or type(e).__name__}", file=sys.stderr)
        return 2
    print(f"done in {time.time() - t0:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())

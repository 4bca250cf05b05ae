#!/usr/bin/env python3
"""Speed against accuracy for every knob that changes an answer or its cost, on shipped real data,
and the stability table at the extremes: docs/speed_accuracy.md is this program's output.

    xvfb-run -a .venv/bin/python bench/tradeoffs.py --json out/tradeoffs.json --md docs/speed_accuracy.md

Each point of a curve is (CPU time, error) of one setting, measured in one run against a reference
at the highest precision the project has; times are process_time() medians over --repeats runs
with one thread, so the other processes on a shared machine slow the wall clock but not these.

- rays (horse.ply, closed; matrixtree_engine.SurfaceTree, the code under vtkMatrixTree):
  Moller-Trumbore against watertight. Half the rays are aimed from outside exactly at a mesh
  vertex: on a closed mesh each must hit at or before that vertex, so a miss is a leak and a
  later t a wrong first hit, with no reference needed; the other half are random rays through
  the bounding box, checked in exact rationals wherever the two tests disagree.
- point location (pipe_flow_tets.vtu; matrixtree_engine.CellLocator, the code under
  vtkMatrixTreeLocator): FindCell's tolerance tol2. Reference: a point is inside the grid when
  its closest point on the grid is at distance 0 (bench/stability.py bounds that query to a few
  ulp); errors are points outside answered (within the tolerance, so with a cell that does not
  contain them) and the interpolated Pressure error there.
- volume (headsq; matrixtree.render_volume, vtkMatrixTreeVolumeRayCaster): sample distance,
  image sample distance, early-termination threshold, double precision, and the bricks' bit depth
  (the scalars given as float32, uint16 or uint8: the brick storage follows the input type).
  Reference: 1/16 of the smallest spacing, double precision, no early termination. Error: PSNR
  and SSIM (bench/volume.py's) against it.
- tree shape (height, leaf scale, block size, exact vs bounding-box overlap, tree kind) for rays
  and FindCell: the answers are the same at every setting (checked, bit for bit); the curve is
  work (time) against memory, not accuracy.

Each knob's Pareto front is computed and its default marked on it; the markdown says for each
default whether it is on the front.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from fractions import Fraction

import numpy as np

from _common import ROOT, machine, markdown, write_json

import matrixtree  # noqa: E402  (path set by _common)
import matrixtree_engine as engine  # noqa: E402
from matrixtree import _quality  # noqa: E402
import stability  # noqa: E402
from matrixtree.volume import default_transfer_functions, frame_camera, read_volume  # noqa: E402
from vtkmodules.util.numpy_support import vtk_to_numpy  # noqa: E402
import pyvista as pv  # noqa: E402
from volume import Ours, psnr, ssim  # noqa: E402

DATA = os.path.join(ROOT, "..", "shared", "data")
EPS = float(np.finfo(float).eps)


def interleaved(fns: list, repeats: int):
    """([median CPU seconds of each fn], [each fn's last result]), the fns called round-robin
    so that load from other processes hits them alike."""
    times, outs = [[] for _ in fns], [None] * len(fns)
    for _ in range(repeats):
        for i, fn in enumerate(fns):
            t0 = time.process_time()
            outs[i] = fn()
            times[i].append(time.process_time() - t0)
    return [statistics.median(t) for t in times], outs


MARGIN = 0.05  # differences under 5% are within the timing noise of a shared machine


def pareto(points: list, x: str, y: str) -> None:
    """Marks each point 'front' True when no other point dominates it: at least as good on x and
    y (smaller is better on both, within MARGIN) and better by more than MARGIN on one."""
    def better(a, b):  # a clearly smaller than b
        return a < b * (1 - MARGIN) if b > 0 else a < b

    def no_worse(a, b):
        return a <= b * (1 + MARGIN) if b > 0 else a <= b

    for p in points:
        p["front"] = not any(q is not p and no_worse(q[x], p[x]) and no_worse(q[y], p[y])
                             and (better(q[x], p[x]) or better(q[y], p[y])) for q in points)


# ---- rays ------------------------------------------------------------------------------------

def mesh_arrays(path: str):
    poly = matrixtree.read_mesh(path)
    pts = vtk_to_numpy(poly.GetPoints().GetData()).astype(float)
    conn = vtk_to_numpy(poly.GetPolys().GetConnectivityArray()).astype(np.int64)
    return np.ascontiguousarray(pts), conn.reshape(-1, 3)


def ray_set(pts: np.ndarray, n: int, seed: int = 7):
    """n/2 rays from a sphere around the mesh aimed exactly at mesh vertices (t = 1 there), n/2
    random rays through the bounding box (unit length, t_max infinite)."""
    rng = np.random.default_rng(seed)
    lo, hi = pts.min(0), pts.max(0)
    centre, radius = (lo + hi) / 2, np.linalg.norm(hi - lo)
    u = rng.normal(size=(n, 3))
    origins = centre + radius * u / np.linalg.norm(u, axis=1, keepdims=True)
    half = n // 2
    aims = np.empty((n, 3))
    aims[:half] = pts[rng.integers(0, len(pts), half)]
    aims[half:] = lo + (hi - lo) * rng.random((n - half, 3))
    return np.ascontiguousarray(origins), np.ascontiguousarray(aims - origins), half


def bench_rays(args) -> dict:
    pts, tris = mesh_arrays(os.path.join(DATA, "meshes", "horse.ply"))
    o, d, half = ray_set(pts, args.rays)
    tree = stability.surface(pts, tris)
    tests = ("moller-trumbore", "watertight")
    secs, outs = interleaved([lambda k=k: tree.intersect(o, d, test=k) for k in tests], args.repeats)
    answers = {k: out[0] for k, out in zip(tests, outs)}
    points = [dict(knob="triangle test", value=k, default=k == "moller-trumbore", rays=len(o),
                   ns_per_ray=sec / len(o) * 1e9) for k, sec in zip(tests, secs)]
    # Suspects: an aimed ray that misses or hits after its vertex (the direction is rounded, so
    # the ray passes within an ulp of the vertex and a miss at a silhouette can be right), and a
    # random ray on which the two tests disagree by more than 4 ulp. Exact rationals decide each.
    tm, tw = answers["moller-trumbore"], answers["watertight"]
    aimed = np.arange(len(tm)) < half
    late = lambda t: ~(t <= 1 + 4 * EPS)
    with np.errstate(invalid="ignore"):
        differ = (np.isinf(tm) != np.isinf(tw)) | (np.abs(tm - tw) > 4 * EPS * np.abs(tw))
    suspects = np.nonzero((aimed & (late(tm) | late(tw))) | (~aimed & differ))[0]
    checked = suspects[: args.exact_checks]
    refs = {i: stability.exact_first_hit(o[i], d[i], pts, tris) for i in checked}
    for p in points:
        t = answers[p["value"]]
        leaks = wrong = touches = 0
        for i, ref in refs.items():
            bad = (ref is None) != np.isinf(t[i]) or (ref is not None and stability._rel(t[i], ref) > 1e-9)
            leaks += int(bad and ref is not None and np.isinf(t[i]))
            wrong += int(bad and not np.isinf(t[i]))
            near = ref is None or abs(ref - 1) <= Fraction(1, 10 ** 9) or abs(t[i] - 1) <= 1e-9
            touches += int(bad and i < half and near)
        rel = [stability._rel(t[i], ref) for i, ref in refs.items() if ref is not None and np.isfinite(t[i])
               and stability._rel(t[i], ref) <= 1e-9]
        p.update(suspects=int(len(suspects)), checked=int(len(checked)), missed=leaks, wrong_first_hit=wrong,
                 at_exact_vertex=touches, max_rel_dt=max(rel) if rel else 0.0,
                 errors_per_million=(leaks + wrong) / p["rays"] * 1e6)
    pareto(points, "ns_per_ray", "errors_per_million")
    return dict(mesh="horse.ply", triangles=len(tris), points=points)


# ---- point location --------------------------------------------------------------------------

def grid_arrays(path: str):
    grid = matrixtree.read_grid(path)
    pts = np.ascontiguousarray(vtk_to_numpy(grid.GetPoints().GetData()).astype(float))
    cells = grid.GetCells()
    off = vtk_to_numpy(cells.GetOffsetsArray()).astype(np.int64)
    conn = vtk_to_numpy(cells.GetConnectivityArray()).astype(np.int64)
    types = vtk_to_numpy(grid.GetCellTypesArray()).astype(np.uint8)
    field = vtk_to_numpy(grid.GetPointData().GetArray("Pressure")).astype(float)
    return pts, off, conn, types, field


def bench_find_cell(args) -> dict:
    pts, off, conn, types, pressure = grid_arrays(os.path.join(DATA, "cfd", "pipe_flow_tets.vtu"))
    loc = engine.CellLocator(pts, off, conn, types, threads=1)
    lo, hi = pts.min(0), pts.max(0)
    rng = np.random.default_rng(8)
    # Half the points in the bounding box, half within 2% of the box's diagonal of mesh points
    # (near the wall, where the tolerance decides).
    n = args.points
    x = np.empty((n, 3))
    x[: n // 2] = lo + (hi - lo) * rng.random((n // 2, 3))
    x[n // 2:] = pts[rng.integers(0, len(pts), n - n // 2)] + rng.normal(size=(n - n // 2, 3)) * 0.005 * np.linalg.norm(hi - lo)
    x = np.ascontiguousarray(x)
    _, _, dist2 = loc.closest_points(x)
    inside = dist2 == 0
    diag = float(np.linalg.norm(hi - lo))

    def interpolate(ids, w):
        val = np.full(len(ids), np.nan)
        for i in np.nonzero(ids >= 0)[0]:
            cell = conn[off[ids[i]]:off[ids[i] + 1]]
            val[i] = float(np.dot(w[i][: len(cell)], pressure[cell]))
        return val

    ref_ids, _, ref_w = loc.find_cells(x, 0.0, weights=True)
    ref_val = interpolate(ref_ids, ref_w)
    prange = float(pressure.max() - pressure.min())
    points = []
    rels = (0.0, 1e-6, 1e-4, 1e-2)
    secs, outs = interleaved([lambda r=r: loc.find_cells(x, (r * diag) ** 2, weights=True) for r in rels], args.repeats)
    for rel, sec, (ids, _, w) in zip(rels, secs, outs):
        tol2 = (rel * diag) ** 2
        outside_answered = int(((ids >= 0) & ~inside).sum())
        missed = int(((ids < 0) & inside).sum())
        val = interpolate(ids, w)
        both = np.isfinite(val) & np.isfinite(ref_val)
        points.append(dict(knob="FindCell tol2", value=f"({rel:g} diag)^2", tol2=tol2, default=rel == 0.0,
                           ns_per_point=sec / n * 1e9, outside_answered=outside_answered, missed_inside=missed,
                           wrong_per_million=(outside_answered + missed) / n * 1e6,
                           max_field_change=float(np.abs(val[both] - ref_val[both]).max() / prange) if both.any() else 0.0))
    pareto(points, "ns_per_point", "wrong_per_million")
    # IntersectWithLine's tolerance: segments from outside the bounding box to points near the
    # wall; tol = 0 is the reference (bounded against exact rationals in bench/stability.py).
    m = max(1, n // 4)
    p1 = np.ascontiguousarray(lo - (hi - lo) * 0.1 + (hi - lo) * 1.2 * (rng.random((m, 3)) < 0.5))
    p2 = np.ascontiguousarray(x[n // 2: n // 2 + m])
    ref_t, ref_c, _ = loc.first_hits(p1, p2, 0.0)
    seg = []
    rels = (0.0, 1e-6, 1e-4, 1e-3, 1e-2)
    secs, outs = interleaved([lambda r=r: loc.first_hits(p1, p2, r * diag) for r in rels], args.repeats)
    for rel, sec, (t, c, _) in zip(rels, secs, outs):
        tol = rel * diag
        hit, ref_hit = c >= 0, ref_c >= 0
        both = hit & ref_hit
        length = np.linalg.norm(p2 - p1, axis=1)
        with np.errstate(invalid="ignore"):  # inf - inf where both miss
            moved = both & (np.abs(t - ref_t) * length > 1e-9 * diag)
        seg.append(dict(knob="IntersectWithLine tol", value=f"{rel:g} diag", tol=tol, default=rel == 0.0,
                        ns_per_segment=sec / m * 1e6 * 1e3, added_hits=int((hit & ~ref_hit).sum()),
                        lost_hits=int((~hit & ref_hit).sum()),
                        moved_hits=int(moved.sum()), wrong_per_million=int(((hit != ref_hit) | moved).sum()) / m * 1e6,
                        max_dx_over_diag=float((np.abs(t[both] - ref_t[both]) * length[both]).max() / diag) if both.any() else 0.0))
    pareto(seg, "ns_per_segment", "wrong_per_million")
    return dict(grid="pipe_flow_tets.vtu", cells=len(types), points_queried=n, inside=int(inside.sum()),
                points=points, segments=seg, segments_queried=m)


# ---- volume ----------------------------------------------------------------------------------

def bench_volume(args) -> dict:
    image = read_volume(os.path.join(DATA, "volumes", "headsq.mhd"))
    scalars = vtk_to_numpy(image.GetPointData().GetScalars())
    sp = np.abs(np.array(image.GetSpacing()))
    ctf, otf = default_transfer_functions(image)
    cam = frame_camera(image)
    size = (args.volume_size, args.volume_size)
    half = 0.5 * float(sp.min())
    defaults = dict(SampleDistance=half, ImageSampleDistance=1.0, EarlyTerminationThreshold=0.99, DoublePrecision=False)
    lo, hi = float(scalars.min()), float(scalars.max())
    depths = {"float32": scalars.astype(np.float32),
              "uint16": ((scalars - lo) * (65535 / (hi - lo))).round().astype(np.uint16),
              "uint8": ((scalars - lo) * (255 / (hi - lo))).round().astype(np.uint8)}
    casters = {}
    for name, data in depths.items():
        im = pv.ImageData(dimensions=image.GetDimensions(), spacing=image.GetSpacing(), origin=image.GetOrigin())
        im.point_data["scalars"] = data
        # the same picture: the transfer functions mapped through the same range
        casters[name] = Ours(im, _rescaled(ctf, lo, hi, name), _rescaled(otf, lo, hi, name), float(sp.mean()), size, cam)
        casters[name].c.SetNumberOfThreads(1)
    ref = casters["float32"].frame(SampleDistance=float(sp.min()) / 16, DoublePrecision=True,
                                   EarlyTerminationThreshold=1.0)[1]

    def frame(caster, opts):
        caster.frame(**opts)  # the first frame after a change may classify: not timed
        times, img = [], None
        for _ in range(args.repeats):
            img = caster.frame(**opts)[1]
            times.append(caster.cpu_ms)
        return statistics.median(times), img

    knobs = [("sample distance (x half spacing)", "SampleDistance", [4.0, 2.0, 1.0, 0.5, 0.25], 1.0, lambda v: v * half),
             ("image sample distance", "ImageSampleDistance", [4.0, 2.0, 1.0], 1.0, float),
             ("early termination", "EarlyTerminationThreshold", [0.9, 0.95, 0.99, 1.0], 0.99, float),
             ("double precision", "DoublePrecision", [False, True], False, bool),
             ("bricks' bit depth", None, ["uint8", "uint16", "float32"], "float32", None)]
    families = []
    for name, key, values, default, conv in knobs:
        points = []
        for v in values:
            caster = casters[v] if key is None else casters["float32"]
            opts = dict(defaults) if key is None else {**defaults, key: conv(v)}
            ms, img = frame(caster, opts)
            p = psnr(img, ref)
            points.append(dict(knob=name, value=v, default=v == default, ms=ms, psnr=p, ssim=ssim(img, ref),
                               error=10 ** (-p / 10), bytes=caster.c.GetAllocatedBytes()))  # error: the MSE
        pareto(points, "ms", "error")
        families.append(points)
    # The quality= presets of render_volume (matrixtree._quality), measured like the knobs.
    points = []
    for q in _quality.QUALITIES:
        scale, isd, et = _quality.volume(q, None, 1.0, 0.99)
        ms, img = frame(casters["float32"], dict(defaults, SampleDistance=scale * half, ImageSampleDistance=isd,
                                                 EarlyTerminationThreshold=et))
        p = psnr(img, ref)
        points.append(dict(knob="quality preset", value=q, default=q == "balanced", ms=ms, psnr=p, ssim=ssim(img, ref),
                           error=10 ** (-p / 10), bytes=casters["float32"].c.GetAllocatedBytes()))
    pareto(points, "ms", "error")
    families.append(points)
    dims = image.GetDimensions()
    return dict(volume="headsq", dims=list(dims), size=list(size), knobs=families)


def _rescaled(fn, lo, hi, depth):
    """A copy of a colour or opacity transfer function with its node positions mapped from the
    scalar range [lo, hi] to the range of the quantized data (0..255, 0..65535; float32 keeps it)."""
    if depth == "float32":
        return fn
    top = 255.0 if depth == "uint8" else 65535.0
    color = hasattr(fn, "AddRGBPoint")
    nodes = []
    for i in range(fn.GetSize()):
        node = [0.0] * (6 if color else 4)
        fn.GetNodeValue(i, node)
        nodes.append(node)
    out = fn.NewInstance()
    for node in nodes:  # added anew: moving nodes one by one in place would reorder them
        x = (node[0] - lo) * top / (hi - lo)
        if color:
            out.AddRGBPoint(x, *node[1:])
        else:
            out.AddPoint(x, *node[1:])
    return out

# ---- tree shape: work against memory, the same answers -----------------------------------------

def bench_shape(args) -> dict:
    pts, tris = mesh_arrays(os.path.join(DATA, "meshes", "horse.ply"))
    o, d, _ = ray_set(pts, args.rays)
    gpts, off, conn, types, _ = grid_arrays(os.path.join(DATA, "cfd", "pipe_flow_tets.vtu"))
    lo, hi = gpts.min(0), gpts.max(0)
    x = np.ascontiguousarray(lo + (hi - lo) * np.random.default_rng(9).random((args.points, 3)))
    ray_knobs = [("tree kind", "tree", ["octree", "kdtree"], "octree"),
                 ("height (0 = automatic)", "height", [0, 5, 6, 7, 8], 0),
                 ("leaf scale", "leaf_scale", [0.5, 1.0, 2.0, 4.0, 8.0], 2.0),
                 ("block size", "block_size", [4, 8, 16], 8),
                 ("exact overlap", "exact", [False, True], True)]
    cell_knobs = [("tree kind", "tree", ["octree", "kdtree"], "octree"),
                  ("height (0 = automatic)", "height", [0, 5, 6, 7, 8], 0),
                  ("leaf scale (0 = automatic)", "leaf_scale", [0.0, 0.5, 1.0, 2.0, 4.0], 0.0),
                  ("max candidates (0 = automatic)", "max_candidates", [0.0, 4.0, 16.0, 64.0], 0.0),
                  ("block size", "block_size", [4, 8, 16], 8),
                  ("exact overlap", "exact_overlap", [False, True], False)]
    out = {"rays": [], "findcell": []}
    ref_rays = stability.surface(pts, tris).intersect(o, d)[:2]
    for name, key, values, default in ray_knobs:
        trees, builds = [], []
        for v in values:
            t0 = time.process_time()
            trees.append(engine.SurfaceTree(pts, np.arange(0, 3 * len(tris) + 1, 3, dtype=np.int64), tris.ravel(),
                                            np.zeros(0, np.int64), np.zeros(0, np.int64), threads=1, **{key: v}))
            builds.append(time.process_time() - t0)
        secs, outs = interleaved([lambda tr=tr: tr.intersect(o, d) for tr in trees], args.repeats)
        points = []
        for v, tree, build, sec, (t, cells, _, tests) in zip(values, trees, builds, secs, outs):
            st = tree.stats()
            same = bool(np.array_equal(t, ref_rays[0]) and np.array_equal(cells, ref_rays[1]))
            points.append(dict(knob=name, value=v, default=v == default, build_ms=build * 1e3,
                               ns_per_ray=sec / len(o) * 1e9, mbytes=(st["bytes"] + st["leaf_triangles_bytes"]) / 2 ** 20,
                               tests_per_ray=tests / len(o), same_answers=same))
        pareto(points, "ns_per_ray", "mbytes")
        out["rays"].append(points)
        del trees
    ref_ids = engine.CellLocator(gpts, off, conn, types, threads=1).find_cells(x)[0]
    for name, key, values, default in cell_knobs:
        locs, builds = [], []
        for v in values:
            t0 = time.process_time()
            locs.append(engine.CellLocator(gpts, off, conn, types, threads=1, **{key: v}))
            builds.append(time.process_time() - t0)
        secs, outs = interleaved([lambda lc=lc: lc.find_cells(x) for lc in locs], args.repeats)
        points = []
        for v, loc, build, sec, (ids, _, _) in zip(values, locs, builds, secs, outs):
            points.append(dict(knob=name, value=v, default=v == default, build_ms=build * 1e3,
                               ns_per_point=sec / len(x) * 1e9, mbytes=loc.stats()["bytes"] / 2 ** 20,
                               same_answers=bool(np.array_equal(ids, ref_ids))))
        pareto(points, "ns_per_point", "mbytes")
        out["findcell"].append(points)
        del locs
    return out


# ---- stability table -------------------------------------------------------------------------

MAGNITUDES = (1e-12, 1e-6, 1.0, 1e6, 1e12)


def locator_classes():
    """vtkMatrixTreeLocator and, for comparison, VTK's vtkStaticCellLocator."""
    from matrixtree_vtk import vtkMatrixTreeLocator
    from vtkmodules.vtkCommonDataModel import vtkStaticCellLocator

    return [("vtkMatrixTreeLocator", vtkMatrixTreeLocator), ("VTK's vtkStaticCellLocator", vtkStaticCellLocator)]


def stability_rows() -> list:
    rows = []
    places = [(s, 0.0) for s in MAGNITUDES] + [(4e-3, 1e8), (4e-3, 1e10)]
    for scale, offset in places:
        where = f"{scale:g}" + (f" at {offset:g}" if offset else "")
        for test in ("moller-trumbore", "watertight"):
            r = stability.rays_closed_sphere(test, scale, offset)
            rows.append(dict(path=f"ray/triangle, {test}", case="closed sphere, rays at vertices and edges",
                             magnitude=where, error=f"rel dt {r['rel_dt']:.1e}", failures=f"{r['leaks']}/{r['rays']} leak"))
        r = stability.find_cell(scale, offset)
        rows.append(dict(path="FindCell (engine)", case="jittered tetrahedra", magnitude=where,
                         error=f"dpcoords {r['dpcoords']:.1e}", failures=f"{r['wrong'] + r['missing']}/{r['points']} wrong"))
        for name, cls in locator_classes():
            r = stability.vtk_find_cell(cls(), scale, offset)
            rows.append(dict(path=f"FindCell, {name}", case="jittered tetrahedra", magnitude=where, error="-",
                             failures=f"{r['wrong'] + r['missing']}/{r['points']} wrong or missing"))
        r = stability.segment_first_hit(scale, offset)
        rows.append(dict(path="segment/cell (IntersectWithLine)", case="segments into the tetrahedra", magnitude=where,
                         error=f"dx/h {r['dx_over_h']:.1e}", failures=f"{r['missed']}/{r['segments']} missed"))
        r = stability.closest_point(scale, offset)
        rows.append(dict(path="closest point", case="points outside the tetrahedra", magnitude=where,
                         error=f"dx/h {r['dx_over_h']:.1e}", failures=f"{r['unanswered']}/{r['points']} unanswered"))
        r = stability.volume_sampling(scale / 4, offset)
        rows.append(dict(path="volume sampling", case="17^3 ball, camera scaled with it", magnitude=where,
                         error=f"max drgba {r['max_drgba']:.1e}", failures="-"))
    for angle in (1e-1, 1e-8, 1e-15):
        for test in ("moller-trumbore", "watertight"):
            r = stability.rays_grazing(test, angle)
            rows.append(dict(path=f"ray/triangle, {test}", case=f"grazing at {angle:g} rad through shared edges",
                             magnitude="1", error=f"rel dt {r['rel_dt']:.1e}", failures=f"{r['leaks']}/{r['rays']} leak"))
    for width in (1e-12, 3e-17, 1e-18):
        for test in ("moller-trumbore", "watertight"):
            r = stability.rays_needle(test, width)
            rows.append(dict(path=f"ray/triangle, {test}", case=f"needle of width {width:g}, length 1",
                             magnitude="1", error=f"rel dt {r['rel_dt']:.1e}", failures=f"{r['misses']}/{r['rays']} missed"))
    return rows


# ---- charts and markdown ---------------------------------------------------------------------

def _plot(ax, points, x, y, label, marker="o-"):
    xs, ys = [p[x] for p in points], [p[y] for p in points]
    line = ax.plot(xs, ys, marker, label=label, alpha=0.8)[0]
    for p in points:
        if p["default"]:
            ax.plot([p[x]], [p[y]], "*", color=line.get_color(), markersize=16, markeredgecolor="k")
            continue
        ax.annotate(str(p["value"]), (p[x], p[y]), fontsize=7, xytext=(3, 3), textcoords="offset points")


def _figure(size, xlabel, ylabel, title, log=False):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=size)
    return fig, ax, lambda: _finish(plt, fig, ax, xlabel, ylabel, title, log)


def _finish(plt, fig, ax, xlabel, ylabel, title, log):
    if log:
        ax.set_xscale("log")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=7)
    fig.tight_layout()
    return fig


def _save(fig, folder, name) -> str:
    import matplotlib.pyplot as plt

    fig.savefig(os.path.join(folder, name), dpi=110)
    plt.close(fig)
    return name


def charts(res: dict, folder: str) -> dict:
    os.makedirs(folder, exist_ok=True)
    files = {}
    r = res["rays"]
    fig, ax, done = _figure((6, 4), "CPU ns per ray (1 thread)", "wrong answers per million rays",
                            f"rays on {r['mesh']} ({r['triangles']} triangles); * = default")
    _plot(ax, r["points"], "ns_per_ray", "errors_per_million", "triangle test", "o")
    files["rays"] = _save(done(), folder, "tradeoffs_rays.png")

    f = res["findcell"]
    fig, ax, done = _figure((6, 4), "CPU ns per query (1 thread)", "wrong answers per million queries",
                            f"cell queries on {f['grid']}; * = default", log=True)
    _plot(ax, f["points"], "ns_per_point", "wrong_per_million", "FindCell tol2 (ns per point)")
    _plot(ax, f["segments"], "ns_per_segment", "wrong_per_million", "IntersectWithLine tol (ns per segment)")
    files["findcell"] = _save(done(), folder, "tradeoffs_findcell.png")

    v = res["volume"]
    fig, ax, done = _figure((7, 4.5), "CPU ms per frame (1 thread)", "PSNR against the reference (dB, higher is better)",
                            f"volume {v['volume']} at {v['size'][0]}^2; * = default", log=True)
    for points in v["knobs"]:
        _plot(ax, points, "ms", "psnr", points[0]["knob"])
    files["volume"] = _save(done(), folder, "tradeoffs_volume.png")

    for key, x, title in (("rays", "ns_per_ray", "rays (horse.ply)"),
                          ("findcell", "ns_per_point", "FindCell (pipe_flow_tets.vtu)")):
        fig, ax, done = _figure((6, 4.5), x.replace("_", " ") + " (CPU, 1 thread)", "MiB held",
                                f"tree shape, {title}: work, not accuracy")
        for points in res["shape"][key]:
            _plot(ax, points, x, "mbytes", points[0]["knob"])
        files["shape_" + key] = _save(done(), folder, f"tradeoffs_shape_{key}.png")
    return files


def front_lines(families: list) -> list:
    lines = []
    for points in families:
        d = [p for p in points if p["default"]]
        if d:
            knob = points[0]["knob"]
            on = "on" if d[0]["front"] else "**off**"
            why = "" if d[0]["front"] else " " + JUSTIFY.get(knob, "(no justification recorded: change this default)")
            lines.append(f"- {knob}: default {d[0]['value']} is {on} the front "
                         f"(front: {', '.join(str(p['value']) for p in points if p['front'])}).{why}")
    return lines

# Why a default that is off its knob's front stays the default (one sentence each), by knob.
JUSTIFY = {
    "triangle test": "Moller-Trumbore stays the default although watertight is as fast on the CPU (paired "
                     "CPU-time ratio watertight/MT 0.95-1.01 on horse, bunny and lucy, 21 interleaved rounds) "
                     "and leaks far less, because it is the only test the OpenCL kernels have: it is the one "
                     "default that draws the same picture on both backends (watertight with OpenCL is an error); "
                     "choose watertight for closed meshes on the CPU.",
    "height (0 = automatic)": "the automatic height follows each mesh's size by the rule docs/bench_height.md "
                              "measures over every shipped scene; a fixed height that suits this one scene cannot.",
    "leaf scale": "the default is the leaf size docs/trees.md measures over every shipped scene; coarser leaves "
                  "hold less here but test 2.5-7x more triangles per ray (tests_per_ray), a cost that grows with "
                  "the mesh.",
    "leaf scale (0 = automatic)": "the automatic leaf size follows the cells' sizes; a fixed one suits one grid.",
    "max candidates (0 = automatic)": "the automatic bound follows the cells' sizes; a fixed one suits one grid.",
    "exact overlap": "bounding-box overlap builds about 30% faster (build_ms), the cost a locator rebuilt every "
                     "frame pays, against about 10% less memory and the same query time with exact overlap.",
    "tree kind": "the octree builds about twice as fast as the kd-tree (build_ms), and their query times are "
                 "within a few percent of each other.",
    "FindCell tol2": "FindCell does not use tol2 for 3-D cells (as VTK 9.1's vtkStaticCellLocator: the cell's "
                     "EvaluatePosition decides, with its parametric tolerance), so every setting gives the same "
                     "answers by the same work, and the spread in time is noise.",
    "IntersectWithLine tol": "0 is the exact answer; a tolerance is a request for hits near the cells, not a "
                             "speed setting (it only adds work).",
    "block size": "8 is the block edge every other measurement of the project uses; 4 and 16 are within the "
                  "timing noise of it or slower.",
    "early termination": "0.99 is VTK's own default, so pictures match VTK's mappers at the same setting.",
    "bricks' bit depth": "the bricks are stored at the depth of the input, so the default is no default: the "
                         "row shows what quantizing the input before rendering would cost and save.",
}


STABILITY_NOTES = """\
Bounds the tests hold (tests/python/test_stability.py), at every magnitude from 1e-12 to 1e12 and
for cells of 1e-3 at 1e8:

- ray/triangle t: within 4 ulp of the exact t in both tests on these scenes (there is one
  precision, double, on the CPU and in the OpenCL kernels); on horse.ply's rays through its
  vertices within the rays table's `max_rel_dt` (about 1e-13: nearly grazing triangles). Watertight never leaks, at any magnitude, angle down to
  1e-15 rad, or on rays through shared vertices and edges. Moller-Trumbore (the default) lets a
  few rays aimed exactly at a shared vertex or edge pass between the neighbours (up to 16 of 318
  here; 5-8% of grazing rays aimed at shared edges), never a random ray: the documented price of
  its one-test-on-every-backend default; choose watertight where a leak matters. The OpenCL
  backend has Moller-Trumbore only and refuses watertight with an error.
- needles: both tests hit needles down to a width of 3e-17 at one unit from the ray origin.
  Below the rounding unit of that distance the watertight test, which moves the vertices to the
  ray origin first (Woop et al. 2013), sees a degenerate triangle and misses it; Moller-Trumbore
  keeps the edge vectors and still hits. Documented bound, not a fallback.
- FindCell: the right cell for every point, pcoords within 8 ulp of exact, through the engine
  and through vtkMatrixTreeLocator. VTK's vtkStaticCellLocator on the same tetrahedra at scale
  1e-12 finds no cell for almost every point (the table's row; its tolerances are absolute).
- segment/cell first hit and closest point: within 8 (4) rounding units of the largest
  coordinate: the error is the input's own quantization (dx/h grows as offset x 2^-52 / h: about
  1e-5 cells at an offset of 1e8 with cells of 1e-3, 1e-3 cells at 1e10), never a wrong or
  missing answer.
- volume sampling: the same picture bit for bit from spacing 1e-12 to 1e12 and at offsets up to
  1e8 (the marcher works in voxel coordinates); at 1e10 with voxels of 1e-3 (rounding unit 2e-3
  voxel) it differs by at most 1e-3 per channel.
"""


def write_markdown(path: str, res: dict, files: dict, cmd: str) -> None:
    folder = os.path.relpath(os.path.join(os.path.dirname(os.path.abspath(path)), "images"),
                             os.path.dirname(os.path.abspath(path)))
    r, f, v, s = res["rays"], res["findcell"], res["volume"], res["shape"]
    out = ["# Speed against accuracy", "",
           "Every knob that changes an answer or its cost, as (CPU time, error) against a reference at the",
           "highest precision the project has, with each knob's Pareto front and its default marked (a star",
           "in the charts); then where each numeric path breaks as coordinates grow. Regenerate with:", "",
           f"    {cmd}", "",
           f"Machine: {res['machine']['cpu']}, {res['machine']['cores']} cores, Python {res['machine']['python']}; "
           f"load average when it ran: {res['load']}. Times are CPU-time medians",
           f"over {res['repeats']} runs with one thread (process_time), so other processes add noise but no bias.",
           "Data: shipped real files (../shared/data).", "",
           "## Rays", "",
           f"{r['points'][0]['rays']} rays on {r['mesh']} ({r['triangles']} triangles, closed): half aimed from outside",
           "exactly at a mesh vertex (a miss is a leak, a t after the vertex a wrong first hit), half random",
           "through the bounding box. Exact rationals decide every suspect: an aimed ray that misses or hits",
           "after its vertex, a random ray on which the two tests differ by more than 4 ulp",
           f"({r['points'][0]['checked']} of {r['points'][0]['suspects']} suspects checked). `at_exact_vertex`: errors on",
           "rays that pass within rounding of the aimed vertex (a silhouette touch is decided by rounding in",
           "either test).", "",
           f"![rays]({folder}/{files['rays']})", "",
           markdown(r["points"], ["value", "default", "ns_per_ray", "checked", "missed", "wrong_first_hit",
                                  "at_exact_vertex", "max_rel_dt", "errors_per_million", "front"]), "",
           *front_lines([r["points"]]), "",
           "## Point location", "",
           f"FindCell on {f['grid']} ({f['cells']} tetrahedra), {f['points_queried']} points, half in the",
           "bounding box and half near the wall; a point is inside when its closest point on the grid is at",
           f"distance 0 ({f['inside']} are). Errors: points outside answered with a cell, points inside",
           "answered with none; `max_field_change`: the largest change of the interpolated Pressure against",
           "tol2 = 0, in units of the Pressure range. As in VTK 9.1, tol2 changes nothing for 3-D cells (the",
           "cell's parametric tolerance decides): the rows measure that it does not.", "",
           f"![findcell]({folder}/{files['findcell']})", "",
           markdown(f["points"], ["value", "default", "ns_per_point", "outside_answered", "missed_inside",
                                  "wrong_per_million", "max_field_change", "front"]), "",
           *front_lines([f["points"]]), "",
           f"IntersectWithLine (first hit) on the same grid: {f['segments_queried']} segments from outside the",
           "bounding box to the points near the wall; tol = 0 is the reference (bounded against exact",
           "rationals below). A tolerance accepts hits within it of a cell: `added_hits` are segments that",
           "miss the grid but are answered, `moved_hits` first hits moved by more than 1e-9 of the diagonal.", "",
           markdown(f["segments"], ["value", "default", "ns_per_segment", "added_hits", "lost_hits", "moved_hits",
                                    "max_dx_over_diag", "wrong_per_million", "front"]), "",
           *front_lines([f["segments"]]), "",
           "## Volume", "",
           f"{v['volume']} ({'x'.join(map(str, v['dims']))}) at {v['size'][0]}x{v['size'][1]}, default",
           "transfer functions and camera; one knob moved at a time from the defaults (sample distance half",
           "the smallest spacing, image sample distance 1, early termination 0.99, float compositing, float32",
           "bricks). Reference: 1/16 of the smallest spacing, double precision, no early termination.",
           "Bit depth: the scalars quantized to 8 or 16 bits over their range (transfer functions mapped",
           "alike); the bricks are stored at the input's depth. The last table: render_volume's `quality=`",
           "presets (matrixtree/_quality.py) measured the same way; render's presets are the triangle tests",
           "of the rays table (exact = watertight, balanced = fast = Moller-Trumbore).", "",
           f"![volume]({folder}/{files['volume']})", ""]
    for points in v["knobs"]:
        out += [markdown(points, ["knob", "value", "default", "ms", "psnr", "ssim", "bytes", "front"]), ""]
    out += [*front_lines(v["knobs"]), "",
            "## Tree shape: work, not accuracy", "",
            "Height, leaf scale, block size, tree kind and exact against bounding-box overlap change what a",
            "query costs and what the tree holds, never its answers (`same_answers`: bit for bit the",
            "default's t and cell ids, or cell ids). The fronts are time against memory.", "",
            f"![shape, rays]({folder}/{files['shape_rays']})", f"![shape, FindCell]({folder}/{files['shape_findcell']})", ""]
    for key, x in (("rays", "ns_per_ray"), ("findcell", "ns_per_point")):
        for points in s[key]:
            cols = ["knob", "value", "default", "build_ms", x, "mbytes"] + (["tests_per_ray"] if key == "rays" else [])
            out += [f"{key}:", "", markdown(points, cols + ["same_answers", "front"]), ""]
        out += [*front_lines(s[key]), ""]
    out += ["## Stability at the extremes", "",
            "Each path on a small scene scaled from 1e-12 to 1e12, and with cells of 1e-3 moved to 1e8 and",
            "1e10, against exact rational arithmetic on the doubles the library sees (bench/stability.py);",
            "the volume against the same scene at scale 1. `rel dt`: |t - t_exact| / t_exact; `dx/h`: the",
            "distance to the exact point over the cell size; `dpcoords`: the largest parametric error.", "",
            markdown(res["stability"], ["path", "case", "magnitude", "error", "failures"]), "",
            STABILITY_NOTES]
    with open(path, "w") as fh:
        fh.write("\n".join(out))


COMMAND = "xvfb-run -a .venv/bin/python bench/tradeoffs.py --json out/tradeoffs.json --md docs/speed_accuracy.md"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--json", default=os.path.join(ROOT, "out", "tradeoffs.json"))
    ap.add_argument("--md", help="write the markdown page here (charts into images/ beside it)")
    ap.add_argument("--rays", type=int, default=20000)
    ap.add_argument("--points", type=int, default=20000)
    ap.add_argument("--volume-size", type=int, default=192)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--exact-checks", type=int, default=400, help="rays checked in exact rationals, at most")
    ap.add_argument("--only", choices=["rays", "findcell", "volume", "shape", "stability"], action="append")
    ap.add_argument("--from-json", help="write --md from this earlier run's JSON instead of measuring")
    args = ap.parse_args()
    if args.from_json:
        import json

        res = json.load(open(args.from_json))
        files = charts(res, os.path.join(os.path.dirname(os.path.abspath(args.md)), "images"))
        write_markdown(args.md, res, files, COMMAND)
        print(f"wrote {args.md}")
        return 0
    only = set(args.only or ["rays", "findcell", "volume", "shape", "stability"])
    res = dict(machine=machine(), load=" ".join(f"{x:.1f}" for x in os.getloadavg()), repeats=args.repeats)
    steps = [("rays", bench_rays), ("findcell", bench_find_cell), ("volume", bench_volume), ("shape", bench_shape),
             ("stability", lambda a: stability_rows())]
    for name, fn in steps:
        if name in only:
            t0 = time.time()
            res[name] = fn(args)
            print(f"[tradeoffs] {name}: {time.time() - t0:.0f} s", file=sys.stderr, flush=True)
    res["load_after"] = " ".join(f"{x:.1f}" for x in os.getloadavg())
    write_json(args.json, res)
    print(f"wrote {args.json}")
    if args.md and only == {"rays", "findcell", "volume", "shape", "stability"}:
        files = charts(res, os.path.join(os.path.dirname(os.path.abspath(args.md)), "images"))
        write_markdown(args.md, res, files, COMMAND)
        print(f"wrote {args.md}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

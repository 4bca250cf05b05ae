"""The paper's ray-tracing experiment (§6, Table 1, Figures 1 and 6) on this machine.

Every tree/traversal pair renders the same frames through one C++ renderer (build/bin/rays_bench:
pinhole camera, primary rays plus one shadow ray per hit towards a point light, Lambert shading,
OpenMP over image rows): matrix octree and regular kd-tree (matrix traversal), and the SAH kd-tree
with KD-Restart, a full stack and a short stack; each with the Moller-Trumbore and the watertight
ray/triangle test, and with the same leaf tests on the same pre-gathered leaf triangles
(``--leaves payload``; ``mesh``: through the ids to the mesh; ``both``: rows for each). The timed
renders run without counters; node visits and triangle tests come from one more, counted render.
Dynamic scenes rebuild every tree (and its leaf triangles) every frame. Embree is the outside
reference: Embree 3 from C++ through the same renderer when rays_bench was built with Debian's
libembree-dev (its default build, its fastest rebuild ``low``: RTC_SCENE_FLAG_DYNAMIC with
RTC_BUILD_QUALITY_LOW, and for animations ``refit``), and Embree 4 (the ``embreex`` package),
Python-driven, on the same primary rays and the same kind of shadow rays.

    .venv/bin/python bench/rays.py                         # every default scene
    .venv/bin/python bench/rays.py --scene ../shared/data/meshes/bunny.ply --json out/bunny.json
    .venv/bin/python bench/rays.py --scene ../shared/data/animated/horse_poses --frames 30
    .venv/bin/python bench/rays.py --scene ben-deformed --frames 30
    .venv/bin/python bench/rays.py --scene bunny --backend all   # + the OpenCL device's rows
    .venv/bin/python bench/rays.py --generated 1e3,1e4,1e5,1e6 --threads 1 --clock cpu  # generated meshes

``--scene`` takes a mesh file, a folder of frames with the same connectivity (interpolated in
time with Catmull-Rom splines to ``--frames`` frames), or ``ben-deformed`` (Utah Ben bent and
twisted over time), or ``gen:SHAPE:N`` (a generated mesh of about N triangles, see
bench/gen_scenes.py: ``sphere``, ``terrain``, ``scatter``); ``--generated N1,N2,..`` adds every
shape at each size (above 2e6 triangles only with ``--huge``: about 16 GB at 1e7 with every
method, 10 GB with ``--methods octree,sah-stack --no-embree``). The
brute-force check uses ``--samples`` pixels up to 1e6 triangles, fewer above (2e9 / triangles, at
least 100). Rows go to ``--json``; ``--md`` writes the markdown table, ``--chart`` the
speed-up chart and ``--heatmaps`` the node-visit and triangle-test heat maps of the first frame.
``--backend opencl|all`` adds (or keeps only) the matrix trees built and traced on an OpenCL device
(``--device`` picks it): rows with ``backend`` "opencl", the device's name, and their first hits
compared with the CPU engine's render of the same frame (``mismatches_vs_cpu``).
"""

from __future__ import annotations

import argparse
import glob
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

import gen_scenes
from _common import ROOT, machine, markdown, require_driver, table  # noqa: F401  (sys.path set up there)
from matrixtree import scenes

try:
    from tqdm import tqdm
except ImportError:  # pragma: no cover
    tqdm = None

BIN = os.path.join(os.environ.get("MATRIXTREE_BUILD", os.path.join(ROOT, "build")), "bin", "rays_bench")

# Camera direction (from the target towards the eye) and up axis per scene; the distance is
# fitted to the scene's bounding sphere. Scenes not listed look from +z with +y up.
VIEWS = {
    "utah_hand": ((0.3, 0.4, 1.0), (0, 1, 0)),
    "utah_ben": ((0.5, 0.35, 1.0), (0, 1, 0)),
    "ben_deformed": ((0.5, 0.35, 1.0), (0, 1, 0)),
    "bunny": ((0.2, 0.25, 1.0), (0, 1, 0)),
    "lucy": ((0.0, -1.0, 0.25), (0, 0, 1)),
    "turbineblade": ((1.0, 0.6, 0.8), (0, 0, 1)),
    "nefertiti": ((0.0, -1.0, 0.2), (0, 0, 1)),
    "horse": ((1.0, 0.3, 0.6), (0, 1, 0)),
    "horse_animated": ((0.4, 0.25, 1.0), (0, 1, 0)),
    "terrain": ((0.5, 0.7, 1.0), (0, 1, 0)),  # generated scenes: keyed by shape, whatever the size
    "scatter": ((0.3, 0.4, 1.0), (0, 1, 0)),
}
#: generated scenes above this many triangles need --huge (memory on a shared machine)
HUGE_TRIANGLES = 2_000_000
#: the brute-force check's budget: samples x triangles (1e6 triangles keep 2,000 samples)
BRUTE_FORCE_TESTS = 2e9

DEFAULT_SCENES = ["utah_hand", "utah_ben", "bunny", "lucy", "turbineblade", "nefertiti", "horse",
                  "horse_animated", "ben_deformed"]

COLS = ["scene", "triangles", "frames", "method", "traversal", "test", "leaves", "backend", "device", "build_ms",
        "render_ms", "build_cpu_ms", "render_cpu_ms", "mrays_per_s", "node_visits_per_ray", "tri_tests_per_ray",
        "ns_per_visit", "miss_ns_per_ray", "tree_mb", "leaf_mb", "speedup_vs_sah_stack", "frame_speedup_vs_sah_stack",
        "mismatches_vs_brute_force", "mismatches_vs_cpu"]


# ---------------------------------------------------------------------------------------------
# Scenes
# ---------------------------------------------------------------------------------------------
def _mesh_arrays(path: str):
    """Points (n, 3) float64 and triangles (m, 3) uint32 of a mesh file (triangulated)."""
    from vtkmodules.util.numpy_support import vtk_to_numpy

    pd = scenes_read(path)
    pts = vtk_to_numpy(pd.GetPoints().GetData()).astype(np.float64)
    conn = vtk_to_numpy(pd.GetPolys().GetConnectivityArray()).astype(np.int64)
    offs = vtk_to_numpy(pd.GetPolys().GetOffsetsArray()).astype(np.int64)
    if not np.all(np.diff(offs) == 3):
        raise ValueError(f"{path}: expected triangles only after triangulation")
    return pts, conn.reshape(-1, 3).astype(np.uint32)


def scenes_read(path: str):
    import matrixtree

    return matrixtree.read_mesh(path)


def _frame_arrays(path: str):
    """A frame of a sequence: triangulated but never merged, so every frame keeps the file's own
    vertex numbering (merging could fuse vertices in one pose and not in another)."""
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkFiltersCore import vtkTriangleFilter
    from vtkmodules.vtkIOGeometry import vtkOBJReader
    from vtkmodules.vtkIOPLY import vtkPLYReader

    ext = os.path.splitext(path)[1].lower()
    reader = vtkOBJReader() if ext == ".obj" else vtkPLYReader() if ext == ".ply" else None
    if reader is None:
        import matrixtree

        pd = matrixtree.read_mesh(path)
    else:
        reader.SetFileName(path)
        tri = vtkTriangleFilter()
        tri.SetInputConnection(reader.GetOutputPort())
        tri.PassVertsOff()
        tri.PassLinesOff()
        tri.Update()
        pd = tri.GetOutput()
    pts = vtk_to_numpy(pd.GetPoints().GetData()).astype(np.float64)
    conn = vtk_to_numpy(pd.GetPolys().GetConnectivityArray()).astype(np.uint32).reshape(-1, 3)
    return pts, conn


def catmull_rom(keys: list, n: int) -> list:
    """n frames through the key poses (arrays of equal shape), uniform in time from the first key
    to the last, on a Catmull-Rom spline (C1: no velocity jumps at the keys)."""
    k = len(keys)
    if k == 1 or n == 1:
        return [keys[0].copy() for _ in range(n)]
    out = []
    for f in range(n):
        s = f * (k - 1) / (n - 1)
        i = min(int(s), k - 2)
        u = s - i
        p0, p1, p2, p3 = keys[max(i - 1, 0)], keys[i], keys[i + 1], keys[min(i + 2, k - 1)]
        u2, u3 = u * u, u * u * u
        out.append(0.5 * ((2 * p1) + (-p0 + p2) * u + (2 * p0 - 5 * p1 + 4 * p2 - p3) * u2
                          + (-p0 + 3 * p1 - 3 * p2 + p3) * u3))
    return out


def deform_ben(points: np.ndarray, n: int) -> list:
    """Utah Ben bent and twisted over n frames: a twist about the vertical (y) axis growing with
    height and a sideways sway, both oscillating in time (one full period over the sequence), so
    every frame moves every vertex and the tree must be rebuilt."""
    lo, hi = points.min(axis=0), points.max(axis=0)
    c = 0.5 * (lo + hi)
    h = (points[:, 1] - lo[1]) / max(hi[1] - lo[1], 1e-30)  # 0 at the feet, 1 at the head
    frames = []
    for f in range(n):
        ph = 2 * np.pi * f / max(n, 1)
        ang = 0.6 * np.sin(ph) * h ** 2
        x, z = points[:, 0] - c[0], points[:, 2] - c[2]
        ca, sa = np.cos(ang), np.sin(ang)
        p = points.copy()
        p[:, 0] = c[0] + ca * x - sa * z + 0.15 * (hi[1] - lo[1]) * np.sin(ph) * h ** 3
        p[:, 2] = c[2] + sa * x + ca * z
        frames.append(p)
    return frames


def load_scene(spec: str, n_frames: int):
    """(name, triangles (m, 3) uint32, [points (n, 3) float64 per frame])."""
    if spec.startswith("gen:"):
        try:
            _, shape, n = spec.split(":")
            n = int(float(n))
            pts, tris = gen_scenes.generate(shape, n)
        except ValueError as e:
            raise SystemExit(f"--scene {spec}: expected gen:SHAPE:N with SHAPE in "
                             f"{', '.join(gen_scenes.SHAPES)} and N triangles ({e})") from None
        return f"{shape}_{gen_scenes.label(n)}", tris, [pts] * max(n_frames, 1)
    real = scenes.real_scenes()
    if spec in ("ben-deformed", "ben_deformed"):
        pts, tris = _mesh_arrays(real["utah_ben"])
        return "ben_deformed", tris, deform_ben(pts, max(n_frames, 1))
    if spec in ("horse_animated", "horse-animated"):
        spec = os.path.join(scenes.data_dir(), "animated", "horse_poses")
        name = "horse_animated"
    elif spec in real:
        name, spec = spec, real[spec]
    else:
        name = os.path.splitext(os.path.basename(os.path.normpath(spec)))[0]
        if name == "horse_poses":
            name = "horse_animated"
    if os.path.isdir(spec):
        files = sorted(f for ext in ("obj", "ply", "vtp", "vtk", "stl")
                       for f in glob.glob(os.path.join(spec, f"*.{ext}")))
        if not files:
            raise SystemExit(f"--scene {spec}: the folder holds no mesh files")
        keys, tris = [], None
        for f in files:
            p, t = _frame_arrays(f)
            if tris is None:
                tris = t
            elif t.shape != tris.shape or not np.array_equal(t, tris):
                raise SystemExit(f"--scene {spec}: {os.path.basename(f)} has a different connectivity "
                                 f"from {os.path.basename(files[0])}; frames must share it")
            if p.shape != keys[0].shape if keys else False:
                raise SystemExit(f"--scene {spec}: {os.path.basename(f)} has a different point count")
            keys.append(p)
        return name, tris, catmull_rom(keys, max(n_frames, 1) if n_frames else max(30, len(keys)))
    if not os.path.exists(spec):
        raise SystemExit(f"--scene {spec}: no such file or folder (or known scene name: "
                         f"{', '.join(sorted(real))}, horse_animated, ben-deformed)")
    pts, tris = _mesh_arrays(spec)
    return name, tris, [pts] * max(n_frames, 1)


def fit_camera(name: str, frames: list, size, fovy: float = 30.0):
    lo = np.min([f.min(axis=0) for f in frames], axis=0)
    hi = np.max([f.max(axis=0) for f in frames], axis=0)
    c, r = 0.5 * (lo + hi), 0.5 * np.linalg.norm(hi - lo)
    d, up = VIEWS.get(name, VIEWS.get(name.rsplit("_", 1)[0], ((0.0, 0.0, 1.0), (0, 1, 0))))
    d = np.asarray(d, float) / np.linalg.norm(d)
    aspect = size[0] / size[1]
    half = np.radians(fovy) / 2
    half_min = min(half, np.arctan(np.tan(half) * aspect))
    dist = 1.02 * r / np.sin(half_min)
    return {"eye": c + d * dist, "target": c, "up": np.asarray(up, float), "fovy": fovy,
            "width": int(size[0]), "height": int(size[1])}


def write_scene_file(path: str, tris: np.ndarray, frames: list, cam: dict) -> None:
    with open(path, "wb") as f:
        f.write(b"MTSCENE1")
        f.write(np.array([frames[0].shape[0], tris.shape[0], len(frames), cam["width"], cam["height"]],
                         dtype="<u4").tobytes())
        f.write(np.concatenate([cam["eye"], cam["target"], cam["up"], [cam["fovy"]]]).astype("<f8").tobytes())
        f.write(np.ascontiguousarray(tris, dtype="<u4").tobytes())
        for p in frames:
            f.write(np.ascontiguousarray(p, dtype="<f8").tobytes())


# ---------------------------------------------------------------------------------------------
# Embree: the same camera rays (render.h's PinholeRays) and the same shading/shadow rule
# ---------------------------------------------------------------------------------------------
def pinhole_directions(cam: dict) -> np.ndarray:
    eye, target, up0 = cam["eye"], cam["target"], cam["up"]
    W, H = cam["width"], cam["height"]
    fwd = (target - eye) / np.linalg.norm(target - eye)
    right = np.cross(fwd, up0)
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    th = np.tan(0.5 * np.radians(cam["fovy"]))
    xs = (2.0 * (np.arange(W) + 0.5) / W - 1.0) * th * (W / H)
    ys = (2.0 * (np.arange(H) + 0.5) / H - 1.0) * th
    d = fwd[None, None, :] + xs[None, :, None] * right[None, None, :] + ys[:, None, None] * up[None, None, :]
    d /= np.linalg.norm(d, axis=2, keepdims=True)
    return d.reshape(-1, 3), right, up


def embree_available() -> bool:
    try:
        import embreex  # noqa: F401
        return True
    except ImportError:
        return False


def _embree_run(scene, o, d, dists=None, query="INTERSECT", output=None, threads=1):
    """embreex traces in one thread per call; split the rays over `threads` Python threads (the
    calls release the GIL only if embreex does; measured, not assumed)."""
    if threads <= 1:
        return scene.run(o, d, dists=dists, query=query, output=output)
    from concurrent.futures import ThreadPoolExecutor

    chunks = np.array_split(np.arange(len(o)), threads)
    with ThreadPoolExecutor(threads) as ex:
        parts = list(ex.map(lambda idx: scene.run(o[idx], d[idx], dists=None if dists is None else dists[idx],
                                                  query=query, output=output), chunks))
    if output:
        return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
    return np.concatenate(parts)


def run_embree(tris: np.ndarray, frames: list, cam: dict, reference: dict, threads: int) -> dict:
    from embreex import rtcore_scene as rtcs
    from embreex.mesh_construction import TriangleMesh

    dirs, right, up = pinhole_directions(cam)
    d32 = dirs.astype(np.float32)
    o32 = np.broadcast_to(cam["eye"].astype(np.float32), d32.shape).copy()
    faces = tris.astype(np.int32)
    builds, renders, rays, mism = [], [], [], 0
    builds_cpu, renders_cpu = [], []
    for fi, pts in enumerate(frames):
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        diag = max(np.linalg.norm(hi - lo), 1e-300)
        eps = 1e-7 * diag + 1e-9 * np.linalg.norm(0.5 * (lo + hi))
        light = cam["eye"] + up * (0.5 * diag) + right * (0.3 * diag)
        t0, c0 = time.perf_counter(), time.process_time()
        scene = rtcs.EmbreeScene()
        TriangleMesh(scene, pts.astype(np.float32), faces)
        scene.run(o32[:1], d32[:1])  # the BVH is built at the first query (rtcCommitScene)
        builds.append(1e3 * (time.perf_counter() - t0))
        builds_cpu.append(1e3 * (time.process_time() - c0))

        t0, c0 = time.perf_counter(), time.process_time()
        res = _embree_run(scene, o32, d32, output=1, threads=threads)
        prim = res["primID"]
        hit = prim >= 0
        tt = res["tfar"]
        # Shadow rays from the hits, offset along the face normal towards the viewer.
        p = cam["eye"][None, :] + dirs[hit] * tt[hit, None].astype(np.float64)
        ng = res["Ng"][hit].astype(np.float64)
        ng /= np.maximum(np.linalg.norm(ng, axis=1, keepdims=True), 1e-300)
        flip = np.sum(ng * dirs[hit], axis=1) > 0
        ng[flip] *= -1
        to_l = light[None, :] - p
        dist_l = np.linalg.norm(to_l, axis=1)
        l_dir = to_l / dist_l[:, None]
        lit = np.sum(ng * l_dir, axis=1) > 0
        so = (p + ng * eps)[lit].astype(np.float32)
        sd = l_dir[lit].astype(np.float32)
        occl = _embree_run(scene, so, sd, dists=dist_l[lit].astype(np.float32), query="OCCLUDED",
                           threads=threads)
        renders.append(1e3 * (time.perf_counter() - t0))
        renders_cpu.append(1e3 * (time.process_time() - c0))
        rays.append(len(d32) + len(so))
        del occl
        if fi == 0 and reference and reference.get("pixels"):
            px = np.asarray(reference["pixels"])
            rp = np.asarray(reference["prim"])
            rt = np.asarray(reference["t"])
            gp = prim[px]
            gt = tt[px].astype(np.float64)
            same = gp == rp
            # float32 rays: a different triangle at the same t (edge ties) within 1e-5 relative
            tie = (gp >= 0) & (rp >= 0) & (np.abs(gt - rt) <= 1e-5 * np.maximum(1.0, np.abs(rt)))
            mism = int(np.sum(~(same | tie)))
    return {"method": "embree", "traversal": "bvh", "test": "embree-float",
            "build_ms": float(np.mean(builds)), "render_ms": float(np.mean(renders)),
            "build_cpu_ms": float(np.mean(builds_cpu)), "render_cpu_ms": float(np.mean(renders_cpu)),
            "rays": float(np.mean(rays)), "node_visits_per_ray": None, "tri_tests_per_ray": None,
            "mismatches_vs_brute_force": mism, "rays_checked": len(reference.get("pixels", [])),
            "build_ms_frames": builds, "render_ms_frames": renders, "embree_threads": threads}


# ---------------------------------------------------------------------------------------------
# Pictures
# ---------------------------------------------------------------------------------------------
def write_heatmaps(name: str, cam: dict, raw_dir: str, out_dir: str, rows: list) -> list:
    """One figure per scene: the render and the per-pixel node visits and triangle tests (primary
    + shadow ray) of the matrix octree and the SAH kd-tree with a stack (the paper's Figure 1),
    on one colour scale per quantity."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    W, H = cam["width"], cam["height"]
    pick = [("matrix-octree-matrix-mt", "matrix octree"), ("matrix-kdtree-matrix-mt", "matrix kd-tree"),
            ("sah-stack-mt", "SAH kd-tree, stack")]
    have = [(k, lab) for k, lab in pick if os.path.exists(os.path.join(raw_dir, k + ".visits"))]
    if not have:
        return []
    data = {}
    for k, _ in have:
        v = np.fromfile(os.path.join(raw_dir, k + ".visits"), dtype=np.uint32).reshape(H, W)[::-1]
        t = np.fromfile(os.path.join(raw_dir, k + ".tests"), dtype=np.uint32).reshape(H, W)[::-1]
        rgb = np.fromfile(os.path.join(raw_dir, k + ".rgb"), dtype=np.uint8).reshape(H, W, 3)[::-1]
        data[k] = (rgb, v, t)
    vmax_v = max(np.percentile(d[1], 99.5) for d in data.values())
    vmax_t = max(np.percentile(d[2], 99.5) for d in data.values())
    fig, axes = plt.subplots(len(have), 3, figsize=(10.5, 3.5 * len(have)), squeeze=False)
    by = {(r["method"] + "-" + r["traversal"] + "-" + r["test"]): r for r in rows}
    for i, (k, lab) in enumerate(have):
        rgb, v, t = data[k]
        r = by.get(k, {})
        axes[i][0].imshow(rgb)
        axes[i][0].set_title(f"{lab}: {r.get('render_ms', 0):.0f} ms")
        im1 = axes[i][1].imshow(v, cmap="inferno", vmin=0, vmax=vmax_v)
        axes[i][1].set_title(f"node visits ({r.get('node_visits_per_ray', 0):.1f}/ray)")
        im2 = axes[i][2].imshow(t, cmap="viridis", vmin=0, vmax=vmax_t)
        axes[i][2].set_title(f"triangle tests ({r.get('tri_tests_per_ray', 0):.1f}/ray)")
        fig.colorbar(im1, ax=axes[i][1], fraction=0.046)
        fig.colorbar(im2, ax=axes[i][2], fraction=0.046)
        for a in axes[i]:
            a.set_xticks([])
            a.set_yticks([])
    fig.suptitle(f"{name}: per-pixel work, primary + shadow ray (same colour scale per column)")
    fig.tight_layout()
    os.makedirs(out_dir, exist_ok=True)
    path = os.path.join(out_dir, f"rays_heatmap_{name}.png")
    fig.savefig(path, dpi=80)
    plt.close(fig)
    return [path]


SUMMARY_COLS = ["scene", "triangles", "frames", "octree_render_x", "kdtree_render_x", "shortstack_render_x",
                "restart_render_x", "octree_mesh_render_x", "embree_render_x", "embree_low_render_x",
                "octree_frame_x", "octree_frame_vs_embree", "octree_frame_vs_embree_low", "octree_frame_vs_embree_refit",
                "octree_frame_vs_embreex", "visits_octree", "visits_sah", "tests_octree", "tests_sah",
                "ns_step_octree", "ns_visit_sah", "miss_ns_octree", "miss_ns_sah", "octree_mb", "sah_mb", "mismatches"]


def summary_rows(rows: list, clock: str = "cpu") -> list:
    """One row per scene: speed-ups over the SAH kd-tree with a stack (Moller-Trumbore rows, CPU
    back end, both on the leaf triangles; octree_mesh_render_x: both without them), render only
    (_render_x) and build + render per frame (_frame_x); the matrix octree's frame against
    Embree's (Embree 3 from C++: its default build, its low-quality dynamic rebuild, its refit;
    embreex: Embree 4 driven from Python), > 1 where the octree is faster; the work per ray of
    the octree and the SAH tree, the time per node visit (the render time over the visits), the
    in-box misses alone (ns per ray), and memory (tree + leaf triangles, MB)."""
    out = []
    scenes_seen = []
    for r in rows:
        if r["scene"] not in scenes_seen:
            scenes_seen.append(r["scene"])
    bk, rk = ("build_cpu_ms", "render_cpu_ms") if clock == "cpu" else ("build_ms", "render_ms")
    for sc in scenes_seen:
        rs = [r for r in rows if r["scene"] == sc and r.get("backend", "cpu") == "cpu"
              and r["test"] in ("mt", "embree-float")]
        if not rs:  # --backend opencl: no CPU rows to summarise
            continue

        def row(m, t, leaves="payload"):
            v = [r for r in rs if r["method"] == m and r["traversal"] == t
                 and r.get("leaves", leaves) in (leaves, "embree")]
            return v[0] if v else None

        def get(m, t, k, leaves="payload"):
            r = row(m, t, leaves)
            return round(r[k], 2) if r and r.get(k) is not None else None

        def frame(r):
            return r[bk] + r[rk] if r else None

        oc = row("matrix-octree", "matrix")
        sah = row("sah", "stack")

        def vs(m, t):  # the octree's frame against another method's: > 1 = octree faster
            other = row(m, t)
            return round(frame(other) / frame(oc), 2) if other and oc else None

        def mb(r):
            return round((r.get("bytes", 0) + r.get("payload_bytes", 0)) / 1e6, 1) if r else None

        out.append({"scene": sc, "triangles": rs[0]["triangles"], "frames": rs[0]["frames"],
                    "octree_render_x": get("matrix-octree", "matrix", "speedup_vs_sah_stack"),
                    "kdtree_render_x": get("matrix-kdtree", "matrix", "speedup_vs_sah_stack"),
                    "shortstack_render_x": get("sah", "shortstack", "speedup_vs_sah_stack"),
                    "restart_render_x": get("sah", "restart", "speedup_vs_sah_stack"),
                    "octree_mesh_render_x": get("matrix-octree", "matrix", "speedup_vs_sah_stack", "mesh"),
                    "embree_render_x": get("embree3", "bvh-default", "speedup_vs_sah_stack"),
                    "embree_low_render_x": get("embree3", "bvh-low", "speedup_vs_sah_stack"),
                    "octree_frame_x": get("matrix-octree", "matrix", "frame_speedup_vs_sah_stack"),
                    "octree_frame_vs_embree": vs("embree3", "bvh-default"),
                    "octree_frame_vs_embree_low": vs("embree3", "bvh-low"),
                    "octree_frame_vs_embree_refit": vs("embree3", "bvh-refit"),
                    "octree_frame_vs_embreex": vs("embree", "bvh"),
                    "visits_octree": get("matrix-octree", "matrix", "node_visits_per_ray"),
                    "visits_sah": get("sah", "stack", "node_visits_per_ray"),
                    "tests_octree": get("matrix-octree", "matrix", "tri_tests_per_ray"),
                    "tests_sah": get("sah", "stack", "tri_tests_per_ray"),
                    "ns_step_octree": get("matrix-octree", "matrix", "ns_per_visit"),
                    "ns_visit_sah": get("sah", "stack", "ns_per_visit"),
                    "miss_ns_octree": get("matrix-octree", "matrix", "miss_ns_per_ray"),
                    "miss_ns_sah": get("sah", "stack", "miss_ns_per_ray"),
                    "octree_mb": mb(oc), "sah_mb": mb(sah),
                    "mismatches": sum(int(r.get("mismatches_vs_brute_force") or 0) for r in rows
                                      if r["scene"] == sc)})
    return out


def write_chart(rows: list, path: str) -> str:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sc = []
    for r in rows:
        if r["scene"] not in sc:
            sc.append(r["scene"])
    series = [("matrix-octree", "matrix", "matrix octree"), ("matrix-kdtree", "matrix", "matrix kd-tree"),
              ("sah", "shortstack", "SAH short stack"), ("sah", "restart", "SAH KD-Restart"),
              ("embree3", "bvh-default", "Embree 3, default build (C++)"),
              ("embree3", "bvh-low", "Embree 3, low-quality dynamic build (C++)"),
              ("embree", "bvh", "Embree 4 (embreex, Python-driven)")]
    fig, axes = plt.subplots(1, 2, figsize=(13, 4.5))
    x = np.arange(len(sc))
    w = 0.8 / len(series)
    for key, ax, title in (("speedup_vs_sah_stack", axes[0], "render time: SAH-stack / method"),
                           ("frame_speedup_vs_sah_stack", axes[1],
                            "build + render per frame: SAH-stack / method")):
        for j, (m, tr, lab) in enumerate(series):
            vals = []
            for s in sc:
                v = [r.get(key) for r in rows if r["scene"] == s and r["method"] == m and r["traversal"] == tr
                     and r["test"] in ("mt", "embree-float") and r.get("leaves", "payload") in ("payload", "embree")
                     and r.get("backend", "cpu") == "cpu"]
                vals.append(v[0] if v and v[0] is not None else 0)
            ax.bar(x + (j - len(series) / 2 + 0.5) * w, vals, w, label=lab)
        ax.axhline(1.0, color="k", lw=0.8)
        ax.axhline(1.45, color="r", lw=0.8, ls="--", label="paper's lowest CPU speed-up (1.45)")
        ax.set_xticks(x)
        ax.set_xticklabels(sc, rotation=30, ha="right")
        ax.set_title(title)
        ax.set_ylabel("x faster than SAH kd-tree with a stack")
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=4, fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0.12, 1, 1))
    os.makedirs(os.path.dirname(path) or ".", exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


# ---------------------------------------------------------------------------------------------
def run_scene(spec: str, args, heat_out: str | None) -> list:
    name, tris, frames = load_scene(spec, args.frames)
    cam = fit_camera(name, frames, args.size)
    with tempfile.TemporaryDirectory() as tmp:
        scene_bin = os.path.join(tmp, "scene.bin")
        out_json = os.path.join(tmp, "out.json")
        write_scene_file(scene_bin, tris, frames, cam)
        raw = os.path.join(tmp, "raw")
        os.makedirs(raw)
        repeat = args.repeat if args.repeat else (3 if len(frames) == 1 else 1)
        methods = args.methods
        if len(frames) == 1:  # a refit needs a previous frame's BVH
            methods = ",".join(m for m in methods.split(",") if m != "embree-refit")
        cmd = [BIN, scene_bin, out_json, "--threads", str(args.threads), "--repeat", str(repeat),
               "--tests", args.tests, "--methods", methods, "--samples",
               str(min(args.samples, max(100, int(BRUTE_FORCE_TESTS // max(len(tris), 1))))),
               "--short-stack", str(args.short_stack), "--backend", args.backend,
               "--leaf-scale", str(args.leaf_scale), "--leaves", args.leaves]
        if args.in_flight:
            cmd += ["--in-flight", str(args.in_flight)]
        if args.simd:
            cmd += ["--simd", args.simd]
        if args.device:
            cmd += ["--device", args.device]
        if args.octree_height:
            cmd += ["--octree-height", str(args.octree_height)]
        if args.kdtree_height:
            cmd += ["--kdtree-height", str(args.kdtree_height)]
        if heat_out:
            cmd += ["--heatmaps", raw]
        proc = subprocess.run(cmd, capture_output=True, text=True)
        if proc.returncode != 0:
            raise SystemExit(f"rays_bench failed on {name}:\n{proc.stderr[-2000:]}")
        res = json.load(open(out_json))
        rows = res["rows"]
        if not args.no_embree and embree_available():
            et = args.threads or os.cpu_count()
            rows.append(dict(run_embree(tris, frames, cam, res.get("reference", {}), et), backend="cpu",
                             device=f"host, {et} threads"))
        for r in rows:
            # image_* keys: "height" is the tree's height (rays_bench's rows)
            r.update(scene=name, triangles=int(tris.shape[0]), frames=len(frames), image_width=cam["width"],
                     image_height=cam["height"], threads=res["threads"])
            r["mrays_per_s"] = r["rays"] / r["render_ms"] / 1e3 if r["render_ms"] else None
            if "bytes" in r:
                r["tree_mb"] = r["bytes"] / 1e6
                r["leaf_mb"] = r.get("payload_bytes", 0) / 1e6
        # The baseline of a row: the SAH stack with the same test and the same leaves (payload or
        # mesh); Embree's rows against the SAH stack's Moller-Trumbore payload row.
        ref = {(r["test"], r.get("leaves")): r for r in rows if r["method"] == "sah" and r["traversal"] == "stack"
               and r.get("backend", "cpu") == "cpu"}
        ref_any = ref.get(("mt", "payload")) or ref.get(("mt", "mesh")) or next(iter(ref.values()), None)
        # Ratios from wall-clock times, or (--clock cpu) from CPU times: with --threads 1 on a
        # machine other processes share, CPU time leaves out the time the process waited.
        bk, rk = ("build_cpu_ms", "render_cpu_ms") if args.clock == "cpu" else ("build_ms", "render_ms")
        for r in rows:
            base = ref.get((r["test"], r.get("leaves")), ref_any)
            if base and r.get(rk) and r.get(bk) is not None:
                r["speedup_vs_sah_stack"] = base[rk] / r[rk]
                r["frame_speedup_vs_sah_stack"] = (base[bk] + base[rk]) / (r[bk] + r[rk])
            r["clock"] = args.clock
        if heat_out:
            r_pics = write_heatmaps(name, cam, raw, heat_out, rows)
            for p in r_pics:
                print(f"wrote {os.path.relpath(p)}")
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", action="append",
                    help="mesh file, folder of frames, or a scene name (repeatable); default: all")
    ap.add_argument("--frames", type=int, default=0,
                    help="frames for a folder of poses or ben-deformed (default 30); a single mesh: 1")
    ap.add_argument("--size", type=int, nargs=2, default=(800, 800), metavar=("W", "H"))
    ap.add_argument("--threads", type=int, default=0, help="OpenMP threads (0 = all cores)")
    ap.add_argument("--repeat", type=int, default=0,
                    help="renders per frame, median kept (default 3 for one frame, 1 for sequences)")
    ap.add_argument("--tests", default="mt,watertight", help="ray/triangle tests: mt, watertight or both")
    ap.add_argument("--methods",
                    default="octree,kdtree,sah-restart,sah-stack,sah-shortstack,embree-default,embree-low,embree-refit",
                    help="rays_bench's methods (embree-*: Embree 3 from C++, where rays_bench has it)")
    ap.add_argument("--leaves", choices=("payload", "mesh", "both"), default="payload",
                    help="leaf tests on the pre-gathered leaf triangles (default), through the ids to the mesh, "
                         "or rows for both (the speed/memory trade; every tree gets the same treatment)")
    ap.add_argument("--in-flight", type=int, default=0,
                    help="rays the matrix walk keeps in flight per core (default: the engine's)")
    ap.add_argument("--simd", choices=("scalar", "sse2", "avx2"), default="",
                    help="the widest leaf test allowed (default: the widest this CPU runs)")
    ap.add_argument("--short-stack", type=int, default=3, help="short-stack entries (default 3)")
    ap.add_argument("--samples", type=int, default=2000,
                    help="pixels of the first and last frame checked against the brute force")
    ap.add_argument("--no-embree", action="store_true", help="skip the Embree reference")
    ap.add_argument("--clock", choices=("wall", "cpu"), default="wall",
                    help="times the speed-up columns use: wall clock (default) or process CPU time "
                         "(use with --threads 1 on a shared machine)")
    ap.add_argument("--leaf-scale", type=float, default=1.0,
                    help="matrix trees: leaf extent as a multiple of the median triangle extent "
                         "(the automatic height rule; default 1.0, the rendering setting: the engine's "
                         "default 2.0 favours build time)")
    ap.add_argument("--octree-height", type=int, default=0,
                    help="matrix octree: levels below the root instead of the automatic height (0 = automatic)")
    ap.add_argument("--kdtree-height", type=int, default=0,
                    help="matrix kd-tree: levels below the root instead of the automatic height (0 = automatic)")
    ap.add_argument("--backend", choices=("cpu", "opencl", "all"), default="cpu",
                    help="cpu (OpenMP engine), opencl (matrix trees on the OpenCL device) or all")
    ap.add_argument("--device", default="",
                    help="OpenCL device selector (P:D, index or name part; default $MATRIXTREE_OPENCL_DEVICE/first)")
    ap.add_argument("--generated", default="",
                    help="comma-separated triangle counts (e.g. 1e3,1e4,1e5,1e6): adds the generated "
                         f"scenes ({', '.join(gen_scenes.SHAPES)}) at each size; alone, only those run")
    ap.add_argument("--huge", action="store_true",
                    help=f"allow generated scenes above {HUGE_TRIANGLES:.0e} triangles: rays_bench peaks near "
                         "1.6 GB per 1e6 triangles with every method, 1.0 GB with --methods octree,sah-stack "
                         "(docs/bench_rays.md)")
    ap.add_argument("--json", default=os.path.join(ROOT, "out", "bench_rays.json"))
    ap.add_argument("--md", help="write the markdown table here (e.g. out/bench_rays.md)")
    ap.add_argument("--chart", help="write the speed-up chart here (e.g. docs/images/rays_speedup.png)")
    ap.add_argument("--heatmaps", help="write per-scene heat maps (PNG) into this folder")
    args = ap.parse_args(argv)

    sizes = [int(float(x)) for x in args.generated.split(",") if x]
    if any(n > HUGE_TRIANGLES for n in sizes) and not args.huge:
        ap.error(f"--generated {args.generated}: sizes above {HUGE_TRIANGLES:.0e} triangles need --huge")
    require_driver(BIN)
    specs = (args.scene or ([] if sizes else DEFAULT_SCENES)) + \
        [f"gen:{shape}:{n}" for n in sizes for shape in gen_scenes.SHAPES]
    if not args.frames:
        args.frames = 30
    rows = []
    it = tqdm(specs, desc="scenes", unit="scene") if tqdm and len(specs) > 1 else specs
    for spec in it:
        single = spec not in ("horse_animated", "ben_deformed", "ben-deformed") and not os.path.isdir(spec)
        frames_arg = args.frames
        if single:
            args.frames = 1
        rows += run_scene(spec, args, args.heatmaps)
        args.frames = frames_arg
    payload = {"machine": machine(), "command": " ".join([os.path.relpath(sys.argv[0])] + sys.argv[1:]),
               "rows": rows}
    os.makedirs(os.path.dirname(os.path.abspath(args.json)), exist_ok=True)
    with open(args.json, "w") as f:
        json.dump(payload, f, indent=1)
    shown = [dict(r, **{k: (round(v, 3) if isinstance(v, float) else v) for k, v in r.items()}) for r in rows]
    print(table(shown, COLS))
    summ = summary_rows(rows, args.clock)
    if summ:  # none with --backend opencl (no CPU rows)
        print("\nSpeed-ups over the SAH kd-tree with a stack (x, > 1 = faster), Moller-Trumbore rows, "
              f"{args.clock} clock:")
        print(table(summ, SUMMARY_COLS))
    print(f"wrote {os.path.relpath(args.json)}")
    if args.md:
        with open(args.md, "w") as f:
            f.write(f"Command: `{payload['command']}`\n\n")
            f.write(f"Speed-ups over the SAH kd-tree with a stack ({args.clock} clock):\n\n")
            f.write(markdown(summ, SUMMARY_COLS) + "\n\nEvery row:\n\n")
            f.write(markdown(shown, COLS) + "\n")
        print(f"wrote {os.path.relpath(args.md)}")
    if args.chart:
        print(f"wrote {os.path.relpath(write_chart(rows, args.chart))}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

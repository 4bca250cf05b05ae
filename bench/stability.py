"""Numerical stability of every query path at the extremes, against exact rational arithmetic.

Each case builds a small scene with numpy, scales it by `scale` and moves it by `offset` (both
rounded to doubles: the reference works on the rounded doubles the library sees), runs the
engine's query (matrixtree_engine, the code under vtkMatrixTree and vtkMatrixTreeLocator), and
measures the answer against a reference computed in Python's fractions.Fraction (exact) over all
cells, or, for the volume, against the same scene at scale 1 (a scaled scene seen by a scaled
camera is the same picture). Errors are relative to the scene's own lengths (cell size h, or the
ray's t), so one bound holds at every magnitude.

Used by bench/tradeoffs.py (the stability table of docs/speed_accuracy.md) and by
tests/python/test_stability.py (which asserts the documented bounds).
"""

from __future__ import annotations

import itertools
from fractions import Fraction

import numpy as np

import matrixtree_engine as engine

VTK_TETRA = 10


# ---- exact arithmetic ------------------------------------------------------------------------

def _q(v):
    return [Fraction(float(x)) for x in v]


def _sub(a, b):
    return [a[0] - b[0], a[1] - b[1], a[2] - b[2]]


def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def exact_ray_triangle(o, d, a, b, c):
    """Exact t >= 0 where the ray o + t d meets the closed triangle abc, else None (Cramer's rule
    on the rational values of the doubles)."""
    o, d, a, b, c = _q(o), _q(d), _q(a), _q(b), _q(c)
    e1, e2, s = _sub(b, a), _sub(c, a), _sub(o, a)
    p = _cross(d, e2)
    det = _dot(e1, p)
    if det == 0:
        return None
    u = _dot(s, p) / det
    q = _cross(s, e1)
    v = _dot(d, q) / det
    if u < 0 or v < 0 or u + v > 1:
        return None
    t = _dot(e2, q) / det
    return t if t >= 0 else None


def exact_first_hit(o, d, pts, tris):
    """The exact first t of a ray over all triangles (None: no hit). A float test with a wide
    margin picks the candidates; only they are tested exactly."""
    a, b, c = pts[tris[:, 0]], pts[tris[:, 1]], pts[tris[:, 2]]
    e1, e2, s = b - a, c - a, o - a
    p = np.cross(d, e2)
    with np.errstate(all="ignore"):
        det = (e1 * p).sum(1)
        u = (s * p).sum(1) / det
        v = (np.cross(s, e1) * d).sum(1) / det
        cand = np.nonzero(~((u < -0.01) | (v < -0.01) | (u + v > 1.02)))[0]
    hits = [exact_ray_triangle(o, d, a[i], b[i], c[i]) for i in cand]
    hits = [t for t in hits if t is not None]
    return min(hits) if hits else None


def exact_barycentrics(x, corners):
    """Exact barycentric coordinates of point x in the tetrahedron `corners` (4 x 3)."""
    x, p = _q(x), [_q(c) for c in corners]
    e = [_sub(p[1], p[0]), _sub(p[2], p[0]), _sub(p[3], p[0])]
    r = _sub(x, p[0])
    det = _dot(e[0], _cross(e[1], e[2]))
    b1 = _dot(r, _cross(e[1], e[2])) / det
    b2 = _dot(e[0], _cross(r, e[2])) / det
    b3 = _dot(e[0], _cross(e[1], r)) / det
    return [1 - b1 - b2 - b3, b1, b2, b3]


def _rel(x: float, ref: Fraction) -> float:
    """|x - ref| / |ref| exactly, rounded once (|x - ref| when ref is 0)."""
    diff = abs(Fraction(float(x)) - ref)
    return float(diff / abs(ref)) if ref else float(diff)


# ---- scenes ----------------------------------------------------------------------------------

def octahedron_sphere(levels: int = 2):
    """A closed triangulated sphere (an octahedron split `levels` times, vertices pushed to the
    unit sphere): every edge is shared by two triangles."""
    verts = [np.array(v, float) for v in itertools.chain(*[[s * np.eye(3)[i] for s in (1, -1)] for i in range(3)])]
    tris = [(0, 2, 4), (2, 1, 4), (1, 3, 4), (3, 0, 4), (2, 0, 5), (1, 2, 5), (3, 1, 5), (0, 3, 5)]
    for _ in range(levels):
        mids, out = {}, []

        def mid(i, j):
            key = (min(i, j), max(i, j))
            if key not in mids:
                m = verts[i] + verts[j]
                verts.append(m / np.linalg.norm(m))
                mids[key] = len(verts) - 1
            return mids[key]

        for a, b, c in tris:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            out += [(a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca)]
        tris = out
    return np.array(verts), np.array(tris, np.int64)


def surface(pts, tris, test_tree="octree"):
    n = len(tris)
    empty = np.zeros(0, np.int64)
    return engine.SurfaceTree(np.ascontiguousarray(pts, float), np.arange(0, 3 * n + 1, 3, dtype=np.int64),
                              np.ascontiguousarray(tris, np.int64).ravel(), empty, empty, tree=test_tree)


def kuhn_tets(n: int, jitter: float = 0.0, seed: int = 0):
    """The unit cube as n^3 lattice cubes of six tetrahedra each (one per ordering of the axes:
    corner 0, then one step along each axis in that order); interior lattice points moved by up
    to `jitter` cells. The hull stays the unit cube."""
    g = np.arange(n + 1)
    ijk = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    pts = ijk / n
    if jitter:
        inner = np.all((ijk > 0) & (ijk < n), axis=1)
        pts[inner] += np.random.default_rng(seed).uniform(-jitter, jitter, (inner.sum(), 3)) / n
    base = np.stack(np.meshgrid(*(np.arange(n),) * 3, indexing="ij"), -1).reshape(-1, 3)
    flat = lambda c: (c[:, 0] * (n + 1) + c[:, 1]) * (n + 1) + c[:, 2]
    tets = []
    for order in itertools.permutations(range(3)):
        corner, ids = base.copy(), [flat(base)]
        for axis in order:
            corner[:, axis] += 1
            ids.append(flat(corner))
        tets.append(np.stack(ids, 1))
    return pts, np.concatenate(tets)


def tet_locator(pts, tets):
    n = len(tets)
    return engine.CellLocator(np.ascontiguousarray(pts, float), np.arange(0, 4 * n + 1, 4, dtype=np.int64),
                              np.ascontiguousarray(tets, np.int64).ravel(), np.full(n, VTK_TETRA, np.uint8))


# ---- ray / triangle --------------------------------------------------------------------------

def rays_closed_sphere(test: str, scale: float, offset: float, random_rays: int = 60) -> dict:
    """Rays from the centre of a closed sphere of radius `scale` centred at (offset, offset,
    offset): through every vertex, every edge's midpoint (shared vertices and edges) and random
    directions. Every ray must hit: a miss is a leak. rel_dt: the largest |t - t_exact| / t_exact
    over the rays checked exactly (every third)."""
    unit, tris = octahedron_sphere()
    pts = unit * scale + offset
    centre = np.full(3, offset, float)
    edges = np.unique(np.sort(tris[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1), axis=0)
    aims = np.vstack([pts, 0.5 * (pts[edges[:, 0]] + pts[edges[:, 1]])]) - centre
    dirs = np.vstack([aims, np.random.default_rng(1).normal(size=(random_rays, 3)) * scale])
    origins = np.tile(centre, (len(dirs), 1))
    t, _, _, _ = surface(pts, tris).intersect(origins, dirs, test=test)
    rel = []
    for i in range(0, len(dirs), 3):
        ref = exact_first_hit(origins[i], dirs[i], pts, tris)
        if ref is not None and np.isfinite(t[i]):
            rel.append(_rel(t[i], ref))
    return {"rays": len(dirs), "leaks": int(np.isinf(t).sum()), "rel_dt": max(rel)}


def _against_exact(pts, tris, origins, dirs, test):
    """(rays the exact answer hits but the library misses, the largest |t - t_exact| / t_exact of
    the rays both hit; NaN when none)."""
    t, _, _, _ = surface(pts, tris).intersect(np.ascontiguousarray(origins), np.ascontiguousarray(dirs), test=test)
    rel, misses = [], 0
    for i in range(len(t)):
        ref = exact_first_hit(origins[i], dirs[i], pts, tris)
        if ref is None:
            continue
        if np.isinf(t[i]):
            misses += 1
        else:
            rel.append(_rel(t[i], ref))
    return misses, max(rel) if rel else float("nan")


def lattice_square(n: int = 8):
    """The unit square in z = 0 as n x n cells of two triangles each (shared edges on the grid
    lines and on the diagonals x - i = y - j)."""
    g = np.linspace(0.0, 1.0, n + 1)
    x, y = np.meshgrid(g, g, indexing="ij")
    pts = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], 1)
    a = (np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]).ravel()
    b = a + n + 1
    tris = np.concatenate([np.stack([a, b, b + 1], 1), np.stack([a, b + 1, a + 1], 1)])
    return pts, tris


def rays_grazing(test: str, angle: float, rays: int = 150, seed: int = 2) -> dict:
    """Rays meeting a flat square of 128 triangles at `angle` radians to its plane, aimed at
    interior points on the shared grid lines, on the shared diagonals and at random (never on the
    square's outer edge), from azimuths at random. Every ray must hit (a miss is a leak);
    rel_dt against the exact t (1 here: the origin is one unit from the aim point)."""
    pts, tris = lattice_square()
    rng = np.random.default_rng(seed)
    aim = np.zeros((rays, 3))
    aim[:, :2] = rng.uniform(1 / 16, 15 / 16, (rays, 2))
    kind = np.arange(rays) % 3
    aim[kind == 0, 1] = np.round(aim[kind == 0, 1] * 8).clip(1, 7) / 8
    aim[kind == 1, 1] = aim[kind == 1, 0]
    phi = rng.uniform(0, 2 * np.pi, rays)
    dirs = np.stack([np.cos(phi) * np.cos(angle), np.sin(phi) * np.cos(angle), np.full(rays, -np.sin(angle))], 1)
    misses, rel_dt = _against_exact(pts, tris, aim - dirs, dirs, test)
    return {"rays": rays, "leaks": misses, "rel_dt": rel_dt}


def rays_needle(test: str, width: float, rays: int = 80, seed: int = 3) -> dict:
    """Two needle triangles of length 1 and width `width` sharing their long edge, rays from one
    unit above at random interior points (half of them on the shared edge). misses: rays whose
    exact answer is a hit but which the library misses."""
    pts = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, width, 0.0], [0.0, -width, 0.0]])
    tris = np.array([[0, 1, 2], [0, 3, 1]], np.int64)
    rng = np.random.default_rng(seed)
    u = rng.uniform(0.05, 0.95, rays)
    v = rng.uniform(0, 1, rays) * (1 - u) * 0.9
    aim = (1 - u - v)[:, None] * pts[0] + u[:, None] * pts[1] + v[:, None] * pts[2]
    aim[::2, 1] = 0.0
    dirs = np.tile([0.3, 0.2, -1.0], (rays, 1))
    misses, rel_dt = _against_exact(pts, tris, aim - dirs, dirs, test)
    return {"rays": rays, "misses": misses, "rel_dt": rel_dt}


# ---- cells: FindCell, segments, closest points -----------------------------------------------

def _scaled_tets(scale, offset, n=4, jitter=0.2):
    pts, tets = kuhn_tets(n, jitter)
    return pts * scale + offset, tets, scale / n


def find_cell(scale: float, offset: float, points: int = 120, seed: int = 4) -> dict:
    """FindCell at points drawn inside random tetrahedra of a jittered grid with cells of size
    h = scale / 4 moved by `offset`. wrong: the cell returned does not contain the point (an
    exact barycentric below -1e-3, VTK's parametric tolerance); missing: no cell returned though
    one contains the point exactly; dpcoords: the largest |pcoords - exact| of the cells
    returned."""
    pts, tets, _ = _scaled_tets(scale, offset)
    loc = tet_locator(pts, tets)
    rng = np.random.default_rng(seed)
    cells = rng.integers(0, len(tets), points)
    w = rng.dirichlet(np.ones(4), points)
    x = np.einsum("mk,mkj->mj", w, pts[tets[cells]])
    ids, pc, _ = loc.find_cells(x, pcoords=True)
    wrong = missing = 0
    dpc = 0.0
    for i in range(points):
        if ids[i] < 0:
            b = exact_barycentrics(x[i], pts[tets[cells[i]]])
            missing += int(min(b) >= 0)
            continue
        b = exact_barycentrics(x[i], pts[tets[ids[i]]])
        if min(b) < Fraction(-1, 1000):
            wrong += 1
        dpc = max(dpc, max(float(abs(Fraction(float(pc[i, k])) - b[k + 1])) for k in range(3)))
    return {"points": points, "wrong": wrong, "missing": missing, "dpcoords": dpc}


def _box(pts):
    return [_q(pts.min(0)), _q(pts.max(0))]


def segment_first_hit(scale: float, offset: float, segments: int = 60, seed: int = 5) -> dict:
    """IntersectWithLine (first hit) of segments from outside the cube of tetrahedra into it or through it:
    the exact first hit is where the segment enters the cube (its hull). dx: the largest distance
    between the hit point returned and the exact entry, over the cell size h."""
    pts, tets, h = _scaled_tets(scale, offset)
    lo, hi = pts.min(0), pts.max(0)
    rng = np.random.default_rng(seed)
    a = lo + (hi - lo) * rng.uniform(-0.6, -0.1, (segments, 3))
    b = lo + (hi - lo) * rng.uniform(1.1, 1.6, (segments, 3))
    inside = lo + (hi - lo) * rng.uniform(0.2, 0.8, (segments, 3))
    p1 = np.ascontiguousarray(a)
    p2 = np.ascontiguousarray(np.where((np.arange(segments) % 2 == 0)[:, None], inside, b))
    t, ids, x = tet_locator(pts, tets).first_hits(p1, p2)
    box = _box(pts)
    worst, missed = 0.0, 0
    for i in range(segments):
        o, e = _q(p1[i]), _q(p2[i])
        t0, t1 = Fraction(0), Fraction(1)
        for k in range(3):
            dk = e[k] - o[k]
            if dk == 0:
                continue
            ta, tb = (box[0][k] - o[k]) / dk, (box[1][k] - o[k]) / dk
            t0, t1 = max(t0, min(ta, tb)), min(t1, max(ta, tb))
        if t0 > t1:
            continue
        if ids[i] < 0:
            missed += 1
            continue
        ref = [o[k] + t0 * (e[k] - o[k]) for k in range(3)]
        dist = max(abs(Fraction(float(x[i, k])) - ref[k]) for k in range(3))
        worst = max(worst, float(dist) / h)
    return {"segments": segments, "missed": missed, "dx_over_h": worst}


def closest_point(scale: float, offset: float, points: int = 60, seed: int = 6) -> dict:
    """FindClosestPoint from points outside the cube of tetrahedra: the exact closest point is
    the point clamped to the cube. dx: the largest distance between the point returned and the
    exact one, over the cell size h."""
    pts, tets, h = _scaled_tets(scale, offset)
    lo, hi = pts.min(0), pts.max(0)
    x = lo + (hi - lo) * np.random.default_rng(seed).uniform(-0.5, 1.5, (points, 3))
    x[np.all((x > lo) & (x < hi), axis=1), 0] = lo[0] - (hi[0] - lo[0]) * 0.25
    closest, ids, _ = tet_locator(pts, tets).closest_points(np.ascontiguousarray(x))
    box = _box(pts)
    worst = 0.0
    for i in range(points):
        q = _q(x[i])
        ref = [min(max(q[k], box[0][k]), box[1][k]) for k in range(3)]
        worst = max(worst, float(max(abs(Fraction(float(closest[i, k])) - ref[k]) for k in range(3))) / h)
    return {"points": points, "unanswered": int((ids < 0).sum()), "dx_over_h": worst}


# ---- volume sampling -------------------------------------------------------------------------

def _ball(n=17):
    g = np.linspace(-1, 1, n)
    x, y, z = np.meshgrid(g, g, g, indexing="ij")
    ball = np.clip(1 - np.sqrt(x * x + y * y + z * z), 0, None).astype(np.float32)
    return np.ascontiguousarray(ball.transpose(2, 1, 0)).ravel()


def volume_render(scale: float, offset: float, double_precision: bool = False, size: int = 24):
    """A 17^3 ball of spacing `scale` with its origin at (offset, offset, offset), seen by a
    perspective camera scaled and moved with it; opacity per unit distance scaled with it too."""
    table = np.ones((256, 4), np.float32)
    table[:, 3] = np.linspace(0, 0.6, 256) ** 2
    vol = engine.Volume(_ball(), [17, 17, 17], table, 0.0, 1.0, unit_distance=scale)
    origin = np.full(3, offset)
    centre = origin + 8 * scale
    img, _ = vol.render(size, size, position=list(centre + np.array([30.0, 20.0, 40.0]) * scale),
                        focal_point=list(centre), view_up=[0, 1, 0], origin=list(origin), spacing=[scale] * 3,
                        sample_distance=0.5 * scale, double_precision=double_precision)
    return img


def volume_sampling(scale: float, offset: float, double_precision: bool = False) -> dict:
    """The largest |rgba - rgba at scale 1, offset 0| of volume_render (0..1 per channel)."""
    ref = volume_render(1.0, 0.0, double_precision)
    img = volume_render(scale, offset, double_precision)
    return {"pixels": ref.shape[0] * ref.shape[1], "max_drgba": float(np.abs(img - ref).max()),
            "coverage": float(ref[..., 3].mean())}


def vtk_find_cell(locator, scale: float, offset: float, points: int = 120, seed: int = 4) -> dict:
    """find_cell's experiment through a VTK cell locator (an instance of any vtkAbstractCellLocator
    class: vtkMatrixTreeLocator, or VTK's own for comparison) on the same tetrahedra as a
    vtkUnstructuredGrid. Needs VTK."""
    from vtkmodules.util.numpy_support import numpy_to_vtk, numpy_to_vtkIdTypeArray
    from vtkmodules.vtkCommonCore import vtkPoints
    from vtkmodules.vtkCommonDataModel import vtkCellArray, vtkGenericCell, vtkUnstructuredGrid

    pts, tets, _ = _scaled_tets(scale, offset)
    grid, p, cells = vtkUnstructuredGrid(), vtkPoints(), vtkCellArray()
    p.SetData(numpy_to_vtk(np.ascontiguousarray(pts), deep=True))
    cells.SetData(numpy_to_vtkIdTypeArray(np.arange(0, 4 * len(tets) + 1, 4, dtype=np.int64), deep=True),
                  numpy_to_vtkIdTypeArray(np.ascontiguousarray(tets, np.int64).ravel(), deep=True))
    grid.SetPoints(p)
    grid.SetCells(VTK_TETRA, cells)
    locator.SetDataSet(grid)
    locator.BuildLocator()
    rng = np.random.default_rng(seed)
    chosen = rng.integers(0, len(tets), points)
    x = np.einsum("mk,mkj->mj", rng.dirichlet(np.ones(4), points), pts[tets[chosen]])
    cell, pc, w = vtkGenericCell(), [0.0] * 3, [0.0] * 4
    wrong = missing = 0
    for i in range(points):
        found = locator.FindCell(list(x[i]), 0.0, cell, pc, w)
        b = exact_barycentrics(x[i], pts[tets[found if found >= 0 else chosen[i]]])
        if found < 0:
            missing += int(min(b) >= 0)
        else:
            wrong += int(min(b) < Fraction(-1, 1000))
    return {"points": points, "wrong": wrong, "missing": missing}

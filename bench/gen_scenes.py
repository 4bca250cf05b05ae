"""Generated test meshes of any size, for benchmarks on data the trees were not tuned on.

Three shapes with different miss rates (the share of in-box rays that hit nothing):

- ``sphere``: a cube-sphere (each cube face an m x m grid of quads, two triangles each, pushed
  onto the unit sphere) with radial noise: a compact closed surface, few in-box misses;
- ``terrain``: an m x m heightfield of fractal (summed-octave sine) noise seen obliquely: an
  open surface, most rays hit, long grazing rays;
- ``scatter``: many small separate noisy spheres (they may intersect) at random places in a cube, sized so that a
  ray across the cube meets about half an object on average whatever their number: more than
  half of the in-box rays pass between them (the high-miss case).

The triangle count is the nearest the shape's grid allows to the one asked for. Each shape is
seeded: the same size gives the same mesh.

    .venv/bin/python bench/gen_scenes.py sphere 1e5 out/sphere_100k.ply   # write one as PLY
"""

from __future__ import annotations

import sys

import numpy as np

SHAPES = ("sphere", "terrain", "scatter")


def label(n: int) -> str:
    """1000 -> '1k', 1000000 -> '1M'."""
    for div, suffix in ((10**6, "M"), (10**3, "k")):
        if n >= div and n % div == 0:
            return f"{n // div}{suffix}"
    return str(n)


def _grid_triangles(rows: int, cols: int, first: int = 0) -> np.ndarray:
    """Two triangles per quad of a (rows+1) x (cols+1) vertex grid numbered row by row from
    ``first``; both clockwise in the grid's (column, row) plane, so that the normals point
    along row x column: out of the cube-sphere, up (+y) on the terrain."""
    r, c = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    v00 = (first + r * (cols + 1) + c).ravel()
    v01, v10 = v00 + 1, v00 + cols + 1
    v11 = v10 + 1
    return np.concatenate([np.column_stack([v00, v11, v01]), np.column_stack([v00, v10, v11])]).astype(np.uint32)


def _octave_noise(x: np.ndarray, y: np.ndarray, z: np.ndarray, rng, octaves: int = 5) -> np.ndarray:
    """A sum of ``octaves`` random plane waves, each twice the frequency and half the amplitude
    of the one before: smooth, band-limited noise in [-1, 1]."""
    out = np.zeros_like(x)
    for k in range(octaves):
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        f = 2.0 ** (k + 1)
        out += 0.5 ** (k + 1) * np.sin(f * np.pi * (d[0] * x + d[1] * y + d[2] * z) + rng.uniform(0, 2 * np.pi))
    return out


def sphere(n: int, seed: int = 1):
    """Cube-sphere with 12 m^2 triangles (m = round(sqrt(n / 12))), radius 1 +- 0.1 noise."""
    rng = np.random.default_rng(seed)
    m = max(1, int(round(np.sqrt(n / 12))))
    u = np.linspace(-1.0, 1.0, m + 1)
    uu, vv = np.meshgrid(u, u, indexing="ij")
    one = np.ones_like(uu)
    pts, tris = [], []
    # per face: the constant axis and the two grid axes, swapped on the negative face so that
    # every face's triangles face outwards
    for axis in range(3):
        for sign in (1.0, -1.0):
            a, b = (uu, vv) if sign > 0 else (vv, uu)
            xyz = [None, None, None]
            xyz[axis] = sign * one
            xyz[(axis + 1) % 3], xyz[(axis + 2) % 3] = a, b
            tris.append(_grid_triangles(m, m, sum(len(p) for p in pts)))
            pts.append(np.column_stack([c.ravel() for c in xyz]))
    p = np.concatenate(pts)
    p /= np.linalg.norm(p, axis=1, keepdims=True)
    p *= (1.0 + 0.1 * _octave_noise(p[:, 0], p[:, 1], p[:, 2], rng))[:, None]  # a function of the position: faces' shared edges stay shared
    return p, np.concatenate(tris)


def terrain(n: int, seed: int = 2):
    """Heightfield over [-1, 1]^2 in x, z with height y: 2 m^2 triangles (m = round(sqrt(n / 2)))."""
    rng = np.random.default_rng(seed)
    m = max(1, int(round(np.sqrt(n / 2))))
    u = np.linspace(-1.0, 1.0, m + 1)
    zz, xx = np.meshgrid(u, u, indexing="ij")
    y = 0.25 * _octave_noise(xx, np.zeros_like(xx), zz, rng, octaves=7)
    return np.column_stack([xx.ravel(), y.ravel(), zz.ravel()]), _grid_triangles(m, m)


def scatter(n: int, seed: int = 3):
    """k = n / 32 noisy spheres (once-subdivided octahedra, 32 triangles each) of radius
    0.8 / sqrt(k) at uniform random places in [-1, 1]^3: a ray crossing the cube (length ~2,
    volume 8) meets k * pi r^2 * 2 / 8 = 0.5 objects on average, for every k."""
    rng = np.random.default_rng(seed)
    k = max(1, int(round(n / 32)))
    # one octahedron subdivided once: 6 + 12 = 18 vertices, 32 triangles
    octa = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
    faces = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]])
    edges = {}
    verts = list(octa)

    def mid(a, b):
        key = (min(a, b), max(a, b))
        if key not in edges:
            edges[key] = len(verts)
            v = octa[a] + octa[b]
            verts.append(v / np.linalg.norm(v))
        return edges[key]

    sub = []
    for a, b, c in faces:
        ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
        sub += [[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]
    unit, sub = np.asarray(verts), np.asarray(sub)
    r = 0.8 / np.sqrt(k)
    centers = rng.uniform(-1.0, 1.0, size=(k, 3))
    radii = r * (1.0 + 0.15 * rng.standard_normal((k, len(unit))))
    pts = (centers[:, None, :] + radii[:, :, None] * unit[None]).reshape(-1, 3)
    tris = (sub[None] + (np.arange(k) * len(unit))[:, None, None]).reshape(-1, 3).astype(np.uint32)
    return pts, tris


GENERATORS = {"sphere": sphere, "terrain": terrain, "scatter": scatter}


def generate(shape: str, n: int):
    """(points (N, 3) float64, triangles (M, 3) uint32) of ``shape`` with about ``n`` triangles."""
    if shape not in GENERATORS:
        raise ValueError(f"unknown generated shape {shape!r}; choose from {', '.join(SHAPES)}")
    if n < 1:
        raise ValueError(f"the triangle count must be >= 1, got {n}")
    return GENERATORS[shape](n)


def main(argv) -> int:
    if len(argv) != 3:
        print(__doc__)
        return 2
    import pyvista as pv

    pts, tris = generate(argv[0], int(float(argv[1])))
    faces = np.column_stack([np.full(len(tris), 3), tris]).ravel()
    pv.PolyData(pts, faces).save(argv[2])
    print(f"wrote {argv[2]}: {len(tris):,} triangles, {len(pts):,} points")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

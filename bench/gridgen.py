#!/usr/bin/env python3
"""Generated test and benchmark grids: every nonlinear cell type of VTK 9.1, curved quadratic
cells, graded boundary layers whose cell heights span 10³–10⁴, small grids and a 5M-cell grid.

    .venv/bin/python bench/gridgen.py OUTDIR [--set small|bench|big] [--only NAME ...] [--list]

Writes OUTDIR/NAME.vtu for each grid of the set (`small`: about 1k cells each; `bench`: about 40k
cells each, the rows of `bench/locators.py --generated`; `big`: the 5M-cell boundary layer,
about 1.5 GiB while it is made).

Construction. Space is cut into an nx×ny×nz lattice of unit boxes; each box is one hexahedron,
two wedges (cut along a diagonal of its z faces), six tetrahedra (the Kuhn split along the
diagonal 0→6, conforming between boxes) or six pyramids (one per face, apex at the box's
centre). A cell's nodes sit where VTK's own parametric coordinates of that node
(vtkCell::GetParametricCoords) fall under the linear map of its corners, so every node ordering
is VTK's. Nodes are shared through their lattice position in twelfths (a pyramid's
mid-edge node on an apex edge sits at a quarter of the box), so the grid is conforming. Last,
one smooth map carries lattice positions to space:

- `curved`: x += a·h·sin(2πy/λh), y += a·h·sin(2πz/λh), z += a·h·sin(2πx/λh) with a = 0.12,
  λ = 3 cells. Its Jacobian I + C (C cyclic off-diagonal, entries ≤ k = 2πa/λ = 0.25) has
  determinant 1 + c₁c₂c₃ ≥ 1 − k³ > 0; mid-edge nodes leave the chords, so the cells are curved.
- `graded` (boundary layers): z = h₀(rᵘ − 1)/(r − 1) over the lattice's z index u, r chosen so
  that the top layer is `span` times the wall layer's height.

2-D cells lie in the plane z = 0 (curved in the plane), so points drawn in their bounding box
lie on them.
"""

from __future__ import annotations

import argparse
import math
import os
import sys

import numpy as np
from vtkmodules.util.numpy_support import numpy_to_vtk, numpy_to_vtkIdTypeArray
from vtkmodules.vtkCommonCore import vtkPoints
from vtkmodules.vtkCommonDataModel import (vtkCellArray, vtkHexahedron, vtkPyramid, vtkQuad, vtkTetra,
                                           vtkTriangle, vtkUnstructuredGrid, vtkWedge)

# Lattice positions are stored in twelfths: every node of every cell below (quarters on a
# pyramid's apex edges, thirds at a biquadratic triangle's centre) is on that grid.
Q = 12

# The corners (unit-box offsets) of each linear topology's pieces of one box, in VTK's corner order.
_BOX = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)]


def _kuhn_tets():
    """Six tetrahedra along the box diagonal (0,0,0)→(1,1,1), one per axis order."""
    out = []
    for order in ((0, 1, 2), (0, 2, 1), (1, 0, 2), (1, 2, 0), (2, 0, 1), (2, 1, 0)):
        p, pts = [0, 0, 0], [(0, 0, 0)]
        for ax in order:
            p = list(p)
            p[ax] = 1
            pts.append(tuple(p))
        out.append(pts)
    return out


def _box_pyramids():
    """Six pyramids, one per box face, apex at the box centre."""
    faces = [(0, 3, 7, 4), (1, 2, 6, 5), (0, 1, 5, 4), (3, 2, 6, 7), (0, 1, 2, 3), (4, 5, 6, 7)]
    return [[_BOX[i] for i in f] + [(0.5, 0.5, 0.5)] for f in faces]


PIECES = {
    "hex": [_BOX],
    "wedge": [[(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1)],
              [(0, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 1, 1), (0, 1, 1)]],
    "tet": _kuhn_tets(),
    "pyramid": _box_pyramids(),
    "quad": [[(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]],
    "tri": [[(0, 0, 0), (1, 0, 0), (1, 1, 0)], [(0, 0, 0), (1, 1, 0), (0, 1, 0)]],
}
LINEAR = {"hex": vtkHexahedron, "wedge": vtkWedge, "tet": vtkTetra, "pyramid": vtkPyramid,
          "quad": vtkQuad, "tri": vtkTriangle}
# VTK's orientation: the sign of the parametric map's Jacobian in a valid cell. A wedge's
# (0,1,2) face normal points away from (3,4,5) (vtkWedge), against its parametric t axis.
ORIENTATION = {"hex": 1, "wedge": -1, "tet": 1, "pyramid": 1, "quad": 1, "tri": 1}
# Corner permutations that reverse a piece's orientation.
FLIP = {"hex": [0, 3, 2, 1, 4, 7, 6, 5], "wedge": [0, 2, 1, 3, 5, 4], "tet": [0, 2, 1, 3],
        "pyramid": [0, 3, 2, 1, 4], "quad": [0, 3, 2, 1], "tri": [0, 2, 1]}

# VTK cell type → (topology, number of nodes). The Lagrange cells are of order 2.
CELL_TYPES = {
    12: ("hex", 8), 13: ("wedge", 6), 10: ("tet", 4), 14: ("pyramid", 5),
    24: ("tet", 10), 25: ("hex", 20), 26: ("wedge", 15), 27: ("pyramid", 13), 29: ("hex", 27),
    31: ("wedge", 12), 32: ("wedge", 18), 33: ("hex", 24),
    71: ("tet", 10), 72: ("hex", 27), 73: ("wedge", 18),
    22: ("tri", 6), 23: ("quad", 8), 28: ("quad", 9), 30: ("quad", 6), 34: ("tri", 7),
    69: ("tri", 6), 70: ("quad", 9),
}
TYPE_NAMES = {10: "tet4", 12: "hex8", 13: "wedge6", 14: "pyr5", 24: "tet10", 25: "hex20",
              26: "wedge15", 27: "pyr13", 29: "hex27", 31: "wedge12", 32: "wedge18", 33: "hex24",
              71: "lagrange_tet10", 72: "lagrange_hex27", 73: "lagrange_wedge18", 22: "tri6",
              23: "quad8", 28: "quad9", 30: "quad6", 34: "tri7", 69: "lagrange_tri6", 70: "lagrange_quad9"}


def node_pcoords(cell_type: int) -> np.ndarray:
    """VTK's parametric coordinates of the cell type's nodes, (n, 3), from a cell VTK builds."""
    n = CELL_TYPES[cell_type][1]
    g = vtkUnstructuredGrid()
    p = vtkPoints()
    p.SetNumberOfPoints(n)
    for i in range(n):
        p.SetPoint(i, float(i), 0.0, 0.0)
    g.SetPoints(p)
    g.InsertNextCell(cell_type, n, list(range(n)))
    pc = g.GetCell(0).GetParametricCoords()
    return np.array(pc, dtype=float).reshape(n, 3)


def _linear_weights(topo: str, pc: np.ndarray) -> np.ndarray:
    cls = LINEAR[topo]
    nc = len(PIECES[topo][0])
    out = np.zeros((len(pc), nc))
    for i, x in enumerate(pc):
        w = [0.0] * nc
        cls.InterpolationFunctions(list(x), w)
        out[i] = w
    return out


def _signed_measure(topo: str, corners: np.ndarray) -> float:
    """The sign-bearing size of a linear piece at its parametric centre (finite differences of
    the linear map; for 2-D pieces the z component of the tangents' cross product)."""
    centre = {"hex": (0.5, 0.5, 0.5), "wedge": (1 / 3, 1 / 3, 0.5), "tet": (0.25, 0.25, 0.25),
              "pyramid": (0.5, 0.5, 0.3), "quad": (0.5, 0.5, 0), "tri": (1 / 3, 1 / 3, 0)}[topo]
    e = 1e-3
    c = np.array(centre)
    pts = np.array([c, c + (e, 0, 0), c + (0, e, 0), c + (0, 0, e)])
    x = _linear_weights(topo, pts) @ corners
    d = x[1:] - x[0]
    if topo in ("quad", "tri"):
        return float(np.cross(d[0], d[1])[2])
    return float(np.linalg.det(d))


def templates(cell_type: int) -> np.ndarray:
    """(pieces, nodes, 3) node positions inside one unit box, in twelfths (integers)."""
    topo, _ = CELL_TYPES[cell_type]
    w = _linear_weights(topo, node_pcoords(cell_type))
    out = []
    for piece in PIECES[topo]:
        corners = np.array(piece, dtype=float)
        if _signed_measure(topo, corners) * ORIENTATION[topo] < 0:
            corners = corners[FLIP[topo]]
        pos = w @ corners * Q
        r = np.rint(pos)
        assert np.allclose(pos, r), (cell_type, pos)
        out.append(r.astype(np.int64))
    return np.array(out)


def build_grid(cells_by_type: list, dims: tuple, mapping) -> vtkUnstructuredGrid:
    """cells_by_type: [(cell_type, box mask or None)] over the nx×ny×nz boxes (nz = 1 and the
    z offsets dropped for 2-D types); mapping: (N, 3) lattice positions → (N, 3) points."""
    nx, ny, nz = dims
    ii, jj, kk = np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij")
    origin = np.stack([ii.ravel(), jj.ravel(), kk.ravel()], axis=1).astype(np.int64) * Q
    keys, types, sizes = [], [], []
    for cell_type, mask in cells_by_type:
        t = templates(cell_type)
        o = origin if mask is None else origin[mask.ravel()]
        k = (o[:, None, None, :] + t[None]).reshape(-1, t.shape[1], 3)
        keys.append(k.reshape(-1, 3))
        types.append(np.full(len(k), cell_type, dtype=np.uint8))
        sizes.append(np.full(len(k), t.shape[1], dtype=np.int64))
    allk = np.concatenate(keys)
    del keys
    span = np.array([nx, ny, nz]) * Q + 1
    code = (allk[:, 0] * span[1] + allk[:, 1]) * span[2] + allk[:, 2]
    uniq, conn = np.unique(code, return_inverse=True)
    del code, allk
    lattice = np.stack([uniq // (span[1] * span[2]), (uniq // span[2]) % span[1], uniq % span[2]],
                       axis=1).astype(float) / Q
    del uniq
    pts = vtkPoints()
    pts.SetData(numpy_to_vtk(np.ascontiguousarray(mapping(lattice)), deep=True))
    sizes = np.concatenate(sizes)
    offsets = np.zeros(len(sizes) + 1, dtype=np.int64)
    np.cumsum(sizes, out=offsets[1:])
    ca = vtkCellArray()
    ca.SetData(numpy_to_vtkIdTypeArray(offsets, deep=True),
               numpy_to_vtkIdTypeArray(conn.astype(np.int64), deep=True))
    g = vtkUnstructuredGrid()
    g.SetPoints(pts)
    g.SetCells(numpy_to_vtk(np.concatenate(types), deep=True), ca)
    return g


def curved(h: float, amplitude: float = 0.12, wavelength: float = 3.0, planar: bool = False):
    k = 2 * math.pi / wavelength

    def f(u):
        x = u * h
        out = x.copy()
        out[:, 0] += amplitude * h * np.sin(k * u[:, 1])
        out[:, 1] += amplitude * h * np.sin(k * (u[:, 0] if planar else u[:, 2]))
        if not planar:
            out[:, 2] += amplitude * h * np.sin(k * u[:, 0])
        return out
    return f


def straight(h: float):
    return lambda u: u * h


def graded(h: float, layers: int, span: float):
    """x, y spaced h; z layers grow geometrically from h/span at the wall to about h on top."""
    r = span ** (1.0 / max(1, layers - 1))
    h0 = h / r ** (layers - 1)

    def f(u):
        out = u * h
        out[:, 2] = h0 * (np.power(r, u[:, 2]) - 1.0) / (r - 1.0)
        return out
    return f


def _pieces(cell_type: int) -> int:
    return len(PIECES[CELL_TYPES[cell_type][0]])


def _cube_dims(cell_type: int, cells: int) -> tuple:
    if CELL_TYPES[cell_type][0] in ("quad", "tri"):
        n = max(2, round(math.sqrt(cells / _pieces(cell_type))))
        return (n, n, 1)
    n = max(2, round((cells / _pieces(cell_type)) ** (1 / 3)))
    return (n, n, n)


def type_grid(cell_type: int, cells: int, curve: bool = True) -> vtkUnstructuredGrid:
    """About `cells` cells of one type filling [0,1]³ (2-D types: [0,1]² at z = 0), curved."""
    dims = _cube_dims(cell_type, cells)
    h = 1.0 / dims[0]
    planar = dims[2] == 1
    m = curved(h, planar=planar) if curve else straight(h)
    return build_grid([(cell_type, None)], dims, (lambda u: _flatten(m, u)) if planar else m)


def _flatten(m, u):
    out = m(u)
    out[:, 2] = 0.0
    return out


def boundary_layer(cells: int, span: float, wedges: str = "half", quadratic: bool = False) -> vtkUnstructuredGrid:
    """A wall at z = 0 under graded layers (heights from h/span to h): hexahedra and wedges
    (wedges="half": a checkerboard of hexahedron columns and wedge-pair columns; "all": wedges
    only), linear or quadratic (hex20/wedge15)."""
    per_box = {"half": 1.5, "all": 2.0}[wedges]
    layers = max(4, round(math.log(span) / math.log(1.25)) + 1)
    n = max(2, round(math.sqrt(cells / per_box / layers)))
    dims = (n, n, layers)
    hex_t, wedge_t = (25, 26) if quadratic else (12, 13)
    ii, jj, _ = np.meshgrid(np.arange(n), np.arange(n), np.arange(layers), indexing="ij")
    hexcol = ((ii + jj) % 2 == 0) if wedges == "half" else np.zeros_like(ii, dtype=bool)
    parts = [(wedge_t, ~hexcol)]
    if hexcol.any():
        parts.insert(0, (hex_t, hexcol))
    return build_grid(parts, dims, graded(1.0 / n, layers, span))


def grid_set(which: str) -> dict:
    """name → a function that makes the grid."""
    size = {"small": 1000, "bench": 40000}.get(which)
    out = {}
    if size:
        for t in sorted(CELL_TYPES):
            if t in (10, 12, 13, 14):
                continue  # linear cells: the shipped grids hold them
            out[f"{TYPE_NAMES[t]}_curved"] = (lambda t=t: type_grid(t, size))
        out["tet10_straight"] = lambda: type_grid(24, size, curve=False)
        out["bl_hexwedge_1e4"] = lambda: boundary_layer(size, 1e4, "half")
        out["bl_wedge_1e3"] = lambda: boundary_layer(size, 1e3, "all")
        out["bl_hex20wedge15_1e3"] = lambda: boundary_layer(size, 1e3, "half", quadratic=True)
    if which == "big":
        out["bl_hexwedge_1e4_5M"] = lambda: boundary_layer(5_000_000, 1e4, "half")
    return out


def write(g: vtkUnstructuredGrid, path: str) -> None:
    from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridWriter
    w = vtkXMLUnstructuredGridWriter()
    w.SetFileName(path)
    w.SetInputData(g)
    w.SetDataModeToAppended()
    w.EncodeAppendedDataOff()
    if not w.Write():
        raise SystemExit(f"cannot write {path}")


def generate(outdir: str, which: str, only=None) -> list:
    os.makedirs(outdir, exist_ok=True)
    paths = []
    for name, make in grid_set(which).items():
        if only and name not in only:
            continue
        path = os.path.join(outdir, name + ".vtu")
        if not os.path.exists(path):
            write(make(), path)
        paths.append(path)
    return paths


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("outdir", nargs="?")
    p.add_argument("--set", choices=("small", "bench", "big"), default="small")
    p.add_argument("--only", action="append")
    p.add_argument("--list", action="store_true")
    a = p.parse_args()
    if a.list:
        print("\n".join(grid_set(a.set)))
        return 0
    if not a.outdir:
        p.error("OUTDIR is required")
    for path in generate(a.outdir, a.set, a.only):
        print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())

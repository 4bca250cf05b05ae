#!/usr/bin/env python3
"""The user guide's pictures (docs/guide.md), drawn with the package's own calls.

    xvfb-run -a .venv/bin/python docs/make_pictures.py [--out docs/images]

guide_tree.png    the bunny and the matrix octree over it (matrixtree.tree_mesh): every leaf,
                  coloured by how many triangles it holds, and one inner level with its occupancy.
guide_locate.png  CellLocator on the pipe-flow CFD grid: velocity magnitude interpolated at the
                  points of a plane through the axis (located cell, weights), and the pressure
                  along the axis from vtkProbeFilter with vtkMatrixTreeLocator as its locator.
guide_volume.png  render_volume on two shared volumes: default transfer functions, unshaded and
                  shaded.

The 3-D views are rendered by pyvista, which needs a display: run under ``xvfb-run -a``.
"""

from __future__ import annotations

import argparse
import os

import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import matrixtree  # noqa: E402
from matrixtree import scenes  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DATA = scenes.data_dir()


def tree_picture(path: str) -> None:
    import pyvista as pv

    bunny = pv.wrap(matrixtree.read_mesh(os.path.join(DATA, "meshes", "bunny.ply")))
    leaves = matrixtree.tree_mesh(bunny, tree="octree", levels=-1)
    height = int(leaves.field_data["tree_height"][0])
    inner = matrixtree.tree_mesh(bunny, tree="octree", levels=height - 2)
    view = [(-0.05, 0.25, 0.45), (-0.017, 0.11, 0.0), (0.0, 1.0, 0.0)]
    bar = {"vertical": False, "position_x": 0.2, "position_y": 0.04, "width": 0.6, "height": 0.06,
           "title_font_size": 13, "label_font_size": 11, "n_labels": 4, "fmt": "%.2g"}
    p = pv.Plotter(off_screen=True, shape=(1, 3), window_size=(1500, 540), border=False)
    p.subplot(0, 0)
    p.add_mesh(bunny, color="wheat", smooth_shading=True)
    p.add_text(f"bunny.ply, {bunny.n_cells:,} triangles", font_size=10)
    p.camera_position = view
    p.subplot(0, 1)
    p.add_mesh(leaves, scalars="cell_count", cmap="viridis", show_edges=True, edge_color="black",
               line_width=0.3, scalar_bar_args={"title": "triangles in the leaf", **bar})
    p.add_text(f"the {leaves.n_cells:,} leaves (level {height})", font_size=10)
    p.camera_position = view
    p.subplot(0, 2)
    p.add_mesh(inner, scalars="occupancy", cmap="plasma", show_edges=True, edge_color="black",
               line_width=0.8, scalar_bar_args={"title": "share of children that exist", **bar})
    p.add_text(f"the {inner.n_cells} nodes of level {height - 2}", font_size=10)
    p.camera_position = view
    p.screenshot(path)
    p.close()


def locate_picture(path: str) -> None:
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkFiltersCore import vtkProbeFilter
    from vtkmodules.vtkFiltersSources import vtkLineSource
    from matrixtree_vtk import vtkMatrixTreeLocator

    grid = matrixtree.read_grid(os.path.join(DATA, "cfd", "pipe_flow_tets.vtu"))
    x0, x1, _, _, z0, z1 = grid.GetBounds()
    nx, nz = 160, 1200
    xs, zs = np.linspace(x0, x1, nx), np.linspace(z0, z1, nz)
    X, Z = np.meshgrid(xs, zs, indexing="ij")
    pts = np.stack([X.ravel(), np.zeros(X.size), Z.ravel()], axis=1)  # the plane y = 0
    cells, weights = matrixtree.CellLocator(grid).locate(pts, return_weights=True)
    inside = cells >= 0
    conn = vtk_to_numpy(grid.GetCells().GetConnectivityArray()).reshape(-1, 4)
    velocity = vtk_to_numpy(grid.GetPointData().GetArray("Velocity"))
    speed = np.full(len(pts), np.nan)
    v = np.einsum("nk,nkc->nc", weights[inside], velocity[conn[cells[inside]]])
    speed[inside] = np.linalg.norm(v, axis=1)

    line = vtkLineSource()
    line.SetPoint1(0.0, 0.0, z0)
    line.SetPoint2(0.0, 0.0, z1)
    line.SetResolution(300)
    probe = vtkProbeFilter()
    probe.SetInputConnection(line.GetOutputPort())
    probe.SetSourceData(grid)
    probe.SetCellLocatorPrototype(vtkMatrixTreeLocator())
    probe.Update()
    out = probe.GetOutput()
    z = vtk_to_numpy(out.GetPoints().GetData())[:, 2]
    found = vtk_to_numpy(out.GetPointData().GetArray("vtkValidPointMask")).astype(bool)
    pressure = vtk_to_numpy(out.GetPointData().GetArray("Pressure"))
    z, pressure = z[found], pressure[found]  # a point in no cell gets 0: left out

    fig, (a, b) = plt.subplots(2, 1, figsize=(12, 5.2), gridspec_kw={"height_ratios": [1.25, 1]})
    im = a.imshow(speed.reshape(nx, nz), origin="lower", extent=(z0, z1, x0, x1), aspect="auto", cmap="turbo")
    a.set_xlabel("z")
    a.set_ylabel("x (plane y = 0)")
    a.set_title(f"CellLocator.locate: {len(pts):,} points, {inside.mean():.0%} inside {grid.GetNumberOfCells():,} "
                "tetrahedra; |velocity| from the cells' weights (white: outside, -1)", fontsize=10)
    fig.colorbar(im, ax=a, label="|velocity|", pad=0.01)
    b.plot(z, pressure, color="#1d3557")
    b.set_xlim(z0, z1)
    b.set_xlabel("z (pipe axis)")
    b.set_ylabel("pressure")
    b.set_title("vtkProbeFilter along the axis with vtkMatrixTreeLocator as its cell locator", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def volume_picture(path: str) -> None:
    names = ["headsq.mhd", "ironProt.vtk"]
    fig, axes = plt.subplots(1, 4, figsize=(14, 4.1), layout="constrained")
    for i, name in enumerate(names):
        im = matrixtree.read_volume(os.path.join(DATA, "volumes", name))
        for j, shade in enumerate((False, True)):
            rgba, st = matrixtree.render_volume(im, size=(360, 360), shade=shade, return_stats=True)
            rgb = rgba[..., :3] + (1.0 - rgba[..., 3:]) * 0.08  # premultiplied colour over dark grey
            ax = axes[2 * i + j]
            ax.imshow(np.clip(rgb, 0, 1))
            ax.set_axis_off()
            dims = "x".join(str(d) for d in im.GetDimensions())
            ax.set_title(f"{name} {dims}, {st['storage']}, shade={shade}\n"
                         f"{st['blocks_allocated']} of {st['blocks_dense']} blocks", fontsize=9)
    fig.savefig(path, dpi=90)
    plt.close(fig)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default=os.path.join(ROOT, "docs", "images"))
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    for name, draw in (("guide_tree.png", tree_picture), ("guide_locate.png", locate_picture),
                       ("guide_volume.png", volume_picture)):
        path = os.path.join(a.out, name)
        draw(path)
        print("wrote", path)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

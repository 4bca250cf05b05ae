"""MatrixTree: implicit, block-sparse matrix trees (Andrysco & Tricoche 2011) for ray casting
and spatial queries on meshes that change every frame, with VTK and pyvista adapters.

The heavy lifting is done by the VTK classes of the compiled ``matrixtree_vtk`` package (built
against Debian's VTK 9.1 by ``scripts/setup.sh``); this package converts numpy arrays and
meshes and delegates, it never loops over points or rays in Python.

Examples
--------
>>> import matrixtree
>>> mesh = matrixtree.scenes.default_scene(resolution=0.3)
>>> tree = matrixtree.MatrixTree(mesh, tree="octree")
>>> tree.stats()["triangles"] == mesh.GetNumberOfPolys()
True
"""

from matrixtree_vtk import vtkMatrixTreeVersion

from matrixtree import scenes
from matrixtree.core import MatrixTree, read_mesh, render, save_heatmap, save_rgb, time_frames, tree_mesh
from matrixtree.grids import read_grid
from matrixtree.locator import CellLocator, cached_memory, release_cached_memory
from matrixtree.volume import default_transfer_functions, frame_camera, read_volume, render_volume

__version__ = vtkMatrixTreeVersion.GetVersion()

__all__ = ["CellLocator", "MatrixTree", "cached_memory", "release_cached_memory", "read_grid", "read_mesh", "render", "save_heatmap", "save_rgb", "scenes", "time_frames", "tree_mesh", "__version__"]

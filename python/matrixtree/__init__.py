"""MatrixTree: implicit, block-sparse matrix trees (Andrysco & Tricoche 2011) for ray casting
and spatial queries on meshes that change every frame, with VTK and pyvista adapters.

The heavy lifting is done in C++ by one of two compiled extensions, chosen once when the package
is imported (``matrixtree.EXTENSION`` says which): the VTK classes of ``matrixtree_vtk`` (built
against Debian's VTK 9.1 by ``scripts/setup.sh``) where that module imports, else the VTK-free
engine of ``matrixtree_engine`` (what ``pip install .`` builds, beside pip's ``vtk`` and
``pyvista`` wheels). Both give the same answers; this package converts numpy arrays and meshes
and delegates, it never loops over points or rays in Python.

``matrixtree.filters`` is the pyvista-style surface (``find_containing_cell``, ``sample``,
``probe``, ``ray_trace``, ``multi_ray_trace``, ...); with pyvista 0.48 or newer it is also
every mesh's ``mesh.matrixtree`` accessor.

Examples
--------
>>> import matrixtree
>>> mesh = matrixtree.scenes.default_scene(resolution=0.3)
>>> tree = matrixtree.MatrixTree(mesh, tree="octree")
>>> tree.stats()["triangles"] == mesh.GetNumberOfPolys()
True
"""

from matrixtree._backend import VTK_MODULE, engine

from matrixtree import scenes
from matrixtree.core import MatrixTree, read_mesh, render, save_heatmap, save_rgb, time_frames, tree_mesh
from matrixtree.grids import read_grid
from matrixtree.locator import CellLocator, cached_memory, release_cached_memory
from matrixtree.volume import default_transfer_functions, frame_camera, read_volume, render_volume
from matrixtree import filters
from matrixtree.filters import (find_cells_along_line, find_cells_within_bounds, find_closest_cell,
                                find_containing_cell, multi_ray_trace, probe, ray_trace, sample)

if VTK_MODULE:
    from matrixtree_vtk import vtkMatrixTreeVersion

    __version__ = vtkMatrixTreeVersion.GetVersion()
    EXTENSION = "matrixtree_vtk"
else:
    __version__ = engine().__version__
    EXTENSION = "matrixtree_engine"

__all__ = ["CellLocator", "EXTENSION", "MatrixTree", "cached_memory", "filters", "find_cells_along_line",
           "find_cells_within_bounds", "find_closest_cell", "find_containing_cell", "multi_ray_trace", "probe",
           "ray_trace", "read_grid", "read_mesh", "release_cached_memory", "render", "sample", "save_heatmap",
           "save_rgb", "scenes", "time_frames", "tree_mesh", "__version__"]

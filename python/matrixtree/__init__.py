"""MatrixTree: block-sparse matrix trees for cell location, ray casting and
volume marching, with VTK and pyvista adapters.

The VTK classes come from the compiled ``matrixtree_vtk`` package, built
against Debian's VTK 9.1; use the project's ``.venv`` (``scripts/setup.sh``).
"""

from matrixtree_vtk import vtkMatrixTreeVersion

__version__ = vtkMatrixTreeVersion.GetVersion()

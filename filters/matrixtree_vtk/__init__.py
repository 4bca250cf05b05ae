"""VTK classes of MatrixTree, wrapped for Python.

Built against the VTK that CMake found (Debian's VTK 9.1): import it only in a
process that uses that same VTK (``/usr/bin/python3`` or the project's
``.venv``), never together with pip's ``vtk`` wheel.

Examples
--------
>>> from matrixtree_vtk import vtkMatrixTreeVersion
>>> vtkMatrixTreeVersion.GetVersion()
'0.1.0'
"""

# VTK's own modules first, so the wrapped superclasses are registered before
# the MatrixTree classes that derive from them.
import vtkmodules.vtkCommonCore  # noqa: F401
import vtkmodules.vtkCommonDataModel  # noqa: F401
import vtkmodules.vtkCommonExecutionModel  # noqa: F401

from .MatrixTreeFilters import *  # noqa: F401,F403

"""Which extension answers ``import matrixtree`` here, for tests of one path only: the VTK module
(``matrixtree_vtk``, scripts/setup.sh) or the engine extension (``pip install .``)."""

import pytest

import matrixtree

needs_vtk_module = pytest.mark.skipif(matrixtree.EXTENSION != "matrixtree_vtk",
                                      reason="needs the VTK module's classes (scripts/setup.sh)")

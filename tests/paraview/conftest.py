"""Fixtures of the ParaView plugin tests (helpers in pvtools.py): the CFD grids as .vtu files
with a point field, and random points over each."""

import os

import numpy as np
import pytest
from vtkmodules.util.numpy_support import numpy_to_vtk, vtk_to_numpy
from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridWriter

import matrixtree
from pvtools import CFD, GRIDS, write_points

collect_ignore = ["pv_checks.py"]  # ParaView's side: pvbatch runs it, this Python must not import it


@pytest.fixture(scope="session")
def cfd_grids(tmp_path_factory):
    """name -> (grid .vtu path, field, destination points .vtp path, grid, points): every grid
    read by matrixtree.read_grid (which reads SU2 and Exodus), written as .vtu for ParaView,
    and 20,000 random points over its bounds (and 5% past them) as a .vtp."""
    d = tmp_path_factory.mktemp("cfd")
    out = {}
    rng = np.random.default_rng(2024)
    for name, field in GRIDS.items():
        g = matrixtree.read_grid(os.path.join(CFD, name))
        if field == "analytic":
            x = vtk_to_numpy(g.GetPoints().GetData())
            a = numpy_to_vtk(np.sin(3 * x[:, 0]) + x[:, 1] * x[:, 2], deep=True)
            a.SetName("analytic")
            g.GetPointData().AddArray(a)
        assert g.GetPointData().GetArray(field) is not None, f"{name} has no point field {field}"
        stem = os.path.splitext(name)[0]
        grid_path = str(d / f"{stem}.vtu")
        w = vtkXMLUnstructuredGridWriter()
        w.SetFileName(grid_path)
        w.SetInputData(g)
        w.Write()
        b = np.array(g.GetBounds())
        lo, hi = b[0::2], b[1::2]
        pad = 0.05 * (hi - lo)
        p = (lo - pad) + (hi - lo + 2 * pad) * rng.random((20000, 3))
        points_path = str(d / f"{stem}_points.vtp")
        write_points(points_path, p)
        out[f"{stem}.vtu"] = (grid_path, field, points_path, g, p)
    return out

"""Fixtures of the ParaView plugin tests: where the plugin and ParaView's Python are, a runner for
pvbatch (serial or under mpirun), and the CFD grids as .vtu files with a point field.

These tests run in the project's .venv (Debian's VTK 9.1), which never loads ParaView: every
ParaView step runs in a pvbatch subprocess (pv_checks.py) and hands back files. The plugin must
be built first (scripts/setup.sh builds it into build-paraview/).
"""

import os
import shutil
import subprocess

import numpy as np
import pytest
from vtkmodules.util.numpy_support import numpy_to_vtk, vtk_to_numpy
from vtkmodules.vtkCommonCore import vtkPoints
from vtkmodules.vtkCommonDataModel import vtkPolyData
from vtkmodules.vtkIOXML import vtkXMLPolyDataWriter, vtkXMLUnstructuredGridWriter

import matrixtree

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
BUILD = os.path.join(ROOT, "build-paraview")
PLUGIN = os.path.join(BUILD, "lib", "paraview-5.11", "plugins", "MatrixTree", "MatrixTree.so")
# python3-paraview unpacked (ParaView's own Python packages) and the plugin's wrapped classes.
PV_PYTHONPATH = [os.path.join(BUILD, "python3-paraview", "usr", "lib", "python3", "dist-packages"),
                 os.path.join(BUILD, "lib", "python3.11", "site-packages")]
CHECKS = os.path.join(os.path.dirname(os.path.abspath(__file__)), "pv_checks.py")
collect_ignore = ["pv_checks.py"]  # ParaView's side: pvbatch runs it, this Python must not import it
CFD = os.path.join(matrixtree.scenes.data_dir(), "cfd")

# The grids resampled: tetrahedra with a flow field, hexahedra with a temperature field, and the
# SU2 bricks (wedges; tetrahedra with pyramids), which carry no field: they get an analytic one.
GRIDS = {"pipe_flow_tets.vtu": "Pressure", "disk_out_ref.ex2": "Temp", "brick_prism.su2": "analytic",
         "brick_pyra.su2": "analytic"}


def pv_env():
    # Python's copy of the environment (never the C one a singleton MPI in this process altered).
    env = {k: v for k, v in os.environ.items() if not k.startswith(("OMPI_", "PMIX_"))}
    env["PYTHONPATH"] = os.pathsep.join(PV_PYTHONPATH)
    env.pop("VIRTUAL_ENV", None)
    return env


def mpirun(ranks: int) -> list:
    """mpirun for `ranks` processes on this machine: as root it needs --allow-run-as-root, and
    --oversubscribe lets it start more ranks than cores; no binding, so OpenMP threads spread."""
    cmd = ["mpirun", "-np", str(ranks), "--oversubscribe", "--bind-to", "none"]
    if os.geteuid() == 0:
        cmd.insert(1, "--allow-run-as-root")
    return cmd


def run_pvbatch(command: str, out: str, *args, ranks: int = 1, timeout: int = 600) -> str:
    """Run pv_checks.py's `command` in pvbatch (under mpirun with `ranks` > 1); returns its output."""
    if not os.path.exists(PLUGIN):
        pytest.fail(f"the ParaView plugin is not built ({PLUGIN} missing): run scripts/setup.sh")
    if shutil.which("pvbatch") is None:
        pytest.fail("pvbatch not found: scripts/setup.sh installs Debian's paraview")
    cmd = ["pvbatch", CHECKS, PLUGIN, command, str(out), *map(str, args)]
    if ranks > 1:
        cmd = mpirun(ranks) + cmd
    proc = subprocess.run(cmd, env=pv_env(), capture_output=True, text=True, timeout=timeout)
    log = proc.stdout + proc.stderr
    assert proc.returncode == 0 and os.path.exists(out), f"pvbatch {command} failed ({proc.returncode}):\n{log[-4000:]}"
    return log


def _write_points(path: str, p: np.ndarray):
    pd = vtkPolyData()
    pts = vtkPoints()
    pts.SetData(numpy_to_vtk(p, deep=True))
    pd.SetPoints(pts)
    w = vtkXMLPolyDataWriter()
    w.SetFileName(path)
    w.SetInputData(pd)
    w.Write()


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
        _write_points(points_path, p)
        out[f"{stem}.vtu"] = (grid_path, field, points_path, g, p)
    return out

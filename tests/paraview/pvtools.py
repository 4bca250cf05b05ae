"""Helpers of the ParaView plugin tests: where the plugin and ParaView's Python are, a runner for
pvbatch (serial or under mpirun), and the CFD grids the tests resample.

These tests run in the project's .venv (Debian's VTK 9.1), which never loads ParaView: every
ParaView step runs in a pvbatch subprocess (pv_checks.py) and hands back files. The plugin must
be built first (scripts/setup.sh builds it into build-paraview/).
"""

import os
import shutil
import subprocess

import numpy as np
import pytest
from vtkmodules.util.numpy_support import numpy_to_vtk
from vtkmodules.vtkCommonCore import vtkPoints
from vtkmodules.vtkCommonDataModel import vtkPolyData
from vtkmodules.vtkIOXML import vtkXMLPolyDataWriter

import matrixtree

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
BUILD = os.path.join(ROOT, "build-paraview")
PLUGIN = os.path.join(BUILD, "lib", "paraview-5.11", "plugins", "MatrixTree", "MatrixTree.so")
# python3-paraview unpacked (ParaView's own Python packages) and the plugin's wrapped classes.
PV_PYTHONPATH = [os.path.join(BUILD, "python3-paraview", "usr", "lib", "python3", "dist-packages"),
                 os.path.join(BUILD, "lib", "python3.11", "site-packages")]
CHECKS = os.path.join(os.path.dirname(os.path.abspath(__file__)), "pv_checks.py")
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


def write_points(path: str, p: np.ndarray):
    pd = vtkPolyData()
    pts = vtkPoints()
    pts.SetData(numpy_to_vtk(p, deep=True))
    pd.SetPoints(pts)
    w = vtkXMLPolyDataWriter()
    w.SetFileName(path)
    w.SetInputData(pd)
    w.Write()



"""Scenes: the generated default scene of the main job, and where the shared real data lives."""

from __future__ import annotations

import math
import os

import numpy as np
from vtkmodules.util.numpy_support import numpy_to_vtk
from vtkmodules.vtkCommonDataModel import vtkPolyData
from vtkmodules.vtkFiltersCore import vtkAppendPolyData, vtkTriangleFilter, vtkTubeFilter
from vtkmodules.vtkFiltersSources import vtkPlaneSource, vtkPolyLineSource, vtkSphereSource

from matrixtree._util import vtk_points


def data_dir() -> str:
    """The shared real-data folder: ``$MATRIXTREE_DATA`` if set, else ``../shared/data`` beside
    the project root."""
    env = os.environ.get("MATRIXTREE_DATA")
    if env:
        return env
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    return os.path.normpath(os.path.join(root, "..", "shared", "data"))


def real_scenes() -> dict:
    """Name -> path of the real meshes and the paper's Utah scenes (those that exist)."""
    d = data_dir()
    names = {
        "bunny": "meshes/bunny.ply",
        "lucy": "meshes/lucy.ply",
        "horse": "meshes/horse.ply",
        "turbineblade": "meshes/turbineblade.ply",
        "nefertiti": "meshes/nefertiti.obj",
        "utah_hand": "scenes/utah_hand/hand_00.obj",
        "utah_ben": "scenes/utah_ben/ben_00.obj",
    }
    return {k: os.path.join(d, v) for k, v in names.items() if os.path.exists(os.path.join(d, v))}


def _torus_knot(p: int, q: int, n: int, radius: float, tube: float, sides: int, phase: float = 0.0):
    s = np.linspace(0.0, 2.0 * math.pi, n, endpoint=False)
    r = radius * (2.0 + np.cos(q * s + phase)) / 3.0
    xyz = np.stack([r * np.cos(p * s), radius * np.sin(q * s + phase) / 3.0 + 1.2, r * np.sin(p * s)], axis=1)
    line = vtkPolyLineSource()  # closed: the last point joins the first
    line.SetPoints(vtk_points(xyz))
    line.ClosedOn()
    tf = vtkTubeFilter()
    tf.SetInputConnection(line.GetOutputPort())
    tf.SetRadius(tube)
    tf.SetNumberOfSides(sides)
    tf.CappingOff()
    tf.Update()
    return tf.GetOutput()


def default_scene(resolution: float = 1.0, time: float = 0.0) -> vtkPolyData:
    """The main job's generated scene: a wavy floor, a torus knot and a ring of spheres.

    About 200k triangles at ``resolution=1``; every size scales with ``resolution``. ``time``
    (in periods, 0..1) animates it with the same connectivity: the knot turns, the floor waves.

    Parameters
    ----------
    resolution : float, default: 1.0
        Tessellation scale (0.3 gives about 20k triangles, for quick tests).
    time : float, default: 0.0

    Returns
    -------
    vtkPolyData
        Triangles only.

    Examples
    --------
    >>> from matrixtree import scenes
    >>> scenes.default_scene(resolution=0.3).GetNumberOfPolys() > 10000
    True
    """
    if not resolution > 0:
        raise ValueError(f"resolution must be > 0, got {resolution!r}")
    app = vtkAppendPolyData()
    nf = max(8, int(160 * resolution))
    floor = vtkPlaneSource()
    floor.SetOrigin(-4, 0, -4)
    floor.SetPoint1(4, 0, -4)
    floor.SetPoint2(-4, 0, 4)
    floor.SetResolution(nf, nf)
    floor.Update()
    fl = vtkPolyData()
    fl.DeepCopy(floor.GetOutput())
    from vtkmodules.util.numpy_support import vtk_to_numpy

    xyz = vtk_to_numpy(fl.GetPoints().GetData()).astype(np.float64)
    phase = 2.0 * math.pi * time
    xyz[:, 1] = 0.12 * np.sin(1.7 * xyz[:, 0] + phase) * np.cos(1.3 * xyz[:, 2] - phase)
    fl.GetPoints().SetData(numpy_to_vtk(np.ascontiguousarray(xyz), deep=True))
    app.AddInputData(fl)
    app.AddInputData(_torus_knot(2, 3, max(64, int(900 * resolution)), 1.6, 0.22,
                                 max(6, int(40 * resolution)), phase=phase))
    for k in range(7):
        a = 2.0 * math.pi * k / 7 + 0.5 * phase
        s = vtkSphereSource()
        s.SetCenter(3.0 * math.cos(a), 0.45 + 0.1 * k, 3.0 * math.sin(a))
        s.SetRadius(0.35 + 0.05 * k)
        s.SetThetaResolution(max(8, int(90 * resolution)))
        s.SetPhiResolution(max(8, int(60 * resolution)))
        app.AddInputConnection(s.GetOutputPort())
    tri = vtkTriangleFilter()
    tri.SetInputConnection(app.GetOutputPort())
    tri.Update()
    out = vtkPolyData()
    out.ShallowCopy(tri.GetOutput())
    return out


DEFAULT_CAMERA = [(6.5, 5.0, 8.5), (0.0, 0.9, 0.0), (0.0, 1.0, 0.0), 38.0]
"""pyvista-style camera position (plus view angle) that frames :func:`default_scene`."""

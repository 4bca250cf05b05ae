"""The ParaView side of tests/paraview: run by pvbatch (ParaView 5.11, its VTK 9.2), never by the
project's .venv (Debian's VTK 9.1). Each subcommand loads the plugin, does one thing through
ParaView's proxies, and writes what it measured to an .npz or a .json file that
tests/paraview/test_plugin.py compares with answers from the VTK 9.1 side.

    pvbatch pv_checks.py PLUGIN proxies OUT.json
    pvbatch pv_checks.py PLUGIN resample OUT.npz GRID.vtu FIELD DEST.vtp [GRID.vtu FIELD DEST.vtp ...]
    mpirun -np 2 pvbatch pv_checks.py PLUGIN resample ...        (redistributes the grid first)
    pvbatch pv_checks.py PLUGIN stream OUT.json GRID.vtu FIELD
    pvbatch pv_checks.py PLUGIN probe OUT.json GRID.vtu FIELD X Y Z [X Y Z ...]
    pvbatch pv_checks.py PLUGIN casters OUT.npz MESH.ply VOLUME.vtk SETTINGS.json
"""

import json
import sys

import numpy as np
from paraview import servermanager as sm
from paraview.simple import (LoadPlugin, PLYReader, ProbeLocation, RedistributeDataSet, ResampleWithDataset,
                             StreamTracer, XMLPolyDataReader, XMLUnstructuredGridReader, LegacyVTKReader,
                             GetColorTransferFunction, GetOpacityTransferFunction)
from vtkmodules.numpy_interface import dataset_adapter as dsa
from vtkmodules.vtkParallelCore import vtkMultiProcessController

PLUGIN, COMMAND, OUT = sys.argv[1], sys.argv[2], sys.argv[3]
ARGS = sys.argv[4:]
LoadPlugin(PLUGIN, ns=globals())
CONTROLLER = vtkMultiProcessController.GetGlobalController()
RANKS = CONTROLLER.GetNumberOfProcesses() if CONTROLLER else 1
LOCATORS = {"static": "Static Cell Locator", "matrixtree": "Matrix Tree Cell Locator"}


def fetch(proxy):
    """The proxy's whole output on this (the client) process, wrapped for numpy."""
    return dsa.WrapDataObject(sm.Fetch(proxy))


def write_json(obj):
    with open(OUT, "w") as f:
        json.dump(obj, f)


def proxies():
    from paraview.simple import ResampleWithDataset as R
    names = ["MatrixTreeRepresentation", "MatrixTreeRayCaster", "MatrixTreeVolumeRayCaster",
             "ProbeLocationWithCellLocator", "StreamTracerWithCellLocator"]
    write_json({"cell_locators": list(R().GetProperty("CellLocator").Available),
                "filters": {n: n in globals() for n in names}, "ranks": RANKS})


def resample():
    """ResampleWithDataset of every grid onto the destination points with each locator; under
    MPI the grid is redistributed over the ranks first, so every rank probes its own piece."""
    out = {}
    for path, field, points in zip(ARGS[0::3], ARGS[1::3], ARGS[2::3]):
        dest = XMLPolyDataReader(FileName=[points])
        src = XMLUnstructuredGridReader(FileName=[path])
        if RANKS > 1:
            src = RedistributeDataSet(Input=src)
        for key, label in LOCATORS.items():
            rs = ResampleWithDataset(SourceDataArrays=src, DestinationMesh=dest)
            rs.CellLocator = label
            rs.UpdatePipeline()
            w = fetch(rs)
            name = path.rsplit("/", 1)[-1]
            out[f"{name}|{key}|mask"] = np.asarray(w.PointData["vtkValidPointMask"])
            out[f"{name}|{key}|value"] = np.asarray(w.PointData[field])
            out[f"{name}|{key}|points"] = np.asarray(w.Points)
    np.savez(OUT, ranks=RANKS, **out)


def stream():
    """Streamlines from a line of seeds: ParaView's Stream Tracer (cell-locator interpolator), and
    the plugin's with VTK's static locator and with the matrix tree as the locator's class."""
    import matrixtree_vtk.MatrixTreeParaView  # noqa: F401  (the client-side object's class)
    src = XMLUnstructuredGridReader(FileName=[ARGS[0]])
    b = src.GetDataInformation().GetBounds()
    lo, hi = np.array(b[0::2]), np.array(b[1::2])

    def lines(tracer):
        tracer.Vectors = ["POINTS", ARGS[1]]
        tracer.SeedType.Point1 = list(lo + (hi - lo) * [0.2, 0.45, 0.1])
        tracer.SeedType.Point2 = list(lo + (hi - lo) * [0.8, 0.55, 0.12])
        tracer.SeedType.Resolution = 39
        tracer.MaximumStreamlineLength = float(np.linalg.norm(hi - lo))
        tracer.UpdatePipeline()
        d = sm.Fetch(tracer)
        w = dsa.WrapDataObject(d)
        seeds, reasons = np.asarray(w.CellData["SeedIds"]), np.asarray(w.CellData["ReasonForTermination"])
        result = {}
        for c in range(d.GetNumberOfCells()):
            ids = d.GetCell(c).GetPointIds()
            result[str(int(seeds[c]))] = {"reason": int(reasons[c]),
                                          "points": [d.GetPoint(ids.GetId(k)) for k in range(ids.GetNumberOfIds())]}
        return result

    paraview = StreamTracer(Input=src, SeedType="Line")
    paraview.InterpolatorType = "Interpolator with Cell Locator"
    static = StreamTracerWithCellLocator(Input=src, SeedType="Line", CellLocator=LOCATORS["static"])  # noqa: F821
    tree = StreamTracerWithCellLocator(Input=src, SeedType="Line")  # noqa: F821
    out = {"paraview": lines(paraview), "static": lines(static), "matrixtree": lines(tree),
           "default_locator": tree.CellLocator.GetXMLName(),
           "locators_built": tree.GetClientSideObject().GetNumberOfLocatorsBuilt(),
           "diagonal": float(np.linalg.norm(hi - lo))}
    write_json(out)


def probe():
    """Probe Location and the plugin's Probe Location With Cell Locator at the given points."""
    src = XMLUnstructuredGridReader(FileName=[ARGS[0]])
    field = ARGS[1]
    xyz = np.array(ARGS[2:], dtype=float).reshape(-1, 3)
    rows = []
    for x in xyz:
        pv = ProbeLocation(Input=src, ProbeType="Fixed Radius Point Source")
        pv.ProbeType.Center = list(x)
        mt = ProbeLocationWithCellLocator(Input=src, ProbeType="Fixed Radius Point Source")  # noqa: F821
        mt.ProbeType.Center = list(x)
        rows.append({"paraview": np.asarray(fetch(pv).PointData[field]).tolist(),
                     "matrixtree": np.asarray(fetch(mt).PointData[field]).tolist(),
                     "locator": mt.CellLocator.GetXMLName()})
    write_json(rows)


def casters():
    """The tree representation, the surface ray caster and the volume ray caster through their
    proxies, with the settings the VTK 9.1 side uses."""
    settings = json.load(open(ARGS[2]))
    mesh = PLYReader(FileNames=[ARGS[0]])
    rep = MatrixTreeRepresentation(Input=mesh)  # noqa: F821
    rep.UpdatePipeline()
    r = fetch(rep)
    w, h = settings["size"]
    rc = MatrixTreeRayCaster(Input=mesh, ImageSize=[w, h])  # noqa: F821
    rc.UpdatePipeline()
    img = fetch(rc)
    vol = LegacyVTKReader(FileNames=[ARGS[1]])
    ctf = GetColorTransferFunction("volume_scalars")
    ctf.RGBPoints = [v for node in settings["color"] for v in node[:4]]
    ctf.ColorSpace = "RGB"
    ctf.Discretize = 0
    otf = GetOpacityTransferFunction("volume_scalars")
    otf.Points = [v for node in settings["opacity"] for v in node[:4]]
    vr = MatrixTreeVolumeRayCaster(Input=vol, ImageSize=[w, h], ColorTransferFunction=ctf,  # noqa: F821
                                   ScalarOpacity=otf, **settings["volume"])
    vr.UpdatePipeline()
    vimg = fetch(vr)
    np.savez(OUT, rep_level=np.asarray(r.CellData["level"]), rep_cell_count=np.asarray(r.CellData["cell_count"]),
             rep_points=np.asarray(r.Points), rgb=np.asarray(img.PointData["RGB"]),
             depth=np.asarray(img.PointData["Depth"]), cell_id=np.asarray(img.PointData["CellId"]),
             rgba=np.asarray(vimg.PointData["RGBAFloat"]))


{"proxies": proxies, "resample": resample, "stream": stream, "probe": probe, "casters": casters}[COMMAND]()

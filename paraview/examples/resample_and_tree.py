"""The plugin in pvbatch: the pipe-flow grid resampled onto a plane through the matrix-tree
locator, the nodes of one level of its tree around it, and a picture of both
(docs/images/paraview_plugin.png).

    xvfb-run -a env PYTHONPATH=build-paraview/python3-paraview/usr/lib/python3/dist-packages \\
        pvbatch paraview/examples/resample_and_tree.py [OUT.png]

(run from the project root; pvbatch renders through X, hence xvfb-run on a machine without one).
"""

import os
import sys

from paraview.simple import (GetActiveViewOrCreate, LoadPlugin, Plane, ResampleWithDataset,
                             SaveScreenshot, Show, ColorBy, XMLUnstructuredGridReader)

ROOT = os.getcwd()
LoadPlugin(os.path.join(ROOT, "build-paraview/lib/paraview-5.11/plugins/MatrixTree/MatrixTree.so"), ns=globals())
out = sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "docs/images/paraview_plugin.png")

grid = XMLUnstructuredGridReader(FileName=[os.path.join(ROOT, "../shared/data/cfd/pipe_flow_tets.vtu")])
plane = Plane(Origin=[-2, 0, 0], Point1=[2, 0, 0], Point2=[-2, 0, 30], XResolution=60, YResolution=450)
resampled = ResampleWithDataset(SourceDataArrays=grid, DestinationMesh=plane)
resampled.CellLocator = "Matrix Tree Cell Locator"        # the plugin's locator, in ParaView's list
nodes = MatrixTreeRepresentation(Input=grid, MinLevel=4, MaxLevel=4)  # noqa: F821 (from the plugin)

view = GetActiveViewOrCreate("RenderView")
view.ViewSize = [1200, 700]
view.OrientationAxesVisibility = 0
slice_display = Show(resampled, view)
ColorBy(slice_display, ("POINTS", "Velocity", "Magnitude"))
slice_display.RescaleTransferFunctionToDataRange(True)
slice_display.SetScalarBarVisibility(view, True)
tree_display = Show(nodes, view)
tree_display.SetRepresentationType("Wireframe")
tree_display.AmbientColor = tree_display.DiffuseColor = [0.25, 0.3, 0.4]
tree_display.Opacity = 0.35
view.CameraPosition = [14, -40, 15]
view.CameraFocalPoint = [0, 0, 15]
view.CameraViewUp = [1, 0, 0]
view.CameraParallelProjection = 1
view.CameraParallelScale = 9
SaveScreenshot(out, view, ImageResolution=[1200, 700])
print(out)

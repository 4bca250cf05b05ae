"""Start-up of paraview/pvpython: ParaView's packages (PYTHONPATH) before Debian's
dist-packages, which pvpython puts first and which hold Debian's VTK 9.1 vtkmodules; then run the
script given (or a prompt). Two VTKs in one process crash it."""

import code
import os
import runpy
import sys

DEBIAN = os.path.realpath("/usr/lib/python3/dist-packages")
system = [p for p in sys.path if p and os.path.realpath(p) == DEBIAN]
sys.path[:] = [p for p in sys.path if p not in system] + system[:1]
sys.argv = sys.argv[1:]
if sys.argv:
    sys.path.insert(0, os.path.dirname(os.path.abspath(sys.argv[0])))
    runpy.run_path(sys.argv[0], run_name="__main__")
else:
    code.interact(banner="pvpython (ParaView 5.11); the MatrixTree plugin: "
                  "paraview.simple.LoadPlugin('build-paraview/lib/paraview-5.11/plugins/MatrixTree/MatrixTree.so', ns=globals())")

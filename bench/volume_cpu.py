"""One thread each, CPU time per frame: ours against vtkFixedPointVolumeRayCastMapper, frames
interleaved (VTK, ours, VTK, ...), the median per volume: bench/volume.py's ``cpu_ms_1t`` loop
alone, quick enough to repeat:

    xvfb-run -a .venv/bin/python bench/volume_cpu.py --frames 7

To compare two build trees on a shared machine, run it for each in turn, several times
(``PYTHONPATH=BUILD/python`` picks the build whose ``matrixtree_vtk`` is measured).

Our marchers against each other (AVX2 and SSE2, skipping on and off): ``build/bin/volume_ab``.
"""

from __future__ import annotations

import argparse
import glob
import os
import statistics
import sys

import numpy as np

from _common import ROOT  # noqa: F401  (puts python/ on the path)

import matrixtree_vtk  # noqa: E402
from matrixtree import scenes  # noqa: E402
from volume import Ours, Vtk, default_transfer_functions, frame_camera, read_volume  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--volume", action="append", help="volume file (repeatable); default: every volume")
    ap.add_argument("--size", nargs=2, type=int, default=[512, 512], metavar=("W", "H"))
    ap.add_argument("--frames", type=int, default=7, help="timed frames per renderer (default 7)")
    args = ap.parse_args()
    paths = args.volume or sorted(p for p in glob.glob(os.path.join(scenes.data_dir(), "volumes", "*"))
                                  if not p.endswith(".raw"))
    print(f"# matrixtree_vtk from {os.path.dirname(matrixtree_vtk.__file__)}; {os.getloadavg()[0]:.2f} load")
    size = tuple(args.size)
    for path in paths:
        image = read_volume(path)
        sp = np.abs(np.array(image.GetSpacing()))
        sd = 0.5 * float(sp.min())
        ctf, otf = default_transfer_functions(image)
        cam = frame_camera(image)
        ours, vtk = Ours(image, ctf, otf, float(sp.mean()), size, cam), Vtk(image, ctf, otf, float(sp.mean()), size,
                                                                           cam, sd)
        matched = dict(SampleDistance=sd, DoublePrecision=False, EarlyTerminationThreshold=0.99)
        vtk.mapper.SetNumberOfThreads(1)
        ours.c.SetNumberOfThreads(1)
        vtk.frame()
        ours.frame(**matched)
        c_vtk, c_ours = [], []
        for _ in range(args.frames):
            vtk.frame()
            c_vtk.append(vtk.cpu_ms)
            ours.frame(**matched)
            c_ours.append(ours.cpu_ms)
        v, o = statistics.median(c_vtk), statistics.median(c_ours)
        print(f"{os.path.basename(path).split('.')[0]:18s} vtk {v:7.1f}  ours {o:7.1f} x{v / o:5.2f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())

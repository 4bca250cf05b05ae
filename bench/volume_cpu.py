"""One thread each, CPU time per frame: ours against vtkFixedPointVolumeRayCastMapper, frames
interleaved (VTK, ours, VTK, ...), the median per volume: bench/volume.py's ``cpu_ms_1t`` loop
alone, quick enough to repeat:

    xvfb-run -a .venv/bin/python bench/volume_cpu.py --frames 7

To compare two build trees on a shared machine, run it for each in turn, several times
(``PYTHONPATH=BUILD/python`` picks the build whose ``matrixtree_vtk`` is measured).

``--simd auto sse2`` renders ours twice per frame, the second time with MATRIXTREE_VOLUME_SIMD=sse2
(the SSE2 marcher instead of the AVX2 one), and reports the largest pixel difference between them.
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
    ap.add_argument("--simd", nargs="+", default=["auto"], choices=("auto", "sse2"),
                    help="our marcher(s), each timed in the same interleaved loop (default: auto)")
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
        matched = dict(SampleDistance=sd, DoublePrecision=False, EarlyTerminationThreshold=0.99,
                       EmptySpaceSkipping=True)
        vtk.mapper.SetNumberOfThreads(1)
        ours.c.SetNumberOfThreads(1)
        vtk.frame()
        ours.frame(**matched)
        c_vtk, c_ours, imgs = [], {m: [] for m in args.simd}, {}
        for _ in range(args.frames):
            vtk.frame()
            c_vtk.append(vtk.cpu_ms)
            for m in args.simd:
                if m == "sse2":
                    os.environ["MATRIXTREE_VOLUME_SIMD"] = "sse2"
                else:
                    os.environ.pop("MATRIXTREE_VOLUME_SIMD", None)
                _, imgs[m] = ours.frame(**matched)
                c_ours[m].append(ours.cpu_ms)
        os.environ.pop("MATRIXTREE_VOLUME_SIMD", None)
        v = statistics.median(c_vtk)
        cols = [f"{os.path.basename(path).split('.')[0]:18s} vtk {v:7.1f}"]
        for m in args.simd:
            o = statistics.median(c_ours[m])
            cols.append(f"{m} {o:7.1f} x{v / o:5.2f}")
        if len(args.simd) > 1:
            cols.append("max_diff %.3g" % max(float(np.abs(imgs[m] - imgs[args.simd[0]]).max()) for m in args.simd))
        print("  ".join(cols), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())

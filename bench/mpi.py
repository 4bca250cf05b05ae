"""matrixtree.mpi on 1, 2 and 4 ranks: distributed point location (and VTK's broadcast probe as
the baseline), distributed surface and volume rendering.

The driver starts ``mpirun -np N`` of this same file (``--worker``) for every N of ``--ranks``,
collects what rank 0 reports, prints the tables and writes JSON (and Markdown with ``--md``):

    .venv/bin/python bench/mpi.py --json out/mpi.json --md docs/bench_mpi.md

Per grid: D3 partition time, locator build time (slowest rank), cells per rank (most, and the
cells held twice because their box crosses a cut), bytes per rank (the rank's piece and its
tree), and for one batch of query points spread evenly over the ranks: the time of one
``locate`` (slowest rank, median of --repeats), points per second, (point, rank) pairs per point
(1 = no point sent twice), bytes each rank sends and receives, and the phases (route, locate,
return). Baseline: vtkPProbeFilter, which probes every point on every rank (the whole batch is
broadcast) and reduces the results to rank 0, with the matrix-tree locator as its prototype.
Rendering: the slowest rank's ray cast, the compositing on rank 0 and the image bytes gathered.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile

from _common import ROOT, machine, markdown, table, write_json

GRIDS = ["cfd/pipe_flow_tets.vtu", "cfd/pipe_lumen_tets.vtu", "cfd/brick_pyra.su2"]


# ------------------------------------------------------------------------------------------------
# Worker (one mpirun)
# ------------------------------------------------------------------------------------------------

def worker(args) -> None:
    import numpy as np
    from mpi4py import MPI
    from vtkmodules.util.numpy_support import numpy_to_vtk
    from vtkmodules.vtkCommonCore import vtkPoints
    from vtkmodules.vtkCommonDataModel import vtkPolyData
    from vtkmodules.vtkFiltersParallel import vtkPProbeFilter

    import matrixtree
    from matrixtree.mpi import DistributedLocator, _controller, render_distributed, render_volume_distributed
    from matrixtree_vtk import vtkMatrixTreeLocator

    comm = MPI.COMM_WORLD
    rank, size = comm.Get_rank(), comm.Get_size()
    data = matrixtree.scenes.data_dir()
    report = {"ranks": size, "locate": [], "render": []}

    def slowest(t):
        return comm.allreduce(t, op=MPI.MAX)

    for rel in args.grids:
        grid = matrixtree.read_grid(os.path.join(data, rel)) if rank == 0 else None
        comm.Barrier()
        t0 = MPI.Wtime()
        loc = DistributedLocator(grid)
        setup_s = slowest(MPI.Wtime() - t0)
        part = loc.partition
        build_ms = slowest(loc.locator.vtk_locator.GetLastBuildTime() if loc.locator else 0.0)
        b = np.array(comm.bcast(grid.GetBounds() if rank == 0 else None))
        lo, hi = b[0::2], b[1::2]
        per_rank = args.points // size
        p = lo + (hi - lo) * np.random.default_rng(rank).random((per_rank, 3))
        times, stats = [], None
        for _ in range(args.repeats):
            comm.Barrier()
            t0 = MPI.Wtime()
            loc.locate(p)
            times.append(slowest(MPI.Wtime() - t0))
            stats = loc.last_exchange
        phases = {k: slowest(v) for k, v in stats.seconds.items()}
        piece_bytes = part.piece.GetActualMemorySize() * 1024
        tree_bytes = loc.locator.vtk_locator.GetMemorySize() if loc.locator else 0
        cells = comm.gather(part.piece.GetNumberOfCells(), root=0)
        routed = comm.reduce(stats.routed, root=0)
        sent = comm.gather(stats.bytes_sent, root=0)
        received = comm.gather(stats.bytes_received, root=0)
        piece_b = comm.gather(piece_bytes + tree_bytes, root=0)

        # Baseline: the whole batch on every rank, VTK's parallel probe, results reduced to rank 0.
        allp = np.vstack(comm.allgather(p))
        pts = vtkPoints()
        pts.SetData(numpy_to_vtk(allp, deep=True))
        probe_input = vtkPolyData()
        probe_input.SetPoints(pts)
        probe = vtkPProbeFilter()
        probe.SetController(_controller(comm))
        probe.SetInputData(probe_input)
        probe.SetSourceData(part.piece)
        probe.SetCellLocatorPrototype(vtkMatrixTreeLocator())
        probe.PassPointArraysOff()
        ptimes = []
        for _ in range(max(1, args.repeats // 2)):
            probe.Modified()
            comm.Barrier()
            t0 = MPI.Wtime()
            probe.Update()
            ptimes.append(slowest(MPI.Wtime() - t0))
        if rank == 0:
            med = statistics.median(times)
            report["locate"].append({
                "grid": os.path.basename(rel), "ranks": size, "cells": part.num_cells,
                "cells_per_rank_max": max(cells), "duplicated_cells": sum(cells) - part.num_cells,
                "setup_s": setup_s, "build_ms": build_ms, "bytes_per_rank_max": max(piece_b),
                "points": per_rank * size, "locate_ms": 1e3 * med,
                "mpoints_per_s": per_rank * size / med / 1e6, "pairs_per_point": routed / (per_rank * size),
                "sent_per_rank_max": max(sent), "received_per_rank_max": max(received), "messages": stats.messages,
                "route_ms": 1e3 * phases["route"], "find_ms": 1e3 * phases["locate"],
                "return_ms": 1e3 * phases["return"], "pprobe_ms": 1e3 * statistics.median(ptimes),
                "pprobe_bytes_per_rank": allp.nbytes + len(allp) * 9})

    mesh = matrixtree.read_mesh(os.path.join(data, "meshes", "lucy.ply")) if rank == 0 else None
    comm.Barrier()
    t0 = MPI.Wtime()
    r = render_distributed(mesh, size=(args.size, args.size))
    total = slowest(MPI.Wtime() - t0)
    if rank == 0:
        report["render"].append({"scene": "lucy.ply (surface)", "ranks": size, "total_s": total,
                                 "render_ms_max": max(r["render_ms"]), "composite_ms": r["composite_ms"],
                                 "gathered_bytes": size * args.size ** 2 * (3 + 4 + 8)})
    vol = matrixtree.read_volume(os.path.join(data, "volumes", "embryo.slc")) if rank == 0 else None
    comm.Barrier()
    t0 = MPI.Wtime()
    render_volume_distributed(vol, size=(args.size, args.size))
    total = slowest(MPI.Wtime() - t0)
    if rank == 0:
        report["render"].append({"scene": "embryo.slc (volume)", "ranks": size, "total_s": total,
                                 "gathered_bytes": size * args.size ** 2 * 16})
        with open(args.worker, "w") as f:
            json.dump(report, f)


# ------------------------------------------------------------------------------------------------
# Driver
# ------------------------------------------------------------------------------------------------

LOCATE_COLS = ["grid", "ranks", "cells_per_rank_max", "duplicated_cells", "bytes_per_rank_max", "setup_s",
               "build_ms", "locate_ms", "mpoints_per_s", "pairs_per_point", "sent_per_rank_max", "route_ms",
               "find_ms", "return_ms", "pprobe_ms"]
RENDER_COLS = ["scene", "ranks", "total_s", "render_ms_max", "composite_ms", "gathered_bytes"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--ranks", type=int, nargs="+", default=[1, 2, 4])
    ap.add_argument("--grids", nargs="+", default=GRIDS, help="paths under ../shared/data")
    ap.add_argument("--points", type=int, default=400_000, help="query points per batch (all ranks)")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--size", type=int, default=512, help="image width and height")
    ap.add_argument("--json", default=os.path.join(ROOT, "out", "mpi.json"))
    ap.add_argument("--md", help="also write the tables as Markdown here")
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        worker(args)
        return
    runs = []
    for n in args.ranks:
        with tempfile.NamedTemporaryFile(suffix=".json", delete=False) as tmp:
            out = tmp.name
        cmd = ["mpirun", "-np", str(n), "--oversubscribe", "--bind-to", "none"]
        if os.geteuid() == 0:
            cmd.insert(1, "--allow-run-as-root")
        cmd += [sys.executable, os.path.abspath(__file__), "--worker", out, "--grids", *args.grids,
                "--points", str(args.points), "--repeats", str(args.repeats), "--size", str(args.size)]
        print("$", " ".join(cmd[:8]), "...", flush=True)
        subprocess.run(cmd, check=True)
        runs.append(json.load(open(out)))
        os.unlink(out)
    locate = [row for r in runs for row in r["locate"]]
    render = [row for r in runs for row in r["render"]]
    print(table(locate, LOCATE_COLS))
    print()
    print(table(render, RENDER_COLS))
    load = os.getloadavg()
    write_json(args.json, {"machine": machine(), "load_before": load, "args": vars(args),
                           "locate": locate, "render": render})
    if args.md:
        with open(args.md, "w") as f:
            f.write(f"Command: `.venv/bin/python bench/mpi.py --md {os.path.relpath(args.md, ROOT)}` "
                    f"({machine()['cores']} cores, load average {load[0]:.1f} when it ended).\n\n")
            f.write(markdown(locate, LOCATE_COLS) + "\n\n" + markdown(render, RENDER_COLS) + "\n")


if __name__ == "__main__":
    main()

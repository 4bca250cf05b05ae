"""The MPI side of tests/mpi: run under ``mpirun -np N`` by tests/mpi/test_mpi.py, with the
project's .venv Python (Debian's VTK 9.1, mpi4py). Rank 0 writes what every rank got to an .npz
that the test compares with one process's answers.

    mpirun -np N python mpi_checks.py locate OUT.npz GRID [GRID ...]
    mpirun -np N python mpi_checks.py render OUT.npz MESH
    mpirun -np N python mpi_checks.py volume OUT.npz VOLUME
"""

import sys

import numpy as np
from mpi4py import MPI
from vtkmodules.util.numpy_support import vtk_to_numpy

import matrixtree
from matrixtree.mpi import DistributedLocator, render_distributed, render_volume_distributed

COMM = MPI.COMM_WORLD
RANK, SIZE = COMM.Get_rank(), COMM.Get_size()
COMMAND, OUT, ARGS = sys.argv[1], sys.argv[2], sys.argv[3:]


def query_points(grid, loc, rank):
    """This rank's queries: a different number per rank (none on the last of several), random
    points over the bounds and past them, and on rank 0 the hard cases: grid vertices (in many
    cells at once), edge midpoints (in two or more) and points on the partition's cuts."""
    rng = np.random.default_rng(100 + rank)
    b = np.array(COMM.bcast(grid.GetBounds() if RANK == 0 else None))
    lo, hi = b[0::2], b[1::2]
    n = 0 if (SIZE > 1 and rank == SIZE - 1) else 4000 * (rank + 1)
    pts = [lo - 0.05 * (hi - lo) + 1.1 * (hi - lo) * rng.random((n, 3))]
    if rank == 0:
        xyz = vtk_to_numpy(grid.GetPoints().GetData()).astype(np.float64)
        pts.append(xyz[::5])
        cells = grid.GetCells()
        conn = vtk_to_numpy(cells.GetConnectivityArray()).astype(np.int64)
        offsets = vtk_to_numpy(cells.GetOffsetsArray()).astype(np.int64)
        first = conn[offsets[:-1]]
        second = conn[offsets[:-1] + 1]
        pts.append(0.5 * (xyz[first] + xyz[second])[::3])
        for bounds in loc.partition.region_bounds:  # the regions' faces: where routing decides
            for axis in range(3):
                q = lo + (hi - lo) * rng.random((300, 3))
                q[:, axis] = bounds[2 * axis + 1]
                pts.append(q)
    return np.vstack(pts)


def locate():
    out = {}
    for path in ARGS:
        grid = matrixtree.read_grid(path) if RANK == 0 else None
        loc = DistributedLocator(grid)
        p = query_points(grid, loc, RANK)
        ids = loc.locate(p)
        name = path.rsplit("/", 1)[-1]
        points, answers = COMM.gather(p, root=0), COMM.gather(ids, root=0)
        stats = COMM.gather(loc.last_exchange, root=0)
        cells = COMM.gather(loc.partition.piece.GetNumberOfCells(), root=0)
        threads = COMM.gather(loc.threads, root=0)
        if RANK == 0:
            for r in range(SIZE):
                out[f"{name}|points|{r}"] = points[r]
                out[f"{name}|ids|{r}"] = answers[r]
            out[f"{name}|routed"] = np.array([s.routed for s in stats])
            out[f"{name}|asked"] = np.array([s.points for s in stats])
            out[f"{name}|answered"] = np.array([s.answered for s in stats])
            out[f"{name}|cells"] = np.array(cells)
            out[f"{name}|threads"] = np.array(threads)
            out[f"{name}|num_cells"] = np.array(loc.partition.num_cells)
    if RANK == 0:
        np.savez(OUT, ranks=SIZE, **out)


def render():
    mesh = matrixtree.read_mesh(ARGS[0]) if RANK == 0 else None
    r = render_distributed(mesh, size=(128, 96))
    if RANK == 0:
        cam = r["camera"]
        np.savez(OUT, ranks=SIZE, rgb=r["rgb"], depth=r["depth"], cell_ids=r["cell_ids"],
                 position=cam[0], focal=cam[1], up=cam[2], angle=cam[3])


def volume():
    vol = matrixtree.read_volume(ARGS[0]) if RANK == 0 else None
    r = render_volume_distributed(vol, size=(128, 96), return_parts=True)
    if RANK == 0:
        np.savez(OUT, ranks=SIZE, image=r["image"], parts=np.stack(r["parts"]), order=np.array(r["order"]))


{"locate": locate, "render": render, "volume": volume}[COMMAND]()

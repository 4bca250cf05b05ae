"""Point location and rendering across MPI ranks (mpi4py and Debian's VTK 9.1 parallel filters).

Every function here is collective: all ranks of ``comm`` call it, each with its own arguments.

Point location (:class:`DistributedLocator`)
    The grid is partitioned by VTK's D3 filter (``vtkPDistributedDataFilter``: a kd-tree of
    regions balanced by cell count, every cell sent to each region its bounding box intersects).
    Each rank builds one :class:`matrixtree.CellLocator` on its piece, with cores / ranks threads.
    A batch of query points is routed, from the kd-tree's region boxes, only to the ranks whose
    region (grown by a margin, below) contains a point, in one ``Alltoallv``; each rank answers
    its points with one batched ``locate``; a second ``Alltoallv`` returns the global cell ids,
    which land in the caller's order. (``vtkPProbeFilter`` instead sends every point to every
    rank.)

    Why the answers are one process's: a cell that accepts a point (VTK's EvaluatePosition, with
    its 1e-3 parametric tolerance) lies within ``margin`` of it (``margin`` = 1e-2 of the largest
    cell's bounding-box diagonal, well above that tolerance); the nearest point of the cell's box
    lies in some region whose rank holds the cell, and that region's box grown by ``margin``
    contains the query point, so the point reaches every rank that holds a cell accepting it.
    Each rank's piece keeps the global cell order (D3 keeps it; the ids ride along as the cell
    array ``GlobalCellId``), so each rank answers with its lowest-id accepting cell, as the
    locator on the whole grid does (its candidates are scanned in cell-id order), and of
    several answers for one point the lowest global id is kept.

Rendering (:func:`render_distributed`, :func:`render_volume_distributed`)
    Surfaces: D3 spreads the triangles; every rank ray casts its piece with the same camera
    (``matrixtree.render``) and the root keeps, per pixel, the nearest hit (sort-last compositing
    by depth). ``render`` lights the scene from the bounding box of the mesh's points, so every
    piece carries the whole mesh's box as two extra points that no triangle uses: each rank
    shades as one process does, and the composited image is ``render(mesh, camera=...,
    shadows=False)``'s, pixel for pixel. Shadows are not offered: a shadow ray must be tested
    against every rank's triangles, which sort-last compositing cannot do.
    Volumes: the root cuts the image into one brick per rank by recursive bisection (bricks
    share their boundary points), every rank renders its brick (``matrixtree.render_volume``,
    same camera and transfer functions), and the root composites the premultiplied RGBA images
    front to back in the visibility order of the bisection tree. Each brick's rays start
    sampling where they enter the brick and each brick's lookup table spans its own scalar
    range, so the image equals one process's up to that resampling (docs/mpi.md measures it).

Run under ``mpirun`` (as root: ``--allow-run-as-root``; more ranks than cores:
``--oversubscribe``); see docs/mpi.md.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np
from mpi4py import MPI
from vtkmodules.util.numpy_support import numpy_to_vtk, vtk_to_numpy
from vtkmodules.vtkCommonCore import vtkPoints
from vtkmodules.vtkCommonDataModel import vtkDataSet, vtkImageData, vtkPiecewiseFunction, vtkPolyData, vtkUnstructuredGrid
from vtkmodules.vtkFiltersGeometry import vtkGeometryFilter
from vtkmodules.vtkFiltersParallelGeometry import vtkPDistributedDataFilter
from vtkmodules.vtkParallelMPI import vtkMPIController
from vtkmodules.vtkParallelMPI4Py import vtkMPI4PyCommunicator
from vtkmodules.vtkRenderingCore import vtkCamera, vtkColorTransferFunction

from matrixtree.locator import CellLocator
from matrixtree.core import render
from matrixtree.volume import default_transfer_functions, frame_camera, render_volume

__all__ = ["Partition", "partition", "DistributedLocator", "threads_per_rank", "render_distributed",
           "render_volume_distributed"]

GLOBAL_CELL_ID = "GlobalCellId"
_MARGIN_SCALE = 1e-2  # of the largest cell's bounding-box diagonal; VTK accepts up to ~1e-3 of it


def _comm(comm):
    return MPI.COMM_WORLD if comm is None else comm


def _controller(comm) -> vtkMPIController:
    """A vtkMPIController over the same processes as ``comm`` (for VTK's parallel filters)."""
    ctrl = vtkMPIController()
    ctrl.SetCommunicator(vtkMPI4PyCommunicator.ConvertToVTK(comm))
    return ctrl


def threads_per_rank(comm=None) -> int:
    """The cores of this node divided among the ranks on it (at least 1)."""
    comm = _comm(comm)
    node = comm.Split_type(MPI.COMM_TYPE_SHARED)
    try:
        return max(1, (os.cpu_count() or 1) // node.Get_size())
    finally:
        node.Free()


@dataclass
class Partition:
    """This rank's piece of a grid distributed by D3, and the regions of its kd-tree.

    Attributes
    ----------
    piece : vtkUnstructuredGrid
        This rank's cells, in ascending global id, with the cell array ``GlobalCellId`` (int64).
    global_ids : numpy.ndarray
        ``GlobalCellId`` as numpy (piece cell -> global cell).
    region_bounds : numpy.ndarray, shape (R, 6)
        Every region's box (xmin, xmax, ymin, ymax, zmin, zmax), the same on all ranks.
    region_rank : numpy.ndarray, shape (R,)
        The rank that holds each region's cells.
    num_cells : int
        Cells of the whole grid.
    """

    piece: vtkUnstructuredGrid
    global_ids: np.ndarray
    region_bounds: np.ndarray
    region_rank: np.ndarray
    num_cells: int

    def rank_boxes(self):
        """(box, rank) pairs covering every rank's regions: a rank's regions as one box where they
        fill their bounding box (kd-tree leaves do not overlap, so equal volumes mean that), else
        region by region. D3 gives each rank a subtree of its kd-tree (one box); on one rank it
        splits the grid into many regions, which this keeps from being tested one by one."""
        pairs = []
        for r in np.unique(self.region_rank):
            boxes = self.region_bounds[self.region_rank == r]
            whole = np.concatenate([[boxes[:, 0::2].min(axis=0)], [boxes[:, 1::2].max(axis=0)]]).T.ravel()
            volume = lambda b: np.prod(b[..., 1::2] - b[..., 0::2], axis=-1)  # noqa: E731
            if np.isclose(volume(boxes).sum(), volume(whole), rtol=1e-9, atol=0.0):
                pairs.append((whole, int(r)))
            else:
                pairs.extend((b, int(r)) for b in boxes)
        return pairs


def partition(dataset, comm=None, boundary: str = "all") -> Partition:
    """Distribute a grid over the ranks of ``comm`` with VTK's D3 filter (collective).

    Parameters
    ----------
    dataset : vtkDataSet or None
        The cells this rank holds before the call: the whole grid on one rank and ``None``
        elsewhere, or any split. Global cell ids number the ranks' cells in rank order.
    comm : mpi4py.MPI.Comm, optional
        Default ``MPI.COMM_WORLD``.
    boundary : {"all", "one"}, default: "all"
        A cell whose box crosses region boundaries goes to every region it intersects ("all":
        what point location needs) or to one region only ("one": no duplicates, for rendering).

    Returns
    -------
    Partition
    """
    comm = _comm(comm)
    if boundary not in ("all", "one"):
        raise ValueError(f"boundary must be 'all' or 'one', got {boundary!r}")
    if dataset is not None and not isinstance(dataset, vtkDataSet):
        raise TypeError(f"dataset must be a vtkDataSet or None, got {type(dataset).__name__}")
    n_local = 0 if dataset is None else int(dataset.GetNumberOfCells())
    offset = comm.exscan(n_local) or 0
    num_cells = comm.allreduce(n_local)
    if num_cells == 0:
        raise ValueError("partition: no rank holds a cell")
    if dataset is None or n_local == 0:
        source = vtkUnstructuredGrid()
        source.SetPoints(vtkPoints())
    else:
        source = dataset.NewInstance()
        source.ShallowCopy(dataset)  # the caller's data set keeps its arrays
    ids = numpy_to_vtk(np.arange(offset, offset + n_local, dtype=np.int64), deep=True)
    ids.SetName(GLOBAL_CELL_ID)
    source.GetCellData().AddArray(ids)

    d3 = vtkPDistributedDataFilter()
    d3.SetController(_controller(comm))
    d3.SetInputData(source)
    if boundary == "all":
        d3.SetBoundaryModeToAssignToAllIntersectingRegions()
    else:
        d3.SetBoundaryModeToAssignToOneRegion()
    d3.RetainKdtreeOn()
    d3.Update()
    piece = vtkUnstructuredGrid()
    piece.ShallowCopy(d3.GetOutput())
    kd = d3.GetKdtree()
    nreg = kd.GetNumberOfRegions()
    bounds = np.zeros((nreg, 6))
    b = [0.0] * 6
    for r in range(nreg):
        kd.GetRegionBounds(r, b)
        bounds[r] = b
    owner = np.array([kd.GetProcessAssignedToRegion(r) for r in range(nreg)], dtype=np.int64)
    arr = piece.GetCellData().GetArray(GLOBAL_CELL_ID)
    gids = (vtk_to_numpy(arr).astype(np.int64) if arr is not None and piece.GetNumberOfCells()
            else np.zeros(0, np.int64))
    if gids.size > 1 and not np.all(np.diff(gids) > 0):
        raise RuntimeError("D3 returned the cells out of global order; DistributedLocator relies on it")
    return Partition(piece, gids, bounds, owner, num_cells)


def _cell_box_diagonals(grid: vtkUnstructuredGrid) -> np.ndarray:
    """The bounding-box diagonal of every cell of an unstructured grid (vectorized)."""
    n = grid.GetNumberOfCells()
    if n == 0:
        return np.zeros(0)
    pts = vtk_to_numpy(grid.GetPoints().GetData()).astype(np.float64)
    cells = grid.GetCells()
    conn = vtk_to_numpy(cells.GetConnectivityArray()).astype(np.int64)
    offsets = vtk_to_numpy(cells.GetOffsetsArray()).astype(np.int64)[:-1]
    xyz = pts[conn]
    lo = np.minimum.reduceat(xyz, offsets, axis=0)
    hi = np.maximum.reduceat(xyz, offsets, axis=0)
    return np.sqrt(((hi - lo) ** 2).sum(axis=1))


@dataclass
class ExchangeStats:
    """What the last :meth:`DistributedLocator.locate` moved, seen from this rank."""

    points: int = 0            # query points this rank asked about
    routed: int = 0            # (point, rank) pairs sent, own rank included
    answered: int = 0          # points this rank answered for all ranks
    bytes_sent: int = 0        # to other ranks: points out, answers back
    bytes_received: int = 0
    messages: int = 0          # collective calls (Alltoall of counts, Alltoallv out, Alltoallv back)
    seconds: dict = field(default_factory=dict)


class DistributedLocator:
    """Point location on a grid partitioned across MPI ranks (collective; see the module doc).

    Parameters
    ----------
    dataset : vtkDataSet or None
        This rank's cells before partitioning (the whole grid on one rank and ``None`` on the
        others, or any split; global ids number them in rank order).
    comm : mpi4py.MPI.Comm, optional
        Default ``MPI.COMM_WORLD``.
    tree, height : as in :class:`matrixtree.CellLocator`
    threads : int, optional
        Threads of each rank's locator; default :func:`threads_per_rank`.

    Examples
    --------
    Under ``mpirun -np 4 python script.py``::

        grid = matrixtree.read_grid(path) if MPI.COMM_WORLD.rank == 0 else None
        loc = DistributedLocator(grid)
        ids = loc.locate(my_points)   # each rank its own points; global cell ids, -1 outside

    On one process it is the plain locator:

    >>> import numpy as np, matrixtree
    >>> from vtkmodules.vtkImagingCore import vtkRTAnalyticSource
    >>> from vtkmodules.vtkFiltersGeneral import vtkDataSetTriangleFilter
    >>> src = vtkRTAnalyticSource(); src.SetWholeExtent(0, 6, 0, 6, 0, 6)
    >>> tets = vtkDataSetTriangleFilter(); tets.SetInputConnection(src.GetOutputPort()); tets.Update()
    >>> p = np.random.default_rng(0).uniform(-1, 7, (500, 3))
    >>> ids = DistributedLocator(tets.GetOutput()).locate(p)
    >>> bool(np.array_equal(ids, matrixtree.CellLocator(tets.GetOutput()).locate(p))), int((ids >= 0).sum()) > 100
    (True, True)
    """

    def __init__(self, dataset, comm=None, tree: str = "octree", height: int = 0, threads: int | None = None):
        self.comm = _comm(comm)
        self.partition = partition(dataset, self.comm, boundary="all")
        self.threads = threads_per_rank(self.comm) if threads is None else int(threads)
        piece = self.partition.piece
        self.locator = (CellLocator(piece, tree=tree, height=height, threads=self.threads)
                        if piece.GetNumberOfCells() else None)
        diag = _cell_box_diagonals(piece)
        self.margin = _MARGIN_SCALE * self.comm.allreduce(float(diag.max()) if diag.size else 0.0, op=MPI.MAX)
        self._boxes = self.partition.rank_boxes()
        self.last_exchange = ExchangeStats()

    def _destinations(self, p: np.ndarray) -> np.ndarray:
        """(n, ranks) bool: which ranks hold a region whose box, grown by the margin, holds each point."""
        size = self.comm.Get_size()
        dest = np.zeros((len(p), size), dtype=bool)
        m = self.margin
        for b, r in self._boxes:
            inside = ((p[:, 0] >= b[0] - m) & (p[:, 0] <= b[1] + m) & (p[:, 1] >= b[2] - m) &
                      (p[:, 1] <= b[3] + m) & (p[:, 2] >= b[4] - m) & (p[:, 2] <= b[5] + m))
            dest[:, r] |= inside
        return dest

    def locate(self, points) -> np.ndarray:
        """The global id of the cell containing each of this rank's points, or -1 (collective).

        Parameters
        ----------
        points : array_like, shape (n, 3)
            This rank's query points (n may differ between ranks, and be 0).

        Returns
        -------
        numpy.ndarray of int64, shape (n,)
            In the order of ``points``: the id the cell had in the numbering of the grid given
            to the constructor (ranks' cells in rank order).
        """
        comm = self.comm
        size = comm.Get_size()
        t0 = MPI.Wtime()
        p = np.ascontiguousarray(np.asarray(points, dtype=np.float64))
        if p.ndim == 1 and p.size == 3:
            p = p.reshape(1, 3)
        if p.ndim != 2 or p.shape[1] != 3:
            raise ValueError(f"points must have shape (n, 3), got {p.shape}")
        dest = self._destinations(p)
        # Outgoing (point, rank) pairs grouped by rank, in point order within each rank.
        rank_of, point_of = np.nonzero(dest.T)
        send_counts = np.bincount(rank_of, minlength=size).astype(np.int64)
        recv_counts = np.zeros(size, dtype=np.int64)
        comm.Alltoall(send_counts, recv_counts)
        send_pts = np.ascontiguousarray(p[point_of])
        recv_pts = np.empty((int(recv_counts.sum()), 3), dtype=np.float64)
        sdispl = np.concatenate([[0], np.cumsum(send_counts)[:-1]])
        rdispl = np.concatenate([[0], np.cumsum(recv_counts)[:-1]])
        comm.Alltoallv([send_pts, (send_counts * 3, sdispl * 3), MPI.DOUBLE],
                       [recv_pts, (recv_counts * 3, rdispl * 3), MPI.DOUBLE])
        t1 = MPI.Wtime()
        answers = np.full(len(recv_pts), -1, dtype=np.int64)
        if self.locator is not None and len(recv_pts):
            local = self.locator.locate(recv_pts)
            found = local >= 0
            answers[found] = self.partition.global_ids[local[found]]
        t2 = MPI.Wtime()
        back = np.empty(len(point_of), dtype=np.int64)
        comm.Alltoallv([answers, (recv_counts, rdispl), MPI.INT64_T], [back, (send_counts, sdispl), MPI.INT64_T])
        # Of several answers for one point the lowest global id (the whole grid's locator's answer).
        best = np.full(len(p), np.iinfo(np.int64).max, dtype=np.int64)
        hit = back >= 0
        np.minimum.at(best, point_of[hit], back[hit])
        best[best == np.iinfo(np.int64).max] = -1
        t3 = MPI.Wtime()
        me = comm.Get_rank()
        others_out = int(send_counts.sum() - send_counts[me])
        others_in = int(recv_counts.sum() - recv_counts[me])
        self.last_exchange = ExchangeStats(
            points=len(p), routed=int(send_counts.sum()), answered=len(recv_pts),
            bytes_sent=others_out * 24 + others_in * 8, bytes_received=others_in * 24 + others_out * 8,
            messages=3, seconds={"route": t1 - t0, "locate": t2 - t1, "return": t3 - t2, "total": t3 - t0})
        return best


# ---------------------------------------------------------------------------------------------
# Rendering
# ---------------------------------------------------------------------------------------------

def _framing_camera(bounds, view_angle: float = 30.0):
    """``[position, focal point, view up, view angle]`` framing ``bounds`` from the +z side, tilted."""
    lo = np.array(bounds[0::2], dtype=float)
    hi = np.array(bounds[1::2], dtype=float)
    c = 0.5 * (lo + hi)
    r = 0.5 * float(np.linalg.norm(hi - lo)) or 1.0
    d = np.array([0.35, 0.45, 1.0])
    d /= np.linalg.norm(d)
    dist = r / np.sin(0.5 * np.radians(view_angle)) * 1.05
    return [tuple(c + d * dist), tuple(c), (0.0, 1.0, 0.0), float(view_angle)]


def _point_bounds(ds) -> np.ndarray:
    """(min xyz, max xyz) of a data set's points; +inf/-inf when it has none."""
    if ds is None or ds.GetNumberOfPoints() == 0:
        return np.array([np.inf] * 3 + [-np.inf] * 3)
    pts = vtk_to_numpy(ds.GetPoints().GetData())
    return np.concatenate([pts.min(axis=0), pts.max(axis=0)]).astype(np.float64)


def render_distributed(mesh, comm=None, size=(800, 800), camera=None, tree: str = "octree",
                       threads: int | None = None, root: int = 0):
    """Ray cast a surface spread over the ranks; the root composites by depth (collective).

    Parameters
    ----------
    mesh : vtkDataSet or None
        This rank's triangles before the call (the whole mesh on one rank and ``None`` on the
        others, or any split); D3 balances them over the ranks.
    size : (int, int), default: (800, 800)
    camera : sequence, optional
        ``[position, focal_point, view_up(, view_angle)]`` as for :func:`matrixtree.render`;
        default: one that frames the whole mesh (returned as ``"camera"``).
    tree : {"octree", "kdtree"}, default: "octree"
    threads : int, optional
        Threads per rank; default :func:`threads_per_rank`.
    root : int, default: 0

    Returns
    -------
    dict or None
        On the root: ``rgb`` (H, W, 3) uint8 and ``depth`` (H, W) float32 (row 0 at the top),
        ``cell_ids`` (H, W) global cell ids (-1: background), ``camera``, ``render_ms`` (per
        rank), ``composite_ms``; ``None`` on the other ranks. ``rgb`` and ``depth`` equal
        ``matrixtree.render(mesh, size, camera=camera, shadows=False)``'s.
    """
    comm = _comm(comm)
    threads = threads_per_rank(comm) if threads is None else int(threads)
    part = partition(mesh, comm, boundary="one")
    geo = vtkGeometryFilter()
    geo.SetInputData(part.piece)
    geo.Update()
    piece = vtkPolyData()
    piece.ShallowCopy(geo.GetOutput())
    # The whole mesh's point box (render() lights and offsets from its own input's box).
    local = _point_bounds(mesh)
    lo, hi = np.empty(3), np.empty(3)
    comm.Allreduce(np.ascontiguousarray(local[:3]), lo, op=MPI.MIN)
    comm.Allreduce(np.ascontiguousarray(local[3:]), hi, op=MPI.MAX)
    if camera is None:
        camera = _framing_camera([lo[0], hi[0], lo[1], hi[1], lo[2], hi[2]])
    w, h = int(size[0]), int(size[1])
    gids = (vtk_to_numpy(piece.GetCellData().GetArray(GLOBAL_CELL_ID)).astype(np.int64)
            if piece.GetNumberOfCells() else np.zeros(0, np.int64))
    if piece.GetNumberOfPolys():
        pts = vtk_to_numpy(piece.GetPoints().GetData()).astype(np.float64)
        with_box = vtkPoints()
        with_box.SetData(numpy_to_vtk(np.vstack([pts, lo, hi]), deep=True))
        lit = vtkPolyData()
        lit.ShallowCopy(piece)
        lit.SetPoints(with_box)
        img = render(lit, size=(w, h), tree=tree, camera=camera, shadows=False, threads=threads)
        rgb, depth, ms = img["rgb"], img["depth"], img["render_ms"]
        cid = vtk_to_numpy(img["caster"].GetOutput().GetPointData().GetArray("CellId")).reshape(h, w)[::-1]
        cells = np.where(cid >= 0, gids[np.clip(cid, 0, None)] if gids.size else -1, -1)
    else:  # no triangles here: a background image that never wins a pixel
        rgb = np.zeros((h, w, 3), np.uint8)
        depth = np.full((h, w), np.inf, np.float32)
        cells = np.full((h, w), -1, np.int64)
        ms = 0.0
    rendered = piece.GetNumberOfPolys() > 0
    rgbs = comm.gather(np.ascontiguousarray(rgb), root=root)
    depths = comm.gather(np.ascontiguousarray(depth), root=root)
    cellss = comm.gather(np.ascontiguousarray(cells), root=root)
    times = comm.gather(ms, root=root)
    renderers = comm.gather(rendered, root=root)
    if comm.Get_rank() != root:
        return None
    t0 = MPI.Wtime()
    stack = np.stack(depths)                     # (ranks, H, W)
    win = np.argmin(stack, axis=0)               # the nearest hit; of equal depths the first rank
    missed = ~np.isfinite(stack.min(axis=0))
    win[missed] = renderers.index(True)          # background: as a rank that rendered draws it
    rows, cols = np.indices((h, w))
    return {"rgb": np.stack(rgbs)[win, rows, cols], "depth": stack[win, rows, cols],
            "cell_ids": np.stack(cellss)[win, rows, cols], "camera": camera,
            "render_ms": times, "composite_ms": 1e3 * (MPI.Wtime() - t0)}


def _bisect(extent, n: int):
    """Split a point extent (i0, i1, j0, j1, k0, k1) into n bricks by recursive bisection along
    the longest axis (neighbours share their boundary plane of points). Returns the bricks and
    the tree: a leaf is a brick index, an inner node (axis, plane coordinate index, low, high)."""
    bricks = []

    def split(ext, n):
        if n == 1:
            bricks.append(tuple(ext))
            return len(bricks) - 1
        lengths = [ext[1] - ext[0], ext[3] - ext[2], ext[5] - ext[4]]
        axis = int(np.argmax(lengths))
        if lengths[axis] < 2:
            raise ValueError(f"the volume is too small for {n} bricks along its longest axis")
        n_lo = n // 2
        cut = ext[2 * axis] + max(1, round(lengths[axis] * n_lo / n))
        lo_ext, hi_ext = list(ext), list(ext)
        lo_ext[2 * axis + 1] = cut
        hi_ext[2 * axis] = cut
        return (axis, cut, split(lo_ext, n_lo), split(hi_ext, n - n_lo))

    tree = split(list(extent), n)
    return bricks, tree


def _visibility_order(tree, eye, origin, spacing):
    """Brick indices front to back for a camera at ``eye``: at every cut, the side holding the
    eye first (the bricks are convex and the cuts planes, so this is a visibility order)."""
    if isinstance(tree, int):
        return [tree]
    axis, cut, lo, hi = tree
    plane = origin[axis] + cut * spacing[axis]
    first, second = (lo, hi) if eye[axis] < plane else (hi, lo)
    return _visibility_order(first, eye, origin, spacing) + _visibility_order(second, eye, origin, spacing)


def _nodes(function, width: int) -> list:
    """A transfer function's nodes as lists of `width` numbers (x and its values), to broadcast."""
    def node(i):
        v = [0.0] * width
        function.GetNodeValue(i, v)
        return v
    return [node(i) for i in range(function.GetSize())]


def _function_nodes(ctf: vtkColorTransferFunction, otf: vtkPiecewiseFunction):
    return _nodes(ctf, 6), _nodes(otf, 4)


def _functions_from_nodes(cn, on):
    ctf = vtkColorTransferFunction()
    for x, r, g, b, mid, sharp in cn:
        ctf.AddRGBPoint(x, r, g, b, mid, sharp)
    otf = vtkPiecewiseFunction()
    for x, y, mid, sharp in on:
        otf.AddPoint(x, y, mid, sharp)
    return ctf, otf


def render_volume_distributed(volume, comm=None, size=(512, 512), camera=None, color=None, opacity=None,
                              sample_distance: float | None = None, early_termination: float = 0.99,
                              threads: int | None = None, root: int = 0, return_parts: bool = False):
    """Volume render an image cut into one brick per rank; the root composites (collective).

    Parameters
    ----------
    volume : vtkImageData or None
        The whole volume on the root (one-component point scalars); ignored elsewhere.
    size, sample_distance, early_termination : as in :func:`matrixtree.render_volume`
    camera : vtkCamera, optional
        Default :func:`matrixtree.frame_camera` of the volume.
    color, opacity : vtkColorTransferFunction, vtkPiecewiseFunction, optional
        On the root; default :func:`matrixtree.default_transfer_functions` of the whole volume.
    threads : int, optional
        Threads per rank; default :func:`threads_per_rank`.
    return_parts : bool, default: False
        Also return every brick's image and the visibility order (for tests).

    Returns
    -------
    numpy.ndarray or None
        On the root, ``(H, W, 4)`` float32 premultiplied RGBA (row 0 at the top); with
        ``return_parts`` a dict ``image``, ``parts`` (per rank), ``order``, ``bricks``.
        ``None`` on the other ranks.
    """
    comm = _comm(comm)
    me, nranks = comm.Get_rank(), comm.Get_size()
    threads = threads_per_rank(comm) if threads is None else int(threads)
    setup = None
    if me == root:
        if not isinstance(volume, vtkImageData):
            raise TypeError(f"the root's volume must be a vtkImageData, got {type(volume).__name__}")
        scalars = volume.GetPointData().GetScalars()
        if scalars is None or scalars.GetNumberOfComponents() != 1:
            raise ValueError("the volume needs one-component point scalars")
        if color is None or opacity is None:
            dc, do = default_transfer_functions(volume)
            color = color if color is not None else dc
            opacity = opacity if opacity is not None else do
        cam = camera if camera is not None else frame_camera(volume)
        sp = np.abs(np.array(volume.GetSpacing(), dtype=float))
        setup = {
            "extent": volume.GetExtent(), "origin": volume.GetOrigin(), "spacing": volume.GetSpacing(),
            "camera": (cam.GetPosition(), cam.GetFocalPoint(), cam.GetViewUp(), cam.GetViewAngle(),
                       cam.GetParallelProjection(), cam.GetParallelScale()),
            "functions": _function_nodes(color, opacity),
            "sample_distance": float(sample_distance or 0.5 * sp.min()),
            "opacity_unit_distance": float(sp.mean()),
        }
    setup = comm.bcast(setup, root=root)
    bricks, tree = _bisect(setup["extent"], nranks)
    # The root sends each rank its brick's scalars.
    if me == root:
        all_s = vtk_to_numpy(volume.GetPointData().GetScalars())
        e = setup["extent"]
        grid = all_s.reshape(e[5] - e[4] + 1, e[3] - e[2] + 1, e[1] - e[0] + 1)  # z, y, x
        for r, b in enumerate(bricks):
            block = np.ascontiguousarray(grid[b[4] - e[4]:b[5] - e[4] + 1, b[2] - e[2]:b[3] - e[2] + 1,
                                              b[0] - e[0]:b[1] - e[0] + 1])
            if r == root:
                mine = block
            else:
                comm.send((block.dtype.str, block.shape), dest=r, tag=11)
                comm.Send(block, dest=r, tag=12)
    else:
        dtype, shape = comm.recv(source=root, tag=11)
        mine = np.empty(shape, dtype=np.dtype(dtype))
        comm.Recv(mine, source=root, tag=12)
    b = bricks[me]
    piece = vtkImageData()  # the brick as an image of its own: extent from 0, origin moved to its corner
    piece.SetDimensions(b[1] - b[0] + 1, b[3] - b[2] + 1, b[5] - b[4] + 1)
    piece.SetOrigin([o + i * s for o, i, s in zip(setup["origin"], b[0::2], setup["spacing"])])
    piece.SetSpacing(setup["spacing"])
    arr = numpy_to_vtk(mine.ravel(), deep=True)
    arr.SetName("scalars")
    piece.GetPointData().SetScalars(arr)
    pos, focal, up, angle, parallel, scale = setup["camera"]
    cam = vtkCamera()
    cam.SetPosition(pos)
    cam.SetFocalPoint(focal)
    cam.SetViewUp(up)
    cam.SetViewAngle(angle)
    cam.SetParallelProjection(parallel)
    cam.SetParallelScale(scale)
    ctf, otf = _functions_from_nodes(*setup["functions"])
    image = render_volume(piece, size=size, camera=cam, color=ctf, opacity=otf,
                          sample_distance=setup["sample_distance"],
                          opacity_unit_distance=setup["opacity_unit_distance"],
                          early_termination=early_termination, threads=threads)
    parts = comm.gather(image, root=root)
    if me != root:
        return None
    if parallel:
        # Parallel rays: the eye is far behind the focal point along the view direction.
        d = np.subtract(focal, pos)
        eye = np.asarray(focal) - d / np.linalg.norm(d) * 1e30
    else:
        eye = np.asarray(pos)
    order = _visibility_order(tree, eye, setup["origin"], setup["spacing"])
    out = np.zeros_like(parts[0])
    for r in order:  # front to back, premultiplied: out += (1 - alpha_out) * part
        out += (1.0 - out[..., 3:4]) * parts[r]
    if return_parts:
        return {"image": out, "parts": parts, "order": order, "bricks": bricks}
    return out

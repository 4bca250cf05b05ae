"""pyvista-style filters on the matrix-tree cell locator: cell queries, sampling and rays.

The functions take the mesh first and mirror pyvista's own filters of the same names
(``DataSet.find_containing_cell``, ``find_closest_cell``, ``find_cells_along_line``,
``find_cells_within_bounds``, ``DataSetFilters.sample`` / ``probe``, ``PolyDataFilters.ray_trace``
/ ``multi_ray_trace``): the same arguments where they mean the same, a scalar for one point and
an array for many, datasets that go straight to ``Plotter.add_mesh``. They answer through a
:class:`matrixtree.CellLocator` over the mesh (any data set, not only triangles), batched in C++.

With pyvista 0.48 or newer every pyvista data set also has them as methods of its
``matrixtree`` accessor (``mesh.matrixtree.sample(source)``), which keeps one locator per mesh;
the locator rebuilds by itself when the mesh changes. The functions build a locator per call
unless given one (``locator=``).

Examples
--------
>>> import numpy as np, pyvista as pv, matrixtree
>>> grid = pv.ImageData(dimensions=(6, 6, 6)).triangulate()
>>> grid.point_data["x"] = grid.points[:, 0]
>>> line = matrixtree.probe(grid, np.array([[0.5, 1.0, 2.0], [2.25, 3.0, 1.5], [9.0, 0.0, 0.0]]))
>>> line.point_data["x"].tolist(), line.point_data["vtkValidPointMask"].tolist()
([0.5, 2.25, 0.0], [1, 1, 0])
"""

from __future__ import annotations

import numpy as np

from matrixtree._cellarrays import cell_arrays
from matrixtree._util import points3

__all__ = ["find_cells_along_line", "find_cells_within_bounds", "find_closest_cell", "find_containing_cell",
           "multi_ray_trace", "probe", "ray_trace", "sample"]

#: Points (or rays) per batch of a call with ``progress_bar=True``: one progress step each.
CHUNK = 1 << 16
#: The point-data array of ``sample``/``probe`` results that marks the points found in a cell
#: (1) or not (0): vtkProbeFilter's name and type.
VALID_MASK = "vtkValidPointMask"


def _locator(mesh, locator):
    """``locator`` if it is a CellLocator over ``mesh``, a new one over ``mesh`` if None."""
    from matrixtree.locator import CellLocator

    if locator is None:
        return CellLocator(mesh)
    if not isinstance(locator, CellLocator) or locator.dataset is not mesh:
        raise ValueError("locator must be a matrixtree.CellLocator built over this mesh")
    return locator


def _chunks(n: int, progress_bar: bool, desc: str):
    """Slices of ``range(n)`` of CHUNK items; a tqdm bar over them with ``progress_bar``."""
    steps = [slice(i, min(i + CHUNK, n)) for i in range(0, n, CHUNK)] if progress_bar else [slice(0, n)]
    if not progress_bar:
        return steps
    try:
        from tqdm import tqdm
    except ImportError:
        raise ImportError("progress_bar=True needs tqdm (pip install tqdm)") from None
    return tqdm(steps, desc=desc, unit="batch")


def _one_or_many(point, name: str):
    """(points (n, 3), whether ``point`` was a single point of shape (3,))."""
    single = np.ndim(point) == 1
    return points3(point, name), single


# ---------------------------------------------------------------------------------------------
# Cell queries
# ---------------------------------------------------------------------------------------------
def find_containing_cell(mesh, point, *, locator=None, progress_bar: bool = False):
    """The index of the cell containing each point, -1 where none does (pyvista's
    ``DataSet.find_containing_cell``).

    Parameters
    ----------
    mesh : pyvista.DataSet or vtkDataSet
    point : array_like, shape (3,) or (n, 3)
    locator : matrixtree.CellLocator, optional
        A locator over ``mesh`` to reuse (default: a new one).
    progress_bar : bool, default: False
        Show a tqdm progress bar over batches of 65,536 points.

    Returns
    -------
    int or numpy.ndarray
        An int for a point of shape (3,); an int64 array of shape (n,) otherwise.

    Examples
    --------
    >>> import pyvista as pv, matrixtree
    >>> cube = pv.ImageData(dimensions=(3, 3, 3))          # 8 unit voxels
    >>> matrixtree.find_containing_cell(cube, [1.5, 0.5, 0.5])
    1
    >>> matrixtree.find_containing_cell(cube, [[0.5, 0.5, 1.5], [5.0, 5.0, 5.0]]).tolist()
    [4, -1]
    """
    p, single = _one_or_many(point, "point")
    loc = _locator(mesh, locator)
    ids = np.empty(len(p), np.int64)
    for s in _chunks(len(p), progress_bar, "find_containing_cell"):
        ids[s] = loc.locate(p[s])
    return int(ids[0]) if single else ids


def find_closest_cell(mesh, point, return_closest_point: bool = False, *, locator=None,
                      progress_bar: bool = False):
    """The index of the cell closest to each point (pyvista's ``DataSet.find_closest_cell``).

    Parameters
    ----------
    mesh : pyvista.DataSet or vtkDataSet
    point : array_like, shape (3,) or (n, 3)
    return_closest_point : bool, default: False
        Also return the closest point on that cell (not necessarily a mesh point).
    locator : matrixtree.CellLocator, optional
    progress_bar : bool, default: False

    Returns
    -------
    int or numpy.ndarray
        The cell (an int for a point of shape (3,)); -1 only for a mesh without cells.
    numpy.ndarray
        The closest points, shape (3,) or (n, 3), if ``return_closest_point``.

    Examples
    --------
    >>> import pyvista as pv, matrixtree
    >>> square = pv.Rectangle()                            # the unit square in z = 0, one cell
    >>> index, closest = matrixtree.find_closest_cell(square, [0.25, 0.25, 0.5], return_closest_point=True)
    >>> index, closest.tolist()
    (0, [0.25, 0.25, 0.0])
    """
    p, single = _one_or_many(point, "point")
    loc = _locator(mesh, locator)
    ids, closest = np.empty(len(p), np.int64), np.empty((len(p), 3))
    for s in _chunks(len(p), progress_bar, "find_closest_cell"):
        closest[s], ids[s], _ = loc.closest_points(p[s])
    if single:
        return (int(ids[0]), closest[0]) if return_closest_point else int(ids[0])
    return (ids, closest) if return_closest_point else ids


def find_cells_along_line(mesh, pointa, pointb, tolerance: float = 0.0, *, locator=None) -> np.ndarray:
    """The cells whose bounding boxes the segment from ``pointa`` to ``pointb`` crosses (grown
    by ``tolerance``), ascending (pyvista's ``DataSet.find_cells_along_line``).

    Examples
    --------
    >>> import pyvista as pv, matrixtree
    >>> cube = pv.ImageData(dimensions=(3, 3, 3))
    >>> matrixtree.find_cells_along_line(cube, [0.5, 0.5, -1.0], [0.5, 0.5, 3.0]).tolist()
    [0, 4]
    """
    return _locator(mesh, locator).cells_along_line(pointa, pointb, tolerance)


def find_cells_within_bounds(mesh, bounds, *, locator=None) -> np.ndarray:
    """The cells whose bounding boxes meet ``bounds`` = (xmin, xmax, ymin, ymax, zmin, zmax),
    ascending (pyvista's ``DataSet.find_cells_within_bounds``).

    Examples
    --------
    >>> import pyvista as pv, matrixtree
    >>> cube = pv.ImageData(dimensions=(3, 3, 3))
    >>> matrixtree.find_cells_within_bounds(cube, [0.2, 0.8, 0.2, 0.8, 1.2, 1.8]).tolist()
    [4]
    """
    return _locator(mesh, locator).cells_within_bounds(bounds)


# ---------------------------------------------------------------------------------------------
# Sampling: point and cell data at points
# ---------------------------------------------------------------------------------------------
def _numeric_arrays(source):
    """``source``'s cell offsets and connectivity, and its numeric point and cell arrays."""
    import pyvista as pv

    source = pv.wrap(source)
    _, offsets, conn, _ = cell_arrays(source)
    pd = {k: np.asarray(source.point_data[k]) for k in source.point_data.keys()}
    cd = {k: np.asarray(source.cell_data[k]) for k in source.cell_data.keys()}
    pd = {k: v for k, v in pd.items() if v.dtype.kind in "biuf"}
    cd = {k: v for k, v in cd.items() if v.dtype.kind in "biuf"}
    return offsets, conn, pd, cd


def _fill_located(out: dict, mask: np.ndarray, start: int, ids: np.ndarray, w: np.ndarray, arrays) -> None:
    """Rows ``start:start + len(ids)`` of ``out`` and ``mask`` from located points: ``ids`` the
    containing cells (-1: none), ``w`` their interpolation weights (CellLocator.locate)."""
    offsets, conn, pd, cd = arrays
    found = np.flatnonzero(ids >= 0)
    cells = ids[found]
    mask[start + found] = 1
    if not len(found):
        return
    size = offsets[cells + 1] - offsets[cells]
    cols = np.arange(w.shape[1])
    used = cols[None, :] < size[:, None]
    where = np.where(used, offsets[cells][:, None] + cols[None, :], 0)
    pids = conn[where]
    wf = np.where(used, w[found], 0.0)
    rows = start + found
    for k, v in pd.items():
        vals = v[pids].astype(np.float64)                  # (m, k, ...)
        vals[~used] = 0.0
        acc = np.einsum("mk,mk...->m...", wf, vals)
        out[k][rows] = _to_type(acc, v.dtype)
    for k, v in cd.items():
        out[k][rows] = v[cells]


def _empty_result(n: int, arrays):
    _, _, pd, cd = arrays
    return {k: np.zeros((n,) + v.shape[1:], v.dtype) for k, v in {**pd, **cd}.items()}, np.zeros(n, np.int8)


def _interpolate(source, loc, points: np.ndarray, progress_bar: bool, desc: str):
    """{name: array} of ``source``'s point arrays interpolated at ``points`` (the containing
    cell's weights) and its cell arrays taken from the containing cell, and the valid mask.

    As vtkProbeFilter: a point in no cell gets 0 in every array and 0 in the mask; integer
    arrays are rounded half away from zero and clamped to their type.
    """
    arrays = _numeric_arrays(source)
    out, mask = _empty_result(len(points), arrays)
    for s in _chunks(len(points), progress_bar, desc):
        ids, w = loc.locate(points[s], return_weights=True)
        _fill_located(out, mask, s.start, ids, w, arrays)
    return out, mask


def _interpolate_located(source, cell_ids: np.ndarray, weights: np.ndarray):
    """:func:`_interpolate`'s result for points already located: ``cell_ids`` and ``weights``
    as ``CellLocator.locate(points, return_weights=True)`` gives them (no second location)."""
    arrays = _numeric_arrays(source)
    out, mask = _empty_result(len(cell_ids), arrays)
    _fill_located(out, mask, 0, np.asarray(cell_ids), np.asarray(weights), arrays)
    return out, mask


def _to_type(values: np.ndarray, dtype: np.dtype) -> np.ndarray:
    """Interpolated doubles as ``dtype``: integers rounded half away from zero and clamped to
    the type's range (VTK's RoundDoubleToIntegralIfNecessary), floats cast."""
    if dtype.kind == "f":
        return values.astype(dtype)
    info = np.iinfo(dtype) if dtype.kind in "iu" else np.iinfo(np.uint8)
    r = np.where(values >= 0, np.floor(values + 0.5), np.ceil(values - 0.5))
    return np.clip(r, info.min, info.max).astype(dtype)


def _as_points_dataset(points):
    import pyvista as pv

    if isinstance(points, pv.DataSet):
        return points.copy(deep=False)
    if hasattr(points, "GetNumberOfPoints"):
        return pv.wrap(points).copy(deep=False)
    return pv.PolyData(points3(points, "points").copy())


def _sample_into(out, source, loc, pass_point_data: bool, pass_cell_data: bool, progress_bar: bool, desc: str):
    """``out`` (a data set of its own, shallow copy) with its point or cell arrays dropped unless
    passed, then ``source``'s arrays at its points and the valid mask as point data."""
    if not pass_point_data:
        out.point_data.clear()
    if not pass_cell_data:
        out.cell_data.clear()
    arrays, mask = _interpolate(source, loc, np.asarray(out.points, dtype=np.float64), progress_bar, desc)
    for k, v in arrays.items():
        out.point_data[k] = v
    out.point_data[VALID_MASK] = mask
    return out


def probe(mesh, points, *, pass_cell_data: bool = True, pass_point_data: bool = True, locator=None,
          progress_bar: bool = False):
    """The mesh's point and cell data at other points (pyvista's ``DataSetFilters.probe``).

    Parameters
    ----------
    mesh : pyvista.DataSet or vtkDataSet
        The source: any cells (VTK module: every cell type; engine extension: the linear cells and
        the quadratic tetra, hexahedron, wedge, pyramid and triquadratic hexahedron).
    points : pyvista.DataSet or array_like, shape (n, 3)
        Where to sample; an array becomes a point cloud (``pyvista.PolyData``).
    pass_cell_data, pass_point_data : bool, default: True
        Keep the arrays ``points`` (a data set) already has.
    locator : matrixtree.CellLocator, optional
    progress_bar : bool, default: False

    Returns
    -------
    pyvista.DataSet
        ``points``'s geometry with, as point data, every numeric point array of ``mesh``
        interpolated in the containing cell (the cell's interpolation weights: exact for fields
        linear in the cell), every numeric cell array of ``mesh`` taken from the containing cell,
        and ``vtkValidPointMask`` (int8: 1 found, 0 in no cell, where every array is 0).

    Examples
    --------
    >>> import numpy as np, pyvista as pv, matrixtree
    >>> grid = pv.ImageData(dimensions=(4, 4, 4))
    >>> grid.point_data["f"] = grid.points @ [1.0, 2.0, 3.0]
    >>> grid.cell_data["id"] = np.arange(grid.n_cells)
    >>> out = matrixtree.probe(grid, [[0.5, 0.5, 0.5], [2.5, 1.5, 0.25]])
    >>> out.point_data["f"].tolist(), out.point_data["id"].tolist()
    ([3.0, 6.25], [0, 5])
    """
    loc = _locator(mesh, locator)
    return _sample_into(_as_points_dataset(points), mesh, loc, pass_point_data, pass_cell_data, progress_bar, "probe")


def sample(mesh, target, *, pass_cell_data: bool = True, pass_point_data: bool = True,
           pass_field_data: bool = True, locator=None, progress_bar: bool = False):
    """``target``'s point and cell data sampled at the points of ``mesh`` (pyvista's
    ``DataSetFilters.sample``: ``mesh.sample(target)``).

    Parameters
    ----------
    mesh : pyvista.DataSet
        Where to sample: the result has its geometry.
    target : pyvista.DataSet or vtkDataSet
        The source of the data (VTK module: every cell type; engine extension: as :func:`probe`).
    pass_cell_data, pass_point_data, pass_field_data : bool, default: True
        Keep ``mesh``'s own cell, point and field arrays.
    locator : matrixtree.CellLocator, optional
        A locator over ``target`` to reuse.
    progress_bar : bool, default: False

    Returns
    -------
    pyvista.DataSet
        A copy of ``mesh`` with ``target``'s arrays as point data and ``vtkValidPointMask``, as
        :func:`probe` describes.

    Examples
    --------
    >>> import pyvista as pv, matrixtree
    >>> source = pv.ImageData(dimensions=(5, 5, 5)).triangulate()
    >>> source.point_data["z"] = source.points[:, 2]
    >>> plane = pv.Plane(center=(2, 2, 1.25), i_size=3, j_size=3, i_resolution=3, j_resolution=3)
    >>> out = matrixtree.sample(plane, source)
    >>> bool(abs(out.point_data["z"] - 1.25).max() < 1e-6), int(out.point_data["vtkValidPointMask"].sum())
    (True, 16)
    """
    import pyvista as pv

    loc = _locator(target, locator)
    out = pv.wrap(mesh).copy(deep=False)
    if not pass_field_data:
        out.field_data.clear()
    return _sample_into(out, target, loc, pass_point_data, pass_cell_data, progress_bar, "sample")


# ---------------------------------------------------------------------------------------------
# Rays
# ---------------------------------------------------------------------------------------------
def ray_trace(mesh, origin, end_point, first_point: bool = False, *, locator=None):
    """Where the segment from ``origin`` to ``end_point`` meets the mesh's cells (pyvista's
    ``PolyDataFilters.ray_trace``, for any data set).

    Parameters
    ----------
    mesh : pyvista.DataSet or vtkDataSet
    origin, end_point : sequence of 3 float
    first_point : bool, default: False
        Only the first intersection.
    locator : matrixtree.CellLocator, optional

    Returns
    -------
    points : numpy.ndarray
        The intersections along the segment, shape (k, 3); with ``first_point`` the first one,
        shape (3,). Empty (shape (0, 3) / (0,)) if the segment meets nothing.
    cells : numpy.ndarray or int
        The cell of each intersection (each cell once, at its first meeting); with
        ``first_point`` an int.

    Examples
    --------
    >>> import pyvista as pv, matrixtree
    >>> sphere = pv.Sphere()
    >>> point, cell = matrixtree.ray_trace(sphere, [0, 0, 0], [1, 0, 0], first_point=True)
    >>> f"{point[0]:.3f} {point[1]:.3f} {point[2]:.3f}"
    '0.499 0.000 0.000'
    >>> points, cells = matrixtree.ray_trace(sphere, [-1, 0.01, 0], [1, 0.01, 0])
    >>> points.shape, cells.shape
    ((2, 3), (2,))
    """
    loc = _locator(mesh, locator)
    a, b = points3(origin, "origin"), points3(end_point, "end_point")
    if first_point:
        t, ids, x = loc.trace(a, ends=b)
        if ids[0] < 0:
            return np.zeros((0, 3)), np.zeros(0, np.int64)
        return x[0], int(ids[0])
    _, _, ids, x = loc.trace_all(a, ends=b)
    return x, ids


def multi_ray_trace(mesh, origins, directions, first_point: bool = False, *, locator=None,
                    progress_bar: bool = False):
    """Intersections of many rays with the mesh's cells (pyvista's
    ``PolyDataFilters.multi_ray_trace``, built in: no trimesh or embree, any data set).

    Parameters
    ----------
    mesh : pyvista.DataSet or vtkDataSet
    origins, directions : array_like, shape (n, 3)
        Each ray starts at its origin and runs along its direction, without end.
    first_point : bool, default: False
        Only each ray's first intersection.
    locator : matrixtree.CellLocator, optional
    progress_bar : bool, default: False

    Returns
    -------
    points : numpy.ndarray, shape (k, 3)
        The intersections, ray by ray, each ray's along it.
    rays : numpy.ndarray, shape (k,)
        The ray of each intersection.
    cells : numpy.ndarray, shape (k,)
        The cell of each intersection.

    Examples
    --------
    >>> import pyvista as pv, matrixtree
    >>> sphere = pv.Sphere()
    >>> points, rays, cells = matrixtree.multi_ray_trace(sphere, [[0, 0, 0]] * 3, [[1, 0, 0], [0, 1, 0], [0, 0, 1]],
    ...                                                  first_point=True)
    >>> rays.tolist(), bool(abs(abs(points).max(axis=1) - 0.5).max() < 1e-2)
    ([0, 1, 2], True)
    """
    loc = _locator(mesh, locator)
    o, d = points3(origins, "origins"), points3(directions, "directions")
    if o.shape != d.shape:
        raise ValueError(f"origins {o.shape} and directions {d.shape} must have the same shape")
    # Each ray as the segment to where it has left the mesh's bounding sphere.
    b = np.array(mesh.GetBounds(), dtype=np.float64).reshape(3, 2)
    center, radius = b.mean(axis=1), 0.5 * np.linalg.norm(b[:, 1] - b[:, 0])
    with np.errstate(divide="ignore", invalid="ignore"):
        reach = (np.linalg.norm(o - center, axis=1) + radius) * 1.01 / np.linalg.norm(d, axis=1)
    reach = np.where(np.isfinite(reach), reach, 0.0)
    ends = o + d * reach[:, None]
    points, rays, cells = [], [], []
    for s in _chunks(len(o), progress_bar, "multi_ray_trace"):
        first = s.start or 0
        if first_point:
            _, ids, x = loc.trace(o[s], ends=ends[s])
            hit = np.flatnonzero(ids >= 0)
            points.append(x[hit])
            rays.append(first + hit)
            cells.append(ids[hit])
        else:
            offsets, _, ids, x = loc.trace_all(o[s], ends=ends[s])
            points.append(x)
            rays.append(first + np.repeat(np.arange(len(offsets) - 1), np.diff(offsets)))
            cells.append(ids)
    if not points:
        return np.zeros((0, 3)), np.zeros(0, np.int64), np.zeros(0, np.int64)
    return np.concatenate(points).reshape(-1, 3), np.concatenate(rays).astype(np.int64), np.concatenate(cells)


# ---------------------------------------------------------------------------------------------
# The pyvista accessor: mesh.matrixtree.<filter>(...)
# ---------------------------------------------------------------------------------------------
class MatrixTreeAccessor:
    """The filters of :mod:`matrixtree.filters` as methods of a mesh, with one cell locator per
    mesh, built on the first query (``mesh.matrixtree.locator``) and rebuilt by itself when the
    mesh changes. Registered as ``matrixtree`` on every ``pyvista.DataSet`` where pyvista has
    ``register_dataset_accessor`` (0.48 and newer).

    Examples
    --------
    >>> import pyvista as pv, matrixtree
    >>> cube = pv.ImageData(dimensions=(3, 3, 3))
    >>> acc = matrixtree.filters.MatrixTreeAccessor(cube)     # what cube.matrixtree is
    >>> acc.find_containing_cell([1.5, 1.5, 1.5]), acc.locator is acc.locator
    (7, True)
    """

    def __init__(self, mesh):
        self._mesh = mesh
        self._locator = None

    @property
    def locator(self):
        """The mesh's :class:`matrixtree.CellLocator` (built on first use)."""
        from matrixtree.locator import CellLocator

        if self._locator is None:
            self._locator = CellLocator(self._mesh)
        return self._locator

    def find_containing_cell(self, point, progress_bar: bool = False):
        """See :func:`matrixtree.filters.find_containing_cell`."""
        return find_containing_cell(self._mesh, point, locator=self.locator, progress_bar=progress_bar)

    def find_closest_cell(self, point, return_closest_point: bool = False, progress_bar: bool = False):
        """See :func:`matrixtree.filters.find_closest_cell`."""
        return find_closest_cell(self._mesh, point, return_closest_point, locator=self.locator,
                                 progress_bar=progress_bar)

    def find_cells_along_line(self, pointa, pointb, tolerance: float = 0.0):
        """See :func:`matrixtree.filters.find_cells_along_line`."""
        return find_cells_along_line(self._mesh, pointa, pointb, tolerance, locator=self.locator)

    def find_cells_within_bounds(self, bounds):
        """See :func:`matrixtree.filters.find_cells_within_bounds`."""
        return find_cells_within_bounds(self._mesh, bounds, locator=self.locator)

    def probe(self, points, pass_cell_data: bool = True, pass_point_data: bool = True, progress_bar: bool = False):
        """See :func:`matrixtree.filters.probe`."""
        return probe(self._mesh, points, pass_cell_data=pass_cell_data, pass_point_data=pass_point_data,
                     locator=self.locator, progress_bar=progress_bar)

    def sample(self, target, pass_cell_data: bool = True, pass_point_data: bool = True,
               pass_field_data: bool = True, progress_bar: bool = False):
        """See :func:`matrixtree.filters.sample` (``target``'s own accessor keeps its locator)."""
        loc = target.matrixtree.locator if hasattr(target, "matrixtree") else None
        return sample(self._mesh, target, pass_cell_data=pass_cell_data, pass_point_data=pass_point_data,
                      pass_field_data=pass_field_data, locator=loc, progress_bar=progress_bar)

    def ray_trace(self, origin, end_point, first_point: bool = False):
        """See :func:`matrixtree.filters.ray_trace`."""
        return ray_trace(self._mesh, origin, end_point, first_point, locator=self.locator)

    def multi_ray_trace(self, origins, directions, first_point: bool = False, progress_bar: bool = False):
        """See :func:`matrixtree.filters.multi_ray_trace`."""
        return multi_ray_trace(self._mesh, origins, directions, first_point, locator=self.locator,
                               progress_bar=progress_bar)


def _register_accessor() -> bool:
    """Register :class:`MatrixTreeAccessor` as ``matrixtree`` on pyvista.DataSet (pyvista >= 0.48);
    False where pyvista has no accessors."""
    import pyvista as pv

    register = getattr(pv, "register_dataset_accessor", None)
    if register is None:
        return False
    if not any(r.name == "matrixtree" for r in pv.registered_accessors()):
        register("matrixtree", pv.DataSet)(MatrixTreeAccessor)
    return True


HAS_ACCESSOR = _register_accessor()
"""Whether pyvista data sets have the ``mesh.matrixtree`` accessor (pyvista 0.48 and newer)."""

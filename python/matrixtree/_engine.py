"""The package's compute calls answered by the engine extension ``matrixtree_engine``.

Where the VTK module ``matrixtree_vtk`` does not import (pip's environment: ``pip install .``
builds the engine extension only), ``matrixtree.CellLocator``, ``MatrixTree``, ``render``,
``tree_mesh``, ``render_volume``, ``cached_memory`` and ``release_cached_memory`` are the names
defined here (see ``matrixtree._backend``). They take the same arguments and return the same
things as the VTK-module versions in ``core.py``, ``locator.py`` and ``volume.py``: numpy arrays,
pyvista meshes, and the same answers (tests/python/test_paths.py compares both where
both are built). The engine builds the same trees with the same automatic heights and asks its
own VTK-rule cell tests (engine/vtk91) where the VTK module asks VTK's cells.

What the engine extension does not have: OpenCL (``backend="opencl"`` raises RuntimeError
saying so) and cells other than VTK's linear types (quadratic and polyhedral cells raise
ValueError naming the first such cell).

Not public API: use the names ``matrixtree`` exports.
"""

from __future__ import annotations

import math
import time

import numpy as np
from vtkmodules.util.numpy_support import vtk_to_numpy

from matrixtree import _checks, _meshstate, _quality
from matrixtree._cellarrays import cell_arrays, points_of, surface_arrays
from matrixtree._backend import engine
from matrixtree._util import RAY_TREES, bounds6, check_backend, points3, segments, tree_type

_TREE_NAMES = {0: "octree", 1: "kdtree"}


def _engine_tree(tree: str) -> str:
    """``tree`` if the engine extension builds it ("octree", "kdtree"); ValueError otherwise,
    naming the VTK module for the split-plane and hybrid trees (docs/trees.md)."""
    tree_type(tree, RAY_TREES)  # ValueError naming every tree
    if tree not in _TREE_NAMES.values():
        raise ValueError(f"tree={tree!r} needs the VTK module (matrixtree_vtk); the engine extension "
                         f"builds {sorted(_TREE_NAMES.values())}")
    return tree


def _no_opencl(what: str) -> RuntimeError:
    return RuntimeError(f"{what}: backend='opencl' needs the VTK module (matrixtree_vtk, built by "
                        "scripts/setup.sh); the engine extension that `pip install .` builds runs on the CPU "
                        "[use backend='cpu']")


def adopt_docs(documented, engine_side) -> None:
    """Give ``engine_side`` (a function or class of this module) the docstrings of its VTK-path
    counterpart, so that both paths have one documentation: the function's or class's own, and
    each method's or property's that the engine class has without one."""
    engine_side.__doc__ = documented.__doc__
    if not isinstance(documented, type):
        return
    for name, member in vars(engine_side).items():
        source = vars(documented).get(name)
        doc = getattr(source, "__doc__", None)
        if doc and not getattr(member, "__doc__", None):
            target = member.fget if isinstance(member, property) else member
            target.__doc__ = doc


def cached_memory() -> int:
    """Bytes of freed tree arrays the process keeps for the next build (see
    ``matrixtree.locator.cached_memory``)."""
    return int(engine().cached_memory())


def release_cached_memory() -> int:
    """Hands every kept mapping back to the system; returns its bytes."""
    return int(engine().release_cached_memory())


# ---------------------------------------------------------------------------------------------
# Cell location
# ---------------------------------------------------------------------------------------------
class CellLocator(_meshstate.RebuildOnChange):
    """Point location, segments and closest points on the cells of a mesh: the engine's
    ``mtree::CellLocator``. The documentation is ``matrixtree.locator.CellLocator``'s; the
    differences are the ones of this module's docstring.

    Examples
    --------
    >>> import numpy as np, pyvista as pv
    >>> grid = pv.ImageData(dimensions=(5, 5, 5)).triangulate()
    >>> ids = CellLocator(grid).locate([[0.5, 0.5, 0.5], [100.0, 0.0, 0.0]])
    >>> bool(ids[0] >= 0), int(ids[1])
    (True, -1)
    """

    def __init__(self, dataset, tree: str = "octree", height: int = 0, threads: int = 0,
                 backend: str = "cpu", device: str | None = None):
        from vtkmodules.vtkCommonDataModel import vtkDataSet

        if not isinstance(dataset, vtkDataSet):
            raise TypeError(f"dataset must be a vtkDataSet (or a pyvista mesh), got {type(dataset).__name__}")
        self._tree = _TREE_NAMES[tree_type(tree)]
        self._height = _checks.integer(height, "height", 0, 63, "0 = automatic")
        self._threads = _checks.threads(threads)
        if check_backend(backend) == "opencl":
            raise _no_opencl("CellLocator")
        if dataset.GetNumberOfCells() == 0:
            raise ValueError("dataset has no cells")
        self.dataset = dataset
        self.backend = backend
        self.builds = 0
        self._build()

    def _build_tree(self) -> None:
        # As the VTK module's locator: a failed build is a RuntimeError with the engine's reason; a
        # cell type the engine's cell mirror lacks is named, with the VTK module that takes it.
        try:
            self._loc = engine().CellLocator(*cell_arrays(self.dataset), tree=self._tree, height=self._height,
                                             threads=self._threads)
        except ValueError as e:
            hint = " (the VTK module of scripts/setup.sh takes every cell type)" if "cell type" in str(e) else ""
            raise RuntimeError(f"{e}{hint}") from None

    def locate(self, points, *, return_pcoords: bool = False, return_weights: bool = False):
        p = points3(points, "points")
        self._sync()
        ids, pc, w = self._loc.find_cells(p, 0.0, return_pcoords, return_weights)
        out = [ids] + ([pc] if return_pcoords else []) + ([w] if return_weights else [])
        return out[0] if len(out) == 1 else tuple(out)

    def trace(self, origins, directions=None, *, ends=None, length: float = 1.0, tolerance: float = 0.0):
        o, e = segments(origins, directions, ends, length)
        tolerance = _checks.real(tolerance, "tolerance", 0.0)
        self._sync()
        return self._loc.first_hits(o, e, tolerance)

    def trace_all(self, origins, directions=None, *, ends=None, length: float = 1.0):
        o, e = segments(origins, directions, ends, length)
        self._sync()
        return self._loc.all_hits(o, e, 0.0)

    def closest_points(self, points):
        p = points3(points, "points")
        self._sync()
        return self._loc.closest_points(p)

    def cells_within_bounds(self, bounds) -> np.ndarray:
        b = bounds6(bounds)
        self._sync()
        return self._loc.cells_within_bounds(b)

    def cells_along_line(self, pointa, pointb, tolerance: float = 0.0) -> np.ndarray:
        a, b = points3(pointa, "pointa")[0], points3(pointb, "pointb")[0]
        tolerance = _checks.real(tolerance, "tolerance", 0.0)
        self._sync()
        return self._loc.cells_along_segment(a.tolist(), b.tolist(), tolerance)

    def __repr__(self) -> str:
        st = self._loc.stats()
        return (f"CellLocator({self.dataset.GetClassName()}, {self.dataset.GetNumberOfCells()} cells, {self._tree}, "
                f"height {st['height']}, {st['bytes']} bytes, backend {self.backend})")


# ---------------------------------------------------------------------------------------------
# Surfaces: rays and renders
# ---------------------------------------------------------------------------------------------
def _surface_tree(pd, tree: str, height: int, block_size: int, exact: bool, leaf_scale: float, threads: int):
    """engine.SurfaceTree over a vtkPolyData, or engine.SahTree for ``tree="sah"``; a bad mesh
    (non-finite coordinates, indices out of range) is a RuntimeError with the engine's reason,
    as the VTK module's failed build is."""
    arrays = surface_arrays(pd)
    try:
        if tree == "sah":
            return engine().SahTree(*arrays, threads=threads)
        return engine().SurfaceTree(*arrays, tree=tree, height=height, block_size=block_size, exact=exact,
                                    leaf_scale=leaf_scale, threads=threads)
    except ValueError as e:
        raise RuntimeError(f"building the matrix tree failed: {e}") from None


class MatrixTree:
    """A matrix octree or regular kd-tree over the triangles of a surface mesh: the engine's
    ``MatrixTree`` and §5.1 builder. The documentation is ``matrixtree.core.MatrixTree``'s.

    Examples
    --------
    >>> import numpy as np, pyvista as pv
    >>> tree = MatrixTree(pv.Sphere(), tree="kdtree")
    >>> t, cell = tree.intersect([[0.0, 0.0, 2.0]], [[0.0, 0.0, -1.0]])
    >>> round(float(t[0]), 3), bool(cell[0] >= 0)
    (1.5, True)
    """

    def __init__(self, mesh, tree: str = "octree", height: int = 0, block_size: int = 8,
                 exact: bool = True, leaf_scale: float | None = None, threads: int = 0,
                 backend: str = "cpu", device: str | None = None):
        from matrixtree.core import _as_polydata, _check_tree_settings

        self.mesh = _as_polydata(mesh)
        if check_backend(backend) == "opencl":
            raise _no_opencl("MatrixTree")
        _, height, leaf_scale, threads = _check_tree_settings(tree, height, block_size, leaf_scale, threads)
        self._settings = dict(tree=_engine_tree(tree), height=height, block_size=int(block_size),
                              exact=bool(exact), leaf_scale=2.0 if leaf_scale is None else leaf_scale,
                              threads=threads)
        self._counters = {"node_visits": 0, "triangle_tests": 0}
        self.build()

    def build(self) -> "MatrixTree":
        """(Re)build the tree now. Queries rebuild by themselves when the mesh changed. Returns self."""
        t0 = time.perf_counter()
        state = _meshstate.fingerprint(self.mesh)
        self._tree = _surface_tree(self.mesh, **self._settings)
        self._state = state
        self._conversion_ms = 1e3 * (time.perf_counter() - t0) - self._tree.stats()["build_ms"]
        return self

    def _sync(self) -> None:
        if _meshstate.fingerprint(self.mesh) != self._state:
            self.build()

    def stats(self) -> dict:
        s = self._tree.stats()
        h = s["height"]
        dims = [list(d) for d in s["level_dims"]]
        return {"tree": s["tree"], "height": h, "triangles": s["triangles"], "leaves": s["leaves"],
                "references": s["references"], "bytes": s["bytes"] + s["leaf_triangles_bytes"],
                "leaf_triangle_bytes": s["leaf_triangles_bytes"], "level_bytes": list(s["level_bytes"]),
                "level_blocks": list(s["level_blocks"]), "leaf_dims": dims[h] if dims else [0, 0, 0],
                "level_dims": dims, "root_bounds": list(s["root_bounds"]),
                "median_triangle_extent": s["median_extent"], "phases_ms": dict(s["phases_ms"]),
                "build_ms": s["build_ms"], "conversion_ms": max(self._conversion_ms, 0.0), "backend": "cpu",
                "device": ""}

    def find_leaves(self, points) -> np.ndarray:
        p = points3(points, "points")
        self._sync()
        return self._tree.find_leaves(p)

    def intersect(self, origins, directions, t_max: float = np.inf):
        from matrixtree.core import _rays

        o, d, t_max = _rays(origins, directions, t_max)
        self._sync()
        t, cells, visits, tests = self._tree.intersect(o, d, t_max)
        self._counters = {"node_visits": int(visits), "triangle_tests": int(tests)}
        return t, cells

    @property
    def last_query_counters(self) -> dict:
        return dict(self._counters)


class SurfaceCaster:
    """What ``render(caster=...)`` reuses on the engine path (the VTK path's
    vtkMatrixTreeRayCaster): the last tree, rebuilt only when the mesh or a tree setting changed."""

    def __init__(self):
        self.mesh = None
        self._key = self._state = self._tree = None
        self._build_ms = 0.0

    def tree_for(self, pd, key: tuple):
        """The tree of ``key`` (kind, height, leaf_scale, threads) over ``pd`` and whether it was
        (re)built now."""
        state = _meshstate.fingerprint(pd)
        if self._tree is not None and self.mesh is pd and self._key == key and self._state == state:
            return self._tree, False
        kind, height, leaf_scale, threads = key
        self._tree = _surface_tree(pd, kind, height, 8, True, leaf_scale, threads)
        self.mesh, self._key, self._state = pd, key, state
        self._build_ms = self._tree.stats()["build_ms"]
        return self._tree, True


def auto_camera(points: np.ndarray, view_angle: float = 30.0):
    """vtkMatrixTreeRayCaster's automatic camera, in its arithmetic: the points' bounding box seen
    from direction (0.35, 0.45, 1) at 1.05 times the distance where its bounding sphere fills the
    view angle, view up +y. (eye, target, up); VTK's default camera for no points."""
    if len(points) == 0:
        return (0.0, 0.0, 1.0), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0)
    lo, hi = points.min(axis=0), points.max(axis=0)
    c = [(float(lo[a]) + float(hi[a])) * 0.5 for a in range(3)]
    e = [float(hi[a]) - float(lo[a]) for a in range(3)]
    r = 0.5 * math.sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2])
    dist = r / math.sin(0.5 * view_angle * math.pi / 180.0) * 1.05
    d = (0.35, 0.45, 1.0)
    inv = 1.0 / math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
    eye = tuple(c[a] + d[a] * inv * dist for a in range(3))
    return eye, tuple(c), (0.0, 1.0, 0.0)


def render(mesh, size=(800, 800), tree: str = "octree", height: int = 0, camera=None,
           shadows: bool = True, threads: int = 0, caster: SurfaceCaster | None = None,
           backend: str = "cpu", traversal: str = "stack", triangle_test: str = "moller-trumbore",
           leaf_scale: float | None = None, counters: bool = False, quality: str | None = None) -> dict:
    """Ray cast a mesh: ``matrixtree.core.render`` on the engine (same arguments and results;
    ``caster`` is a :class:`SurfaceCaster`)."""
    from matrixtree.core import _as_polydata, _check_render_settings

    triangle_test = _quality.triangle_test(quality, triangle_test)
    pd = _as_polydata(mesh)
    w, h, camera, height, threads, leaf_scale = _check_render_settings(size, traversal, triangle_test, camera, tree,
                                                                       backend, height, threads, leaf_scale)
    if check_backend(backend) == "opencl":
        raise _no_opencl("render")
    kind = "sah" if tree == "sah" else _engine_tree(tree)
    rc = caster if caster is not None else SurfaceCaster()
    if not isinstance(rc, SurfaceCaster):
        raise TypeError(f"caster must be the 'caster' of an earlier render, got {type(rc).__name__}")
    key = ("sah", 0, 0.0, int(threads)) if kind == "sah" else \
        (kind, int(height), 2.0 if leaf_scale is None else float(leaf_scale), int(threads))
    st, rebuilt = rc.tree_for(pd, key)
    if camera is None:
        eye, target, up = auto_camera(points_of(pd))
        angle = 30.0
    else:
        eye, target, up = (tuple(float(v) for v in camera[i]) for i in range(3))
        angle = 30.0 if camera[3] is None else camera[3]
    view = dict(eye=list(eye), target=list(target), up=list(up), view_angle=angle, shadows=bool(shadows),
                test=triangle_test, counters=bool(counters))
    if kind == "sah":
        r = st.render(w, h, traversal=traversal, **view)
    else:
        r = st.render(w, h, **view)
    rays = r["primary_rays"] + r["shadow_rays"]
    return {
        "rgb": np.ascontiguousarray(r["rgb"][::-1]),
        "node_visits": np.ascontiguousarray(r["node_visits"][::-1]) if counters else None,
        "triangle_tests": np.ascontiguousarray(r["triangle_tests"][::-1]) if counters else None,
        "depth": np.ascontiguousarray(r["depth"][::-1]),
        "build_ms": rc._build_ms,
        "render_ms": r["render_ms"],
        "rebuilt": rebuilt,
        "rays": rays,
        "hits": r["hits"],
        "node_visits_per_ray": r["total_node_visits"] / max(rays, 1) if counters else None,
        "triangle_tests_per_ray": r["total_triangle_tests"] / max(rays, 1) if counters else None,
        "caster": rc,
    }


def tree_mesh(mesh, tree: str = "octree", height: int = 0, levels=None, exact_overlap: bool = False):
    """The cell locator's matrix tree over a mesh as voxels: ``matrixtree.core.tree_mesh`` on the
    engine (same arguments and result)."""
    import pyvista as pv

    from matrixtree.core import _level_range, _tree_mesh_input

    tree = _engine_tree(tree)
    mesh = _tree_mesh_input(mesh)
    lo, hi, leaves_only = _level_range(levels)
    loc = engine().CellLocator(*cell_arrays(mesh), tree=tree, height=int(height),
                               exact_overlap=bool(exact_overlap))
    h = loc.stats()["height"]
    nodes = loc.nodes(h, h) if leaves_only else loc.nodes(lo, hi)
    n = len(nodes["level"])
    corner = np.array([[k & 1, (k >> 1) & 1, (k >> 2) & 1] for k in range(8)], dtype=bool)
    pts = np.where(corner[None], nodes["hi"][:, None, :], nodes["lo"][:, None, :]).reshape(-1, 3)
    cells = np.hstack([np.full((n, 1), 8), np.arange(8 * n).reshape(n, 8)]).ravel()
    out = pv.UnstructuredGrid(cells, np.full(n, pv.CellType.VOXEL, np.uint8), pts)
    out.cell_data["level"] = nodes["level"].astype(np.int32)
    out.cell_data["occupancy"] = nodes["occupancy"]
    out.cell_data["cell_count"] = nodes["count"]
    out.field_data["tree_height"] = np.array([h], np.int32)
    return out


# ---------------------------------------------------------------------------------------------
# Volumes
# ---------------------------------------------------------------------------------------------
#: Entries of the transfer table (vtkMatrixTreeVolumeRayCaster's TableSize).
TABLE_SIZE = 4096


def transfer_table(scalars: np.ndarray, color, opacity):
    """(table (n, 4) float32, lo, hi): colour and opacity sampled over the scalars' finite range
    (of their float32 values; hi = lo + 1 for a constant volume), as the VTK caster samples them."""
    v = np.asarray(scalars).astype(np.float32).astype(np.float64)
    v = v[np.isfinite(v)]
    if v.size == 0:
        raise ValueError("The input scalars hold no finite value.")
    lo, hi = float(v.min()), float(v.max())
    if hi == lo:
        hi = lo + 1.0
    rgb = np.ones(3 * TABLE_SIZE, np.float32)
    alpha = np.zeros(TABLE_SIZE, np.float32)
    color.GetTable(lo, hi, TABLE_SIZE, rgb)
    opacity.GetTable(lo, hi, TABLE_SIZE, alpha)
    return np.ascontiguousarray(np.column_stack([rgb.reshape(-1, 3), alpha]), np.float32), lo, hi


class VolumeRenderer:
    """``matrixtree.volume.VolumeRenderer`` on the engine (same arguments and results): the engine
    volume is kept across frames and built again when the scalars or a transfer function changed
    (their modification times), or the colour one (the engine's table holds both)."""

    def __init__(self, volume, *, color=None, opacity=None, spacing=None, origin=None,
                 opacity_unit_distance: float | None = None, threads: int = 0, backend: str = "cpu",
                 device: str | None = None):
        from matrixtree.volume import _prepare_volume

        if check_backend(backend) == "opencl":
            raise _no_opencl("render_volume")
        v = _prepare_volume(volume, color, opacity, spacing, origin, opacity_unit_distance, threads)
        self.image, self.color, self.opacity = v.image, v.color, v.opacity
        self.backend = backend
        self._unit, self._threads = float(v.opacity_unit_distance), int(v.threads)
        self._vol, self._key = None, None

    def _volume(self) -> bool:
        """Builds the engine volume if its inputs changed since the last build; True if it did."""
        s = self.image.GetPointData().GetScalars()
        key = (self.image.GetMTime(), s.GetMTime(), id(self.color), self.color.GetMTime(), id(self.opacity),
               self.opacity.GetMTime())  # a new scalar array modifies the image
        if key == self._key:
            return False
        scalars = np.ascontiguousarray(vtk_to_numpy(s))
        table, lo, hi = transfer_table(scalars, self.color, self.opacity)
        self._vol = engine().Volume(scalars, list(self.image.GetDimensions()), table, lo, hi,
                                    unit_distance=self._unit, sparse=True, threads=self._threads)
        self._key = key
        return True

    def render(self, *, camera=None, size=(512, 512), sample_distance: float | None = None,
               image_sample_distance: float = 1.0, early_termination: float = 0.99, double_precision: bool = False,
               shade: bool = False, return_stats: bool = False, quality: str | None = None):
        from matrixtree.volume import _prepare_frame

        f = _prepare_frame(self.image, size, camera, sample_distance, image_sample_distance, early_termination,
                           quality)
        rebuilt = self._volume()
        cam, image = f.camera, self.image
        # The first point's position: the origin moved by the extent's start (vtkImageData places
        # point (i, j, k) of an extent starting at e at origin + (e + (i, j, k)) * spacing).
        ext, sp = image.GetExtent(), image.GetSpacing()
        first = [image.GetOrigin()[a] + ext[2 * a] * sp[a] for a in range(3)]
        rgba, st = self._vol.render(f.width, f.height, position=list(cam.GetPosition()),
                                    focal_point=list(cam.GetFocalPoint()), view_up=list(cam.GetViewUp()),
                                    view_angle=cam.GetViewAngle(), parallel=bool(cam.GetParallelProjection()),
                                    parallel_scale=cam.GetParallelScale(), origin=first, spacing=list(sp),
                                    sample_distance=float(f.sample_distance),
                                    image_sample_distance=float(f.image_sample_distance),
                                    early_termination=float(f.early_termination),
                                    double_precision=bool(double_precision), shade=bool(shade),
                                    threads=self._threads)
        img = np.ascontiguousarray(rgba[::-1])
        if not return_stats:
            return img
        vs = self._vol.stats()
        stats = {"render_ms": st["render_ms"], "build_ms": vs["build_ms"], "rebuilt": rebuilt,
                 "samples": st["samples"], "skips": st["skips"], "blocks_allocated": vs["blocks_allocated"],
                 "blocks_dense": vs["blocks_dense"], "bricks_visible": vs["bricks_visible"], "bricks": vs["bricks"],
                 "levels": vs["levels"], "visible_block_bytes": vs["block_bytes"], "bytes": vs["bytes"],
                 "dense_bytes": vs["dense_bytes"], "non_finite": vs["non_finite"], "storage": vs["storage"],
                 "quantization_step": vs["quantization_step"], "backend": "cpu", "device": ""}
        return img, stats


def render_volume(volume, *, size=(512, 512), camera=None, color=None, opacity=None, spacing=None, origin=None,
                  sample_distance: float | None = None, image_sample_distance: float = 1.0,
                  opacity_unit_distance: float | None = None, early_termination: float = 0.99,
                  double_precision: bool = False, shade: bool = False, threads: int = 0, backend: str = "cpu",
                  device: str | None = None, return_stats: bool = False, quality: str | None = None):
    """Ray cast a scalar volume: ``matrixtree.volume.render_volume`` on the engine (same
    arguments and results)."""
    return VolumeRenderer(volume, color=color, opacity=opacity, spacing=spacing, origin=origin,
                          opacity_unit_distance=opacity_unit_distance, threads=threads, backend=backend,
                          device=device).render(camera=camera, size=size, sample_distance=sample_distance,
                                                image_sample_distance=image_sample_distance,
                                                early_termination=early_termination,
                                                double_precision=double_precision, shade=shade,
                                                return_stats=return_stats, quality=quality)

"""Thin numpy-facing wrappers over the VTK classes ``vtkMatrixTree`` and ``vtkMatrixTreeRayCaster``.

Where the VTK module does not import, ``MatrixTree``, ``render`` and ``tree_mesh`` are the
engine extension's (``matrixtree._engine``, bound at the end of this module), with the same
arguments and answers.
"""

from __future__ import annotations

import os

import numpy as np
from vtkmodules.util.numpy_support import numpy_to_vtk, vtk_to_numpy
from vtkmodules.vtkCommonCore import vtkDoubleArray, vtkIdTypeArray, vtkIntArray
from vtkmodules.vtkCommonDataModel import vtkDataSet, vtkPolyData

from matrixtree._backend import VTK_MODULE

if VTK_MODULE:
    from matrixtree_vtk import vtkMatrixTree, vtkMatrixTreeRayCaster
from matrixtree import _checks, _meshstate, _quality
from matrixtree._readers import check_not_empty, read_obj, read_off, read_ply
from matrixtree._util import (RAY_TREES, SPLIT_TREES, VtkErrors, check_backend, existing_file, points3, read_by_extension,
                              tree_type, vtk_points)


def _backend(backend: str) -> int:
    return vtkMatrixTree.OPENCL if check_backend(backend) == "opencl" else vtkMatrixTree.CPU


# PLY, OBJ and OFF go through the checking readers of matrixtree._readers (VTK 9.1's crash on, or
# read out of bounds for, truncated and malformed files, and has no OFF reader); the others through VTK's readers in a
# child process (matrixtree._sandbox), whose errors and crashes become ValueError.
_MESH_READERS = {".stl": "vtkIOGeometry.vtkSTLReader", ".vtp": "vtkIOXML.vtkXMLPolyDataReader",
                 ".vtk": "vtkIOLegacy.vtkPolyDataReader"}
#: Bytes per pixel a render holds at its peak: the engine's arrays (19), the output image's (23)
#: and the numpy copies (15), rounded up.
_RENDER_BYTES_PER_PIXEL = 64


def read_mesh(path: str | os.PathLike) -> vtkPolyData:
    """Read a surface mesh file into a triangulated ``vtkPolyData``.

    Parameters
    ----------
    path : str or os.PathLike
        A ``.ply``, ``.obj``, ``.off``, ``.stl``, ``.vtp`` or legacy ``.vtk`` file. OBJ files are
        triangulated and their duplicated vertices merged. PLY (ASCII and binary, faces and
        triangle strips), OBJ and OFF (ASCII, Geomview's prefixes ST, C, N, n) are read by
        checking readers: every count in a header is checked against the data that follow and
        every face index against the vertices, before anything is allocated.

    Returns
    -------
    vtkPolyData
        Triangles only.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    ValueError
        If the extension is not one of the above, the file is empty, truncated or malformed (the
        message names the element, record or line; for ``.stl``, ``.vtp`` and ``.vtk``, read by
        VTK in a child process, what the reader reported, or that it crashed or ran out of
        memory or time), a face refers to a missing vertex, or the file holds no polygons.

    Examples
    --------
    >>> import matrixtree, os
    >>> mesh = matrixtree.read_mesh(os.path.join(matrixtree.scenes.data_dir(), "meshes", "bunny.ply"))
    >>> mesh.GetNumberOfPolys()
    69451
    """
    path = existing_file(path, "mesh")
    ext = os.path.splitext(path)[1].lower()
    if ext == ".ply":
        out = read_ply(path)
    elif ext == ".obj":
        out = read_obj(path)
    elif ext == ".off":
        out = read_off(path)
    else:
        unsupported = f"unsupported mesh extension {ext!r} (use .ply, .obj, .off, .stl, .vtp or .vtk)"
        if ext in _MESH_READERS:
            check_not_empty(path, "mesh")
        out = read_by_extension(path, _MESH_READERS, unsupported)  # in a child process: see _sandbox
    out = _triangulated(out, merge_points=ext == ".obj")
    if out.GetNumberOfPolys() == 0:
        raise ValueError(f"{path} holds no polygons")
    return out


def _triangulated(out: vtkPolyData, merge_points: bool) -> vtkPolyData:
    """The polygons and strips of ``out`` as triangles (vertices and lines dropped); with
    ``merge_points`` coincident points merged (an OBJ file repeats them per texture corner)."""
    from vtkmodules.vtkFiltersCore import vtkCleanPolyData, vtkTriangleFilter

    tri = vtkTriangleFilter()
    tri.SetInputData(out)
    tri.PassVertsOff()
    tri.PassLinesOff()
    if merge_points:
        clean = vtkCleanPolyData()
        clean.SetInputConnection(tri.GetOutputPort())
        clean.PointMergingOn()
        clean.ConvertPolysToLinesOff()
        clean.ConvertLinesToPointsOff()
        clean.ConvertStripsToPolysOff()
        clean.Update()
        out = clean.GetOutput()
    else:
        tri.Update()
        out = tri.GetOutput()
    result = vtkPolyData()
    result.ShallowCopy(out)
    return result


def _check_tree_settings(tree, height, block_size, leaf_scale, threads):
    """(tree id, height, leaf_scale, threads) of MatrixTree's settings, checked; ValueError for
    an unknown tree or a setting out of range."""
    tree_id = tree_type(tree, RAY_TREES)
    height = _checks.integer(height, "height", 0, 63, "0 = automatic")
    if block_size not in (1, 2, 4, 8, 16, 32):
        raise ValueError(f"block_size must be a power of two in [1, 32], got {block_size!r}")
    if leaf_scale is not None:
        leaf_scale = _checks.real(leaf_scale, "leaf_scale", 1e-3, 1e3, meaning="median triangle extents")
    return tree_id, height, leaf_scale, _checks.threads(threads)


def _rays(origins, directions, t_max):
    """:meth:`MatrixTree.intersect`'s rays as two (N, 3) arrays and ``t_max`` as a float; ValueError
    for other shapes or a ``t_max`` that is negative or NaN."""
    o = points3(origins, "origins")
    d = points3(directions, "directions")
    if o.shape != d.shape:
        raise ValueError(f"origins {o.shape} and directions {d.shape} must have the same shape")
    t_max = float(t_max)
    if not t_max >= 0:
        raise ValueError(f"t_max must be >= 0 (inf allowed), got {t_max!r}")
    return o, d, t_max


def _as_polydata(mesh) -> vtkPolyData:
    if isinstance(mesh, vtkPolyData):
        return mesh
    if isinstance(mesh, vtkDataSet):
        from vtkmodules.vtkFiltersGeometry import vtkGeometryFilter

        g = vtkGeometryFilter()
        g.SetInputData(mesh)
        g.Update()
        return g.GetOutput()
    if isinstance(mesh, (str, os.PathLike)):
        return read_mesh(mesh)
    raise TypeError(f"expected a vtkPolyData, pyvista mesh or file path, got {type(mesh).__name__}")


class MatrixTree:
    """A matrix octree or kd-tree, an implicit general kd-tree or BSP tree, or the hybrid
    matrix/SAH tree over the triangles of a surface mesh.

    Parameters
    ----------
    mesh : vtkPolyData, pyvista.PolyData, any vtkDataSet, or str
        The surface (polygons and strips are triangulated; other data sets contribute their
        boundary surface); a path is read with :func:`read_mesh`.
    tree : {"octree", "kdtree", "implicit-kd", "bsp", "hybrid"}, default: "octree"
        The matrix octree or regular kd-tree (centre splits, one axis per level; the fastest
        builds); ``"implicit-kd"``, a kd-tree with SAH splits stored in the same per-level
        matrices (the paper's §4.1); ``"bsp"``, an implicit BSP tree with 26-DOP planes (§4.2, a
        slow build); ``"hybrid"``, a matrix octree with small SAH kd-trees in its leaves (§7).
        docs/trees.md compares them.
    height : int, default: 0
        Levels below the root (0..63), 0 = chosen from the scene (leaves about ``leaf_scale`` median
        triangle extents wide); for ``"implicit-kd"`` and ``"bsp"`` the depth limit of the build
        (0 = round(8 + 1.3 log2 N); a tree deeper than 46 levels fails to build).
    block_size : int, default: 8
        Edge of the B^3 blocks of the block-sparse levels (power of two, 1..32); ``"implicit-kd"``
        and ``"bsp"`` choose each level's block shape themselves.
    exact : bool, default: True
        Exact triangle/leaf overlap; False uses bounding boxes (faster build, more tests per ray).
    leaf_scale : float, optional
        Target leaf extent of the automatic height, in median triangle extents (0.001..1000): default
        2.0, and 4.0 for the hybrid's matrix part (its kd-trees split the larger leaves).
    threads : int, default: 0
        OpenMP threads (0..4096), 0 = all.
    backend : {"cpu", "opencl"}, default: "cpu"
        Where the build and the queries run: the OpenMP engine, or OpenCL kernels (same tree,
        same answers). ``"opencl"`` without a device raises RuntimeError saying so. The split
        trees are built on the CPU and traced on the device by the stackless walk; ``"hybrid"``
        has no OpenCL walk (ValueError).
    device : str, optional
        OpenCL device: ``"P:D"`` indices, a device number, or part of its name; default
        ``$MATRIXTREE_OPENCL_DEVICE``, else the first GPU, else the first device.

    Raises
    ------
    ValueError
        A setting out of the range given above.
    RuntimeError
        The build failed, with the engine's reason: a coordinate that is NaN, inf or beyond
        +-1e30, a mesh spanning less than 1e-30, or a ``height`` whose leaf level would need more
        than 1 GiB of pointers. If a later :meth:`build` fails, every query raises that reason.

    Examples
    --------
    >>> import numpy as np, matrixtree
    >>> mesh = matrixtree.scenes.default_scene(resolution=0.3)
    >>> tree = matrixtree.MatrixTree(mesh, tree="kdtree")
    >>> t, cell = tree.intersect([[0.0, 5.0, 0.0]], [[0.0, -1.0, 0.0]])
    >>> bool(np.isfinite(t[0]) and cell[0] >= 0)
    True
    """

    def __init__(self, mesh, tree: str = "octree", height: int = 0, block_size: int = 8,
                 exact: bool = True, leaf_scale: float | None = None, threads: int = 0,
                 backend: str = "cpu", device: str | None = None):
        self.mesh = _as_polydata(mesh)
        backend_id = _backend(backend)
        tree_id, height, leaf_scale, threads = _check_tree_settings(tree, height, block_size, leaf_scale, threads)
        if tree == "hybrid" and backend_id == vtkMatrixTree.OPENCL:
            raise ValueError("the hybrid tree has no OpenCL walk: use backend='cpu'")
        self._tree = vtkMatrixTree()
        self._tree.SetDataSet(self.mesh)
        self._tree.SetTreeType(tree_id)
        self._tree.SetHeight(height)
        self._tree.SetBlockSize(int(block_size))
        self._tree.SetExactOverlap(bool(exact))
        if leaf_scale is not None:
            (self._tree.SetHybridLeafScale if tree == "hybrid" else self._tree.SetLeafScale)(leaf_scale)
        self._tree.SetNumberOfThreads(threads)
        self._tree.SetBackend(backend_id)
        if device is not None:
            self._tree.SetOpenCLDevice(str(device))
        self.build()

    @property
    def vtk_tree(self) -> vtkMatrixTree:
        """The underlying ``vtkMatrixTree``."""
        return self._tree

    def build(self) -> "MatrixTree":
        """(Re)build the tree now. Queries rebuild by themselves when the mesh changed (points
        moved, even in place through a numpy view; cells replaced; see matrixtree._meshstate).
        Returns self.

        RuntimeError with the engine's reason if the build fails; every query then raises it too."""
        self._state = _meshstate.fingerprint(self.mesh)
        with VtkErrors(self._tree) as errors:
            ok = self._tree.Build()
        if not ok:
            why = errors.last or "building the matrix tree failed"
            if self._tree.GetBackend() == vtkMatrixTree.OPENCL:
                why += " [use backend='cpu', or install an OpenCL driver (e.g. pocl-opencl-icd)]"
            raise RuntimeError(why)
        return self

    def _query(self, method, *args):
        """``vtk_tree.<method>(*args)`` on a tree that matches the mesh (rebuilt if it changed);
        RuntimeError with VTK's message if it reports one (a failed build: every query raises
        its reason)."""
        if _meshstate.fingerprint(self.mesh) != self._state:
            self.build()
        with VtkErrors(self._tree) as errors:
            out = getattr(self._tree, method)(*args)
        errors.raise_last(RuntimeError)
        return out

    def stats(self) -> dict:
        """Build statistics: tree, height, triangles, leaves, references, nodes, bytes (the tree
        with its leaf triangles), the leaf triangles' bytes alone (``leaf_triangle_bytes``),
        per-level bytes, blocks and dimensions, the root box, per-phase build times (ms) and the total (ms).

        The level entries describe the matrix levels (for the hybrid, its matrix part). For
        ``"implicit-kd"`` and ``"bsp"`` also ``pointer_tree_bytes``: the same tree as 8-byte
        pointer nodes, what the implicit layout's storage is compared with."""
        t = self._tree
        h = t.GetTreeHeight()
        root = [0.0] * 6
        t.GetRootBounds(root)
        name = t.GetTreeTypeAsString()
        extra = {}
        if name in SPLIT_TREES:
            extra = {"pointer_tree_bytes": t.GetPointerTreeMemorySize()}
        return {
            "tree": name,
            "height": h,
            "triangles": t.GetNumberOfTriangles(),
            "leaves": t.GetNumberOfLeaves(),
            "references": t.GetNumberOfReferences(),
            "nodes": t.GetNumberOfNodes(),
            "bytes": t.GetMemorySize(),
            "leaf_triangle_bytes": t.GetLeafTrianglesMemorySize(),
            "level_bytes": [t.GetLevelMemorySize(l) for l in range(h + 1)],
            "level_blocks": [t.GetLevelNumberOfBlocks(l) for l in range(h + 1)],
            "leaf_dims": [t.GetLevelDimension(h, a) for a in range(3)],
            "level_dims": [[t.GetLevelDimension(l, a) for a in range(3)] for l in range(h + 1)],
            "root_bounds": root,
            "median_triangle_extent": t.GetMedianTriangleExtent(),
            "phases_ms": {t.GetBuildPhaseName(i): t.GetBuildPhaseTime(i)
                          for i in range(t.GetNumberOfBuildPhases())},
            "build_ms": t.GetBuildTime(),
            "conversion_ms": t.GetConversionTime(),
            "backend": t.GetBackendAsString(),
            "device": t.GetOpenCLDeviceName() if t.GetBackend() == vtkMatrixTree.OPENCL else "",
            **extra,
        }

    def find_leaves(self, points) -> np.ndarray:
        """Leaf finding for many points at once.

        Parameters
        ----------
        points : array_like, shape (N, 3)

        Returns
        -------
        numpy.ndarray, shape (N, 5), int32
            ``level, i, j, k, exists`` per point: the existing leaf containing it (exists = 1)
            or the largest empty node containing it (exists = 0); level -1 outside the tree.
            ``"implicit-kd"``, ``"bsp"``: the leaf on the point's side of every plane (the left
            side on a plane), exists = 0 for an empty leaf; ``"hybrid"``: its matrix part's.
        """
        p = points3(points, "points")
        out = vtkIntArray()
        self._query("FindLeaves", numpy_to_vtk(p, deep=False), out)
        return vtk_to_numpy(out).reshape(-1, 5).copy()

    def intersect(self, origins, directions, t_max: float = np.inf):
        """First hits of many rays ``o + t d`` with ``0 <= t <= t_max``.

        Parameters
        ----------
        origins, directions : array_like, shape (N, 3)
            A ray with a NaN or infinite component, or a zero direction, misses.
        t_max : float, default: inf
            At least 0 (``inf`` allowed).

        Returns
        -------
        t : numpy.ndarray, shape (N,)
            Hit distance in units of ``|d|``; ``inf`` where the ray misses.
        cell : numpy.ndarray, shape (N,)
            Hit cell id of the mesh; -1 where the ray misses.
        """
        o, d, t_max = _rays(origins, directions, t_max)
        t = vtkDoubleArray()
        c = vtkIdTypeArray()
        self._query("IntersectRays", numpy_to_vtk(o, deep=False), numpy_to_vtk(d, deep=False), t_max, t, c)
        return vtk_to_numpy(t).copy(), vtk_to_numpy(c).copy()

    @property
    def last_query_counters(self) -> dict:
        """Node visits and triangle tests summed over the last :meth:`intersect` call."""
        return {"node_visits": self._tree.GetLastNodeVisits(),
                "triangle_tests": self._tree.GetLastTriangleTests()}


_TRAVERSALS = {"restart": 0, "stack": 1, "shortstack": 2}
_TESTS = {"moller-trumbore": 0, "mt": 0, "watertight": 1}


def _check_render_settings(size, traversal: str, triangle_test: str, camera, tree: str, backend: str, height,
                           threads, leaf_scale):
    """(width, height, camera, tree height, threads, leaf_scale) of :func:`render`'s arguments,
    checked; ValueError for a bad size, setting, traversal, triangle test or camera, or a
    CPU-only tree asked for on another backend."""
    w, h = _checks.image_size(size, _RENDER_BYTES_PER_PIXEL)
    height = _checks.integer(height, "height", 0, 63, "0 = automatic")
    threads = _checks.threads(threads)
    if leaf_scale is not None:
        leaf_scale = _checks.real(leaf_scale, "leaf_scale", 1e-3, 1e3, meaning="median triangle extents")
    if camera is not None:
        if len(camera) not in (3, 4):
            raise ValueError("camera must be [position, focal_point, view_up] or with a view angle as 4th item")
        camera = _checks.camera(*camera, up_along_view_ok=True)
    if tree != "sah":
        tree_type(tree, {**RAY_TREES, "sah": None})  # ValueError naming every tree
    if traversal not in _TRAVERSALS:
        raise ValueError(f"traversal must be one of {sorted(_TRAVERSALS)}, got {traversal!r}")
    if triangle_test not in _TESTS:
        raise ValueError(f"triangle_test must be 'moller-trumbore' or 'watertight', got {triangle_test!r}")
    if tree in ("sah", "hybrid") and backend != "cpu":
        raise ValueError(f"the {tree!r} tree runs on the CPU only: use backend='cpu'")
    return w, h, camera, height, threads, leaf_scale


def render(mesh, size=(800, 800), tree: str = "octree", height: int = 0, camera=None,
           shadows: bool = True, threads: int = 0, caster: vtkMatrixTreeRayCaster | None = None,
           backend: str = "cpu", traversal: str = "stack", triangle_test: str = "moller-trumbore",
           leaf_scale: float | None = None, counters: bool = False, quality: str | None = None) -> dict:
    """Ray cast a mesh through a matrix tree: primary rays, one shadow ray per hit, Lambert shading.

    Parameters
    ----------
    mesh : vtkPolyData, pyvista.PolyData or str
    size : (int, int), default: (800, 800)
        Image width and height, each 1..16384; refused (ValueError) when the image arrays (about
        64 bytes per pixel) would not fit in the memory available.
    tree : {"octree", "kdtree", "implicit-kd", "bsp", "hybrid", "sah"}, default: "octree"
        A tree of :class:`MatrixTree` (the matrix octree or kd-tree, the implicit kd-tree or BSP
        tree, the hybrid), or the baseline: a SAH kd-tree (Wald & Havran build, 8-byte pointer
        nodes; CPU only) traced with ``traversal``.
    height : int, default: 0
        Matrix-tree height, 0 = automatic (from the scene, see ``leaf_scale``); the depth limit of
        ``"implicit-kd"`` and ``"bsp"`` (see :class:`MatrixTree`).
    traversal : {"stack", "shortstack", "restart"}, default: "stack"
        SAH kd-tree traversal: a full stack, a short stack of 3 entries, or KD-Restart. Ignored
        for the trees of :class:`MatrixTree` (each has its production walk).
    triangle_test : {"moller-trumbore", "watertight"}, default: "moller-trumbore"
        The watertight test (Woop, Benthin & Wald 2013) lets no ray slip between the triangles of
        a closed mesh, within a few percent of Moller-Trumbore's speed on the CPU; Moller-Trumbore,
        the default, is the one test of both backends ("watertight" with "opencl" is an error).
    quality : {"exact", "balanced", "fast"}, optional
        One word for ``triangle_test`` (not to be combined with it): "exact" = "watertight",
        "balanced" and "fast" = "moller-trumbore" (docs/speed_accuracy.md).
    leaf_scale : float, optional
        Automatic height: the leaf extent aimed at, as a multiple of the median triangle extent
        (engine default 2.0, fastest build; 1.0 renders faster on most meshes, see
        docs/bench_rays.md); for ``"hybrid"`` its matrix part's (default 4.0).
    camera : None or sequence, default: None
        ``None`` frames the mesh automatically; otherwise a pyvista-style camera position
        ``[position, focal_point, view_up]`` (optionally with a fourth item, the vertical view
        angle in degrees, 0.01..179, default 30): finite, with the position away from the focal
        point. A view up along the view direction is replaced by the y (or x) axis.
    shadows : bool, default: True
    threads : int, default: 0
    counters : bool, default: False
        Count node visits and triangle tests per pixel (the paper's Figure 1). Off, the walks run
        without counters (the timed render) and the counts in the result are ``None``.
    caster : vtkMatrixTreeRayCaster, optional
        Reuse a caster (and its tree) across frames; the tree is rebuilt only if the mesh changed.
    backend : {"cpu", "opencl"}, default: "cpu"
        Build and trace on the OpenMP engine or with OpenCL kernels (see :class:`MatrixTree`);
        with "opencl" the per-pixel ``node_visits``/``triangle_tests`` are 0. ``"sah"`` and
        ``"hybrid"`` run on the CPU only (ValueError).

    Returns
    -------
    dict
        ``rgb`` (H, W, 3) uint8 with row 0 at the top, ``node_visits`` and ``triangle_tests``
        (H, W) uint32 (``None`` without ``counters``), ``depth`` (H, W) float32, ``build_ms``,
        ``render_ms``, ``rebuilt``, ``rays`` (primary + shadow), ``node_visits_per_ray``,
        ``triangle_tests_per_ray`` (``None`` without ``counters``), ``caster``.

    Examples
    --------
    >>> import matrixtree
    >>> img = matrixtree.render(matrixtree.scenes.default_scene(resolution=0.3), size=(64, 48))
    >>> img["rgb"].shape
    (48, 64, 3)
    """
    triangle_test = _quality.triangle_test(quality, triangle_test)
    pd = _as_polydata(mesh)
    w, h, camera, height, threads, leaf_scale = _check_render_settings(size, traversal, triangle_test, camera, tree,
                                                                       backend, height, threads, leaf_scale)
    rc = caster if caster is not None else vtkMatrixTreeRayCaster()
    if tree == "sah":
        rc.SetAcceleratorToSAHKdTree()
        rc.SetSAHTraversal(_TRAVERSALS[traversal])
    else:
        rc.SetAcceleratorToMatrixTree()
        rc.GetTree().SetTreeType(RAY_TREES[tree])
    rc.SetTriangleTest(_TESTS[triangle_test])
    if leaf_scale is not None:
        (rc.GetTree().SetHybridLeafScale if tree == "hybrid" else rc.GetTree().SetLeafScale)(leaf_scale)
    rc.GetTree().SetBackend(_backend(backend))
    rc.GetTree().SetHeight(height)
    rc.GetTree().SetNumberOfThreads(threads)
    rc.SetNumberOfThreads(threads)
    rc.SetInputData(pd)
    rc.SetImageSize(w, h)
    rc.SetShadows(bool(shadows))
    rc.SetCounters(bool(counters))
    if camera is None:
        rc.AutoCameraOn()
    else:
        rc.AutoCameraOff()
        rc.SetPosition(*camera[0])
        rc.SetFocalPoint(*camera[1])
        rc.SetViewUp(*camera[2])
        rc.SetViewAngle(30.0 if camera[3] is None else camera[3])
    rc.Modified()
    with VtkErrors(rc.GetTree()) as tree_errors, VtkErrors(rc) as errors:
        rc.Update()
    tree_errors.raise_last(RuntimeError)  # the build's reason comes before the caster's summary
    errors.raise_last(RuntimeError)
    img = rc.GetOutput()
    pdata = img.GetPointData()

    def grid(name, comps=1):
        a = vtk_to_numpy(pdata.GetArray(name))
        a = a.reshape(h, w, comps) if comps > 1 else a.reshape(h, w)
        return np.ascontiguousarray(a[::-1])  # VTK's row 0 is the bottom

    rays = rc.GetNumberOfPrimaryRays() + rc.GetNumberOfShadowRays()
    return {
        "rgb": grid("RGB", 3),
        "node_visits": grid("NodeVisits") if counters else None,
        "triangle_tests": grid("TriangleTests") if counters else None,
        "depth": grid("Depth"),
        "build_ms": rc.GetLastBuildTime(),
        "render_ms": rc.GetLastRenderTime(),
        "rebuilt": bool(rc.GetLastRebuilt()),
        "rays": rays,
        "hits": rc.GetNumberOfHits(),
        "node_visits_per_ray": rc.GetTotalNodeVisits() / max(rays, 1) if counters else None,
        "triangle_tests_per_ray": rc.GetTotalTriangleTests() / max(rays, 1) if counters else None,
        "caster": rc,
    }


def time_frames(frames, methods=("octree", "kdtree", "sah-stack"), size=(800, 800), camera=None,
                threads: int = 0, triangle_test: str = "moller-trumbore", leaf_scale: float | None = 1.0,
                progress: bool = True, keep_images: bool = False, counters: bool = True) -> list:
    """Rebuild and render every frame of an animation with each method: the paper's Table 1.

    Every method renders the same frames through the same ray caster (primary rays plus one shadow
    ray per hit); the tree is rebuilt every frame because every frame moves the points.

    Parameters
    ----------
    frames : sequence
        The frames: meshes (vtkPolyData / pyvista.PolyData) with the same triangles, or a tuple
        ``(mesh, [points_0, points_1, ...])`` of one mesh and (n, 3) point arrays per frame.
    methods : sequence of str, default: ("octree", "kdtree", "sah-stack")
        ``"octree"``, ``"kdtree"`` (matrix trees) and ``"sah-stack"``, ``"sah-shortstack"``,
        ``"sah-restart"`` (the SAH kd-tree baseline; built once per frame and shared by its
        traversals, each row reports that build).
    size, camera, threads, triangle_test, leaf_scale
        As in :func:`render` (``leaf_scale`` defaults to 1.0 here, the rendering setting).
    progress : bool, default: True
        Show a progress bar (tqdm) over the frames.
    keep_images : bool, default: False
        Keep the first frame's render (and heat maps) of every method in ``row["first_frame"]``.
    counters : bool, default: True
        Count node visits and triangle tests: every frame is rendered once more with counters
        on, untimed (the timed render runs without them).

    Returns
    -------
    list of dict
        One row per method: ``method``, ``frames``, ``triangles``, ``build_ms`` and ``render_ms``
        (means per frame), ``frame_ms`` (their sum), ``node_visits_per_ray``,
        ``triangle_tests_per_ray``, ``build_ms_frames``, ``render_ms_frames``.

    Examples
    --------
    >>> import matrixtree
    >>> frames = [matrixtree.scenes.default_scene(0.2, time=t) for t in (0.0, 0.5)]
    >>> rows = matrixtree.time_frames(frames, size=(48, 32), progress=False)
    >>> [r["method"] for r in rows], rows[0]["frames"]
    (['octree', 'kdtree', 'sah-stack'], 2)
    """
    if isinstance(frames, tuple) and len(frames) == 2 and isinstance(frames[1], (list, tuple)):
        base = _as_polydata(frames[0])
        point_sets = [np.asarray(p, dtype=np.float64) for p in frames[1]]
    else:
        meshes = [_as_polydata(f) for f in frames]
        if not meshes:
            raise ValueError("frames is empty")
        base = meshes[0]
        point_sets = [vtk_to_numpy(m.GetPoints().GetData()).astype(np.float64) for m in meshes]
        ntri = base.GetNumberOfPolys()
        for i, m in enumerate(meshes):
            if m.GetNumberOfPolys() != ntri or m.GetNumberOfPoints() != base.GetNumberOfPoints():
                raise ValueError(f"frame {i} has {m.GetNumberOfPoints()} points / {m.GetNumberOfPolys()} "
                                 f"polygons, frame 0 {base.GetNumberOfPoints()} / {ntri}: frames must "
                                 "share their connectivity")
    if not point_sets:
        raise ValueError("frames is empty")
    for i, p in enumerate(point_sets):
        if p.shape != (base.GetNumberOfPoints(), 3):
            raise ValueError(f"frame {i}: points of shape {p.shape}, expected ({base.GetNumberOfPoints()}, 3)")
    valid = {"octree", "kdtree", "sah-stack", "sah-shortstack", "sah-restart"}
    bad = [m for m in methods if m not in valid]
    if bad:
        raise ValueError(f"unknown method(s) {bad}; choose from {sorted(valid)}")
    # One polydata per accelerator (same connectivity, points replaced each frame), one caster each.
    work = vtkPolyData()
    work.DeepCopy(base)
    casters = {}
    rows = {m: {"method": m, "build_ms_frames": [], "render_ms_frames": [], "rays": 0, "visits": 0, "tests": 0}
            for m in methods}
    it = range(len(point_sets))
    if progress:
        try:
            from tqdm import tqdm

            it = tqdm(it, desc="frames", unit="frame")
        except ImportError:  # pragma: no cover
            pass
    for fi in it:
        work.SetPoints(vtk_points(point_sets[fi]))
        work.Modified()
        sah_build = None  # the SAH tree is built by the first SAH row of the frame, shared by the rest
        for m in methods:
            key = "sah" if m.startswith("sah") else m
            img = render(work, size=size, tree=key, camera=camera, threads=threads, caster=casters.get(key),
                         traversal=m.split("-")[1] if key == "sah" else "stack",
                         triangle_test=triangle_test, leaf_scale=leaf_scale)
            casters[key] = img["caster"]
            r = rows[m]
            build = img["build_ms"]
            if key == "sah":
                if img["rebuilt"] or sah_build is None:
                    sah_build = img["build_ms"]
                build = sah_build
            r["build_ms_frames"].append(build)
            r["render_ms_frames"].append(img["render_ms"])
            if counters:  # the same frame again, counted and untimed (the tree is reused)
                img = render(work, size=size, tree=key, camera=camera, threads=threads, caster=casters[key],
                             traversal=m.split("-")[1] if key == "sah" else "stack",
                             triangle_test=triangle_test, leaf_scale=leaf_scale, counters=True)
                r["rays"] += img["rays"]
                r["visits"] += img["node_visits_per_ray"] * img["rays"]
                r["tests"] += img["triangle_tests_per_ray"] * img["rays"]
            if keep_images and fi == 0:
                r["first_frame"] = {k: img[k] for k in ("rgb", "node_visits", "triangle_tests")}
    out = []
    for m in methods:
        r = rows[m]
        nf = len(r["build_ms_frames"])
        b = float(np.mean(r["build_ms_frames"]))
        rm = float(np.mean(r["render_ms_frames"]))
        row = {"method": m, "frames": nf, "triangles": base.GetNumberOfPolys(), "build_ms": b, "render_ms": rm,
               "frame_ms": b + rm,
               "node_visits_per_ray": r["visits"] / max(r["rays"], 1) if counters else None,
               "triangle_tests_per_ray": r["tests"] / max(r["rays"], 1) if counters else None,
               "build_ms_frames": r["build_ms_frames"], "render_ms_frames": r["render_ms_frames"]}
        if "first_frame" in r:
            row["first_frame"] = r["first_frame"]
        out.append(row)
    return out


def save_rgb(rgb: np.ndarray, path: str | os.PathLike) -> str:
    """Write an (H, W, 3) uint8 image (row 0 at the top) as PNG. Returns the path."""
    from PIL import Image

    path = os.fspath(path)
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    Image.fromarray(np.asarray(rgb, dtype=np.uint8)).save(path)
    return path


def save_heatmap(counts: np.ndarray, path: str | os.PathLike, vmax: float, cmap: str = "inferno") -> str:
    """Write a per-pixel counter (node visits, triangle tests) as a PNG heat map, black = 0 and
    the brightest colour at ``vmax`` and above (the paper's Figure 1 uses 100 visits, 250 tests)."""
    from matplotlib import colormaps

    c = np.clip(np.asarray(counts, dtype=np.float64) / float(vmax), 0.0, 1.0)
    rgb = (colormaps[cmap](c)[..., :3] * 255.0 + 0.5).astype(np.uint8)
    return save_rgb(rgb, path)


def _level_range(levels):
    """(lo, hi, leaves_only) of :func:`tree_mesh`'s ``levels``: hi = -1 is the leaf level;
    ``levels=-1`` asks for the leaves alone (0, -1, True). ValueError for anything else."""
    if levels is None:
        return 0, -1, False
    if isinstance(levels, (int, np.integer)):
        lo, hi = int(levels), int(levels)
    else:
        lo, hi = (int(v) for v in levels)
    if lo < 0 and hi == lo:
        return 0, -1, True
    if lo < 0 or (hi < lo and hi != -1):
        raise ValueError(f"levels must be None, a level >= 0 (or -1 for the leaves), or (lo, hi) with "
                         f"0 <= lo <= hi (hi = -1: the leaves); got {levels!r}")
    return lo, hi, False


def _tree_mesh_input(mesh) -> vtkDataSet:
    """:func:`tree_mesh`'s mesh as a data set with cells (a path is read); TypeError or
    ValueError otherwise."""
    if isinstance(mesh, (str, os.PathLike)):
        mesh = read_mesh(mesh)
    if not isinstance(mesh, vtkDataSet):
        raise TypeError(f"tree_mesh needs a VTK/pyvista data set or a mesh file path, got {type(mesh).__name__}")
    if mesh.GetNumberOfCells() == 0:
        raise ValueError("tree_mesh: the data set has no cells (nothing to build a tree over)")
    return mesh


def tree_mesh(mesh, tree: str = "octree", height: int = 0, levels=None, exact_overlap: bool = False):
    """The tree over a mesh or grid for plotting: a matrix tree's nodes as boxes (one voxel per
    existing node), or the split planes of an implicit kd-tree, BSP tree or hybrid tree.

    Parameters
    ----------
    mesh : vtkDataSet, pyvista dataset or str
        Any data set (its cells are indexed; a surface mesh's triangles), or a mesh file path.
        ``"implicit-kd"``, ``"bsp"`` and ``"hybrid"`` index triangles: a data set that is not a
        surface contributes its boundary surface.
    tree : {"octree", "kdtree", "implicit-kd", "bsp", "hybrid"}, default: "octree"
        The cell locator's matrix octree or kd-tree, or a tree of :class:`MatrixTree`.
    height : int, default: 0
        Tree height; 0 = automatic (the cell locator's rule: leaf extent from the median cell);
        for ``"implicit-kd"`` and ``"bsp"`` the depth limit of their build.
    levels : None, int or (int, int), default: None
        Which levels to output: ``None`` = every level from the root to the leaves, an int = that
        level only, ``(lo, hi)`` = levels lo..hi (``hi = -1``: the leaf level; for the split
        planes, every level).
    exact_overlap : bool, default: False
        Bounding-box cell/box overlap (the cell locator's default) or exact (a separating-axis
        test: fewer references on tetrahedra, a slower build); for ``"hybrid"``, of its matrix part.

    Returns
    -------
    pyvista.UnstructuredGrid
        Matrix trees: voxels with cell arrays ``level``, ``occupancy`` (fraction of an inner
        node's children that exist; 1 for leaves) and ``cell_count`` (cells overlapping the node);
        field data ``tree_height``. ``"implicit-kd"``, ``"bsp"``: one polygon per inner node, its
        split plane clipped to the node's cell, with cell arrays ``level`` and ``direction`` (0-2
        the axes, 3-12 the BSP tree's diagonals); ``"hybrid"``: voxels for its matrix nodes
        (``direction`` -1) and polygons for its leaves' kd-trees, whose planes start at the matrix
        leaves' level ``tree_height``. ``levels=-1`` keeps the matrix leaves only.

    Examples
    --------
    >>> import matrixtree
    >>> boxes = matrixtree.tree_mesh(matrixtree.scenes.default_scene(0.2), levels=-1)
    >>> bool(boxes.n_cells > 0), sorted(set(boxes.cell_data["level"])) == [int(boxes.field_data["tree_height"][0])]
    (True, True)
    """
    import pyvista as pv
    from matrixtree_vtk import vtkMatrixTreeRepresentation

    tree_id = tree_type(tree, RAY_TREES)
    mesh = _tree_mesh_input(mesh)
    if tree_id >= RAY_TREES["implicit-kd"]:
        mesh = _as_polydata(mesh)
    rep = vtkMatrixTreeRepresentation()
    rep.SetTreeType(tree_id)
    rep.SetHeight(int(height))
    rep.SetExactOverlap(bool(exact_overlap))
    lo, hi, leaves_only = _level_range(levels)
    if leaves_only and tree in SPLIT_TREES:
        raise ValueError(f"levels=-1: a {tree!r} tree draws its inner nodes' planes, its leaves have none; "
                         "give a level or (lo, hi)")
    rep.SetMinLevel(lo)
    rep.SetMaxLevel(hi)
    rep.SetInputData(mesh)
    with VtkErrors(rep) as errors:
        rep.Update()
    if errors.last:
        raise RuntimeError(f"tree_mesh: {errors.last}")
    out = pv.wrap(rep.GetOutput())
    if leaves_only and out.n_cells:
        h = int(out.field_data["tree_height"][0])
        keep = np.asarray(out.cell_data["level"]) == h
        if "direction" in out.cell_data:  # the hybrid: its matrix leaves, not its kd roots' planes
            keep &= np.asarray(out.cell_data["direction"]) == -1
        out = out.extract_cells(np.flatnonzero(keep))
        out.field_data["tree_height"] = [h]
    return out


if not VTK_MODULE:  # the engine extension answers (matrixtree._backend): one path per process
    from matrixtree import _engine  # noqa: E402

    for _name in ("MatrixTree", "render", "tree_mesh"):
        _engine.adopt_docs(globals()[_name], getattr(_engine, _name))
    from matrixtree._engine import MatrixTree, render, tree_mesh  # noqa: E402, F811

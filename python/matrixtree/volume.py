"""Volume rendering through ``vtkMatrixTreeVolumeRayCaster``: numpy and pyvista in, RGBA out.

The renderer stores only what a visible sample can read (Andrysco & Tricoche 2011, §3): 8/16-bit
scalars (and float scalars holding only integers) as 8^3-cell bricks with a 1-voxel apron in their
own width, other floating-point scalars quantised into 16-bit bricks where the lookup table cannot
resolve the step (else as a block-sparse matrix of 8x8x8-voxel float blocks); it skips invisible
space through the matrix-tree levels above them. Rays are marched on the CPU (OpenMP) or, with
``backend="opencl"``, by OpenCL kernels over the same storage. This module converts and delegates.
Where the VTK module does not import, ``render_volume`` is the engine extension's
(``matrixtree._engine``, bound at the end of this module; CPU only), with the same answers.
"""

from __future__ import annotations

import os
from types import SimpleNamespace

import numpy as np
from vtkmodules.util.numpy_support import numpy_to_vtk, vtk_to_numpy
from vtkmodules.vtkCommonDataModel import vtkImageData, vtkPiecewiseFunction
from vtkmodules.vtkRenderingCore import vtkCamera, vtkColorTransferFunction

from matrixtree._backend import VTK_MODULE

if VTK_MODULE:
    from matrixtree_vtk import vtkMatrixTreeVolumeRayCaster

from matrixtree import _checks, _quality
from matrixtree._readers import check_not_empty
from matrixtree._util import VtkErrors, check_backend, existing_file, read_by_extension

__all__ = ["VolumeRenderer", "default_transfer_functions", "read_volume", "render_volume", "frame_camera"]


#: Bytes per pixel a volume render holds at its peak: the float RGBA image (16), the 8-bit one (4),
#: the engine's accumulation buffers (about 32) and the numpy copy (16), rounded up.
_VOLUME_BYTES_PER_PIXEL = 64

_VOLUME_READERS = {".mhd": "vtkIOImage.vtkMetaImageReader", ".mha": "vtkIOImage.vtkMetaImageReader",
                   ".nii": "vtkIOImage.vtkNIFTIImageReader", ".nii.gz": "vtkIOImage.vtkNIFTIImageReader",
                   ".slc": "vtkIOImage.vtkSLCReader", ".vti": "vtkIOXML.vtkXMLImageDataReader",
                   ".vtk": "vtkIOLegacy.vtkStructuredPointsReader"}


def read_volume(path: str | os.PathLike) -> vtkImageData:
    """Read a scalar volume file into a ``vtkImageData`` with one-component active scalars.

    Parameters
    ----------
    path : str or os.PathLike
        ``.mhd``/``.mha`` (MetaImage), ``.nii``/``.nii.gz`` (NIfTI), ``.vtk`` (legacy structured
        points), ``.slc`` or ``.vti``.

    Returns
    -------
    vtkImageData
        The image; if its scalars have several components, the first is kept.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    ValueError
        If the extension is unknown, the file is empty, the reader reports an error, crashes or
        runs out of memory or time on it (it runs in a child process, see
        ``matrixtree._sandbox``), or the file holds no point scalars.

    Examples
    --------
    >>> import os, matrixtree
    >>> im = matrixtree.read_volume(os.path.join(matrixtree.scenes.data_dir(), "volumes", "ironProt.vtk"))
    >>> im.GetDimensions()
    (68, 68, 68)
    """
    path = existing_file(path, "volume")
    check_not_empty(path, "volume")
    read = read_by_extension(path, _VOLUME_READERS, f"unknown volume format: {path}")
    out = vtkImageData()
    out.ShallowCopy(read)
    scalars = out.GetPointData().GetScalars()
    if scalars is None:
        raise ValueError(f"{path} holds no point scalars")
    if scalars.GetNumberOfComponents() > 1:
        first = vtk_to_numpy(scalars)[:, 0].copy()
        arr = numpy_to_vtk(first, deep=True)
        arr.SetName(scalars.GetName() or "scalars")
        out.GetPointData().SetScalars(arr)
    return out


def _as_image(volume, spacing, origin) -> vtkImageData:
    if isinstance(volume, vtkImageData):  # pyvista.ImageData is one
        return volume
    arr = np.asarray(volume)
    if arr.ndim != 3:
        raise ValueError(f"volume must be a vtkImageData/pyvista.ImageData or a 3-D array, got shape {arr.shape}")
    if arr.size == 0:
        raise ValueError("volume is empty")
    if arr.dtype.kind not in "biuf":
        raise ValueError(f"volume scalars must be numeric, got {arr.dtype}")
    im = vtkImageData()
    im.SetDimensions(*arr.shape)  # arr[i, j, k]: x = i
    im.SetSpacing(*(spacing if spacing is not None else (1.0, 1.0, 1.0)))
    im.SetOrigin(*(origin if origin is not None else (0.0, 0.0, 0.0)))
    flat = np.ascontiguousarray(arr.transpose(2, 1, 0)).ravel()  # x fastest, as VTK stores it
    if flat.dtype == np.bool_:
        flat = flat.astype(np.uint8)
    vtk_arr = numpy_to_vtk(flat, deep=True)
    vtk_arr.SetName("scalars")
    im.GetPointData().SetScalars(vtk_arr)
    return im


def _scalars(image: vtkImageData) -> np.ndarray:
    s = image.GetPointData().GetScalars()
    if s is None:
        raise ValueError("the image has no point scalars")
    return vtk_to_numpy(s)


def default_transfer_functions(volume, max_opacity: float = 0.25):
    """Colour and opacity functions derived from the scalars' histogram.

    Scalars up to the 60th percentile (the background and the bulk of soft values in the volumes
    of ``../shared/data/volumes``) are transparent; above it opacity rises linearly to
    ``max_opacity`` at the maximum, and colour runs from dark red through orange to white.

    Parameters
    ----------
    volume : vtkImageData, pyvista.ImageData or numpy.ndarray
        The volume (one-component scalars).
    max_opacity : float, default: 0.25
        Opacity at the highest scalar, per ``ScalarOpacityUnitDistance``.

    Returns
    -------
    tuple of (vtkColorTransferFunction, vtkPiecewiseFunction)

    Examples
    --------
    >>> import numpy as np, matrixtree
    >>> ctf, otf = matrixtree.default_transfer_functions(np.arange(1000.0).reshape(10, 10, 10))
    >>> otf.GetValue(0.0), round(otf.GetValue(999.0), 3)
    (0.0, 0.25)
    """
    image = _as_image(volume, None, None)
    v = _scalars(image).astype(np.float64).ravel()
    v = v[np.isfinite(v)]
    if v.size == 0:
        raise ValueError("the volume has no finite scalar")
    lo, hi = float(v.min()), float(v.max())
    if hi <= lo:
        hi = lo + 1.0
    t = float(np.percentile(v, 60))
    t = min(max(t, lo), lo + 0.9 * (hi - lo))
    otf = vtkPiecewiseFunction()
    otf.AddPoint(lo, 0.0)
    otf.AddPoint(t, 0.0)
    otf.AddPoint(hi, max_opacity)
    ctf = vtkColorTransferFunction()
    ctf.AddRGBPoint(lo, 0.0, 0.0, 0.0)
    ctf.AddRGBPoint(t, 0.55, 0.1, 0.05)
    ctf.AddRGBPoint(t + 0.5 * (hi - t), 1.0, 0.6, 0.2)
    ctf.AddRGBPoint(hi, 1.0, 1.0, 0.95)
    return ctf, otf


def frame_camera(volume, azimuth: float = 30.0, elevation: float = 20.0, view_angle: float = 30.0) -> vtkCamera:
    """A perspective camera that frames the volume's bounds, as ``vtkRenderer.ResetCamera`` does.

    Parameters
    ----------
    volume : vtkImageData, pyvista.ImageData or numpy.ndarray
    azimuth, elevation : float, default: 30.0, 20.0
        Rotation (degrees) of the view about the view up and the right axis, from the -y side.
    view_angle : float, default: 30.0
        Vertical view angle in degrees.

    Returns
    -------
    vtkCamera

    Examples
    --------
    >>> import numpy as np, matrixtree
    >>> cam = matrixtree.frame_camera(np.zeros((5, 5, 5)))
    >>> [round(c, 6) for c in cam.GetFocalPoint()]
    [2.0, 2.0, 2.0]
    """
    image = _as_image(volume, None, None)
    b = image.GetBounds()
    center = [(b[0] + b[1]) / 2, (b[2] + b[3]) / 2, (b[4] + b[5]) / 2]
    radius = 0.5 * float(np.linalg.norm([b[1] - b[0], b[3] - b[2], b[5] - b[4]])) or 1.0
    cam = vtkCamera()
    cam.SetFocalPoint(*center)
    cam.SetPosition(center[0], center[1] - 1.0, center[2])
    cam.SetViewUp(0, 0, 1)
    cam.SetViewAngle(view_angle)
    cam.Azimuth(azimuth)
    cam.Elevation(elevation)
    cam.OrthogonalizeViewUp()
    dist = radius / np.sin(np.radians(view_angle) / 2)
    d = np.array(cam.GetDirectionOfProjection())
    cam.SetPosition(*(np.array(center) - d * dist))
    return cam


def _prepare_volume(volume, color, opacity, spacing, origin, opacity_unit_distance, threads):
    """The volume-level inputs of :class:`VolumeRenderer` checked and completed, for both backends:
    a namespace with image, color, opacity, opacity_unit_distance and threads. ValueError for the
    bad input :func:`render_volume`'s docstring lists."""
    image = _as_image(volume, spacing, origin)
    s = image.GetPointData().GetScalars()
    if image.GetNumberOfPoints() == 0 or s is None:
        raise ValueError("the volume is empty or has no point scalars")
    if s.GetNumberOfComponents() != 1:
        raise ValueError(f"the volume has {s.GetNumberOfComponents()}-component scalars; pass one component")
    dims = image.GetDimensions()
    if s.GetNumberOfTuples() != image.GetNumberOfPoints():
        raise ValueError(f"the volume's scalar array has {s.GetNumberOfTuples()} values for "
                         f"{dims[0]}x{dims[1]}x{dims[2]} = {image.GetNumberOfPoints()} points: one per point is needed")
    if min(dims) < 2:
        raise ValueError(f"the volume is {dims[0]}x{dims[1]}x{dims[2]} points; at least 2 along every axis are needed")
    sp = np.abs(np.array(image.GetSpacing(), dtype=float))
    if not np.all(np.isfinite(sp)) or np.any(sp == 0):
        raise ValueError(f"spacing must be finite and non-zero, got {tuple(image.GetSpacing())}")
    if opacity_unit_distance is None:
        opacity_unit_distance = sp.mean()
    opacity_unit_distance = _checks.real(opacity_unit_distance, "opacity_unit_distance", 0.0, lo_open=True,
                                         meaning="world units")
    threads = _checks.threads(threads)
    if color is None or opacity is None:
        dc, do = default_transfer_functions(image)
        color = color if color is not None else dc
        opacity = opacity if opacity is not None else do
    return SimpleNamespace(image=image, color=color, opacity=opacity, opacity_unit_distance=opacity_unit_distance,
                           threads=threads)


def _prepare_frame(image, size, camera, sample_distance, image_sample_distance, early_termination, quality=None):
    """The per-frame inputs of :meth:`VolumeRenderer.render` checked and completed: a namespace
    with width, height, camera, sample_distance, image_sample_distance and early_termination."""
    dims = image.GetDimensions()
    sp = np.abs(np.array(image.GetSpacing(), dtype=float))
    w, h = _checks.image_size(size, _VOLUME_BYTES_PER_PIXEL)
    diagonal = float(np.linalg.norm((np.array(dims) - 1) * sp))
    scale, image_sample_distance, early_termination = _quality.volume(quality, sample_distance,
                                                                      image_sample_distance, early_termination)
    if sample_distance is None:
        sample_distance = 0.5 * scale * sp.min()
    sample_distance = _checks.real(sample_distance, "sample_distance", 0.0, lo_open=True, meaning="world units")
    if diagonal / sample_distance > _checks.MAX_SAMPLES_PER_RAY:
        raise ValueError(f"sample_distance {sample_distance!r} asks for {diagonal / sample_distance:.3g} samples "
                         f"across the volume's diagonal ({diagonal:.6g}); at most 2^20 per ray are supported: "
                         f"use sample_distance >= {diagonal / _checks.MAX_SAMPLES_PER_RAY:.3g}")
    image_sample_distance = _checks.real(image_sample_distance, "image_sample_distance", 1.0, 32.0)
    early_termination = _checks.real(early_termination, "early_termination", 0.0, 1.0, meaning="opacity")
    cam = camera if camera is not None else frame_camera(image)
    _checks.camera(cam.GetPosition(), cam.GetFocalPoint(), cam.GetViewUp(),
                   None if cam.GetParallelProjection() else cam.GetViewAngle())
    return SimpleNamespace(width=w, height=h, camera=cam, sample_distance=sample_distance,
                           image_sample_distance=image_sample_distance, early_termination=early_termination)


class VolumeRenderer:
    """One volume rendered frame after frame: classified and stored once, again only when it must be.

    The volume is classified with the opacity function into the block-sparse storage on the first
    :meth:`render`; later frames reuse it, so a camera move or a new image size costs only the ray
    marching. The volume is classified again when its scalars or the opacity function change
    (their VTK modification times: modify them in place, or assign :attr:`opacity`); a colour
    change only rebuilds the lookup table. :func:`render_volume` is one frame of a new renderer.

    Parameters
    ----------
    volume, color, opacity, spacing, origin, opacity_unit_distance, threads, backend, device
        As in :func:`render_volume`.

    Examples
    --------
    >>> import numpy as np, matrixtree
    >>> x, y, z = np.mgrid[-1:1:40j, -1:1:40j, -1:1:40j]
    >>> r = matrixtree.VolumeRenderer((1.0 - np.sqrt(x**2 + y**2 + z**2)).clip(0))
    >>> cam = matrixtree.frame_camera(r.image)
    >>> a, st = r.render(camera=cam, size=(64, 48), return_stats=True)
    >>> cam.Azimuth(30)
    >>> b, st2 = r.render(camera=cam, size=(64, 48), return_stats=True)
    >>> st["rebuilt"], st2["rebuilt"]                       # the camera move reuses the storage
    (True, False)
    """

    def __init__(self, volume, *, color=None, opacity=None, spacing=None, origin=None,
                 opacity_unit_distance: float | None = None, threads: int = 0, backend: str = "cpu",
                 device: str | None = None):
        check_backend(backend)
        v = _prepare_volume(volume, color, opacity, spacing, origin, opacity_unit_distance, threads)
        self.image = v.image
        self.backend = backend
        c = self._caster = vtkMatrixTreeVolumeRayCaster()
        c.SetInputData(v.image)
        c.SetColorTransferFunction(v.color)
        c.SetScalarOpacity(v.opacity)
        c.SetScalarOpacityUnitDistance(v.opacity_unit_distance)
        c.SetNumberOfThreads(v.threads)
        if backend == "opencl":
            c.SetBackendToOpenCL()
            if device is not None:
                c.SetOpenCLDevice(str(device))

    @property
    def color(self):
        """The colour transfer function (vtkColorTransferFunction)."""
        return self._caster.GetColorTransferFunction()

    @color.setter
    def color(self, ctf) -> None:
        self._caster.SetColorTransferFunction(ctf)

    @property
    def opacity(self):
        """The scalar opacity function (vtkPiecewiseFunction); a new one reclassifies the volume."""
        return self._caster.GetScalarOpacity()

    @opacity.setter
    def opacity(self, otf) -> None:
        self._caster.SetScalarOpacity(otf)

    def render(self, *, camera=None, size=(512, 512), sample_distance: float | None = None,
               image_sample_distance: float = 1.0, early_termination: float = 0.99, double_precision: bool = False,
               shade: bool = False, return_stats: bool = False, quality: str | None = None):
        """One frame: the arguments and results of :func:`render_volume`; the stats also say
        whether this frame classified the volume (``rebuilt``)."""
        f = _prepare_frame(self.image, size, camera, sample_distance, image_sample_distance, early_termination,
                           quality)
        c = self._caster
        c.SetImageSize(f.width, f.height)
        c.SetCamera(f.camera)
        c.SetSampleDistance(f.sample_distance)
        c.SetImageSampleDistance(f.image_sample_distance)
        c.SetEarlyTerminationThreshold(f.early_termination)
        c.SetDoublePrecision(bool(double_precision))
        c.SetShade(bool(shade))
        with VtkErrors(c) as errors:
            c.Update()
        out = c.GetOutput().GetPointData().GetArray("RGBAFloat")
        if out is None:
            if self.backend == "opencl":
                why = errors.last if errors.messages else "no OpenCL device, or a device error"
                raise RuntimeError(f"{why} [render_volume: backend='cpu' needs no OpenCL]")
            raise ValueError(errors.last if errors.messages else "volume rendering failed (see the VTK error above)")
        img = vtk_to_numpy(out).reshape(f.height, f.width, 4)[::-1].copy()
        if not return_stats:
            return img
        stats = {
            "render_ms": c.GetLastRenderTime(),
            "build_ms": c.GetLastBuildTime(),
            "rebuilt": bool(c.GetLastRebuilt()),
            "samples": c.GetNumberOfSamples(),
            "skips": c.GetNumberOfSkips(),
            "blocks_allocated": c.GetNumberOfAllocatedBlocks(),
            "blocks_dense": c.GetNumberOfDenseBlocks(),
            "bricks_visible": c.GetNumberOfVisibleBricks(),
            "bricks": c.GetNumberOfBricks(),
            "levels": c.GetNumberOfLevels(),
            "visible_block_bytes": c.GetVisibleBlockBytes(),
            "bytes": c.GetAllocatedBytes(),
            "dense_bytes": c.GetDenseBytes(),
            "non_finite": c.GetNumberOfNonFiniteScalars(),
            "storage": ("float32", "uint8", "uint16")[c.GetVoxelStorage()],
            "quantization_step": c.GetQuantizationStep(),
            "backend": c.GetBackendAsString(),
            "device": c.GetOpenCLDeviceName() if self.backend == "opencl" else "",
        }
        return img, stats


def render_volume(volume, *, size=(512, 512), camera=None, color=None, opacity=None, spacing=None, origin=None,
                  sample_distance: float | None = None, image_sample_distance: float = 1.0,
                  opacity_unit_distance: float | None = None, early_termination: float = 0.99,
                  double_precision: bool = False, shade: bool = False, threads: int = 0, backend: str = "cpu",
                  device: str | None = None, return_stats: bool = False, quality: str | None = None):
    """Ray cast a scalar volume into an RGBA image on the block-sparse encoding.

    Parameters
    ----------
    volume : pyvista.ImageData, vtkImageData or numpy.ndarray
        One-component scalars of any numeric type; a 3-D array is indexed ``[x, y, z]``.
    size : tuple of int, default: (512, 512)
        Image width and height, each 1..16384; refused when the image arrays (about 64 bytes per
        pixel) would not fit in the memory available.
    camera : vtkCamera or pyvista.Camera, optional
        Default: :func:`frame_camera`. Its position, focal point and view up must be finite, the
        position away from the focal point and the view up not along the view direction.
    color, opacity : vtkColorTransferFunction, vtkPiecewiseFunction, optional
        Default: :func:`default_transfer_functions`.
    spacing, origin : sequence of 3 float, optional
        Only for a numpy volume. Default: 1 and 0.
    sample_distance : float, optional
        World units between samples along a ray, > 0 and at least the volume's diagonal / 2^20
        (at most 2^20 samples per ray). Default: half the smallest spacing. Halving it doubles
        the time and roughly halves the error.
    image_sample_distance : float, default: 1.0
        Cast ``size / image_sample_distance`` rays per axis and interpolate: ~quadratic speed-up.
        1..32.
    opacity_unit_distance : float, optional
        Length over which ``opacity`` applies, > 0. Default: the mean spacing.
    early_termination : float, default: 0.99
        A ray stops once its opacity reaches this (0..1); ``1.0`` never stops early.
    double_precision : bool, default: False
        Interpolate and composite in double (differences ~1e-6 per channel).
    shade : bool, default: False
        Gradient shading with a headlight.
    threads : int, default: 0
        OpenMP threads (0..4096); 0 uses all.
    backend : {"cpu", "opencl"}, default: "cpu"
        March the rays with the OpenMP engine or with OpenCL kernels. The volume is classified and
        stored the same way for both (every scalar type works on both); the OpenCL image equals
        the CPU's (identical unshaded, within ~1e-7 shaded). ``"opencl"`` without a device raises
        RuntimeError saying so.
    device : str, optional
        OpenCL device: ``"P:D"`` indices, a device number, or part of its name; default
        ``$MATRIXTREE_OPENCL_DEVICE``, else the first GPU, else the first device.
    return_stats : bool, default: False
        Also return a dict of timings, samples, block/byte counts and the storage (``storage``:
        ``float32``, ``uint8`` or ``uint16``; floating-point scalars are quantised into 16-bit
        bricks, ``quantization_step`` their range / 65535, where the 4096-entry lookup table is
        16 times coarser than a step: a sample moves by at most 1/32 of a table entry).
    quality : {"exact", "balanced", "fast"}, optional
        One word for ``sample_distance``, ``image_sample_distance`` and ``early_termination``
        (not to be combined with them): "exact" = a quarter of the default sample distance and no
        early termination; "balanced" = the defaults; "fast" = twice the default sample distance,
        image sample distance 2 and early termination 0.95. Each is a point on the speed/accuracy
        fronts of docs/speed_accuracy.md.

    Returns
    -------
    numpy.ndarray
        ``(height, width, 4)`` float32: premultiplied RGB and opacity, row 0 at the top.
    dict
        Only if ``return_stats``.

    Raises
    ------
    ValueError
        Empty or multi-component volumes, a scalar array whose length is not the number of
        points, fewer than 2 points along an axis, zero spacing, scalars with no finite value, a
        setting out of the range given above, a degenerate camera, or an unknown ``backend``.
    RuntimeError
        ``backend="opencl"`` with no OpenCL device (or none matching ``device``), or a build
        without OpenCL.

    See Also
    --------
    matrixtree.render : surface ray casting of a mesh (also with ``backend``).
    VolumeRenderer : the same frame after frame, the volume classified once.

    Examples
    --------
    >>> import numpy as np, matrixtree
    >>> x, y, z = np.mgrid[-1:1:40j, -1:1:40j, -1:1:40j]
    >>> ball = (1.0 - np.sqrt(x**2 + y**2 + z**2)).clip(0)      # a soft ball in empty space
    >>> img, st = matrixtree.render_volume(ball, size=(64, 48), return_stats=True)
    >>> img.shape, img.dtype
    ((48, 64, 4), dtype('float32'))
    >>> bool(img[24, 32, 3] > 0.1), float(img[0, 0, 3])            # centre seen, corner empty
    (True, 0.0)
    >>> st["blocks_allocated"] < st["blocks_dense"]
    True
    """
    renderer = VolumeRenderer(volume, color=color, opacity=opacity, spacing=spacing, origin=origin,
                              opacity_unit_distance=opacity_unit_distance, threads=threads, backend=backend,
                              device=device)
    return renderer.render(camera=camera, size=size, sample_distance=sample_distance,
                           image_sample_distance=image_sample_distance, early_termination=early_termination,
                           double_precision=double_precision, shade=shade, return_stats=return_stats, quality=quality)


if not VTK_MODULE:  # the engine extension answers (matrixtree._backend): one path per process
    from matrixtree import _engine  # noqa: E402

    for _name in ("render_volume", "VolumeRenderer"):
        _engine.adopt_docs(globals()[_name], getattr(_engine, _name))
    from matrixtree._engine import VolumeRenderer, render_volume  # noqa: E402, F811

"""Volume ray casting: vtkMatrixTreeVolumeRayCaster against vtkFixedPointVolumeRayCastMapper.

For every volume (``--volume FILE``, or every one in ../shared/data/volumes), in one process:
the same transfer functions, camera, image size and sample distance for both renderers; time
per frame (median, the two renderers interleaved frame by frame), and CPU time per frame
(process_time, both renderers limited to 1 thread, interleaved: the noise-robust comparison on a
shared machine); SSIM/PSNR between the two
images; PSNR of each against a reference (ours at 1/16 of the smallest spacing, double precision,
no early termination); allocated vs dense blocks and bytes; and our speed/accuracy curve over the
sample distance. VTK renders off-screen, so run it under a display, e.g.

    xvfb-run -a .venv/bin/python bench/volume.py --json out/volume.json --md out/bench_volume.md

``--md`` writes the tables as markdown and its two pictures into ``images/`` beside it.

``--backend all`` adds our OpenCL backend (row ``matrixtree-opencl``, with ``max_diff_vs_cpu``).

Frames after the first: ``first_ms`` is each renderer's first frame (ours: classification and
storage included), ``camera_ms`` the median frame after a camera move (azimuth +/-10 degrees,
alternating), ``tf_ms`` the median frame after an opacity-function change (its ramp start moved
by 2% of the range, alternating: ours reclassifies). Volumes generated at bench time:
``--phantom N`` (repeatable) adds bench/ct_phantom.py's CT-like torso at N^3 as float32 (noisy
Hounsfield units: quantised into 16-bit bricks) and as uint16; ``--upsample K`` adds headsq
upsampled K times per axis (trilinear); ``--large`` is ``--phantom 512 --upsample 6`` (a few
minutes more). Generated volumes get no speed/accuracy curve.
"""

from __future__ import annotations

import argparse
import glob
import os
import statistics
import sys
import time

import numpy as np

from _common import ROOT, machine, markdown, table, write_json
from ct_phantom import ct_phantom, ct_transfer_functions, to_image

import matrixtree  # noqa: E402  (path set by _common)
from matrixtree import scenes  # noqa: E402
from matrixtree.volume import default_transfer_functions, frame_camera, read_volume  # noqa: E402
from matrixtree_vtk import vtkMatrixTreeVolumeRayCaster  # noqa: E402
from vtkmodules.util.numpy_support import vtk_to_numpy  # noqa: E402
from vtkmodules.vtkRenderingCore import (vtkRenderer, vtkRenderWindow, vtkVolume,  # noqa: E402
                                         vtkVolumeProperty, vtkWindowToImageFilter)
from vtkmodules.vtkRenderingVolume import vtkFixedPointVolumeRayCastMapper  # noqa: E402
import vtkmodules.vtkRenderingOpenGL2  # noqa: E402,F401  (the render window implementation)
import vtkmodules.vtkRenderingVolumeOpenGL2  # noqa: E402,F401  (vtkRayCastImageDisplayHelper)

CURVE = (2.0, 1.0, 0.5, 0.25, 0.125)  # sample distance in units of the smallest spacing


# ------------------------------------------------------------------------------------ metrics
def _box(a: np.ndarray, r: int) -> np.ndarray:
    """Mean over a (2r+1)^2 window (valid region), by summed-area tables."""
    s = np.pad(a, ((1, 0), (1, 0))).cumsum(0).cumsum(1)
    k = 2 * r + 1
    return (s[k:, k:] - s[:-k, k:] - s[k:, :-k] + s[:-k, :-k]) / (k * k)


def ssim(a: np.ndarray, b: np.ndarray, r: int = 3) -> float:
    """Mean SSIM (Wang et al. 2004) over RGB channels in [0, 1], 7x7 uniform window."""
    c1, c2 = 0.01 ** 2, 0.03 ** 2
    vals = []
    for ch in range(3):
        x, y = a[..., ch].astype(np.float64), b[..., ch].astype(np.float64)
        mx, my = _box(x, r), _box(y, r)
        sxx, syy, sxy = _box(x * x, r) - mx * mx, _box(y * y, r) - my * my, _box(x * y, r) - mx * my
        m = ((2 * mx * my + c1) * (2 * sxy + c2)) / ((mx * mx + my * my + c1) * (sxx + syy + c2))
        vals.append(m.mean())
    return float(np.mean(vals))


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = float(np.mean((a[..., :3].astype(np.float64) - b[..., :3]) ** 2))
    return float("inf") if mse == 0 else 10 * np.log10(1.0 / mse)


# ---------------------------------------------------------------------------------- renderers
class Ours:
    def __init__(self, image, ctf, otf, unit, size, cam):
        self.c = vtkMatrixTreeVolumeRayCaster()
        self.c.SetInputData(image)
        self.c.SetColorTransferFunction(ctf)
        self.c.SetScalarOpacity(otf)
        self.c.SetScalarOpacityUnitDistance(unit)
        self.c.SetImageSize(*size)
        self.c.SetCamera(cam)
        self.size = size

    def frame(self, **opts) -> tuple[float, np.ndarray]:
        for k, v in opts.items():
            getattr(self.c, "Set" + k)(v)
        self.c.Modified()
        t0, c0 = time.perf_counter(), time.process_time()
        self.c.Update()
        ms = (time.perf_counter() - t0) * 1e3
        self.cpu_ms = (time.process_time() - c0) * 1e3
        a = vtk_to_numpy(self.c.GetOutput().GetPointData().GetArray("RGBAFloat"))
        return ms, np.clip(a.reshape(self.size[1], self.size[0], 4), 0, 1)


class Vtk:
    def __init__(self, image, ctf, otf, unit, size, cam, sample_distance):
        self.mapper = vtkFixedPointVolumeRayCastMapper()
        self.mapper.SetInputData(image)
        self.mapper.AutoAdjustSampleDistancesOff()
        self.mapper.SetSampleDistance(sample_distance)
        self.mapper.SetInteractiveSampleDistance(sample_distance)
        self.mapper.SetImageSampleDistance(1.0)
        self.mapper.SetMinimumImageSampleDistance(1.0)
        self.mapper.SetMaximumImageSampleDistance(1.0)
        prop = vtkVolumeProperty()
        prop.SetColor(ctf)
        prop.SetScalarOpacity(otf)
        prop.SetScalarOpacityUnitDistance(unit)
        prop.SetInterpolationTypeToLinear()
        prop.ShadeOff()
        self.prop = prop
        vol = vtkVolume()
        vol.SetMapper(self.mapper)
        vol.SetProperty(prop)
        self.ren = vtkRenderer()
        self.ren.SetBackground(0, 0, 0)
        self.ren.AddVolume(vol)
        self.ren.SetActiveCamera(cam)
        self.ren.ResetCameraClippingRange()
        self.win = vtkRenderWindow()
        self.win.SetOffScreenRendering(1)
        self.win.SetSize(*size)
        self.win.AddRenderer(self.ren)
        self.size = size

    def frame(self) -> tuple[float, np.ndarray]:
        t0, c0 = time.perf_counter(), time.process_time()
        self.win.Render()
        ms = (time.perf_counter() - t0) * 1e3
        self.cpu_ms = (time.process_time() - c0) * 1e3
        grab = vtkWindowToImageFilter()
        grab.SetInput(self.win)
        grab.SetInputBufferTypeToRGB()
        grab.ReadFrontBufferOff()
        grab.Update()
        a = vtk_to_numpy(grab.GetOutput().GetPointData().GetScalars()).reshape(self.size[1], self.size[0], 3)
        return ms, np.concatenate([a / 255.0, np.ones(a.shape[:2] + (1,))], axis=2)


# ------------------------------------------------------------------------------------ volumes
def upsampled(image, k: int):
    """`image` resampled trilinearly to k times as many points per axis (spacing / k)."""
    from vtkmodules.vtkImagingCore import vtkImageResize

    r = vtkImageResize()
    r.SetInputData(image)
    r.SetResizeMethodToMagnificationFactors()
    r.SetMagnificationFactors(k, k, k)
    r.InterpolateOn()
    r.Update()
    out = r.GetOutput()
    out.SetExtent(0, out.GetDimensions()[0] - 1, 0, out.GetDimensions()[1] - 1, 0, out.GetDimensions()[2] - 1)
    return out


def volumes(args) -> list:
    """(name, loader, transfer functions or None for the default ones) per volume to bench: the
    files, the phantoms (with a CT preset), the upsampled CT."""
    out = []
    for p in args.paths:
        out.append((os.path.basename(p).split(".")[0], lambda p=p: read_volume(p), None))
    for n in args.phantom:
        for dt in ("float32", "uint16"):
            out.append((f"phantom{n}-{dt}", lambda n=n, dt=dt: to_image(ct_phantom(n, dt)),
                        lambda dt=dt: ct_transfer_functions(dt)))
    if args.upsample:
        head = os.path.join(scenes.data_dir(), "volumes", "headsq.mhd")
        out.append((f"headsq-x{args.upsample}", lambda: upsampled(read_volume(head), args.upsample), None))
    return out


def opacity_shifted(otf, lo: float, hi: float, frac: float):
    """A copy of `otf` with its points above the lowest moved by frac * (hi - lo)."""
    from vtkmodules.vtkCommonDataModel import vtkPiecewiseFunction

    out = vtkPiecewiseFunction()
    for i in range(otf.GetSize()):
        node = [0.0] * 4
        otf.GetNodeValue(i, node)
        out.AddPoint(node[0] + (frac * (hi - lo) if 0 < i < otf.GetSize() - 1 else 0.0), node[1])
    return out


# -------------------------------------------------------------------------------------- main
def bench_volume(name: str, image, size, frames: int, threads: int, backend: str = "cpu",
                 curve_points=CURVE, transfer=None) -> tuple[list, dict]:
    sp = np.abs(np.array(image.GetSpacing()))
    unit = float(sp.mean())
    sd = 0.5 * float(sp.min())  # matched sample distance: half the smallest spacing
    ctf, otf = transfer() if transfer else default_transfer_functions(image)
    cam = frame_camera(image)
    ours, vtk = Ours(image, ctf, otf, unit, size, cam), Vtk(image, ctf, otf, unit, size, cam, sd)
    ours.c.SetNumberOfThreads(threads)
    c = ours.c
    matched = dict(SampleDistance=sd, DoublePrecision=False, EarlyTerminationThreshold=0.99)
    # First frames: ours classifies and stores the volume, VTK builds its min/max volume and tables.
    first_ours, _ = ours.frame(**matched)
    first_vtk, _ = vtk.frame()
    bytes_info = dict(blocks_allocated=c.GetNumberOfAllocatedBlocks(), blocks_dense=c.GetNumberOfDenseBlocks(),
                      bytes=c.GetAllocatedBytes(), visible_block_bytes=c.GetVisibleBlockBytes(),
                      dense_bytes=c.GetDenseBytes(), build_ms=c.GetLastBuildTime(),
                      quantization_step=c.GetQuantizationStep())
    ref_ms, ref = ours.frame(SampleDistance=float(sp.min()) / 16, DoublePrecision=True,
                             EarlyTerminationThreshold=1.0)
    vtk.frame()
    ours.frame(**matched)
    dev = None
    if backend != "cpu":
        # Our OpenCL backend: its own filter (classified once, uploaded once), warmed up so that
        # the kernel compile and the upload are not timed; frames interleaved with the CPU's.
        dev = Ours(image, ctf, otf, unit, size, cam)
        dev.c.SetNumberOfThreads(threads)
        dev.c.SetBackendToOpenCL()
        dev.frame(**matched)
        if dev.c.GetOutput().GetPointData().GetArray("RGBAFloat") is None:
            raise RuntimeError("the OpenCL backend failed (see the VTK error above); run with --backend cpu")
    t_vtk, t_ours, t_dev = [], [], []
    for _ in range(frames):  # interleaved, so load from other processes hits both alike
        ms, img_vtk = vtk.frame()
        t_vtk.append(ms)
        ms, img_ours = ours.frame(**matched)
        t_ours.append(ms)
        if dev is not None:
            ms, img_dev = dev.frame(**matched)
            t_dev.append(ms)
    samples = c.GetNumberOfSamples()
    # CPU time per frame with one thread each (VTK's mapper through its own thread count).
    vtk_threads = vtk.mapper.GetNumberOfThreads()
    vtk.mapper.SetNumberOfThreads(1)
    ours.c.SetNumberOfThreads(1)
    vtk.frame()
    ours.frame(**matched)
    c_vtk, c_ours = [], []
    for _ in range(frames):
        vtk.frame()
        c_vtk.append(vtk.cpu_ms)
        ours.frame(**matched)
        c_ours.append(ours.cpu_ms)
    vtk.mapper.SetNumberOfThreads(vtk_threads)
    ours.c.SetNumberOfThreads(threads)
    # Frames after the first: a camera move (no reclassification), an opacity change (ours
    # reclassifies); all threads, interleaved, alternating between two cameras / two functions.
    from vtkmodules.vtkRenderingCore import vtkCamera

    cams = []
    for a in (10.0, -10.0):
        cm = vtkCamera()
        cm.DeepCopy(cam)
        cm.Azimuth(a)
        cams.append(cm)
    rng = image.GetPointData().GetScalars().GetRange()
    otfs = [opacity_shifted(otf, rng[0], rng[1], f) for f in (0.02, 0.0)]

    def alternating(change) -> tuple[float, float, list]:
        """Median VTK and our frame times, interleaved, with change(i % 2) before frame i; and
        whether each of our frames reclassified."""
        t_vtk, t_ours, rebuilt = [], [], []
        for i in range(frames):
            change(i % 2)
            t_vtk.append(vtk.frame()[0])
            t_ours.append(ours.frame(**matched)[0])
            rebuilt.append(c.GetLastRebuilt())
        return statistics.median(t_vtk), statistics.median(t_ours), rebuilt

    def set_camera(i: int) -> None:
        c.SetCamera(cams[i])
        vtk.ren.SetActiveCamera(cams[i])

    def set_opacity(i: int) -> None:
        c.SetScalarOpacity(otfs[i])
        vtk.prop.SetScalarOpacity(otfs[i])

    *camera_ms, rebuilt = alternating(set_camera)
    if any(rebuilt):
        raise RuntimeError("a camera move reclassified the volume")
    c.SetCamera(cam)
    vtk.ren.SetActiveCamera(cam)
    *tf_ms, rebuilt = alternating(set_opacity)
    if not all(rebuilt):
        raise RuntimeError("an opacity change should reclassify the volume")
    c.SetScalarOpacity(otf)
    vtk.prop.SetScalarOpacity(otf)
    later = dict(first_ms=(first_vtk, first_ours), camera_ms=tuple(camera_ms), tf_ms=tuple(tf_ms))
    dims = "x".join(str(d) for d in image.GetDimensions())
    base = dict(volume=name, dims=dims, width=size[0], height=size[1], sample_distance=sd)
    rows = []
    ms_vtk, ms_ours = statistics.median(t_vtk), statistics.median(t_ours)
    cpu_vtk, cpu_ours = statistics.median(c_vtk), statistics.median(c_ours)
    frames_vtk = {k: v[0] for k, v in later.items()}
    frames_ours = dict({k: v[1] for k, v in later.items()},
                       **{k.replace("_ms", "_speedup"): v[0] / v[1] for k, v in later.items()})
    visible_voxels = max(1, bytes_info["blocks_allocated"]) * 512
    rows.append(dict(base, renderer="vtkFixedPointVolumeRayCastMapper", ms=ms_vtk, speedup=1.0, **frames_vtk,
                     cpu_ms_1t=cpu_vtk, cpu_speedup_1t=1.0, storage=image.GetPointData().GetScalars().GetDataTypeAsString(),
                     ssim_vs_vtk=1.0, psnr_vs_vtk=None, psnr_vs_reference=psnr(img_vtk, ref),
                     blocks_allocated=bytes_info["blocks_dense"], blocks_dense=bytes_info["blocks_dense"],
                     bytes=int(image.GetPointData().GetScalars().GetDataSize() *
                               image.GetPointData().GetScalars().GetDataTypeSize())))
    rows.append(dict(base, renderer="matrixtree", ms=ms_ours, speedup=ms_vtk / ms_ours, **frames_ours,
                     bytes_per_visible_voxel=bytes_info["bytes"] / visible_voxels,
                     quantization_step=bytes_info["quantization_step"],
                     cpu_ms_1t=cpu_ours, cpu_speedup_1t=cpu_vtk / cpu_ours,
                     storage=("float32", "uint8", "uint16")[c.GetVoxelStorage()],
                     ssim_vs_vtk=ssim(img_ours, img_vtk), psnr_vs_vtk=psnr(img_ours, img_vtk),
                     psnr_vs_reference=psnr(img_ours, ref), samples=samples,
                     **{k: bytes_info[k] for k in ("blocks_allocated", "blocks_dense", "bytes",
                                                   "visible_block_bytes", "dense_bytes", "build_ms")}))
    if dev is not None:
        ms_dev = statistics.median(t_dev)
        rows.append(dict(base, renderer="matrixtree-opencl", ms=ms_dev, speedup=ms_vtk / ms_dev,
                         storage=("float32", "uint8", "uint16")[dev.c.GetVoxelStorage()],
                         ssim_vs_vtk=ssim(img_dev, img_vtk), psnr_vs_vtk=psnr(img_dev, img_vtk),
                         psnr_vs_reference=psnr(img_dev, ref), samples=dev.c.GetNumberOfSamples(),
                         max_diff_vs_cpu=float(np.abs(img_dev - img_ours).max()),
                         device=dev.c.GetOpenCLDeviceName(), uploads=dev.c.GetNumberOfOpenCLUploads(),
                         blocks_allocated=bytes_info["blocks_allocated"], blocks_dense=bytes_info["blocks_dense"],
                         bytes=bytes_info["bytes"]))
    curve = []
    for f in curve_points:
        times = []
        for _ in range(max(1, frames // 2)):
            ms, img = ours.frame(SampleDistance=f * float(sp.min()))
            times.append(ms)
        curve.append(dict(volume=name, renderer="matrixtree-curve", sample_distance_voxels=f,
                          sample_distance=f * float(sp.min()), ms=statistics.median(times),
                          psnr_vs_reference=psnr(img, ref), ssim_vs_vtk=ssim(img, img_vtk),
                          blocks_allocated=bytes_info["blocks_allocated"], blocks_dense=bytes_info["blocks_dense"],
                          bytes=bytes_info["bytes"]))
    rows[1]["reference_ms"] = ref_ms
    return rows + curve, dict(name=name, ours=img_ours, vtk=img_vtk, ref=ref)


def write_docs(md_path: str, rows: list, pictures: list, args, cmd: str) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    img_dir = os.path.join(os.path.dirname(os.path.abspath(md_path)), "images")
    os.makedirs(img_dir, exist_ok=True)
    vols = sorted({r["volume"] for r in rows})
    fig, ax = plt.subplots(figsize=(7.5, 4.5))
    for i, v in enumerate(vols):
        col = f"C{i}"
        cur = [r for r in rows if r["volume"] == v and r["renderer"] == "matrixtree-curve"]
        ax.plot([r["ms"] for r in cur], [r["psnr_vs_reference"] for r in cur], "o-", color=col, label=v)
        vr = [r for r in rows if r["volume"] == v and r["renderer"] == "vtkFixedPointVolumeRayCastMapper"][0]
        ax.plot([vr["ms"]], [vr["psnr_vs_reference"]], "x", color=col, markersize=10, mew=2)
    ax.set_xscale("log")
    ax.set_xlabel("ms per frame (log)")
    ax.set_ylabel("PSNR vs 1/16-voxel reference (dB)")
    ax.set_title("Sample distance 2 .. 1/8 voxel (dots, ours) vs vtkFixedPoint at 1/2 voxel (x)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    chart = os.path.join(img_dir, "volume_speed_accuracy.png")
    fig.savefig(chart, dpi=110)
    plt.close(fig)

    fig, axes = plt.subplots(2, len(pictures), figsize=(2.4 * len(pictures), 5))
    axes = np.array(axes).reshape(2, -1)
    for j, p in enumerate(pictures):
        for i, (key, label) in enumerate((("ours", "matrixtree"), ("vtk", "vtkFixedPoint"))):
            axes[i, j].imshow(np.clip(p[key][::-1, :, :3], 0, 1))
            axes[i, j].set_title(f"{p['name']}: {label}", fontsize=7)
            axes[i, j].axis("off")
    fig.tight_layout()
    pics = os.path.join(img_dir, "volume_compare.png")
    fig.savefig(pics, dpi=100)
    plt.close(fig)

    main = [r for r in rows if r["renderer"] != "matrixtree-curve"]
    cols = ["volume", "dims", "renderer", "ms", "speedup", "cpu_ms_1t", "cpu_speedup_1t", "ssim_vs_vtk",
            "psnr_vs_vtk", "psnr_vs_reference", "storage", "blocks_allocated", "blocks_dense", "bytes"]
    if args.backend != "cpu":
        cols.append("max_diff_vs_cpu")
    curve = [r for r in rows if r["renderer"] == "matrixtree-curve"]
    ccols = ["volume", "sample_distance_voxels", "ms", "psnr_vs_reference", "ssim_vs_vtk"]
    mem = [dict(volume=r["volume"], storage=r["storage"], quantization_step=r["quantization_step"],
                blocks_allocated=r["blocks_allocated"], blocks_dense=r["blocks_dense"],
                visible_block_bytes=r["visible_block_bytes"], bytes=r["bytes"], dense_bytes=r["dense_bytes"],
                bytes_per_visible_voxel=r["bytes_per_visible_voxel"],
                overhead_vs_visible=r["bytes"] / max(1, r["visible_block_bytes"]) - 1, build_ms=r["build_ms"])
           for r in rows if r["renderer"] == "matrixtree"]
    mcols = ["volume", "storage", "quantization_step", "blocks_allocated", "blocks_dense", "visible_block_bytes",
             "bytes", "dense_bytes", "bytes_per_visible_voxel", "overhead_vs_visible", "build_ms"]
    later = [r for r in rows if r["renderer"] in ("vtkFixedPointVolumeRayCastMapper", "matrixtree")]
    lcols = ["volume", "dims", "renderer", "first_ms", "first_speedup", "ms", "camera_ms", "camera_speedup", "tf_ms",
             "tf_speedup"]
    m = machine()
    with open(md_path, "w") as f:
        f.write("# Volume ray casting: matrixtree vs vtkFixedPointVolumeRayCastMapper\n\n")
        f.write(f"Produced by `{cmd}` on {m['cores']} cores ({m['cpu']}), Python {m['python']}, "
                f"{args.size[0]}x{args.size[1]} pixels. Both renderers run in one process with the same "
                "transfer functions (`matrixtree.default_transfer_functions`; the phantoms: bench/ct_phantom.py's "
                "CT preset), camera "
                "(`matrixtree.frame_camera`), sample distance (half the smallest spacing), linear "
                "interpolation, no shading, opacity unit distance = mean spacing; frames are interleaved "
                f"(VTK, ours, VTK, ...), {args.frames} each, median reported. VTK renders off-screen "
                "under Xvfb and its time includes the blit into the window. The machine is shared, so "
                "wall times are noisy; `cpu_ms_1t` (process CPU time per frame with both renderers "
                "limited to one thread, also interleaved) is the robust comparison.\n\n")
        f.write("![speed vs accuracy](images/volume_speed_accuracy.png)\n\n")
        f.write("![ours (top) and VTK (bottom)](images/volume_compare.png)\n\n")
        f.write("## Matched settings\n\n`speedup` = VTK ms / our ms (wall, all threads); `cpu_speedup_1t` = "
                "VTK CPU ms / our CPU ms, one thread each. `storage`: how our voxels are held (VTK: its "
                "input type). `psnr_vs_reference`: against our "
                "renderer at 1/16 of the smallest spacing in double precision without early termination. "
                "VTK's `bytes` is its input scalars. Our renderer against its own alternatives (skipping "
                "off, dense storage, the SSE2 marcher): `build/bin/volume_ab`.\n\n")
        f.write(markdown(main, cols) + "\n\n")
        f.write("## Memory\n\n`visible_block_bytes`: the 8^3-voxel float blocks holding a corner of a "
                "cell the opacity function can show (the float block-sparse encoding; the target is "
                "`bytes` <= 1.10 x this). `bytes`: everything held: for `float32` those blocks plus the "
                "pointer matrix, per-brick value ranges and matrix-tree levels; for `uint8`/`uint16` "
                "(8/16-bit input, or float input holding only integers: lossless) the visible bricks of "
                "8^3 cells as 9^3 voxels (a 1-voxel apron) in that width (8-bit bricks of grids of at most "
                "4096 bricks in rows of y pairs, 1296 bytes a brick, so that a cell's 4 corners in a z plane "
                "are 4 consecutive bytes), their pointers and 512-bit visible-cell masks, the ranges "
                "and the levels. `dense_bytes`: all voxels as float.\n\n")
        f.write(markdown(mem, mcols) + "\n\n")
        f.write("## Frames after the first\n\n`first_ms`: the first frame (ours: classification and storage "
                "included; VTK: its min/max volume and tables); `ms`: the matched frame above; `camera_ms`: the "
                "median frame after a camera move (azimuth +/-10 degrees, alternating; ours does not reclassify); "
                "`tf_ms`: the median frame after an opacity change (ramp start moved by 2% of the range, "
                "alternating; ours reclassifies the volume). `*_speedup` = VTK ms / our ms. Wall clock, all "
                "threads.\n\n")
        f.write(markdown(later, lcols) + "\n\n")
        f.write("## Speed/accuracy curve (ours)\n\nSample distance in units of the smallest spacing.\n\n")
        f.write(markdown(curve, ccols) + "\n")
    print(f"wrote {md_path}, {chart}, {pics}")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--volume", action="append", help="volume file (repeatable); default: every volume in "
                    "../shared/data/volumes")
    ap.add_argument("--size", nargs=2, type=int, default=[512, 512], metavar=("W", "H"))
    ap.add_argument("--frames", type=int, default=5, help="timed frames per renderer (default 5)")
    ap.add_argument("--threads", type=int, default=0, help="our OpenMP threads (0 = all)")
    ap.add_argument("--backend", choices=("cpu", "opencl", "all"), default="cpu",
                    help="cpu (default): our OpenMP marcher; opencl or all: also our OpenCL backend (row "
                    "matrixtree-opencl, frames interleaved with the others, its image compared with our CPU "
                    "image: max_diff_vs_cpu). The CPU rows stay in both: they are the device's reference")
    ap.add_argument("--json", default=os.path.join(ROOT, "out", "volume.json"))
    ap.add_argument("--md", default=None, help="write the markdown report (and its pictures in images/ beside it)")
    ap.add_argument("--phantom", type=int, action="append", default=[],
                    help="add bench/ct_phantom.py's CT-like volume at N^3 points, float32 and uint16 (repeatable; "
                    "default: 128 unless --volume is given)")
    ap.add_argument("--upsample", type=int, default=0, help="add headsq upsampled K times per axis")
    ap.add_argument("--large", action="store_true", help="add --phantom 512 --upsample 6")
    ap.add_argument("--no-files", action="store_true", help="only the generated volumes")
    args = ap.parse_args()
    args.paths = [] if args.no_files else (
        args.volume or sorted(p for p in glob.glob(os.path.join(scenes.data_dir(), "volumes", "*"))
                              if not p.endswith(".raw")))
    if not args.phantom and not args.volume:
        args.phantom = [128]
    if args.large:
        args.phantom = sorted(set(args.phantom) | {512})
        args.upsample = args.upsample or 6
    rows, pictures = [], []
    for name, load, transfer in volumes(args):
        print(f"[volume] {name}", flush=True)
        image = load()
        small = name in [os.path.basename(p).split(".")[0] for p in args.paths] or image.GetNumberOfPoints() < 256 ** 3
        r, pic = bench_volume(name, image, tuple(args.size), args.frames, args.threads, args.backend,
                              CURVE if small else (), transfer)
        del image
        rows += r
        pictures.append(pic)
        print(table([x for x in r if x["renderer"] != "matrixtree-curve"],
                    ["volume", "renderer", "ms", "speedup", "cpu_ms_1t", "cpu_speedup_1t", "ssim_vs_vtk",
                     "psnr_vs_reference", "first_ms", "camera_ms", "tf_ms", "storage", "bytes"] +
                    (["max_diff_vs_cpu"] if args.backend != "cpu" else [])),
              flush=True)
    print()
    print(table(rows, ["volume", "renderer", "sample_distance", "ms", "speedup", "ssim_vs_vtk", "psnr_vs_reference",
                       "blocks_allocated", "blocks_dense", "bytes"]))
    write_json(args.json, dict(machine=machine(), size=args.size, frames=args.frames, rows=rows))
    print(f"\nwrote {args.json}")
    if args.md:
        cmd = "xvfb-run -a .venv/bin/python bench/" + " ".join([os.path.basename(sys.argv[0])] + sys.argv[1:])
        write_docs(args.md, rows, pictures, args, cmd)
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""vtkMatrixTreeVolumeRayCaster and matrixtree.render_volume: analytic transmittance, storage
invariants through the VTK class, VTK's fixed-point ray caster as reference, bad input. The
checks against the C++-only developer settings (skipping off, dense storage, the SSE2 marcher)
are in tests/cpp/test_volume_filter.cpp."""

import os

import numpy as np
import pytest
from vtkmodules.util.numpy_support import vtk_to_numpy
from vtkmodules.vtkCommonDataModel import vtkImageData, vtkPiecewiseFunction
from vtkmodules.vtkRenderingCore import vtkCamera, vtkColorTransferFunction

import matrixtree
from matrixtree_vtk import vtkMatrixTreeVolumeRayCaster

VOLUMES = os.path.join(matrixtree.scenes.data_dir(), "volumes")


def _constant_tf(alpha):
    ctf = vtkColorTransferFunction()
    ctf.AddRGBPoint(0.0, 1, 1, 1)
    ctf.AddRGBPoint(2.0, 1, 1, 1)
    otf = vtkPiecewiseFunction()
    otf.AddPoint(0.0, alpha)
    otf.AddPoint(2.0, alpha)
    return ctf, otf


def _camera(pos, focal, up=(0, 1, 0)):
    cam = vtkCamera()
    cam.SetPosition(*pos)
    cam.SetFocalPoint(*focal)
    cam.SetViewUp(*up)
    return cam


def test_constant_box_transmittance_through_vtk_class():
    sigma = 0.4
    vol = np.ones((9, 5, 5), dtype=np.float32)  # x in [0, 8] at spacing 0.5 -> [0, 4]
    ctf, otf = _constant_tf(1 - np.exp(-sigma))
    img = matrixtree.render_volume(vol, spacing=(0.5, 1, 1), size=(1, 1), color=ctf, opacity=otf,
                                   camera=_camera((-3, 2, 2), (10, 2, 2)), sample_distance=1e-3,
                                   opacity_unit_distance=1.0, early_termination=1.0)
    assert abs((1 - img[0, 0, 3]) - np.exp(-sigma * 4.0)) < 1e-3


def test_numpy_and_vtk_image_inputs_agree_and_any_scalar_type():
    x, y, z = np.mgrid[0:1:20j, 0:1:24j, 0:1:16j]
    f = (100 * (x * y + z)).astype(np.int16)
    cam = _camera((-2, 0.5, 0.5), (0.5, 0.5, 0.5), (0, 0, 1))
    sp = (1 / 19, 1 / 23, 1 / 15)
    a = matrixtree.render_volume(f, spacing=sp, size=(32, 32), camera=cam, sample_distance=0.01)
    b = matrixtree.render_volume(f.astype(np.float64), spacing=sp, size=(32, 32), camera=cam, sample_distance=0.01)
    assert np.abs(a - b).max() < 1e-5
    assert a[..., 3].max() > 0.1


def test_close_to_vtk_fixed_point_ray_caster():
    """VTK's own ray caster as the reference image (needs an X display: xvfb-run)."""
    pytest.importorskip("vtkmodules.vtkRenderingVolumeOpenGL2")
    if not os.environ.get("DISPLAY"):
        pytest.skip("no X display (run pytest under xvfb-run)")
    import vtkmodules.vtkRenderingOpenGL2  # noqa: F401
    import vtkmodules.vtkRenderingVolumeOpenGL2  # noqa: F401
    from vtkmodules.vtkRenderingCore import (vtkRenderer, vtkRenderWindow, vtkVolume, vtkVolumeProperty,
                                             vtkWindowToImageFilter)
    from vtkmodules.vtkRenderingVolume import vtkFixedPointVolumeRayCastMapper

    im = matrixtree.read_volume(os.path.join(VOLUMES, "ironProt.vtk"))
    ctf, otf = matrixtree.default_transfer_functions(im)
    cam = matrixtree.frame_camera(im)
    w, h, sd = 96, 80, 0.5
    ours = matrixtree.render_volume(im, size=(w, h), camera=cam, color=ctf, opacity=otf, sample_distance=sd,
                                    opacity_unit_distance=1.0)
    mapper = vtkFixedPointVolumeRayCastMapper()
    mapper.SetInputData(im)
    mapper.AutoAdjustSampleDistancesOff()
    mapper.SetSampleDistance(sd)
    mapper.SetImageSampleDistance(1.0)
    prop = vtkVolumeProperty()
    prop.SetColor(ctf)
    prop.SetScalarOpacity(otf)
    prop.SetInterpolationTypeToLinear()
    vol = vtkVolume()
    vol.SetMapper(mapper)
    vol.SetProperty(prop)
    ren = vtkRenderer()
    ren.AddVolume(vol)
    ren.SetActiveCamera(cam)
    ren.ResetCameraClippingRange()
    win = vtkRenderWindow()
    win.SetOffScreenRendering(1)
    win.SetSize(w, h)
    win.AddRenderer(ren)
    win.Render()
    grab = vtkWindowToImageFilter()
    grab.SetInput(win)
    grab.SetInputBufferTypeToRGB()
    grab.ReadFrontBufferOff()
    grab.Update()
    ref = vtk_to_numpy(grab.GetOutput().GetPointData().GetScalars()).reshape(h, w, 3)[::-1] / 255.0
    diff = np.abs(np.clip(ours[..., :3], 0, 1) - ref)
    psnr = 10 * np.log10(1.0 / np.mean(diff ** 2))
    assert ref.mean() > 0.02, "VTK's image should not be empty"
    assert psnr > 30, f"PSNR vs vtkFixedPointVolumeRayCastMapper {psnr:.1f} dB"


def test_bad_input_raises_clear_errors():
    with pytest.raises(ValueError, match="at least 2"):
        matrixtree.render_volume(np.ones((10, 10, 1)), size=(8, 8))
    with pytest.raises(ValueError, match="empty"):
        matrixtree.render_volume(np.ones((0, 3, 3)), size=(8, 8))
    with pytest.raises(ValueError, match="spacing"):
        matrixtree.render_volume(np.ones((4, 4, 4)), spacing=(1, 0, 1), size=(8, 8))
    with pytest.raises(ValueError, match="3-D"):
        matrixtree.render_volume(np.ones((4, 4)), size=(8, 8))
    im = vtkImageData()
    im.SetDimensions(4, 4, 4)
    im.AllocateScalars(10, 3)  # float, 3 components
    with pytest.raises(ValueError, match="component"):
        matrixtree.render_volume(im, size=(8, 8))


def test_nan_scalars_render_finite():
    v = np.ones((6, 6, 6), dtype=np.float32)
    v[2, 3, 1] = np.nan
    img, st = matrixtree.render_volume(v, size=(16, 16), return_stats=True)
    assert np.isfinite(img).all()
    assert st["non_finite"] == 1


def test_vtk_class_reports_errors_without_crashing():
    c = vtkMatrixTreeVolumeRayCaster()
    im = vtkImageData()  # empty
    c.SetInputData(im)
    c.GlobalWarningDisplayOff()
    try:
        c.Update()
    finally:
        c.GlobalWarningDisplayOn()
    assert c.GetOutput().GetPointData().GetArray("RGBA") is None
    assert "ScalarOpacityUnitDistance" in str(c)


def test_compact_storage_is_chosen_and_matches_float_storage():
    """8-bit input (and integer-valued float input) is held in 8/16-bit apron bricks; the image
    matches the rendering of the same values shifted by 0.25 (opacity shifted too), which are not
    integers: quantised into 16-bit bricks (255 / 65535 steps: 0.25 + k exactly)."""
    im = matrixtree.read_volume(os.path.join(VOLUMES, "HeadMRVolume.mhd"))
    common = dict(size=(40, 40), camera=matrixtree.frame_camera(im))
    a, sa = matrixtree.render_volume(im, return_stats=True, **common)
    assert sa["storage"] == "uint8"
    assert sa["bytes"] <= 1.10 * sa["visible_block_bytes"]
    arr = vtk_to_numpy(im.GetPointData().GetScalars()).astype(np.float64)
    arr = arr.reshape(tuple(reversed(im.GetDimensions()))).transpose(2, 1, 0)
    b, sb = matrixtree.render_volume(arr + 0.25, spacing=im.GetSpacing(), origin=im.GetOrigin(), return_stats=True,
                                     color=matrixtree.default_transfer_functions(im)[0],
                                     opacity=_shifted(matrixtree.default_transfer_functions(im)[1], 0.25), **common)
    assert sb["storage"] == "uint16"
    assert np.abs(a - b).max() < 2e-3
    c, sc = matrixtree.render_volume(arr, spacing=im.GetSpacing(), origin=im.GetOrigin(), return_stats=True,
                                     **common)
    assert sc["storage"] == "uint8"  # float64 holding integers 0..255: lossless
    assert np.abs(a - c).max() < 1e-6


def _shifted(otf, delta):
    out = vtkPiecewiseFunction()
    for i in range(otf.GetSize()):
        node = [0.0] * 4
        otf.GetNodeValue(i, node)
        out.AddPoint(node[0] + delta, node[1], node[2], node[3])
    return out


def test_filter_output_arrays_are_reused_only_when_nobody_holds_them():
    """The filter keeps its output arrays across renders and writes the next frame into them,
    unless something else still holds them: an array taken from an earlier output keeps its image."""
    im = matrixtree.read_volume(os.path.join(VOLUMES, "HeadMRVolume.mhd"))
    ctf, otf = matrixtree.default_transfer_functions(im)
    cams = [matrixtree.frame_camera(im), matrixtree.frame_camera(im, azimuth=120, elevation=-30)]

    def caster():
        c = vtkMatrixTreeVolumeRayCaster()
        c.SetInputData(im)
        c.SetColorTransferFunction(ctf)
        c.SetScalarOpacity(otf)
        c.SetImageSize(40, 32)
        return c

    def frame(c, cam):
        c.SetCamera(cam)
        c.Update()
        return c.GetOutput().GetPointData().GetArray("RGBAFloat")

    # Nobody holds the arrays between frames: reused, and each frame equals a fresh filter's.
    c = caster()
    images = [vtk_to_numpy(frame(c, cam)).copy() for cam in cams + cams]
    for cam, img in zip(cams, images[:2]):
        assert np.array_equal(img, vtk_to_numpy(frame(caster(), cam)))
    assert np.array_equal(images[0], images[2]) and np.array_equal(images[1], images[3])
    assert not np.array_equal(images[0], images[1])
    assert images[0][:, 3].max() > 0.05
    # An array held from an earlier frame is not written by the next one.
    held = frame(c, cams[0])
    before = vtk_to_numpy(held).copy()
    after = frame(c, cams[1])
    assert np.array_equal(vtk_to_numpy(held), before)
    assert not np.array_equal(vtk_to_numpy(after), before)


def test_filter_8bit_output_is_the_float_image_rounded():
    """The RGBA scalars (unsigned char) are the RGBAFloat image clamped to [0, 1], times 255, plus
    0.5, truncated (in float): checked against that formula in numpy for every value, at a size
    whose value count is not a multiple of the converter's 16-value steps (37 x 23 x 4)."""
    im = matrixtree.read_volume(os.path.join(VOLUMES, "HeadMRVolume.mhd"))
    ctf, otf = matrixtree.default_transfer_functions(im, max_opacity=0.9)
    c = vtkMatrixTreeVolumeRayCaster()
    c.SetInputData(im)
    c.SetColorTransferFunction(ctf)
    c.SetScalarOpacity(otf)
    c.SetImageSize(37, 23)
    c.SetCamera(matrixtree.frame_camera(im))
    c.Update()
    pd = c.GetOutput().GetPointData()
    f = vtk_to_numpy(pd.GetArray("RGBAFloat")).astype(np.float32).ravel()
    u = vtk_to_numpy(pd.GetArray("RGBA")).ravel()
    v = np.minimum(np.float32(1), np.maximum(np.float32(0), f))
    expected = (v * np.float32(255) + np.float32(0.5)).astype(np.uint8)
    assert f.size == 37 * 23 * 4 and f.size % 16 != 0
    assert np.array_equal(u, expected)
    assert len(np.unique(u)) > 50  # many levels, not just 0 and 255


def _opencl_platform_count() -> int:
    import ctypes
    import ctypes.util
    try:
        lib = ctypes.CDLL(ctypes.util.find_library("OpenCL") or "libOpenCL.so.1")
    except OSError:
        return 0
    n = ctypes.c_uint(0)
    return n.value if lib.clGetPlatformIDs(0, None, ctypes.byref(n)) == 0 else 0


@pytest.mark.skipif(_opencl_platform_count() == 0, reason="no OpenCL platform")
@pytest.mark.parametrize("name, paired", [("HeadMRVolume.mhd", True), ("embryo.slc", False)])
def test_both_8bit_brick_layouts_render_alike_on_cpu_and_opencl(name, paired):
    """8-bit bricks are held in rows of y pairs on grids of at most 4096 level-0 bricks
    (HeadMRVolume: 6 x 8 x 6) and x fastest beyond (embryo: 32^3); the OpenCL kernel derives the
    layout from the dimensions as the host does, and gives the CPU's image and samples."""
    im = matrixtree.read_volume(os.path.join(VOLUMES, name))
    nb = [(d - 1 + 7) // 8 for d in im.GetDimensions()]
    assert (nb[0] * nb[1] * nb[2] <= 4096) == paired
    cam = matrixtree.frame_camera(im, azimuth=40, elevation=25)
    a, sa = matrixtree.render_volume(im, size=(64, 56), camera=cam, return_stats=True)
    b, sb = matrixtree.render_volume(im, size=(64, 56), camera=cam, backend="opencl", return_stats=True)
    assert sa["storage"] == sb["storage"] == "uint8"
    assert a[..., 3].mean() > 0.02
    assert np.abs(a - b).max() <= 1e-5, np.abs(a - b).max()
    assert (sa["samples"], sa["skips"]) == (sb["samples"], sb["skips"])


def test_volume_renderer_classifies_once_and_renders_as_render_volume():
    """A camera move and a colour change reuse the classification; an opacity change (in place)
    classifies again; every frame equals a fresh render_volume of the same inputs."""
    im = matrixtree.read_volume(os.path.join(VOLUMES, "ironProt.vtk"))
    ctf, otf = matrixtree.default_transfer_functions(im)
    r = matrixtree.VolumeRenderer(im, color=ctf, opacity=otf)
    cam = matrixtree.frame_camera(im)
    lo, hi = im.GetScalarRange()
    for step, rebuilt in enumerate((True, False, False, True)):
        if step == 1:
            cam.Azimuth(40)
        if step == 2:
            ctf.AddRGBPoint(0.5 * (lo + hi), 0.1, 0.9, 0.2)
        if step == 3:
            otf.AddPoint(0.7 * lo + 0.3 * hi, 0.15)
        img, st = r.render(camera=cam, size=(48, 40), return_stats=True)
        assert st["rebuilt"] == rebuilt, step
        ref = matrixtree.render_volume(im, camera=cam, size=(48, 40), color=ctf, opacity=otf)
        np.testing.assert_array_equal(img, ref)
        assert img[..., 3].max() > 0.1


def test_float_ct_phantom_is_quantised_and_close_to_vtk_fixed_point_ray_caster():
    """A CT-like float volume (bench/ct_phantom.py: noisy Hounsfield units) is held in 16-bit
    bricks; its image matches vtkFixedPointVolumeRayCastMapper's (SSIM) and is closer to a fine
    reference than VTK's is (PSNR)."""
    pytest.importorskip("vtkmodules.vtkRenderingVolumeOpenGL2")
    if not os.environ.get("DISPLAY"):
        pytest.skip("no X display (run pytest under xvfb-run)")
    import sys
    sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))),
                                    "bench"))
    from ct_phantom import ct_phantom, ct_transfer_functions, to_image
    from volume import Vtk, psnr, ssim

    im = to_image(ct_phantom(64, "float32", seed=3))
    ctf, otf = ct_transfer_functions("float32")
    cam = matrixtree.frame_camera(im)
    w, h, sd = 96, 96, 0.5
    ours, st = matrixtree.render_volume(im, size=(w, h), camera=cam, color=ctf, opacity=otf, sample_distance=sd,
                                        opacity_unit_distance=1.0, return_stats=True)
    assert st["storage"] == "uint16" and 0 < st["quantization_step"] < 0.1
    assert st["bytes"] <= 1.10 * st["visible_block_bytes"]
    fine = matrixtree.render_volume(im, size=(w, h), camera=cam, color=ctf, opacity=otf, sample_distance=sd / 16,
                                    opacity_unit_distance=1.0, double_precision=True, early_termination=1.0)
    _, ref = Vtk(im, ctf, otf, 1.0, (w, h), cam, sd).frame()
    ours, fine = np.clip(ours, 0, 1)[::-1], np.clip(fine, 0, 1)[::-1]  # row 0 at the bottom, as VTK's
    assert ref[..., :3].mean() > 0.02, "VTK's image should not be empty"
    assert ssim(ours, ref) > 0.97  # the gap is VTK's: it is the farther of the two from the reference
    assert psnr(ours, fine) > psnr(ref, fine) + 3

"""A CT-like volume generated on the spot (no data file): a torso phantom in Hounsfield units.

Air (-1000) around an elliptic body of soft tissue (40) under a fat layer (-100), two lungs
(-850) holding vessels (40), a spine (cortical shell 1200 around marrow 300) and a contrast-filled
aorta (300), ribs (800) every few slices, a liver (60); edges blurred over about a voxel (partial
volume), and noise as a CT reconstruction leaves it: Gaussian, correlated in-plane (a [1 2 1]
filter along x and y), about 15 HU standard deviation. ``float32`` keeps the noisy values as they
are (not integer-valued); ``uint16`` stores HU + 1024 clipped to 0..4095, as CT scanners do.

Built slab by slab along z, so a 512^3 float volume needs about its own 0.5 GiB plus a slab.

    .venv/bin/python bench/ct_phantom.py 128 --dtype float32 --out out/phantom128.vti
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

NOISE_HU = 40.0  # white noise before the in-plane [1 2 1] x [1 2 1] filter: ~15 HU after it


def _inside(q: np.ndarray, edge: float) -> np.ndarray:
    """Fraction of a voxel inside the region q <= 1 (q: normalised ellipsoid radius squared),
    blurred over about a voxel: `edge` is the radius, in voxels, the boundary sits at."""
    return np.clip(0.5 - (np.sqrt(q) - 1.0) * edge, 0.0, 1.0)


def ct_phantom(n: int, dtype: str = "float32", seed: int = 0, slab: int = 16) -> np.ndarray:
    """The phantom on an n x n x n grid as a C-ordered array of shape (n, n, n) indexed [z, y, x]
    (x fastest in memory, as vtkImageData holds it); dtype ``float32`` (HU) or ``uint16``
    (HU + 1024, clipped to 0..4095)."""
    if n < 8:
        raise ValueError(f"the phantom needs n >= 8, got {n}")
    if dtype not in ("float32", "uint16"):
        raise ValueError(f"dtype must be float32 or uint16, got {dtype!r}")
    rng = np.random.default_rng(seed)
    out = np.empty((n, n, n), dtype=np.dtype(dtype))
    c = (n - 1) / 2.0
    u = (np.arange(n, dtype=np.float32) - c) / n  # -0.5 .. 0.5 across the grid
    y, x = np.meshgrid(u, u, indexing="ij")
    for z0 in range(0, n, slab):
        z = u[z0:z0 + slab, None, None]
        hu = np.full((z.shape[0], n, n), -1000.0, dtype=np.float32)

        def put(region: np.ndarray, value: float) -> None:
            hu[...] += region * (value - hu)

        # the body and its fat layer, narrowing a little towards the ends
        taper = 1.0 - 0.25 * (z / 0.5) ** 2
        ax, ay = 0.42 * taper, 0.30 * taper
        put(_inside((x / ax) ** 2 + (y / ay) ** 2 + (z / 0.48) ** 8, 0.30 * n), -100.0)
        put(_inside((x / (ax - 0.02)) ** 2 + (y / (ay - 0.02)) ** 2 + (z / 0.47) ** 8, 0.28 * n), 40.0)
        # the liver: a soft blob on one side
        put(_inside(((x + 0.14) / 0.13) ** 2 + ((y - 0.02) / 0.12) ** 2 + ((z + 0.18) / 0.2) ** 2, 0.12 * n), 60.0)
        # the lungs and the vessels in them
        for s in (-1.0, 1.0):
            lung = _inside(((x - 0.17 * s) / 0.14) ** 2 + ((y - 0.01) / 0.19) ** 2 + ((z - 0.12) / 0.28) ** 2, 0.14 * n)
            put(lung, -850.0)
            vessel = np.sin(37.0 * (x - 0.17 * s) + 11.0 * z) * np.sin(29.0 * y - 13.0 * z)
            put(lung * np.clip((vessel - 0.93) * 20.0, 0.0, 1.0), 40.0)
        # ribs: an elliptic ring every few slices
        ring = np.abs(np.sqrt((x / (ax - 0.03)) ** 2 + (y / (ay - 0.03)) ** 2) - 1.0)
        rib_z = np.clip((np.cos(2 * np.pi * z / 0.07) - 0.6) * 3.0, 0.0, 1.0) * (np.abs(z) < 0.3)
        put(np.clip(1.0 - ring * 0.35 * n / 1.5, 0.0, 1.0) * rib_z, 800.0)
        # the spine (cortical shell, marrow) and the aorta in front of it
        rs = ((x / 0.055) ** 2 + ((y + 0.21) / 0.055) ** 2) + 0 * z
        put(_inside(rs, 0.055 * n), 1200.0)
        put(_inside(rs / 0.6, 0.04 * n), 300.0)
        put(_inside((((x - 0.04) / 0.03) ** 2 + ((y + 0.12) / 0.03) ** 2) + 0 * z, 0.03 * n), 300.0)
        # reconstruction noise, correlated in-plane
        e = rng.standard_normal(hu.shape, dtype=np.float32) * np.float32(NOISE_HU)
        e[:, :, 1:-1] = 0.25 * e[:, :, :-2] + 0.5 * e[:, :, 1:-1] + 0.25 * e[:, :, 2:]
        e[:, 1:-1, :] = 0.25 * e[:, :-2, :] + 0.5 * e[:, 1:-1, :] + 0.25 * e[:, 2:, :]
        hu += e
        if dtype == "uint16":
            out[z0:z0 + slab] = np.clip(np.rint(hu + 1024.0), 0, 4095).astype(np.uint16)
        else:
            out[z0:z0 + slab] = hu
    return out


def ct_transfer_functions(dtype: str = "float32"):
    """A CT preset for the phantom (points in HU, + 1024 for uint16): air and lungs transparent,
    soft tissue faint, contrast and bone opaque. (vtkColorTransferFunction, vtkPiecewiseFunction)."""
    from vtkmodules.vtkCommonDataModel import vtkPiecewiseFunction
    from vtkmodules.vtkRenderingCore import vtkColorTransferFunction

    o = 1024.0 if dtype == "uint16" else 0.0
    otf = vtkPiecewiseFunction()
    for hu, a in ((-1200, 0.0), (-150, 0.0), (20, 0.01), (120, 0.03), (250, 0.25), (1300, 0.6)):
        otf.AddPoint(hu + o, a)
    ctf = vtkColorTransferFunction()
    for hu, r, g, b in ((-150, 0.5, 0.2, 0.1), (40, 0.85, 0.45, 0.35), (250, 1.0, 0.85, 0.7), (1300, 1.0, 1.0, 1.0)):
        ctf.AddRGBPoint(hu + o, r, g, b)
    return ctf, otf


def to_image(arr: np.ndarray, spacing=(1.0, 1.0, 1.0), origin=(0.0, 0.0, 0.0)):
    """A vtkImageData over `arr` ([z, y, x], C-ordered), the scalars copied."""
    from vtkmodules.util.numpy_support import numpy_to_vtk
    from vtkmodules.vtkCommonDataModel import vtkImageData

    im = vtkImageData()
    im.SetDimensions(arr.shape[2], arr.shape[1], arr.shape[0])
    im.SetSpacing(*spacing)
    im.SetOrigin(*origin)
    s = numpy_to_vtk(np.ascontiguousarray(arr).ravel(), deep=True)
    s.SetName("HU" if arr.dtype == np.float32 else "HU+1024")
    im.GetPointData().SetScalars(s)
    return im


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("n", type=int, help="points per axis")
    ap.add_argument("--dtype", choices=("float32", "uint16"), default="float32")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", required=True, help="a .vti file to write")
    args = ap.parse_args()
    from vtkmodules.vtkIOXML import vtkXMLImageDataWriter

    w = vtkXMLImageDataWriter()
    w.SetInputData(to_image(ct_phantom(args.n, args.dtype, args.seed)))
    w.SetFileName(args.out)
    if not w.Write():
        print(f"could not write {args.out}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())

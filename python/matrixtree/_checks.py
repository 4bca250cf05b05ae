"""Argument checks shared by the matrixtree front ends (the VTK-backed classes and functions, and
any other binding of the engine): every numeric setting against its range, image sizes against
the per-axis limit and the memory the images need, cameras, and the failure mode of a failed build.

Each check returns the normalized value or raises ValueError whose message names the argument,
the value given and the valid range. The limits match the VTK classes' (their RequestData refuses
the same values), so a setting refused here is never one the C++ side would take.

Not public API.
"""

from __future__ import annotations

import math
import numbers
import os

import numpy as np

#: Largest image side the ray casters render (vtkMatrixTreeRayCaster, vtkMatrixTreeVolumeRayCaster).
MAX_IMAGE_SIDE = 16384
#: Most samples one volume ray may take across the volume's diagonal (vtkMatrixTreeVolumeRayCaster).
MAX_SAMPLES_PER_RAY = 1 << 20
#: Most OpenMP threads a setting may ask for (the VTK classes' NumberOfThreads range).
MAX_THREADS = 4096


def integer(value, name: str, lo: int, hi: int, meaning: str = "") -> int:
    """``value`` as an int in [lo, hi]; integral floats (``2.0``) are accepted, bools are not."""
    ok = isinstance(value, (numbers.Integral, np.integer)) and not isinstance(value, (bool, np.bool_))
    if not ok and isinstance(value, (numbers.Real, np.floating)) and math.isfinite(value) and value == int(value):
        ok = True
    if not ok or not lo <= int(value) <= hi:
        extra = f" ({meaning})" if meaning else ""
        raise ValueError(f"{name} must be an integer in [{lo}, {hi}]{extra}, got {value!r}")
    return int(value)


def real(value, name: str, lo: float | None = None, hi: float | None = None, *, lo_open: bool = False,
         meaning: str = "") -> float:
    """``value`` as a finite float in [lo, hi] (``(lo, hi]`` with ``lo_open``); NaN and inf are
    refused."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = math.nan
    bad = not math.isfinite(v) or isinstance(value, (bool, np.bool_))
    if lo is not None:
        bad |= v <= lo if lo_open else v < lo
    if hi is not None:
        bad |= v > hi
    if bad:
        left = "(" if lo_open else "["
        rng = f"{left}{'-inf' if lo is None else f'{lo:g}'}, " + ("inf)" if hi is None else f"{hi:g}]")
        extra = f" ({meaning})" if meaning else ""
        raise ValueError(f"{name} must be a finite number in {rng}{extra}, got {value!r}")
    return v


def threads(value) -> int:
    """An OpenMP thread count: 0 (all) to MAX_THREADS."""
    return integer(value, "threads", 0, MAX_THREADS, "0 = all cores")


def available_memory() -> int | None:
    """Bytes the system can give this process now (Linux: MemAvailable), or None if unknown."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def image_size(size, bytes_per_pixel: int, name: str = "size") -> tuple[int, int]:
    """``(width, height)``, each in [1, MAX_IMAGE_SIDE], whose images (``bytes_per_pixel`` over all
    the arrays a render keeps at once) fit in the memory available now."""
    try:
        w, h = size
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be (width, height), got {size!r}") from None
    w = integer(w, f"{name}[0] (width)", 1, MAX_IMAGE_SIDE)
    h = integer(h, f"{name}[1] (height)", 1, MAX_IMAGE_SIDE)
    need = w * h * bytes_per_pixel
    have = available_memory()
    if have is not None and need > have:
        raise ValueError(f"{name} {w}x{h} needs about {need / 2**30:.1f} GiB for its image arrays "
                         f"({bytes_per_pixel} bytes per pixel) but only {have / 2**30:.1f} GiB of memory is "
                         "available: render a smaller image (or tiles of it)")
    return w, h


def vector3(value, name: str) -> np.ndarray:
    """Three finite floats."""
    try:
        v = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be three finite numbers, got {value!r}") from None
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise ValueError(f"{name} must be three finite numbers, got {value!r}")
    return v


def camera(position, focal_point, view_up, view_angle=None, name: str = "camera", up_along_view_ok: bool = False):
    """A pinhole camera's vectors as arrays (and the view angle): finite, the eye away from the
    focal point, the angle in [0.01, 179] degrees, and (unless ``up_along_view_ok``: the surface
    renderer then picks another up) the view up neither zero nor along the view direction."""
    p = vector3(position, f"{name} position")
    f = vector3(focal_point, f"{name} focal point")
    u = vector3(view_up, f"{name} view up")
    d = f - p
    dn = float(np.linalg.norm(d))
    if not dn > 0:
        raise ValueError(f"{name}: the position {tuple(p)} equals the focal point: no view direction")
    un = float(np.linalg.norm(u))
    if not up_along_view_ok and (not un > 0 or float(np.linalg.norm(np.cross(d / dn, u / un))) < 1e-12):
        raise ValueError(f"{name}: the view up {tuple(u)} is zero or along the view direction {tuple(d / dn)}")
    angle = None if view_angle is None else real(view_angle, f"{name} view angle", 0.01, 179.0,
                                                 meaning="degrees")
    return p, f, u, angle


"""Shared helpers of the benchmark programs: scenes, timing, tables, JSON."""

from __future__ import annotations

import json
import os
import platform
import statistics
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, os.path.join(ROOT, "python"))

import matrixtree  # noqa: E402
from matrixtree import scenes  # noqa: E402


def check_build_dir(build_dir: str | None) -> None:
    """Exits with a message unless matrixtree_vtk was imported from build_dir's python/ folder.

    A build tree without python/matrixtree_vtk/__init__.py (a partial build) is skipped by
    Python's import in favour of the package the .venv's .pth names: the benchmark would then
    measure that other build's library without saying so."""
    if not build_dir:
        return
    import matrixtree_vtk.MatrixTreeFilters as wrapped

    want = os.path.realpath(os.path.join(build_dir, "python"))
    got = os.path.realpath(wrapped.__file__)
    if not got.startswith(want + os.sep):
        raise SystemExit(f"--build-dir {build_dir}: matrixtree_vtk was imported from {got}, not from {want} "
                         "(is it a full build, with python/matrixtree_vtk/__init__.py?)")


def default_scene_paths() -> dict:
    """Every mesh in ../shared/data/meshes plus the Utah Hand and Ben scenes."""
    return scenes.real_scenes()


def load(path: str):
    return matrixtree.read_mesh(path)


MESH_EXTENSIONS = (".ply", ".obj", ".stl", ".vtp")


def read_any(path: str):
    """A surface as bench/locators.py gives it to the locators (triangle polydata), else a grid."""
    if os.path.splitext(path)[1].lower() in MESH_EXTENSIONS:
        return matrixtree.read_mesh(path)
    return matrixtree.read_grid(path)


def median_time_ms(fn, repeats: int) -> tuple[float, list]:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append((time.perf_counter() - t0) * 1e3)
    return statistics.median(times), times


def machine() -> dict:
    return {"cpu": platform.processor() or platform.machine(), "cores": os.cpu_count(),
            "python": platform.python_version()}


def require_driver(path: str) -> str:
    """``path`` if that C++ benchmark driver exists, else exits saying how to build it."""
    if not os.path.exists(path):
        raise SystemExit(f"{path} not found: the bench/cpp drivers are built with -DMATRIXTREE_BENCHMARKS=ON "
                         "(bash scripts/setup.sh configures build/ so)")
    return path


def fmt(v) -> str:
    """A table cell: floats to 3 significant digits (one decimal from 100 up), the rest as str."""
    if isinstance(v, float):
        return f"{v:.3g}" if abs(v) < 100 else f"{v:.1f}"
    return str(v)


def table(rows: list, cols: list) -> str:
    widths = [max(len(c), *(len(fmt(r.get(c, ""))) for r in rows)) for c in cols]
    out = ["  ".join(c.rjust(w) for c, w in zip(cols, widths)), "  ".join("-" * w for w in widths)]
    for r in rows:
        out.append("  ".join(fmt(r.get(c, "")).rjust(w) for c, w in zip(cols, widths)))
    return "\n".join(out)


def markdown(rows: list, cols: list) -> str:
    out = ["| " + " | ".join(cols) + " |", "|" + "|".join("---" for _ in cols) + "|"]
    for r in rows:
        out.append("| " + " | ".join(fmt(r.get(c, "")) for c in cols) + " |")
    return "\n".join(out)


def write_json(path: str, rows) -> None:
    os.makedirs(os.path.dirname(os.path.abspath(path)) or ".", exist_ok=True)
    with open(path, "w") as f:
        json.dump(rows, f, indent=1)


def print_rows(rows: list, json_path: str | None) -> None:
    """Print rows as a table with every key, in the order the keys first appear, and write them
    as JSON if a path is given."""
    keys = []
    for r in rows:
        keys += [k for k in r if k not in keys]
    print(table(rows, keys))
    if json_path:
        write_json(json_path, rows)


def write_outputs(json_path: str, payload, md_path: str | None, md_rows: list, md_cols: list) -> None:
    """Write the JSON results and, if asked, the markdown table; say where."""
    write_json(json_path, payload)
    print(f"\nwrote {json_path}")
    if md_path:
        with open(md_path, "w") as f:
            f.write(markdown(md_rows, md_cols) + "\n")
        print(f"wrote {md_path}")

#!/usr/bin/env python3
"""The locator's targets table from several bench/locators.py runs: per grid, one locator's ratios
to vtkStaticCellLocator (each computed within its run), as the median over the runs and their
range, in bold where the median meets the target.

    .venv/bin/python bench/locators_summary.py RUN.json [RUN2.json ...] [--locator NAME]
                                               [--previous OLD.json ...] [--targets shipped|generated]

Columns: FindCell (one-thread CPU time, target >= 5), rays (one-thread CPU time, >= 10): the
paired ratios (findcell_paired_speedup_vs_static, rays_paired_speedup_vs_static: slice by slice,
back to back with vtkStaticCellLocator) where a run's JSON has them, else the quotient of the
two locators' separate loops (findcell_cpu_speedup_vs_static, rays_cpu_speedup_vs_static); build
(build_ms: median of 3 builds, each locator alone in a fresh process since bench/locators.py
measures it so; <= 1), first build (build_first_ms, <= 1), rebuild after the points moved
(<= 1 is not a target, shown for deforming meshes), memory (<= 1). --previous: runs whose
median build ratio goes in brackets after the shared-process one (build_shared_ratio_vs_static,
or build_ratio_vs_static where a run has no shared-process build).
--targets generated: the targets of the generated grids (bench/gridgen.py: FindCell >= 2, rays
>= 5, build <= 1.5, memory <= 1), with the rates beside the ratios (FindCell and rays per CPU
second, this locator | vtkStaticCellLocator, medians over the runs), the wrong answers
(disagreements, the most over the runs) and the points where only vtkCellLocator found no cell
(reference_misses), the rays whose first hit differs from vtkStaticCellLocator's (hit against
miss, or t by more than 1e-9; ray_disagreements_vs_static).
"""

from __future__ import annotations

import argparse
import json
import statistics

COLUMNS = (  # key (or keys, the first a row has), target test, header
    (("findcell_paired_speedup_vs_static", "findcell_cpu_speedup_vs_static"), lambda m: m >= 5, "FindCell ×"),
    (("rays_paired_speedup_vs_static", "rays_cpu_speedup_vs_static"), lambda m: m >= 10, "rays ×"),
    ("build_ratio_vs_static", lambda m: m <= 1, "build ×"),
    ("build_first_ratio_vs_static", lambda m: m <= 1, "first build ×"),
    ("rebuild_ratio_vs_static", lambda m: m <= 1, "rebuild ×"),
)


TARGETS = {"shipped": (5, 10, 1, 1), "generated": (2, 5, 1.5, 1)}


def columns(targets: str):
    f, r, b, m = TARGETS[targets]
    return ((COLUMNS[0][0], lambda v: v >= f, COLUMNS[0][2]), (COLUMNS[1][0], lambda v: v >= r, COLUMNS[1][2]),
            (COLUMNS[2][0], lambda v: v <= b, COLUMNS[2][2])) + COLUMNS[3:], m


def load(paths: list, locator: str) -> dict:
    rows = {}
    for path in paths:
        with open(path) as f:
            for r in json.load(f):
                if r["locator"] == locator and r.get("backend", "cpu") == "cpu":
                    rows.setdefault(r["grid"], []).append(r)
    return rows


def value(row: dict, keys):
    """The row's value for the first of `keys` (a key or a tuple of keys) it has, else None."""
    for k in (keys,) if isinstance(keys, str) else keys:
        if k in row:
            return row[k]
    return None


def cell(values: list, ok) -> str:
    if not values:
        return "–"
    m = statistics.median(values)
    s = f"{m:.2f}"
    return f"{'**' + s + '**' if ok(m) else s} ({min(values):.2f}–{max(values):.2f})"


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("runs", nargs="+")
    p.add_argument("--locator", default="matrix-octree")
    p.add_argument("--previous", nargs="*", default=[])
    p.add_argument("--targets", choices=tuple(TARGETS), default="shipped")
    a = p.parse_args()
    rows = load(a.runs, a.locator)
    static = load(a.runs, "vtkStaticCellLocator")
    old = load(a.previous, a.locator)
    cols_spec, mem_target = columns(a.targets)
    rates = a.targets == "generated"
    head = ["grid", "cells", "height"] + [c[2] for c in cols_spec] + ["memory ×", "build × (shared process)"]
    if rates:
        head += ["FindCell /s (ours \\| static)", "rays /s (ours \\| static)", "wrong", "VTK misses", "rays ≠ static"]
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for grid, rs in rows.items():
        cols = [grid, str(rs[0]["cells"]), str(rs[0].get("height", ""))]
        cols += [cell([v for v in (value(r, k) for r in rs) if v is not None], ok) for k, ok, _ in cols_spec]
        mem = statistics.median(r["bytes_ratio_vs_static"] for r in rs)
        cols.append(f"**{mem:.2f}**" if mem <= mem_target else f"{mem:.2f}")
        shared = [r["build_shared_ratio_vs_static"] for r in rs if "build_shared_ratio_vs_static" in r]
        s = f"{statistics.median(shared):.2f}" if shared else "–"
        if grid in old:
            prev = [r.get("build_shared_ratio_vs_static", r["build_ratio_vs_static"]) for r in old[grid]]
            s += f" [{statistics.median(prev):.2f}]"
        cols.append(s)
        if rates:
            st = static.get(grid, [])
            for k in ("findcell_pts_per_cpu_s_1thread", "rays_per_cpu_s"):
                ours_k = statistics.median(r[k] for r in rs)
                st_k = statistics.median(r[k] for r in st) if st else float("nan")
                cols.append(f"{ours_k:.3g} \\| {st_k:.3g}")
            cols.append(str(max(r.get("disagreements", -1) for r in rs)))
            cols.append(str(max(r.get("reference_misses", -1) for r in rs)))
            cols.append(str(max(r.get("ray_disagreements_vs_static", -1) for r in rs)))
        print("| " + " | ".join(cols) + " |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

#!/usr/bin/env python3
"""Charts of the benchmark JSON files, written as PNG into docs/images/.

    .venv/bin/python bench/plot.py [--build out/bench_build.json] [--height out/bench_height.json]
                                   [--locators RUN.json [RUN2.json ...]]

build_phases.png: per scene, the median build time of the matrix octree and kd-tree split into
the §5.1 phases (the paper's Figure 4), next to VTK's locators built in the same run.
height_sweep.png: render and build time against the tree height per scene, auto height marked.
locator_ratios.png: per grid and mesh, the matrix octree's FindCell and ray speed-ups, build
time and memory as ratios to vtkStaticCellLocator (bench/locators.py JSON), with the locator's
target for each (5x, 10x, no slower, no larger).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics

import matplotlib
import matplotlib.ticker

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from locators_summary import value  # noqa: E402  (bench/ is the script's directory)

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def plot_build(rows, path):
    scenes = list(dict.fromkeys(r["scene"] for r in rows))
    ours = [r for r in rows if r.get("overlap") == "exact"]
    phases = list(ours[0]["phases_ms"])
    fig, ax = plt.subplots(figsize=(11, 4.8))
    width = 0.2
    colors = plt.cm.Set2.colors + plt.cm.Dark2.colors  # no grey: greys are the VTK peers
    for si, scene in enumerate(scenes):
        for ti, tree in enumerate(["matrix-octree", "matrix-kdtree"]):
            r = next((x for x in ours if x["scene"] == scene and x["tree"] == tree), None)
            if r is None:
                continue
            x = si + (ti - 1.5) * width
            bottom = 0
            for pi, ph in enumerate(phases):
                v = r["phases_ms"][ph]
                ax.bar(x, v, width, bottom=bottom, color=colors[pi % len(colors)], edgecolor="white", linewidth=0.3,
                       label=ph if (si == 0 and ti == 0) else None)
                bottom += v
            ax.text(x, bottom, "oct" if ti == 0 else "kd", ha="center", va="bottom", fontsize=7)
        for pi, peer in enumerate(["vtkStaticCellLocator", "vtkCellTreeLocator"]):
            r = next((x for x in rows if x["scene"] == scene and x["tree"] == peer), None)
            if r is None:
                continue
            x = si + (pi + 0.5) * width
            ax.bar(x, r["build_ms"], width, color="0.75" if pi == 0 else "0.55", edgecolor="white",
                   label=peer if si == 0 else None)
    ax.set_xticks(range(len(scenes)))
    ax.set_xticklabels([f"{s}\n{next(r['triangles'] for r in rows if r['scene'] == s):,} tri" for s in scenes],
                       fontsize=8)
    ax.set_ylabel("build time (ms), median")
    ax.set_title("Matrix-tree build (§5.1 phases) vs VTK locators, same run, 2 threads")
    ax.legend(fontsize=7, ncol=3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_height(data, path):
    sweep = data["sweep"]
    scenes = list(dict.fromkeys(r["scene"] for r in sweep))
    fig, axes = plt.subplots(2, len(scenes), figsize=(2.3 * len(scenes), 5), squeeze=False)
    for col, scene in enumerate(scenes):
        for row, tree in enumerate(["octree", "kdtree"]):
            ax = axes[row][col]
            pts = sorted((r for r in sweep if r["scene"] == scene and r["tree"] == tree and r["height_setting"] != "auto"),
                         key=lambda r: r["height"])
            auto = next(r for r in sweep if r["scene"] == scene and r["tree"] == tree and r["height_setting"] == "auto")
            h = [r["height"] for r in pts]
            ax.plot(h, [r["render_ms"] for r in pts], "o-", ms=3, label="render")
            ax.plot(h, [r["build_ms"] for r in pts], "s-", ms=3, label="build")
            ax.axvline(auto["height"], color="k", ls=":", lw=1)
            ax.set_yscale("log")
            ax.set_title(f"{scene} {tree}", fontsize=8)
            ax.tick_params(labelsize=7)
            if col == 0:
                ax.set_ylabel("ms")
            if row == 1:
                ax.set_xlabel("height (dotted: auto)", fontsize=7)
    axes[0][0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def plot_locators(runs, path):
    """runs: one row list per bench/locators.py run; with several, each bar is the median over
    the runs of that grid's ratio (each ratio taken within its own run)."""
    per_run = [[r for r in rows if r["locator"] == "matrix-octree" and r.get("backend", "cpu") == "cpu"]
               for rows in runs]
    ours = per_run[0]
    grids = [r["grid"].rsplit(".", 1)[0] for r in ours]
    panels = [  # (column, title, target, True if higher is better)
        # The targets table's keys (bench/locators_summary.py): the paired ratios, else, in a JSON
        # file without them, the quotients of CPU times, else of wall times.
        (("findcell_paired_speedup_vs_static", "findcell_cpu_speedup_vs_static", "findcell_speedup_vs_static"),
         "FindCell speed-up (1 thread)", 5.0, True),
        (("rays_paired_speedup_vs_static", "rays_cpu_speedup_vs_static", "rays_speedup_vs_static"),
         "IntersectWithLine speed-up", 10.0, True),
        ("build_ratio_vs_static", "build time ratio", 1.0, False),
        ("bytes_ratio_vs_static", "memory ratio", 1.0, False),
    ]
    fig, axes = plt.subplots(1, 4, figsize=(15, 4.6), sharey=False)
    for ax, (col, title, target, higher) in zip(axes, panels):
        vals = [statistics.median(value(next(x for x in rows if x["grid"] == r["grid"]), col) for rows in per_run)
                for r in ours]
        ok = [(v >= target) if higher else (v <= target) for v in vals]
        ax.barh(range(len(vals)), vals, color=["#2a9d8f" if o else "#e76f51" for o in ok])
        ax.axvline(target, color="k", ls="--", lw=1)
        ax.axvline(1.0, color="0.6", lw=0.8)
        ax.set_xscale("log")
        ax.xaxis.set_major_formatter(matplotlib.ticker.FormatStrFormatter("%g"))
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.set_yticks(range(len(grids)))
        ax.set_yticklabels(grids if ax is axes[0] else [""] * len(grids), fontsize=8)
        ax.invert_yaxis()
        ax.set_title(f"{title}\ntarget {'>=' if higher else '<='} {target:g}x (dashed)", fontsize=9)
        for i, v in enumerate(vals):
            ax.text(v, i, f" {v:.2f}", va="center", fontsize=7)
    what = "same run" if len(runs) == 1 else f"median of {len(runs)} runs, each ratio within its run"
    fig.suptitle(f"matrix octree / vtkStaticCellLocator, {what} (green: target met)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--build", default=os.path.join(ROOT, "out", "bench_build.json"))
    p.add_argument("--height", default=os.path.join(ROOT, "out", "bench_height.json"))
    p.add_argument("--locators", nargs="+", default=[os.path.join(ROOT, "out", "bench_locators_all.json")],
                   help="bench/locators.py JSON; several runs: the chart shows each ratio's median")
    p.add_argument("--out", default=os.path.join(ROOT, "docs", "images"))
    a = p.parse_args()
    os.makedirs(a.out, exist_ok=True)
    if os.path.exists(a.build):
        with open(a.build) as f:
            plot_build(json.load(f), os.path.join(a.out, "build_phases.png"))
        print("wrote", os.path.join(a.out, "build_phases.png"))
    if os.path.exists(a.height):
        with open(a.height) as f:
            plot_height(json.load(f), os.path.join(a.out, "height_sweep.png"))
        print("wrote", os.path.join(a.out, "height_sweep.png"))
    runs = []
    for path in a.locators:
        if os.path.exists(path):
            with open(path) as f:
                data = json.load(f)
            runs.append(data if isinstance(data, list) else data["rows"])
    if runs:
        plot_locators(runs, os.path.join(a.out, "locator_ratios.png"))
        print("wrote", os.path.join(a.out, "locator_ratios.png"))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""bench/cpp/locator_ab (two locator settings timed alternately in one process): it runs, writes
its JSON, rejects a bad setting, and its answer check finds no difference where there is none."""

import json
import os
import subprocess

import pytest
import pyvista as pv

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
EXE = os.path.join(os.environ.get("MATRIXTREE_BUILD_DIR", os.path.join(ROOT, "build")), "bin", "locator_ab")

pytestmark = pytest.mark.skipif(not os.path.exists(EXE), reason="build/bin/locator_ab not built (scripts/setup.sh)")


@pytest.fixture(scope="module")
def tet_grid(tmp_path_factory):
    path = tmp_path_factory.mktemp("ab") / "tets.vtu"
    grid = pv.ImageData(dimensions=(9, 8, 7), spacing=(0.5, 0.25, 1.0)).triangulate()
    assert grid.n_cells > 0 and set(grid.celltypes) == {10}
    grid.save(path)
    return str(path)


def run(*args):
    return subprocess.run([EXE, *args], capture_output=True, text=True, timeout=300)


def test_locator_ab_writes_paired_ratios(tet_grid, tmp_path):
    out = tmp_path / "ab.json"
    p = run(tet_grid, "default", "default", "2000", "1000", "3", str(out))
    assert p.returncode == 0, p.stderr
    rows = json.load(open(out))
    assert [r["measure"] for r in rows] == ["build", "findcell", "rays"]
    for r in rows:
        assert r["a"] == "default" and r["b"] == "default" and r["rounds"] == 3
        assert r["a_median"] > 0 and r["b_median"] > 0
        assert 0 < r["ratio_q1"] <= r["ratio_median"] <= r["ratio_q3"]
    # the same settings give the same answers
    assert "FindCell 0 of 2000 differ" in p.stdout and "rays 0 of 1000" in p.stdout


def test_locator_ab_against_static_finds_containing_cells(tet_grid):
    # vtkStaticCellLocator may return the other cell of a shared face; the check counts only a
    # cell that does not contain the point, or found against not found.
    p = run(tet_grid, "kdtree,height=3", "static", "2000", "0", "2")
    assert p.returncode == 0, p.stderr
    assert "B = static: vtkStaticCellLocator" in p.stdout and "height 3" in p.stdout
    assert "FindCell 0 of 2000 differ" in p.stdout


@pytest.mark.parametrize("bad", ["height=x", "leaf_scale=", "sort=quick", "nonsense"])
def test_locator_ab_rejects_unknown_settings(tet_grid, bad):
    p = run(tet_grid, "default", bad)
    assert p.returncode == 2 and bad.split("=")[0] in p.stderr

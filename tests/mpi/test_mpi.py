"""matrixtree.mpi under ``mpirun -np 2`` and ``-np 4`` against one process's answers.

Point location: every rank's answers equal :class:`matrixtree.CellLocator` on the whole grid,
point for point, also at grid vertices and edge midpoints (points several cells accept) and on
the partition's cuts; each point goes to few ranks (not to all). Surface rendering: the
composited image equals :func:`matrixtree.render` of the whole mesh with the same camera, pixel for
pixel. Volume rendering: the composited image equals :func:`matrixtree.render_volume` of the whole
volume up to the resampling the bricks bring (each brick starts its samples where its rays
enter it; docs/mpi.md), and compositing in the wrong order is far off.
"""

import os
import subprocess
import sys

import numpy as np
import pytest

import matrixtree

HERE = os.path.dirname(os.path.abspath(__file__))
DATA = matrixtree.scenes.data_dir()
GRIDS = ["cfd/pipe_flow_tets.vtu", "cfd/disk_out_ref.ex2", "cfd/brick_prism.su2", "cfd/brick_pyra.su2"]


def run_mpi(ranks, command, out, *args, timeout=900):
    cmd = ["mpirun", "-np", str(ranks), "--oversubscribe", "--bind-to", "none"]
    if os.geteuid() == 0:
        cmd.insert(1, "--allow-run-as-root")
    cmd += [sys.executable, os.path.join(HERE, "mpi_checks.py"), command, str(out), *map(str, args)]
    # Python's copy of the environment: a singleton MPI in this process (a doctest importing
    # matrixtree.mpi) sets OMPI_* variables in the C environment that would make mpirun fail.
    env = {k: v for k, v in os.environ.items() if not k.startswith(("OMPI_", "PMIX_"))}
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env)
    log = proc.stdout + proc.stderr
    assert proc.returncode == 0 and os.path.exists(out), f"mpirun {command} failed ({proc.returncode}):\n{log[-4000:]}"
    got = np.load(out)
    assert int(got["ranks"]) == ranks
    return got


@pytest.mark.parametrize("ranks", [2, 4])
def test_distributed_locate_equals_one_process(tmp_path, ranks):
    got = run_mpi(ranks, "locate", tmp_path / "locate.npz", *[os.path.join(DATA, g) for g in GRIDS])
    for rel in GRIDS:
        name = rel.rsplit("/", 1)[-1]
        grid = matrixtree.read_grid(os.path.join(DATA, rel))
        one = matrixtree.CellLocator(grid)
        assert int(got[f"{name}|num_cells"]) == grid.GetNumberOfCells()
        assert np.all(got[f"{name}|cells"] > 0), f"{name}: a rank holds no cells"
        assert np.all(got[f"{name}|threads"] == max(1, os.cpu_count() // ranks))
        for r in range(ranks):
            p, ids = got[f"{name}|points|{r}"], got[f"{name}|ids|{r}"]
            ref = one.locate(p)
            assert ids.shape == ref.shape
            bad = np.flatnonzero(ids != ref)
            assert bad.size == 0, f"{name}, rank {r}: {bad.size} of {len(p)} answers differ, e.g. {p[bad[:3]]}"
            if r == 0:
                assert (ref >= 0).mean() > 0.5
        # Routing, not broadcast: each point went to about one rank.
        asked, routed = got[f"{name}|asked"].sum(), got[f"{name}|routed"].sum()
        assert routed < 1.3 * asked, f"{name}: {routed} (point, rank) pairs for {asked} points"
        assert got[f"{name}|answered"].sum() == routed


@pytest.mark.parametrize("ranks", [2, 4])
def test_distributed_render_equals_one_process(tmp_path, ranks):
    mesh_path = os.path.join(DATA, "meshes", "bunny.ply")
    got = run_mpi(ranks, "render", tmp_path / "render.npz", mesh_path)
    camera = [tuple(got["position"]), tuple(got["focal"]), tuple(got["up"]), float(got["angle"])]
    ref = matrixtree.render(matrixtree.read_mesh(mesh_path), size=(128, 96), camera=camera, shadows=False)
    assert (ref["depth"] < np.inf).mean() > 0.1
    assert np.array_equal(got["depth"], ref["depth"])
    assert np.array_equal(got["rgb"], ref["rgb"])
    cell_ids = ref["caster"].GetOutput().GetPointData().GetArray("CellId")
    ref_cells = np.array([cell_ids.GetValue(i) for i in range(cell_ids.GetNumberOfTuples())]).reshape(96, 128)[::-1]
    assert np.array_equal(got["cell_ids"], ref_cells)


@pytest.mark.parametrize("ranks", [2, 4])
def test_distributed_volume_render_is_one_process_image(tmp_path, ranks):
    path = os.path.join(DATA, "volumes", "ironProt.vtk")
    got = run_mpi(ranks, "volume", tmp_path / "volume.npz", path)
    vol = matrixtree.read_volume(path)
    ref = matrixtree.render_volume(vol, size=(128, 96), camera=matrixtree.frame_camera(vol))
    assert ref[..., 3].max() > 0.9
    err = np.abs(got["image"] - ref)
    assert err.mean() < 5e-4 and err.max() < 0.05, (err.mean(), err.max())
    # Back to front instead of front to back: the order matters, and the test sees it.
    wrong = np.zeros_like(ref)
    for r in got["order"][::-1]:
        wrong += (1.0 - wrong[..., 3:4]) * got["parts"][r]
    assert np.abs(wrong - ref).max() > 0.2

"""Seeded, time-bounded fuzzer of the file readers: read_mesh, read_grid, read_volume, and what a
user does next with what they return (a tree and a query, a volume render).

Seeds are small valid files of every format the readers take (written here from pyvista/VTK
objects, plus three of the shared data: an Exodus grid and two volumes); each case is a seed
mutated once or a few times: truncated, bytes flipped, a number of its header replaced by a huge,
negative or zero one, a chunk deleted or repeated. A worker process reads the cases one by one;
the outcome of a case must be a result or one of the documented errors (ValueError, OSError,
RuntimeError from a refused build). A crash or a hang of the worker, or any other exception, is a
finding: the case is copied to --findings with its seed's name, the worker restarted, and the run
ends with exit status 1.

    .venv/bin/python tests/fuzz/fuzz_readers.py --seconds 20 --seed 1 [--findings DIR]
    .venv/bin/python tests/fuzz/fuzz_readers.py --replay FILE...      (a finding, in a worker)
"""

from __future__ import annotations

import argparse
import os
import random
import re
import shutil
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
EXPECTED = (ValueError, OSError, RuntimeError)
CASE_TIMEOUT = 30.0


# ---------------------------------------------------------------------------------------------
# Worker: reads one case per stdin line ("path"), answers one line per case.
# ---------------------------------------------------------------------------------------------
def exercise(path: str) -> str:
    """Read the file as its extension says and use the result; the outcome in a word."""
    import numpy as np

    import matrixtree

    low = os.path.basename(path).lower()  # seeds are named mesh*, grid*, volume* by what they hold
    if low.endswith((".ply", ".obj", ".stl", ".vtp")) or "mesh" in low:
        mesh = matrixtree.read_mesh(path)
        tree = matrixtree.MatrixTree(mesh, threads=1)
        b = np.array(mesh.GetBounds()).reshape(3, 2)
        o = b[:, 0] - 1.0
        tree.intersect([o], [b[:, 1] - o])
        matrixtree.CellLocator(mesh, threads=1).closest_points([o])
        return f"mesh {mesh.GetNumberOfPolys()}"
    if low.endswith((".su2", ".vtu", ".ex2", ".msh")) or "grid" in low:
        grid = matrixtree.read_grid(path)
        if grid.GetNumberOfCells() == 0:
            return "grid 0"
        loc = matrixtree.CellLocator(grid, threads=1)
        b = np.array(grid.GetBounds()).reshape(3, 2)
        pts = b[:, 0] + np.random.default_rng(0).random((50, 3)) * (b[:, 1] - b[:, 0])
        loc.locate(pts, return_weights=True)
        loc.trace(pts[:10], ends=pts[10:20])
        return f"grid {grid.GetNumberOfCells()}"
    vol = matrixtree.read_volume(path)
    matrixtree.render_volume(vol, size=(8, 6), threads=1)
    return f"volume {vol.GetNumberOfPoints()}"


def worker() -> None:
    import logging

    logging.disable(logging.CRITICAL)
    from vtkmodules.vtkCommonCore import vtkObject

    vtkObject.GlobalWarningDisplayOff()  # VTK's messages: thousands of lines otherwise
    for line in sys.stdin:
        path = line.strip()
        try:
            out = "ok " + exercise(path)
        except EXPECTED as e:
            out = f"refused {type(e).__name__}"
        except BaseException as e:  # noqa: BLE001 - anything else is the finding
            out = f"UNEXPECTED {type(e).__name__}: {str(e)[:300]!r}"
        print(out.replace("\n", " "), flush=True)


# ---------------------------------------------------------------------------------------------
# Seeds
# ---------------------------------------------------------------------------------------------
def write_seeds(folder: str) -> list[str]:
    """Small valid files of every reader format; returns their paths."""
    import numpy as np
    import pyvista as pv
    from vtkmodules.vtkIOImage import vtkNIFTIImageWriter
    from vtkmodules.vtkIOLegacy import vtkPolyDataWriter, vtkStructuredPointsWriter, vtkUnstructuredGridWriter

    seeds = []

    def add(name):
        seeds.append(os.path.join(folder, name))
        return seeds[-1]

    sphere = pv.Sphere(theta_resolution=6, phi_resolution=5)
    mixed = (pv.Plane(i_resolution=2, j_resolution=2).triangulate() + pv.Plane(center=(0, 0, 1), i_resolution=2,
                                                                             j_resolution=1)).clean()
    sphere.save(add("mesh_bin.ply"), binary=True)
    mixed.save(add("mesh_ascii.ply"), binary=False)
    sphere.save(add("mesh_bin.stl"), binary=True)
    sphere.save(add("mesh_ascii.stl"), binary=False)
    sphere.save(add("mesh.vtp"), binary=False)
    w = vtkPolyDataWriter()
    w.SetInputData(sphere)
    w.SetFileName(add("mesh_poly.vtk"))
    w.Write()
    with open(add("mesh.obj"), "w") as f:
        for p in sphere.points:
            f.write(f"v {p[0]} {p[1]} {p[2]}\nvt 0.5 0.5\n")
        faces = sphere.faces.reshape(-1, 4)[:, 1:] + 1
        for i, t in enumerate(faces):
            f.write(f"f {t[0]}/{t[0]} {t[1]} -1\n" if i % 5 == 0 else f"f {t[0]} {t[1]} {t[2]}\n")
    grid = pv.ImageData(dimensions=(4, 3, 3)).cast_to_unstructured_grid().triangulate()
    grid.save(add("grid.vtu"), binary=False)
    grid.save(add("grid_bin.vtu"), binary=True)
    w = vtkUnstructuredGridWriter()
    w.SetInputData(grid)
    w.SetFileName(add("grid_legacy.vtk"))
    w.Write()
    with open(add("grid.su2"), "w") as f:
        f.write("NDIME= 3\nNELEM= 2\n10 0 1 2 3 0\n10 1 2 3 4 1\nNPOIN= 5\n"
                "0 0 0 0\n1 0 0 1\n0 1 0 2\n0 0 1 3\n1 1 1 4\nNMARK= 1\nMARKER_TAG= wall\nMARKER_ELEMS= 1\n5 0 1 2\n")
    shutil.copy(os.path.join(ROOT, "..", "shared", "data", "cfd", "disk_out_ref.ex2"), add("grid.ex2"))
    vol = pv.ImageData(dimensions=(6, 5, 4), spacing=(1, 0.5, 2))
    vol.point_data["s"] = (np.arange(vol.n_points) % 11).astype(np.uint8)
    vol.save(add("volume.vti"), binary=True)
    w = vtkStructuredPointsWriter()
    w.SetInputData(vol)
    w.SetFileName(add("volume_points.vtk"))
    w.Write()
    w = vtkNIFTIImageWriter()
    w.SetInputData(vol)
    w.SetFileName(add("volume.nii"))
    w.Write()
    data = os.path.join(ROOT, "..", "shared", "data", "volumes")
    for name in ("HeadMRVolume.mhd", "HeadMRVolume.raw"):
        shutil.copy(os.path.join(data, name), os.path.join(folder, name))
    seeds.append(os.path.join(folder, "HeadMRVolume.mhd"))
    shutil.copy(os.path.join(data, "ironProt.vtk"), add("volume_iron.vtk"))
    return seeds


# ---------------------------------------------------------------------------------------------
# Mutations
# ---------------------------------------------------------------------------------------------
NUMBER = re.compile(rb"-?\d+")


def mutate(data: bytes, rng: random.Random) -> bytes:
    for _ in range(1 + (rng.random() < 0.3) * rng.randrange(1, 4)):
        kind = rng.randrange(5)
        if not data:
            return data
        if kind == 0:  # truncate
            data = data[:rng.randrange(len(data))]
        elif kind == 1:  # flip a few bytes
            b = bytearray(data)
            for _ in range(rng.randrange(1, 9)):
                b[rng.randrange(len(b))] = rng.randrange(256)
            data = bytes(b)
        elif kind == 2:  # a number, preferably of the first 2 KiB (the header), made huge/negative/zero
            head = [m for m in NUMBER.finditer(data[:2048])] or [m for m in NUMBER.finditer(data[:65536])]
            if head:
                m = rng.choice(head)
                new = rng.choice([b"0", b"-1", b"1000000000", b"2147483647", b"4294967296", b"99999999999999",
                                  str(int(m.group()) * rng.choice([2, 3, 10]) if len(m.group()) < 12 else 7).encode()])
                data = data[:m.start()] + new + data[m.end():]
        elif kind == 3:  # delete a chunk
            a = rng.randrange(len(data))
            data = data[:a] + data[a + rng.randrange(1, 64):]
        else:  # repeat a chunk
            a = rng.randrange(len(data))
            data = data[:a] + data[a:a + rng.randrange(1, 64)] * 2 + data[a + 64:]
    return data


# ---------------------------------------------------------------------------------------------
# Driver
# ---------------------------------------------------------------------------------------------
class Worker:
    def __init__(self):
        # The readers' own time limit (matrixtree._sandbox) below the case's: a reader that runs
        # away is then a refused file, and only a hang elsewhere a finding.
        env = dict(os.environ, MATRIXTREE_READ_TIMEOUT=str(CASE_TIMEOUT / 2),
                   PYTHONPATH=os.pathsep.join(filter(None, [os.path.join(ROOT, "python"), os.environ.get("PYTHONPATH")])))
        self.err = tempfile.TemporaryFile(mode="w+")  # a file, not a pipe: VTK's messages never block it
        self.p = subprocess.Popen([sys.executable, os.path.abspath(__file__), "--worker"], stdin=subprocess.PIPE,
                                  stdout=subprocess.PIPE, stderr=self.err, text=True, env=env)

    def run(self, path: str) -> str:
        """The case's outcome line, or 'CRASH ...'/'HANG' (the worker is then dead)."""
        import selectors

        self.p.stdin.write(path + "\n")
        self.p.stdin.flush()
        sel = selectors.DefaultSelector()
        sel.register(self.p.stdout, selectors.EVENT_READ)
        if not sel.select(CASE_TIMEOUT):
            self.p.kill()
            self.p.wait()
            return f"HANG: no answer in {CASE_TIMEOUT} s"
        line = self.p.stdout.readline()
        if not line:
            self.p.wait()
            self.err.seek(0)
            err = self.err.read()[-500:]
            return f"CRASH rc={self.p.returncode}: {err!r}"
        return line.strip()

    def close(self):
        if self.p.poll() is None:
            self.p.stdin.close()
            self.p.wait(timeout=30)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=20)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--findings", default=os.path.join(ROOT, "build-fuzz", "findings"))
    ap.add_argument("--only", default="", help="fuzz only the seed files whose names contain this (e.g. .vtu)")
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--replay", nargs="+", help="run these files through a worker and print the outcomes")
    a = ap.parse_args()
    if a.worker:
        worker()
        return 0
    if a.replay:
        bad = 0
        for path in a.replay:
            w = Worker()
            out = w.run(os.path.abspath(path))
            w.close()
            print(f"{path}: {out}")
            bad += not (out.startswith("ok") or out.startswith("refused"))
        return 1 if bad else 0
    rng = random.Random(a.seed)
    tmp = tempfile.mkdtemp(prefix="fuzz_readers_")
    try:
        seeds = [s for s in write_seeds(tmp) if a.only in os.path.basename(s)]
        blobs = {s: open(s, "rb").read() for s in seeds}
        w = Worker()
        t0, cases, outcomes, findings = time.time(), 0, {}, []
        while time.time() - t0 < a.seconds:
            seed = rng.choice(seeds)
            base = os.path.basename(seed)
            case_dir = os.path.join(tmp, "case")
            os.makedirs(case_dir, exist_ok=True)
            path = os.path.join(case_dir, base)
            with open(path, "wb") as f:
                f.write(mutate(blobs[seed], rng))
            if base.endswith(".mhd"):  # the header's data file beside it, intact
                shutil.copy(os.path.join(tmp, "HeadMRVolume.raw"), os.path.join(case_dir, "HeadMRVolume.raw"))
            out = w.run(path)
            cases += 1
            key = out.split()[0]
            outcomes[key] = outcomes.get(key, 0) + 1
            if not (out.startswith("ok") or out.startswith("refused")):
                os.makedirs(a.findings, exist_ok=True)
                keep = os.path.join(a.findings, f"readers-{a.seed}-{cases}-{base}")
                shutil.copy(path, keep)
                findings.append(f"{keep}: {out}")
                print(f"[fuzz_readers] FINDING {keep}: {out}", flush=True)
                if w.p.poll() is not None or out.startswith("HANG"):
                    w = Worker()
        w.close()
        print(f"[fuzz_readers] {cases} cases from seed {a.seed} in {time.time() - t0:.0f} s over {len(seeds)} "
              f"seed files: " + ", ".join(f"{k} {v}" for k, v in sorted(outcomes.items())))
        return 1 if findings else 0
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())

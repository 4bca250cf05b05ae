"""bench/gen_scenes.py (the generated meshes of bench/rays.py --generated): sizes near the one
asked for, consistent outward orientation, a closed sphere, small separate scattered objects, and
rays.py's scene spec and size guard."""

import os
import subprocess
import sys

import numpy as np
import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(ROOT, "bench"))
import gen_scenes  # noqa: E402


def normals_and_centres(pts, tris):
    t = pts[tris]
    return np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), t.mean(axis=1)


@pytest.mark.parametrize("shape", gen_scenes.SHAPES)
@pytest.mark.parametrize("n", [1000, 30000])
def test_sizes_are_near_the_request(shape, n):
    pts, tris = gen_scenes.generate(shape, n)
    assert abs(len(tris) - n) <= 0.05 * n
    assert tris.dtype == np.uint32 and tris.min() == 0 and tris.max() == len(pts) - 1
    assert np.all(np.isfinite(pts))
    a, b = gen_scenes.generate(shape, n)
    np.testing.assert_array_equal(a, pts)  # seeded


def test_sphere_is_closed_and_faces_outwards():
    pts, tris = gen_scenes.sphere(5000)
    n, c = normals_and_centres(pts, tris)
    assert np.all(np.einsum("ij,ij->i", n, c) > 0)
    # welded by position, every edge is shared by exactly two triangles, once in each direction
    _, weld = np.unique(np.round(pts, 12), axis=0, return_inverse=True)
    t = weld.ravel()[tris]
    edges = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
    directed = {tuple(e) for e in edges}
    assert len(directed) == len(edges)
    assert all((b, a) in directed for a, b in directed)
    radius = np.linalg.norm(pts, axis=1)
    assert radius.min() > 0.85 and radius.max() < 1.15


def test_terrain_faces_up_and_scatter_objects_are_small_and_inside_the_cube():
    pts, tris = gen_scenes.terrain(5000)
    n, _ = normals_and_centres(pts, tris)
    assert np.all(n[:, 1] > 0)
    pts, tris = gen_scenes.scatter(3200)
    k = len(tris) // 32
    objects = pts.reshape(k, -1, 3)
    centres = objects.mean(axis=1)
    extent = np.linalg.norm(objects - centres[:, None], axis=2).max(axis=1)
    n, c = normals_and_centres(pts, tris)
    assert np.all(np.einsum("ij,ij->i", n, c - np.repeat(centres, 32, axis=0)) > 0)
    assert extent.max() < 0.8 / np.sqrt(k) * 1.8
    assert np.all(np.abs(centres) <= 1.0 + extent[:, None]) and len(tris) == 3200


def test_bad_requests_are_errors():
    with pytest.raises(ValueError, match="unknown generated shape 'cube'"):
        gen_scenes.generate("cube", 100)
    with pytest.raises(ValueError, match="must be >= 1"):
        gen_scenes.generate("sphere", 0)
    assert gen_scenes.label(10**6) == "1M" and gen_scenes.label(10**4) == "10k" and gen_scenes.label(1234) == "1234"


def test_rays_bench_loads_generated_specs_and_guards_huge_sizes():
    sys.path.insert(0, os.path.join(ROOT, "bench"))
    import rays

    name, tris, frames = rays.load_scene("gen:terrain:2e3", 1)
    assert name == "terrain_2k" and len(frames) == 1 and abs(len(tris) - 2000) < 100
    with pytest.raises(SystemExit, match="expected gen:SHAPE:N"):
        rays.load_scene("gen:cube:1e3", 1)
    r = subprocess.run([sys.executable, os.path.join(ROOT, "bench", "rays.py"), "--generated", "1e7"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "need --huge" in r.stderr

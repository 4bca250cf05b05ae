// Fuzz harness: the triangle-mesh builder (MatrixTreeBuilder<TriangleMesh>, paper §5.1) and the
// ray queries over random and degenerate meshes.
//
// A case is a mesh of up to 40 triangles over up to 32 points (coordinates in one of
// mfuzz::Input's modes: coincident points, zero-area and collinear triangles, NaN/inf/huge raw
// doubles, the ends of the supported range), build options (octree or regular kd-tree, height,
// block edge, overlap test, sort, 1-2 threads) and 8 rays (axis-aligned directions and zero
// components included). Invariants:
//   - TriangleMesh and the builder either accept the case or throw std::invalid_argument /
//     std::length_error (refused input, a height too large); never crash or overflow;
//   - intersectFirst through the tree equals intersectFirstBruteForce over all triangles: the
//     same triangle and t, or another triangle at the same t within 1e-6 (a tie, as
//     tests/cpp/test_rays.cpp accepts);
//   - intersectAny agrees with whether the brute force hits;
//   - leafFind of a point inside the root box gives a node of the tree.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <vector>

#include "fuzz_input.h"
#include "mtree/core/builder.h"
#include "mtree/core/primitives.h"
#include "mtree/rays/raycast.h"

using namespace mtree;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  mfuzz::Input in(data, size);
  BuildOptions opt = mfuzz::treeOptions(in);
  opt.threads = 1 + int(in.below(2));

  const mfuzz::Input::Mode mode = in.mode();
  const uint32_t nv = 3 + in.below(30), nt = in.below(41);
  std::vector<double> pts(3 * size_t(nv));
  for (double& v : pts) v = in.coordinate(mode);
  std::vector<uint32_t> tris(3 * size_t(nt));
  for (uint32_t& i : tris) i = in.below(nv + (in.below(64) == 0 ? 2 : 0));  // now and then out of range

  TriangleMesh mesh;
  MatrixTree tree;
  try {
    mesh = TriangleMesh(pts, tris);
    MatrixTreeBuilder<TriangleMesh>::build(mesh, opt, tree, nullptr);
  } catch (const std::invalid_argument&) {
    return 0;  // refused input: a bad index, a coordinate out of range
  } catch (const std::length_error&) {
    return 0;  // a height whose leaf level would pass the memory limit
  }

  Box scene;
  for (size_t i = 0; i < mesh.numPoints(); ++i) scene.extend(Vec3(&mesh.points()[3 * i]));
  const Vec3 lo = scene.empty() ? Vec3(-1, -1, -1) : scene.lo, hi = scene.empty() ? Vec3(1, 1, 1) : scene.hi;
  auto inScene = [&](double margin) {
    Vec3 p;
    for (int a = 0; a < 3; ++a) {
      const double w = hi[a] - lo[a];
      p[a] = in.flag() ? lo[a] + w * double(in.below(5)) / 4 : in.uniform(lo[a] - margin * w, hi[a] + margin * w);
    }
    return p;
  };
  for (int r = 0; r < 8 && !in.empty(); ++r) {
    const Vec3 o = inScene(0.5);
    Vec3 d = inScene(0.5) - o;
    if (in.below(4) == 0) d[in.below(3)] = 0;  // a direction in a coordinate plane
    const double tmin = in.below(4) == 0 ? in.uniform(0, 1) : 0.0;
    const double tmax = in.below(4) == 0 ? in.uniform(tmin, 2) : std::numeric_limits<double>::infinity();
    RayHit got, ref;
    intersectFirst(tree, mesh, o, d, tmin, tmax, got);
    intersectFirstBruteForce(mesh, o, d, tmin, tmax, ref);
    const bool same = got.prim == ref.prim ? (!got.hit() || got.t == ref.t)
                                           : got.hit() && ref.hit() &&
                                                 std::fabs(got.t - ref.t) <= 1e-6 * std::max(1.0, std::fabs(ref.t));
    if (!same) {
      std::fprintf(stderr,
                   "ray o=(%.17g, %.17g, %.17g) d=(%.17g, %.17g, %.17g) [%.17g, %.17g]: tree prim %d t %.17g, "
                   "brute force prim %d t %.17g\n",
                   o.x, o.y, o.z, d.x, d.y, d.z, tmin, tmax, got.hit() ? int(got.prim) : -1, got.t,
                   ref.hit() ? int(ref.prim) : -1, ref.t);
      mfuzz::fail("intersectFirst differs from the brute force");
    }
    if (intersectAny(tree, mesh, o, d, tmin, tmax) != ref.hit()) mfuzz::fail("intersectAny differs from the brute force");
    if (!tree.empty() && tree.rootBox().contains(o)) {
      const NodeRef n = tree.leafFind(o);
      if (n.level < 0 || n.level > tree.height()) mfuzz::fail("leafFind of a point in the root box found no node");
    }
  }
  return 0;
}

// Ray queries through matrix trees (octree and regular kd-tree) over the 7 real meshes, against a
// brute-force reference over all triangles with the same Möller–Trumbore arithmetic.
//
// 10^5 seeded rays per mesh, the same rays for both tree kinds:
//   40%  from outside the mesh box, aimed at a random point inside it;
//   30%  starting inside the box, random direction;
//   15%  axis-parallel directions (one or two zero components);
//   15%  origin exactly on a bottom-level node plane (of the octree or of the kd-tree), direction
//        parallel to that plane; a third of them on two planes at once (along a node edge).
// One ray in ten has a clipped interval [tmin, tmax] instead of [0, inf).
// The brute force (mtest::BruteForce) runs about 0.9 ns per ray/triangle test on two cores with
// AVX2, so all 7 meshes keep 10^5 rays (about 60 s for the file on the 2-core CI machine).
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "test_util.h"

namespace {

using mtest::Ray;
using mtree::Box;
using mtree::MatrixTree;
using mtree::RayHit;
using mtree::TreeKind;
using mtree::Vec3;

constexpr int kRaysPerMesh = 100000;

double seconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

std::vector<Ray> makeRays(const mtree::TriangleMesh& mesh, const MatrixTree* trees[2], int n, uint64_t seed) {
  mtest::Rng rng(seed);
  const Box mb = mtest::meshBounds(mesh);
  const Box wide = mtest::enlarged(mb, 0.05);
  const Vec3 c = mb.center();
  const double diag = mtree::norm(mb.extent());
  std::vector<Ray> rays(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) {
    Ray& r = rays[i];
    const int kind = i % 20;
    if (kind < 8) {  // outside, aimed inside
      r.o = c + rng.direction() * (diag * rng.uniform(0.55, 1.5));
      r.d = rng.inBox(mb) - r.o;
      if (rng.below(2)) r.d = mtree::normalized(r.d);
    } else if (kind < 14) {  // inside, random direction
      r.o = rng.inBox(mb);
      r.d = rng.direction();
    } else if (kind < 17) {  // axis-parallel
      r.o = rng.inBox(wide);
      r.d = rng.direction();
      const int a = static_cast<int>(rng.below(3));
      r.d[a] = 0;
      if (rng.below(2)) r.d[(a + 1 + rng.below(2)) % 3] = 0;  // two zero components
      // A third start outside the box along a moving axis, heading in.
      if (rng.below(3) == 0) {
        for (int b = 0; b < 3; ++b)
          if (r.d[b] != 0) {
            r.o[b] =
                r.d[b] > 0 ? mb.lo[b] - 0.3 * (mb.hi[b] - mb.lo[b]) : mb.hi[b] + 0.3 * (mb.hi[b] - mb.lo[b]);
            break;
          }
      }
    } else {  // on a bottom-level node plane, parallel to it
      const MatrixTree& t = *trees[i % 2];
      const int H = t.height();
      const Box root = t.rootBox();
      const Vec3 cs = t.cellSize(H);
      r.o = rng.inBox(mb);
      r.d = rng.direction();
      const int a = static_cast<int>(rng.below(3));
      const int k = static_cast<int>(rng.below(static_cast<uint32_t>(t.dim(H, a) + 1)));
      r.o[a] = root.lo[a] + k * cs[a];  // the plane exactly as MatrixTree::nodeBox computes it
      r.d[a] = 0;
      if (rng.below(3) == 0) {  // along a node edge: on two planes, moving along the third axis
        const int b = (a + 1 + static_cast<int>(rng.below(2))) % 3;
        const int kb = static_cast<int>(rng.below(static_cast<uint32_t>(t.dim(H, b) + 1)));
        r.o[b] = root.lo[b] + kb * cs[b];
        r.d[b] = 0;
      }
      if (rng.below(4) == 0) {  // start outside along a moving axis
        for (int b = 0; b < 3; ++b)
          if (r.d[b] != 0) {
            r.o[b] = r.d[b] > 0 ? root.lo[b] - 0.2 * diag : root.hi[b] + 0.2 * diag;
            break;
          }
      }
    }
    if (i % 10 == 9) {  // a clipped interval
      const double scale = diag / mtree::norm(r.d);
      r.tmin = rng.uniform(0, 0.5) * scale;
      r.tmax = r.tmin + rng.uniform(0, 1.5) * scale;
    }
  }
  return rays;
}

class RealMeshRays : public ::testing::TestWithParam<std::string> {};

TEST_P(RealMeshRays, FirstHitEqualsBruteForce) {
  const std::string rel = GetParam();
  const mtree::TriangleMesh mesh = mtest::loadRealMesh(rel);
  const MatrixTree oct = mtest::buildTree(mesh, mtest::options(TreeKind::Octree));
  const MatrixTree kd = mtest::buildTree(mesh, mtest::options(TreeKind::RegularKd));
  const MatrixTree* trees[2] = {&oct, &kd};
  const std::vector<Ray> rays = makeRays(mesh, trees, kRaysPerMesh, mtest::seedFor(rel, 7));

  double t0 = seconds();
  const mtest::BruteForce bf(mesh);
  const std::vector<RayHit> ref = bf.firstAll(rays);
  const double bfSeconds = seconds() - t0;

  // The fast reference is the engine's reference, bit for bit (checked on a sample).
  int refDiffers = 0;
  for (int i = 0; i < kRaysPerMesh; i += 1000) {
    RayHit h;
    mtree::intersectFirstBruteForce(mesh, rays[i].o, rays[i].d, rays[i].tmin, rays[i].tmax, h);
    refDiffers += h.prim != ref[i].prim || h.t != ref[i].t || h.u != ref[i].u || h.v != ref[i].v;
  }
  ASSERT_EQ(refDiffers, 0) << "mtest::BruteForce disagrees with mtree::intersectFirstBruteForce";

  uint64_t hits = 0;
  for (const RayHit& h : ref) hits += h.hit();
  EXPECT_GT(hits, static_cast<uint64_t>(kRaysPerMesh / 10)) << "too few rays hit: the test would be weak";

  for (const MatrixTree* tree : trees) {
    SCOPED_TRACE(mtree::treeKindName(tree->kind()));
    t0 = seconds();
    std::vector<RayHit> got(rays.size());
    const int64_t n = static_cast<int64_t>(rays.size());
#pragma omp parallel for schedule(dynamic, 256)
    for (int64_t i = 0; i < n; ++i)
      mtree::intersectFirst(*tree, mesh, rays[i].o, rays[i].d, rays[i].tmin, rays[i].tmax, got[i]);
    const double treeSeconds = seconds() - t0;
    mtest::HitComparison cmp;
    for (size_t i = 0; i < rays.size(); ++i) cmp.add(got[i], ref[i], rays[i], i);
    EXPECT_EQ(cmp.mismatches, 0u) << "first: " << cmp.firstMismatch;
    std::printf(
        "[rays] %-28s %-6s rays %llu  hits %llu  id differs (same t) %llu  mismatches %llu  "
        "tree %.2fs  brute force %.1fs\n",
        rel.c_str(), mtree::treeKindName(tree->kind()), (unsigned long long)cmp.rays,
        (unsigned long long)cmp.hits, (unsigned long long)cmp.idDiffers, (unsigned long long)cmp.mismatches,
        treeSeconds, bfSeconds);
    RecordProperty(std::string(mtree::treeKindName(tree->kind())) + "_idDiffers",
                   static_cast<int>(cmp.idDiffers));

    // intersectAny on every 7th ray, with tmax around the reference hit. A hit exists in
    // [tmin, T] iff the reference first hit over [tmin, tmax] has t <= T (T <= tmax), because
    // rayTriangleMT's t does not depend on the interval it is given.
    mtest::Rng rng(mtest::seedFor(rel, 11));
    int anyWrong = 0, anyTrue = 0, anyFalse = 0;
    std::string firstAny;
    for (size_t i = 0; i < rays.size(); i += 7) {
      const Ray& r = rays[i];
      double T = r.tmax;
      if (ref[i].hit()) {
        switch (rng.below(4)) {
          case 0:
            T = ref[i].t;
            break;  // exactly at the hit
          case 1:
            T = std::nextafter(ref[i].t, -1.0);
            break;  // just before it
          case 2:
            T = std::min(r.tmax, ref[i].t * rng.uniform(1.0, 2.0));
            break;
          default:
            T = r.tmin + (ref[i].t - r.tmin) * rng.uniform(0.0, 1.0);
            break;
        }
      }
      const bool expected = ref[i].hit() && ref[i].t <= T;
      const bool any = mtree::intersectAny(*tree, mesh, r.o, r.d, r.tmin, T);
      (expected ? anyTrue : anyFalse)++;
      if (any != expected && anyWrong++ == 0) {
        char buf[200];
        std::snprintf(buf, sizeof buf, "ray %zu, T=%.17g: intersectAny %d, reference t %.17g", i, T, any,
                      ref[i].t);
        firstAny = buf;
      }
    }
    EXPECT_EQ(anyWrong, 0) << firstAny;
    EXPECT_GT(anyTrue, 0);
    EXPECT_GT(anyFalse, 0);
  }
}

INSTANTIATE_TEST_SUITE_P(RealMeshes, RealMeshRays, ::testing::ValuesIn(mtest::realMeshes()),
                         [](const ::testing::TestParamInfo<std::string>& info) {
                           return mtest::meshTag(info.param);
                         });

}  // namespace

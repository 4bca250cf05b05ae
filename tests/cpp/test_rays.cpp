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
#include <limits>
#include <string>
#include <vector>

#include "mtree/rays/batch_trace.h"
#include "mtree/rays/render.h"
#include "test_util.h"

namespace {

using mtest::Ray;
using mtree::Box;
using mtree::MatrixTree;
using mtree::RayHit;
using mtree::TreeKind;
using mtree::Vec3;

constexpr int kRaysPerMesh = 100000;

using mtest::seconds;

std::vector<Ray> makeRays(const mtree::TriangleMesh& mesh, const MatrixTree* trees[2], int n, uint64_t seed) {
  mtest::Rng rng(seed);
  const Box mb = mtest::meshBounds(mesh);
  const Box wide = mtest::enlarged(mb, 0.05);
  const double diag = mtree::norm(mb.extent());
  std::vector<Ray> rays(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) {
    Ray& r = rays[i];
    const int kind = i % 20;
    if (kind < 8) {  // outside, aimed inside
      mtest::aimFromOutside(r, mb, diag, rng);
    } else if (kind < 14) {  // inside, random direction
      r.o = rng.inBox(mb);
      r.d = rng.direction();
    } else if (kind < 17) {  // axis-parallel
      mtest::axisParallel(r, wide, rng);
      // A third start outside the box along a moving axis, heading in.
      if (rng.below(3) == 0) mtest::startOutside(r, mb, mb.extent() * 0.3);
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
      if (rng.below(4) == 0) mtest::startOutside(r, root, Vec3(0.2 * diag, 0.2 * diag, 0.2 * diag));
    }
    if (i % 10 == 9) mtest::clipInterval(r, diag, rng);
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

  const mtest::TimedFirstHits reference(mesh, rays);
  const std::vector<RayHit>& ref = reference.hits;
  const double bfSeconds = reference.elapsed;
  double t0;

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

// The batch tracers (render()'s path) against one ray at a time. The reference walks each ray
// alone through MatrixTree::traverseRay (the scalar TableWalk, or the tree walk without a step
// table) with the scalar leaf test, counting steps and tests; every batch configuration -- each
// leaf-test width this CPU runs (scalar, SSE2, AVX2) and 1, 2, 4 or 8 rays in flight -- must give
// the same first hit (triangle, t, u, v to the bit), the same any-hit answer, and the same node
// visits and triangle tests per ray: the same nodes, the same leaves, the same tests as the ray
// alone. And the batch's first hits are the brute force's.
TEST_P(RealMeshRays, BatchWalkIsTheSingleRayWalk) {
  const std::string rel = GetParam();
  const mtree::TriangleMesh mesh = mtest::loadRealMesh(rel);
  const MatrixTree oct = mtest::buildTree(mesh, mtest::options(TreeKind::Octree));
  const MatrixTree kd = mtest::buildTree(mesh, mtest::options(TreeKind::RegularKd));
  const MatrixTree* trees[2] = {&oct, &kd};
  const int n = 20000;
  const std::vector<Ray> rays = makeRays(mesh, trees, n, mtest::seedFor(rel, 17));
  std::vector<Vec3> o(n), d(n);
  std::vector<double> tmin(n), tmax(n), shadowMax(n);
  for (int i = 0; i < n; ++i) {
    o[i] = rays[i].o;
    d[i] = rays[i].d;
    tmin[i] = rays[i].tmin;
    tmax[i] = rays[i].tmax;
  }
  const mtest::BruteForce bf(mesh);
  const std::vector<RayHit> ref = bf.firstAll(rays);
  // Shadow-ray intervals: up to the first hit (half of them just before it), else the ray's own.
  for (int i = 0; i < n; ++i)
    shadowMax[i] = ref[i].hit() ? (i % 2 ? ref[i].t : std::nextafter(ref[i].t, -1.0)) : tmax[i];
  std::vector<mtree::Simd> widths = {mtree::Simd::Scalar};
  if (mtree::simdSupported() >= mtree::Simd::Sse2) widths.push_back(mtree::Simd::Sse2);
  if (mtree::simdSupported() >= mtree::Simd::Avx2) widths.push_back(mtree::Simd::Avx2);
  for (const MatrixTree* tree : trees) {
    SCOPED_TRACE(mtree::treeKindName(tree->kind()));
    mtree::LeafTriangles payload;
    payload.build(tree->primitiveIndices().data(), tree->primitiveIndices().size(), mesh, 0);
    for (auto test : {mtree::TriangleTest::MollerTrumbore, mtree::TriangleTest::Watertight}) {
      SCOPED_TRACE(mtree::triangleTestName(test));
      // One ray at a time.
      std::vector<RayHit> one(n);
      std::vector<uint8_t> oneAny(n);
      std::vector<uint32_t> oneVisits(n), oneTests(n), oneAnyVisits(n), oneAnyTests(n);
      const uint32_t* ids = tree->primitiveIndices().data();
      for (int i = 0; i < n; ++i) {
        const auto walk = [&](auto testTag, double t1, bool any, RayHit& hit, uint32_t& visits, uint32_t& tests) {
          using Leaf = mtree::LeafTest<mtree::Simd::Scalar, decltype(testTag)::value>;
          mtree::LeafRay ray;
          ray.set<decltype(testTag)::value>(o[i], d[i], tmin[i]);
          mtree::TraversalStats st;
          hit = RayHit{};
          hit.t = t1;
          bool found = false;
          tests = 0;
          tree->traverseRay(
              o[i], d[i], tmin[i], t1,
              [&](const uint32_t* leaf, uint32_t count, double, double tExit) {
                const uint32_t begin = static_cast<uint32_t>(leaf - ids);
                if (any) {
                  uint32_t tested = 0;
                  found = Leaf::any(payload, begin, count, ray, t1, tested);
                  tests += tested;
                  return found;
                }
                Leaf::first(payload, ids, begin, count, ray, hit);
                tests += count;
                return hit.hit() && hit.t <= tExit;
              },
              &st);
          visits = static_cast<uint32_t>(st.nodeVisits);
          if (!hit.hit()) hit.t = std::numeric_limits<double>::infinity();
          return found;
        };
        RayHit unused;
        if (test == mtree::TriangleTest::Watertight) {
          using Tag = std::integral_constant<mtree::TriangleTest, mtree::TriangleTest::Watertight>;
          walk(Tag{}, tmax[i], false, one[i], oneVisits[i], oneTests[i]);
          oneAny[i] = walk(Tag{}, shadowMax[i], true, unused, oneAnyVisits[i], oneAnyTests[i]);
        } else {
          using Tag = std::integral_constant<mtree::TriangleTest, mtree::TriangleTest::MollerTrumbore>;
          walk(Tag{}, tmax[i], false, one[i], oneVisits[i], oneTests[i]);
          oneAny[i] = walk(Tag{}, shadowMax[i], true, unused, oneAnyVisits[i], oneAnyTests[i]);
        }
      }
      if (test == mtree::TriangleTest::MollerTrumbore) {
        mtest::HitComparison cmp;
        for (int i = 0; i < n; ++i) cmp.add(one[i], ref[i], rays[i], size_t(i));
        EXPECT_EQ(cmp.mismatches, 0u) << "first: " << cmp.firstMismatch;
      }
      for (const mtree::Simd simd : widths) {
        for (const int inFlight : {1, 2, 4, 8}) {
          SCOPED_TRACE(std::string(mtree::simdName(simd)) + ", " + std::to_string(inFlight) + " in flight");
          mtree::TraceTuning tuning;
          tuning.simd = simd;
          tuning.inFlight = inFlight;
          const mtree::MatrixTreeTracer tracer{*tree, mesh, test, &payload, tuning};
          mtree::RayBatch b;
          b.o = o.data();
          b.d = d.data();
          b.tmin = tmin.data();
          b.tmax = tmax.data();
          b.n = size_t(n);
          std::vector<RayHit> got(n);
          std::vector<uint32_t> visits(n, 0), tests(n, 0);
          tracer.first(b, got.data(), mtree::RayCounters{visits.data(), tests.data()});
          // Without counters: the same hits.
          std::vector<RayHit> plain(n);
          tracer.first(b, plain.data(), {});
          b.tmax = shadowMax.data();
          std::vector<uint8_t> blocked(n);
          std::vector<uint32_t> anyVisits(n, 0), anyTests(n, 0);
          tracer.any(b, blocked.data(), mtree::RayCounters{anyVisits.data(), anyTests.data()});
          uint64_t differ = 0, countsDiffer = 0, anyDiffer = 0;
          for (int i = 0; i < n; ++i) {
            const RayHit& g = got[i];
            const RayHit& w = one[i];
            differ += !(g.prim == w.prim && g.t == w.t && g.u == w.u && g.v == w.v);
            differ += !(plain[i].prim == g.prim && plain[i].t == g.t);
            countsDiffer += visits[i] != oneVisits[i] || tests[i] != oneTests[i];
            anyDiffer += blocked[i] != oneAny[i];
            countsDiffer += anyVisits[i] != oneAnyVisits[i] || anyTests[i] != oneAnyTests[i];
          }
          EXPECT_EQ(differ, 0u);
          EXPECT_EQ(countsDiffer, 0u);
          EXPECT_EQ(anyDiffer, 0u);
        }
      }
    }
  }
}

INSTANTIATE_TEST_SUITE_P(RealMeshes, RealMeshRays, ::testing::ValuesIn(mtest::realMeshes()),
                         [](const ::testing::TestParamInfo<std::string>& info) {
                           return mtest::meshTag(info.param);
                         });

// mtree::testTriangles (two Moller-Trumbore tests per SSE2 step) reports exactly what
// rayTriangleMT reports one by one: the same list positions, and t, u, v equal bit for bit, for lists
// of 0..9 triangles of a real mesh (pairs and a tail), rays aimed at a vertex, an edge midpoint
// or a random point of a listed triangle (hits on edges and vertices), random rays, a ray in a
// triangle's plane, a list holding one triangle twice, degenerate triangles (det = 0), a NaN
// origin, coordinates scaled to 1e12 and to 1e-12, and narrowed [tmin, tmax].
TEST(TriangleBatch, EqualsOneByOneMollerTrumbore) {
  const mtree::TriangleMesh real = mtest::loadRealMesh("scenes/utah_hand/hand_00.obj");
  for (const double scale : {1.0, 1e12, 1e-12}) {
    SCOPED_TRACE("coordinates x " + std::to_string(scale));
    std::vector<double> pts = real.points();
    for (double& x : pts) x *= scale;
    std::vector<uint32_t> tris = real.triangles();
    // Degenerate triangles appended: a repeated vertex, and three collinear points.
    const uint32_t nv = static_cast<uint32_t>(pts.size() / 3);
    for (int k = 0; k < 3; ++k) pts.push_back(pts[k] + (pts[3 + k] - pts[k]) * 0.5);
    tris.insert(tris.end(), {0, 0, 1, 0, nv, 1});
    const mtree::TriangleMesh mesh(pts, tris);
    const uint32_t nt = static_cast<uint32_t>(mesh.size());
    mtest::Rng rng(mtest::seedFor("triangle-batch", static_cast<uint64_t>(std::log10(scale) + 20)));
    const Box mb = mtest::meshBounds(mesh);
    const double diag = mtree::norm(mb.extent());
    uint64_t lists = 0, reported = 0, differ = 0;
    std::string first;
    for (int trial = 0; trial < 20000; ++trial) {
      const uint32_t n = rng.below(10);
      std::vector<uint32_t> ids(n);
      for (uint32_t& id : ids) id = rng.below(nt);
      if (n >= 2 && trial % 7 == 0) ids[n - 1] = ids[0];              // one triangle twice
      if (n >= 1 && trial % 11 == 0) ids[rng.below(n)] = nt - 1 - rng.below(2);  // a degenerate one
      Vec3 o = mb.center() + rng.direction() * (diag * rng.uniform(0.6, 2.0)), target = rng.inBox(mb);
      if (n > 0) {
        const uint32_t id = ids[rng.below(n)];
        const Vec3 a = mesh.vertex(id, 0), b = mesh.vertex(id, 1), c = mesh.vertex(id, 2);
        switch (trial % 5) {
          case 0: target = a; break;                                    // a vertex
          case 1: target = (b + c) * 0.5; break;                        // an edge midpoint
          case 2: {                                                     // inside
            const double u = rng.uniform(), v = rng.uniform() * (1 - u);
            target = a + (b - a) * u + (c - a) * v;
            break;
          }
          case 3:  // in the triangle's plane
            o = a + (b - a) * 3.0;
            target = a + (c - a) * 0.5;
            break;
          default: break;  // random
        }
      }
      Vec3 d = target - o;
      if (trial % 13 == 0) o.x = std::numeric_limits<double>::quiet_NaN();
      double tmin = 0, tmax = std::numeric_limits<double>::infinity();
      if (trial % 4 == 3) {
        tmin = rng.uniform(0, 0.9);
        tmax = tmin + rng.uniform(0, 0.3);
      }
      struct Hit {
        uint32_t k;  // position in the list
        double t, u, v;
      };
      std::vector<Hit> want, got;
      for (uint32_t k = 0; k < n; ++k) {
        const uint32_t id = ids[k];
        double t, u, v;
        if (mtree::rayTriangleMT(o, d, mesh.vertex(id, 0), mesh.vertex(id, 1), mesh.vertex(id, 2), tmin, tmax, t, u,
                                 v))
          want.push_back({k, t, u, v});
      }
      const bool stopped = mtree::testTriangles<mtree::TriangleTest::MollerTrumbore>(
          mesh, o, d, ids.data(), n, tmin, tmax, [&](uint32_t k, double t, double u, double v) {
            got.push_back({k, t, u, v});
            return false;
          });
      ++lists;
      reported += got.size();
      bool same = !stopped && got.size() == want.size();
      for (size_t k = 0; same && k < got.size(); ++k)
        same = got[k].k == want[k].k && got[k].t == want[k].t && got[k].u == want[k].u && got[k].v == want[k].v;
      if (!same && differ++ == 0)
        first = "trial " + std::to_string(trial) + ": " + std::to_string(got.size()) + " reported, " +
                std::to_string(want.size()) + " one by one";
      // A true return from the callback stops the list at that triangle.
      if (!want.empty()) {
        uint32_t calls = 0;
        EXPECT_TRUE(mtree::testTriangles<mtree::TriangleTest::MollerTrumbore>(
            mesh, o, d, ids.data(), n, tmin, tmax, [&](uint32_t k, double, double, double) {
              ++calls;
              return k == want[0].k;
            }));
        EXPECT_EQ(calls, 1u);
      }
    }
    EXPECT_EQ(differ, 0u) << first;
    EXPECT_GT(reported, lists / 4) << "too few hits: the comparison would be weak";
  }
}

}  // namespace

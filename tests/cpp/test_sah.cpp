// The ray-tracing baseline: SAH kd-tree (Wald & Havran 2006) with the Restart, Stack and
// ShortStack traversals, and the watertight ray/triangle test (Woop, Benthin & Wald 2013).
//
// On each of the 7 real meshes, seeded rays (1.5*10^9 ray/triangle tests of brute force a mesh,
// at least 2*10^4 rays and at most 10^5):
//   40%  from outside the mesh box, aimed at a random point inside it;
//   25%  starting inside the box, random direction;
//   15%  axis-parallel directions (one or two zero components);
//   10%  origin exactly on a split plane of the tree, direction parallel to it (a third on two
//        planes: along a line where two planes meet);
//   10%  from a vertex or an edge point of a random triangle, or aimed exactly at one;
// one ray in ten with a clipped interval [tmin, tmax].
// Every traversal (restart, stack, shortstack K=3 and K=1) must give the brute force's first hit
// (same triangle, or the same t to 1e-6 where two triangles meet) and the stack traversal's hit
// bit for bit; any-hit queries must agree with the reference; stack visits no more nodes than
// restart or shortstack on every ray. The watertight test is checked the same way against a
// watertight brute force on a sample, and on closed spheres it must never let a ray through an
// edge or a vertex.
// Synthetic scenes check the rest: the build's invariant (every leaf whose closed box holds a point
// of a triangle lists the triangle), determinism, boxes on a grid (triangles in split planes, rays
// along faces and through corners), empty / single-triangle / flat / degenerate / far-away / tiny
// scenes, non-finite and empty rays, depth limits and cost options, short-stack sizes, and the
// tracer in render.h against the matrix tree's.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include "mtree/rays/intersect.h"
#include "mtree/rays/render.h"
#include "mtree/rays/sah_kdtree.h"
#include "test_util.h"

namespace {

using mtest::aimedRays;
using mtest::Ray;
using mtest::transformed;
using mtree::Box;
using mtree::RayHit;
using mtree::SahKdTree;
using mtree::SahTraversal;
using mtree::TraversalStats;
using mtree::TriangleMesh;
using mtree::TriangleTest;
using mtree::Vec3;

const double kInf = std::numeric_limits<double>::infinity();
const double kNaN = std::numeric_limits<double>::quiet_NaN();

struct Config {
  SahTraversal traversal;
  int K;
  const char* name;
};
// Stack first: the others are compared with it.
const Config kConfigs[4] = {{SahTraversal::Stack, 3, "stack"},
                            {SahTraversal::Restart, 3, "restart"},
                            {SahTraversal::ShortStack, 3, "shortstack3"},
                            {SahTraversal::ShortStack, 1, "shortstack1"}};

using mtest::seconds;

int raysFor(size_t triangles) {
  const double n = 1.5e9 / std::max<size_t>(triangles, 1);
  return static_cast<int>(std::min(1e5, std::max(2e4, n)));
}


std::vector<Ray> makeRays(const TriangleMesh& mesh, const SahKdTree& tree, int n, uint64_t seed) {
  mtest::Rng rng(seed);
  const Box mb = mtest::meshBounds(mesh);
  const Box wide = mtest::enlarged(mb, 0.05);
  const double diag = std::max(mtree::norm(mb.extent()), 1e-300);
  std::vector<uint32_t> inner;
  for (uint32_t i = 0; i < tree.nodes().size(); ++i)
    if (!tree.nodes()[i].isLeaf()) inner.push_back(i);
  std::vector<Ray> rays(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) {
    Ray& r = rays[i];
    const int kind = i % 20;
    if (kind < 8 || (kind >= 16 && kind < 18 && inner.empty())) {  // outside, aimed inside
      mtest::aimFromOutside(r, mb, diag, rng);
    } else if (kind < 13) {  // inside, random direction
      r.o = rng.inBox(mb);
      r.d = rng.direction();
    } else if (kind < 16) {  // axis-parallel
      mtest::axisParallel(r, wide, rng);
      if (rng.below(3) == 0) mtest::startOutside(r, mb, mb.extent() * 0.3);  // heading in
    } else if (kind < 18) {  // on a split plane, parallel to it
      const mtree::SahKdNode& nd = tree.nodes()[inner[rng.below(static_cast<uint32_t>(inner.size()))]];
      const int a = nd.axis();
      r.o = rng.inBox(mb);
      r.d = rng.direction();
      r.o[a] = tree.planeWorld(a, nd.split());
      r.d[a] = 0;
      if (rng.below(3) == 0) {  // also on a plane of another axis
        for (int tries = 0; tries < 32; ++tries) {
          const mtree::SahKdNode& n2 = tree.nodes()[inner[rng.below(static_cast<uint32_t>(inner.size()))]];
          if (n2.axis() == a) continue;
          r.o[n2.axis()] = tree.planeWorld(n2.axis(), n2.split());
          r.d[n2.axis()] = 0;
          break;
        }
      }
      if (rng.below(4) == 0) mtest::startOutside(r, mb, Vec3(0.2 * diag, 0.2 * diag, 0.2 * diag));
    } else {  // from or at a vertex or an edge
      const size_t tri = rng.below(static_cast<uint32_t>(mesh.size()));
      const int k = static_cast<int>(rng.below(3));
      const Vec3 a = mesh.vertex(tri, k), b = mesh.vertex(tri, (k + 1) % 3);
      r.d = rng.direction();
      const int which = static_cast<int>(rng.below(4));
      r.o = mtest::atVertexOrEdge(which, a, b, r.d, diag, rng);
    }
    if (i % 10 == 9) mtest::clipInterval(r, diag, rng);
  }
  return rays;
}

/// Watertight brute force: every triangle, the same tie rule as intersectFirstBruteForce.
RayHit bruteForceWatertight(const TriangleMesh& mesh, const Ray& r) {
  RayHit hit;
  hit.t = r.tmax;
  for (size_t id = 0; id < mesh.size(); ++id) {
    double t, u, v;
    if (mtree::rayTriangleWatertight(r.o, r.d, mesh.vertex(id, 0), mesh.vertex(id, 1), mesh.vertex(id, 2), r.tmin,
                                     hit.t, t, u, v)) {
      if (t < hit.t || (t == hit.t && id < hit.prim)) {
        hit.t = t;
        hit.prim = static_cast<uint32_t>(id);
        hit.u = u;
        hit.v = v;
      }
    }
  }
  if (!hit.hit()) hit.t = kInf;
  return hit;
}

struct RunResult {
  std::vector<RayHit> hits;
  std::vector<uint32_t> visits;
  TraversalStats total;
  double seconds = 0;
};

RunResult runFirst(const SahKdTree& tree, const TriangleMesh& mesh, const std::vector<Ray>& rays, const Config& c,
                   TriangleTest test) {
  RunResult out;
  out.hits.resize(rays.size());
  out.visits.resize(rays.size());
  const int64_t n = static_cast<int64_t>(rays.size());
  uint64_t nodes = 0, prims = 0;
  const double t0 = seconds();
#pragma omp parallel for schedule(dynamic, 256) reduction(+ : nodes, prims)
  for (int64_t i = 0; i < n; ++i) {
    TraversalStats st;
    tree.intersectFirst(mesh, rays[i].o, rays[i].d, rays[i].tmin, rays[i].tmax, out.hits[i], c.traversal, test, &st,
                        c.K);
    out.visits[i] = static_cast<uint32_t>(st.nodeVisits);
    nodes += st.nodeVisits;
    prims += st.primTests;
  }
  out.seconds = seconds() - t0;
  out.total.nodeVisits = nodes;
  out.total.primTests = prims;
  return out;
}

/// Hits of two traversals, bit for bit.
int countDifferent(const std::vector<RayHit>& a, const std::vector<RayHit>& b, std::string* first) {
  int bad = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    const bool same = a[i].prim == b[i].prim && std::memcmp(&a[i].t, &b[i].t, sizeof(double)) == 0 &&
                      a[i].u == b[i].u && a[i].v == b[i].v;
    if (!same && bad++ == 0 && first) {
      char buf[200];
      std::snprintf(buf, sizeof buf, "ray %zu: prim %d t %.17g vs prim %d t %.17g", i,
                    a[i].hit() ? int(a[i].prim) : -1, a[i].t, b[i].hit() ? int(b[i].prim) : -1, b[i].t);
      *first = buf;
    }
  }
  return bad;
}

// ---------------------------------------------------------------------------------------------
// The 7 real meshes
// ---------------------------------------------------------------------------------------------
class RealMeshSah : public ::testing::TestWithParam<std::string> {};

TEST_P(RealMeshSah, AllTraversalsEqualBruteForce) {
  const std::string rel = GetParam();
  const TriangleMesh mesh = mtest::loadRealMesh(rel);
  const SahKdTree tree(mesh);
  const mtree::SahBuildStats& bs = tree.stats();
  std::printf(
      "[sah build] %-28s tris %llu  nodes %llu  leaves %llu (empty %llu)  refs %llu (%.2f/tri)  depth %d/%d  "
      "max leaf %u  %.1f MiB  SAH cost %.1f  build %.0f ms\n",
      rel.c_str(), (unsigned long long)bs.primitives, (unsigned long long)bs.nodes, (unsigned long long)bs.leaves,
      (unsigned long long)bs.emptyLeaves, (unsigned long long)bs.references,
      double(bs.references) / std::max<uint64_t>(bs.primitives, 1), bs.depth, bs.maxDepth, bs.maxLeafSize,
      bs.bytes / 1048576.0, bs.sahCost, bs.buildMs);
  RecordProperty("buildMs", static_cast<int>(bs.buildMs));
  ASSERT_FALSE(tree.empty());
  EXPECT_EQ(bs.nodes, 2 * bs.leaves - 1);
  EXPECT_EQ(bs.bytes, bs.nodes * 8 + bs.references * 4);
  EXPECT_LE(bs.depth, bs.maxDepth);
  EXPECT_GE(bs.references, bs.primitives);

  const int nRays = raysFor(mesh.size());
  const std::vector<Ray> rays = makeRays(mesh, tree, nRays, mtest::seedFor(rel, 31));
  const mtest::TimedFirstHits reference(mesh, rays);
  const std::vector<RayHit>& ref = reference.hits;
  const double bfSeconds = reference.elapsed;
  double t0;
  uint64_t refHits = 0;
  for (const RayHit& h : ref) refHits += h.hit();
  EXPECT_GT(refHits, static_cast<uint64_t>(nRays / 10)) << "too few rays hit: the test would be weak";

  std::vector<RunResult> runs;
  for (const Config& c : kConfigs) {
    SCOPED_TRACE(c.name);
    runs.push_back(runFirst(tree, mesh, rays, c, TriangleTest::MollerTrumbore));
    const RunResult& run = runs.back();
    mtest::HitComparison cmp;
    for (size_t i = 0; i < rays.size(); ++i) cmp.add(run.hits[i], ref[i], rays[i], i);
    EXPECT_EQ(cmp.mismatches, 0u) << "first: " << cmp.firstMismatch;
    std::string first;
    EXPECT_EQ(countDifferent(run.hits, runs[0].hits, &first), 0) << "differs from stack: " << first;
    std::printf(
        "[sah rays] %-28s %-11s rays %d  hits %llu  id differs (same t) %llu  mismatches %llu  "
        "nodes/ray %.1f  tests/ray %.1f  %.3fs  (brute force %.1fs)\n",
        rel.c_str(), c.name, nRays, (unsigned long long)cmp.hits, (unsigned long long)cmp.idDiffers,
        (unsigned long long)cmp.mismatches, double(run.total.nodeVisits) / nRays,
        double(run.total.primTests) / nRays, run.seconds, bfSeconds);
    // Stack visits every node at most once; the others revisit ancestors.
    int moreVisits = 0;
    for (size_t i = 0; i < rays.size(); ++i) moreVisits += runs[0].visits[i] > run.visits[i];
    EXPECT_EQ(moreVisits, 0) << "rays where stack visits more nodes than " << c.name;
  }
  EXPECT_LE(runs[0].total.nodeVisits, runs[1].total.nodeVisits);
  for (const RunResult& run : runs) EXPECT_EQ(run.total.primTests, runs[0].total.primTests);  // same leaves

  // Any hit on every 7th ray, with T around the reference hit (exactly at it, just before it,
  // after it, or anywhere before it). A hit exists in [tmin, T] iff the reference's t <= T.
  mtest::Rng rng(mtest::seedFor(rel, 37));
  std::vector<double> Ts;
  std::vector<size_t> idx;
  for (size_t i = 0; i < rays.size(); i += 7) {
    const Ray& r = rays[i];
    double T = r.tmax;
    if (ref[i].hit()) {
      switch (rng.below(4)) {
        case 0:
          T = ref[i].t;
          break;
        case 1:
          T = std::nextafter(ref[i].t, -kInf);
          break;
        case 2:
          T = std::min(r.tmax, ref[i].t * rng.uniform(1.0, 2.0));
          break;
        default:
          T = r.tmin + (ref[i].t - r.tmin) * rng.uniform(0.0, 1.0);
          break;
      }
    }
    Ts.push_back(T);
    idx.push_back(i);
  }
  for (const Config& c : kConfigs) {
    SCOPED_TRACE(c.name);
    int wrong = 0, yes = 0, no = 0;
    std::string firstWrong;
    for (size_t j = 0; j < idx.size(); ++j) {
      const size_t i = idx[j];
      const Ray& r = rays[i];
      const bool expected = ref[i].hit() && ref[i].t <= Ts[j];
      const bool any = tree.intersectAny(mesh, r.o, r.d, r.tmin, Ts[j], c.traversal, TriangleTest::MollerTrumbore,
                                         nullptr, c.K);
      (expected ? yes : no)++;
      if (any != expected && wrong++ == 0) {
        char buf[400];
        std::snprintf(buf, sizeof buf,
                      "ray %zu o=(%.17g, %.17g, %.17g) d=(%.17g, %.17g, %.17g) tmin=%.17g T=%.17g: any %d, "
                      "reference prim %d t %.17g",
                      i, r.o.x, r.o.y, r.o.z, r.d.x, r.d.y, r.d.z, r.tmin, Ts[j], any,
                      ref[i].hit() ? int(ref[i].prim) : -1, ref[i].t);
        firstWrong = buf;
      }
    }
    EXPECT_EQ(wrong, 0) << firstWrong;
    EXPECT_GT(yes, 0);
    EXPECT_GT(no, 0);
  }

  // The watertight test through the tree against a watertight brute force, on a sample.
  const size_t sample = static_cast<size_t>(std::min(3000.0, std::max(300.0, 6e7 / mesh.size())));
  std::vector<Ray> wrays;
  for (size_t i = 0; i < sample; ++i) wrays.push_back(rays[(i * 7919) % rays.size()]);
  std::vector<RayHit> wref(wrays.size());
  t0 = seconds();
#pragma omp parallel for schedule(dynamic, 8)
  for (int64_t i = 0; i < static_cast<int64_t>(wrays.size()); ++i) wref[i] = bruteForceWatertight(mesh, wrays[i]);
  const double wbfSeconds = seconds() - t0;
  std::vector<RayHit> wstack;
  for (const Config& c : kConfigs) {
    SCOPED_TRACE(std::string("watertight ") + c.name);
    const RunResult run = runFirst(tree, mesh, wrays, c, TriangleTest::Watertight);
    mtest::HitComparison cmp;
    for (size_t i = 0; i < wrays.size(); ++i) cmp.add(run.hits[i], wref[i], wrays[i], i);
    EXPECT_EQ(cmp.mismatches, 0u) << "first: " << cmp.firstMismatch;
    if (wstack.empty()) {
      wstack = run.hits;
      std::printf("[sah watertight] %-28s rays %zu  hits %llu  id differs %llu  (brute force %.1fs)\n", rel.c_str(),
                  wrays.size(), (unsigned long long)cmp.hits, (unsigned long long)cmp.idDiffers, wbfSeconds);
    }
    std::string first;
    EXPECT_EQ(countDifferent(run.hits, wstack, &first), 0) << "differs from stack: " << first;
  }
}

INSTANTIATE_TEST_SUITE_P(RealMeshes, RealMeshSah, ::testing::ValuesIn(mtest::realMeshes()),
                         [](const ::testing::TestParamInfo<std::string>& info) {
                           return mtest::meshTag(info.param);
                         });

// ---------------------------------------------------------------------------------------------
// Helpers of the synthetic tests
// ---------------------------------------------------------------------------------------------


struct Agreement {
  uint64_t rays = 0, hits = 0, idDiffers = 0, mismatches = 0, anyWrong = 0, differsFromStack = 0;
  std::string first;
};

// Every traversal (and, with `test`, that triangle test) against the brute force of the same test:
// first hits, any hits over [tmin, tmax], and first hits bit for bit equal to the stack's.
Agreement agree(const SahKdTree& tree, const TriangleMesh& mesh, const std::vector<Ray>& rays,
                TriangleTest test = TriangleTest::MollerTrumbore) {
  Agreement ag;
  std::vector<RayHit> ref;
  if (test == TriangleTest::MollerTrumbore) {
    ref = mtest::BruteForce(mesh).firstAll(rays);
  } else {
    ref.resize(rays.size());
    for (size_t i = 0; i < rays.size(); ++i) ref[i] = bruteForceWatertight(mesh, rays[i]);
  }
  std::vector<RayHit> stackHits;
  for (const Config& c : kConfigs) {
    const RunResult run = runFirst(tree, mesh, rays, c, test);
    mtest::HitComparison cmp;
    for (size_t i = 0; i < rays.size(); ++i) {
      cmp.add(run.hits[i], ref[i], rays[i], i);
      const Ray& r = rays[i];
      if (tree.intersectAny(mesh, r.o, r.d, r.tmin, r.tmax, c.traversal, test, nullptr, c.K) != ref[i].hit())
        ++ag.anyWrong;
    }
    if (stackHits.empty()) stackHits = run.hits;
    ag.differsFromStack += countDifferent(run.hits, stackHits, nullptr);
    ag.rays = cmp.rays;
    ag.hits = cmp.hits;
    ag.idDiffers += cmp.idDiffers;
    ag.mismatches += cmp.mismatches;
    if (ag.first.empty() && cmp.mismatches) ag.first = std::string(c.name) + ": " + cmp.firstMismatch;
  }
  return ag;
}

#define EXPECT_SAH_AGREES(agreement)                                                         \
  do {                                                                                       \
    const Agreement& ag_ = (agreement);                                                      \
    EXPECT_EQ(ag_.mismatches, 0u) << ag_.first;                                              \
    EXPECT_EQ(ag_.anyWrong, 0u) << "intersectAny disagrees with the brute force";            \
    EXPECT_EQ(ag_.differsFromStack, 0u) << "a traversal's first hit differs from the stack's"; \
  } while (0)

// ---------------------------------------------------------------------------------------------
// Watertightness
// ---------------------------------------------------------------------------------------------

// Rays through points of shared edges and through shared vertices of closed spheres, from inside
// and from outside: each must hit. Möller–Trumbore lets some through (counted, printed); the
// watertight test must let none through, by brute force and through the tree.
TEST(SahWatertight, NoRayFallsThroughEdgesOrVerticesOfClosedSpheres) {
  struct Sphere {
    int subdiv;
    double radius;
    Vec3 center;
  };
  const Sphere spheres[] = {{4, 1.0, Vec3(0, 0, 0)}, {3, 0.37, Vec3(3.1, -7.3, 11.9)}, {5, 2.5, Vec3(1e3, -2e3, 5e2)}};
  uint64_t mtLeaksTotal = 0, rayTotal = 0;
  for (const Sphere& sp : spheres) {
    const TriangleMesh mesh = mtest::makeIcosphere(sp.subdiv, sp.radius, sp.center);
    const SahKdTree tree(mesh);
    mtest::Rng rng(mtest::seedFor("leaks", sp.subdiv));
    const int n = 6000;
    const std::vector<Ray> rays = mtest::edgeAndVertexRays(mesh, sp.center, sp.radius, n, rng);
    int mtBrute = 0, wtBrute = 0;
    for (const Ray& r : rays) {
      RayHit h;
      mtBrute += !mtree::intersectFirstBruteForce(mesh, r.o, r.d, 0, kInf, h);
      wtBrute += !bruteForceWatertight(mesh, r).hit();
    }
    EXPECT_EQ(wtBrute, 0) << "watertight brute force lets rays through";
    for (const Config& c : kConfigs) {
      SCOPED_TRACE(c.name);
      int mtTree = 0, wtTree = 0, wtAnyMiss = 0;
      for (const Ray& r : rays) {
        RayHit h;
        mtTree += !tree.intersectFirst(mesh, r.o, r.d, 0, kInf, h, c.traversal, TriangleTest::MollerTrumbore,
                                       nullptr, c.K);
        wtTree += !tree.intersectFirst(mesh, r.o, r.d, 0, kInf, h, c.traversal, TriangleTest::Watertight, nullptr,
                                       c.K);
        wtAnyMiss += !tree.intersectAny(mesh, r.o, r.d, 0, kInf, c.traversal, TriangleTest::Watertight, nullptr, c.K);
      }
      EXPECT_EQ(wtTree, 0) << "watertight first hit through the tree lets rays through";
      EXPECT_EQ(wtAnyMiss, 0) << "watertight any hit through the tree lets rays through";
      EXPECT_EQ(mtTree, mtBrute) << "the tree changes Möller–Trumbore's answer";
      if (c.traversal == SahTraversal::Stack) {
        std::printf(
            "[sah leaks] icosphere(%d) r=%g at (%g, %g, %g): %d rays through edges/vertices: Möller–Trumbore "
            "leaks %d (brute force %d), watertight leaks %d (brute force %d)\n",
            sp.subdiv, sp.radius, sp.center.x, sp.center.y, sp.center.z, n, mtTree, mtBrute, wtTree, wtBrute);
        mtLeaksTotal += mtTree;
      }
    }
    rayTotal += n;
    const Agreement ag = agree(tree, mesh, rays, TriangleTest::Watertight);
    EXPECT_SAH_AGREES(ag);
  }
  RecordProperty("mtLeaks", static_cast<int>(mtLeaksTotal));
}

TEST(SahWatertight, ContractMatchesMollerTrumbore) {
  // Same hit, t, u, v (to round-off) on ordinary rays; NaN and degenerate input rejected.
  mtest::Rng rng(5);
  int both = 0, disagree = 0;
  for (int i = 0; i < 20000; ++i) {
    const Vec3 a = rng.inBox(Box{Vec3(-1, -1, -1), Vec3(1, 1, 1)}), b = rng.inBox(Box{Vec3(-1, -1, -1), Vec3(1, 1, 1)}),
               c = rng.inBox(Box{Vec3(-1, -1, -1), Vec3(1, 1, 1)});
    const Vec3 o = rng.direction() * 3.0, d = rng.inBox(Box{Vec3(-0.5, -0.5, -0.5), Vec3(0.5, 0.5, 0.5)}) - o;
    double t1 = 0, u1 = 0, v1 = 0, t2 = 0, u2 = 0, v2 = 0;
    const bool h1 = mtree::rayTriangleMT(o, d, a, b, c, 0, kInf, t1, u1, v1);
    const bool h2 = mtree::rayTriangleWatertight(o, d, a, b, c, 0, kInf, t2, u2, v2);
    const bool h3 = mtree::rayTriangle(TriangleTest::Watertight, o, d, a, b, c, 0, kInf, t2, u2, v2);
    EXPECT_EQ(h2, h3);
    if (h1 != h2) {
      ++disagree;  // only on the edge, to round-off
      const double m = std::min({u1, v1, 1 - u1 - v1, u2, v2, 1 - u2 - v2});
      EXPECT_LT(std::fabs(m), 1e-9) << "i=" << i;
      continue;
    }
    if (!h1) continue;
    ++both;
    EXPECT_NEAR(t1, t2, 1e-9 * std::max(1.0, t1));
    EXPECT_NEAR(u1, u2, 1e-9);
    EXPECT_NEAR(v1, v2, 1e-9);
    // The interval is closed and checked on t.
    double t, u, v;
    EXPECT_TRUE(mtree::rayTriangleWatertight(o, d, a, b, c, t2, t2, t, u, v));
    EXPECT_FALSE(mtree::rayTriangleWatertight(o, d, a, b, c, 0, std::nextafter(t2, 0.0), t, u, v));
    EXPECT_FALSE(mtree::rayTriangleWatertight(o, d, a, b, c, std::nextafter(t2, kInf), kInf, t, u, v));
  }
  EXPECT_GT(both, 1000);
  EXPECT_LT(disagree, 5);
  const Vec3 a(0, 0, 0), b(1, 0, 0), c(0, 1, 0);
  double t, u, v;
  ASSERT_TRUE(mtree::rayTriangleWatertight(Vec3(0.2, 0.3, 1), Vec3(0, 0, -1), a, b, c, 0, kInf, t, u, v));
  EXPECT_EQ(t, 1.0);
  EXPECT_DOUBLE_EQ(u, 0.2);
  EXPECT_DOUBLE_EQ(v, 0.3);
  // Backfaces count too; the opposite winding gives the same hit.
  ASSERT_TRUE(mtree::rayTriangleWatertight(Vec3(0.2, 0.3, -1), Vec3(0, 0, 1), a, c, b, 0, kInf, t, u, v));
  EXPECT_EQ(t, 1.0);
  // On an edge and on a vertex: inside.
  EXPECT_TRUE(mtree::rayTriangleWatertight(Vec3(0.5, 0, 1), Vec3(0, 0, -1), a, b, c, 0, kInf, t, u, v));
  EXPECT_TRUE(mtree::rayTriangleWatertight(Vec3(0, 0, 1), Vec3(0, 0, -1), a, b, c, 0, kInf, t, u, v));
  // NaN, infinity, zero direction, a ray in the plane, a degenerate triangle.
  for (const Vec3& o : {Vec3(kNaN, 0.3, 1), Vec3(0.2, kInf, 1), Vec3(0.2, 0.3, -kInf)})
    EXPECT_FALSE(mtree::rayTriangleWatertight(o, Vec3(0, 0, -1), a, b, c, 0, kInf, t, u, v));
  for (const Vec3& d : {Vec3(0, 0, kNaN), Vec3(0, 0, 0), Vec3(kInf, 0, -1), Vec3(1, 1, 0)})
    EXPECT_FALSE(mtree::rayTriangleWatertight(Vec3(0.2, 0.3, 1), d, a, b, c, 0, kInf, t, u, v));
  EXPECT_FALSE(mtree::rayTriangleWatertight(Vec3(-1, 0.25, 0), Vec3(1, 0, 0), a, b, c, 0, kInf, t, u, v));
  EXPECT_FALSE(mtree::rayTriangleWatertight(Vec3(0.2, 0, 1), Vec3(0, 0, -1), a, b, Vec3(2, 0, 0), 0, kInf, t, u, v));
  EXPECT_FALSE(mtree::rayTriangleWatertight(Vec3(0.2, 0.3, 1), Vec3(0, 0, -1), a, b, c, kNaN, kInf, t, u, v));
  EXPECT_FALSE(mtree::rayTriangleWatertight(Vec3(0.2, 0.3, 1), Vec3(0, 0, -1), a, b, c, 0, kNaN, t, u, v));
}

// ---------------------------------------------------------------------------------------------
// Build
// ---------------------------------------------------------------------------------------------

TEST(SahBuild, NodeLayout) {
  static_assert(sizeof(mtree::SahKdNode) == 8, "8-byte nodes");
  for (int axis = 0; axis < 3; ++axis)
    for (float s : {0.0f, -0.0f, 1.5f, -3.25e-20f, 1e30f})
      for (uint32_t child : {0u, 1u, 12345u, SahKdTree::kMaxIndex}) {
        const mtree::SahKdNode n = mtree::SahKdNode::inner(axis, s, child);
        EXPECT_FALSE(n.isLeaf());
        EXPECT_EQ(n.axis(), axis);
        const float got = n.split();
        EXPECT_EQ(std::memcmp(&got, &s, sizeof(float)), 0);
        EXPECT_EQ(n.leftChild(), child);
      }
  for (uint32_t count : {0u, 1u, 77u, 0xffffffffu})
    for (uint32_t off : {0u, 9u, SahKdTree::kMaxIndex}) {
      const mtree::SahKdNode n = mtree::SahKdNode::leaf(count, off);
      EXPECT_TRUE(n.isLeaf());
      EXPECT_EQ(n.primCount(), count);
      EXPECT_EQ(n.primOffset(), off);
    }
}

TEST(SahBuild, Deterministic) {
  const TriangleMesh hand = mtest::loadRealMesh("scenes/utah_hand/hand_00.obj");
  const TriangleMesh sphere = mtest::makeIcosphere(4);
  for (const TriangleMesh* mesh : {&hand, &sphere}) {
    const SahKdTree a(*mesh), b(*mesh);
    ASSERT_EQ(a.nodes().size(), b.nodes().size());
    EXPECT_TRUE(a.nodes() == b.nodes());
    EXPECT_TRUE(a.primitiveIndices() == b.primitiveIndices());
    EXPECT_EQ(a.stats().sahCost, b.stats().sahCost);
    EXPECT_EQ(a.stats().references, b.stats().references);
    for (int k = 0; k < 3; ++k) {
      EXPECT_EQ(a.rootBox().lo[k], b.rootBox().lo[k]);
      EXPECT_EQ(a.rootBox().hi[k], b.rootBox().hi[k]);
    }
    // Structure: children adjacent, every node reached once, leaves hold sorted valid ids, the
    // root box holds the mesh.
    std::vector<int> reached(a.nodes().size(), 0);
    std::vector<uint32_t> todo = {0};
    reached[0] = 1;
    uint64_t refs = 0;
    while (!todo.empty()) {
      const mtree::SahKdNode& nd = a.nodes()[todo.back()];
      todo.pop_back();
      if (nd.isLeaf()) {
        const uint32_t* p = a.primitiveIndices().data() + nd.primOffset();
        for (uint32_t k = 0; k < nd.primCount(); ++k) {
          EXPECT_LT(p[k], mesh->size());
          if (k) {
            EXPECT_LT(p[k - 1], p[k]);
          }
        }
        refs += nd.primCount();
        continue;
      }
      ASSERT_LT(nd.leftChild() + 1, a.nodes().size());
      for (uint32_t c : {nd.leftChild(), nd.leftChild() + 1}) {
        EXPECT_EQ(reached[c]++, 0);
        todo.push_back(c);
      }
    }
    EXPECT_EQ(refs, a.stats().references);
    for (int r : reached) EXPECT_EQ(r, 1);
    const Box mb = mtest::meshBounds(*mesh);
    for (int k = 0; k < 3; ++k) {
      EXPECT_LE(a.rootBox().lo[k], mb.lo[k]);
      EXPECT_GE(a.rootBox().hi[k], mb.hi[k]);
    }
  }
}

// The build's invariant: every leaf whose closed box holds a point of a triangle references the
// triangle. Checked at the vertices (exact points of their triangles): every leaf whose box holds
// the vertex (both children where it lies on a plane) must list every triangle at that vertex.
int leavesMissingTheirTriangles(const SahKdTree& tree, const TriangleMesh& mesh, size_t samples, uint64_t seed) {
  mtest::Rng rng(seed);
  int missing = 0;
  for (size_t i = 0; i < samples; ++i) {
    const uint32_t tri = rng.below(static_cast<uint32_t>(mesh.size()));
    const Vec3 v = mesh.vertex(tri, static_cast<int>(rng.below(3)));
    std::vector<uint32_t> todo = {0};
    while (!todo.empty()) {
      const mtree::SahKdNode& nd = tree.nodes()[todo.back()];
      todo.pop_back();
      if (nd.isLeaf()) {
        const uint32_t* b = tree.primitiveIndices().data() + nd.primOffset();
        missing += !std::binary_search(b, b + nd.primCount(), tri);
        continue;
      }
      const double w = tree.planeWorld(nd.axis(), nd.split());
      if (v[nd.axis()] <= w) todo.push_back(nd.leftChild());
      if (v[nd.axis()] >= w) todo.push_back(nd.leftChild() + 1);
    }
  }
  return missing;
}

TEST(SahBuild, ClosedLeafBoxesHoldTheirTriangles) {
  std::vector<double> p;  // unit boxes on a grid of 0.25: vertices on many planes at once
  std::vector<uint32_t> t;
  mtest::Rng rng(8);
  for (int b = 0; b < 60; ++b) {
    const Vec3 lo(0.25 * rng.below(12), 0.25 * rng.below(12), 0.25 * rng.below(12));
    const uint32_t base = static_cast<uint32_t>(p.size() / 3);
    for (int k = 0; k < 8; ++k)
      p.insert(p.end(), {lo.x + (k & 1 ? 0.5 : 0), lo.y + (k & 2 ? 0.25 : 0), lo.z + (k & 4 ? 0.75 : 0)});
    const uint32_t quads[6][4] = {{0, 2, 6, 4}, {1, 5, 7, 3}, {0, 4, 5, 1}, {2, 3, 7, 6}, {0, 1, 3, 2}, {4, 6, 7, 5}};
    for (const auto& q : quads)
      t.insert(t.end(), {base + q[0], base + q[1], base + q[2], base + q[0], base + q[2], base + q[3]});
  }
  const TriangleMesh boxes(p, t);
  const TriangleMesh hand = mtest::loadRealMesh("scenes/utah_hand/hand_00.obj");
  const TriangleMesh far = transformed(hand, 10.0, Vec3(1e8, -1e8, 1e8));
  for (const TriangleMesh* mesh : {&boxes, &hand, &far}) {
    const SahKdTree tree(*mesh);
    EXPECT_EQ(leavesMissingTheirTriangles(tree, *mesh, 20000, 9), 0);
  }
}

TEST(SahBuild, OptionsAndDepthLimits) {
  const TriangleMesh mesh = mtest::makeIcosphere(3, 1.0, Vec3(0.3, -0.2, 0.1));
  std::vector<Ray> rays = aimedRays(mesh, 3000, 21);
  struct Case {
    mtree::SahBuildOptions opt;
    const char* name;
  };
  std::vector<Case> cases;
  for (int depth : {-1, 1, 2, 5, 100}) {
    mtree::SahBuildOptions o;
    o.maxDepth = depth;
    cases.push_back({o, "depth"});
  }
  mtree::SahBuildOptions expensiveTraversal;
  expensiveTraversal.costTraverse = 1e6;  // never split
  cases.push_back({expensiveTraversal, "K_T 1e6"});
  mtree::SahBuildOptions noBonus;
  noBonus.emptyBonus = 1.0;
  cases.push_back({noBonus, "no empty bonus"});
  mtree::SahBuildOptions cheapTraversal;
  cheapTraversal.costTraverse = 0.01;
  cases.push_back({cheapTraversal, "K_T 0.01"});
  for (const Case& c : cases) {
    SCOPED_TRACE(std::string(c.name) + " maxDepth " + std::to_string(c.opt.maxDepth));
    const SahKdTree tree(mesh, c.opt);
    const mtree::SahBuildStats& st = tree.stats();
    EXPECT_LE(st.depth, std::max(0, std::min(c.opt.maxDepth == 0 ? 100 : c.opt.maxDepth, SahKdTree::kMaxDepth)));
    if (c.opt.maxDepth < 0 || c.opt.costTraverse > 1e5) {
      EXPECT_EQ(st.nodes, 1u);
    }
    EXPECT_SAH_AGREES(agree(tree, mesh, rays));
  }
}

// ---------------------------------------------------------------------------------------------
// Edge cases
// ---------------------------------------------------------------------------------------------

TEST(SahEdgeCases, EmptyMesh) {
  for (const TriangleMesh& mesh : {TriangleMesh(), TriangleMesh({0, 0, 0, 1, 1, 1}, {})}) {
    const SahKdTree tree(mesh);
    EXPECT_TRUE(tree.empty());
    EXPECT_EQ(tree.stats().nodes, 0u);
    EXPECT_EQ(tree.stats().references, 0u);
    EXPECT_EQ(tree.bytes(), 0u);
    for (const Config& c : kConfigs) {
      RayHit h;
      TraversalStats st;
      EXPECT_FALSE(tree.intersectFirst(mesh, Vec3(-1, 0.2, 0.3), Vec3(1, 0, 0), 0, kInf, h, c.traversal,
                                       TriangleTest::Watertight, &st, c.K));
      EXPECT_FALSE(h.hit());
      EXPECT_EQ(h.t, kInf);
      EXPECT_FALSE(tree.intersectAny(mesh, Vec3(-1, 0.2, 0.3), Vec3(1, 0.01, 0), 0, kInf, c.traversal,
                                     TriangleTest::MollerTrumbore, &st, c.K));
      EXPECT_EQ(st.nodeVisits, 0u);
      EXPECT_EQ(st.primTests, 0u);
    }
  }
}

TEST(SahEdgeCases, SingleTriangle) {
  const TriangleMesh mesh({0.1, 0.2, 0.3, 1.3, 0.1, 0.5, 0.4, 1.1, 0.9}, {0, 1, 2});
  const SahKdTree tree(mesh);
  EXPECT_EQ(tree.stats().nodes, 1u);  // one triangle: the leaf-size-1 stop
  const std::vector<Ray> rays = aimedRays(mesh, 3000, 1);
  for (TriangleTest test : {TriangleTest::MollerTrumbore, TriangleTest::Watertight}) {
    const Agreement ag = agree(tree, mesh, rays, test);
    EXPECT_SAH_AGREES(ag);
    EXPECT_GT(ag.hits, 1000u);
  }
}

TEST(SahEdgeCases, FlatScene) {
  // A 30 x 30 grid of quads in the plane z = 0.25 (the root box has no z extent), rays aimed at it,
  // rays in its plane and rays leaving it from a point on it.
  const int n = 30;
  const TriangleMesh mesh = mtest::flatGrid(n);
  const SahKdTree tree(mesh);
  EXPECT_GT(tree.stats().nodes, 1u);
  std::vector<Ray> rays = aimedRays(mesh, 3000, 5);
  mtest::Rng rng(6);
  for (int i = 0; i < 1500; ++i) {
    Ray r;
    r.o = Vec3(rng.uniform(-0.2, 1.2), rng.uniform(-0.2, 0.9), 0.25);
    r.d = rng.direction();
    if (i % 3 == 0) r.d.z = 0;                                      // in the plane
    if (i % 3 == 1) r.o.x = std::round(r.o.x * n) / n;              // from a grid line
    if (i % 6 == 1) r.d.x = 0;                                      // ... along it
    rays.push_back(r);
  }
  for (TriangleTest test : {TriangleTest::MollerTrumbore, TriangleTest::Watertight}) {
    const Agreement ag = agree(tree, mesh, rays, test);
    EXPECT_SAH_AGREES(ag);
    EXPECT_GT(ag.hits, 1500u);
  }
}

TEST(SahEdgeCases, DegenerateTriangles) {
  mtest::Rng rng(3);
  // (1) every triangle a point; (2) every triangle a segment; (3) a sphere with both mixed in.
  std::vector<double> p1, p2;
  std::vector<uint32_t> t1, t2;
  mtest::degenerateTriangles(rng, p1, t1, p2, t2);
  const TriangleMesh sphere = mtest::makeIcosphere(3, 1.0, Vec3(0.5, 1, 1.5));
  std::vector<double> p3 = sphere.points();
  std::vector<uint32_t> t3 = sphere.triangles();
  const uint32_t base = static_cast<uint32_t>(sphere.numPoints());
  p3.insert(p3.end(), p2.begin(), p2.end());
  for (uint32_t v : t2) t3.push_back(v + base);
  for (uint32_t i = 0; i < 200; ++i) t3.insert(t3.end(), {i, i, i});
  for (const TriangleMesh& mesh : {TriangleMesh(p1, t1), TriangleMesh(p2, t2), TriangleMesh(p3, t3)}) {
    const SahKdTree tree(mesh);
    std::vector<Ray> rays = aimedRays(mesh, 2000, 4);
    mtest::addVertexRays(rays, mesh, 500, rng);  // plus rays aimed exactly at vertices
    EXPECT_SAH_AGREES(agree(tree, mesh, rays));
  }
}

TEST(SahEdgeCases, AxisAlignedBoxes) {
  // Boxes on a grid of 0.25 (float-exact planes): many triangles lie in split planes, many planes
  // coincide, and the rays run along faces, edges and through corners.
  mtest::Rng rng(23);
  std::vector<double> p;
  std::vector<uint32_t> t;
  for (int b = 0; b < 40; ++b) {
    Vec3 lo, hi;
    for (int a = 0; a < 3; ++a) {
      const int i0 = static_cast<int>(rng.below(14)), len = 1 + static_cast<int>(rng.below(3));
      lo[a] = 0.25 * i0;
      hi[a] = 0.25 * (i0 + len);
    }
    const uint32_t base = static_cast<uint32_t>(p.size() / 3);
    for (int k = 0; k < 8; ++k) p.insert(p.end(), {k & 1 ? hi.x : lo.x, k & 2 ? hi.y : lo.y, k & 4 ? hi.z : lo.z});
    const uint32_t quads[6][4] = {{0, 2, 6, 4}, {1, 5, 7, 3}, {0, 4, 5, 1}, {2, 3, 7, 6}, {0, 1, 3, 2}, {4, 6, 7, 5}};
    for (const auto& q : quads)
      t.insert(t.end(), {base + q[0], base + q[1], base + q[2], base + q[0], base + q[2], base + q[3]});
  }
  const TriangleMesh mesh(p, t);
  const SahKdTree tree(mesh);
  EXPECT_GT(tree.stats().depth, 3);
  auto grid = [&](double lo, double hi) { return 0.25 * std::round(rng.uniform(lo, hi) * 4); };
  std::vector<Ray> rays = aimedRays(mesh, 2000, 24);
  for (int i = 0; i < 6000; ++i) {
    Ray r;
    switch (i % 4) {
      case 0: {  // axis-parallel on grid planes (in face planes, along edges)
        r.o = Vec3(grid(-0.5, 4.5), grid(-0.5, 4.5), grid(-0.5, 4.5));
        r.d = Vec3(0, 0, 0);
        r.d[rng.below(3)] = rng.below(2) ? 1.0 : -1.0;
        if (i % 8 == 0) r.o[rng.below(3)] += rng.uniform(-0.1, 0.1);
        break;
      }
      case 1: {  // in a grid plane, any direction in it
        r.o = Vec3(grid(-0.5, 4.5), rng.uniform(-0.5, 4.5), rng.uniform(-0.5, 4.5));
        r.d = rng.direction();
        r.d.x = 0;
        break;
      }
      case 2: {  // at a corner or an edge midpoint of a box
        const size_t tri = rng.below(static_cast<uint32_t>(mesh.size()));
        const Vec3 a = mesh.vertex(tri, 0), b = mesh.vertex(tri, 1);
        const Vec3 target = i % 8 == 2 ? a : (a + b) * 0.5;
        r.o = target + rng.direction() * rng.uniform(0.5, 6.0);
        r.d = target - r.o;
        break;
      }
      default: {  // from a corner
        r.o = mesh.vertex(rng.below(static_cast<uint32_t>(mesh.size())), static_cast<int>(rng.below(3)));
        r.d = rng.direction();
        if (i % 8 == 7) r.d[rng.below(3)] = 0;
        break;
      }
    }
    rays.push_back(r);
  }
  for (TriangleTest test : {TriangleTest::MollerTrumbore, TriangleTest::Watertight}) {
    SCOPED_TRACE(mtree::triangleTestName(test));
    const Agreement ag = agree(tree, mesh, rays, test);
    EXPECT_SAH_AGREES(ag);
    EXPECT_GT(ag.hits, 3000u);
    std::printf("[sah boxes] %s: rays %llu hits %llu id differs (same t) %llu\n", mtree::triangleTestName(test),
                (unsigned long long)ag.rays, (unsigned long long)ag.hits, (unsigned long long)ag.idDiffers);
  }
}

TEST(SahEdgeCases, HugeAndTinyCoordinates) {
  // The hand at 1e8 from the origin (scaled by 10: triangles of about 1e-2, float ulp there is 8,
  // so planes must be relative to the scene), a small sphere far out, and the hand scaled by 1e-12.
  const TriangleMesh hand = mtest::loadRealMesh("scenes/utah_hand/hand_00.obj");
  const TriangleMesh far = transformed(hand, 10.0, Vec3(1e8, -1e8, 1e8));
  const TriangleMesh sphere = mtest::makeIcosphere(3, 0.1, Vec3(-1e8, 1e8, 3e8));
  const TriangleMesh tiny = transformed(hand, 1e-12, Vec3(0, 0, 0));
  const TriangleMesh reference(hand);
  const SahKdTree refTree(reference);
  for (const TriangleMesh* mesh : {&far, &sphere, &tiny}) {
    const SahKdTree tree(*mesh);
    EXPECT_GT(tree.stats().depth, 10) << "the planes lost their resolution";
    if (mesh != &sphere) {
      EXPECT_GT(tree.stats().nodes, refTree.stats().nodes / 2);
    }
    const std::vector<Ray> rays = aimedRays(*mesh, 3000, 11);
    const Agreement ag = agree(tree, *mesh, rays);
    EXPECT_SAH_AGREES(ag);
    EXPECT_GT(ag.hits, 1000u);
  }
}

TEST(SahEdgeCases, NonFiniteZeroAndEmptyRaysMissQuickly) {
  const TriangleMesh mesh = mtest::makeIcosphere(3);
  const SahKdTree tree(mesh);
  const auto start = std::chrono::steady_clock::now();
  const Vec3 o(0.1, -3, 0.2), d(0, 1, 0);
  const Vec3 nan3(kNaN, kNaN, kNaN);
  struct Case {
    Vec3 o, d;
    double tmin, tmax;
  };
  const std::vector<Case> cases = {{Vec3(kNaN, -3, 0.2), d, 0, kInf},   {o, Vec3(0, kNaN, 0), 0, kInf},
                                   {nan3, nan3, 0, kInf},                {Vec3(kInf, -3, 0.2), d, 0, kInf},
                                   {Vec3(0.1, -kInf, 0.2), d, 0, kInf}, {o, Vec3(0, kInf, 0), 0, kInf},
                                   {o, Vec3(0, 0, 0), 0, kInf},          {o, Vec3(-0.0, 0.0, -0.0), 0, kInf},
                                   {o, d, kNaN, kInf},                   {o, d, 0, kNaN},
                                   {o, d, kNaN, kNaN},                   {o, d, kInf, kInf},
                                   {o, d, -kInf, -kInf},                 {o, d, 1.0, 0.5},
                                   {o, d, 0, 1.0},                       {o, Vec3(0, 1e-320, 0), 0, kInf}};
  for (const TriangleTest test : {TriangleTest::MollerTrumbore, TriangleTest::Watertight})
    for (const Config& c : kConfigs) {
      RayHit h;
      ASSERT_TRUE(tree.intersectFirst(mesh, o, d, 0, kInf, h, c.traversal, test, nullptr, c.K));
      for (size_t i = 0; i < cases.size(); ++i) {
        SCOPED_TRACE(std::string(c.name) + " case " + std::to_string(i));
        const Case& k = cases[i];
        EXPECT_FALSE(tree.intersectFirst(mesh, k.o, k.d, k.tmin, k.tmax, h, c.traversal, test, nullptr, c.K));
        EXPECT_FALSE(h.hit());
        EXPECT_FALSE(tree.intersectAny(mesh, k.o, k.d, k.tmin, k.tmax, c.traversal, test, nullptr, c.K));
      }
    }
  // Point intervals: [t, t] at the hit finds it, elsewhere nothing.
  RayHit h;
  ASSERT_TRUE(tree.intersectFirst(mesh, o, d, 0, kInf, h));
  for (const Config& c : kConfigs) {
    RayHit g;
    EXPECT_TRUE(tree.intersectFirst(mesh, o, d, h.t, h.t, g, c.traversal, TriangleTest::MollerTrumbore, nullptr, c.K));
    EXPECT_EQ(g.prim, h.prim);
    EXPECT_TRUE(tree.intersectAny(mesh, o, d, h.t, h.t, c.traversal, TriangleTest::MollerTrumbore, nullptr, c.K));
    EXPECT_FALSE(tree.intersectAny(mesh, o, d, 0.5 * h.t, 0.5 * h.t, c.traversal, TriangleTest::MollerTrumbore,
                                   nullptr, c.K));
  }
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_LT(secs, 2.0);
}

TEST(SahEdgeCases, ShortStackSizes) {
  const TriangleMesh mesh = mtest::loadRealMesh("scenes/utah_hand/hand_00.obj");
  const SahKdTree tree(mesh);
  const std::vector<Ray> rays = makeRays(mesh, tree, 20000, 41);
  const RunResult stack = runFirst(tree, mesh, rays, kConfigs[0], TriangleTest::MollerTrumbore);
  uint64_t prev = ~0ull;
  for (int K : {0, 1, 2, 3, 4, 8, 64, 1000, -5}) {
    SCOPED_TRACE("K = " + std::to_string(K));
    const RunResult run = runFirst(tree, mesh, rays, Config{SahTraversal::ShortStack, K, "shortstack"},
                                   TriangleTest::MollerTrumbore);
    std::string first;
    EXPECT_EQ(countDifferent(run.hits, stack.hits, &first), 0) << first;
    if (K >= 0 && K <= 64) {
      EXPECT_LE(run.total.nodeVisits, prev) << "a larger short stack visits more nodes";
      prev = run.total.nodeVisits;
    }
    if (K >= 64) {  // never overflows: the walk of a full stack
      EXPECT_EQ(run.visits, stack.visits);
      EXPECT_EQ(run.total.primTests, stack.total.primTests);
    }
  }
}

TEST(SahEdgeCases, RaysFromVerticesAndEdges) {
  const TriangleMesh hand = mtest::loadRealMesh("scenes/utah_hand/hand_00.obj");
  const TriangleMesh sphere = mtest::makeIcosphere(4);
  for (const TriangleMesh* mesh : {&hand, &sphere}) {
    const SahKdTree tree(*mesh);
    mtest::Rng rng(18);
    std::vector<Ray> rays;
    for (int i = 0; i < 4000; ++i) {
      const size_t tri = rng.below(static_cast<uint32_t>(mesh->size()));
      const int k = static_cast<int>(rng.below(3));
      const Vec3 a = mesh->vertex(tri, k), b = mesh->vertex(tri, (k + 1) % 3);
      Ray r;
      r.d = rng.direction();
      r.o = mtest::atVertexOrEdge(i % 4, a, b, r.d, 1.0, rng);
      rays.push_back(r);
    }
    for (TriangleTest test : {TriangleTest::MollerTrumbore, TriangleTest::Watertight}) {
      const Agreement ag = agree(tree, *mesh, rays, test);
      EXPECT_SAH_AGREES(ag);
      EXPECT_GT(ag.hits, 1000u);
    }
  }
}

// ---------------------------------------------------------------------------------------------
// The tracer in the renderer
// ---------------------------------------------------------------------------------------------

TEST(SahTracer, RendersLikeTheMatrixTree) {
  const TriangleMesh mesh = mtest::loadRealMesh("meshes/bunny.ply");
  const SahKdTree tree(mesh);
  const mtree::MatrixTree mt = mtest::buildTree(mesh, mtest::options(mtree::TreeKind::Octree));
  const Box box = mtest::meshBounds(mesh);
  mtree::Camera cam;
  cam.target = box.center();
  cam.eye = box.center() + Vec3(0.1, 0.05, 1.0) * (2.2 * mtree::norm(box.extent()));
  cam.width = cam.height = 96;
  mtree::RenderOptions opt;
  opt.counters = true;
  const mtree::RenderResult ref = mtree::render(mtree::MatrixTreeTracer{mt, mesh}, mesh, box, cam, opt);
  for (const Config& c : kConfigs)
    for (TriangleTest test : {TriangleTest::MollerTrumbore, TriangleTest::Watertight}) {
      SCOPED_TRACE(std::string(c.name) + " " + mtree::triangleTestName(test));
      const mtree::SahTracer tracer{tree, mesh, c.traversal, test, c.K};
      const mtree::RenderResult r = mtree::render(tracer, mesh, box, cam, opt);
      EXPECT_EQ(r.hits, ref.hits);
      EXPECT_GT(r.hits, 1000u);
      int differ = 0;
      for (size_t i = 0; i < r.hitPrim.size(); ++i)
        differ += r.hitPrim[i] != ref.hitPrim[i] &&
                  !(std::fabs(r.depth[i] - ref.depth[i]) <= 1e-5f * std::fabs(ref.depth[i]));
      EXPECT_EQ(differ, 0);
      if (test == TriangleTest::MollerTrumbore) {
        EXPECT_EQ(r.hitPrim, ref.hitPrim);
        EXPECT_EQ(r.rgb, ref.rgb);
      }
      EXPECT_GT(r.stats.nodeVisits, 0u);
    }
}

}  // namespace

// Edge cases of building and querying matrix trees: empty, single-triangle, degenerate, flat,
// line-like, huge- and tiny-coordinate scenes; invalid input; non-finite and zero rays; every
// explicit height; every block edge; rays from vertices and edges; empty and point intervals.
// Every ray answer is checked against the brute-force reference (same arithmetic, all triangles).
#include <gtest/gtest-spi.h>
#include <gtest/gtest.h>
#include <unistd.h>
#include <vtkCellArray.h>
#include <vtkNew.h>
#include <vtkPLYWriter.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkPolyDataWriter.h>
#include <vtkSTLWriter.h>
#include <vtkXMLPolyDataWriter.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "test_util.h"

namespace {

using mtest::aimedRays;
using mtest::pointOn;
using mtest::Ray;
using mtest::transformed;
using mtree::Box;
using mtree::MatrixTree;
using mtree::NodeRef;
using mtree::RayHit;
using mtree::TreeKind;
using mtree::TriangleMesh;
using mtree::Vec3;

const double kInf = std::numeric_limits<double>::infinity();
const double kNaN = std::numeric_limits<double>::quiet_NaN();
const TreeKind kKinds[2] = {TreeKind::Octree, TreeKind::RegularKd};

TriangleMesh merged(const TriangleMesh& a, const TriangleMesh& b) {
  std::vector<double> p = a.points();
  std::vector<uint32_t> t = a.triangles();
  const uint32_t base = static_cast<uint32_t>(a.numPoints());
  p.insert(p.end(), b.points().begin(), b.points().end());
  for (uint32_t v : b.triangles()) t.push_back(v + base);
  return TriangleMesh(std::move(p), std::move(t));
}



struct Agreement {
  mtest::HitComparison first;
  int anyWrong = 0;
  uint64_t hits() const { return first.hits; }
};

// intersectFirst and intersectAny of `tree` against the brute force over `mesh`.
Agreement agreeWithBruteForce(const MatrixTree& tree, const TriangleMesh& mesh,
                              const std::vector<Ray>& rays) {
  Agreement r;
  const mtest::BruteForce bf(mesh);
  const std::vector<RayHit> ref = bf.firstAll(rays);
  for (size_t i = 0; i < rays.size(); ++i) {
    const Ray& q = rays[i];
    RayHit h;
    mtree::intersectFirst(tree, mesh, q.o, q.d, q.tmin, q.tmax, h);
    r.first.add(h, ref[i], q, i);
    r.anyWrong += mtree::intersectAny(tree, mesh, q.o, q.d, q.tmin, q.tmax) != ref[i].hit();
  }
  return r;
}

#define EXPECT_AGREES(agreement)                                                          \
  do {                                                                                    \
    const Agreement& ag_ = (agreement);                                                   \
    EXPECT_EQ(ag_.first.mismatches, 0u) << "first mismatch: " << ag_.first.firstMismatch; \
    EXPECT_EQ(ag_.anyWrong, 0) << "intersectAny disagrees with the brute force";          \
  } while (0)

// leafFind vs leafFindTopDown on n points of the enlarged scene box.
int leafFindMismatches(const MatrixTree& t, const Box& box, int n, uint64_t seed) {
  mtest::Rng rng(seed);
  int bad = 0;
  for (int i = 0; i < n; ++i) {
    const Vec3 p = rng.inBox(box);
    const NodeRef a = t.leafFind(p), b = t.leafFindTopDown(p);
    bad += a.level != b.level || a.exists != b.exists ||
           (a.level >= 0 && (a.c[0] != b.c[0] || a.c[1] != b.c[1] || a.c[2] != b.c[2]));
  }
  return bad;
}

// ---------------------------------------------------------------------------------------------

TEST(EdgeCases, EmptyMesh) {
  for (const TriangleMesh& mesh : {TriangleMesh(), TriangleMesh({0, 0, 0, 1, 1, 1}, {})}) {
    for (TreeKind kind : kKinds) {
      mtree::BuildStats st;
      const MatrixTree t = mtest::buildTree(mesh, mtest::options(kind), &st);
      EXPECT_TRUE(t.empty());
      EXPECT_EQ(t.numLeaves(), 0u);
      EXPECT_TRUE(t.primitiveIndices().empty());
      EXPECT_EQ(st.primitives, 0u);
      EXPECT_EQ(st.references, 0u);
      for (const Vec3& p : {Vec3(0, 0, 0), Vec3(0.5, 0.5, 0.5), Vec3(1e300, -1e300, 0)}) {
        EXPECT_EQ(t.leafFind(p).level, -1);
        EXPECT_FALSE(t.leafFind(p).exists);
        EXPECT_EQ(t.leafFindTopDown(p).level, -1);
      }
      RayHit h;
      EXPECT_FALSE(mtree::intersectFirst(t, mesh, Vec3(-1, 0.2, 0.3), Vec3(1, 0, 0), 0, kInf, h));
      EXPECT_FALSE(h.hit());
      EXPECT_EQ(h.t, kInf);
      EXPECT_FALSE(mtree::intersectAny(t, mesh, Vec3(-1, 0.2, 0.3), Vec3(1, 0.01, 0), 0, kInf));
      int calls = 0;
      t.traverseRay(
          Vec3(0, 0, 0), Vec3(1, 1, 1), 0, kInf,
          [&](const uint32_t*, uint32_t, double, double) {
            ++calls;
            return false;
          },
          nullptr);
      EXPECT_EQ(calls, 0);
    }
  }
}

TEST(EdgeCases, SingleTriangle) {
  const TriangleMesh mesh({0.1, 0.2, 0.3, 1.3, 0.1, 0.5, 0.4, 1.1, 0.9}, {0, 1, 2});
  const std::vector<Ray> rays = aimedRays(mesh, 3000, 1);
  for (TreeKind kind : kKinds) {
    for (int h = 0; h <= 8; ++h) {  // 0 = automatic
      SCOPED_TRACE(std::string(mtree::treeKindName(kind)) + " height " + std::to_string(h));
      const MatrixTree t = mtest::buildTree(mesh, mtest::options(kind, h));
      ASSERT_FALSE(t.empty());
      const Agreement ag = agreeWithBruteForce(t, mesh, rays);
      EXPECT_AGREES(ag);
      EXPECT_GT(ag.hits(), 1000u);
      EXPECT_EQ(leafFindMismatches(t, mtest::enlarged(t.rootBox(), 0.1), 2000, 2), 0);
    }
  }
}

TEST(EdgeCases, AllDegenerateTriangles) {
  mtest::Rng rng(3);
  // (1) every triangle is a point; (2) every triangle is a segment (three collinear points,
  // exactly collinear where the coordinates allow it: a, a + v, a + 2v).
  std::vector<double> p1, p2;
  std::vector<uint32_t> t1, t2;
  mtest::degenerateTriangles(rng, p1, t1, p2, t2);
  for (const TriangleMesh& mesh : {TriangleMesh(p1, t1), TriangleMesh(p2, t2)}) {
    std::vector<Ray> rays = aimedRays(mesh, 2000, 4);
    mtest::addVertexRays(rays, mesh, 500, rng);  // plus rays aimed exactly at the vertices
    for (TreeKind kind : kKinds) {
      SCOPED_TRACE(mtree::treeKindName(kind));
      const MatrixTree t = mtest::buildTree(mesh, mtest::options(kind));
      ASSERT_FALSE(t.empty());
      EXPECT_AGREES(agreeWithBruteForce(t, mesh, rays));
      // Every degenerate triangle is still referenced by the leaf holding its first vertex.
      int lost = 0;
      for (size_t i = 0; i < mesh.size(); ++i) {
        const NodeRef n = t.leafFind(mesh.vertex(i, 0));
        if (!n.exists) {
          ++lost;
          continue;
        }
        const MtLeafRange r = t.leafRange(n);
        const auto& prims = t.primitiveIndices();
        lost += !std::binary_search(prims.begin() + r.begin, prims.begin() + r.end, static_cast<uint32_t>(i));
      }
      EXPECT_EQ(lost, 0);
    }
  }
}

TEST(EdgeCases, FlatScene) {
  // A 30 x 30 grid of quads in the plane z = 0.25: the root box has no z extent of its own.
  const TriangleMesh mesh = mtest::flatGrid(30);
  std::vector<Ray> rays = aimedRays(mesh, 3000, 5);
  mtest::Rng rng(6);
  for (int i = 0; i < 1000; ++i) {
    Ray r;
    r.o = Vec3(rng.uniform(-0.2, 1.2), rng.uniform(-0.2, 0.9), 0.25);
    if (i % 2) {  // in the plane
      r.d = rng.direction();
      r.d.z = 0;
    } else {  // leaving the plane from a point on it
      r.d = rng.direction();
    }
    rays.push_back(r);
  }
  for (TreeKind kind : kKinds) {
    SCOPED_TRACE(mtree::treeKindName(kind));
    const MatrixTree t = mtest::buildTree(mesh, mtest::options(kind));
    ASSERT_FALSE(t.empty());
    EXPECT_GT(t.rootBox().extent().z, 0.0);
    EXPECT_LE(t.rootBox().lo.z, 0.25);
    EXPECT_GE(t.rootBox().hi.z, 0.25);
    const Agreement ag = agreeWithBruteForce(t, mesh, rays);
    EXPECT_AGREES(ag);
    EXPECT_GT(ag.hits(), 1000u);
    EXPECT_EQ(leafFindMismatches(t, Box{Vec3(-0.1, -0.1, 0.25), Vec3(1.1, 0.8, 0.25)}, 5000, 7), 0);
  }
}

TEST(EdgeCases, LineLikeScenes) {
  mtest::Rng rng(8);
  // (1) a thin strip of small triangles, 1000 long, 1 x 0.5 across;
  // (2) a needle: every vertex on the x axis (all triangles degenerate, root box 0 x 0 across).
  std::vector<double> p1, p2;
  std::vector<uint32_t> t1, t2;
  for (uint32_t i = 0; i < 4000; ++i) {
    const Vec3 c(rng.uniform(0, 1000), rng.uniform(0, 1), rng.uniform(0, 0.5));
    for (int k = 0; k < 3; ++k) {
      const Vec3 q = c + rng.direction() * 0.3;
      p1.insert(p1.end(), {q.x, q.y, q.z});
      p2.insert(p2.end(), {c.x + rng.uniform(-0.3, 0.3), 0.0, 0.0});
    }
    t1.insert(t1.end(), {3 * i, 3 * i + 1, 3 * i + 2});
    t2.insert(t2.end(), {3 * i, 3 * i + 1, 3 * i + 2});
  }
  for (const TriangleMesh& mesh : {TriangleMesh(p1, t1), TriangleMesh(p2, t2)}) {
    std::vector<Ray> rays = aimedRays(mesh, 3000, 9);
    for (int i = 0; i < 300; ++i) {  // along the scene, the longest walks
      Ray r;
      r.o = Vec3(-10, rng.uniform(0, 1), rng.uniform(0, 0.5));
      r.d = Vec3(1, (i % 3) ? 0.0 : rng.uniform(-1e-3, 1e-3), 0);
      rays.push_back(r);
    }
    for (TreeKind kind : kKinds) {
      SCOPED_TRACE(mtree::treeKindName(kind));
      const MatrixTree t = mtest::buildTree(mesh, mtest::options(kind));
      ASSERT_FALSE(t.empty());
      EXPECT_AGREES(agreeWithBruteForce(t, mesh, rays));
      EXPECT_EQ(leafFindMismatches(t, mtest::enlarged(t.rootBox(), 0.05), 5000, 10), 0);
    }
  }
}

TEST(EdgeCases, HugeCoordinates) {
  // Triangles of about 1e-2 at 1e8 from the origin (ulp 1.5e-8): the bunny scaled by 10, and a
  // small sphere.
  const TriangleMesh bunny = transformed(mtest::loadRealMesh("meshes/bunny.ply"), 10.0, Vec3(1e8, -1e8, 1e8));
  const TriangleMesh sphere = mtest::makeIcosphere(3, 0.1, Vec3(-1e8, 1e8, 3e8));
  for (const TriangleMesh* mesh : {&bunny, &sphere}) {
    const std::vector<Ray> rays = aimedRays(*mesh, 3000, 11);
    for (TreeKind kind : kKinds) {
      SCOPED_TRACE(mtree::treeKindName(kind));
      const MatrixTree t = mtest::buildTree(*mesh, mtest::options(kind));
      EXPECT_GT(t.height(), 0);
      const Agreement ag = agreeWithBruteForce(t, *mesh, rays);
      EXPECT_AGREES(ag);
      EXPECT_GT(ag.hits(), 1000u);
      EXPECT_EQ(leafFindMismatches(t, mtest::enlarged(t.rootBox(), 0.05), 5000, 12), 0);
    }
  }
}

TEST(EdgeCases, TinyCoordinates) {
  // The whole bunny scaled by 1e-12 (coordinates ~1e-13, triangles ~1e-15).
  const TriangleMesh mesh = transformed(mtest::loadRealMesh("meshes/bunny.ply"), 1e-12, Vec3(0, 0, 0));
  const std::vector<Ray> rays = aimedRays(mesh, 3000, 13);
  for (TreeKind kind : kKinds) {
    SCOPED_TRACE(mtree::treeKindName(kind));
    const MatrixTree t = mtest::buildTree(mesh, mtest::options(kind));
    EXPECT_GT(t.height(), 0);
    const Agreement ag = agreeWithBruteForce(t, mesh, rays);
    EXPECT_AGREES(ag);
    EXPECT_GT(ag.hits(), 1000u);
    EXPECT_EQ(leafFindMismatches(t, mtest::enlarged(t.rootBox(), 0.05), 5000, 14), 0);
  }
}

TEST(EdgeCases, NonFiniteCoordinatesThrow) {
  const std::vector<uint32_t> tri = {0, 1, 2};
  for (double bad : {kNaN, kInf, -kInf}) {
    for (int k = 0; k < 9; ++k) {
      std::vector<double> p = {0, 0, 0, 1, 0, 0, 0, 1, 0};
      p[k] = bad;
      EXPECT_THROW(TriangleMesh(p, tri), std::invalid_argument) << "coordinate " << k << " = " << bad;
    }
    // An unused point must not be non-finite either: the mesh owns every coordinate.
    EXPECT_THROW(TriangleMesh({0, 0, 0, 1, 0, 0, 0, 1, 0, bad, 0, 0}, tri), std::invalid_argument);
    TriangleMesh ok({0, 0, 0, 1, 0, 0, 0, 1, 0}, tri);
    EXPECT_THROW(ok.setPoints({0, 0, 0, 1, bad, 0, 0, 1, 0}), std::invalid_argument);
    EXPECT_EQ(ok.points()[4], 0.0) << "a rejected setPoints must leave the mesh as it was";
  }
  TriangleMesh ok({0, 0, 0, 1, 0, 0, 0, 1, 0}, tri);
  EXPECT_THROW(ok.setPoints({0, 0, 0, 1, 0, 0}), std::invalid_argument);
  EXPECT_NO_THROW(ok.setPoints({0, 0, 1, 1, 0, 1, 0, 1, 1}));
  EXPECT_EQ(ok.vertex(0, 0).z, 1.0);
}

TEST(EdgeCases, BadIndicesAndCountsThrow) {
  const std::vector<double> p = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  EXPECT_THROW(TriangleMesh(p, {0, 1, 3}), std::invalid_argument);
  EXPECT_THROW(TriangleMesh(p, {0, 1, 2, 2, 1, 0xFFFFFFFFu}), std::invalid_argument);
  EXPECT_THROW(TriangleMesh(p, {0, 1}), std::invalid_argument);                // not a triple
  EXPECT_THROW(TriangleMesh({0, 0, 0, 1}, {0, 0, 0}), std::invalid_argument);  // not a triple
  EXPECT_THROW(TriangleMesh({}, {0, 0, 0}), std::invalid_argument);            // no points at all
  EXPECT_NO_THROW(TriangleMesh(p, {0, 1, 2, 2, 2, 2}));                        // degenerate is fine
}

TEST(EdgeCases, NonFiniteAndZeroRaysMissQuickly) {
  const TriangleMesh mesh = mtest::makeIcosphere(3);
  const auto start = std::chrono::steady_clock::now();
  for (TreeKind kind : kKinds) {
    const MatrixTree t = mtest::buildTree(mesh, mtest::options(kind));
    const Vec3 o(0.1, -3, 0.2), d(0, 1, 0);
    RayHit h;
    ASSERT_TRUE(mtree::intersectFirst(t, mesh, o, d, 0, kInf, h)) << "the sane ray must hit";
    const Vec3 nan3(kNaN, kNaN, kNaN);
    struct Case {
      Vec3 o, d;
      double tmin, tmax;
    };
    const std::vector<Case> cases = {{Vec3(kNaN, -3, 0.2), d, 0, kInf},
                                     {o, Vec3(0, kNaN, 0), 0, kInf},
                                     {nan3, nan3, 0, kInf},
                                     {Vec3(kInf, -3, 0.2), d, 0, kInf},
                                     {Vec3(0.1, -kInf, 0.2), d, 0, kInf},
                                     {o, Vec3(0, kInf, 0), 0, kInf},
                                     {o, Vec3(0, 0, 0), 0, kInf},
                                     {o, Vec3(-0.0, 0.0, -0.0), 0, kInf},
                                     {o, d, kNaN, kInf},
                                     {o, d, 0, kNaN},
                                     {o, d, kNaN, kNaN},
                                     {o, d, kInf, kInf},
                                     {o, d, -kInf, -kInf},
                                     {o, Vec3(0, 1e-320, 0), 0, kInf}};
    for (size_t i = 0; i < cases.size(); ++i) {
      const Case& c = cases[i];
      SCOPED_TRACE("case " + std::to_string(i));
      RayHit got;
      EXPECT_FALSE(mtree::intersectFirst(t, mesh, c.o, c.d, c.tmin, c.tmax, got));
      EXPECT_FALSE(got.hit());
      EXPECT_FALSE(mtree::intersectAny(t, mesh, c.o, c.d, c.tmin, c.tmax));
    }
    EXPECT_EQ(t.leafFind(nan3).level, -1);
    EXPECT_EQ(t.leafFind(Vec3(kInf, 0, 0)).level, -1);
    EXPECT_EQ(t.leafFindTopDown(nan3).level, -1);
  }
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_LT(s, 5.0) << "non-finite rays must not walk the tree for long";
}

// rayTriangleMT must not accept a ray whose barycentric coordinates are NaN. With an infinite
// origin coordinate, dot(s, p) is inf * 0 = NaN, and `uu < 0 || uu > 1` lets NaN through; the
// test then reports a hit at t = inf with u = v = NaN, so intersectFirstBruteForce "hits" a
// triangle nowhere near the ray while the tree (which rejects non-finite rays) misses.
TEST(EdgeCases, RayTriangleRejectsNaNBarycentrics) {
  const Vec3 a(-0.52573111211913359, 0.85065080835203999, 0);
  const Vec3 b(-0.6156420208736807, 0.78384304241997127, 0.081086293443303523);
  const Vec3 c(-0.48444164206066781, 0.86492933586327481, 0.13120037881301283);
  double t = 0, u = 0, v = 0;
  const bool hit = mtree::rayTriangleMT(Vec3(0.1, -kInf, 0.2), Vec3(0, 1, 0), a, b, c, 0.0, kInf, t, u, v);
  EXPECT_FALSE(hit) << "t = " << t << ", u = " << u << ", v = " << v;
  // The same through the brute-force reference over a sphere (the triangle above is its first).
  const TriangleMesh sphere = mtest::makeIcosphere(3);
  for (const Vec3& o : {Vec3(0.1, -kInf, 0.2), Vec3(kInf, 0.3, 0.1), Vec3(0.2, 0.1, -kInf)}) {
    RayHit ref;
    Vec3 d(0, 0, 0);
    for (int k = 0; k < 3; ++k)
      if (std::isinf(o[k])) d[k] = o[k] > 0 ? -1 : 1;
    mtree::intersectFirstBruteForce(sphere, o, d, 0, kInf, ref);
    EXPECT_FALSE(ref.hit()) << "o = (" << o.x << ", " << o.y << ", " << o.z << "): prim " << ref.prim << " t "
                            << ref.t << " u " << ref.u;
  }
}

// A sphere of 1280 triangles; for the deep levels, inside a scene box 80 wide (two specks at its
// corners), so that even the leaves of height 12 (about 1/5 of a triangle) keep the build cheap.
TEST(EdgeCases, EveryExplicitHeightGivesBruteForceHits) {
  const TriangleMesh sphere = mtest::makeIcosphere(3);
  const TriangleMesh specks(
      {-40, -40, -40, -39.99, -40, -40, -40, -39.99, -40, 40, 40, 40, 39.99, 40, 40, 40, 39.99, 40},
      {0, 1, 2, 3, 4, 5});
  const TriangleMesh wide = merged(sphere, specks);
  const std::vector<Ray> sphereRays = aimedRays(sphere, 1500, 15);
  for (TreeKind kind : kKinds) {
    const int maxH = kind == TreeKind::Octree ? 12 : 30;
    const int firstWide = kind == TreeKind::Octree ? 7 : 19;
    for (int h = 0; h <= maxH; ++h) {
      const bool deep = h >= firstWide;
      const TriangleMesh& mesh = deep ? wide : sphere;
      SCOPED_TRACE(std::string(mtree::treeKindName(kind)) + " height " + std::to_string(h));
      // Block edge 32 at octree height 12: with 8 the leaf pointer matrix alone is 512 MiB.
      const int B = kind == TreeKind::Octree && h == 12 ? 32 : 8;
      mtree::BuildStats st;
      MatrixTree t;
      mtree::MatrixTreeBuilder<TriangleMesh>::build(mesh, mtest::options(kind, h, B), t,
                                                    &st);  // 0: automatic
      if (h > 0) {
        EXPECT_EQ(t.height(), h);
        EXPECT_FALSE(st.autoHeight);
      }
      std::vector<Ray> rays = sphereRays;
      // Rays along node planes of this tree, parallel to them.
      mtest::Rng rng(100 + h);
      const int H = t.height();
      for (int i = 0; i < 300; ++i) {
        Ray r;
        r.o = rng.inBox(Box{Vec3(-1, -1, -1), Vec3(1, 1, 1)});
        r.d = rng.direction();
        const int a = i % 3;
        const int k = static_cast<int>(rng.below(static_cast<uint32_t>(t.dim(H, a) + 1)));
        r.o[a] = t.rootBox().lo[a] + k * t.cellSize(H)[a];
        r.d[a] = 0;
        rays.push_back(r);
      }
      const Agreement ag = agreeWithBruteForce(t, mesh, rays);
      EXPECT_AGREES(ag);
      EXPECT_GT(ag.hits(), 1000u);
      EXPECT_EQ(leafFindMismatches(t, Box{Vec3(-1.2, -1.2, -1.2), Vec3(1.2, 1.2, 1.2)}, 2000, 16), 0);
    }
  }
}

TEST(EdgeCases, BadOptionsThrow) {
  const TriangleMesh mesh = mtest::makeIcosphere(1);
  for (TreeKind kind : kKinds) {
    for (int h : {-1, MT_MAX_LEVELS, MT_MAX_LEVELS + 1, 1000})
      EXPECT_THROW(mtest::buildTree(mesh, mtest::options(kind, h)), std::invalid_argument) << "height " << h;
    for (int b : {0, -8, 3, 6, 64, 128})
      EXPECT_THROW(mtest::buildTree(mesh, mtest::options(kind, 0, b)), std::invalid_argument)
          << "block edge " << b;
    for (double s : {0.0, -1.0, kNaN}) {
      mtree::BuildOptions o = mtest::options(kind);
      o.leafScale = s;
      EXPECT_THROW(mtest::buildTree(mesh, o), std::invalid_argument) << "leafScale " << s;
    }
    // Options are checked before anything else, also for an empty mesh.
    EXPECT_THROW(mtest::buildTree(TriangleMesh(), mtest::options(kind, MT_MAX_LEVELS)),
                 std::invalid_argument);
    EXPECT_THROW(mtest::buildTree(TriangleMesh(), mtest::options(kind, 0, 5)), std::invalid_argument);
  }
}

TEST(EdgeCases, HeightsBeyondMemoryThrowAndLeaveAnEmptyTree) {
  // An octree over a cube root at height 13 needs 2^36 leaves: a 4 GiB leaf pointer matrix with
  // blocks of 8. Every height from there to the maximum must be refused, not attempted.
  const TriangleMesh mesh = mtest::makeIcosphere(1);
  for (int h = 13; h < MT_MAX_LEVELS; ++h) {
    MatrixTree t = mtest::buildTree(mesh, mtest::options(TreeKind::Octree, 3));
    ASSERT_FALSE(t.empty());
    EXPECT_THROW(
        mtree::MatrixTreeBuilder<TriangleMesh>::build(mesh, mtest::options(TreeKind::Octree, h), t, nullptr),
        std::length_error)
        << "octree height " << h;
    // Whatever a failed build left behind must answer queries safely (as an empty tree).
    EXPECT_TRUE(t.empty()) << "octree height " << h;
    RayHit hit;
    EXPECT_FALSE(mtree::intersectFirst(t, mesh, Vec3(0, 0, -5), Vec3(0, 0, 1), 0, kInf, hit));
    EXPECT_EQ(t.leafFind(Vec3(0, 0, 0)).level, -1);
  }
  for (int h = 40; h < MT_MAX_LEVELS; ++h)
    EXPECT_THROW(mtest::buildTree(mesh, mtest::options(TreeKind::RegularKd, h)), std::length_error)
        << "kd height " << h;
}

TEST(EdgeCases, BlockEdgesGiveIdenticalTreesAndHits) {
  const TriangleMesh mesh = mtest::loadRealMesh("scenes/utah_hand/hand_00.obj");
  const std::vector<Ray> rays = aimedRays(mesh, 5000, 17);
  for (TreeKind kind : kKinds) {
    const MatrixTree ref = mtest::buildTree(mesh, mtest::options(kind, 0, 8));
    const int H = ref.height();
    std::vector<RayHit> refHits(rays.size());
    for (size_t i = 0; i < rays.size(); ++i)
      mtree::intersectFirst(ref, mesh, rays[i].o, rays[i].d, rays[i].tmin, rays[i].tmax, refHits[i]);
    for (int B : {1, 2, 4, 16, 32}) {
      SCOPED_TRACE(std::string(mtree::treeKindName(kind)) + " block edge " + std::to_string(B));
      const MatrixTree t = mtest::buildTree(mesh, mtest::options(kind, H, B));
      ASSERT_EQ(t.height(), H);
      EXPECT_EQ(t.blockEdge(), B);
      EXPECT_EQ(t.numLeaves(), ref.numLeaves());
      EXPECT_EQ(t.primitiveIndices().size(), ref.primitiveIndices().size());
      // Same nodes at every level, same triangles in every leaf.
      uint64_t diff = 0;
      for (int l = 0; l <= H; ++l) {
        const int dx = ref.dim(l, 0), dy = ref.dim(l, 1), dz = ref.dim(l, 2);
        if (uint64_t(dx) * dy * dz > (1u << 22)) continue;  // the bottom of the kd-tree: via leaves below
        for (int z = 0; z < dz; ++z)
          for (int y = 0; y < dy; ++y)
            for (int x = 0; x < dx; ++x) {
              const int c[3] = {x, y, z};
              diff += t.nodeExists(l, c) != ref.nodeExists(l, c);
            }
      }
      EXPECT_EQ(diff, 0u) << "node existence differs";
      uint64_t leafDiff = 0;
      const auto& rp = ref.primitiveIndices();
      const auto& tp = t.primitiveIndices();
      const auto& rl = ref.leafLevel();
      for (size_t p = 0; p < rl.pointers().size(); ++p) {
        if (rl.pointers()[p] == MT_NULL) continue;
        for (uint32_t e = 0; e < rl.blockVolume(); ++e) {
          const uint32_t s = rl.pointers()[p] * rl.blockVolume() + e;
          const MtLeafRange r = rl.data()[s];
          if (r.begin == MT_NULL) continue;
          int c[3];
          // Coordinates of entry e of block p.
          const MtSparseDesc& d = rl.desc();
          const int bx = static_cast<int>(p % d.ptrDims[0]),
                    by = static_cast<int>((p / d.ptrDims[0]) % d.ptrDims[1]),
                    bz = static_cast<int>(p / (size_t(d.ptrDims[0]) * d.ptrDims[1]));
          c[0] = (bx << d.logBlock[0]) + static_cast<int>(e & ((1u << d.logBlock[0]) - 1));
          c[1] = (by << d.logBlock[1]) + static_cast<int>((e >> d.logBlock[0]) & ((1u << d.logBlock[1]) - 1));
          c[2] = (bz << d.logBlock[2]) + static_cast<int>(e >> (d.logBlock[0] + d.logBlock[1]));
          if (!t.nodeExists(H, c)) {
            ++leafDiff;
            continue;
          }
          const MtLeafRange q = t.leafLevel().get(c[0], c[1], c[2]);
          leafDiff +=
              !std::equal(rp.begin() + r.begin, rp.begin() + r.end, tp.begin() + q.begin, tp.begin() + q.end);
        }
      }
      EXPECT_EQ(leafDiff, 0u) << "leaf contents differ";
      uint64_t hitDiff = 0;
      for (size_t i = 0; i < rays.size(); ++i) {
        RayHit h;
        mtree::intersectFirst(t, mesh, rays[i].o, rays[i].d, rays[i].tmin, rays[i].tmax, h);
        hitDiff += h.prim != refHits[i].prim || !(h.t == refHits[i].t || (!h.hit() && !refHits[i].hit()));
      }
      EXPECT_EQ(hitDiff, 0u) << "hits differ from block edge 8";
    }
  }
}

TEST(EdgeCases, RaysFromVerticesAndEdges) {
  const TriangleMesh hand = mtest::loadRealMesh("scenes/utah_hand/hand_00.obj");
  const TriangleMesh sphere = mtest::makeIcosphere(4);
  for (const TriangleMesh* mesh : {&hand, &sphere}) {
    mtest::Rng rng(18);
    std::vector<Ray> rays;
    for (int i = 0; i < 4000; ++i) {
      const size_t tri = rng.below(static_cast<uint32_t>(mesh->size()));
      const int k = static_cast<int>(rng.below(3));
      const Vec3 a = mesh->vertex(tri, k), b = mesh->vertex(tri, (k + 1) % 3);
      Ray r;
      switch (i % 4) {
        case 0:
          r.o = a;
          r.d = rng.direction();
          break;  // from a vertex
        case 1:
          r.o = a + (b - a) * rng.uniform();
          r.d = rng.direction();
          break;  // from an edge
        case 2:   // at a vertex
          r.d = rng.direction();
          r.o = a - r.d * rng.uniform(0.01, 1.0);
          break;
        default:  // at an edge
          r.d = rng.direction();
          r.o = a + (b - a) * 0.5 - r.d * rng.uniform(0.01, 1.0);
          break;
      }
      rays.push_back(r);
    }
    for (TreeKind kind : kKinds) {
      SCOPED_TRACE(mtree::treeKindName(kind));
      const MatrixTree t = mtest::buildTree(*mesh, mtest::options(kind));
      const Agreement ag = agreeWithBruteForce(t, *mesh, rays);
      EXPECT_AGREES(ag);
      EXPECT_GT(ag.hits(), 1000u);
      std::printf("[edges] %s %s: rays %llu hits %llu id differs (same t) %llu\n",
                  mesh == &hand ? "hand" : "sphere", mtree::treeKindName(kind),
                  (unsigned long long)ag.first.rays, (unsigned long long)ag.first.hits,
                  (unsigned long long)ag.first.idDiffers);
    }
  }
}

TEST(EdgeCases, EmptyAndPointIntervals) {
  const TriangleMesh mesh = mtest::loadRealMesh("scenes/utah_hand/hand_00.obj");
  const std::vector<Ray> base = aimedRays(mesh, 2000, 19);
  const mtest::BruteForce bf(mesh);
  const std::vector<RayHit> ref = bf.firstAll(base);
  for (TreeKind kind : kKinds) {
    SCOPED_TRACE(mtree::treeKindName(kind));
    const MatrixTree t = mtest::buildTree(mesh, mtest::options(kind));
    int pointHits = 0;
    mtest::HitComparison point, after, both;
    for (size_t i = 0; i < base.size(); ++i) {
      const Ray& r = base[i];
      // tmin > tmax: nothing, and the walk never calls back.
      int calls = 0;
      t.traverseRay(
          r.o, r.d, 1.0, 0.5,
          [&](const uint32_t*, uint32_t, double, double) {
            ++calls;
            return false;
          },
          nullptr);
      EXPECT_EQ(calls, 0);
      RayHit h;
      EXPECT_FALSE(mtree::intersectFirst(t, mesh, r.o, r.d, 1.0, 0.5, h));
      EXPECT_FALSE(mtree::intersectAny(t, mesh, r.o, r.d, 1.0, 0.5));
      if (!ref[i].hit()) continue;
      ++pointHits;
      // The point interval [t*, t*] at the reference hit.
      Ray p = r;
      p.tmin = p.tmax = ref[i].t;
      const RayHit bp = bf.first(p);
      ASSERT_TRUE(bp.hit());
      mtree::intersectFirst(t, mesh, p.o, p.d, p.tmin, p.tmax, h);
      point.add(h, bp, p, i);
      EXPECT_TRUE(mtree::intersectAny(t, mesh, p.o, p.d, p.tmin, p.tmax)) << "ray " << i;
      // Just past the hit.
      p.tmin = std::nextafter(ref[i].t, kInf);
      p.tmax = kInf;
      mtree::intersectFirst(t, mesh, p.o, p.d, p.tmin, p.tmax, h);
      after.add(h, bf.first(p), p, i);
      // Negative tmin: hits behind the origin count too.
      p.tmin = -kInf;
      mtree::intersectFirst(t, mesh, p.o, p.d, p.tmin, p.tmax, h);
      both.add(h, bf.first(p), p, i);
    }
    EXPECT_EQ(point.mismatches, 0u) << "[t*, t*]: " << point.firstMismatch;
    EXPECT_EQ(after.mismatches, 0u) << "(t*, inf]: " << after.firstMismatch;
    EXPECT_EQ(both.mismatches, 0u) << "[-inf, inf]: " << both.firstMismatch;
    EXPECT_GT(pointHits, 500);
  }
}

// Rays from far away (up to 1e9 scene sizes: the walk's exit points then carry round-off far
// larger than the builder's box padding) and with tiny or huge direction vectors.
TEST(EdgeCases, FarOriginsAndScaledDirections) {
  const TriangleMesh mesh = mtest::loadRealMesh("scenes/utah_hand/hand_00.obj");
  const Box mb = mtest::meshBounds(mesh);
  const double diag = mtree::norm(mb.extent());
  std::vector<Ray> rays;
  mtest::Rng rng(21);
  for (double far : {1e3, 1e6, 1e9})
    for (double scale : {1.0, 1e-150, 1e150})
      for (int i = 0; i < 400; ++i) {
        Ray r;
        r.o = mb.center() + rng.direction() * (far * diag);
        r.d = mtree::normalized(pointOn(mesh, rng.below(static_cast<uint32_t>(mesh.size())), rng) - r.o) *
              scale;
        rays.push_back(r);
      }
  for (TreeKind kind : kKinds) {
    SCOPED_TRACE(mtree::treeKindName(kind));
    const MatrixTree t = mtest::buildTree(mesh, mtest::options(kind));
    const Agreement ag = agreeWithBruteForce(t, mesh, rays);
    EXPECT_AGREES(ag);
    EXPECT_GT(ag.hits(), rays.size() / 2);
  }
}

// Every triangle twice (ids i and i + n, bit-identical): each hit is a tie at the same t, and
// the documented rule picks the smaller id, in the tree exactly as in the brute force.
TEST(EdgeCases, DuplicateTrianglesTieBreakBySmallerId) {
  const TriangleMesh sphere = mtest::makeIcosphere(3);
  std::vector<uint32_t> tris = sphere.triangles();
  const std::vector<uint32_t> rotated = [&] {
    std::vector<uint32_t> r;  // the same triangles, corners rotated (same plane, other rounding)
    for (size_t i = 0; i < sphere.size(); ++i)
      r.insert(r.end(),
               {sphere.triangles()[3 * i + 1], sphere.triangles()[3 * i + 2], sphere.triangles()[3 * i]});
    return r;
  }();
  // Triangle i + n is triangle i again; i + 2n is triangle i with its corners rotated.
  tris.insert(tris.end(), sphere.triangles().begin(), sphere.triangles().end());
  tris.insert(tris.end(), rotated.begin(), rotated.end());
  const TriangleMesh mesh(sphere.points(), tris);
  const std::vector<Ray> rays = aimedRays(mesh, 4000, 22);
  const mtest::BruteForce bf(mesh);
  const std::vector<RayHit> ref = bf.firstAll(rays);
  for (TreeKind kind : kKinds) {
    SCOPED_TRACE(mtree::treeKindName(kind));
    const MatrixTree t = mtest::buildTree(mesh, mtest::options(kind));
    uint64_t differ = 0, hits = 0, upper = 0;
    for (size_t i = 0; i < rays.size(); ++i) {
      RayHit h;
      mtree::intersectFirst(t, mesh, rays[i].o, rays[i].d, rays[i].tmin, rays[i].tmax, h);
      differ += h.prim != ref[i].prim || (h.hit() && h.t != ref[i].t);
      hits += h.hit();
      upper += h.hit() && h.prim >= sphere.size() && h.prim < 2 * sphere.size();  // never: i wins the tie
    }
    EXPECT_EQ(differ, 0u) << "the tie rule (equal t: smaller id) must give the same triangle";
    EXPECT_EQ(upper, 0u);
    EXPECT_GT(hits, 2000u);
  }
}

// ---- the test helpers themselves ----------------------------------------------------------

// loadMesh reads every supported format, triangulates (a quad and a triangle strip become
// triangles) and merges duplicated points; a missing file fails the test with its path.
TEST(TestUtil, LoadMeshReadsEveryFormat) {
  vtkNew<vtkPoints> pts;
  for (const Vec3& p :
       {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(1, 1, 0), Vec3(0, 1, 0), Vec3(0, 0, 1), Vec3(1, 0, 1)})
    pts->InsertNextPoint(p.x, p.y, p.z);
  vtkNew<vtkCellArray> polys;
  const vtkIdType quad[4] = {0, 1, 2, 3}, tri[3] = {0, 1, 4}, tri2[3] = {1, 5, 4};
  polys->InsertNextCell(4, quad);
  polys->InsertNextCell(3, tri);
  polys->InsertNextCell(3, tri2);
  vtkNew<vtkPolyData> pd;
  pd->SetPoints(pts);
  pd->SetPolys(polys);
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("mtree_loadmesh_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  auto check = [&](const std::string& name) {
    SCOPED_TRACE(name);
    const TriangleMesh m = mtest::loadMesh((dir / name).string());
    EXPECT_EQ(m.size(), 4u);  // the quad gives two triangles
    EXPECT_EQ(m.numPoints(), 6u);
    const Box b = mtest::meshBounds(m);
    EXPECT_EQ(b.lo.x, 0.0);
    EXPECT_EQ(b.hi.x, 1.0);
    EXPECT_EQ(b.hi.z, 1.0);
  };
  {
    vtkNew<vtkPLYWriter> w;
    w->SetInputData(pd);
    w->SetFileName((dir / "m.ply").string().c_str());
    ASSERT_EQ(w->Write(), 1);
    check("m.ply");
  }
  {
    vtkNew<vtkSTLWriter> w;  // STL stores every triangle's corners: loadMesh merges them
    w->SetInputData(pd);
    w->SetFileName((dir / "m.stl").string().c_str());
    ASSERT_EQ(w->Write(), 1);
    check("m.stl");
  }
  {
    vtkNew<vtkXMLPolyDataWriter> w;
    w->SetInputData(pd);
    w->SetFileName((dir / "m.vtp").string().c_str());
    ASSERT_EQ(w->Write(), 1);
    check("m.vtp");
  }
  {
    vtkNew<vtkPolyDataWriter> w;
    w->SetInputData(pd);
    w->SetFileName((dir / "m.vtk").string().c_str());
    ASSERT_EQ(w->Write(), 1);
    check("m.vtk");
  }
  std::filesystem::remove_all(dir);
  EXPECT_NONFATAL_FAILURE(
      {
        try {
          mtest::loadMesh("/nonexistent/dir/missing.ply");
        } catch (const std::runtime_error&) {
        }
      },
      "missing.ply): file not found");
}

// The real meshes load with the triangle counts of the data README (hand: quads triangulated).
TEST(TestUtil, RealMeshesHaveTheirDocumentedTriangleCounts) {
  const std::vector<size_t> counts = {69451, 99970, 96966, 199034, 99938, 15855, 78029};
  ASSERT_EQ(mtest::realMeshes().size(), counts.size());
  for (size_t i = 0; i < counts.size(); ++i) {
    const TriangleMesh m = mtest::loadRealMesh(mtest::realMeshes()[i]);
    EXPECT_EQ(m.size(), counts[i]) << mtest::realMeshes()[i];
    EXPECT_LT(m.numPoints(), m.size()) << "duplicated points should have been merged";
  }
}

}  // namespace

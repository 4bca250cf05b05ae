// The hybrid matrix/SAH tree (paper §7; engine/include/mtree/trees/hybrid_tree.h).
//
// On each of the 7 real meshes: first hits equal the brute force's (same triangle, or the same t
// where two triangles meet), any-hit answers equal it, the watertight test through the tree
// equals a watertight walk of the matrix tree alone on a sample, and the per-leaf kd-trees hold
// their invariant (a seeded point of every listed triangle of a matrix leaf, inside the leaf's
// box, lies in a kd leaf whose closed box lists the triangle). Seeded rays as in test_sah
// (aimed at triangle points, vertices and edges, inside, axis-parallel, along the matrix's cell
// planes). Synthetic cases: with no kd-tree (leafTriangles above every leaf) the hybrid is its
// matrix tree, hit for hit and count for count; bad options; empty meshes.
#include <gtest/gtest.h>

#include <cstdio>
#include <string>
#include <vector>

#include "mtree/rays/raycast.h"
#include "mtree/trees/hybrid_tree.h"
#include "test_util.h"
#include "trees_test_util.h"

namespace {

using mtest::Ray;
using mtree::Box;
using mtree::HybridBuildOptions;
using mtree::HybridBuildStats;
using mtree::HybridTree;
using mtree::RayHit;
using mtree::SahKdNode;
using mtree::TraversalStats;
using mtree::TriangleMesh;
using mtree::TriangleTest;
using mtree::Vec3;

// Rays of splitTreeRays() over the matrix tree's bottom-level cell planes (a pointer tree of one
// plane per axis and cell boundary is not needed: aimed and in-box rays plus rays along planes).
std::vector<Ray> hybridRays(const TriangleMesh& mesh, const HybridTree& t, int n, uint64_t seed) {
  std::vector<Ray> rays = mtest::aimedRays(mesh, n * 3 / 4, seed);
  mtest::Rng rng(seed ^ 77);
  const Box rb = t.matrix().rootBox();
  const int H = t.matrix().height();
  while (static_cast<int>(rays.size()) < n) {
    Ray r;
    r.o = rng.inBox(rb);
    r.d = rng.direction();
    // In a cell plane of the matrix's leaf level, or in a kd plane of a random kd node.
    const int a = static_cast<int>(rng.below(3));
    if (rng.below(2) || t.kdNodes().empty()) {
      const int c = static_cast<int>(rng.below(static_cast<uint32_t>(t.matrix().dim(H, a))));
      r.o[a] = rb.lo[a] + c * t.matrix().cellSize(H)[a];
    } else {
      const SahKdNode& nd = t.kdNodes()[rng.below(static_cast<uint32_t>(t.kdNodes().size()))];
      if (!nd.isLeaf()) r.o[nd.axis()] = t.frame().world(nd.axis(), nd.split());
    }
    r.d[a] = 0;
    if (rng.below(4) == 0) r.d[(a + 1) % 3] = 0;
    rays.push_back(r);
  }
  for (size_t i = 9; i < rays.size(); i += 10) {
    const double scale = mtree::norm(rb.extent()) / std::max(mtree::norm(rays[i].d), 1e-300);
    rays[i].tmin = rng.uniform(0, 0.5) * scale;
    rays[i].tmax = rays[i].tmin + rng.uniform(0, 1.5) * scale;
  }
  return rays;
}

// Every triangle of every matrix leaf with a kd-tree, sampled at a point inside the leaf's box:
// the kd leaf reached by descending with that point (either side at a plane it lies on) lists it.
uint64_t kdInvariantViolations(const HybridTree& t, const TriangleMesh& mesh, uint64_t seed) {
  mtest::Rng rng(seed);
  const mtree::MatrixTree& m = t.matrix();
  const int H = m.height();
  uint64_t bad = 0;
  const auto& lv = m.leafLevel();
  for (uint32_t s = 0; s < lv.data().size(); ++s) {
    const MtLeafRange r = lv.data()[s];
    if (r.begin == MT_NULL) continue;
    int c[3];
    lv.entryCoords(s, c);
    const uint32_t root = t.subtreeOf(c);
    if (root == MT_NULL) continue;
    const Box box = m.nodeBox(H, c);
    for (uint32_t k = r.begin; k < r.end; ++k) {
      const uint32_t tri = m.primitiveIndices()[k];
      for (int tries = 0; tries < 8; ++tries) {
        const Vec3 p = mtest::pointOn(mesh, tri, rng);
        if (!box.contains(p)) continue;
        uint32_t n = root;
        while (!t.kdNodes()[n].isLeaf()) {
          const SahKdNode& nd = t.kdNodes()[n];
          const double w = t.frame().world(nd.axis(), nd.split());
          n = nd.leftChild() + (p[nd.axis()] > w || (p[nd.axis()] == w && rng.below(2)) ? 1 : 0);
        }
        const SahKdNode& leaf = t.kdNodes()[n];
        const auto b = t.kdPrimitives().begin() + leaf.primOffset();
        bad += !std::binary_search(b, b + leaf.primCount(), tri);
        break;
      }
    }
  }
  return bad;
}

class RealMeshHybrid : public ::testing::TestWithParam<std::string> {};

TEST_P(RealMeshHybrid, EqualsBruteForce) {
  const std::string rel = GetParam();
  const TriangleMesh mesh = mtest::loadRealMesh(rel);
  HybridTree tree;
  HybridBuildStats hs;
  tree.build(mesh, HybridBuildOptions{}, &hs);
  ASSERT_FALSE(tree.empty());
  EXPECT_GT(hs.subtrees, 0u) << "no matrix leaf got a kd-tree: the test would test the matrix tree only";
  std::printf("[hybrid] %-28s matrix height %d  kd-trees %llu  kd nodes %llu (depth %d)  build %.1f ms (matrix %.1f, "
              "kd %.1f)  %.2f MiB\n",
              rel.c_str(), tree.matrix().height(), (unsigned long long)hs.subtrees, (unsigned long long)hs.kdNodes,
              hs.kdDepth, hs.totalMs, hs.matrixMs, hs.subtreeMs, tree.bytes() / 1048576.0);
  EXPECT_EQ(kdInvariantViolations(tree, mesh, mtest::seedFor(rel, 3)), 0u);
  const std::vector<Ray> rays = hybridRays(mesh, tree, 6000, mtest::seedFor(rel, 47));
  const std::vector<RayHit> ref = mtest::BruteForce(mesh).firstAll(rays);
  mtest::HitComparison cmp;
  uint64_t anyWrong = 0;
  for (size_t i = 0; i < rays.size(); ++i) {
    const Ray& r = rays[i];
    RayHit h;
    tree.intersectFirst(mesh, r.o, r.d, r.tmin, r.tmax, h);
    cmp.add(h, ref[i], r, i);
    anyWrong += tree.intersectAny(mesh, r.o, r.d, r.tmin, r.tmax) != ref[i].hit();
  }
  EXPECT_EQ(cmp.mismatches, 0u) << cmp.firstMismatch;
  EXPECT_EQ(anyWrong, 0u);
  EXPECT_GT(cmp.hits, rays.size() / 4);
  // Watertight: the same triangles as the matrix tree's own walk with the watertight test (both
  // are exact walks, so the closest hit is the same up to ties at one t).
  mtest::HitComparison wt;
  for (size_t i = 0; i < rays.size(); i += 7) {
    RayHit a, b;
    tree.intersectFirst(mesh, rays[i].o, rays[i].d, rays[i].tmin, rays[i].tmax, a, TriangleTest::Watertight);
    mtree::intersectFirst<TriangleTest::Watertight>(tree.matrix(), mesh, rays[i].o, rays[i].d, rays[i].tmin,
                                                   rays[i].tmax, b);
    wt.add(a, b, rays[i], i);
  }
  EXPECT_EQ(wt.mismatches, 0u) << wt.firstMismatch;
}

INSTANTIATE_TEST_SUITE_P(RealMeshes, RealMeshHybrid, ::testing::ValuesIn(mtest::realMeshes()),
                         [](const ::testing::TestParamInfo<std::string>& info) {
                           return mtest::meshTag(info.param);
                         });

TEST(Hybrid, WithoutKdTreesItIsItsMatrixTree) {
  const TriangleMesh mesh = mtest::loadRealMesh("scenes/utah_hand/hand_00.obj");
  HybridBuildOptions o;
  o.leafTriangles = 1 << 30;
  HybridTree tree;
  HybridBuildStats hs;
  tree.build(mesh, o, &hs);
  EXPECT_EQ(hs.subtrees, 0u);
  EXPECT_TRUE(tree.kdNodes().empty());
  const std::vector<Ray> rays = hybridRays(mesh, tree, 2000, 5);
  uint64_t differ = 0;
  for (const Ray& r : rays) {
    RayHit a, b;
    TraversalStats sa, sb;
    tree.intersectFirst(mesh, r.o, r.d, r.tmin, r.tmax, a, TriangleTest::MollerTrumbore, &sa);
    mtree::intersectFirst(tree.matrix(), mesh, r.o, r.d, r.tmin, r.tmax, b, &sb);
    differ += !mtest::sameHitBits(a, b) || sa.nodeVisits != sb.nodeVisits || sa.primTests != sb.primTests;
  }
  EXPECT_EQ(differ, 0u);
}

TEST(Hybrid, BadOptionsAndEmptyMeshes) {
  const TriangleMesh one({0, 0, 0, 1, 0, 0, 0, 1, 0}, {0, 1, 2});
  HybridTree tree;
  HybridBuildOptions o;
  o.bins = 1;
  EXPECT_THROW(tree.build(one, o), std::invalid_argument);
  o = HybridBuildOptions{};
  o.maxDepth = 0;
  EXPECT_THROW(tree.build(one, o), std::invalid_argument);
  o = HybridBuildOptions{};
  o.leafTriangles = 0;
  EXPECT_THROW(tree.build(one, o), std::invalid_argument);
  tree.build(TriangleMesh{});
  EXPECT_TRUE(tree.empty());
  RayHit h;
  EXPECT_FALSE(tree.intersectFirst(TriangleMesh{}, Vec3(0, 0, 1), Vec3(0, 0, -1), 0, 10, h));
  tree.build(one);
  ASSERT_TRUE(tree.intersectFirst(one, Vec3(0.2, 0.2, 1), Vec3(0, 0, -1), 0, 10, h));
  EXPECT_EQ(h.prim, 0u);
  EXPECT_TRUE(tree.intersectAny(one, Vec3(0.2, 0.2, 1), Vec3(0, 0, -1), 0, 10));
  EXPECT_FALSE(tree.intersectAny(one, Vec3(0.2, 0.2, 1), Vec3(0, 0, -1), 0, 0.5));
}

}  // namespace

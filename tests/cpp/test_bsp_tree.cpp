// Implicit restricted BSP trees (paper §4.2; bsp_builder.h, implicit_tree.h).
//
// On the two Utah scenes: the SAH BSP tree over the 13 directions of a 26-DOP, stored
// implicitly, must give the brute force's first hits (same triangle, or the same t where two
// triangles meet) and any-hit answers with every traversal; Stack, Restart and Backtrack must
// agree bit for bit and visit the same leaves. Seeded rays as in test_implicit_kd, including
// rays lying in the tree's (diagonal) planes. The build's invariant is checked directly: every
// leaf lists every triangle that reaches its cell (a triangle point strictly inside a leaf's cell
// is in its list). Synthetic cases: the 3-direction build, option errors, empty and one-triangle
// meshes, watertight rays through the edges and vertices of a closed sphere.
#include <gtest/gtest.h>

#include <cstdio>
#include <string>
#include <vector>

#include "mtree/trees/bsp_builder.h"
#include "mtree/trees/implicit_tree.h"
#include "test_util.h"
#include "trees_test_util.h"

namespace {

using mtest::kTraversals;
using mtest::Ray;
using mtree::BspBuildOptions;
using mtree::BspBuildStats;
using mtree::ImplicitSplitTree;
using mtree::PointerSplitTree;
using mtree::RayHit;
using mtree::SplitTraversal;
using mtree::TraversalStats;
using mtree::TriangleMesh;
using mtree::TriangleTest;
using mtree::Vec3;

struct Agreement {
  uint64_t mismatches = 0, anyWrong = 0, notBitEqual = 0, leavesDiffer = 0, hits = 0;
  std::string first;
};

Agreement agree(const ImplicitSplitTree& tree, const TriangleMesh& mesh, const std::vector<Ray>& rays,
                TriangleTest test = TriangleTest::MollerTrumbore) {
  Agreement ag;
  const std::vector<RayHit> ref = mtest::BruteForce(mesh).firstAll(rays);
  std::vector<RayHit> stackHits(rays.size());
  std::vector<uint64_t> stackTests(rays.size());
  for (SplitTraversal trav : kTraversals) {
    mtest::HitComparison cmp;
    for (size_t i = 0; i < rays.size(); ++i) {
      const Ray& r = rays[i];
      RayHit h;
      TraversalStats st;
      tree.intersectFirst(mesh, r.o, r.d, r.tmin, r.tmax, h, trav, test, &st);
      cmp.add(h, ref[i], r, i);
      if (trav == SplitTraversal::Stack) {
        stackHits[i] = h;
        stackTests[i] = st.primTests;
      } else {
        ag.notBitEqual += !mtest::sameHitBits(h, stackHits[i]);
        ag.leavesDiffer += st.primTests != stackTests[i];
      }
      if (test == TriangleTest::MollerTrumbore)
        ag.anyWrong += tree.intersectAny(mesh, r.o, r.d, r.tmin, r.tmax, trav, test) != ref[i].hit();
    }
    if (test == TriangleTest::MollerTrumbore) ag.mismatches += cmp.mismatches;
    ag.hits = cmp.hits;
    if (ag.first.empty() && cmp.mismatches)
      ag.first = std::string(mtree::splitTraversalName(trav)) + ": " + cmp.firstMismatch;
  }
  return ag;
}

// Every leaf's cell (the intersection of its ancestors' half-spaces) and list: a seeded point of
// each triangle that lies strictly inside a leaf's cell (by more than the frame's pad on every
// plane) must be a triangle of that leaf.
uint64_t leafInvariantViolations(const PointerSplitTree& p, const TriangleMesh& mesh, int samplesPerTri,
                                 uint64_t seed) {
  mtest::Rng rng(seed);
  uint64_t bad = 0;
  for (size_t t = 0; t < mesh.size(); t += 3) {
    for (int s = 0; s < samplesPerTri; ++s) {
      const Vec3 x = mtest::pointOn(mesh, t, rng);
      // Descend to the leaf strictly containing x (stop where x lies on a plane, within the pad).
      uint32_t n = 0;
      bool onPlane = false;
      while (!p.nodes[n].leaf) {
        const auto& nd = p.nodes[n];
        const double d = p.frame.project(nd.dir, x) - p.frame.world(nd.dir, nd.s);
        if (std::fabs(d) <= 2 * p.frame.pad(nd.dir)) {
          onPlane = true;
          break;
        }
        n = nd.child + (d > 0 ? 1 : 0);
      }
      if (onPlane) continue;
      const auto& leaf = p.nodes[n];
      const auto b = p.prims.begin() + leaf.offset, e = b + leaf.count;
      bad += !std::binary_search(b, e, static_cast<uint32_t>(t));
    }
  }
  return bad;
}

class RealMeshBsp : public ::testing::TestWithParam<std::string> {};

TEST_P(RealMeshBsp, AllTraversalsEqualBruteForce) {
  const std::string rel = GetParam();
  const TriangleMesh mesh = mtest::loadRealMesh(rel);
  BspBuildStats bs;
  const PointerSplitTree p = mtree::buildBspTree(mesh, BspBuildOptions{}, &bs);
  ImplicitSplitTree tree;
  tree.build(p, mesh);
  ASSERT_FALSE(tree.empty());
  EXPECT_FALSE(tree.redistributed()) << "the builder chooses encodable planes";
  EXPECT_EQ(tree.numNodes(), bs.nodes);
  EXPECT_EQ(bs.nodes, 2 * bs.leaves - 1);
  EXPECT_EQ(p.prims.size(), bs.references);
  EXPECT_GT(bs.diagonalSplits, 0u) << "a 26-DOP build that never uses a diagonal plane tests nothing";
  std::printf("[bsp] %-28s nodes %llu (axis %llu, diagonal %llu)  depth %d  refs %.2f/tri  SAH %.1f  build %.0f ms  "
              "implicit %.2f MiB  pointer %.2f MiB\n",
              rel.c_str(), (unsigned long long)bs.nodes, (unsigned long long)bs.axisSplits,
              (unsigned long long)bs.diagonalSplits, bs.depth, double(bs.references) / mesh.size(), bs.sahCost,
              bs.buildMs, tree.bytes() / 1048576.0, p.pointerBytes() / 1048576.0);
  EXPECT_EQ(leafInvariantViolations(p, mesh, 2, mtest::seedFor(rel, 5)), 0u);
  const std::vector<Ray> rays = mtest::splitTreeRays(mesh, p, 4000, mtest::seedFor(rel, 83));
  const Agreement ag = agree(tree, mesh, rays);
  EXPECT_EQ(ag.mismatches, 0u) << ag.first;
  EXPECT_EQ(ag.anyWrong, 0u);
  EXPECT_EQ(ag.notBitEqual, 0u) << "a traversal's first hit differs from the stack's";
  EXPECT_EQ(ag.leavesDiffer, 0u) << "a traversal tested other triangles than the stack";
  EXPECT_GT(ag.hits, rays.size() / 4);
}

// The two Utah scenes (16k and 78k triangles): the BSP build takes seconds to minutes on the
// larger meshes; bench/trees.py checks all seven against the brute force.
const std::vector<std::string> kBspMeshes = {"scenes/utah_hand/hand_00.obj", "scenes/utah_ben/ben_00.obj"};
INSTANTIATE_TEST_SUITE_P(RealMeshes, RealMeshBsp, ::testing::ValuesIn(kBspMeshes),
                         [](const ::testing::TestParamInfo<std::string>& info) {
                           return mtest::meshTag(info.param);
                         });

TEST(Bsp, ThreeDirectionsIsAKdTree) {
  const TriangleMesh mesh = mtest::loadRealMesh("scenes/utah_hand/hand_00.obj");
  BspBuildOptions o;
  o.directions = 3;
  BspBuildStats bs;
  const PointerSplitTree p = mtree::buildBspTree(mesh, o, &bs);
  EXPECT_EQ(p.frame.count, 3);
  EXPECT_EQ(p.frame.tagBits, 2);
  EXPECT_EQ(bs.diagonalSplits, 0u);
  ImplicitSplitTree tree;
  tree.build(p, mesh);
  const Agreement ag = agree(tree, mesh, mtest::splitTreeRays(mesh, p, 3000, 29));
  EXPECT_EQ(ag.mismatches, 0u) << ag.first;
  EXPECT_EQ(ag.anyWrong, 0u);
  EXPECT_EQ(ag.notBitEqual, 0u);
}

TEST(Bsp, SplitPolygonsLieOnTheirPlanes) {
  const TriangleMesh mesh = mtest::loadRealMesh("scenes/utah_hand/hand_00.obj");
  mtree::BspBuildOptions o;
  o.maxDepth = 10;
  const PointerSplitTree p = mtree::buildBspTree(mesh, o);
  ImplicitSplitTree tree;
  tree.build(p, mesh);
  const std::vector<mtree::SplitPolygon> polys = tree.splitPolygons(10);
  uint64_t inner = 0;
  for (const auto& n : p.nodes) inner += !n.leaf;
  EXPECT_GT(polys.size(), inner * 9 / 10) << "a plane inside its cell must cut it";
  EXPECT_LE(polys.size(), inner);
  const double tol = 1e-9 * mtree::norm(mtest::meshBounds(mesh).extent());
  uint64_t off = 0, diagonal = 0;
  for (const mtree::SplitPolygon& q : polys) {
    EXPECT_GE(q.points.size(), 3u);
    diagonal += q.dir >= 3;
    // The plane's world distance from the node word at the root: every point on the plane.
    for (const Vec3& x : q.points) {
      const Vec3 n = tree.frame().normal[q.dir];
      const double w = mtree::dot(n, x);
      off += !(std::fabs(w - mtree::dot(n, q.points[0])) <= tol * mtree::norm(n));
    }
  }
  EXPECT_EQ(off, 0u);
  EXPECT_GT(diagonal, 0u);
}

TEST(Bsp, WatertightThroughEdgesAndVertices) {
  const TriangleMesh sphere = mtest::makeIcosphere(3, 1.0);
  const PointerSplitTree p = mtree::buildBspTree(sphere);
  ImplicitSplitTree tree;
  tree.build(p, sphere);
  mtest::Rng rng(7);
  const std::vector<Ray> rays = mtest::edgeAndVertexRays(sphere, Vec3(0, 0, 0), 1.0, 4000, rng);
  for (SplitTraversal trav : kTraversals) {
    uint64_t missed = 0;
    for (const Ray& r : rays) {
      RayHit h;
      missed += !tree.intersectFirst(sphere, r.o, r.d, r.tmin, r.tmax, h, trav, TriangleTest::Watertight);
    }
    EXPECT_EQ(missed, 0u) << mtree::splitTraversalName(trav);
  }
}

TEST(Bsp, OptionsAndSmallMeshes) {
  const TriangleMesh none;
  EXPECT_TRUE(mtree::buildBspTree(none).nodes.empty());
  const TriangleMesh one({0, 0, 0, 1, 0, 0, 0, 1, 0}, {0, 1, 2});
  const PointerSplitTree p = mtree::buildBspTree(one);
  ASSERT_EQ(p.nodes.size(), 1u);
  ImplicitSplitTree tree;
  tree.build(p, one);
  RayHit h;
  ASSERT_TRUE(tree.intersectFirst(one, Vec3(0.2, 0.2, 1), Vec3(0, 0, -1), 0, 10, h, SplitTraversal::Backtrack));
  EXPECT_EQ(h.prim, 0u);
  BspBuildOptions bad;
  bad.directions = 7;
  EXPECT_THROW(mtree::buildBspTree(one, bad), std::invalid_argument);
  bad = BspBuildOptions{};
  bad.bins = 1;
  EXPECT_THROW(mtree::buildBspTree(one, bad), std::invalid_argument);
  bad = BspBuildOptions{};
  bad.costIntersect = 0;
  EXPECT_THROW(mtree::buildBspTree(one, bad), std::invalid_argument);
}

}  // namespace

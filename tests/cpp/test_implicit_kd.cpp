// Implicit general kd-trees (paper §4.1, engine/include/mtree/trees/implicit_tree.h).
//
// On each of the 7 real meshes: the implicit tree built from the SAH kd-tree (block shape per
// level) must hold the same tree (every node's split, every leaf's triangles, at the position
// derived from its parent), and its three traversals must give the brute force's first hits
// (same triangle, or the same t where two triangles meet), the SAH stack traversal's hits bit for
// bit, the brute force's any-hit answers, and the visits the pointer tree's traversals make
// (Stack and Restart: equal, ray by ray; Backtrack: Stack's plus its re-reads). Seeded rays:
// aimed at points of triangles (vertices, edges, interiors), from inside the box, axis-parallel,
// and lying in split planes (through the lines where two planes meet).
// Synthetic trees check the rest: uniform block edges give the same hits; layoutCost() equals
// the built bytes; a general kd-tree with planes that are not encodable is rounded and its
// triangles redistributed, and still gives the brute force's hits; empty, single-leaf and
// too-deep trees; bad block edges.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include "mtree/rays/sah_kdtree.h"
#include "mtree/trees/implicit_tree.h"
#include "test_util.h"
#include "trees_test_util.h"

namespace {

using mtest::kTraversals;
using mtest::Ray;
using mtree::Box;
using mtree::ImplicitSplitTree;
using mtree::PointerSplitTree;
using mtree::RayHit;
using mtree::SahKdTree;
using mtree::SahTraversal;
using mtree::SplitTraversal;
using mtree::TraversalStats;
using mtree::TriangleMesh;
using mtree::TriangleTest;
using mtree::Vec3;

// Walks the pointer tree and the implicit one together: the node the implicit tree derives for
// each child must hold what the pointer tree's child holds.
void expectSameNodes(const PointerSplitTree& p, const ImplicitSplitTree& t) {
  struct Item {
    uint32_t n;
    int level, c[3];
  };
  std::vector<Item> stack{{0, 0, {0, 0, 0}}};
  uint64_t checked = 0, bad = 0;
  while (!stack.empty()) {
    const Item it = stack.back();
    stack.pop_back();
    const PointerSplitTree::Node& nd = p.nodes[it.n];
    const uint32_t w = t.word(it.level, it.c[0], it.c[1], it.c[2]);
    ++checked;
    if (nd.leaf) {
      uint32_t count;
      const uint32_t* ids = t.leafPrims(w, count);
      const bool same = t.isLeaf(w) && count == nd.count &&
                        std::equal(ids, ids + count, p.prims.begin() + nd.offset);
      bad += !same;
      continue;
    }
    bad += t.isLeaf(w) || t.direction(w) != nd.dir || t.split(w) != nd.s;
    Item l = it, r = it;
    const int a = ImplicitSplitTree::doublingAxis(it.level);
    l.n = nd.child;
    r.n = nd.child + 1;
    l.level = r.level = it.level + 1;
    l.c[a] = 2 * it.c[a];
    r.c[a] = 2 * it.c[a] + 1;
    stack.push_back(l);
    stack.push_back(r);
  }
  EXPECT_EQ(bad, 0u) << "of " << checked << " nodes";
  EXPECT_EQ(checked, t.numNodes());
}

class RealMeshImplicitKd : public ::testing::TestWithParam<std::string> {};

TEST_P(RealMeshImplicitKd, SameTreeSameHitsAsThePointerTree) {
  const std::string rel = GetParam();
  const TriangleMesh mesh = mtest::loadRealMesh(rel);
  const SahKdTree sah(mesh);
  const PointerSplitTree ptr = mtree::pointerTreeOf(sah);
  ImplicitSplitTree tree;
  tree.build(ptr, mesh);
  ASSERT_FALSE(tree.empty());
  EXPECT_FALSE(tree.redistributed()) << "SahKdTree's planes are encodable: nothing may be rounded";
  EXPECT_EQ(tree.numNodes(), sah.stats().nodes);
  EXPECT_EQ(tree.numLevels(), sah.stats().depth + 1);
  expectSameNodes(ptr, tree);
  EXPECT_EQ(tree.nodeBytes(), tree.levelCosts().nodeBytes());
  EXPECT_EQ(ImplicitSplitTree::layoutCost(ptr, 0).nodeBytes(), tree.nodeBytes());
  std::printf("[implicit kd] %-28s nodes %llu  levels %d  pointer %.2f MiB  implicit %.2f MiB (nodes %.2f MiB)\n",
              rel.c_str(), (unsigned long long)tree.numNodes(), tree.numLevels(), ptr.pointerBytes() / 1048576.0,
              tree.bytes() / 1048576.0, tree.nodeBytes() / 1048576.0);

  const std::vector<Ray> rays = mtest::splitTreeRays(mesh, ptr, 6000, mtest::seedFor(rel, 71));
  const std::vector<RayHit> ref = mtest::BruteForce(mesh).firstAll(rays);
  // The pointer tree's stack and restart traversals, ray by ray.
  std::vector<RayHit> sahHits(rays.size());
  std::vector<TraversalStats> sahStack(rays.size()), sahRestart(rays.size());
  for (size_t i = 0; i < rays.size(); ++i) {
    RayHit h;
    sah.intersectFirst(mesh, rays[i].o, rays[i].d, rays[i].tmin, rays[i].tmax, sahHits[i], SahTraversal::Stack,
                       TriangleTest::MollerTrumbore, &sahStack[i]);
    sah.intersectFirst(mesh, rays[i].o, rays[i].d, rays[i].tmin, rays[i].tmax, h, SahTraversal::Restart,
                       TriangleTest::MollerTrumbore, &sahRestart[i]);
  }
  for (SplitTraversal trav : kTraversals) {
    SCOPED_TRACE(mtree::splitTraversalName(trav));
    mtest::HitComparison cmp;
    uint64_t notBitEqual = 0, visitsDiffer = 0, testsDiffer = 0, anyWrong = 0;
    for (size_t i = 0; i < rays.size(); ++i) {
      const Ray& r = rays[i];
      RayHit h;
      TraversalStats st;
      tree.intersectFirst(mesh, r.o, r.d, r.tmin, r.tmax, h, trav, TriangleTest::MollerTrumbore, &st);
      cmp.add(h, ref[i], r, i);
      notBitEqual += !mtest::sameHitBits(h, sahHits[i]);
      const TraversalStats& want = trav == SplitTraversal::Restart ? sahRestart[i] : sahStack[i];
      testsDiffer += st.primTests != want.primTests || st.cells != want.cells;
      if (trav == SplitTraversal::Backtrack)
        visitsDiffer += st.nodeVisits < want.nodeVisits;
      else
        visitsDiffer += st.nodeVisits != want.nodeVisits;
      anyWrong += tree.intersectAny(mesh, r.o, r.d, r.tmin, r.tmax, trav) != ref[i].hit();
    }
    EXPECT_EQ(cmp.mismatches, 0u) << cmp.firstMismatch;
    EXPECT_EQ(notBitEqual, 0u) << "first hits differ from the SAH stack traversal's";
    EXPECT_EQ(visitsDiffer, 0u) << "node visits differ from the pointer tree's";
    EXPECT_EQ(testsDiffer, 0u) << "leaves or triangle tests differ from the pointer tree's";
    EXPECT_EQ(anyWrong, 0u);
    EXPECT_GT(cmp.hits, rays.size() / 4);
  }
  // The watertight test through the implicit tree against the SAH tree's, bit for bit.
  uint64_t wtDiffer = 0;
  for (size_t i = 0; i < rays.size(); i += 5) {
    RayHit a, b;
    sah.intersectFirst(mesh, rays[i].o, rays[i].d, rays[i].tmin, rays[i].tmax, a, SahTraversal::Stack,
                       TriangleTest::Watertight);
    tree.intersectFirst(mesh, rays[i].o, rays[i].d, rays[i].tmin, rays[i].tmax, b, SplitTraversal::Backtrack,
                        TriangleTest::Watertight);
    wtDiffer += !mtest::sameHitBits(a, b);
  }
  EXPECT_EQ(wtDiffer, 0u);
}

INSTANTIATE_TEST_SUITE_P(RealMeshes, RealMeshImplicitKd, ::testing::ValuesIn(mtest::realMeshes()),
                         [](const ::testing::TestParamInfo<std::string>& info) {
                           return mtest::meshTag(info.param);
                         });

TEST(ImplicitKd, UniformBlockEdgesHoldTheSameTree) {
  const TriangleMesh mesh = mtest::loadRealMesh("scenes/utah_hand/hand_00.obj");
  mtree::SahBuildOptions so;
  so.maxDepth = 18;  // B = 1 keeps a pointer per node of every level: 2^18 cells at most
  const SahKdTree sah(mesh, so);
  const PointerSplitTree ptr = mtree::pointerTreeOf(sah);
  const std::vector<Ray> rays = mtest::splitTreeRays(mesh, ptr, 1500, 17);
  const std::vector<RayHit> ref = mtest::BruteForce(mesh).firstAll(rays);
  for (int B : {1, 2, 4, 8, 16, 32}) {
    SCOPED_TRACE("B = " + std::to_string(B));
    ImplicitSplitTree tree;
    tree.build(ptr, mesh, B);
    expectSameNodes(ptr, tree);
    const mtree::ImplicitLayoutCost cost = ImplicitSplitTree::layoutCost(ptr, B);
    EXPECT_EQ(cost.nodeBytes(), tree.nodeBytes());
    for (int l = 0; l < tree.numLevels(); ++l) {
      const auto& c = cost.levels[l];
      EXPECT_EQ(c.blocks, tree.level(l).numBlocks());
      EXPECT_EQ(c.pointers, tree.level(l).pointerCount());
      for (int a = 0; a < 3; ++a)
        EXPECT_EQ(c.logBlock[a], std::min(mtree::ceilLog2(B), ImplicitSplitTree::logDim(l, a)));
    }
    mtest::HitComparison cmp;
    for (size_t i = 0; i < rays.size(); ++i) {
      RayHit h;
      tree.intersectFirst(mesh, rays[i].o, rays[i].d, rays[i].tmin, rays[i].tmax, h, SplitTraversal::Backtrack);
      cmp.add(h, ref[i], rays[i], i);
    }
    EXPECT_EQ(cmp.mismatches, 0u) << cmp.firstMismatch;
  }
  // The per-level choice never costs more than any uniform edge, level by level.
  const mtree::ImplicitLayoutCost best = ImplicitSplitTree::layoutCost(ptr, 0);
  for (int B : {1, 2, 4, 8, 16, 32}) {
    const mtree::ImplicitLayoutCost u = ImplicitSplitTree::layoutCost(ptr, B);
    for (size_t l = 0; l < best.levels.size(); ++l) EXPECT_LE(best.levels[l].bytes, u.levels[l].bytes) << l;
  }
}

TEST(ImplicitKd, SplitPolygonsAreTheNodesPlanesInTheirCells) {
  const TriangleMesh mesh = mtest::loadRealMesh("scenes/utah_hand/hand_00.obj");
  const SahKdTree sah(mesh);
  const PointerSplitTree ptr = mtree::pointerTreeOf(sah);
  ImplicitSplitTree tree;
  tree.build(ptr, mesh);
  const int L = 9;
  const std::vector<mtree::SplitPolygon> polys = tree.splitPolygons(L);
  // One rectangle per inner node of levels 0..L, on its plane, inside the root box; the root's
  // spans the root box.
  uint64_t inner = 0;
  std::vector<std::pair<uint32_t, int>> stack{{0u, 0}};
  while (!stack.empty()) {
    const auto [n, l] = stack.back();
    stack.pop_back();
    if (ptr.nodes[n].leaf || l > L) continue;
    ++inner;
    stack.push_back({ptr.nodes[n].child, l + 1});
    stack.push_back({ptr.nodes[n].child + 1, l + 1});
  }
  EXPECT_EQ(polys.size(), inner);
  const Box rb = tree.rootBox();
  uint64_t bad = 0;
  for (const mtree::SplitPolygon& p : polys) {
    bad += p.points.size() != 4;
    for (const Vec3& q : p.points) {
      for (int a = 0; a < 3; ++a) bad += q[a] < rb.lo[a] || q[a] > rb.hi[a];
    }
  }
  EXPECT_EQ(bad, 0u);
  const mtree::SplitPolygon& root = polys[0];
  EXPECT_EQ(root.level, 0);
  const int a = root.dir, a1 = (a + 1) % 3;
  double lo = 1e300, hi = -1e300;
  for (const Vec3& q : root.points) {
    // Interpolated along the cell's edges: on the plane to round-off.
    EXPECT_NEAR(q[a], sah.planeWorld(a, sah.nodes()[0].split()), 1e-12 * mtree::norm(rb.extent()));
    lo = std::min(lo, q[a1]);
    hi = std::max(hi, q[a1]);
  }
  EXPECT_EQ(lo, rb.lo[a1]);
  EXPECT_EQ(hi, rb.hi[a1]);
}

// Point location: a point of a triangle lies in a leaf that lists the triangle (the build's
// conservative classification, split_tree.h), whatever side of a plane through it the walk takes;
// outside the root box, or NaN, there is no leaf.
TEST(ImplicitKd, LeafFindListsEveryTriangleThroughThePoint) {
  const TriangleMesh mesh = mtest::loadRealMesh("scenes/utah_hand/hand_00.obj");
  const SahKdTree sah(mesh);
  ImplicitSplitTree tree;
  tree.build(mtree::pointerTreeOf(sah), mesh);
  mtest::Rng rng(0x1eaf);
  uint64_t missing = 0, deepest = 0;
  for (int i = 0; i < 20000; ++i) {
    const size_t t = rng.below(static_cast<uint32_t>(mesh.size()));
    // Interior points, and the triangle's vertices (on many planes: triangle bounds are candidates).
    const Vec3 p = i % 4 == 0 ? mesh.vertex(t, i % 3) : mtest::pointOn(mesh, t, rng);
    int level, c[3];
    const uint32_t w = tree.leafFind(p, level, c);
    ASSERT_GE(level, 0);
    EXPECT_EQ(w, tree.word(level, c[0], c[1], c[2]));
    uint32_t count;
    const uint32_t* ids = tree.leafPrims(w, count);
    missing += std::find(ids, ids + count, static_cast<uint32_t>(t)) == ids + count;
    deepest = std::max<uint64_t>(deepest, static_cast<uint64_t>(level));
  }
  EXPECT_EQ(missing, 0u);
  EXPECT_GT(deepest, 10u);
  int level, c[3];
  const Box rb = tree.rootBox();
  EXPECT_EQ(tree.leafFind(rb.hi + rb.extent(), level, c), ImplicitSplitTree::kEmpty);
  EXPECT_EQ(level, -1);
  EXPECT_EQ(tree.leafFind(Vec3(std::numeric_limits<double>::quiet_NaN(), 0, 0), level, c), ImplicitSplitTree::kEmpty);
  EXPECT_EQ(level, -1);
  EXPECT_EQ(ImplicitSplitTree().leafFind(rb.center(), level, c), ImplicitSplitTree::kEmpty);
  EXPECT_EQ(level, -1);
}

TEST(ImplicitKd, UnencodablePlanesAreRoundedAndTrianglesRedistributed) {
  const TriangleMesh mesh = mtest::loadRealMesh("scenes/utah_hand/hand_00.obj");
  // A general kd-tree with planes anywhere (random axis, random float inside the cell: most have
  // non-zero tag bits) and every triangle in every leaf: only its planes matter.
  const PointerSplitTree src = mtest::randomKdTree(mesh, 14, 91);
  ImplicitSplitTree tree;
  tree.build(src, mesh);
  EXPECT_TRUE(tree.redistributed());
  const uint64_t leaves = tree.leafStart().size() - 1;
  ASSERT_GT(leaves, 100u);
  EXPECT_LT(tree.primitiveIndices().size() / leaves, mesh.size() / 8) << "redistribution should shrink the leaves";
  const std::vector<Ray> rays = mtest::splitTreeRays(mesh, src, 3000, 23);
  const std::vector<RayHit> ref = mtest::BruteForce(mesh).firstAll(rays);
  for (SplitTraversal trav : kTraversals) {
    SCOPED_TRACE(mtree::splitTraversalName(trav));
    mtest::HitComparison cmp;
    uint64_t anyWrong = 0;
    for (size_t i = 0; i < rays.size(); ++i) {
      RayHit h;
      tree.intersectFirst(mesh, rays[i].o, rays[i].d, rays[i].tmin, rays[i].tmax, h, trav);
      cmp.add(h, ref[i], rays[i], i);
      anyWrong += tree.intersectAny(mesh, rays[i].o, rays[i].d, rays[i].tmin, rays[i].tmax, trav) != ref[i].hit();
    }
    EXPECT_EQ(cmp.mismatches, 0u) << cmp.firstMismatch;
    EXPECT_EQ(anyWrong, 0u);
  }
}

TEST(ImplicitKd, EmptyAndSingleLeafTrees) {
  ImplicitSplitTree tree;
  const TriangleMesh none;
  tree.build(mtree::pointerTreeOf(SahKdTree(none)), none);
  EXPECT_TRUE(tree.empty());
  RayHit h;
  EXPECT_FALSE(tree.intersectFirst(none, Vec3(0, 0, -1), Vec3(0, 0, 1), 0, 10, h));
  EXPECT_FALSE(tree.intersectAny(none, Vec3(0, 0, -1), Vec3(0, 0, 1), 0, 10));

  const TriangleMesh one({0, 0, 0, 1, 0, 0, 0, 1, 0}, {0, 1, 2});
  tree.build(mtree::pointerTreeOf(SahKdTree(one)), one);
  ASSERT_FALSE(tree.empty());
  EXPECT_EQ(tree.numLevels(), 1);
  for (SplitTraversal trav : kTraversals) {
    ASSERT_TRUE(tree.intersectFirst(one, Vec3(0.25, 0.25, -1), Vec3(0, 0, 1), 0, 10, h, trav));
    EXPECT_EQ(h.prim, 0u);
    EXPECT_EQ(h.t, 1.0);
    EXPECT_FALSE(tree.intersectFirst(one, Vec3(0.75, 0.75, -1), Vec3(0, 0, 1), 0, 10, h, trav));
    // Bad rays miss.
    const double nan = std::numeric_limits<double>::quiet_NaN();
    EXPECT_FALSE(tree.intersectFirst(one, Vec3(nan, 0, 0), Vec3(0, 0, 1), 0, 10, h, trav));
    EXPECT_FALSE(tree.intersectFirst(one, Vec3(0.25, 0.25, -1), Vec3(0, 0, 0), 0, 10, h, trav));
    EXPECT_FALSE(tree.intersectFirst(one, Vec3(0.25, 0.25, -1), Vec3(0, 0, 1), 5, 1, h, trav));
  }
}

TEST(ImplicitKd, BadInputIsRefused) {
  const TriangleMesh one({0, 0, 0, 1, 0, 0, 0, 1, 0}, {0, 1, 2});
  const PointerSplitTree p = mtree::pointerTreeOf(SahKdTree(one));
  ImplicitSplitTree tree;
  for (int B : {-1, 3, 64}) EXPECT_THROW(tree.build(p, one, B), std::invalid_argument) << B;
  // A chain deeper than kMaxLevel: node 2i splits into the leaf 2i + 1 and the node 2i + 2.
  PointerSplitTree deep = p;
  const int depth = ImplicitSplitTree::kMaxLevel + 2;
  deep.nodes.assign(2 * depth + 1, PointerSplitTree::Node{});
  for (int i = 0; i < depth; ++i) {
    PointerSplitTree::Node& inner = deep.nodes[2 * i];
    inner.leaf = false;
    inner.dir = static_cast<uint8_t>(i % 3);
    inner.s = 0.125f;
    inner.child = static_cast<uint32_t>(2 * i + 1);
  }
  EXPECT_THROW(tree.build(deep, one), std::length_error);
  EXPECT_TRUE(tree.empty());
  // A triangle the mesh does not have.
  PointerSplitTree wrongMesh = p;
  wrongMesh.prims[0] = 7;
  EXPECT_THROW(tree.build(wrongMesh, one), std::invalid_argument);
  // A direction the frame does not have, a child past the end.
  PointerSplitTree bad = deep;
  bad.nodes[0].dir = 3;
  EXPECT_THROW(tree.build(bad, one), std::invalid_argument);
  bad = deep;
  bad.nodes[2 * depth - 2].child = static_cast<uint32_t>(bad.nodes.size());
  EXPECT_THROW(tree.build(bad, one), std::invalid_argument);
}

}  // namespace

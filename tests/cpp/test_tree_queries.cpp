// The tree queries of engine/include/mtree/core/tree_queries.h against brute force over every
// node of each level (nodeExists on the level's full grid), on the bunny's triangles and a
// tetrahedral grid, octree and kd-tree:
//   forEachChild / forEachNode      the existing nodes, and per node the nodes of the next level
//                                   whose coordinates shifted right by its split bits are its own;
//   closestPrimitiveSearch          the closest triangle (lowest id among equal distances) of
//                                   every point, without and within a radius, as a scan of all
//                                   triangles finds it;
//   primitivesInLeavesOverlapping   the union of the references of every leaf whose box
//                                   overlaps the query box, including every triangle with a vertex
//                                   in it;
//   distinctPrimitivesPerNode       per node, the number of distinct primitives of the leaves
//                                   below it, and the fraction of its child slots that exist.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "mtree/core/builder.h"
#include "mtree/core/tree_queries.h"
#include "test_util.h"

namespace {

using mtree::Box;
using mtree::MatrixTree;
using mtree::Vec3;

struct Node {
  int c[3];
};

/// Every existing node of level l, in linear order of the coordinates (x fastest).
std::vector<Node> allNodes(const MatrixTree& t, int l) {
  std::vector<Node> out;
  for (int z = 0; z < t.dim(l, 2); ++z)
    for (int y = 0; y < t.dim(l, 1); ++y)
      for (int x = 0; x < t.dim(l, 0); ++x) {
        const int c[3] = {x, y, z};
        if (t.nodeExists(l, c)) out.push_back(Node{{x, y, z}});
      }
  return out;
}

/// Whether node c of level l is an ancestor of (or is) node cc of level m >= l.
bool below(const MatrixTree& t, int l, const int c[3], int m, const int cc[3]) {
  for (int a = 0; a < 3; ++a)
    if ((cc[a] >> (t.logDim(m, a) - t.logDim(l, a))) != c[a]) return false;
  return true;
}

/// Closest point of triangle abc to p (Ericson, Real-Time Collision Detection, 5.1.5); its squared distance.
double triangleDistance2(Vec3 p, Vec3 a, Vec3 b, Vec3 c) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = mtree::dot(ab, ap), d2 = mtree::dot(ac, ap);
  auto dist2 = [&](Vec3 q) { return mtree::dot(p - q, p - q); };
  if (d1 <= 0 && d2 <= 0) return dist2(a);
  const Vec3 bp = p - b;
  const double d3 = mtree::dot(ab, bp), d4 = mtree::dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return dist2(b);
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return dist2(a + ab * (d1 / (d1 - d3)));
  const Vec3 cp = p - c;
  const double d5 = mtree::dot(ab, cp), d6 = mtree::dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) return dist2(c);
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return dist2(a + ac * (d2 / (d2 - d6)));
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) return dist2(b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6))));
  const double denom = 1.0 / (va + vb + vc);
  return dist2(a + ab * (vb * denom) + ac * (vc * denom));
}

struct Case {
  std::string mesh;
  mtree::TreeKind kind;
  int height;
};

class TreeQueries : public ::testing::TestWithParam<Case> {
 protected:
  void SetUp() override {
    mesh_ = mtest::loadRealMesh(GetParam().mesh);
    tree_ = mtest::buildTree(mesh_, mtest::options(GetParam().kind, GetParam().height, 8, 1));
    ASSERT_FALSE(tree_.empty());
    ASSERT_EQ(tree_.height(), GetParam().height);
  }
  mtree::TriangleMesh mesh_;
  MatrixTree tree_;
};

TEST_P(TreeQueries, NodesAndChildrenAreTheGridsExistingNodes) {
  const MatrixTree& t = tree_;
  for (int l = 0; l <= t.height(); ++l) {
    const std::vector<Node> want = allNodes(t, l);
    std::set<std::array<int, 3>> got;
    mtree::forEachNode(t, l, [&](const int c[3], uint32_t refs) {
      EXPECT_TRUE(got.insert({c[0], c[1], c[2]}).second) << "node visited twice";
      if (l == t.height()) {
        const MtLeafRange r = t.leafLevel().get(c[0], c[1], c[2]);
        EXPECT_EQ(refs, r.end - r.begin);
        EXPECT_GT(refs, 0u);
      } else {
        EXPECT_EQ(refs, 0u);
      }
    });
    ASSERT_EQ(got.size(), want.size()) << "level " << l;
    for (const Node& n : want) EXPECT_TRUE(got.count({n.c[0], n.c[1], n.c[2]}));
    if (l == t.height()) continue;
    const std::vector<Node> next = allNodes(t, l + 1);
    for (const Node& n : want) {
      std::vector<std::array<int, 3>> kids, wantKids;
      mtree::forEachChild(t, l, n.c, [&](const int cc[3]) { kids.push_back({cc[0], cc[1], cc[2]}); });
      for (const Node& m : next)
        if (below(t, l, n.c, l + 1, m.c)) wantKids.push_back({m.c[0], m.c[1], m.c[2]});
      std::sort(kids.begin(), kids.end());
      std::sort(wantKids.begin(), wantKids.end());
      ASSERT_EQ(kids, wantKids) << "level " << l;
      EXPECT_FALSE(kids.empty()) << "an inner node exists only with a child";
    }
  }
}

TEST_P(TreeQueries, ClosestTriangleIsTheScansClosest) {
  const MatrixTree& t = tree_;
  const mtree::TriangleMesh& m = mesh_;
  mtest::Rng rng(mtest::seedFor(GetParam().mesh, 3));
  const Box grown = mtest::enlarged(t.rootBox(), 0.2);
  const double diag = mtree::norm(t.rootBox().hi - t.rootBox().lo);
  for (int i = 0; i < 200; ++i) {
    const Vec3 p = rng.inBox(grown);
    const double x[3] = {p.x, p.y, p.z};
    // The scan: every triangle's distance, lowest id among equal ones.
    double want2 = std::numeric_limits<double>::infinity();
    int64_t wantId = -1;
    std::vector<double> d2(m.size());
    for (size_t k = 0; k < m.size(); ++k) {
      d2[k] = triangleDistance2(p, m.vertex(k, 0), m.vertex(k, 1), m.vertex(k, 2));
      if (d2[k] < want2) want2 = d2[k], wantId = static_cast<int64_t>(k);
    }
    for (const double radius2 : {std::numeric_limits<double>::infinity(), 0.05 * diag * 0.05 * diag}) {
      int64_t gotId = -1;
      double got2 = radius2;
      size_t visits = 0;
      mtree::closestPrimitiveSearch(
          t, x, radius2, [&](uint32_t id, double bound2) { return !(mtree::boxDistance2(x, m.bounds(id)) > bound2); },
          [&](uint32_t id, double bound2) {
            ++visits;
            if (d2[id] < bound2 || (d2[id] == bound2 && gotId >= 0 && id < gotId) || (gotId < 0 && d2[id] <= bound2)) {
              gotId = id;
              got2 = d2[id];
              return d2[id];
            }
            return bound2;
          });
      if (want2 <= radius2) {
        ASSERT_EQ(gotId, wantId) << "point " << i << ", radius2 " << radius2;
        ASSERT_EQ(got2, want2);
      } else {
        ASSERT_EQ(gotId, -1) << "point " << i << ": nothing within the radius";
      }
      EXPECT_LT(visits, m.size() / 4) << "the search prunes";
    }
  }
}

TEST_P(TreeQueries, LeavesOverlappingABoxAreTheBruteForceUnion) {
  const MatrixTree& t = tree_;
  const int H = t.height();
  const std::vector<Node> leaves = allNodes(t, H);
  mtest::Rng rng(mtest::seedFor(GetParam().mesh, 4));
  const double diag = mtree::norm(t.rootBox().hi - t.rootBox().lo);
  for (int i = 0; i < 100; ++i) {
    const Vec3 c = rng.inBox(mtest::enlarged(t.rootBox(), 0.1));
    const Vec3 h = Vec3(rng.uniform(), rng.uniform(), rng.uniform()) * (0.1 * diag);
    Box q;
    q.lo = c - h;
    q.hi = c + h;
    std::vector<uint32_t> want;
    for (const Node& n : leaves) {
      if (!t.nodeBox(H, n.c).overlaps(q)) continue;
      const MtLeafRange r = t.leafLevel().get(n.c[0], n.c[1], n.c[2]);
      for (uint32_t k = r.begin; k < r.end; ++k) want.push_back(t.primitiveIndices()[k]);
    }
    std::sort(want.begin(), want.end());
    want.erase(std::unique(want.begin(), want.end()), want.end());
    const std::vector<uint32_t> got = mtree::primitivesInLeavesOverlapping(t, q);
    ASSERT_EQ(got, want) << "box " << i;
    for (size_t k = 0; k < mesh_.size(); ++k) {
      for (int v = 0; v < 3; ++v) {
        if (q.contains(mesh_.vertex(k, v))) {
          ASSERT_TRUE(std::binary_search(got.begin(), got.end(), static_cast<uint32_t>(k))) << "triangle " << k;
        }
      }
    }
  }
}

TEST_P(TreeQueries, DistinctPrimitivesPerNodeAreTheLeavesBelow) {
  const MatrixTree& t = tree_;
  const int H = t.height();
  const std::vector<Node> leaves = allNodes(t, H);
  for (const auto& range : {std::pair<int, int>{0, H}, std::pair<int, int>{H / 2, H / 2 + 1}, {H, H}}) {
    const auto got = mtree::distinctPrimitivesPerNode(t, range.first, range.second);
    ASSERT_EQ(got.size(), static_cast<size_t>(range.second - range.first + 1));
    for (int l = range.first; l <= range.second; ++l) {
      SCOPED_TRACE("level " + std::to_string(l));
      const std::vector<Node> nodes = allNodes(t, l);
      const auto& level = got[static_cast<size_t>(l - range.first)];
      ASSERT_EQ(level.size(), nodes.size());
      const std::vector<Node> next = l < H ? allNodes(t, l + 1) : std::vector<Node>();
      for (size_t i = 0; i < nodes.size(); ++i) {
        const Node& n = nodes[i];
        for (int a = 0; a < 3; ++a) ASSERT_EQ(level[i].c[a], n.c[a]) << "node " << i << " (linear order)";
        std::set<uint32_t> prims;
        size_t refs = 0;
        for (const Node& leaf : leaves) {
          if (!below(t, l, n.c, H, leaf.c)) continue;
          const MtLeafRange r = t.leafLevel().get(leaf.c[0], leaf.c[1], leaf.c[2]);
          for (uint32_t k = r.begin; k < r.end; ++k) prims.insert(t.primitiveIndices()[k]);
          refs += r.end - r.begin;
        }
        EXPECT_EQ(level[i].primitives, l == H ? refs : prims.size()) << "node " << i;
        double occupancy = 1.0;
        if (l < H) {
          int present = 0, slots = 1;
          for (int a = 0; a < 3; ++a) slots <<= t.logDim(l + 1, a) - t.logDim(l, a);
          for (const Node& m : next) present += below(t, l, n.c, l + 1, m.c) ? 1 : 0;
          occupancy = static_cast<double>(present) / slots;
        }
        EXPECT_EQ(level[i].occupancy, occupancy) << "node " << i;
      }
    }
  }
  EXPECT_TRUE(mtree::distinctPrimitivesPerNode(t, 1, 0).empty()) << "an empty range";
  EXPECT_TRUE(mtree::distinctPrimitivesPerNode(MatrixTree(), 0, 0).empty()) << "an empty tree";
}

INSTANTIATE_TEST_SUITE_P(Meshes, TreeQueries,
                         ::testing::Values(Case{"meshes/bunny.ply", mtree::TreeKind::Octree, 5},
                                           Case{"meshes/horse.ply", mtree::TreeKind::Octree, 4},
                                           Case{"meshes/bunny.ply", mtree::TreeKind::RegularKd, 13}),
                         [](const auto& info) {
                           return mtest::meshTag(info.param.mesh) + "_" + mtree::treeKindName(info.param.kind) +
                                  "_" + std::to_string(info.param.height);
                         });

}  // namespace

// Matrix trees built over the 7 real meshes, as octree and as regular kd-tree with the automatic
// height, checked against references computed here:
//   leafFind (hash + binary search)  vs  leafFindTopDown (plain descent), 10^5 random points
//   (and leafHolding: leafFind's leaf or nothing);
//   leaf contents                    vs  the exact triangle/box test, both ways (sound, complete);
//   inner levels                     vs  the OR of their children (monotone and exact existence);
//   builds with 1, 2, 4 threads      vs  each other, byte for byte;
//   BoundingBox overlap mode         vs  Exact mode (a superset, leaf by leaf).
#include <gtest/gtest.h>

#include <algorithm>
#include <bitset>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <string>
#include <tuple>
#include <vector>

#include "test_util.h"

namespace {

using mtree::Box;
using mtree::MatrixTree;
using mtree::NodeRef;
using mtree::TreeKind;
using mtree::Vec3;

// Calls fn(c) for every entry of every allocated block of level l (entries inside the matrix).
template <class T, class Fn>
void forEachAllocated(const mtree::BlockSparseMatrix<T>& m, Fn&& fn) {
  const MtSparseDesc& d = m.desc();
  const std::vector<uint32_t>& ptr = m.pointers();
  for (size_t p = 0; p < ptr.size(); ++p) {
    if (ptr[p] == MT_NULL) continue;
    const int bx = static_cast<int>(p % d.ptrDims[0]);
    const int by = static_cast<int>((p / d.ptrDims[0]) % d.ptrDims[1]);
    const int bz = static_cast<int>(p / (size_t(d.ptrDims[0]) * d.ptrDims[1]));
    for (int z = 0; z < (1 << d.logBlock[2]); ++z)
      for (int y = 0; y < (1 << d.logBlock[1]); ++y)
        for (int x = 0; x < (1 << d.logBlock[0]); ++x) {
          const int c[3] = {(bx << d.logBlock[0]) + x, (by << d.logBlock[1]) + y, (bz << d.logBlock[2]) + z};
          if (m.inRange(c[0], c[1], c[2])) fn(c);
        }
  }
}

// Calls fn(c, range) for every existing leaf.
template <class Fn>
void forEachLeaf(const MatrixTree& tree, Fn&& fn) {
  const auto& leaves = tree.leafLevel();
  forEachAllocated(leaves, [&](const int c[3]) {
    const MtLeafRange r = leaves.get(c[0], c[1], c[2]);
    if (r.begin != MT_NULL) fn(c, r);
  });
}

Box padded(const Box& b, double pad) {
  Box r;
  r.lo = b.lo - Vec3(pad, pad, pad);
  r.hi = b.hi + Vec3(pad, pad, pad);
  return r;
}

double maxComponent(Vec3 v) { return std::max(v.x, std::max(v.y, v.z)); }

bool leafHolds(const MatrixTree& tree, const int c[3], uint32_t prim) {
  if (!tree.nodeExists(tree.height(), c)) return false;
  const MtLeafRange r = tree.leafLevel().get(c[0], c[1], c[2]);
  const uint32_t* b = tree.primitiveIndices().data() + r.begin;
  const uint32_t* e = tree.primitiveIndices().data() + r.end;
  return std::binary_search(b, e, prim);
}

class RealMeshTree : public ::testing::TestWithParam<std::tuple<std::string, TreeKind>> {
 protected:
  void SetUp() override {
    rel_ = std::get<0>(GetParam());
    kind_ = std::get<1>(GetParam());
    mesh_ = mtest::loadRealMesh(rel_);
    ASSERT_GT(mesh_.size(), 0u);
    tree_ = mtest::buildTree(mesh_, mtest::options(kind_), &stats_);
    ASSERT_FALSE(tree_.empty());
    ASSERT_EQ(tree_.kind(), kind_);
    ASSERT_TRUE(stats_.autoHeight);
    ASSERT_EQ(stats_.height, tree_.height());
    ASSERT_EQ(stats_.primitives, mesh_.size());
  }
  uint64_t seed(uint64_t salt) const { return mtest::seedFor(rel_, salt * 2 + static_cast<int>(kind_)); }

  std::string rel_;
  TreeKind kind_ = TreeKind::Octree;
  mtree::TriangleMesh mesh_;
  MatrixTree tree_;
  mtree::BuildStats stats_;
};

// (a) 10^5 seeded points in the mesh box enlarged by 10% (5% per side): the sub-linear search
// and the top-down descent agree on level, coordinates and existence. One point in ten lies
// exactly on a bottom-level node plane.
TEST_P(RealMeshTree, LeafFindMatchesTopDown) {
  const MatrixTree& t = tree_;
  const int H = t.height();
  const Box root = t.rootBox();
  const Box query = mtest::enlarged(mtest::meshBounds(mesh_), 0.05);
  const Vec3 leaf = t.cellSize(H);
  mtest::Rng rng(seed(1));
  const int N = 100000;
  int mismatches = 0, outside = 0, leaves = 0, empties = 0, badInvariant = 0;
  uint64_t maxVisits = 0;
  std::string first;
  int maxLogSteps = 0;
  while ((1 << maxLogSteps) < H) ++maxLogSteps;
  for (int i = 0; i < N; ++i) {
    Vec3 p = rng.inBox(query);
    if (i % 10 == 0) {
      const int a = static_cast<int>(rng.below(3));
      const int k = static_cast<int>(rng.below(static_cast<uint32_t>(t.dim(H, a) + 1)));
      p[a] = root.lo[a] + k * leaf[a];
    }
    mtree::TraversalStats st;
    const NodeRef a = t.leafFind(p, &st);
    const NodeRef b = t.leafFindTopDown(p);
    // leafHolding: leafFind's leaf when it exists (same cell and range), else nothing.
    const NodeRef h = t.leafHolding(p);
    const bool holdingSame =
        h.exists == a.exists && (!a.exists || (h.level == a.level && h.c[0] == a.c[0] && h.c[1] == a.c[1] &&
                                               h.c[2] == a.c[2] && h.range.begin == a.range.begin &&
                                               h.range.end == a.range.end));
    const bool same = holdingSame && a.level == b.level && a.exists == b.exists &&
                      (a.level < 0 || (a.c[0] == b.c[0] && a.c[1] == b.c[1] && a.c[2] == b.c[2]));
    if (!same && mismatches++ == 0) {
      char buf[300];
      std::snprintf(buf, sizeof buf,
                    "p=(%.17g, %.17g, %.17g): leafFind level %d (%d,%d,%d) exists %d, top-down level %d "
                    "(%d,%d,%d) exists %d",
                    p.x, p.y, p.z, a.level, a.c[0], a.c[1], a.c[2], a.exists, b.level, b.c[0], b.c[1], b.c[2],
                    b.exists);
      first = buf;
    }
    maxVisits = std::max(maxVisits, st.nodeVisits);
    if (a.level < 0) {
      ++outside;
      badInvariant += root.contains(p);
      continue;
    }
    badInvariant += !root.contains(p);
    // The node found contains p (up to round-off of the cell index).
    const Box nb = padded(t.nodeBox(a.level, a.c), 1e-9 * maxComponent(root.extent()));
    badInvariant += !nb.contains(p);
    if (a.exists) {
      ++leaves;
      badInvariant += a.level != H || !t.nodeExists(H, a.c);
      const MtLeafRange r = t.leafRange(a);
      badInvariant += !(r.begin < r.end);
    } else {
      ++empties;
      // The largest empty node: absent itself, its parent present.
      int parent[3];
      for (int ax = 0; ax < 3; ++ax)
        parent[ax] = a.c[ax] >> (t.logDim(a.level, ax) - t.logDim(a.level - 1, ax));
      badInvariant += a.level < 1 || t.nodeExists(a.level, a.c) || !t.nodeExists(a.level - 1, parent);
    }
  }
  EXPECT_EQ(mismatches, 0) << "first: " << first;
  EXPECT_EQ(badInvariant, 0);
  EXPECT_GT(outside, 0) << "the enlarged box should put some points outside the root";
  EXPECT_GT(leaves, 0);
  EXPECT_GT(empties, 0);
  // Sub-linear: one hashed lookup, then a binary search over at most H levels.
  EXPECT_LE(maxVisits, static_cast<uint64_t>(1 + maxLogSteps)) << "height " << H;
  RecordProperty("height", H);
}

// Every mesh vertex lies in an existing leaf that references every triangle using the vertex.
TEST_P(RealMeshTree, VerticesFindLeavesHoldingTheirTriangles) {
  const MatrixTree& t = tree_;
  std::vector<std::vector<uint32_t>> incident(mesh_.numPoints());
  for (size_t i = 0; i < mesh_.size(); ++i)
    for (int k = 0; k < 3; ++k) incident[mesh_.triangles()[3 * i + k]].push_back(static_cast<uint32_t>(i));
  int missing = 0, notLeaf = 0;
  for (size_t v = 0; v < mesh_.numPoints(); v += 3) {
    if (incident[v].empty()) continue;
    const Vec3 p(&mesh_.points()[3 * v]);
    const NodeRef n = t.leafFind(p);
    if (!n.exists) {
      ++notLeaf;
      continue;
    }
    for (uint32_t tri : incident[v]) missing += !leafHolds(t, n.c, tri);
  }
  EXPECT_EQ(notLeaf, 0);
  EXPECT_EQ(missing, 0);
}

// (b) Soundness: every (leaf, triangle) reference overlaps (exact separating-axis test on the
// leaf box, padded by 1e-9 of the scene size). Completeness: every leaf cell whose closed box the
// exact test says a triangle overlaps exists and references that triangle; this is what makes
// ray answers exact. Also: ranges partition the index array, triangles sorted in a leaf.
TEST_P(RealMeshTree, LeavesHoldExactlyTheOverlappingTriangles) {
  const MatrixTree& t = tree_;
  const int H = t.height();
  const mtree::LargeVector<uint32_t>& prims = t.primitiveIndices();
  const double tol = 1e-9 * maxComponent(t.rootBox().extent());
  uint64_t refs = 0, unsound = 0, unsorted = 0, leaves = 0;
  std::vector<std::pair<uint32_t, uint32_t>> ranges;
  forEachLeaf(t, [&](const int c[3], const MtLeafRange& r) {
    ++leaves;
    ASSERT_LT(r.begin, r.end);
    ASSERT_LE(r.end, prims.size());
    ranges.emplace_back(r.begin, r.end);
    const Box box = padded(t.nodeBox(H, c), tol);
    for (uint32_t k = r.begin; k < r.end; ++k) {
      ++refs;
      const uint32_t id = prims[k];
      ASSERT_LT(id, mesh_.size());
      if (k > r.begin && !(prims[k - 1] < id)) ++unsorted;
      if (!mesh_.overlaps(id, box)) ++unsound;
    }
  });
  EXPECT_EQ(unsound, 0u) << "references to triangles that do not overlap their leaf";
  EXPECT_EQ(unsorted, 0u) << "a leaf's triangles must be distinct and in id order";
  EXPECT_EQ(refs, prims.size());
  EXPECT_EQ(refs, stats_.references);
  EXPECT_EQ(leaves, t.numLeaves());
  EXPECT_EQ(leaves, stats_.leaves);
  std::sort(ranges.begin(), ranges.end());
  uint32_t next = 0;
  for (const auto& r : ranges) {
    ASSERT_EQ(r.first, next) << "leaf ranges must tile the primitive index array";
    next = r.second;
  }
  EXPECT_EQ(next, prims.size());

  // Completeness, for every triangle: all bottom cells of its bounding box (one cell of margin
  // on each side), tested with the exact test on the unpadded closed cell box.
  const Box root = t.rootBox();
  const Vec3 cs = t.cellSize(H);
  uint64_t tested = 0, missing = 0;
  std::string first;
  for (size_t i = 0; i < mesh_.size(); ++i) {
    const Box b = mesh_.bounds(i);
    int lo[3], hi[3];
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::max(0, static_cast<int>(std::floor((b.lo[a] - root.lo[a]) / cs[a])) - 1);
      hi[a] = std::min(t.dim(H, a) - 1, static_cast<int>(std::floor((b.hi[a] - root.lo[a]) / cs[a])) + 1);
    }
    for (int z = lo[2]; z <= hi[2]; ++z)
      for (int y = lo[1]; y <= hi[1]; ++y)
        for (int x = lo[0]; x <= hi[0]; ++x) {
          const int c[3] = {x, y, z};
          if (!mesh_.overlaps(i, t.nodeBox(H, c))) continue;
          ++tested;
          if (!leafHolds(t, c, static_cast<uint32_t>(i)) && missing++ == 0)
            first = "triangle " + std::to_string(i) + " missing from cell (" + std::to_string(x) + "," +
                    std::to_string(y) + "," + std::to_string(z) + ")";
        }
  }
  EXPECT_EQ(missing, 0u) << first;
  EXPECT_GE(tested, mesh_.size()) << "every triangle overlaps at least one cell";
}

// (c) Existence: every existing node's parent exists (monotone along root-to-leaf paths), and
// every existing inner node has an existing child (an inner node exists iff a child does).
// Level shapes follow the documented split rules and the automatic height rule.
TEST_P(RealMeshTree, ExistenceIsMonotoneAndExact) {
  const MatrixTree& t = tree_;
  const int H = t.height();
  int root[3] = {0, 0, 0};
  EXPECT_TRUE(t.nodeExists(0, root));
  for (int a = 0; a < 3; ++a) EXPECT_EQ(t.dim(0, a), 1);
  uint64_t orphans = 0, childless = 0, nodes = 0;
  for (int l = 1; l <= H; ++l) {
    auto check = [&](const int c[3]) {
      if (!t.nodeExists(l, c)) return;
      ++nodes;
      int p[3];
      for (int a = 0; a < 3; ++a) p[a] = c[a] >> (t.logDim(l, a) - t.logDim(l - 1, a));
      orphans += !t.nodeExists(l - 1, p);
    };
    if (l == H)
      forEachAllocated(t.leafLevel(), check);
    else
      forEachAllocated(t.innerLevel(l), check);
  }
  for (int l = 0; l < H; ++l) {
    int sh[3];
    for (int a = 0; a < 3; ++a) sh[a] = t.logDim(l + 1, a) - t.logDim(l, a);
    forEachAllocated(t.innerLevel(l), [&](const int c[3]) {
      if (!t.nodeExists(l, c)) return;
      bool any = false;
      for (int z = 0; z < (1 << sh[2]) && !any; ++z)
        for (int y = 0; y < (1 << sh[1]) && !any; ++y)
          for (int x = 0; x < (1 << sh[0]) && !any; ++x) {
            const int cc[3] = {(c[0] << sh[0]) + x, (c[1] << sh[1]) + y, (c[2] << sh[2]) + z};
            any = t.nodeExists(l + 1, cc);
          }
      childless += !any;
    });
  }
  EXPECT_EQ(orphans, 0u) << "existing nodes under an absent parent";
  EXPECT_EQ(childless, 0u) << "existing inner nodes without an existing child";
  EXPECT_GT(nodes, 0u);

  // Level shapes: node extent = root extent / 2^logDim; each level splits by the kind's rule.
  const Vec3 ext = t.rootBox().extent();
  for (int l = 0; l <= H; ++l)
    for (int a = 0; a < 3; ++a) EXPECT_EQ(t.cellSize(l)[a], std::ldexp(ext[a], -t.logDim(l, a)));
  for (int l = 1; l <= H; ++l) {
    const Vec3 c = t.cellSize(l - 1);
    const double m = maxComponent(c);
    int splits = 0;
    for (int a = 0; a < 3; ++a) {
      const int s = t.logDim(l, a) - t.logDim(l - 1, a);
      ASSERT_TRUE(s == 0 || s == 1);
      splits += s;
      if (kind_ == TreeKind::Octree) {
        EXPECT_EQ(s, c[a] * 2.0 > m ? 1 : 0) << "level " << l << " axis " << a;
      }
    }
    if (kind_ == TreeKind::RegularKd) {
      ASSERT_EQ(splits, 1);
      const int a = (c.x >= c.y && c.x >= c.z) ? 0 : (c.y >= c.z ? 1 : 2);
      EXPECT_EQ(t.logDim(l, a) - t.logDim(l - 1, a), 1) << "level " << l << " must split its largest axis";
    }
  }
  // Automatic height: the shallowest level whose largest node extent is <= leafScale x median
  // triangle extent, unless that level's candidate leaves (bounding-box cells) average more than
  // BuildOptions::maxCandidates per triangle, in which case it goes up one level at a time.
  // The engine samples the triangles; here the mean is over all of them, hence the margins.
  const double target = 2.0 * stats_.medianPrimitiveExtent;
  const double maxCandidates = mtree::BuildOptions{}.maxCandidates;
  EXPECT_GT(stats_.medianPrimitiveExtent, 0);
  auto split = [&](Vec3 cell, int ld[3]) {  // one level down, by the kind's rule
    const double m = maxComponent(cell);
    if (kind_ == TreeKind::Octree) {
      for (int a = 0; a < 3; ++a)
        if (cell[a] * 2.0 > m) cell[a] *= 0.5, ++ld[a];
    } else {
      const int a = (cell.x >= cell.y && cell.x >= cell.z) ? 0 : (cell.y >= cell.z ? 1 : 2);
      cell[a] *= 0.5, ++ld[a];
    }
    return cell;
  };
  auto meanCandidates = [&](const int ld[3]) {
    double sum = 0;
    const Box root = t.rootBox();
    for (size_t i = 0; i < mesh_.size(); ++i) {
      const Box b = mesh_.bounds(i);
      double c = 1;
      for (int a = 0; a < 3; ++a) {
        const double cs = std::ldexp(ext[a], -ld[a]);
        const int top = (1 << ld[a]) - 1;
        const int lo = std::min(top, std::max(0, static_cast<int>(std::floor((b.lo[a] - root.lo[a]) / cs))));
        const int hi = std::min(top, std::max(0, static_cast<int>(std::floor((b.hi[a] - root.lo[a]) / cs))));
        c *= hi - lo + 1;
      }
      sum += c;
    }
    return sum / double(mesh_.size());
  };
  int ldH[3] = {t.logDim(H, 0), t.logDim(H, 1), t.logDim(H, 2)};
  const double meanH = meanCandidates(ldH);
  if (maxComponent(t.cellSize(H)) <= target) {
    if (H > 0) {
      EXPECT_GT(maxComponent(t.cellSize(H - 1)), target) << "not the shallowest level reaching the target";
    }
  } else {
    // Stopped above the target: the next level down has too many candidates per triangle.
    int ld[3] = {ldH[0], ldH[1], ldH[2]};
    split(t.cellSize(H), ld);
    EXPECT_GT(meanCandidates(ld), 0.8 * maxCandidates) << "height " << H << " stops short of the target";
  }
  if (H > 0) {
    EXPECT_LE(meanH, 1.25 * maxCandidates) << "height " << H;
  }
  std::printf("[height] %s %s: H=%d, leaf extent %.4g, target %.4g, candidates per triangle %.2f\n",
              rel_.c_str(), mtree::treeKindName(kind_), H, maxComponent(t.cellSize(H)), target, meanH);
}

// (d) The build does not depend on the thread count.
TEST_P(RealMeshTree, DeterministicAcrossThreadCounts) {
  std::vector<MatrixTree> trees;
  for (int threads : {1, 2, 4})
    trees.push_back(mtest::buildTree(mesh_, mtest::options(kind_, 0, 8, threads)));
  const MatrixTree& r = trees[0];
  for (size_t k = 1; k < trees.size(); ++k) {
    const MatrixTree& t = trees[k];
    mtest::expectSameTree(t, r, "threads index " + std::to_string(k));
    EXPECT_EQ(t.bytes(), r.bytes());
  }
  // And the tree of the fixture (default thread count) is the same tree.
  EXPECT_TRUE(tree_.primitiveIndices() == r.primitiveIndices());
}

// The ray walk's caches are copies of the levels: every bit of the dense upper levels equals
// the block-sparse existence byte (all nodes of those levels, present or not), and every leaf
// occupancy bit equals `range.begin != MT_NULL` (every entry of every allocated leaf block).
// Both caches must be in use on these meshes (8^3 leaf blocks, small upper levels), or the walk's
// fast paths would go untested; a rebuild with a different block edge drops the leaf masks.
// The work arrays a build keeps for the next one: freed on request, and a build after that
// (allocating them again) gives the same tree.
TEST_P(RealMeshTree, ReleasedBuildScratchRebuildsTheSameTree) {
  MatrixTree t = mtest::buildTree(mesh_, mtest::options(kind_, 0, 8, 2));
  EXPECT_GT(t.buildScratchBytes(), 0u);
  const size_t bytes = t.bytes();
  t.releaseBuildScratch();
  EXPECT_EQ(t.buildScratchBytes(), 0u);
  EXPECT_EQ(t.bytes(), bytes);
  mtest::expectSameTree(t, tree_, "released");
  mtree::MatrixTreeBuilder<mtree::TriangleMesh>::build(mesh_, mtest::options(kind_, 0, 8, 2), t, nullptr);
  mtest::expectSameTree(t, tree_, "rebuilt after the release");
}

TEST_P(RealMeshTree, WalkCachesMirrorTheLevels) {
  const MatrixTree& t = tree_;
  const int H = t.height();
  ASSERT_GT(t.denseLevels(), 0);
  ASSERT_LE(t.denseLevels(), H);
  uint64_t checked = 0, differ = 0;
  for (int l = 0; l < t.denseLevels(); ++l) {
    for (int z = 0; z < t.dim(l, 2); ++z)
      for (int y = 0; y < t.dim(l, 1); ++y)
        for (int x = 0; x < t.dim(l, 0); ++x) {
          const int c[3] = {x, y, z};
          const uint8_t* v = t.innerLevel(l).find(x, y, z);
          differ += t.innerExists(l, c) != (v && *v);
          ++checked;
        }
  }
  EXPECT_EQ(differ, 0u) << "dense level bits differ from the block-sparse levels (" << checked << " nodes)";
  // Below the dense levels innerExists reads the levels themselves: spot-check it there too.
  for (int l = t.denseLevels(); l < H; ++l)
    forEachAllocated(t.innerLevel(l), [&](const int c[3]) {
      differ += t.innerExists(l, c) != t.nodeExists(l, c);
    });
  EXPECT_EQ(differ, 0u);

  const auto& leaves = t.leafLevel();
  const std::vector<uint64_t>& masks = t.leafMasks();
  ASSERT_EQ(masks.size(), size_t(leaves.numBlocks()) * 8) << "one 512-bit mask per 8x8x8 leaf block";
  uint64_t leafBits = 0, leafDiffer = 0;
  forEachAllocated(leaves, [&](const int c[3]) {
    const uint32_t b = leaves.pointers()[leaves.pointerIndex(c[0], c[1], c[2])];
    const bool bit = (masks[size_t(b) * 8 + (c[2] & 7)] >> (8 * (c[1] & 7) + (c[0] & 7))) & 1u;
    leafDiffer += bit != (leaves.get(c[0], c[1], c[2]).begin != MT_NULL);
    leafBits += bit;
  });
  EXPECT_EQ(leafDiffer, 0u) << "leaf occupancy bits differ from the leaf ranges";
  EXPECT_EQ(leafBits, t.numLeaves());
  EXPECT_EQ(t.bytes() - t.walkCacheBytes(), [&] {
    size_t b = t.primitiveIndices().size() * sizeof(uint32_t);
    for (int l = 0; l <= H; ++l) b += t.levelBytes(l);
    return b;
  }()) << "bytes() must count the caches on top of the levels";

  const MatrixTree other = mtest::buildTree(mesh_, mtest::options(kind_, H, 4));
  EXPECT_TRUE(other.leafMasks().empty()) << "4x4x4 leaf blocks: no masks (the walk reads the ranges)";
}

// nodeOf (the walk's classification of a bottom-level cell from the masks and the per-block
// empty levels) gives locate's answer from the root, level, coordinates, existence and range,
// for every bottom-level cell: at the automatic height and two deeper ones (more levels inside
// and above the blocks). Octrees over these meshes always qualify; a kd-tree may not (its
// nodes can straddle leaf blocks), and then the walk keeps the searches.
TEST_P(RealMeshTree, NodeOfMatchesLocateEverywhere) {
  for (int extra : {0, 1, 2}) {
    const MatrixTree t = extra == 0 ? MatrixTree(tree_)
                                    : mtest::buildTree(mesh_, mtest::options(kind_, tree_.height() + extra));
    const int H = t.height();
    if (kind_ == TreeKind::Octree) {
      ASSERT_TRUE(t.fastNodeOf()) << "height " << H;
    }
    if (!t.fastNodeOf()) continue;
    uint64_t cells = 0, differ = 0, leaves = 0, levels[MT_MAX_LEVELS] = {};
    mtree::TraversalStats fastStats, searchStats;
    for (int z = 0; z < t.dim(H, 2); ++z)
      for (int y = 0; y < t.dim(H, 1); ++y)
        for (int x = 0; x < t.dim(H, 0); ++x) {
          const int L[3] = {x, y, z};
          const mtree::NodeRef a = t.nodeOf(L, &fastStats), b = t.locate(L, 0, H + 1, &searchStats);
          const bool same = a.level == b.level && a.exists == b.exists && a.c[0] == b.c[0] && a.c[1] == b.c[1] &&
                            a.c[2] == b.c[2] && (!a.exists || (a.range.begin == b.range.begin && a.range.end == b.range.end));
          if (!same && differ < 5)
            ADD_FAILURE() << "height " << H << " cell (" << x << ", " << y << ", " << z << "): nodeOf level " << a.level
                          << " exists " << a.exists << ", locate level " << b.level << " exists " << b.exists;
          differ += !same;
          leaves += b.exists;
          ++levels[b.level];
          ++cells;
        }
    EXPECT_EQ(differ, 0u) << "height " << H << ", " << cells << " cells";
    EXPECT_EQ(leaves, t.numLeaves());
    // The answers span the levels: leaves, empty cells beside them, and large empty nodes.
    EXPECT_GT(levels[H], leaves) << "empty bottom-level cells next to leaves";
    int emptyLevels = 0;
    for (int l = 1; l < H; ++l) emptyLevels += levels[l] > 0;
    EXPECT_GE(emptyLevels, 2) << "height " << H;
    EXPECT_LT(fastStats.nodeVisits, searchStats.nodeVisits) << "height " << H;
  }
}

// One traverseRay call's leaf calls, exactly: where the leaf's ids start, how many, the
// segment's t interval in it, and the leaf's bottom-level coordinates (the five-argument call),
// with whether those coordinates hold exactly that leaf.
struct LeafCall {
  const uint32_t* ids;
  uint32_t count;
  double tEnter, tExit;
  int L[3];
  bool coordsHoldIt;
  bool operator==(const LeafCall& o) const {
    return ids == o.ids && count == o.count && tEnter == o.tEnter && tExit == o.tExit && L[0] == o.L[0] &&
           L[1] == o.L[1] && L[2] == o.L[2] && coordsHoldIt == o.coordsHoldIt;
  }
};

// The walk's leaf calls for the segment o + t d, t in [0, 1], stopping after `stopAfter` calls
// (0: never), with or without stats (a compile-time policy of the same walk).
std::vector<LeafCall> leafCalls(const MatrixTree& t, Vec3 o, Vec3 d, int stopAfter, bool stats) {
  std::vector<LeafCall> calls;
  mtree::TraversalStats st;
  t.traverseRay(
      o, d, 0.0, 1.0,
      [&](const uint32_t* ids, uint32_t count, double tEnter, double tExit, const int* L) {
        MtLeafRange r;
        const bool holds = t.leafAt(L, r) && t.primitiveIndices().data() + r.begin == ids && r.end - r.begin == count;
        calls.push_back({ids, count, tEnter, tExit, {L[0], L[1], L[2]}, holds});
        return stopAfter > 0 && static_cast<int>(calls.size()) >= stopAfter;
      },
      stats ? &st : nullptr);
  return calls;
}

// The step table (one byte per bottom-level cell of the allocated leaf blocks: nodeOf's answer)
// exists exactly where the rule says (nodeOf available, at most half of those cells leaves),
// holds nodeOf's answer for every bottom-level cell, and the walk by it makes the same leaf
// calls, with the same t intervals to the bit, as the walk that classifies each cell from the
// masks; the coordinates a five-argument callback receives hold the leaf it is called for. 20 000
// seeded segments per tree (a fifth parallel to one or two axes, a tenth starting on a
// bottom-level node plane, some stopping after the first or second leaf), at the automatic
// height and one and two levels deeper.
TEST_P(RealMeshTree, StepTableWalkIsTheTreeWalk) {
  for (int extra : {0, 1, 2}) {
    MatrixTree t = extra == 0 ? MatrixTree(tree_)
                              : mtest::buildTree(mesh_, mtest::options(kind_, tree_.height() + extra));
    const int H = t.height();
    uint64_t leafBits = 0;
    for (const uint64_t w : t.leafMasks()) leafBits += std::bitset<64>(w).count();
    const uint64_t blockCells = uint64_t(t.leafLevel().numBlocks()) * 512;
    const bool rule = t.fastNodeOf() && !t.leafMasks().empty() && 2 * leafBits <= blockCells;
    EXPECT_EQ(t.hasStepTable(), rule) << "height " << H << ": " << leafBits << " leaves in " << blockCells << " cells";
    if (kind_ == TreeKind::Octree) {
      EXPECT_TRUE(t.hasStepTable()) << "a surface's octree: most cells of its leaf blocks are empty (height " << H << ")";
    }
    if (!t.hasStepTable()) continue;
    // Every bottom-level cell: the table's node is nodeOf's (level; leaf or empty).
    uint64_t cellsDiffer = 0;
    for (int z = 0; z < t.dim(H, 2); ++z)
      for (int y = 0; y < t.dim(H, 1); ++y)
        for (int x = 0; x < t.dim(H, 0); ++x) {
          const int L[3] = {x, y, z};
          bool leaf = false;
          const int level = t.stepTableLevel(L, leaf);
          const NodeRef n = t.nodeOf(L, nullptr);
          cellsDiffer += level != n.level || leaf != n.exists;
        }
    EXPECT_EQ(cellsDiffer, 0u) << "height " << H;
    mtest::Rng rng(seed(70 + extra));
    const Box root = t.rootBox();
    const Vec3 e = root.extent();
    uint64_t differ = 0, calls = 0, coordsWrong = 0;
    for (int i = 0; i < 20000; ++i) {
      Vec3 o, d;
      for (int a = 0; a < 3; ++a) {
        o[a] = rng.uniform(root.lo[a] - 0.1 * e[a], root.hi[a] + 0.1 * e[a]);
        d[a] = rng.uniform(-0.6, 0.6) * e[a];
      }
      const uint32_t kind = rng.below(10);
      if (kind < 2) {
        d[rng.below(3)] = 0.0;  // parallel to an axis plane
        if (kind == 0) d[rng.below(3)] = 0.0;  // and maybe to a second: along an axis
      } else if (kind == 2) {
        // On a bottom-level node plane of a random axis.
        const int a = static_cast<int>(rng.below(3));
        o[a] = root.lo[a] + rng.below(static_cast<uint32_t>(t.dim(H, a))) * t.cellSize(H)[a];
      }
      const int stopAfter = static_cast<int>(rng.below(4)) - 1 > 0 ? static_cast<int>(rng.below(2)) + 1 : 0;
      const std::vector<LeafCall> byTable = leafCalls(t, o, d, stopAfter, false);
      const std::vector<LeafCall> byTableCounted = leafCalls(t, o, d, stopAfter, true);
      t.enableStepTable(false);
      const std::vector<LeafCall> byMasks = leafCalls(t, o, d, stopAfter, true);
      t.enableStepTable(true);
      EXPECT_TRUE(byTableCounted == byTable) << "height " << H << " ray " << i << ": counting changed the walk";
      calls += byMasks.size();
      for (const LeafCall& c : byMasks) coordsWrong += !c.coordsHoldIt;
      if (byTable != byMasks) {
        if (differ < 3)
          ADD_FAILURE() << "height " << H << " ray " << i << ": " << byTable.size() << " leaf calls by the table, "
                        << byMasks.size() << " by the masks";
        ++differ;
      }
    }
    EXPECT_EQ(differ, 0u) << "height " << H;
    EXPECT_EQ(coordsWrong, 0u) << "height " << H << ": the leaf's coordinates handed to fn must hold it";
    EXPECT_GT(calls, 10000u) << "the segments must cross leaves";
  }
}

// BoundingBox mode references every leaf its box touches: a superset of Exact, leaf by leaf.
TEST_P(RealMeshTree, BoundingBoxModeIsASupersetOfExact) {
  mtree::BuildOptions opt = mtest::options(kind_);
  opt.overlap = mtree::OverlapMode::BoundingBox;
  mtree::BuildStats bst;
  const MatrixTree bb = mtest::buildTree(mesh_, opt, &bst);
  ASSERT_EQ(bb.height(), tree_.height());
  for (int a = 0; a < 3; ++a) ASSERT_EQ(bb.logDim(bb.height(), a), tree_.logDim(tree_.height(), a));
  EXPECT_GE(bst.references, stats_.references);
  EXPECT_GE(bst.leaves, stats_.leaves);
  uint64_t notSuperset = 0, extra = 0;
  const auto& ep = tree_.primitiveIndices();
  const auto& bp = bb.primitiveIndices();
  forEachLeaf(tree_, [&](const int c[3], const MtLeafRange& r) {
    if (!bb.nodeExists(bb.height(), c)) {
      ++notSuperset;
      return;
    }
    const MtLeafRange s = bb.leafLevel().get(c[0], c[1], c[2]);
    if (!std::includes(bp.begin() + s.begin, bp.begin() + s.end, ep.begin() + r.begin, ep.begin() + r.end))
      ++notSuperset;
    extra += (s.end - s.begin) - (r.end - r.begin);
  });
  EXPECT_EQ(notSuperset, 0u);
  // Every box-mode reference: the triangle's bounding box touches the leaf.
  const double tol = 1e-9 * maxComponent(bb.rootBox().extent());
  uint64_t far = 0;
  forEachLeaf(bb, [&](const int c[3], const MtLeafRange& r) {
    const Box box = padded(bb.nodeBox(bb.height(), c), tol);
    for (uint32_t k = r.begin; k < r.end; ++k) far += !mesh_.bounds(bp[k]).overlaps(box);
  });
  EXPECT_EQ(far, 0u);
  RecordProperty("extraReferences", static_cast<int>(extra));
}

// The builder's batched overlap test (TriangleBoxTester: box centres, one half size, box-normal
// axes skipped) against triangleOverlapsBox, on boxes that overlap the triangle's bounding box
// (the builder's candidates). Within a relative 1e-9 of the box size the two must agree: a
// tester "no" where the exact test says "yes" would drop a reference.
TEST(TriangleBoxTester, AgreesWithTheSeparatingAxisTest) {
  mtest::Rng rng(42);
  uint64_t boxes = 0, overlapping = 0, missed = 0, spurious = 0;
  for (int tri = 0; tri < 3000; ++tri) {
    const Vec3 a = rng.inBox(Box{Vec3(-1, -1, -1), Vec3(1, 1, 1)});
    Vec3 b = a + rng.direction() * rng.uniform(0.01, 1.0), c = a + rng.direction() * rng.uniform(0.01, 1.0);
    if (tri % 10 == 0) c = a + (b - a) * 2.0;  // degenerate: a segment
    if (tri % 10 == 1) c = b = a;              // degenerate: a point
    const Vec3 half(rng.uniform(0.01, 0.3), rng.uniform(0.01, 0.3), rng.uniform(0.01, 0.3));
    const mtree::TriangleBoxTester tester(a, b, c, half);
    Box tb;
    tb.extend(a), tb.extend(b), tb.extend(c);
    for (int k = 0; k < 60; ++k) {
      // A box centre whose box overlaps the triangle's bounding box.
      Vec3 ctr;
      for (int ax = 0; ax < 3; ++ax) ctr[ax] = rng.uniform(tb.lo[ax] - half[ax], tb.hi[ax] + half[ax]);
      ++boxes;
      const double eps = 1e-9 * maxComponent(half);
      const Box box{ctr - half, ctr + half};
      const Box shrunk{ctr - half + Vec3(eps, eps, eps), ctr + half - Vec3(eps, eps, eps)};
      const Box grown{ctr - half - Vec3(eps, eps, eps), ctr + half + Vec3(eps, eps, eps)};
      const bool t = tester.overlaps(ctr);
      overlapping += mtree::triangleOverlapsBox(a, b, c, box);
      missed += !t && mtree::triangleOverlapsBox(a, b, c, shrunk);
      spurious += t && !mtree::triangleOverlapsBox(a, b, c, grown);
    }
  }
  EXPECT_EQ(missed, 0u) << "TriangleBoxTester rejects boxes the triangle overlaps";
  EXPECT_EQ(spurious, 0u) << "TriangleBoxTester accepts boxes the triangle does not touch";
  EXPECT_GT(overlapping, boxes / 10);
  EXPECT_LT(overlapping, boxes - boxes / 10);
}

INSTANTIATE_TEST_SUITE_P(RealMeshes, RealMeshTree,
                         ::testing::Combine(::testing::ValuesIn(mtest::realMeshes()),
                                            ::testing::Values(TreeKind::Octree, TreeKind::RegularKd)),
                         [](const ::testing::TestParamInfo<std::tuple<std::string, TreeKind>>& info) {
                           return mtest::meshTag(std::get<0>(info.param)) + "_" +
                                  mtree::treeKindName(std::get<1>(info.param));
                         });

}  // namespace

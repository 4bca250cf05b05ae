// The quantized leaf boxes (engine/include/mtree/cells/leaf_boxes.h) and the ray queries' leaf
// filter (mtree/cells/leaf_segment_filter.h) against brute force:
//   LeafBoxTest      gather() equals a byte-by-byte comparison of every box with the range, on
//                    both paths (eight at a time from 8 boxes on, one at a time below);
//   quantizePoint    on real grids built with the locator's boxes, every cell of a point's leaf
//                    whose padded bounds hold the point keeps its box (no false rejection), and
//                    every box that passes holds the point's quantized position;
//   LeafSegmentFilter on a surface and a grid, every candidate whose dequantized box the segment
//                    crosses in the leaf at t in [0, 1] is kept, with an entry t no later than
//                    the exact slab test's, sorted; it declines (-1) with a tolerance.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "mtree/cells/cells.h"
#include "mtree/cells/leaf_boxes.h"
#include "mtree/cells/leaf_segment_filter.h"
#include "mtree/core/builder.h"
#include "test_util.h"
#include "vtk_grid_util.h"

namespace {

using mtree::Box;
using mtree::CellSet;
using mtree::MatrixTree;
using mtree::Vec3;

/// The tree and quantized leaf boxes the locator builds on these cells (counting sort, bounding-box overlap).
struct Built {
  CellSet cells;
  MatrixTree tree;
  mtree::LargeVector<uint8_t> boxes;
};

void build(Built& b) {
  mtree::BuildOptions o;
  o.threads = 1;
  o.sort = mtree::BuildSort::Counting;
  mtree::MatrixTreeBuilder<CellSet>::build<6>(b.cells, o, b.tree, nullptr, &b.boxes, mtree::LeafBoxQuantizer());
  ASSERT_EQ(b.boxes.size(), 6 * b.tree.primitiveIndices().size());
}

/// A triangle mesh as a CellSet of VTK_TRIANGLE cells (what the locator builds on polydata).
CellSet asCells(const mtree::TriangleMesh& m) {
  std::vector<uint32_t> off(m.size() + 1);
  for (size_t i = 0; i <= m.size(); ++i) off[i] = static_cast<uint32_t>(3 * i);
  return CellSet(m.points(), std::move(off), m.triangles(), std::vector<uint8_t>(m.size(), mtree::kTriangle));
}

TEST(LeafBoxTest, GatherEqualsTheByteComparison) {
  mtest::Rng rng(17);
  std::vector<uint8_t> boxes(6 * 300);
  std::vector<uint32_t> got(300), want;
  for (int round = 0; round < 3000; ++round) {
    // Bytes from a narrow range in some rounds, so that many boxes pass and fail on one field.
    const uint32_t span = round % 3 == 0 ? 256 : 24;
    const uint32_t base = rng.below(256 - std::min<uint32_t>(span, 255));
    for (uint8_t& v : boxes) v = static_cast<uint8_t>(std::min<uint32_t>(255, base + rng.below(span)));
    uint8_t qmax[3], qmin[3];
    for (int a = 0; a < 3; ++a) {
      qmax[a] = static_cast<uint8_t>(std::min<uint32_t>(255, base + rng.below(span)));
      qmin[a] = static_cast<uint8_t>(std::min<uint32_t>(255, base + rng.below(span)));
    }
    const uint32_t k = rng.below(40), stop = k + rng.below(260);
    const mtree::LeafBoxTest test(qmax, qmin, stop - k);
    const int n = test.gather(boxes.data(), k, stop, got.data());
    want.clear();
    for (uint32_t i = k; i < stop; ++i) {
      const uint8_t* q = &boxes[6 * i];
      bool pass = true;
      for (int a = 0; a < 3; ++a) pass = pass && q[2 * a] <= qmax[a] && q[2 * a + 1] >= qmin[a];
      if (pass) want.push_back(i);
    }
    ASSERT_EQ(std::vector<uint32_t>(got.begin(), got.begin() + n), want) << "round " << round;
  }
}

/// A surface (meshes/...) or a CFD grid, built as the locator builds it.
void load(const std::string& rel, Built& b) {
  if (rel.rfind("meshes/", 0) == 0) {
    b.cells = asCells(mtest::loadRealMesh(rel));
  } else {
    auto g = mtest::readGrid(rel);
    ASSERT_TRUE(g) << rel;
    b.cells = mtest::cellSet(g);
  }
  build(b);
}

class LeafBoxesOnGrids : public ::testing::TestWithParam<std::string> {};

TEST_P(LeafBoxesOnGrids, APointInItsCellsPaddedBoundsIsNeverRejected) {
  Built b;
  load(GetParam(), b);
  if (HasFatalFailure()) return;
  const CellSet& cells = b.cells;
  const MatrixTree& tree = b.tree;
  mtest::Rng rng(mtest::seedFor(GetParam()));
  // Points at random and near the cells' vertices (where several padded boxes meet).
  std::vector<Vec3> pts;
  for (int i = 0; i < 2000; ++i) pts.push_back(rng.inBox(tree.rootBox()));
  for (int i = 0; i < 2000; ++i) {
    const size_t c = rng.below(static_cast<uint32_t>(cells.size()));
    const Vec3 p = cells.cellPoint(c, static_cast<int>(rng.below(static_cast<uint32_t>(cells.numCellPoints(c)))));
    pts.push_back(p + rng.direction() * (1e-4 * std::max({cells.maxExtent().x, cells.maxExtent().y})));
  }
  // Per point, every cell its leaf references whose padded bounds hold it (the brute-force test,
  // reference by reference) must keep its box.
  size_t checked = 0, passed = 0;
  std::vector<uint32_t> idx(cells.size());
  for (size_t i = 0; i < pts.size(); ++i) {
    const double x[3] = {pts[i].x, pts[i].y, pts[i].z};
    const mtree::NodeRef n = tree.leafHolding(pts[i]);
    if (!n.exists) continue;
    const Box lb = tree.nodeBox(n.level, n.c);
    uint8_t qmax[3], qmin[3];
    mtree::quantizePoint(x, lb, qmax, qmin);
    const mtree::LeafBoxTest test(qmax, qmin, n.range.end - n.range.begin);
    const int np = test.gather(b.boxes.data(), n.range.begin, n.range.end, idx.data());
    for (int j = 0; j < np; ++j) {
      const uint8_t* q = &b.boxes[6 * size_t(idx[j])];
      for (int a = 0; a < 3; ++a) {
        // The box holds the point's quantized position (quantizePoint's expression).
        const double qa =
            std::min(255.0, std::max(0.0, (x[a] - lb.lo[a]) * mtree::detail::leafBoxScale(lb.lo[a], lb.hi[a])));
        ASSERT_LE(q[2 * a], qa);
        ASSERT_GE(q[2 * a + 1], qa);
      }
    }
    passed += static_cast<size_t>(np);
    const std::vector<uint32_t> kept(idx.begin(), idx.begin() + np);
    for (uint32_t k = n.range.begin; k < n.range.end; ++k) {
      const Box cb = cells.bounds(tree.primitiveIndices()[k]);
      const double pad = mtree::detail::leafBoxPad(cb);
      bool in = true;
      for (int a = 0; a < 3; ++a) in = in && x[a] >= cb.lo[a] - pad && x[a] <= cb.hi[a] + pad;
      if (!in) continue;
      ++checked;
      ASSERT_TRUE(std::binary_search(kept.begin(), kept.end(), k))
          << "point " << i << ": cell " << tree.primitiveIndices()[k] << " rejected";
    }
  }
  EXPECT_GT(checked, pts.size() / 2) << "the points must meet cells";
  EXPECT_GE(passed, checked);
}

INSTANTIATE_TEST_SUITE_P(Grids, LeafBoxesOnGrids,
                         ::testing::Values("cfd/brick_tets.su2", "cfd/brick_hex.su2", "meshes/bunny.ply"),
                         [](const auto& info) { return mtest::meshTag(info.param); });

/// The exact slab test of segment o + t d, t in [0, 1], against box b: entry t, or NaN on a miss.
double slabEntry(Vec3 o, Vec3 d, const Box& b) {
  double t0 = 0, t1 = 1;
  for (int a = 0; a < 3; ++a) {
    if (d[a] == 0) {
      if (o[a] < b.lo[a] || o[a] > b.hi[a]) return std::numeric_limits<double>::quiet_NaN();
      continue;
    }
    double ta = (b.lo[a] - o[a]) / d[a], tb = (b.hi[a] - o[a]) / d[a];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
  }
  return t0 <= t1 ? t0 : std::numeric_limits<double>::quiet_NaN();
}

TEST_P(LeafBoxesOnGrids, TheSegmentFilterKeepsEveryBoxTheSegmentCrosses) {
  Built b;
  load(GetParam(), b);
  if (HasFatalFailure()) return;
  const MatrixTree& tree = b.tree;
  mtest::Rng rng(mtest::seedFor(GetParam(), 5));
  const Box root = tree.rootBox();
  const double diag = mtree::norm(root.hi - root.lo);
  std::vector<mtree::LeafSegmentFilter::Candidate> out;
  size_t leaves = 0, kept = 0, crossing = 0;
  for (int s = 0; s < 1500; ++s) {
    const Vec3 o = rng.inBox(root);
    Vec3 d = rng.direction() * (0.3 * diag);
    if (s % 5 == 0) d = Vec3(s % 3 == 0 ? 0 : d.x, s % 3 == 1 ? 0 : d.y, s % 3 == 2 ? 0 : d.z);  // in an axis plane
    const mtree::LeafSegmentFilter filter(tree, b.boxes.data(), b.boxes.size(), b.cells, o, d, 0.0);
    const mtree::LeafSegmentFilter withTol(tree, b.boxes.data(), b.boxes.size(), b.cells, o, d, 1e-6);
    tree.traverseRay(
        o, d, 0.0, 1.0,
        [&](const uint32_t* ids, uint32_t count, double, double, const int* leaf) {
          out.assign(count, {});
          EXPECT_EQ(withTol.candidates(ids, count, leaf, 1.0, out.data()), -1) << "a tolerance: every candidate";
          const int n = filter.candidates(ids, count, leaf, 1.0, out.data());
          EXPECT_GE(n, 0);
          ++leaves;
          const Box lb = tree.nodeBox(tree.height(), leaf);
          const size_t first = static_cast<size_t>(ids - tree.primitiveIndices().data());
          std::vector<double> entry(count, std::numeric_limits<double>::quiet_NaN());
          for (int j = 0; j < n; ++j) {
            EXPECT_LT(out[j].k, count);
            if (j > 0) {
              EXPECT_LE(out[j - 1].t, out[j].t) << "sorted by entry";
            }
            entry[out[j].k] = out[j].t;
          }
          for (uint32_t k = 0; k < count; ++k) {
            const uint8_t* q = &b.boxes[6 * (first + k)];
            Box qb;
            for (int a = 0; a < 3; ++a) {
              const double unit = (lb.hi[a] - lb.lo[a]) / 255.0;
              qb.lo[a] = lb.lo[a] + q[2 * a] * unit;
              qb.hi[a] = lb.lo[a] + q[2 * a + 1] * unit;
            }
            const double te = slabEntry(o, d, qb);
            if (std::isnan(te)) continue;
            ++crossing;
            EXPECT_FALSE(std::isnan(entry[k])) << "segment " << s << ": box " << k << " crossed at " << te
                                               << " but rejected";
            EXPECT_LE(entry[k], te + 1e-9) << "segment " << s << ": entry later than the box's";
          }
          kept += static_cast<size_t>(n);
          return false;
        },
        nullptr);
  }
  EXPECT_GT(leaves, 1000u);
  EXPECT_GT(crossing, 1000u);
  EXPECT_GE(kept, crossing);
}

}  // namespace

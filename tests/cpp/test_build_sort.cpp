// The builder's two ways of grouping references by leaf (BuildOptions::sort):
//   trees    BuildSort::Counting gives the Radix tree array for array (leaf ranges, primitive
//            lists, existence at every level) at 1, 2 and 3 threads, octree and regular kd-tree,
//            exact and bounding-box overlap, on real surface meshes and a CFD grid, with the
//            automatic height and with a low one (long leaves: the sort's std::sort path);
//   boxes    the per-reference data of build<6> with LeafBoxQuantizer (the locator's quantized
//            leaf boxes, leaf_boxes.h) equals, byte for byte, a pass over the leaves with
//            floor/ceil on each reference's cached cell bounds (the boxes' definition);
//   pieces   quantizeLeafBox against that formula on edge cases, detail::sortLeaf on long and
//            short leaves with data, a two-thread build in a team of one, an empty primitive set,
//            a bad sort value.
#include <gtest/gtest.h>


#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <string>
#include <vector>

#include "mtree/cells/leaf_boxes.h"
#include "mtree/core/builder.h"
#include "mtree/cells/cells.h"
#include "test_util.h"
#include "vtk_grid_util.h"

namespace {

using mtree::BuildOptions;
using mtree::BuildSort;
using mtree::CellSet;
using mtree::MatrixTree;
using mtree::MatrixTreeBuilder;
using mtree::OverlapMode;
using mtree::TreeKind;

/// A CFD grid of the shared data folder as a CellSet, in the file's cell order.
CellSet loadGrid(const std::string& rel) {
  vtkSmartPointer<vtkUnstructuredGrid> g = mtest::readGrid(rel);
  if (!g || g->GetNumberOfCells() == 0) {
    ADD_FAILURE() << "no cells read from " << rel;
    throw std::runtime_error("loadGrid");
  }
  return mtest::cellSet(g);
}

/// A triangle mesh as a CellSet of VTK_TRIANGLE cells (what the locator builds on polydata).
CellSet asCells(const mtree::TriangleMesh& m) {
  std::vector<uint32_t> off(m.size() + 1);
  for (size_t i = 0; i <= m.size(); ++i) off[i] = static_cast<uint32_t>(3 * i);
  return CellSet(m.points(), std::move(off), m.triangles(), std::vector<uint8_t>(m.size(), mtree::kTriangle));
}

BuildOptions opts(TreeKind kind, OverlapMode overlap, BuildSort sort, int threads, int height = 0) {
  BuildOptions o;
  o.kind = kind;
  o.overlap = overlap;
  o.sort = sort;
  o.threads = threads;
  o.height = height;
  return o;
}

std::string name(const BuildOptions& o) {
  return std::string(mtree::treeKindName(o.kind)) + (o.overlap == OverlapMode::Exact ? " exact" : " bbox") +
         (o.sort == BuildSort::Radix ? " radix" : " counting") + " threads " + std::to_string(o.threads) +
         " height " + std::to_string(o.height);
}

/// The quantized leaf boxes by their definition (leaf_boxes.h): a pass over the leaves,
/// floor/ceil on each reference's cached (float) cell bounds padded by 1e-3 of their extent.
std::vector<uint8_t> gatherLeafBoxes(const MatrixTree& tree, const CellSet& cells) {
  const mtree::LargeVector<uint32_t>& prims = tree.primitiveIndices();
  std::vector<uint8_t> out(prims.size() * 6);
  if (tree.empty()) return out;
  const auto& m = tree.leafLevel();
  for (size_t e = 0; e < m.data().size(); ++e) {
    const MtLeafRange r = m.data()[e];
    if (r.begin == MT_NULL) continue;
    int c[3];
    m.entryCoords(static_cast<uint32_t>(e), c);
    const mtree::Box lb = tree.nodeBox(tree.height(), c);
    double scale[3];
    for (int a = 0; a < 3; ++a) scale[a] = 255.0 / (lb.hi[a] - lb.lo[a]);
    for (uint32_t k = r.begin; k < r.end; ++k) {
      const std::array<float, 6> b = cells.cellBox(prims[k]);
      const double pad = 1e-3 * std::max({double(b[1]) - b[0], double(b[3]) - b[2], double(b[5]) - b[4]});
      uint8_t* q = &out[6 * size_t(k)];
      for (int a = 0; a < 3; ++a) {
        const double lo = std::floor((b[2 * a] - pad - lb.lo[a]) * scale[a]);
        const double hi = std::ceil((b[2 * a + 1] + pad - lb.lo[a]) * scale[a]);
        q[2 * a] = static_cast<uint8_t>(lo > 0 ? (lo < 255 ? lo : 255) : 0);
        q[2 * a + 1] = static_cast<uint8_t>(hi < 255 ? (hi > 0 ? hi : 0) : 255);
        if (!(lo <= hi)) {
          q[2 * a] = 0;
          q[2 * a + 1] = 255;
        }
      }
    }
  }
  return out;
}

/// Every sort and thread count against the 1-thread radix build of the same options.
template <class Prims>
void expectSortsAgree(const Prims& prims, TreeKind kind, OverlapMode overlap, int height, const std::string& what) {
  MatrixTree ref;
  mtree::BuildStats refStats;
  MatrixTreeBuilder<Prims>::build(prims, opts(kind, overlap, BuildSort::Radix, 1, height), ref, &refStats);
  ASSERT_FALSE(ref.empty());
  for (BuildSort sort : {BuildSort::Counting, BuildSort::Radix})
    for (int threads : {1, 2, 3}) {
      // Two threads fill the counting sort's leaves from both ends, three take shared cursors.
      if (sort == BuildSort::Radix && threads != 2) continue;
      const BuildOptions o = opts(kind, overlap, sort, threads, height);
      MatrixTree t;
      mtree::BuildStats st;
      MatrixTreeBuilder<Prims>::build(prims, o, t, &st);
      mtest::expectSameTree(ref, t, what + ": " + name(o));
      EXPECT_EQ(st.leaves, refStats.leaves) << what << ": " << name(o);
      EXPECT_EQ(st.references, refStats.references) << what << ": " << name(o);
      EXPECT_EQ(st.height, refStats.height) << what << ": " << name(o);
    }
}

class SortMesh : public ::testing::TestWithParam<std::string> {};

TEST_P(SortMesh, CountingGivesTheRadixTree) {
  const mtree::TriangleMesh mesh = mtest::loadRealMesh(GetParam());
  for (TreeKind kind : {TreeKind::Octree, TreeKind::RegularKd})
    for (OverlapMode overlap : {OverlapMode::Exact, OverlapMode::BoundingBox})
      expectSortsAgree(mesh, kind, overlap, 0, GetParam());
}

INSTANTIATE_TEST_SUITE_P(RealMeshes, SortMesh,
                         ::testing::Values("meshes/bunny.ply", "meshes/horse.ply", "meshes/turbineblade.ply"),
                         [](const auto& info) { return mtest::meshTag(info.param); });

TEST(BuildSort, CountingGivesTheRadixTreeOnACfdGrid) {
  const CellSet cells = loadGrid("cfd/pipe_flow_tets.vtu");
  for (TreeKind kind : {TreeKind::Octree, TreeKind::RegularKd})
    for (OverlapMode overlap : {OverlapMode::Exact, OverlapMode::BoundingBox})
      expectSortsAgree(cells, kind, overlap, 0, "pipe_flow_tets");
}

TEST(BuildSort, BothWaysOfCountingLeavesGiveTheRadixTree) {
  // With three threads count+mark counts the references per leaf when the dense leaf level has
  // at most 2^21 entries and a separate pass counts them beyond (one or two threads always count
  // in count+mark): lucy as cells (what the locator builds) at height 7 (2^21 leaves) and 8
  // (2^24) takes both, and the CFD grid as well.
  const CellSet cells = asCells(mtest::loadRealMesh("meshes/lucy.ply"));
  for (int height : {7, 8}) expectSortsAgree(cells, TreeKind::Octree, OverlapMode::Exact, height, "lucy cells");
  const CellSet grid = loadGrid("cfd/brick_tets.su2");
  for (int height : {5, 8}) expectSortsAgree(grid, TreeKind::Octree, OverlapMode::Exact, height, "brick_tets");
}

TEST(BuildSort, LongLeavesAtALowHeight) {
  // Height 3 over ~70k triangles: leaves of hundreds to thousands of references, which the
  // counting sort orders with std::sort instead of an insertion sort.
  const mtree::TriangleMesh mesh = mtest::loadRealMesh("meshes/bunny.ply");
  for (OverlapMode overlap : {OverlapMode::Exact, OverlapMode::BoundingBox})
    expectSortsAgree(mesh, TreeKind::Octree, overlap, 3, "bunny");
  const CellSet cells = loadGrid("cfd/pipe_flow_tets.vtu");
  expectSortsAgree(cells, TreeKind::RegularKd, OverlapMode::Exact, 4, "pipe_flow_tets");
}

TEST(BuildSort, ReusedMappingsGiveTheSameTree) {
  // A build's large arrays come from mappings freed by earlier builds (memory.h's cache), holding
  // whatever those wrote; here filled with 0xA5 bytes. A build that read an element it did not
  // write would then differ from the 1-thread radix build on fresh memory.
  if (!mtree::detail::mappingCacheWanted()) GTEST_SKIP() << "MATRIXTREE_MAP_CACHE=0";
  const CellSet cells = loadGrid("cfd/pipe_flow_tets.vtu");
  for (OverlapMode overlap : {OverlapMode::BoundingBox, OverlapMode::Exact}) {
    mtree::releaseCachedMemory();
    MatrixTree ref;
    mtree::LargeVector<uint8_t> refBoxes;
    MatrixTreeBuilder<CellSet>::build<6>(cells, opts(TreeKind::Octree, overlap, BuildSort::Radix, 1, 0), ref, nullptr,
                                         &refBoxes, mtree::LeafBoxQuantizer());
    mtree::detail::setMappingCachePoison(true);
    for (BuildSort sort : {BuildSort::Counting, BuildSort::Radix})
      for (int threads : {1, 2, 3})
        for (int rep = 0; rep < 2; ++rep) {
          const BuildOptions o = opts(TreeKind::Octree, overlap, sort, threads, 0);
          MatrixTree t;
          mtree::LargeVector<uint8_t> boxes;
          MatrixTreeBuilder<CellSet>::build<6>(cells, o, t, nullptr, &boxes, mtree::LeafBoxQuantizer());
          mtest::expectSameTree(ref, t, "pipe_flow_tets on reused mappings: " + name(o));
          EXPECT_TRUE(boxes == refBoxes) << name(o);
        }
    EXPECT_GT(mtree::cachedMemoryBytes(), 0u) << "the builds' arrays were kept";
    mtree::detail::setMappingCachePoison(false);
  }
  mtree::releaseCachedMemory();
}

/// build<6> with LeafBoxQuantizer against gatherLeafBoxes, for both sorts and 1 to 3 threads,
/// and the tree the same as a plain build's.
void expectLeafBoxesAsGathered(const CellSet& cells, TreeKind kind, OverlapMode overlap, int height,
                               const std::string& what) {
  MatrixTree plain;
  MatrixTreeBuilder<CellSet>::build(cells, opts(kind, overlap, BuildSort::Radix, 1, height), plain, nullptr);
  const std::vector<uint8_t> expected = gatherLeafBoxes(plain, cells);
  ASSERT_EQ(expected.size(), 6 * plain.primitiveIndices().size());
  for (BuildSort sort : {BuildSort::Radix, BuildSort::Counting})
    for (int threads : {1, 2, 3}) {
      const BuildOptions o = opts(kind, overlap, sort, threads, height);
      MatrixTree t;
      mtree::LargeVector<uint8_t> boxes = {1, 2, 3};  // stale content is replaced
      mtree::BuildStats st;
      MatrixTreeBuilder<CellSet>::build<6>(cells, o, t, &st, &boxes, mtree::LeafBoxQuantizer());
      mtest::expectSameTree(plain, t, what + ": " + name(o));
      ASSERT_EQ(boxes.size(), expected.size()) << what << ": " << name(o);
      size_t bad = 0, first = boxes.size();
      for (size_t i = 0; i < boxes.size(); ++i)
        if (boxes[i] != expected[i]) {
          ++bad;
          first = std::min(first, i);
        }
      EXPECT_EQ(bad, 0u) << what << ": " << name(o) << ", first differing byte " << first;
      bool named = false;
      for (const auto& ph : st.phasesMs) named |= ph.first == (sort == BuildSort::Radix ? "refdata" : "scatter");
      EXPECT_TRUE(named) << "the phase that writes the data is reported";
    }
}

TEST(LeafBoxes, FusedEqualGatheredOnACfdGrid) {
  const CellSet cells = loadGrid("cfd/pipe_flow_tets.vtu");
  for (TreeKind kind : {TreeKind::Octree, TreeKind::RegularKd})
    for (OverlapMode overlap : {OverlapMode::Exact, OverlapMode::BoundingBox})
      expectLeafBoxesAsGathered(cells, kind, overlap, 0, "pipe_flow_tets");
  expectLeafBoxesAsGathered(cells, TreeKind::Octree, OverlapMode::Exact, 4, "pipe_flow_tets");
}

TEST(LeafBoxes, FusedEqualGatheredOnASurface) {
  const CellSet cells = asCells(mtest::loadRealMesh("meshes/bunny.ply"));
  for (TreeKind kind : {TreeKind::Octree, TreeKind::RegularKd})
    expectLeafBoxesAsGathered(cells, kind, OverlapMode::Exact, 0, "bunny");
  expectLeafBoxesAsGathered(cells, TreeKind::Octree, OverlapMode::BoundingBox, 3, "bunny");
}

TEST(LeafBoxes, FusedEqualGatheredWithCellsLargerThanTheScatterTables) {
  // The counting scatter computes each axis's bytes once per cell and candidate row (tables of
  // up to 32 leaves per axis) and falls back to one call per reference beyond that: the bunny
  // plus three triangles across the whole box (64 leaves per axis at its height) takes
  // both paths in one build, with the same bytes as the gather.
  const mtree::TriangleMesh mesh = mtest::loadRealMesh("meshes/bunny.ply");
  std::vector<double> pts = mesh.points();
  std::vector<uint32_t> tris = mesh.triangles();
  mtree::Box b;
  for (size_t i = 0; i < pts.size(); i += 3) b.extend(mtree::Vec3(&pts[i]));
  const uint32_t base = static_cast<uint32_t>(pts.size() / 3);
  pts.insert(pts.end(), {b.lo.x, b.lo.y, b.lo.z, b.hi.x, b.hi.y, b.lo.z, b.hi.x, b.lo.y, b.hi.z,
                         b.lo.x, b.hi.y, b.hi.z});
  tris.insert(tris.end(), {base, base + 1, base + 2, base + 1, base + 2, base + 3, base, base + 3, base + 1});
  const CellSet cells = asCells(mtree::TriangleMesh(std::move(pts), std::move(tris)));
  MatrixTree t;
  MatrixTreeBuilder<CellSet>::build(cells, opts(TreeKind::Octree, OverlapMode::Exact, BuildSort::Counting, 1), t,
                                    nullptr);
  ASSERT_GE(t.dim(t.height(), 0), 64) << "the large triangles must span more than a table's 32 leaves";
  expectLeafBoxesAsGathered(cells, TreeKind::Octree, OverlapMode::Exact, 0, "bunny + large triangles");
}

/// A CellSet seen without CellSet::Local::vertices(): the builder then runs the separating-axis
/// test on every candidate leaf (the path before the point shortcut of count+mark).
struct EveryCandidateTested {
  const CellSet* cells;
  struct Local {
    CellSet::Local cell;
    mtree::Box bounds() const { return cell.bounds(); }
    CellSet::Local::Tester tester(mtree::Vec3 half) const { return cell.tester(half); }
  };
  size_t size() const { return cells->size(); }
  mtree::Box bounds(size_t i) const { return cells->bounds(i); }
  Local local(size_t i) const { return Local{cells->local(i)}; }
};

/// count+mark takes a candidate leaf that contains a point of the cell as overlapped without the
/// separating-axis test (and builds no tester when those are all the candidates): the tree must
/// be the one the test on every candidate gives, leaf for leaf and reference for reference.
void expectPointShortcutExact(const CellSet& cells, const std::string& what) {
  for (TreeKind kind : {TreeKind::Octree, TreeKind::RegularKd})
    for (int height : {0, 1}) {
      BuildOptions o = opts(kind, OverlapMode::Exact, BuildSort::Counting, 1);
      o.leafScale = 1.0;  // the locator's automatic height
      o.maxCandidates = 16;
      MatrixTree tested, shortcut;
      mtree::BuildStats st;
      MatrixTreeBuilder<EveryCandidateTested>::build(EveryCandidateTested{&cells}, o, tested, &st);
      if (height) o.height = st.height + 1;  // smaller leaves: more candidates hold no point
      if (height) MatrixTreeBuilder<EveryCandidateTested>::build(EveryCandidateTested{&cells}, o, tested, nullptr);
      MatrixTreeBuilder<CellSet>::build(cells, o, shortcut, nullptr);
      mtest::expectSameTree(tested, shortcut, what + ": " + name(o));
    }
}

TEST(CountMark, PointShortcutGivesTheTestedTreeOnCfdGrids) {
  for (const char* g : {"cfd/brick_hex.su2", "cfd/brick_prism.su2", "cfd/brick_pyra.su2", "cfd/brick_tets.su2",
                        "cfd/pipe_flow_tets.vtu", "cfd/pipe_lumen_tets.vtu"}) {
    CellSet cells = loadGrid(g);
    expectPointShortcutExact(cells, g);
    cells.setAxes(mtree::CellAxes::All);
    expectPointShortcutExact(cells, std::string(g) + " (all axes)");
  }
}

TEST(CountMark, PointShortcutGivesTheTestedTreeOnSurfaces) {
  for (const char* m : {"meshes/bunny.ply", "meshes/lucy.ply"})
    expectPointShortcutExact(asCells(mtest::loadRealMesh(m)), m);
}

TEST(LeafBoxes, QuantizerMatchesTheFloorCeilFormula) {
  // gatherLeafBoxes' formula, for one cell and leaf.
  auto reference = [](const mtree::Box& cell, const mtree::Box& lb, uint8_t q[6]) {
    const double pad = 1e-3 * std::max({cell.hi.x - cell.lo.x, cell.hi.y - cell.lo.y, cell.hi.z - cell.lo.z});
    for (int a = 0; a < 3; ++a) {
      const double scale = 255.0 / (lb.hi[a] - lb.lo[a]);
      const double lo = std::floor((cell.lo[a] - pad - lb.lo[a]) * scale);
      const double hi = std::ceil((cell.hi[a] + pad - lb.lo[a]) * scale);
      q[2 * a] = static_cast<uint8_t>(lo > 0 ? (lo < 255 ? lo : 255) : 0);
      q[2 * a + 1] = static_cast<uint8_t>(hi < 255 ? (hi > 0 ? hi : 0) : 255);
      if (!(lo <= hi)) {
        q[2 * a] = 0;
        q[2 * a + 1] = 255;
      }
    }
  };
  const double inf = std::numeric_limits<double>::infinity(), nan = std::numeric_limits<double>::quiet_NaN();
  mtree::Box leaf;
  leaf.lo = mtest::Vec3(-1, 2, 0.5);
  leaf.hi = mtest::Vec3(-0.75, 2.125, 0.5 + 1.0 / 3);
  std::vector<mtree::Box> cells;
  mtest::Rng rng(7);
  for (int i = 0; i < 50000; ++i) {  // around and across the leaf, some far outside
    mtree::Box c;
    for (int a = 0; a < 3; ++a) {
      const double w = leaf.hi[a] - leaf.lo[a];
      const double x = leaf.lo[a] + w * rng.uniform(-2, 3), y = x + w * rng.uniform(0, 2) * (i % 5 == 0 ? 0 : 1);
      c.lo[a] = x;
      c.hi[a] = y;
    }
    cells.push_back(c);
  }
  mtree::Box empty;  // inf / -inf: the CellSet's bounds of a cell without points
  cells.push_back(empty);
  mtree::Box exactEdges;  // boundaries exactly on the leaf's 1/255 grid
  for (int a = 0; a < 3; ++a) {
    exactEdges.lo[a] = leaf.lo[a];
    exactEdges.hi[a] = leaf.hi[a];
  }
  cells.push_back(exactEdges);
  mtree::Box inverted = exactEdges;  // lo > hi along one axis
  std::swap(inverted.lo.y, inverted.hi.y);
  cells.push_back(inverted);
  mtree::Box withNan = exactEdges;
  withNan.lo.z = nan;
  cells.push_back(withNan);
  mtree::Box huge = exactEdges;
  huge.lo.x = -inf;
  huge.hi.x = 1e300;
  cells.push_back(huge);
  // The leaf and its neighbours (one step along each axis, and back, as the scatter's
  // candidate loop visits them), plus one of another width: LeafBoxQuantizer's per-cell cache
  // and its width memo must give what the formula gives for each.
  std::vector<mtree::Box> leaves;
  for (int dz = 0; dz < 2; ++dz)
    for (int dy = 0; dy < 2; ++dy)
      for (int dx = 0; dx < 3; ++dx) {
        mtree::Box l = leaf;
        const int d[3] = {dx, dy, dz};
        for (int a = 0; a < 3; ++a) {
          const double w = leaf.hi[a] - leaf.lo[a];
          l.lo[a] = leaf.lo[a] + d[a] * w;
          l.hi[a] = leaf.lo[a] + (d[a] + 1) * w;
        }
        leaves.push_back(l);
      }
  leaves.push_back(leaves.front());
  leaves.back().hi.y += 0.5;
  mtree::LeafBoxQuantizer quantizer;
  for (size_t i = 0; i < cells.size(); ++i) {
    const mtree::Box& c = cells[i];
    CellSet::Local l;
    l.cell = i;
    l.box = c;
    for (const mtree::Box& lb : leaves) {
      uint8_t want[6], got[6], got2[6];
      reference(c, lb, want);
      mtree::quantizeLeafBox(c, lb, got);
      quantizer(got2, l, lb);
      for (int k = 0; k < 6; ++k) {
        ASSERT_EQ(got[k], want[k]) << "byte " << k << " of cell [" << c.lo.x << " " << c.hi.x << "] ["
                                   << c.lo.y << " " << c.hi.y << "] [" << c.lo.z << " " << c.hi.z << "]";
        ASSERT_EQ(got2[k], want[k]) << "byte " << k << " (LeafBoxQuantizer), cell " << i;
      }
    }
  }
}

TEST(BuildSort, SortLeafOrdersIdsAndTheirData) {
  mtest::Rng rng(11);
  std::vector<mtree::detail::Reference<3>> buf;
  for (uint32_t n : {2u, 5u, 31u, 32u, 33u, 200u, 5000u}) {
    // Ids: distinct, shuffled except for a sorted run; data: three bytes derived from the id.
    std::vector<uint32_t> ids(n + 4);
    std::iota(ids.begin(), ids.end(), 100u);
    for (uint32_t i = n + 3; i > 2 + n / 2; --i) std::swap(ids[i], ids[2 + rng.below(i - 1)]);
    std::vector<uint8_t> data(3 * ids.size());
    for (size_t i = 0; i < ids.size(); ++i)
      for (int k = 0; k < 3; ++k) data[3 * i + k] = static_cast<uint8_t>(ids[i] * (k + 3) >> k);
    const std::vector<uint32_t> before = ids;
    mtree::detail::sortLeaf<3>(ids.data(), data.data(), 2, 2 + n, buf);
    EXPECT_EQ(ids[0], before[0]);
    EXPECT_EQ(ids[1], before[1]);
    EXPECT_EQ(ids[n + 2], before[n + 2]) << "outside [begin, end) untouched";
    EXPECT_TRUE(std::is_sorted(ids.begin() + 2, ids.begin() + 2 + n)) << n;
    for (size_t i = 0; i < ids.size(); ++i)
      for (int k = 0; k < 3; ++k)
        ASSERT_EQ(data[3 * i + k], static_cast<uint8_t>(ids[i] * (k + 3) >> k)) << "data follows its id, n " << n;
    std::vector<uint32_t> sortedIds = ids, all = before;
    std::sort(sortedIds.begin(), sortedIds.end());
    std::sort(all.begin(), all.end());
    EXPECT_EQ(sortedIds, all) << "a permutation";
  }
}

TEST(BuildSort, TwoThreadsGivenATeamOfOne) {
  // A two-thread build started inside a parallel region gets a team of one thread (no nested
  // parallelism): thread 0 then takes every chunk from the front, the same tree and leaf boxes.
  const CellSet cells = loadGrid("cfd/brick_tets.su2");
  const BuildOptions o = opts(TreeKind::Octree, OverlapMode::Exact, BuildSort::Counting, 2);
  MatrixTree ref, t;
  mtree::LargeVector<uint8_t> refBoxes, boxes;
  MatrixTreeBuilder<CellSet>::build<6>(cells, o, ref, nullptr, &refBoxes, mtree::LeafBoxQuantizer());
  const int levels = omp_get_max_active_levels();
  omp_set_max_active_levels(1);
#pragma omp parallel num_threads(2)
  {
#pragma omp single
    MatrixTreeBuilder<CellSet>::build<6>(cells, o, t, nullptr, &boxes, mtree::LeafBoxQuantizer());
  }
  omp_set_max_active_levels(levels);
  mtest::expectSameTree(ref, t, "brick_tets in a parallel region");
  EXPECT_TRUE(boxes == refBoxes);
}

TEST(BuildSort, EmptySetAndBadValue) {
  const CellSet none(std::vector<double>{}, std::vector<uint32_t>{0}, std::vector<uint32_t>{}, std::vector<uint8_t>{});
  MatrixTree t;
  mtree::LargeVector<uint8_t> boxes(12, 7);
  MatrixTreeBuilder<CellSet>::build<6>(none, opts(TreeKind::Octree, OverlapMode::Exact, BuildSort::Counting, 2), t,
                                       nullptr, &boxes, mtree::LeafBoxQuantizer());
  EXPECT_TRUE(t.empty());
  EXPECT_TRUE(boxes.empty());
  const mtree::TriangleMesh mesh = mtest::makeIcosphere(1);
  BuildOptions bad;
  bad.sort = static_cast<BuildSort>(7);
  EXPECT_THROW(MatrixTreeBuilder<mtree::TriangleMesh>::build(mesh, bad, t, nullptr), std::invalid_argument);
  EXPECT_THROW((MatrixTreeBuilder<CellSet>::build<6>(none, BuildOptions{}, t, nullptr, nullptr,
                                                      mtree::LeafBoxQuantizer())),
               std::invalid_argument)
      << "data without an output vector";
}

}  // namespace

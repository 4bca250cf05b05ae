// CellSet storage: a grid whose cells all have the same number of points keeps no offsets (cell
// c starts at c x k in the connectivity); points that are all exact floats are kept as floats.
// Every accessor answers as with the arrays given, and the tree built over it is the same.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "mtree/core/builder.h"
#include "mtree/cells/cells.h"
#include "test_util.h"
#include "vtk_grid_util.h"

namespace {

using mtree::CellSet;

/// Every accessor of `cells` against the offsets `off` and connectivity `conn` it was made of.
void expectCellsAsGiven(const CellSet& cells, const std::vector<uint32_t>& off, const std::vector<uint32_t>& conn,
                        const std::string& what) {
  SCOPED_TRACE(what);
  ASSERT_EQ(cells.size() + 1, off.size());
  for (size_t c = 0; c < cells.size(); ++c) {
    ASSERT_EQ(cells.numCellPoints(c), int64_t(off[c + 1]) - int64_t(off[c])) << "cell " << c;
    for (int64_t k = 0; k < cells.numCellPoints(c); ++k) {
      ASSERT_EQ(cells.cellPointIds(c)[k], conn[off[c] + k]) << "cell " << c << " point " << k;
      const mtree::Vec3 p = cells.cellPoint(c, k), q = cells.point(conn[off[c] + k]);
      ASSERT_TRUE(p.x == q.x && p.y == q.y && p.z == q.z) << "cell " << c << " point " << k;
    }
  }
}

struct Arrays {
  std::vector<double> pts;
  std::vector<uint32_t> off, conn;
  std::vector<uint8_t> types;
};

Arrays arraysOf(vtkUnstructuredGrid* g) {
  Arrays a;
  const mtree::CellSet cells = mtest::cellSet(g);
  for (size_t i = 0; i < cells.numPoints(); ++i) {
    const mtree::Vec3 p = cells.point(i);
    a.pts.insert(a.pts.end(), {p.x, p.y, p.z});
  }
  a.off.push_back(0);
  for (size_t c = 0; c < cells.size(); ++c) {
    const CellSet::PointIds ids = cells.cellPointIds(c);
    for (int64_t k = 0; k < cells.numCellPoints(c); ++k) a.conn.push_back(ids[k]);
    a.off.push_back(static_cast<uint32_t>(a.conn.size()));
    a.types.push_back(cells.type(c));
  }
  return a;
}

TEST(CellSet, SingleTypeGridsKeepNoOffsets) {
  for (const char* rel : {"cfd/pipe_flow_tets.vtu", "cfd/brick_hex.su2", "cfd/brick_tets.su2"}) {
    vtkSmartPointer<vtkUnstructuredGrid> g = mtest::readGrid(rel);
    ASSERT_TRUE(g) << rel;
    const Arrays a = arraysOf(g);
    const CellSet cells(a.pts, a.off, a.conn, a.types);
    EXPECT_TRUE(cells.uniformCellSize()) << rel;
    EXPECT_TRUE(cells.uniformType()) << rel;
    const size_t pointBytes = a.pts.size() * (cells.floatPoints() ? sizeof(float) : sizeof(double));
    const size_t expected = pointBytes + a.conn.size() * sizeof(uint32_t) + 6 * sizeof(float) * cells.size();
    EXPECT_EQ(cells.bytes(), expected) << rel << ": no offsets or types counted";
    expectCellsAsGiven(cells, a.off, a.conn, rel);
  }
}

TEST(CellSet, MixedGridKeepsOffsetsAndBuildsTheSameTree) {
  // brick_tets with one hexahedron of brick_hex's first cell's points appended: mixed sizes.
  vtkSmartPointer<vtkUnstructuredGrid> g = mtest::readGrid("cfd/brick_tets.su2");
  ASSERT_TRUE(g);
  Arrays a = arraysOf(g);
  const std::vector<uint32_t> hex = {a.conn[0], a.conn[1], a.conn[2], a.conn[3], a.conn[4], a.conn[5], a.conn[6], a.conn[7]};
  a.conn.insert(a.conn.end(), hex.begin(), hex.end());
  a.off.push_back(static_cast<uint32_t>(a.conn.size()));
  a.types.push_back(mtree::kHexahedron);
  const CellSet mixed(a.pts, a.off, a.conn, a.types);
  EXPECT_FALSE(mixed.uniformCellSize());
  EXPECT_EQ(mixed.bytes(), a.pts.size() * (mixed.floatPoints() ? sizeof(float) : sizeof(double)) +
                               (a.off.size() + a.conn.size()) * sizeof(uint32_t) + a.types.size() +
                               6 * sizeof(float) * mixed.size());
  expectCellsAsGiven(mixed, a.off, a.conn, "mixed");

  // The uniform part alone, without offsets, builds the tree a mixed-size copy of it builds:
  // an empty cell (no points) appended keeps the offsets there and is in no leaf.
  Arrays t = arraysOf(g);
  const CellSet uniform(t.pts, t.off, t.conn, t.types);
  t.off.push_back(t.off.back());
  t.types.push_back(mtree::kEmptyCell);
  const CellSet withEmpty(t.pts, t.off, t.conn, t.types);
  ASSERT_TRUE(uniform.uniformCellSize());
  ASSERT_FALSE(withEmpty.uniformCellSize());
  for (mtree::TreeKind kind : {mtree::TreeKind::Octree, mtree::TreeKind::RegularKd}) {
    mtree::BuildOptions o;
    o.kind = kind;
    mtree::MatrixTree a1, a2;
    mtree::MatrixTreeBuilder<CellSet>::build(uniform, o, a1, nullptr);
    mtree::MatrixTreeBuilder<CellSet>::build(withEmpty, o, a2, nullptr);
    mtest::expectSameTree(a1, a2, mtree::treeKindName(kind));
  }
}

TEST(CellSet, ExactFloatPointsAreKeptAsFloats) {
  // pipe_flow_tets.vtu stores Float32 points: kept as floats, read back as the same doubles.
  vtkSmartPointer<vtkUnstructuredGrid> g = mtest::readGrid("cfd/pipe_flow_tets.vtu");
  ASSERT_TRUE(g);
  const Arrays a = arraysOf(g);
  const CellSet asFloats(a.pts, a.off, a.conn, a.types);
  ASSERT_TRUE(asFloats.floatPoints());
  ASSERT_EQ(asFloats.numPoints() * 3, a.pts.size());
  for (size_t i = 0; i < asFloats.numPoints(); ++i) {
    const mtree::Vec3 p = asFloats.point(i);
    ASSERT_TRUE(p.x == a.pts[3 * i] && p.y == a.pts[3 * i + 1] && p.z == a.pts[3 * i + 2]) << "point " << i;
  }
  // One unused point that is no float keeps every point a double; cells, bounds and trees agree.
  Arrays d = a;
  d.pts.insert(d.pts.end(), {0.1, 0.2, 0.3});
  const CellSet asDoubles(d.pts, d.off, d.conn, d.types);
  ASSERT_FALSE(asDoubles.floatPoints());
  EXPECT_EQ(asDoubles.bytes() - asFloats.bytes(), a.pts.size() * (sizeof(double) - sizeof(float)) + 3 * sizeof(double));
  mtest::Rng rng(3);
  for (size_t c = 0; c < asFloats.size(); ++c) {
    for (int k = 0; k < 6; ++k) ASSERT_EQ(asFloats.cellBox(c)[k], asDoubles.cellBox(c)[k]) << "cell " << c;
    const mtree::Vec3 x = asFloats.cellPoint(c, 0) * 0.7 + asFloats.cellPoint(c, 1) * (0.3 + 0.1 * rng.uniform());
    ASSERT_EQ(asFloats.tetraMayContain(c, x, 0.01), asDoubles.tetraMayContain(c, x, 0.01)) << "cell " << c;
  }
  mtree::MatrixTree t1, t2;
  mtree::MatrixTreeBuilder<CellSet>::build(asFloats, mtree::BuildOptions{}, t1, nullptr);
  mtree::MatrixTreeBuilder<CellSet>::build(asDoubles, mtree::BuildOptions{}, t2, nullptr);
  mtest::expectSameTree(t1, t2, "float and double points");
  // SU2 text coordinates are no floats: kept as doubles.
  vtkSmartPointer<vtkUnstructuredGrid> h = mtest::readGrid("cfd/brick_hex.su2");
  ASSERT_TRUE(h);
  EXPECT_FALSE(mtest::cellSet(h).floatPoints());
}

/// The cached bounds are the tightest floats outside the exact bounds: lo the largest float not
/// above the exact minimum, hi the smallest float not below the exact maximum (std::nextafter
/// decides "tightest", independently of the bit arithmetic that rounds them).
void expectTightestFloatBounds(const CellSet& cells, const std::string& what) {
  SCOPED_TRACE(what);
  const float inf = std::numeric_limits<float>::infinity();
  for (size_t c = 0; c < cells.size(); ++c) {
    const mtree::Box e = cells.exactBounds(c);
    const std::array<float, 6> f = cells.cellBox(c);
    for (int a = 0; a < 3; ++a) {
      ASSERT_LE(double(f[2 * a]), e.lo[a]) << "cell " << c << " axis " << a;
      ASSERT_GT(double(std::nextafter(f[2 * a], inf)), e.lo[a]) << "cell " << c << " axis " << a;
      ASSERT_GE(double(f[2 * a + 1]), e.hi[a]) << "cell " << c << " axis " << a;
      ASSERT_LT(double(std::nextafter(f[2 * a + 1], -inf)), e.hi[a]) << "cell " << c << " axis " << a;
    }
  }
}

TEST(CellSet, CachedBoundsAreTheTightestFloatsOutside) {
  // SU2 coordinates are doubles that are no floats: every bound is rounded outwards.
  vtkSmartPointer<vtkUnstructuredGrid> g = mtest::readGrid("cfd/brick_pyra.su2");
  ASSERT_TRUE(g);
  const CellSet grid = mtest::cellSet(g);
  ASSERT_FALSE(grid.floatPoints());
  expectTightestFloatBounds(grid, "brick_pyra");
  // Edge cases of the rounding: both signs, zeros, subnormals, values next to zero and next to
  // a power of two, exact floats, the ends of the supported coordinate range (+-1e30,
  // coordinate_range.h), one tetrahedron per coordinate value.
  const double tiny = std::numeric_limits<float>::denorm_min();
  const double values[] = {0.0, -0.0, 0.1, -0.1, 1.0, -1.0, 1.0 + 1e-12, -(1.0 + 1e-12), 1.0 - 1e-12,
                           -(1.0 - 1e-12), 0.5 * tiny, -0.5 * tiny, 1.5 * tiny, -1.5 * tiny, 1e-300, -1e-300,
                           1e30, -1e30, 1e5 + 1e-7, -(1e5 + 1e-7)};
  std::vector<double> pts;
  std::vector<uint32_t> off = {0}, conn;
  for (double v : values) {
    const uint32_t b = static_cast<uint32_t>(pts.size() / 3);
    // The value is the minimum on x, the maximum on y, and both on z (a flat tetrahedron).
    pts.insert(pts.end(), {v, v - 1, v, v + 1, v - 2, v, v + 2, v, v, v + 3, v - 3, v});
    conn.insert(conn.end(), {b, b + 1, b + 2, b + 3});
    off.push_back(static_cast<uint32_t>(conn.size()));
  }
  const CellSet edge(pts, off, conn, std::vector<uint8_t>(off.size() - 1, mtree::kTetra));
  expectTightestFloatBounds(edge, "edge cases");
}

/// arrays `a` as the caller's 32- or 64-bit offsets and connectivity (I) and types, in place.
template <class I>
struct ViewedArrays {
  std::vector<I> off, conn;
  std::vector<uint8_t> types;
  std::vector<double> pts;
  explicit ViewedArrays(const Arrays& a)
      : off(a.off.begin(), a.off.end()), conn(a.conn.begin(), a.conn.end()), types(a.types), pts(a.pts) {}
  mtree::CellArrays view(bool withTypes = true) const {
    mtree::CellArrays v;
    v.offsets = off.data();
    v.connectivity = conn.data();
    v.numCells = types.size();
    v.connectivitySize = conn.size();
    v.indexBytes = sizeof(I);
    if (withTypes) v.types = types.data();
    else v.typeCopy = types;
    return v;
  }
  CellSet cells(bool withTypes = true) const { return CellSet(pts.data(), pts.size() / 3, view(withTypes)); }
};

/// Every accessor, the bounds (cached and computed) and the tree of `viewed` against `copy`.
void expectSameCells(const CellSet& copy, CellSet viewed, const Arrays& a, const std::string& what) {
  SCOPED_TRACE(what);
  ASSERT_TRUE(viewed.cellsViewed());
  ASSERT_EQ(viewed.size(), copy.size());
  EXPECT_EQ(viewed.uniformCellSize(), copy.uniformCellSize());
  EXPECT_EQ(viewed.uniformType(), copy.uniformType());
  expectCellsAsGiven(viewed, a.off, a.conn, what);
  for (size_t c = 0; c < copy.size(); ++c) {
    ASSERT_EQ(viewed.type(c), a.types[c]) << "cell " << c;
    ASSERT_EQ(viewed.cellBox(c), copy.cellBox(c)) << "cell " << c;
  }
  const mtree::Vec3 e = viewed.maxExtent(), f = copy.maxExtent();
  EXPECT_TRUE(e.x == f.x && e.y == f.y && e.z == f.z);
  mtree::MatrixTree t1, t2;
  mtree::MatrixTreeBuilder<CellSet>::build(copy, mtree::BuildOptions{}, t1, nullptr);
  mtree::MatrixTreeBuilder<CellSet>::build(viewed, mtree::BuildOptions{}, t2, nullptr);
  mtest::expectSameTree(t1, t2, what);
  // Released bounds are computed from the points: the same floats.
  const CellSet copied = viewed;  // the copy reads the same arrays
  viewed.releaseBounds();
  EXPECT_FALSE(viewed.boundsCached());
  for (size_t c = 0; c < copy.size(); ++c) {
    ASSERT_EQ(viewed.cellBox(c), copy.cellBox(c)) << "released, cell " << c;
    ASSERT_EQ(copied.cellPoint(c, 0).x, copy.cellPoint(c, 0).x) << "copied set, cell " << c;
  }
}

TEST(CellSet, ViewedCellArraysReadAsTheCopy) {
  // 64- and 32-bit arrays (vtkCellArray's two storages), a single-type grid, a mixed one
  // (brick_tets plus one hexahedron) and one with an empty cell; types viewed or copied.
  vtkSmartPointer<vtkUnstructuredGrid> g = mtest::readGrid("cfd/brick_tets.su2");
  ASSERT_TRUE(g);
  const Arrays single = arraysOf(g);
  Arrays mixed = single;
  for (int k = 0; k < 8; ++k) mixed.conn.push_back(mixed.conn[k]);
  mixed.off.push_back(static_cast<uint32_t>(mixed.conn.size()));
  mixed.types.push_back(mtree::kHexahedron);
  Arrays withEmpty = single;
  withEmpty.off.insert(withEmpty.off.begin() + 3, withEmpty.off[3]);
  withEmpty.types.insert(withEmpty.types.begin() + 3, mtree::kEmptyCell);
  for (const auto& [name, a] : {std::pair<std::string, const Arrays&>{"single", single}, {"mixed", mixed},
                                {"with an empty cell", withEmpty}}) {
    const CellSet copy(a.pts, a.off, a.conn, a.types);
    const ViewedArrays<int64_t> v64(a);
    const ViewedArrays<int32_t> v32(a);
    expectSameCells(copy, v64.cells(), a, name + ", 64-bit");
    expectSameCells(copy, v32.cells(), a, name + ", 32-bit");
    expectSameCells(copy, v64.cells(false), a, name + ", 64-bit, types copied");
    // Nothing of the cells is held but the cached bounds (the points are viewed too).
    EXPECT_EQ(v64.cells().bytes(), 6 * sizeof(float) * a.types.size()) << name;
    CellSet released = v32.cells();
    released.releaseBounds();
    EXPECT_EQ(released.bytes(), 0u) << name;
  }
  // One type for all cells, given as `type` alone.
  const ViewedArrays<int64_t> v(single);
  mtree::CellArrays byType = v.view();
  byType.types = nullptr;
  byType.type = mtree::kTetra;
  const CellSet uniform(v.pts.data(), v.pts.size() / 3, byType);
  EXPECT_TRUE(uniform.uniformType());
  expectSameCells(CellSet(single.pts, single.off, single.conn, single.types), uniform, single, "one type");
}

TEST(CellSet, ViewedCellArraysAreChecked) {
  const std::vector<double> pts = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
  const uint8_t tet = mtree::kTetra;
  auto make = [&](std::vector<int64_t> off, std::vector<int64_t> conn) {
    mtree::CellArrays a;
    a.offsets = off.data();
    a.connectivity = conn.data();
    a.numCells = off.size() - 1;
    a.connectivitySize = conn.size();
    a.type = tet;
    return CellSet(pts.data(), 4, a);
  };
  EXPECT_NO_THROW(make({0, 4}, {0, 1, 2, 3}));
  EXPECT_THROW(make({0, 4}, {0, 1, 2, 4}), std::invalid_argument);   // point 4 of 4
  EXPECT_THROW(make({0, 4}, {0, 1, -1, 3}), std::invalid_argument);  // negative
  EXPECT_THROW(make({0, 4}, {0, 1, 2, 3 + (int64_t{1} << 32)}), std::invalid_argument);  // past 32 bits
  EXPECT_THROW(make({0, 3}, {0, 1, 2, 3}), std::invalid_argument);   // last offset != size
  EXPECT_THROW(make({0, 3, 2, 4}, {0, 1, 2, 3}), std::invalid_argument);  // decreasing
  EXPECT_THROW(make({1, 4}, {0, 1, 2, 3}), std::invalid_argument);   // first offset != 0
}

// The builder's separating-axis tester leaves out a quad's second triangle normal when it is
// parallel to the first (a planar face): its verdicts must stay those of the full test
// (Local::overlaps, every face normal) on parallelepipeds and prisms, whose faces are planar,
// and on the same cells with their points moved (warped faces keep both normals). Boxes are
// drawn around the cell's bounding box, as the builder's candidates are; both verdicts occur.
TEST(CellSet, TesterLeavesOutOnlyParallelAxes) {
  mtest::Rng rng(2026);
  const int hexCorner[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
  const int wedgeCorner[6][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 0, 1}, {0, 1, 1}};
  uint64_t tested = 0, separated = 0, differ = 0;
  for (int warp = 0; warp < 2; ++warp)
    for (int shape = 0; shape < 2; ++shape)
      for (int cell = 0; cell < 200; ++cell) {
        const bool hex = shape == 0;
        const int n = hex ? 8 : 6;
        const mtree::Vec3 o(rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(-5, 5));
        const mtree::Vec3 u = rng.direction() * rng.uniform(0.2, 2), v = rng.direction() * rng.uniform(0.2, 2),
                          w = rng.direction() * rng.uniform(0.2, 2);
        std::vector<double> pts;
        for (int k = 0; k < n; ++k) {
          const int* c = hex ? hexCorner[k] : wedgeCorner[k];
          mtree::Vec3 p = o + u * double(c[0]) + v * double(c[1]) + w * double(c[2]);
          if (warp) p = p + rng.direction() * 0.1;
          pts.insert(pts.end(), {p.x, p.y, p.z});
        }
        std::vector<uint32_t> conn(n);
        for (int k = 0; k < n; ++k) conn[k] = uint32_t(k);
        const CellSet cells(pts, std::vector<uint32_t>{0, uint32_t(n)}, conn,
                            std::vector<uint8_t>{hex ? mtree::kHexahedron : mtree::kWedge});
        const CellSet::Local local = cells.local(0);
        const mtree::Box bb = local.bounds();
        const mtree::Vec3 e = bb.extent();
        for (int trial = 0; trial < 50; ++trial) {
          const double size = std::max(e.x, std::max(e.y, e.z)) * rng.uniform(0.02, 0.5);
          const mtree::Vec3 half(size, size * rng.uniform(0.5, 1), size * rng.uniform(0.5, 1));
          mtree::Box grown = bb;
          grown.lo = grown.lo - half;
          grown.hi = grown.hi + half;
          const mtree::Vec3 c = rng.inBox(grown);  // the box [c - half, c + half] meets bb
          mtree::Box box;
          box.lo = c - half;
          box.hi = c + half;
          const bool full = local.overlaps(box), fast = local.tester(half).overlaps(c);
          ++tested;
          separated += !full;
          differ += full != fast;
        }
      }
  EXPECT_EQ(differ, 0u) << "of " << tested;
  EXPECT_GT(separated, tested / 10) << "the boxes must test separation too";
  EXPECT_LT(separated, tested - tested / 10) << "and overlap";
}

}  // namespace

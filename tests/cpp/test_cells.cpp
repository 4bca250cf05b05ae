// CellSet storage: a grid whose cells all have the same number of points keeps no offsets (cell
// c starts at c x k in the connectivity); points that are all exact floats are kept as floats.
// Every accessor answers as with the arrays given, and the tree built over it is the same.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "mtree/builder.h"
#include "mtree/cells.h"
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
    ASSERT_EQ(cells.cellPointIds(c), cells.cellPointIds(0) + off[c]) << "cell " << c;
    for (int64_t k = 0; k < cells.numCellPoints(c); ++k) {
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
    const uint32_t* ids = cells.cellPointIds(c);
    a.conn.insert(a.conn.end(), ids, ids + cells.numCellPoints(c));
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
    const size_t pointBytes = a.pts.size() * (cells.floatPoints() ? sizeof(float) : sizeof(double));
    const size_t expected = pointBytes + a.conn.size() * sizeof(uint32_t) + a.types.size() + 6 * sizeof(float) * cells.size();
    EXPECT_EQ(cells.bytes(), expected) << rel << ": no offsets counted";
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
    const float* f = cells.cellBox(c);
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
  // a power of two, exact floats, one tetrahedron per coordinate value.
  const double tiny = std::numeric_limits<float>::denorm_min();
  const double values[] = {0.0, -0.0, 0.1, -0.1, 1.0, -1.0, 1.0 + 1e-12, -(1.0 + 1e-12), 1.0 - 1e-12,
                           -(1.0 - 1e-12), 0.5 * tiny, -0.5 * tiny, 1.5 * tiny, -1.5 * tiny, 1e-300, -1e-300,
                           3e38, -3e38, 1e5 + 1e-7, -(1e5 + 1e-7)};
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

}  // namespace

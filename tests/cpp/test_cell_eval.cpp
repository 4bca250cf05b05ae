// mtree::vtk91::evaluateLinearCell (engine/vtk91/include/mtree/vtk91/cell_eval.h) against VTK's own
// vtkCell::EvaluatePosition, the reference it must reproduce: whenever the engine answers (not
// kAskVtk), VTK must make the same inside/outside decision, and for an inside answer give the
// same pcoords and weights, bit for bit (the engine repeats VTK's operations; 1e-12 is the
// documented contract, bitwise is what this build delivers and what is asserted).
//
// Points per cell: random parametric points inside (mapped with VTK's EvaluateLocation), points
// on faces, edges and at the vertices, points on and around the acceptance limits (-0.001 and
// 1.001, or -1e-6 and 1 + 1e-6 for hexahedra, 0 and 1 for voxels), points further out, random
// points in the padded bounding box, and points outside the grid. Cells: the real CFD grids
// (hexahedra, prisms, pyramids + tetrahedra, tetrahedra; disk_out_ref needs VTK's Exodus reader,
// whose CMake package does not configure here: tests/python/test_locator_cell_eval.py covers it,
// and all six grids, through FindCell), and made-up ones: twisted, sheared, collapsed, flat, tangled and
// degenerate cells at scales 1e-12 and 1e12 and offsets of 1e12, and NaN points.
// The split must also earn its keep: on the real grids the engine answers for nearly every pair.
// Every pair runs with both Newton steps (SSE2, and AVX2 where the processor has it), which must
// agree bit for bit.
#include <gtest/gtest.h>

#include <vtkCell.h>
#include <vtkCellType.h>
#include <vtkGenericCell.h>
#include <vtkNew.h>
#include <vtkPoints.h>
#include <vtkSmartPointer.h>
#include <vtkUnstructuredGrid.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <ostream>
#include <random>
#include <string>
#include <vector>

#include "mtree/vtk91/cell_eval.h"
#include "test_util.h"
#include "vtk_grid_util.h"

namespace {

using mtree::vtk91::PointInCell;

struct Tally {
  long long pairs = 0, inside = 0, outside = 0, ask = 0;
  long long vtkInside = 0;  // pairs VTK accepts
  long long askWhereVtkInside = 0;
};

// Built with MATRIXTREE_CELL_EVAL_ROUNDING_DIFFERS (by hand, with -mfma -ffp-contract=fast, so
// that the engine rounds differently from Debian's VTK), the decisions must still be VTK's —
// that is what the round-off margins are for — while pcoords and weights can only agree to the
// round-off itself (1e-12 on ordinary cells, up to ~1e-7 on the made-up cells at 1e6 offsets
// and 3e-3 scale): compared to 1e-6 then.
#ifdef MATRIXTREE_CELL_EVAL_ROUNDING_DIFFERS
constexpr double kValueTolerance = 1e-6;
bool sameBits(double a, double b) { return std::fabs(a - b) <= kValueTolerance; }
#else
constexpr double kValueTolerance = 1e-12;
bool sameBits(double a, double b) { return std::memcmp(&a, &b, sizeof(double)) == 0; }
#endif

/// evaluateLinearCell with the SSE2 Newton step, and with the AVX2 one where the processor has
/// it: the two must give the same verdict and the same bits (also where they differ from VTK's,
/// in a build that rounds differently). Returns the SSE2 answer.
PointInCell evaluateEachIsa(uint8_t type, int n, const double* pts, const double x[3], double pc[3], double* w,
                            const std::string& what) {
  using mtree::vtk91::cell_eval::NewtonIsa;
  mtree::vtk91::cell_eval::newtonIsa() = NewtonIsa::kSse2;
  const PointInCell v = mtree::vtk91::evaluateLinearCell(type, pts, x, pc, w);
  if (mtree::vtk91::cell_eval::haveAvx2()) {
    double pc2[3] = {-7, -7, -7}, w2[8] = {-7, -7, -7, -7, -7, -7, -7, -7};
    mtree::vtk91::cell_eval::newtonIsa() = NewtonIsa::kAvx2;
    const PointInCell v2 = mtree::vtk91::evaluateLinearCell(type, pts, x, pc2, w2);
    EXPECT_EQ(v, v2) << what << ": SSE2 and AVX2 verdicts differ";
    if (v == PointInCell::kInside && v2 == PointInCell::kInside) {
      for (int i = 0; i < 3; ++i) EXPECT_TRUE(sameBits(pc[i], pc2[i])) << what << ": SSE2 and AVX2 pcoords differ";
      for (int k = 0; k < n; ++k) EXPECT_TRUE(sameBits(w[k], w2[k])) << what << ": SSE2 and AVX2 weights differ";
    }
  }
  mtree::vtk91::cell_eval::newtonIsa() = NewtonIsa::kAuto;
  return v;
}

/// One (cell, point) pair: the engine's verdict against VTK's EvaluatePosition. `pts` are the
/// engine's coordinates of the cell (3 per point), `cell` VTK's cell with the same points.
void checkPair(vtkCell* cell, const double* pts, const double x[3], Tally& t, const std::string& what) {
  const int n = static_cast<int>(cell->GetNumberOfPoints());
  double pc[3] = {-7, -7, -7}, w[8] = {-7, -7, -7, -7, -7, -7, -7, -7};
  const PointInCell v = evaluateEachIsa(static_cast<uint8_t>(cell->GetCellType()), n, pts, x, pc, w, what);
  double cp[3], vpc[3], d2 = 0, vw[8];
  int sub = 0;
  const int ret = cell->EvaluatePosition(x, cp, sub, vpc, d2, vw);
  ++t.pairs;
  t.vtkInside += ret == 1;
  if (v == PointInCell::kAskVtk) {
    ++t.ask;
    t.askWhereVtkInside += ret == 1;
    return;
  }
  if (v == PointInCell::kOutside) {
    ++t.outside;
    ASSERT_NE(ret, 1) << what << ": the engine says outside, VTK inside; x = " << x[0] << " " << x[1] << " "
                      << x[2] << ", VTK pcoords " << vpc[0] << " " << vpc[1] << " " << vpc[2];
    return;
  }
  ++t.inside;
  ASSERT_EQ(ret, 1) << what << ": the engine says inside, VTK " << ret << "; engine pcoords " << pc[0] << " "
                    << pc[1] << " " << pc[2];
  for (int i = 0; i < 3; ++i) {
    ASSERT_LE(std::fabs(pc[i] - vpc[i]), kValueTolerance) << what << ": pcoords[" << i << "]";
    ASSERT_TRUE(sameBits(pc[i], vpc[i])) << what << ": pcoords[" << i << "] " << pc[i] << " vs VTK " << vpc[i];
  }
  for (int k = 0; k < n; ++k) {
    ASSERT_LE(std::fabs(w[k] - vw[k]), kValueTolerance) << what << ": weights[" << k << "]";
    ASSERT_TRUE(sameBits(w[k], vw[k])) << what << ": weights[" << k << "] " << w[k] << " vs VTK " << vw[k];
  }
}

/// Parametric points of a cell type worth testing: inside at random, on faces/edges/vertices,
/// on and around the type's acceptance limits, and further out.
std::vector<std::array<double, 3>> parametricPoints(int type, std::mt19937_64& rng, int nRandom) {
  std::uniform_real_distribution<double> U(0.0, 1.0);
  std::vector<std::array<double, 3>> out;
  const double tol = type == VTK_HEXAHEDRON ? 1e-6 : (type == VTK_VOXEL ? 0.0 : 1e-3);
  // Values around the limits lo = -tol and hi = 1 + tol, and beyond.
  const double edge[] = {0.0, 1.0, -tol, 1.0 + tol, -tol - 1e-9, -tol + 1e-9, 1.0 + tol + 1e-9, 1.0 + tol - 1e-9,
                         -tol - 1e-7, 1.0 + tol + 1e-7, -2e-3, 1.002, -0.01, 1.01, -0.3, 1.3, 0.5, -3.0, 4.0};
  for (int i = 0; i < nRandom; ++i) {
    std::array<double, 3> p = {U(rng), U(rng), U(rng)};
    if (type == VTK_TETRA || type == VTK_WEDGE) {
      if (p[0] + p[1] > 1) p = {1 - p[0], 1 - p[1], p[2]};
      if (type == VTK_TETRA && p[0] + p[1] + p[2] > 1) p[2] = U(rng) * (1 - p[0] - p[1]);
    }
    out.push_back(p);
    // The same point with one coordinate moved to a limit value (faces, edges, tolerance band).
    std::array<double, 3> q = p;
    q[i % 3] = edge[(i / 3) % (sizeof(edge) / sizeof(edge[0]))];
    out.push_back(q);
    // Two coordinates at limits (edges, corners of the band).
    q[(i + 1) % 3] = edge[(i / 7) % (sizeof(edge) / sizeof(edge[0]))];
    out.push_back(q);
  }
  // The cell's own parametric vertices.
  const double corners[2] = {0.0, 1.0};
  for (double a : corners)
    for (double b : corners)
      for (double c : corners) out.push_back({a, b, c});
  return out;
}

/// Checks a VTK cell (any of the five types) against the engine with points from
/// parametricPoints (mapped by VTK's EvaluateLocation), its vertices, random points of its
/// bounding box padded by 20%, and `extra` points.
void checkCell(vtkCell* cell, std::mt19937_64& rng, int nRandom, Tally& t, const std::string& what,
               const std::vector<std::array<double, 3>>& extra = {}) {
  const int n = static_cast<int>(cell->GetNumberOfPoints());
  double pts[24];
  for (int k = 0; k < n; ++k) cell->GetPoints()->GetPoint(k, pts + 3 * k);
  const int type = cell->GetCellType();
  double w[8], x[3];
  int sub = 0;
  for (const auto& p : parametricPoints(type, rng, nRandom)) {
    cell->EvaluateLocation(sub, p.data(), x, w);
    checkPair(cell, pts, x, t, what);
    if (::testing::Test::HasFatalFailure()) return;
  }
  for (int k = 0; k < n; ++k) {
    checkPair(cell, pts, pts + 3 * k, t, what + " (vertex)");
    if (::testing::Test::HasFatalFailure()) return;
  }
  double b[6];
  cell->GetBounds(b);
  std::uniform_real_distribution<double> U(-0.2, 1.2);
  for (int i = 0; i < nRandom; ++i) {
    for (int a = 0; a < 3; ++a) x[a] = b[2 * a] + U(rng) * (b[2 * a + 1] - b[2 * a]);
    checkPair(cell, pts, x, t, what + " (box)");
    if (::testing::Test::HasFatalFailure()) return;
  }
  for (const auto& e : extra) {
    checkPair(cell, pts, e.data(), t, what + " (extra)");
    if (::testing::Test::HasFatalFailure()) return;
  }
}

std::string describe(const Tally& t) {
  return std::to_string(t.pairs) + " pairs: engine inside " + std::to_string(t.inside) + ", outside " +
         std::to_string(t.outside) + ", asked VTK " + std::to_string(t.ask) + " (" +
         std::to_string(t.askWhereVtkInside) + " of them inside); VTK inside " + std::to_string(t.vtkInside);
}

// ---------------------------------------------------------------------------------------------
// The real grids
// ---------------------------------------------------------------------------------------------

struct GridCase {
  const char* path;
};
// So that ctest's log names the grid instead of the parameter's bytes.
void PrintTo(const GridCase& c, std::ostream* os) { *os << c.path; }

class CellEvalGrid : public ::testing::TestWithParam<GridCase> {};

TEST_P(CellEvalGrid, AgreesWithVtkEvaluatePosition) {
  const std::string rel = GetParam().path;
  auto g = mtest::readGrid(rel);
  ASSERT_TRUE(g) << "cannot read " << rel;
  // The engine's copy of the cells, as the locator makes it (floats kept where exact).
  const mtree::CellSet cells = mtest::cellSet(g);
  std::mt19937_64 rng(20261121);
  const vtkIdType nc = g->GetNumberOfCells();
  std::uniform_int_distribution<vtkIdType> pick(0, nc - 1);
  vtkNew<vtkGenericCell> cell;
  Tally t;
  double gb[6];
  g->GetBounds(gb);
  // Points outside the grid, checked against every sampled cell too.
  const std::vector<std::array<double, 3>> outsideGrid = {
      {gb[0] - 0.5 * (gb[1] - gb[0]), gb[2], gb[4]}, {gb[1] + 1e-9, 0.5 * (gb[2] + gb[3]), 0.5 * (gb[4] + gb[5])}};
  int evaluable = 0;
  for (int s = 0; s < 1500; ++s) {
    const vtkIdType c = pick(rng);
    g->GetCell(c, cell);
    const int64_t np = cells.numCellPoints(static_cast<size_t>(c));
    if (!mtree::vtk91::cellEvaluable(cells.type(static_cast<size_t>(c)), np)) continue;
    ++evaluable;
    // The engine reads its own copy: it must hold VTK's coordinates exactly.
    double pts[24];
    const mtree::CellSet::PointIds pid = cells.cellPointIds(static_cast<size_t>(c));
    for (int64_t k = 0; k < np; ++k) {
      const mtree::Vec3 p = cells.point(pid[k]);
      double q[3];
      cell->GetPoints()->GetPoint(k, q);
      ASSERT_TRUE(p.x == q[0] && p.y == q[1] && p.z == q[2]);
      pts[3 * k] = p.x;
      pts[3 * k + 1] = p.y;
      pts[3 * k + 2] = p.z;
    }
    (void)pts;
    checkCell(cell->GetRepresentativeCell(), rng, 8, t, rel + " cell " + std::to_string(c), outsideGrid);
    if (HasFatalFailure()) return;
  }
  ASSERT_GT(evaluable, 1000);
  std::printf("[ tally    ] %s: %s\n", rel.c_str(), describe(t).c_str());
  // The split must pay: VTK is asked about few pairs (points placed on the tolerance limits
  // by construction, about one in twelve, are the most of them).
  EXPECT_LT(t.ask, t.pairs / 8) << describe(t);
  EXPECT_GT(t.inside, t.pairs / 4) << describe(t);
}

INSTANTIATE_TEST_SUITE_P(Grids, CellEvalGrid,
                         ::testing::Values(GridCase{"cfd/brick_hex.su2"}, GridCase{"cfd/brick_prism.su2"},
                                           GridCase{"cfd/brick_pyra.su2"}, GridCase{"cfd/brick_tets.su2"},
                                           GridCase{"cfd/pipe_flow_tets.vtu"},
                                           GridCase{"cfd/pipe_lumen_tets.vtu"}),
                         [](const ::testing::TestParamInfo<GridCase>& info) {
                           std::string s = info.param.path;
                           s = s.substr(s.find('/') + 1);
                           for (char& ch : s)
                             if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
                           return s;
                         });

// ---------------------------------------------------------------------------------------------
// Made-up cells
// ---------------------------------------------------------------------------------------------

/// A VTK cell of `type` with the given points (already transformed).
vtkSmartPointer<vtkGenericCell> makeCell(int type, const std::vector<std::array<double, 3>>& p) {
  auto c = vtkSmartPointer<vtkGenericCell>::New();
  c->SetCellType(type);
  c->PointIds->SetNumberOfIds(static_cast<vtkIdType>(p.size()));
  c->Points->SetNumberOfPoints(static_cast<vtkIdType>(p.size()));
  for (size_t k = 0; k < p.size(); ++k) {
    c->PointIds->SetId(static_cast<vtkIdType>(k), static_cast<vtkIdType>(k));
    c->Points->SetPoint(static_cast<vtkIdType>(k), p[k].data());
  }
  return c;
}

struct Shape {
  std::string name;
  int type;
  std::vector<std::array<double, 3>> pts;
};

std::vector<Shape> shapes() {
  std::vector<Shape> s;
  const std::vector<std::array<double, 3>> cube = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
                                                   {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
  s.push_back({"unit hexahedron", VTK_HEXAHEDRON, cube});
  auto hex = [&](const std::string& name, auto f) {
    std::vector<std::array<double, 3>> p = cube;
    for (auto& q : p) q = f(q);
    s.push_back({name, VTK_HEXAHEDRON, p});
  };
  hex("sheared hexahedron", [](std::array<double, 3> q) { return std::array<double, 3>{q[0] + 0.4 * q[2], q[1] + 0.2 * q[0], q[2]}; });
  for (double deg : {20.0, 60.0, 90.0, 150.0}) {
    // Top face rotated about the axis: non-planar side faces, a tangled cell past 90 degrees.
    const double a = deg * 3.14159265358979323846 / 180;
    hex("twisted hexahedron " + std::to_string(int(deg)), [a](std::array<double, 3> q) {
      const double t = a * q[2], x = q[0] - 0.5, y = q[1] - 0.5;
      return std::array<double, 3>{0.5 + x * std::cos(t) - y * std::sin(t), 0.5 + x * std::sin(t) + y * std::cos(t), q[2]};
    });
  }
  hex("warped hexahedron", [](std::array<double, 3> q) {
    return std::array<double, 3>{q[0], q[1], q[2] + 0.3 * q[0] * q[1]};
  });
  hex("trapezoidal hexahedron", [](std::array<double, 3> q) {
    return std::array<double, 3>{q[0] * (1 - 0.7 * q[2]) + 0.35 * q[2], q[1], q[2]};
  });
  hex("flat hexahedron 1e-8", [](std::array<double, 3> q) { return std::array<double, 3>{q[0], q[1], 1e-8 * q[2]}; });
  hex("thin hexahedron 1e-4", [](std::array<double, 3> q) { return std::array<double, 3>{q[0], q[1], 1e-4 * q[2]}; });
  {
    std::vector<std::array<double, 3>> p = cube;
    p[4] = p[5] = p[6] = p[7] = {0.5, 0.5, 1};  // top face collapsed to a point
    s.push_back({"hexahedron with collapsed face", VTK_HEXAHEDRON, p});
    p = cube;
    p[6] = p[7];  // one edge collapsed
    s.push_back({"hexahedron with collapsed edge", VTK_HEXAHEDRON, p});
    p = cube;
    p[4] = p[0];
    p[5] = p[1];
    p[6] = p[2];
    p[7] = p[3];  // zero volume
    s.push_back({"hexahedron of zero volume", VTK_HEXAHEDRON, p});
    p = cube;
    std::swap(p[0], p[1]);  // tangled (inverted corner ordering)
    s.push_back({"tangled hexahedron", VTK_HEXAHEDRON, p});
  }
  const std::vector<std::array<double, 3>> wedge = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 0, 1}, {0, 1, 1}};
  s.push_back({"unit wedge", VTK_WEDGE, wedge});
  {
    std::vector<std::array<double, 3>> p = wedge;
    p[3] = {0.2, 0.1, 1.1};
    p[4] = {0.9, 0.5, 0.8};
    p[5] = {-0.3, 0.9, 1.2};
    s.push_back({"twisted wedge", VTK_WEDGE, p});
    p = wedge;
    p[3] = p[4] = p[5] = {0.3, 0.3, 1};  // top triangle collapsed
    s.push_back({"wedge with collapsed face", VTK_WEDGE, p});
    p = wedge;
    for (auto& q : p) q[2] *= 1e-9;
    s.push_back({"flat wedge", VTK_WEDGE, p});
  }
  const std::vector<std::array<double, 3>> pyr = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0.5, 0.5, 1}};
  s.push_back({"unit pyramid", VTK_PYRAMID, pyr});
  {
    std::vector<std::array<double, 3>> p = pyr;
    p[4] = {1.2, -0.1, 0.6};  // apex beyond a base corner
    s.push_back({"oblique pyramid", VTK_PYRAMID, p});
    p = pyr;
    p[2] = {1.2, 1.1, 0.3};  // non-planar base
    s.push_back({"warped pyramid", VTK_PYRAMID, p});
    p = pyr;
    p[4] = {0.5, 0.5, 0};  // apex at the base centre: zero volume, length2 == 0
    s.push_back({"flat pyramid", VTK_PYRAMID, p});
    p = pyr;
    p[4] = {0.5, 0.5, 1e-7};
    s.push_back({"nearly flat pyramid", VTK_PYRAMID, p});
  }
  const std::vector<std::array<double, 3>> tet = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  s.push_back({"unit tetrahedron", VTK_TETRA, tet});
  {
    std::vector<std::array<double, 3>> p = tet;
    p[3] = {0.3, 0.3, 1e-7};
    s.push_back({"sliver tetrahedron", VTK_TETRA, p});
    p[3] = {0.3, 0.3, 0};
    s.push_back({"coplanar tetrahedron", VTK_TETRA, p});
    p = tet;
    p[3] = p[2];
    s.push_back({"tetrahedron with a repeated point", VTK_TETRA, p});
    p = {{0, 0, 0}, {0, 1, 0}, {1, 0, 0}, {0, 0, 1}};
    s.push_back({"inverted tetrahedron", VTK_TETRA, p});
  }
  const std::vector<std::array<double, 3>> vox = {{0, 0, 0}, {2, 0, 0}, {0, 1, 0}, {2, 1, 0},
                                                  {0, 0, 0.5}, {2, 0, 0.5}, {0, 1, 0.5}, {2, 1, 0.5}};
  s.push_back({"voxel", VTK_VOXEL, vox});
  {
    std::vector<std::array<double, 3>> p = vox;
    for (auto& q : p) q[2] = 0;
    s.push_back({"voxel of zero height", VTK_VOXEL, p});
  }
  return s;
}

TEST(CellEval, MadeUpCellsAtEveryScale) {
  std::mt19937_64 rng(7);
  Tally all;
  for (const Shape& sh : shapes()) {
    Tally perShape;
    // Scales and offsets: as given, tiny, huge, far from the origin.
    const double scales[] = {1.0, 1e-12, 1e12, 1.0, 3e-3};
    const double offsets[] = {0.0, 0.0, 0.0, 1e12, -1e6};
    for (int v = 0; v < 5; ++v) {
      std::vector<std::array<double, 3>> p = sh.pts;
      for (auto& q : p)
        for (double& c : q) c = c * scales[v] + offsets[v];
      auto cell = makeCell(sh.type, p);
      const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
      const std::vector<std::array<double, 3>> extra = {
          {nan, 0, 0}, {p[0][0], nan, p[0][2]}, {inf, p[0][1], p[0][2]}, {-inf, -inf, -inf}};
      Tally t;
      checkCell(cell->GetRepresentativeCell(), rng, 200, t, sh.name + " scale " + std::to_string(scales[v]) +
                " offset " + std::to_string(offsets[v]), extra);
      if (HasFatalFailure()) return;
      for (Tally* a : {&all, &perShape}) {
        a->pairs += t.pairs;
        a->inside += t.inside;
        a->outside += t.outside;
        a->ask += t.ask;
        a->vtkInside += t.vtkInside;
        a->askWhereVtkInside += t.askWhereVtkInside;
      }
    }
    std::printf("[ tally    ] %s: %s\n", sh.name.c_str(), describe(perShape).c_str());
  }
  std::printf("[ tally    ] made-up cells: %s\n", describe(all).c_str());
}

TEST(CellEval, RegularCellsAreDecidedHere) {
  // On undistorted cells at ordinary scales, points away from the limits are always answered.
  std::mt19937_64 rng(3);
  for (const Shape& sh : shapes()) {
    if (sh.name.rfind("unit", 0) != 0 && sh.name != "voxel") continue;
    auto cell = makeCell(sh.type, sh.pts);
    vtkCell* c = cell->GetRepresentativeCell();
    double pts[24];
    for (size_t k = 0; k < sh.pts.size(); ++k)
      for (int a = 0; a < 3; ++a) pts[3 * k + a] = sh.pts[k][a];
    std::uniform_real_distribution<double> U(0.05, 0.3);
    for (int i = 0; i < 200; ++i) {
      double p[3] = {U(rng), U(rng), U(rng)}, x[3], w[8], pc[3];
      int sub = 0;
      c->EvaluateLocation(sub, p, x, w);
      EXPECT_EQ(mtree::vtk91::evaluateLinearCell(static_cast<uint8_t>(sh.type), pts, x, pc, w), PointInCell::kInside)
          << sh.name;
      const double far[3] = {x[0] + 5, x[1], x[2]};
      EXPECT_EQ(mtree::vtk91::evaluateLinearCell(static_cast<uint8_t>(sh.type), pts, far, pc, w), PointInCell::kOutside)
          << sh.name;
    }
  }
}

// The face Newton's first iterate points to (outsideFace) is the cell's face on that side: for a
// point half a cell beyond each side of a unit hexahedron, wedge and pyramid (mapped from its
// pcoords by the cell's own interpolation), faceSeparates proves it outside by the hull margin.
template <class S>
void expectFacesSeparate(const std::vector<double>& pts, const std::vector<std::array<double, 3>>& beyond) {
  for (const auto& pc : beyond) {
    double w[8], x[3] = {0, 0, 0};
    S::functions(pc.data(), w);
    for (int k = 0; k < S::N; ++k)
      for (int a = 0; a < 3; ++a) x[a] += w[k] * pts[3 * k + a];
    const int f = S::outsideFace(pc.data());
    ASSERT_GE(f, 0) << pc[0] << " " << pc[1] << " " << pc[2];
    EXPECT_TRUE(mtree::vtk91::cell_eval::faceSeparates(pts.data(), *mtree::cellTopology(S::kType), f, x, S::kHullMargin, 1e-12))
        << "face " << f << " for pcoords " << pc[0] << " " << pc[1] << " " << pc[2];
  }
  const double inside[3] = {0.3, 0.3, 0.3};
  EXPECT_LT(S::outsideFace(inside), 0);
}

TEST(CellEval, FirstStepOutsideFaceIsTheCellsFace) {
  namespace ce = mtree::vtk91::cell_eval;
  expectFacesSeparate<ce::Hexahedron>({0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0, 0, 1, 1, 0, 1, 1, 1, 1, 0, 1, 1},
                                      {{-0.5, 0.5, 0.5}, {1.5, 0.5, 0.5}, {0.5, -0.5, 0.5}, {0.5, 1.5, 0.5},
                                       {0.5, 0.5, -0.5}, {0.5, 0.5, 1.5}});
  expectFacesSeparate<ce::Wedge>({0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 1, 0, 1, 0, 1, 1},
                                 {{0.2, 0.2, -0.5}, {0.2, 0.2, 1.5}, {0.3, -0.5, 0.5}, {0.8, 0.8, 0.5}, {-0.5, 0.3, 0.5}});
  expectFacesSeparate<ce::Pyramid>({0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0.5, 0.5, 1},
                                   {{0.5, 0.5, -0.5}, {0.5, -0.5, 0.3}, {1.5, 0.5, 0.3}, {0.5, 1.5, 0.3}, {-0.5, 0.5, 0.3}});
}

TEST(CellEval, SimdColumnsEqualTheScalarLoop) {
  // newtonColumns (two sums per SSE2 register) against the plain loop, bit for bit, on random
  // points and coefficients of mixed signs and magnitudes.
#ifdef MATRIXTREE_CELL_EVAL_ROUNDING_DIFFERS
  GTEST_SKIP() << "the plain loop is contracted to FMA in this build";
#endif
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> U(-1, 1), E(-12, 12);
  for (int rep = 0; rep < 2000; ++rep) {
    double pts[24], w[8], d[24];
    for (double& v : pts) v = U(rng) * std::pow(10.0, E(rng));
    for (double& v : w) v = U(rng);
    for (double& v : d) v = U(rng);
    double a[4][3], b[4][3];
    mtree::vtk91::cell_eval::newtonColumns<8>(pts, w, d, a[0], a[1], a[2], a[3]);
    mtree::vtk91::cell_eval::newtonColumnsScalar<8>(pts, w, d, b[0], b[1], b[2], b[3]);
    for (int c = 0; c < 4; ++c)
      for (int j = 0; j < 3; ++j) ASSERT_TRUE(sameBits(a[c][j], b[c][j])) << c << " " << j;
    mtree::vtk91::cell_eval::newtonColumns<5>(pts, w, d, a[0], a[1], a[2], a[3]);
    mtree::vtk91::cell_eval::newtonColumnsScalar<5>(pts, w, d, b[0], b[1], b[2], b[3]);
    for (int c = 0; c < 4; ++c)
      for (int j = 0; j < 3; ++j) ASSERT_TRUE(sameBits(a[c][j], b[c][j])) << c << " " << j;
  }
}

TEST(CellEval, Avx2StepEqualsSse2Step) {
  // The Newton step's determinants, four lanes against two, bit for bit, on random points,
  // parametric positions and magnitudes (the shape functions of each Newton type).
#ifdef MATRIXTREE_CELL_EVAL_ROUNDING_DIFFERS
  GTEST_SKIP() << "the SSE2 step is contracted to FMA in this build";
#endif
  if (!mtree::vtk91::cell_eval::haveAvx2()) GTEST_SKIP() << "no AVX2 on this processor";
#if MTREE_CELL_EVAL_AVX2
  using mtree::vtk91::cell_eval::Avx2Step;
  using mtree::vtk91::cell_eval::Sse2Step;
  std::mt19937_64 rng(12);
  std::uniform_real_distribution<double> U(-1, 1), E(-12, 12);
  for (int rep = 0; rep < 2000; ++rep) {
    double pts[24], x[3], pc[3];
    for (double& v : pts) v = U(rng) * std::pow(10.0, E(rng));
    for (double& v : x) v = U(rng) * std::pow(10.0, E(rng));
    for (double& v : pc) v = 2 * U(rng);
    double a[4], b[4];
    Sse2Step::run<mtree::vtk91::cell_eval::Hexahedron>(pts, x, pc, a);
    Avx2Step::run<mtree::vtk91::cell_eval::Hexahedron>(pts, x, pc, b);
    ASSERT_EQ(std::memcmp(a, b, sizeof a), 0) << "hexahedron " << rep;
    Sse2Step::run<mtree::vtk91::cell_eval::Wedge>(pts, x, pc, a);
    Avx2Step::run<mtree::vtk91::cell_eval::Wedge>(pts, x, pc, b);
    ASSERT_EQ(std::memcmp(a, b, sizeof a), 0) << "wedge " << rep;
    Sse2Step::run<mtree::vtk91::cell_eval::Pyramid>(pts, x, pc, a);
    Avx2Step::run<mtree::vtk91::cell_eval::Pyramid>(pts, x, pc, b);
    ASSERT_EQ(std::memcmp(a, b, sizeof a), 0) << "pyramid " << rep;
  }
#endif
}

TEST(CellEval, OtherTypesAreLeftToVtk) {
  double pts[24] = {0, 0, 0, 1, 0, 0, 0, 1, 0}, x[3] = {0.2, 0.2, 0}, pc[3], w[8];
  for (uint8_t type : {uint8_t(VTK_TRIANGLE), uint8_t(VTK_QUAD), uint8_t(VTK_POLYGON), uint8_t(VTK_LINE),
                       uint8_t(VTK_QUADRATIC_TETRA), uint8_t(VTK_POLYHEDRON)})
    EXPECT_EQ(mtree::vtk91::evaluateLinearCell(type, pts, x, pc, w), PointInCell::kAskVtk) << int(type);
  EXPECT_FALSE(mtree::vtk91::cellEvaluable(VTK_HEXAHEDRON, 7));
  EXPECT_TRUE(mtree::vtk91::cellEvaluable(VTK_WEDGE, 6));
}

}  // namespace

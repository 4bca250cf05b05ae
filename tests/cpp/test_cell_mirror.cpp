// mtree::vtk91::evaluatePosition / intersectWithLine / intersectFace (cell_mirror.h) against the
// VTK they transcribe: for every covered cell type, every output (return value, subId, pcoords,
// weights, closest point, dist2; t and x) must be VTK's bit for bit, and written exactly where
// VTK writes it (the outputs start as a sentinel on both sides and are compared as bytes).
//
// Cells: regular, randomly perturbed, warped, sheared and flat ones, degenerate ones (repeated
// points, collinear and coplanar points), at scales 1e-9..1e9 and offsets up to 1e7. Points:
// random in the padded bounds, the cell's points, edge midpoints and points just beside them.
// Segments: random, through points and edges, lying in a face's plane, parallel to axes,
// starting inside, of zero length; tolerances 0, 1e-12 of the cell and 1e-2 of the cell.
// Polygons: vtkPolygon::PointInPolygon votes over random rays (vtkMath::Random), so a polygon is
// compared only at points whose answer every ray agrees on (away from its edges).
#include <gtest/gtest.h>

#include <vtkCell.h>
#include <vtkCellType.h>
#include <vtkGenericCell.h>
#include <vtkIdList.h>
#include <vtkNew.h>
#include <vtkPoints.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "mtree/cells/cells.h"
#include "mtree/vtk91/cell_mirror.h"

namespace {

constexpr double kSentinel = -12345.6789;

bool same(double a, double b) { return std::memcmp(&a, &b, sizeof(double)) == 0; }

std::string describe(int type, const std::vector<double>& pts, const double* q, int nq) {
  std::ostringstream os;
  os.precision(17);
  os << "type " << type << " points";
  for (double v : pts) os << ' ' << v;
  os << " query";
  for (int i = 0; i < nq; ++i) os << ' ' << q[i];
  return os.str();
}

/// The reference cell: a vtkGenericCell of the type with these points and ids.
struct VtkCell {
  vtkNew<vtkGenericCell> cell;
  void set(int type, const std::vector<double>& pts, const std::vector<int64_t>& ids) {
    cell->SetCellType(type);
    const vtkIdType n = static_cast<vtkIdType>(pts.size() / 3);
    cell->PointIds->SetNumberOfIds(n);
    cell->Points->SetNumberOfPoints(n);
    for (vtkIdType k = 0; k < n; ++k) {
      cell->PointIds->SetId(k, ids[k]);
      cell->Points->SetPoint(k, &pts[3 * k]);
    }
  }
};

struct Counts {
  long long evaluations = 0, inside = 0, segments = 0, hits = 0;
};

void compareEvaluate(VtkCell& ref, const mtree::vtk91::MirrorCell& mc, const std::vector<double>& pts,
                     const double x[3], bool withClosest, Counts& counts) {
  const int n = mc.n;
  double cpA[3] = {kSentinel, kSentinel, kSentinel}, cpB[3] = {kSentinel, kSentinel, kSentinel};
  double pcA[3] = {kSentinel, kSentinel, kSentinel}, pcB[3] = {kSentinel, kSentinel, kSentinel};
  std::vector<double> wA(static_cast<size_t>(n) + 2, kSentinel), wB(static_cast<size_t>(n) + 2, kSentinel);
  double d2A = kSentinel, d2B = kSentinel;
  int subA = -77, subB = -77;
  double xx[3] = {x[0], x[1], x[2]};
  const int rA = ref.cell->EvaluatePosition(xx, withClosest ? cpA : nullptr, subA, pcA, d2A, wA.data());
  const int rB = mtree::vtk91::evaluatePosition(mc, x, withClosest ? cpB : nullptr, subB, pcB, d2B, wB.data());
  const std::string what = describe(mc.type, pts, x, 3) + (withClosest ? " (closest)" : "");
  ++counts.evaluations;
  counts.inside += rA == 1;
  ASSERT_EQ(rA, rB) << what;
  EXPECT_EQ(subA, subB) << what;
  for (int i = 0; i < 3; ++i) EXPECT_TRUE(same(pcA[i], pcB[i])) << what << " pcoords[" << i << "] " << pcA[i] << " " << pcB[i];
  for (int k = 0; k < n + 2; ++k) EXPECT_TRUE(same(wA[k], wB[k])) << what << " weights[" << k << "] " << wA[k] << " " << wB[k];
  for (int i = 0; i < 3; ++i) EXPECT_TRUE(same(cpA[i], cpB[i])) << what << " closest[" << i << "] " << cpA[i] << " " << cpB[i];
  EXPECT_TRUE(same(d2A, d2B)) << what << " dist2 " << d2A << " " << d2B;
}

void compareIntersect(VtkCell& ref, const mtree::vtk91::MirrorCell& mc, const std::vector<double>& pts,
                      const double p1[3], const double p2[3], double tol, Counts& counts) {
  double tA = kSentinel, tB = kSentinel;
  double xA[3] = {kSentinel, kSentinel, kSentinel}, xB[3] = {kSentinel, kSentinel, kSentinel};
  double pcA[3] = {kSentinel, kSentinel, kSentinel}, pcB[3] = {kSentinel, kSentinel, kSentinel};
  int subA = -77, subB = -77;
  double a[3] = {p1[0], p1[1], p1[2]}, b[3] = {p2[0], p2[1], p2[2]};
  const int rA = ref.cell->IntersectWithLine(a, b, tol, tA, xA, pcA, subA);
  const int rB = mtree::vtk91::intersectWithLine(mc, p1, p2, tol, tB, xB, pcB, subB);
  const double q[7] = {p1[0], p1[1], p1[2], p2[0], p2[1], p2[2], tol};
  const std::string what = describe(mc.type, pts, q, 7);
  ++counts.segments;
  counts.hits += rA != 0;
  ASSERT_EQ(rA, rB) << what;
  EXPECT_EQ(subA, subB) << what;
  EXPECT_TRUE(same(tA, tB)) << what << " t " << tA << " " << tB;
  for (int i = 0; i < 3; ++i) EXPECT_TRUE(same(xA[i], xB[i])) << what << " x[" << i << "] " << xA[i] << " " << xB[i];
  for (int i = 0; i < 3; ++i) EXPECT_TRUE(same(pcA[i], pcB[i])) << what << " pcoords[" << i << "] " << pcA[i] << " " << pcB[i];
}

/// The reference shapes of each type, in [0, 1]^3 (VTK's point order).
std::vector<double> unitCell(int type) {
  switch (type) {
    case VTK_VERTEX: return {0.3, 0.4, 0.5};
    case VTK_POLY_VERTEX: return {0, 0, 0, 1, 0, 0, 0.5, 1, 0.2};
    case VTK_LINE: return {0, 0, 0, 1, 0.5, 0.25};
    case VTK_POLY_LINE: return {0, 0, 0, 1, 0, 0, 1, 1, 0, 0.5, 1, 1};
    case VTK_TRIANGLE: return {0, 0, 0, 1, 0, 0, 0, 1, 0};
    case VTK_TRIANGLE_STRIP: return {0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0.2, 0.5, 1.6, 0.4};
    case VTK_POLYGON: return {0, 0, 0, 1, 0, 0, 1.2, 0.8, 0, 0.5, 1.3, 0, -0.2, 0.7, 0};
    case VTK_PIXEL: return {0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0};
    case VTK_QUAD: return {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
    case VTK_TETRA: return {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
    case VTK_VOXEL: return {0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0, 0, 0, 1, 1, 0, 1, 0, 1, 1, 1, 1, 1};
    case VTK_HEXAHEDRON: return {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0, 0, 1, 1, 0, 1, 1, 1, 1, 0, 1, 1};
    case VTK_WEDGE: return {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 1, 0, 1, 0, 1, 1};
    case VTK_PYRAMID: return {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0.5, 0.5, 1};
    default: {
      // A higher-order cell: its nodes at their parametric coordinates (VTK's own), bent by a
      // smooth displacement so that the cell is curved.
      vtkNew<vtkGenericCell> cell;
      cell->SetCellType(type);
      const double* pc = cell->GetParametricCoords();
      std::vector<double> p(pc, pc + 3 * cell->GetNumberOfPoints());
      for (size_t k = 0; k < p.size() / 3; ++k) {
        double* q = &p[3 * k];
        const double bend[3] = {0.08 * std::sin(2.0 * q[1] + q[2]), 0.08 * std::sin(1.5 * q[2] + 2 * q[0]),
                                0.08 * std::cos(2.5 * q[0] + q[1])};
        for (int a = 0; a < 3; ++a) q[a] += bend[a];
      }
      return p;
    }
  }
}

/// Whether the type keeps its axis alignment (voxel, pixel: only scaled and shifted, never
/// perturbed or rotated, as VTK requires of them).
bool axisAligned(int type) { return type == VTK_VOXEL || type == VTK_PIXEL; }

struct Case {
  std::vector<double> pts;
  std::vector<int64_t> ids;
  bool collinear = false;  // every point on one line
  double offset = 0;
};

/// Variants of a type's reference shape: as is, perturbed, warped, flattened, with a repeated
/// point, sheared, scaled and shifted.
std::vector<Case> cellsOf(int type, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> U(-1, 1);
  const std::vector<double> base = unitCell(type);
  const size_t n = base.size() / 3;
  std::vector<Case> out;
  auto add = [&](std::vector<double> p, double scale, double offset, bool randomIds) {
    for (double& v : p) v = v * scale + offset;
    Case c;
    c.pts = p;
    c.offset = offset;
    c.ids.resize(n);
    for (size_t k = 0; k < n; ++k) c.ids[k] = randomIds ? static_cast<int64_t>(rng() % 1000) : static_cast<int64_t>(k + 10);
    out.push_back(c);
  };
  const double scales[] = {1.0, 1e-9, 1e9, 3e-3};
  const double offsets[] = {0.0, 1e7, -250.0};
  for (double s : scales)
    for (double o : offsets) {
      if (s == 1e-9 && o == 1e7) continue;  // the cell is below the coordinates' round-off
      add(base, s, o, false);
      for (int r = 0; r < 3; ++r) {
        std::vector<double> p = base;
        if (!axisAligned(type))
          for (double& v : p) v += 0.15 * U(rng);
        else
          for (size_t k = 0; k < n; ++k) p[3 * k] *= 1.7;  // a long voxel or pixel
        add(p, s, o, true);
      }
    }
  if (!axisAligned(type) && n >= 3) {
    // Flat: every point in the plane z = 0.3 (a 3-D cell is then degenerate).
    std::vector<double> p = base;
    for (size_t k = 0; k < n; ++k) p[3 * k + 2] = 0.3;
    add(p, 1.0, 0.0, false);
    // A repeated point.
    p = base;
    for (int a = 0; a < 3; ++a) p[3 + a] = p[a];
    add(p, 1.0, 0.0, false);
    // Collinear points.
    p = base;
    for (size_t k = 0; k < n; ++k) {
      const double t = 0.37 * static_cast<double>(k);
      p[3 * k] = t;
      p[3 * k + 1] = 2 * t;
      p[3 * k + 2] = -t;
    }
    add(p, 1.0, 0.0, false);
    out.back().collinear = true;
    // Warped: a point lifted off the others' plane.
    p = base;
    p[3 * (n - 1) + 2] += 0.4;
    add(p, 1.0, 0.0, true);
    // Equal quad diagonals with every tie of the ids.
    if (type == VTK_QUAD)
      for (int m = 0; m < 4; ++m) {
        Case c;
        c.pts = {0, 0, 0, 2, 0, 0, 2, 1, 0, 0, 1, 0.1};
        c.ids = {1, 2, 3, 4};
        c.ids[m] = 9;
        out.push_back(c);
      }
  }
  return out;
}

/// Query points around cell `pts` (n points): random in the padded bounds, the points, edge
/// midpoints and points nudged off them.
std::vector<std::array<double, 3>> pointsAround(const std::vector<double>& pts, std::mt19937_64& rng, int count) {
  const size_t n = pts.size() / 3;
  double lo[3], hi[3];
  for (int a = 0; a < 3; ++a) {
    lo[a] = hi[a] = pts[a];
    for (size_t k = 1; k < n; ++k) {
      lo[a] = std::min(lo[a], pts[3 * k + a]);
      hi[a] = std::max(hi[a], pts[3 * k + a]);
    }
  }
  double ext = 0;
  for (int a = 0; a < 3; ++a) ext = std::max(ext, hi[a] - lo[a]);
  if (!(ext > 0)) ext = 1e-3 * (std::fabs(lo[0]) + 1);
  std::uniform_real_distribution<double> U(0, 1);
  std::vector<std::array<double, 3>> out;
  for (int i = 0; i < count; ++i) {
    std::array<double, 3> x;
    for (int a = 0; a < 3; ++a) x[a] = lo[a] - 0.2 * ext + U(rng) * (hi[a] - lo[a] + 0.4 * ext);
    out.push_back(x);
  }
  for (size_t k = 0; k < n; ++k) {
    std::array<double, 3> p{pts[3 * k], pts[3 * k + 1], pts[3 * k + 2]};
    out.push_back(p);
    const std::array<double, 3> q{pts[3 * ((k + 1) % n)], pts[3 * ((k + 1) % n) + 1], pts[3 * ((k + 1) % n) + 2]};
    std::array<double, 3> m;
    for (int a = 0; a < 3; ++a) m[a] = 0.5 * (p[a] + q[a]);
    out.push_back(m);
    for (double eps : {1e-9, 1e-4, 2e-3})
      for (int a = 0; a < 3; ++a) {
        std::array<double, 3> e = m;
        e[a] += eps * ext;
        out.push_back(e);
        e[a] -= 2 * eps * ext;
        out.push_back(e);
      }
  }
  return out;
}

void runType(int type, int pointsPerCell, int segmentsPerCell) {
  std::mt19937_64 rng(1000 + type);
  VtkCell ref;
  Counts counts;
  for (const Case& c : cellsOf(type, rng)) {
    ref.set(type, c.pts, c.ids);
    mtree::vtk91::MirrorCell mc;
    mc.type = static_cast<uint8_t>(type);
    mc.n = static_cast<int>(c.pts.size() / 3);
    mc.pts = c.pts.data();
    mc.ids = c.ids.data();
    ASSERT_TRUE(mtree::vtk91::mirrorCovers(mc.type, mc.n));
    const auto xs = pointsAround(c.pts, rng, pointsPerCell);
    // Collinear points: VTK's strip leaves subId unset and indexes its weights with it, and a
    // tetrahedron's closest point compares its faces' unset distances: undefined in VTK, skipped.
    if (c.collinear && type == VTK_TRIANGLE_STRIP) continue;
    const bool closestDefined = !(c.collinear && type == VTK_TETRA);
    if (type != VTK_POLYGON) {
      for (const auto& x : xs) {
        compareEvaluate(ref, mc, c.pts, x.data(), false, counts);
        if (closestDefined) compareEvaluate(ref, mc, c.pts, x.data(), true, counts);
        if (::testing::Test::HasFatalFailure()) return;
      }
    }
    double ext = 0;
    for (size_t k = 1; k < c.pts.size() / 3; ++k)
      for (int a = 0; a < 3; ++a) ext = std::max(ext, std::fabs(c.pts[3 * k + a] - c.pts[a]));
    std::uniform_int_distribution<size_t> pick(0, xs.size() - 1);
    for (int s = 0; s < segmentsPerCell; ++s) {
      const auto& a = xs[pick(rng)];
      auto b = xs[pick(rng)];
      if (s % 7 == 0) b = a;  // zero length
      if (s % 7 == 1) b = {a[0] + ext, a[1], a[2]};  // parallel to an axis
      if (s % 7 == 2 && c.pts.size() >= 9) {
        // In the plane of the first three points.
        for (int k = 0; k < 3; ++k) b[k] = a[k];
        for (int k = 0; k < 3; ++k) b[k] = c.pts[6 + k] + 2 * (c.pts[3 + k] - c.pts[k]);
        std::array<double, 3> a2;
        for (int k = 0; k < 3; ++k) a2[k] = c.pts[k] - 0.5 * (c.pts[6 + k] - c.pts[k]);
        for (double tol : {0.0, 1e-2 * ext})
          if (type != VTK_POLYGON) compareIntersect(ref, mc, c.pts, a2.data(), b.data(), tol, counts);
      }
      for (double tol : {0.0, 1e-12 * ext, 1e-2 * ext}) {
        if (type == VTK_POLYGON) continue;
        compareIntersect(ref, mc, c.pts, a.data(), b.data(), tol, counts);
        if (::testing::Test::HasFatalFailure()) return;
      }
    }
  }
  EXPECT_GT(counts.inside, 0) << "type " << type << ": no point inside any cell";
  if (type != VTK_POLYGON) {
    EXPECT_GT(counts.hits, 0) << "type " << type << ": no segment hit any cell";
  }
}

TEST(CellMirror, Vertex) { runType(VTK_VERTEX, 40, 60); }
TEST(CellMirror, PolyVertex) { runType(VTK_POLY_VERTEX, 40, 60); }
TEST(CellMirror, Line) { runType(VTK_LINE, 60, 120); }
TEST(CellMirror, PolyLine) { runType(VTK_POLY_LINE, 60, 120); }
TEST(CellMirror, Triangle) { runType(VTK_TRIANGLE, 200, 300); }
TEST(CellMirror, TriangleStrip) { runType(VTK_TRIANGLE_STRIP, 100, 150); }
TEST(CellMirror, Pixel) { runType(VTK_PIXEL, 100, 150); }
TEST(CellMirror, Quad) { runType(VTK_QUAD, 200, 300); }
TEST(CellMirror, Tetra) { runType(VTK_TETRA, 200, 300); }
TEST(CellMirror, Voxel) { runType(VTK_VOXEL, 100, 150); }
TEST(CellMirror, Hexahedron) { runType(VTK_HEXAHEDRON, 200, 300); }
TEST(CellMirror, Wedge) { runType(VTK_WEDGE, 200, 300); }
TEST(CellMirror, Pyramid) { runType(VTK_PYRAMID, 200, 300); }
TEST(CellMirror, QuadraticTetra) { runType(VTK_QUADRATIC_TETRA, 150, 200); }
TEST(CellMirror, QuadraticHexahedron) { runType(VTK_QUADRATIC_HEXAHEDRON, 150, 200); }
TEST(CellMirror, QuadraticWedge) { runType(VTK_QUADRATIC_WEDGE, 150, 200); }
TEST(CellMirror, QuadraticPyramid) { runType(VTK_QUADRATIC_PYRAMID, 150, 200); }
TEST(CellMirror, TriQuadraticHexahedron) { runType(VTK_TRIQUADRATIC_HEXAHEDRON, 150, 200); }

// A polygon is compared where VTK's random-ray votes are unanimous: points at least 2e-2 of the
// polygon's size from its edges, on polygons near the origin (at an offset of 1e7 the relative
// tolerance of vtkLine::Intersection exceeds the polygon, and VTK's votes are random).
TEST(CellMirror, PolygonAwayFromEdges) {
  std::mt19937_64 rng(77);
  VtkCell ref;
  Counts counts;
  for (const Case& c : cellsOf(VTK_POLYGON, rng)) {
    const int n = static_cast<int>(c.pts.size() / 3);
    if (c.offset != 0.0) continue;
    ref.set(VTK_POLYGON, c.pts, c.ids);
    mtree::vtk91::MirrorCell mc{VTK_POLYGON, n, c.pts.data(), c.ids.data()};
    double ext = 0;
    for (int k = 1; k < n; ++k)
      for (int a = 0; a < 3; ++a) ext = std::max(ext, std::fabs(c.pts[3 * k + a] - c.pts[a]));
    if (!(ext > 0)) continue;
    for (const auto& x : pointsAround(c.pts, rng, 150)) {
      // The squared distance from x to the nearest edge.
      double near = 1e300;
      for (int k = 0; k < n; ++k) {
        const double* a = &c.pts[3 * k];
        const double* b = &c.pts[3 * ((k + 1) % n)];
        double ab[3], ax[3], t = 0, l2 = 0;
        for (int i = 0; i < 3; ++i) ab[i] = b[i] - a[i], ax[i] = x[i] - a[i], t += ab[i] * ax[i], l2 += ab[i] * ab[i];
        t = l2 > 0 ? std::min(1.0, std::max(0.0, t / l2)) : 0.0;
        double d2 = 0;
        for (int i = 0; i < 3; ++i) d2 += (ax[i] - t * ab[i]) * (ax[i] - t * ab[i]);
        near = std::min(near, d2);
      }
      // VTK's rays are uncertain where they cross an edge within 1e-3 of their length (about
      // twice the polygon) of x: 2e-2 of the polygon's size keeps clear of that.
      if (!(near > 4e-4 * ext * ext)) continue;
      compareEvaluate(ref, mc, c.pts, x.data(), false, counts);
      compareEvaluate(ref, mc, c.pts, x.data(), true, counts);
      if (::testing::Test::HasFatalFailure()) return;
    }
  }
  EXPECT_GT(counts.inside, 0);
}

// intersectFace: a face tested alone gives what the cell's IntersectWithLine gives when that
// face holds its (only) hit.
TEST(CellMirror, OneFaceIsTheCellsAnswerWhereItHoldsTheOnlyHit) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> U(0, 1);
  long long checked = 0;
  for (int type : {VTK_TETRA, VTK_HEXAHEDRON, VTK_WEDGE, VTK_PYRAMID}) {
    const std::vector<double> base = unitCell(type);
    const int n = static_cast<int>(base.size() / 3);
    const int faces = type == VTK_TETRA ? 4 : type == VTK_HEXAHEDRON ? 6 : 5;
    mtree::vtk91::MirrorCell mc{static_cast<uint8_t>(type), n, base.data(), nullptr};
    for (int s = 0; s < 400; ++s) {
      // From the centre outwards: exactly one face is crossed.
      double c[3] = {0, 0, 0};
      for (int k = 0; k < n; ++k)
        for (int a = 0; a < 3; ++a) c[a] += base[3 * k + a] / n;
      double d[3] = {U(rng) - 0.5, U(rng) - 0.5, U(rng) - 0.5};
      const double len = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
      const double p2[3] = {c[0] + 4 * d[0] / len, c[1] + 4 * d[1] / len, c[2] + 4 * d[2] / len};
      double t, x[3], pc[3];
      int sub;
      ASSERT_EQ(mtree::vtk91::intersectWithLine(mc, c, p2, 0.0, t, x, pc, sub), 1) << "type " << type;
      int hits = 0;
      for (int f = 0; f < faces; ++f) {
        double tf, xf[3], pcf[3];
        int subf;
        if (!mtree::vtk91::intersectFace(mc, f, c, p2, 0.0, tf, xf, pcf, subf)) continue;
        ++hits;
        if (!same(tf, t)) continue;  // a face met only at a shared edge or vertex, further on
        for (int i = 0; i < 3; ++i) EXPECT_TRUE(same(xf[i], x[i]));
        for (int i = 0; i < 3; ++i) EXPECT_TRUE(same(pcf[i], pc[i]));
        ++checked;
      }
      EXPECT_GE(hits, 1);
    }
  }
  EXPECT_GT(checked, 1000);
}

}  // namespace

namespace {

TEST(CellMirror, CoverageAndTypeNames) {
  EXPECT_FALSE(mtree::vtk91::mirrorCovers(VTK_POLYHEDRON, 12));
  EXPECT_FALSE(mtree::vtk91::mirrorCovers(VTK_LAGRANGE_TETRAHEDRON, 10));
  EXPECT_FALSE(mtree::vtk91::mirrorCovers(VTK_QUADRATIC_TETRA, 4));
  EXPECT_TRUE(mtree::vtk91::mirrorCovers(VTK_QUADRATIC_TETRA, 10));
  EXPECT_FALSE(mtree::vtk91::mirrorCovers(VTK_TETRA, 5));
  EXPECT_TRUE(mtree::vtk91::mirrorCovers(VTK_POLYGON, 7));
  EXPECT_STREQ(mtree::cellTypeName(VTK_WEDGE), "VTK_WEDGE");
  EXPECT_STREQ(mtree::cellTypeName(VTK_QUADRATIC_TETRA), "cell type 24");
  // The engine's dimension table is VTK's own classes' answer for every type VTK defines; -1
  // for the empty cell and codes VTK does not define (it instantiates an empty cell for those).
  for (int t = 0; t < VTK_NUMBER_OF_CELL_TYPES; ++t) {
    vtkCell* cell = vtkGenericCell::InstantiateCell(t);
    const int want = !cell || cell->GetCellType() == VTK_EMPTY_CELL ? -1 : cell->GetCellDimension();
    EXPECT_EQ(mtree::cellTypeDimension(static_cast<uint8_t>(t)), want) << "type " << t;
    if (cell) cell->Delete();
  }
}

}  // namespace

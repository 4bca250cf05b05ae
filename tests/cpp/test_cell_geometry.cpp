// mtree/vtk91/cell_geometry.h (the cell tests of the VTK-free cell locator) against VTK's own
// cells, type by type: vtkCell::EvaluatePosition (inside or not, pcoords, weights, closest point)
// and vtkCell::IntersectWithLine (hit, t). The engine decides alone what VTK's cells decide, with
// VTK's rules: the same verdicts except for points within round-off of a cell's acceptance limit,
// the same pcoords and weights, and closest points equal where VTK's are exact (vertices, lines,
// triangles, pixels, tetrahedra, voxels); elsewhere (VTK clamps pcoords) the engine's are checked
// against the exact distance to the cell's boundary triangles.
//
// Cells: one of each linear type (vertex to pyramid, polygons and strips), with seeded random
// perturbations of their points, planar where the type must be; query points uniform in the
// cell's box padded by half its size; segments through random points of that box.
#include <gtest/gtest.h>

#include <vtkCell.h>
#include <vtkCellType.h>
#include <vtkGenericCell.h>
#include <vtkNew.h>
#include <vtkPoints.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "mtree/vtk91/cell_geometry.h"

namespace {

using mtree::Vec3;

struct TestCell {
  int type;
  std::vector<double> pts;  // 3 per point
  int n() const { return static_cast<int>(pts.size() / 3); }
};

/// One cell of `type` around the origin. Cells without quad faces have their points moved by up to
/// `jitter` (2-D ones within their plane); cells with quad faces (quads, hexahedra, wedges,
/// pyramids) are mapped by a random affine map of up to `jitter`, so their faces stay planar:
/// the split of a warped face is where VTK 9.1 and the engine differ by design (see
/// cell_geometry.h). Pixels and voxels stay axis-aligned.
TestCell makeCell(int type, std::mt19937& rng, double jitter) {
  std::uniform_real_distribution<double> u(-jitter, jitter);
  const bool affine = type == VTK_QUAD || type == VTK_HEXAHEDRON || type == VTK_WEDGE || type == VTK_PYRAMID;
  double m[3][3] = {{1 + u(rng), u(rng), u(rng)}, {u(rng), 1 + u(rng), u(rng)}, {u(rng), u(rng), 1 + u(rng)}};
  if (type == VTK_QUAD) m[2][0] = m[2][1] = m[0][2] = m[1][2] = 0;
  auto pts = [&](std::vector<std::array<double, 3>> p, bool planar) {
    TestCell c{type, {}};
    for (auto& q : p) {
      if (affine) {
        const std::array<double, 3> r = q;
        for (int a = 0; a < 3; ++a) q[a] = m[a][0] * r[0] + m[a][1] * r[1] + m[a][2] * r[2];
      } else {
        q[0] += u(rng);
        q[1] += u(rng);
        if (!planar) q[2] += u(rng);
      }
      c.pts.insert(c.pts.end(), q.begin(), q.end());
    }
    return c;
  };
  switch (type) {
    case VTK_VERTEX: return pts({{0.2, 0.3, 0.1}}, false);
    case VTK_POLY_VERTEX: return pts({{0, 0, 0}, {1, 0.2, 0.1}, {0.3, 1, 0.5}}, false);
    case VTK_LINE: return pts({{0, 0, 0}, {1, 0.5, 0.3}}, false);
    case VTK_POLY_LINE: return pts({{0, 0, 0}, {1, 0.2, 0.1}, {1.3, 1, 0.4}, {0.5, 1.4, 1}}, false);
    case VTK_TRIANGLE: return pts({{0, 0, 0.2}, {1, 0.1, 0.5}, {0.3, 1, 0.9}}, false);
    case VTK_TRIANGLE_STRIP: return pts({{0, 0, 0}, {0, 1, 0}, {1, 0, 0}, {1, 1, 0}, {2, 0, 0}, {2, 1, 0}}, true);
    case VTK_POLYGON: return pts({{0, 0, 0}, {1, -0.2, 0}, {1.5, 0.6, 0}, {0.9, 1.3, 0}, {-0.1, 1, 0}}, true);
    case VTK_PIXEL: {
      TestCell c{type, {0, 0, 0.3, 1.2, 0, 0.3, 0, 0.8, 0.3, 1.2, 0.8, 0.3}};
      return c;
    }
    case VTK_QUAD: return pts({{0, 0, 0}, {1, 0, 0}, {1.1, 1, 0}, {-0.1, 0.9, 0}}, true);
    case VTK_TETRA: return pts({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}}, false);
    case VTK_VOXEL: {
      TestCell c{type, {}};
      for (int k = 0; k < 8; ++k) c.pts.insert(c.pts.end(), {(k & 1) * 1.3, (k >> 1 & 1) * 0.7, (k >> 2 & 1) * 0.9});
      return c;
    }
    case VTK_HEXAHEDRON:
      return pts({{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}}, false);
    case VTK_WEDGE: return pts({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 0, 1}, {0, 1, 1}}, false);
    case VTK_PYRAMID: return pts({{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0.5, 0.5, 1}}, false);
    default: ADD_FAILURE() << "no test cell for type " << type; return TestCell{type, {}};
  }
}

void toVtk(const TestCell& c, vtkGenericCell* cell) {
  cell->SetCellType(c.type);
  cell->PointIds->SetNumberOfIds(c.n());
  cell->Points->SetNumberOfPoints(c.n());
  for (int k = 0; k < c.n(); ++k) {
    cell->PointIds->SetId(k, k);
    cell->Points->SetPoint(k, &c.pts[3 * k]);
  }
}

struct Box3 {
  double lo[3], hi[3];
};
Box3 paddedBox(const TestCell& c, double pad) {
  Box3 b{{1e300, 1e300, 1e300}, {-1e300, -1e300, -1e300}};
  for (int k = 0; k < c.n(); ++k)
    for (int a = 0; a < 3; ++a) {
      b.lo[a] = std::min(b.lo[a], c.pts[3 * k + a]);
      b.hi[a] = std::max(b.hi[a], c.pts[3 * k + a]);
    }
  for (int a = 0; a < 3; ++a) {
    const double e = std::max(b.hi[a] - b.lo[a], 0.2) * pad;
    b.lo[a] -= e;
    b.hi[a] += e;
  }
  return b;
}

/// Whether the closest points of the infinite lines through the line cell and the segment lie
/// inside both: there VTK and the engine measure the same distance (elsewhere VTK measures from
/// the segment's end its parameter passes, the engine between the nearest points of both).
bool linesMeetInside(const TestCell& c, const double p1[3], const double p2[3]) {
  const Vec3 d1 = Vec3(p2) - Vec3(p1), d2 = Vec3(&c.pts[3]) - Vec3(&c.pts[0]), r = Vec3(p1) - Vec3(&c.pts[0]);
  const double a = mtree::dot(d1, d1), b = mtree::dot(d1, d2), e = mtree::dot(d2, d2);
  const double cc = mtree::dot(d1, r), f = mtree::dot(d2, r), den = a * e - b * b;
  if (!(den > 1e-12 * a * e)) return false;
  const double s = (b * f - cc * e) / den, t = (a * f - b * cc) / den;
  return s > 1e-6 && s < 1 - 1e-6 && t > 1e-6 && t < 1 - 1e-6;
}

/// Whether VTK's cell type has closest points that are exact (so the engine's must equal them).
bool vtkClosestIsExact(int type) {
  return type == VTK_VERTEX || type == VTK_POLY_VERTEX || type == VTK_LINE || type == VTK_POLY_LINE ||
         type == VTK_TRIANGLE || type == VTK_TRIANGLE_STRIP || type == VTK_PIXEL || type == VTK_TETRA ||
         type == VTK_VOXEL;
}

const int kTypes[] = {VTK_VERTEX, VTK_POLY_VERTEX, VTK_LINE, VTK_POLY_LINE, VTK_TRIANGLE, VTK_TRIANGLE_STRIP,
                      VTK_POLYGON, VTK_PIXEL, VTK_QUAD, VTK_TETRA, VTK_VOXEL, VTK_HEXAHEDRON, VTK_WEDGE,
                      VTK_PYRAMID};

class CellGeometry : public ::testing::TestWithParam<int> {};

TEST_P(CellGeometry, EvaluatePositionIsVtks) {
  const int type = GetParam();
  std::mt19937 rng(1000 + type);
  vtkNew<vtkGenericCell> cell;
  long long pairs = 0, differ = 0, inside = 0;
  for (int trial = 0; trial < 20; ++trial) {
    const TestCell c = makeCell(type, rng, trial == 0 ? 0.0 : 0.15);
    toVtk(c, cell);
    ASSERT_TRUE(mtree::cellTypeSupported(static_cast<uint8_t>(type), c.n()));
    const Box3 b = paddedBox(c, 0.5);
    std::uniform_real_distribution<double> ux(b.lo[0], b.hi[0]), uy(b.lo[1], b.hi[1]), uz(b.lo[2], b.hi[2]);
    for (int q = 0; q < 400; ++q) {
      double x[3] = {ux(rng), uy(rng), uz(rng)};
      // 2-D cells: half the points in the cell's plane (z of point 0 for the planar test cells).
      if (q % 2 == 0 && (type == VTK_POLYGON || type == VTK_PIXEL || type == VTK_QUAD ||
                         type == VTK_TRIANGLE_STRIP))
        x[2] = c.pts[2];
      std::vector<double> w(c.n()), vw(c.n());
      const mtree::CellPoint e = mtree::evaluateCellPoint(static_cast<uint8_t>(type), c.pts.data(), c.n(), x,
                                                          w.data(), true);
      double cp[3], pc[3], d2;
      int sub;
      const int v = cell->EvaluatePosition(x, cp, sub, pc, d2, vw.data());
      ++pairs;
      if ((v == 1) != (e.status == 1)) {
        ++differ;
        continue;
      }
      if (v == 1) {
        ++inside;
        for (int k = 0; k < c.n(); ++k) {
          EXPECT_NEAR(w[k], vw[k], 1e-9) << "weight " << k;
        }
        // VTK's polygon pcoords are in a frame of its own; the engine gives none.
        for (int a = 0; a < 3 && type != VTK_POLYGON; ++a) {
          EXPECT_NEAR(e.pcoords[a], pc[a], 1e-9) << "pcoords " << a;
        }
      }
      // Elsewhere (VTK's clamped pcoords) ClosestPointsOfVolumeCellsAreOnTheirBoundary checks.
      if (v == 1 || vtkClosestIsExact(type)) {
        EXPECT_NEAR(e.dist2, d2, 1e-9 * (1 + d2)) << "type " << type << " status " << v;
      }
      const Vec3 ec = e.closest;
      EXPECT_NEAR(std::sqrt(e.dist2), std::sqrt((ec.x - x[0]) * (ec.x - x[0]) + (ec.y - x[1]) * (ec.y - x[1]) +
                                                (ec.z - x[2]) * (ec.z - x[2])), 1e-12);
    }
  }
  // Different verdicts only within round-off of a limit: a handful in 8000 random points.
  EXPECT_LE(differ, pairs / 2000) << differ << " of " << pairs;
  if (type != VTK_VERTEX && type != VTK_POLY_VERTEX) {
    EXPECT_GT(inside, 20);
  }
}

TEST_P(CellGeometry, IntersectWithLineIsVtks) {
  const int type = GetParam();
  std::mt19937 rng(2000 + type);
  vtkNew<vtkGenericCell> cell;
  const int dim = mtree::cellDimension(static_cast<uint8_t>(type));
  // Lines and vertices are hit only within a tolerance; the others at tolerance 0 (polygons at
  // 1e-12: VTK's polygon asks dist2 <= tol^2 even inside, and the projection of a point on the
  // plane is a few ulp off it).
  const double tol = dim <= 1 ? 0.05 : (type == VTK_POLYGON ? 1e-12 : 0.0);
  long long segments = 0, hits = 0, differ = 0;
  for (int trial = 0; trial < 20; ++trial) {
    const TestCell c = makeCell(type, rng, trial == 0 ? 0.0 : 0.15);
    toVtk(c, cell);
    const Box3 b = paddedBox(c, 0.5);
    std::uniform_real_distribution<double> ux(b.lo[0], b.hi[0]), uy(b.lo[1], b.hi[1]), uz(b.lo[2], b.hi[2]);
    std::uniform_int_distribution<int> pick(0, c.n() - 1);
    std::normal_distribution<double> g(0, 0.6 * tol);
    for (int q = 0; q < 400; ++q) {
      double p1[3] = {ux(rng), uy(rng), uz(rng)}, p2[3];
      if (dim <= 1) {
        // Aim near a point of the cell, so that some segments pass within tol.
        const int k = pick(rng);
        const int k2 = c.n() > 1 ? (k + 1) % c.n() : k;
        const double s = std::uniform_real_distribution<double>(0, 1)(rng);
        for (int a = 0; a < 3; ++a) {
          const double aim = c.pts[3 * k + a] * (1 - s) + c.pts[3 * k2 + a] * s + g(rng);
          p2[a] = p1[a] + 2.0 * (aim - p1[a]);
        }
      } else {
        p2[0] = ux(rng);
        p2[1] = uy(rng);
        p2[2] = uz(rng);
      }
      double t = 0, x[3], pc[3];
      int sub;
      if (type == VTK_VOXEL) {
        // VTK's voxel is a box: a segment starting inside it hits at t = 0; the engine's volume
        // cells are hit where the segment crosses their boundary.
        std::vector<double> w(8);
        if (mtree::evaluateCellPoint(VTK_VOXEL, c.pts.data(), 8, p1, w.data(), false).status == 1) continue;
      }
      if (type == VTK_LINE && !linesMeetInside(c, p1, p2)) continue;
      if (type == VTK_POLY_LINE) {
        // The nearest hit of its lines, each decided as a line cell (compared with VTK above).
        double best = 2, lt;
        Vec3 lx;
        for (int k = 0; k + 1 < c.n(); ++k)
          if (mtree::intersectCellSegment(VTK_LINE, &c.pts[3 * k], 2, Vec3(p1), Vec3(p2), tol, lt, lx))
            best = std::min(best, lt);
        double pt;
        Vec3 px;
        const bool ph = mtree::intersectCellSegment(VTK_POLY_LINE, c.pts.data(), c.n(), Vec3(p1), Vec3(p2), tol, pt, px);
        EXPECT_EQ(ph, best <= 1);
        if (ph) {
          EXPECT_EQ(pt, best);
          ++hits;
        }
        continue;
      }
      const int v = cell->IntersectWithLine(p1, p2, tol, t, x, pc, sub);
      double et = 0;
      Vec3 ex;
      const bool e = mtree::intersectCellSegment(static_cast<uint8_t>(type), c.pts.data(), c.n(), Vec3(p1), Vec3(p2),
                                                 tol, et, ex);
      ++segments;
      if ((v != 0) != e) {
        ++differ;
        continue;
      }
      if (!e) continue;
      ++hits;
      // VTK's quads, strips, polylines and polyvertices return their first part hit, the engine
      // the nearest; equal where only one part is hit, which is nearly always.
      if (type == VTK_QUAD || type == VTK_TRIANGLE_STRIP || type == VTK_POLY_LINE || type == VTK_POLY_VERTEX) {
        if (std::fabs(et - t) > 1e-9) ++differ;
        continue;
      }
      EXPECT_NEAR(et, t, 1e-9) << "type " << type;
      if (dim >= 2) {
        EXPECT_NEAR(ex.x, x[0], 1e-9);
        EXPECT_NEAR(ex.y, x[1], 1e-9);
        EXPECT_NEAR(ex.z, x[2], 1e-9);
      }
    }
  }
  EXPECT_GT(hits, 20) << "segments that hit";
  EXPECT_LE(differ, segments / 500) << differ << " of " << segments;
}

INSTANTIATE_TEST_SUITE_P(LinearTypes, CellGeometry, ::testing::ValuesIn(kTypes),
                         [](const ::testing::TestParamInfo<int>& i) {
                           return std::string(mtree::cellTypeName(static_cast<uint8_t>(i.param))).substr(4);
                         });

TEST(CellGeometry, ClosestPointsOfVolumeCellsAreOnTheirBoundary) {
  // Outside a hexahedron, wedge or pyramid the engine's closest point is the nearest point of the
  // boundary triangles: compare with a dense sampling of those triangles.
  std::mt19937 rng(77);
  for (int type : {VTK_HEXAHEDRON, VTK_WEDGE, VTK_PYRAMID}) {
    const TestCell c = makeCell(type, rng, 0.1);
    const Box3 b = paddedBox(c, 1.0);
    std::uniform_real_distribution<double> ux(b.lo[0], b.hi[0]), uy(b.lo[1], b.hi[1]), uz(b.lo[2], b.hi[2]);
    vtkNew<vtkGenericCell> cell;
    toVtk(c, cell);
    for (int q = 0; q < 50; ++q) {
      const double x[3] = {ux(rng), uy(rng), uz(rng)};
      std::vector<double> w(c.n());
      const mtree::CellPoint e =
          mtree::evaluateCellPoint(static_cast<uint8_t>(type), c.pts.data(), c.n(), x, w.data(), true);
      if (e.status == 1) continue;
      // The boundary of the cell: VTK's faces, each triangulated (0, 1, 2), (2, 3, 0).
      double best = 1e300;
      for (int f = 0; f < cell->GetNumberOfFaces(); ++f) {
        vtkCell* face = cell->GetFace(f);
        const int m = static_cast<int>(face->GetNumberOfPoints());
        for (int k = 0; k + 2 < m + (m == 4 ? 1 : 0); k += 2) {
          double a[3], bb[3], cc[3];
          face->GetPoints()->GetPoint(k % m, a);
          face->GetPoints()->GetPoint((k + 1) % m, bb);
          face->GetPoints()->GetPoint((k + 2) % m, cc);
          const Vec3 p = mtree::closestPointOnTriangle(Vec3(x), Vec3(a), Vec3(bb), Vec3(cc));
          best = std::min(best, (p.x - x[0]) * (p.x - x[0]) + (p.y - x[1]) * (p.y - x[1]) + (p.z - x[2]) * (p.z - x[2]));
        }
      }
      EXPECT_NEAR(e.dist2, best, 1e-12 * (1 + best)) << "type " << type;
    }
  }
}

TEST(CellGeometry, UnsupportedTypesAreNamed) {
  EXPECT_FALSE(mtree::cellTypeSupported(VTK_QUADRATIC_TETRA, 10));
  EXPECT_FALSE(mtree::cellTypeSupported(VTK_POLYHEDRON, 12));
  EXPECT_FALSE(mtree::cellTypeSupported(VTK_TETRA, 5));
  EXPECT_TRUE(mtree::cellTypeSupported(VTK_POLYGON, 7));
  EXPECT_STREQ(mtree::cellTypeName(VTK_WEDGE), "VTK_WEDGE");
  EXPECT_STREQ(mtree::cellTypeName(VTK_QUADRATIC_TETRA), "cell type 24");
  EXPECT_EQ(mtree::cellDimension(VTK_QUADRATIC_TETRA), -1);
}

}  // namespace

// VTK 9.1's vtkTriangle::IntersectWithLine and vtkQuad::IntersectWithLine at tolerance 0,
// recomputed in plain arithmetic with VTK's operations in VTK's order, so that a hit's t, x and
// pcoords are VTK's bit for bit without a vtkCell, its vtkPoints and their virtual calls.
//
// The ray queries use it for the one face of a cell whose hit is already certain
// (vtkMatrixTreeCellBridge::CertainFaceHit), where VTK's own face test cost 12-28% of a ray on
// the volume grids, and for a surface's triangles (vtkMatrixTreeCellBridge::RecomputedTriangleHit). Only the
// main path is recomputed: the triangle's plane (its normal normalised as vtkTriangle::
// ComputeNormal does), the line's crossing of it (vtkPlane::IntersectWithLine: parallel when
// |den| <= 1e-6 |num|), the crossing projected back onto the plane and its two pcoords by
// Cramer's rule on the two coordinates where the normal is not largest (vtkTriangle::
// EvaluatePosition), inside when all three barycentrics lie in [0, 1]. Everything else that
// VTK treats on a path of its own answers kAskVtk: a degenerate triangle (zero normal or zero
// 2 x 2 determinant), a line parallel to the plane (9.1 then tests a coplanar segment), and a
// crossing outside the triangle by no more than round-off of the coordinates (VTK reports a hit
// there when the distance to its closest edge point rounds to exactly 0, which tol 0 accepts).
//
// vtkQuad (9.1) means to split along the shorter diagonal, but it measures both diagonals
// through vtkPoints::GetPoint pointers that share one tuple buffer, so both lengths come out 0;
// the tie goes to the point ids, which a quad built by vtkQuad's constructor has all 0: the
// split (0, 1, 2) + (2, 3, 0), whatever the quad's shape (segment_filter.h's kDiagonal02;
// test_segment_filter's long rectangles would catch a VTK that measured them). The triangles are tried in that order and
// the hit's (r, s) mapped back as vtkQuad maps them.
//
// No FMA may contract these products (the project builds without -march; a build with FMA
// contraction would differ in the last bits): tests/cpp/test_segment_filter compares every
// answer with the VTK it links.
#pragma once

#include <cmath>

namespace mtree {
namespace vtk91 {

enum class FaceHit : unsigned char { kMiss, kHit, kAskVtk };

/// t, x and pcoords as VTK's IntersectWithLine leaves them on a hit (pcoords[2] = 0; subId 0).
struct LineHit {
  double t = 0;
  double x[3] = {0, 0, 0};
  double pcoords[3] = {0, 0, 0};
};

/// vtkTriangle::IntersectWithLine(p1, p2, 0, ...) of the triangle whose VTK points are q0, q1, q2.
inline FaceHit triangleLineHit(const double q0[3], const double q1[3], const double q2[3], const double p1[3],
                               const double p2[3], LineHit& h) {
  // VTK names the points pt1 = point 1, pt2 = point 2, pt3 = point 0.
  const double* pt1 = q1;
  const double* pt2 = q2;
  const double* pt3 = q0;
  // vtkTriangle::ComputeNormalDirection(pt1, pt2, pt3): a = pt3 - pt2, b = pt1 - pt2, a x b.
  const double ax = pt3[0] - pt2[0], ay = pt3[1] - pt2[1], az = pt3[2] - pt2[2];
  const double bx = pt1[0] - pt2[0], by = pt1[1] - pt2[1], bz = pt1[2] - pt2[2];
  const double nd[3] = {ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx};
  // ComputeNormal: divided by its length where that is not 0.
  const double len = std::sqrt(nd[0] * nd[0] + nd[1] * nd[1] + nd[2] * nd[2]);
  if (!(len != 0.0) || !std::isfinite(len)) return FaceHit::kAskVtk;
  const double n[3] = {nd[0] / len, nd[1] / len, nd[2] / len};
  if (n[0] == 0.0 && n[1] == 0.0 && n[2] == 0.0) return FaceHit::kAskVtk;
  // vtkPlane::IntersectWithLine(p1, p2, n, pt1, t, x).
  const double p21[3] = {p2[0] - p1[0], p2[1] - p1[1], p2[2] - p1[2]};
  const double num = (n[0] * pt1[0] + n[1] * pt1[1] + n[2] * pt1[2]) - (n[0] * p1[0] + n[1] * p1[1] + n[2] * p1[2]);
  const double den = n[0] * p21[0] + n[1] * p21[1] + n[2] * p21[2];
  const double fabsden = den < 0.0 ? -den : den, fabsnum = num < 0.0 ? -num : num;
  if (!(fabsden > fabsnum * 1e-6)) return FaceHit::kAskVtk;  // parallel (or NaN): 9.1's coplanar path
  const double t = num / den;
  double x[3];
  for (int i = 0; i < 3; ++i) x[i] = p1[i] + t * p21[i];
  if (!(t >= 0.0 && t <= 1.0)) return std::isnan(t) ? FaceHit::kAskVtk : FaceHit::kMiss;
  // vtkTriangle::EvaluatePosition(x): the normal's direction again, x projected onto the plane
  // through pt1 (vtkPlane::GeneralizedProjectPoint).
  double cp[3];
  const double nn = nd[0] * nd[0] + nd[1] * nd[1] + nd[2] * nd[2];
  if (nn == 0.0) {
    for (int i = 0; i < 3; ++i) cp[i] = x[i];
  } else {
    const double s = (x[0] - pt1[0]) * nd[0] + (x[1] - pt1[1]) * nd[1] + (x[2] - pt1[2]) * nd[2];
    for (int i = 0; i < 3; ++i) cp[i] = x[i] - nd[i] * s / nn;
  }
  // The two coordinates other than the normal's largest (the first largest, from 0).
  double maxComponent = 0.0;
  int idx = 0;
  for (int i = 0; i < 3; ++i) {
    const double a = nd[i] < 0 ? -nd[i] : nd[i];
    if (a > maxComponent) {
      maxComponent = a;
      idx = i;
    }
  }
  const int i0 = idx == 0 ? 1 : 0, i1 = idx == 2 ? 1 : 2;
  const double rhs[2] = {cp[i0] - pt3[i0], cp[i1] - pt3[i1]};
  const double c1[2] = {pt1[i0] - pt3[i0], pt1[i1] - pt3[i1]};
  const double c2[2] = {pt2[i0] - pt3[i0], pt2[i1] - pt3[i1]};
  // vtkMath::Determinant2x2(a, b) = a[0] b[1] - b[0] a[1].
  const double det = c1[0] * c2[1] - c2[0] * c1[1];
  if (det == 0.0 || !std::isfinite(det)) return FaceHit::kAskVtk;
  const double r = (rhs[0] * c2[1] - c2[0] * rhs[1]) / det;
  const double s = (c1[0] * rhs[1] - rhs[0] * c1[1]) / det;
  const double w0 = 1 - (r + s);
  if (w0 >= 0.0 && w0 <= 1.0 && r >= 0.0 && r <= 1.0 && s >= 0.0 && s <= 1.0) {
    h.t = t;
    for (int i = 0; i < 3; ++i) h.x[i] = x[i];
    h.pcoords[0] = r;
    h.pcoords[1] = s;
    h.pcoords[2] = 0.0;
    return FaceHit::kHit;
  }
  // Outside. VTK still reports a hit when its closest point on the triangle equals x to the bit
  // (tol 0 accepts a distance of exactly 0): possible only within round-off of an edge. A miss is
  // certain when x lies off the triangle by more than 64 eps of the coordinates' magnitude: the
  // largest barycentric violation times the smallest height (2 area / longest edge).
  const double violation = std::fmax(std::fmax(std::fmax(-w0, w0 - 1), std::fmax(-r, r - 1)), std::fmax(-s, s - 1));
  const double cx = pt3[0] - pt1[0], cy = pt3[1] - pt1[1], cz = pt3[2] - pt1[2];
  const double longest2 =
      std::fmax(std::fmax(ax * ax + ay * ay + az * az, bx * bx + by * by + bz * bz), cx * cx + cy * cy + cz * cz);
  double mag = 0;
  for (int i = 0; i < 3; ++i)
    mag = std::fmax(mag, std::fmax(std::fmax(std::fabs(pt1[i]), std::fabs(pt2[i])), std::fmax(std::fabs(pt3[i]), std::fabs(x[i]))));
  const double off = violation * len / std::sqrt(longest2);  // NaN: not > below
  return off > 64 * 2.220446049250313e-16 * mag && mag > 1e-100 ? FaceHit::kMiss : FaceHit::kAskVtk;
}

/// vtkQuad::IntersectWithLine(p1, p2, 0, ...) of the quad with points q[0..3], its point ids the
/// constructor's (all 0).
inline FaceHit quadLineHit(const double q[4][3], const double p1[3], const double p2[3], LineHit& h) {
  const FaceHit first = triangleLineHit(q[0], q[1], q[2], p1, p2, h);
  if (first == FaceHit::kHit) {
    h.pcoords[0] = h.pcoords[0] + h.pcoords[1];
    return first;
  }
  if (first == FaceHit::kAskVtk) return first;
  const FaceHit second = triangleLineHit(q[2], q[3], q[0], p1, p2, h);
  if (second == FaceHit::kHit) {
    const double r = h.pcoords[0], s = h.pcoords[1];
    h.pcoords[0] = 1.0 - (r + s);
    h.pcoords[1] = 1.0 - s;
  }
  return second;
}

}  // namespace vtk91
}  // namespace mtree

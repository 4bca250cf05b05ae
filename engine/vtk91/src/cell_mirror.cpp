// VTK 9.1's EvaluatePosition and IntersectWithLine of the linear cell types (see cell_mirror.h).
// Each function is named after the VTK method it repeats and keeps its branches and its order of
// operations; vtkMath's helpers are repeated as VTK 9.1 writes them (vtkMath.h, vtkMath.cxx).
// The quadratic volume cells are in cell_mirror_quadratic.cpp.
#include "mtree/vtk91/cell_mirror.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "mtree/cells/cells.h"
#include "mtree/vtk91/cell_eval.h"
#include "mtree/vtk91/cell_faces.h"
#include "cell_mirror_detail.h"

namespace mtree {
namespace vtk91 {
namespace mirror {

// ---- vtkMath ----------------------------------------------------------------------------------

double determinant2x2(const double c1[2], const double c2[2]) { return c1[0] * c2[1] - c2[0] * c1[1]; }

double norm(const double v[3]) { return std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]); }

double normalize(double v[3]) {
  const double den = norm(v);
  if (den != 0.0)
    for (int i = 0; i < 3; ++i) v[i] /= den;
  return den;
}

void cross(const double a[3], const double b[3], double c[3]) {
  const double cx = a[1] * b[2] - a[2] * b[1];
  const double cy = a[2] * b[0] - a[0] * b[2];
  const double cz = a[0] * b[1] - a[1] * b[0];
  c[0] = cx;
  c[1] = cy;
  c[2] = cz;
}

/// vtkMath::SolveLinearSystemGEPP2x2.
bool solve2x2(double a00, double a01, double a10, double a11, double b0, double b1, double& x0, double& x1) {
  bool colsSwapped = false;
  if ((a00 == 0) || (a01 == 0) || (a10 == 0) || (a11 == 0)) {
    if ((a01 == 0) || (a11 == 0)) {
      std::swap(a00, a01);
      std::swap(a10, a11);
      colsSwapped = true;
    }
    if (a00 == 0) {
      std::swap(a00, a10);
      std::swap(a01, a11);
      std::swap(b0, b1);
    }
  } else {
    if (std::fabs(a00) < std::fabs(a10)) {
      std::swap(a00, a10);
      std::swap(a01, a11);
      std::swap(b0, b1);
    }
    const double f = -a10 / a00;
    a11 += a01 * f;
    b1 += b0 * f;
  }
  const double eps = 256 * std::numeric_limits<double>::epsilon();
  if (std::fabs(a11) < eps) return false;
  if (a11 != 0) x1 = b1 / a11;
  else return false;
  if (a00 != 0) x0 = (b0 - a01 * x1) / a00;
  else return false;
  if (!std::isfinite(x0) || !std::isfinite(x1)) return false;
  if (colsSwapped) std::swap(x0, x1);
  return true;
}

// ---- vtkPlane ---------------------------------------------------------------------------------

void projectPoint(const double x[3], const double origin[3], const double normal[3], double xproj[3]) {
  double xo[3];
  xo[0] = x[0] - origin[0];
  xo[1] = x[1] - origin[1];
  xo[2] = x[2] - origin[2];
  const double t = dot(normal, xo);
  xproj[0] = x[0] - t * normal[0];
  xproj[1] = x[1] - t * normal[1];
  xproj[2] = x[2] - t * normal[2];
}

void generalizedProjectPoint(const double x[3], const double origin[3], const double normal[3], double xproj[3]) {
  double xo[3];
  xo[0] = x[0] - origin[0];
  xo[1] = x[1] - origin[1];
  xo[2] = x[2] - origin[2];
  const double t = dot(normal, xo);
  const double n2 = dot(normal, normal);
  if (n2 != 0) {
    xproj[0] = x[0] - t * normal[0] / n2;
    xproj[1] = x[1] - t * normal[1] / n2;
    xproj[2] = x[2] - t * normal[2] / n2;
  } else {
    xproj[0] = x[0];
    xproj[1] = x[1];
    xproj[2] = x[2];
  }
}

int planeIntersectWithLine(const double p1[3], const double p2[3], const double n[3], const double p0[3], double& t,
                           double x[3]) {
  constexpr double kPlaneTol = 1.0e-06;
  double p21[3];
  p21[0] = p2[0] - p1[0];
  p21[1] = p2[1] - p1[1];
  p21[2] = p2[2] - p1[2];
  const double num = dot(n, p0) - (n[0] * p1[0] + n[1] * p1[1] + n[2] * p1[2]);
  const double den = n[0] * p21[0] + n[1] * p21[1] + n[2] * p21[2];
  const double fabsden = den < 0.0 ? -den : den;
  const double fabstolerance = num < 0.0 ? -num * kPlaneTol : num * kPlaneTol;
  if (fabsden <= fabstolerance) {
    t = kDoubleMax;
    return 0;
  }
  t = num / den;
  x[0] = p1[0] + t * p21[0];
  x[1] = p1[1] + t * p21[1];
  x[2] = p1[2] + t * p21[2];
  return t >= 0.0 && t <= 1.0 ? 1 : 0;
}

// ---- vtkLine ----------------------------------------------------------------------------------

double distanceToLine(const double x[3], const double p1[3], const double p2[3], double& t, double* closestPoint) {
  const double* closest = nullptr;
  double p21[3] = {p2[0] - p1[0], p2[1] - p1[1], p2[2] - p1[2]};
  const double num = p21[0] * (x[0] - p1[0]) + p21[1] * (x[1] - p1[1]) + p21[2] * (x[2] - p1[2]);
  if (num == 0.0) {
    t = 0;
    closest = p1;
  } else {
    const double denom = dot(p21, p21);
    double tolerance = kVtkTol * num;
    if (tolerance < 0.0) tolerance = -tolerance;
    if (denom < tolerance) {
      if (num > 0) {
        closest = p2;
        t = kDoubleMax;
      } else {
        closest = p1;
        t = kDoubleMin;
      }
    } else if ((t = num / denom) < 0.0) {
      closest = p1;
    } else if (t > 1.0) {
      closest = p2;
    } else {
      closest = p21;
      p21[0] = p1[0] + t * p21[0];
      p21[1] = p1[1] + t * p21[1];
      p21[2] = p1[2] + t * p21[2];
    }
  }
  if (closestPoint) {
    closestPoint[0] = closest[0];
    closestPoint[1] = closest[1];
    closestPoint[2] = closest[2];
  }
  return distance2(closest, x);
}

/// vtkLine::Intersection (tolerance and type as vtkLine::IntersectWithLine and PointInPolygon
/// call it: relative tolerance; an infinite tolerance skips the distance check).
int lineIntersection(const double a1[3], const double a2[3], const double b1[3], const double b2[3], double& u,
                     double& v, double tolerance) {
  double a21[3], b21[3], b1a1[3];
  u = v = 0.0;
  for (int i = 0; i < 3; ++i) {
    a21[i] = a2[i] - a1[i];
    b21[i] = b2[i] - b1[i];
    b1a1[i] = b1[i] - a1[i];
  }
  double row1[2], row2[2], c[2];
  row1[0] = dot(a21, a21);
  row1[1] = -dot(a21, b21);
  row2[0] = row1[1];
  row2[1] = dot(b21, b21);
  c[0] = dot(a21, b1a1);
  c[1] = -dot(b21, b1a1);
  if (!solve2x2(row1[0], row1[1], row2[0], row2[1], c[0], c[1], c[0], c[1])) {
    // Colinear: the closest approach is at one of the four end points.
    double minDist = kDoubleMax;
    const double* p[4] = {a1, a2, b1, b2};
    const double* l1[4] = {b1, b1, a1, a1};
    const double* l2[4] = {b2, b2, a2, a2};
    double* uv1[4] = {&v, &v, &u, &u};
    double* uv2[4] = {&u, &u, &v, &v};
    double t = 0;
    for (unsigned i = 0; i < 4; i++) {
      const double dist = distanceToLine(p[i], l1[i], l2[i], t, nullptr);
      if (dist < minDist) {
        minDist = dist;
        *(uv1[i]) = t;
        *(uv2[i]) = static_cast<double>(i % 2);
      }
    }
    return kOnLine;
  }
  u = c[0];
  v = c[1];
  double ptu[3] = {a21[0], a21[1], a21[2]};
  for (int i = 0; i < 3; ++i) ptu[i] *= u;
  for (int i = 0; i < 3; ++i) ptu[i] = ptu[i] + a1[i];
  double ptv[3] = {b21[0], b21[1], b21[2]};
  for (int i = 0; i < 3; ++i) ptv[i] *= v;
  for (int i = 0; i < 3; ++i) ptv[i] = ptv[i] + b1[i];
  double diff[3];
  for (int i = 0; i < 3; ++i) diff[i] = ptu[i] - ptv[i];
  const double diff2 = dot(diff, diff);
  double tol2 = 0.0;
  if (std::isfinite(tolerance)) {
    tol2 = tolerance * tolerance * std::max(dot(ptv, ptv), dot(ptu, ptu));
    if (diff2 > tol2) return kNoIntersect;
  }
  if ((0.0 <= u) && (u <= 1.0) && (0.0 <= v) && (v <= 1.0)) return kIntersect;
  return kNoIntersect;
}

int lineEvaluatePosition(const double* a1, const double* a2, const double x[3], double* closestPoint, int& subId,
                         double pcoords[3], double& dist2, double* weights) {
  subId = 0;
  pcoords[0] = pcoords[1] = pcoords[2] = 0.0;
  dist2 = distanceToLine(x, a1, a2, pcoords[0], closestPoint);
  weights[0] = 1.0 - pcoords[0];
  weights[1] = pcoords[0];
  return pcoords[0] < 0.0 || pcoords[0] > 1.0 ? 0 : 1;
}

int lineIntersectWithLine(const double* a1, const double* a2, const double p1[3], const double p2[3], double tol,
                          double& t, double x[3], double pcoords[3], int& subId) {
  double projXYZ[3];
  subId = 0;
  pcoords[1] = pcoords[2] = 0.0;
  if (lineIntersection(p1, p2, a1, a2, t, pcoords[0], std::numeric_limits<double>::infinity()) == kIntersect) {
    for (int i = 0; i < 3; i++) {
      x[i] = a1[i] + pcoords[0] * (a2[i] - a1[i]);
      projXYZ[i] = p1[i] + t * (p2[i] - p1[i]);
    }
    return distance2(x, projXYZ) <= tol * tol ? 1 : 0;
  }
  if (t < 0.0) {
    t = 0.0;
    return distanceToLine(p1, a1, a2, pcoords[0], x) <= tol * tol ? 1 : 0;
  }
  if (t > 1.0) {
    t = 1.0;
    return distanceToLine(p2, a1, a2, pcoords[0], x) <= tol * tol ? 1 : 0;
  }
  if (pcoords[0] < 0.0) {
    pcoords[0] = 0.0;
    return distanceToLine(a1, p1, p2, t, x) <= tol * tol ? 1 : 0;
  }
  if (pcoords[0] > 1.0) {
    pcoords[0] = 1.0;
    return distanceToLine(a2, p1, p2, t, x) <= tol * tol ? 1 : 0;
  }
  return 0;
}

// ---- vtkVertex, vtkPolyVertex, vtkPolyLine ------------------------------------------------------

int vertexEvaluatePosition(const double* X, const double x[3], double* closestPoint, int& subId, double pcoords[3],
                           double& dist2, double* weights) {
  subId = 0;
  pcoords[1] = pcoords[2] = 0.0;
  if (closestPoint) {
    closestPoint[0] = X[0];
    closestPoint[1] = X[1];
    closestPoint[2] = X[2];
  }
  dist2 = distance2(X, x);
  weights[0] = 1.0;
  if (dist2 == 0.0) {
    pcoords[0] = 0.0;
    return 1;
  }
  pcoords[0] = -1.0;
  return 0;
}

int vertexIntersectWithLine(const double* X, const double p1[3], const double p2[3], double tol, double& t,
                            double x[3], double pcoords[3], int& subId) {
  double ray[3], projXYZ[3];
  subId = 0;
  pcoords[1] = pcoords[2] = 0.0;
  for (int i = 0; i < 3; i++) ray[i] = p2[i] - p1[i];
  const double rayFactor = dot(ray, ray);
  if (rayFactor == 0.0) return 0;
  t = (ray[0] * (X[0] - p1[0]) + ray[1] * (X[1] - p1[1]) + ray[2] * (X[2] - p1[2])) / rayFactor;
  if (t >= 0.0 && t <= 1.0) {
    int i;
    for (i = 0; i < 3; i++) {
      projXYZ[i] = p1[i] + t * ray[i];
      if (std::fabs(X[i] - projXYZ[i]) > tol) break;
    }
    if (i > 2) {
      pcoords[0] = 0.0;
      x[0] = X[0];
      x[1] = X[1];
      x[2] = X[2];
      return 1;
    }
  }
  pcoords[0] = -1.0;
  return 0;
}

int polyVertexEvaluatePosition(const double* pts, int numPts, const double x[3], double* closestPoint, int& subId,
                               double pcoords[3], double& minDist2, double* weights) {
  pcoords[1] = pcoords[2] = -1.0;
  minDist2 = kDoubleMax;
  for (int i = 0; i < numPts; i++) {
    const double* X = pts + 3 * i;
    const double dist2 = distance2(X, x);
    if (dist2 < minDist2) {
      setClosest(closestPoint, X);
      minDist2 = dist2;
      subId = i;
    }
  }
  for (int i = 0; i < numPts; i++) weights[i] = 0.0;
  weights[subId] = 1.0;
  if (minDist2 == 0.0) {
    pcoords[0] = 0.0;
    return 1;
  }
  pcoords[0] = -1.0;
  return 0;
}

int polyLineEvaluatePosition(const double* pts, int numPts, const double x[3], double* closestPoint, int& subId,
                             double pcoords[3], double& minDist2, double* weights) {
  double closest[3], pc[3], dist2, lineWeights[2], closestWeights[2] = {0.0, 0.0};
  int ignoreId;
  pcoords[1] = pcoords[2] = 0.0;
  int returnStatus = 0;
  subId = -1;
  minDist2 = kDoubleMax;
  for (int i = 0; i < numPts - 1; i++) {
    const int status =
        lineEvaluatePosition(pts + 3 * i, pts + 3 * (i + 1), x, closest, ignoreId, pc, dist2, lineWeights);
    if (status != -1 && dist2 < minDist2) {
      returnStatus = status;
      setClosest(closestPoint, closest);
      minDist2 = dist2;
      subId = i;
      pcoords[0] = pc[0];
      closestWeights[0] = lineWeights[0];
      closestWeights[1] = lineWeights[1];
    }
  }
  std::fill_n(weights, numPts, 0.0);
  if (subId >= 0) {
    weights[subId] = closestWeights[0];
    weights[subId + 1] = closestWeights[1];
  }
  return returnStatus;
}

// ---- vtkTriangle ------------------------------------------------------------------------------

void triangleComputeNormalDirection(const double v1[3], const double v2[3], const double v3[3], double n[3]) {
  const double ax = v3[0] - v2[0], ay = v3[1] - v2[1], az = v3[2] - v2[2];
  const double bx = v1[0] - v2[0], by = v1[1] - v2[1], bz = v1[2] - v2[2];
  n[0] = (ay * bz - az * by);
  n[1] = (az * bx - ax * bz);
  n[2] = (ax * by - ay * bx);
}

void triangleComputeNormal(const double v1[3], const double v2[3], const double v3[3], double n[3]) {
  triangleComputeNormalDirection(v1, v2, v3, n);
  const double length = std::sqrt((n[0] * n[0] + n[1] * n[1] + n[2] * n[2]));
  if (length != 0.0) {
    n[0] /= length;
    n[1] /= length;
    n[2] /= length;
  }
}

int triangleEvaluatePosition(const double* q0, const double* q1, const double* q2, const double x[3],
                             double* closestPoint, int& subId, double pcoords[3], double& dist2, double* weights) {
  double n[3], cp[3], rhs[2], c1[2], c2[2];
  double closestPoint1[3], closestPoint2[3];
  subId = 0;
  pcoords[2] = 0.0;
  // VTK's pt1, pt2, pt3 are points 1, 2, 0.
  const double* pt1 = q1;
  const double* pt2 = q2;
  const double* pt3 = q0;
  triangleComputeNormalDirection(pt1, pt2, pt3, n);
  generalizedProjectPoint(x, pt1, n, cp);
  double maxComponent = 0.0;
  int idx = 0, indices[2];
  for (int i = 0; i < 3; i++) {
    const double fabsn = n[i] < 0 ? -n[i] : n[i];
    if (fabsn > maxComponent) {
      maxComponent = fabsn;
      idx = i;
    }
  }
  for (int j = 0, i = 0; i < 3; i++)
    if (i != idx) indices[j++] = i;
  for (int i = 0; i < 2; i++) {
    rhs[i] = cp[indices[i]] - pt3[indices[i]];
    c1[i] = pt1[indices[i]] - pt3[indices[i]];
    c2[i] = pt2[indices[i]] - pt3[indices[i]];
  }
  const double det = determinant2x2(c1, c2);
  if (det == 0.0) {
    pcoords[0] = pcoords[1] = 0.0;
    return -1;
  }
  pcoords[0] = determinant2x2(rhs, c2) / det;
  pcoords[1] = determinant2x2(c1, rhs) / det;
  weights[0] = 1 - (pcoords[0] + pcoords[1]);
  weights[1] = pcoords[0];
  weights[2] = pcoords[1];
  if (weights[0] >= 0.0 && weights[0] <= 1.0 && weights[1] >= 0.0 && weights[1] <= 1.0 && weights[2] >= 0.0 &&
      weights[2] <= 1.0) {
    closestIsProjection(cp, x, closestPoint, dist2);
    return 1;
  }
  if (!closestPoint) return 0;
  double t;
  // The vertex region between two negative weights: that vertex or its two edges.
  auto corner = [&](const double* vertex, const double* a1, const double* a2, const double* b1, const double* b2) {
    const double dist2Point = distance2(x, vertex);
    const double dist2Line1 = distanceToLine(x, a1, a2, t, closestPoint1);
    const double dist2Line2 = distanceToLine(x, b1, b2, t, closestPoint2);
    const double* closest;
    if (dist2Point < dist2Line1) {
      dist2 = dist2Point;
      closest = vertex;
    } else {
      dist2 = dist2Line1;
      closest = closestPoint1;
    }
    if (dist2Line2 < dist2) {
      dist2 = dist2Line2;
      closest = closestPoint2;
    }
    for (int i = 0; i < 3; i++) closestPoint[i] = closest[i];
  };
  if (weights[1] < 0.0 && weights[2] < 0.0) {
    corner(pt3, pt1, pt3, pt3, pt2);
  } else if (weights[2] < 0.0 && weights[0] < 0.0) {
    corner(pt1, pt1, pt3, pt1, pt2);
  } else if (weights[1] < 0.0 && weights[0] < 0.0) {
    corner(pt2, pt2, pt3, pt1, pt2);
  } else if (weights[0] < 0.0) {
    dist2 = distanceToLine(x, pt1, pt2, t, closestPoint);
  } else if (weights[1] < 0.0) {
    dist2 = distanceToLine(x, pt2, pt3, t, closestPoint);
  } else if (weights[2] < 0.0) {
    dist2 = distanceToLine(x, pt1, pt3, t, closestPoint);
  }
  return 0;
}

int triangleIntersectWithLine(const double* q0, const double* q1, const double* q2, const double p1[3],
                              const double p2[3], double tol, double& t, double x[3], double pcoords[3], int& subId) {
  double n[3] = {0., 0., 0.};
  double closestPoint[3] = {0., 0., 0.};
  double weights[3] = {0., 0., 0.};
  double dist2{};
  const double tol2 = tol * tol;
  subId = 0;
  pcoords[2] = 0.0;
  const double* pt1 = q1;
  const double* pt2 = q2;
  const double* pt3 = q0;
  triangleComputeNormal(pt1, pt2, pt3, n);
  if (n[0] != 0 || n[1] != 0 || n[2] != 0) {
    if (!planeIntersectWithLine(p1, p2, n, pt1, t, x)) {
      if (t != kDoubleMax || (dot(n, pt1) - dot(n, p1)) != 0.0) {
        pcoords[0] = pcoords[1] = 0.0;
        return 0;
      }
      // The line lies in the triangle's plane: the point closest to p1.
      if (triangleEvaluatePosition(q0, q1, q2, p1, closestPoint, subId, pcoords, dist2, weights) == 1) {
        t = 0.0;
        x[0] = p1[0];
        x[1] = p1[1];
        x[2] = p1[2];
        return 1;
      }
      bool intersection = false;
      double closestDistance = kDoubleMax;
      double closestX[3] = {0., 0., 0.};
      double closestPCoords[3] = {0., 0., 0.};
      const double* q[3] = {q0, q1, q2};
      for (int i = 0; i < 3; i++) {
        // vtkTriangle::GetEdge(i): points i and i + 1 (mod 3).
        if (lineIntersectWithLine(q[i], q[i > 1 ? 0 : i + 1], p1, p2, tol, t, x, pcoords, subId) != 0) {
          intersection = true;
          if (t < closestDistance) {
            closestDistance = t;
            triangleEvaluatePosition(q0, q1, q2, x, closestPoint, subId, pcoords, dist2, weights);
            for (int j = 0; j < 3; j++) {
              closestX[j] = x[j];
              closestPCoords[j] = pcoords[j];
            }
          }
        }
      }
      if (!intersection) {
        pcoords[0] = pcoords[1] = 0.0;
        return 0;
      }
      t = closestDistance;
      for (int i = 0; i < 3; i++) {
        x[i] = closestX[i];
        pcoords[i] = closestPCoords[i];
      }
      return 1;
    }
    const int inside = triangleEvaluatePosition(q0, q1, q2, x, closestPoint, subId, pcoords, dist2, weights);
    if (inside >= 0) {
      if (dist2 <= tol2) return 1;
      return inside;
    }
  }
  // A degenerate triangle (or one VTK cannot evaluate): its longest edge.
  const double dist2Pt1Pt2 = distance2(pt1, pt2);
  const double dist2Pt2Pt3 = distance2(pt2, pt3);
  const double dist2Pt3Pt1 = distance2(pt3, pt1);
  const double *a, *b;
  if (dist2Pt1Pt2 > dist2Pt2Pt3 && dist2Pt1Pt2 > dist2Pt3Pt1) {
    a = pt1;
    b = pt2;
  } else if (dist2Pt2Pt3 > dist2Pt3Pt1 && dist2Pt2Pt3 > dist2Pt1Pt2) {
    a = pt2;
    b = pt3;
  } else {
    a = pt3;
    b = pt1;
  }
  if (lineIntersectWithLine(a, b, p1, p2, tol, t, x, pcoords, subId)) {
    double pt3Pt1[3], pt3Pt2[3], pt3X[3];
    for (int i = 0; i < 3; i++) {
      pt3Pt1[i] = pt1[i] - pt3[i];
      pt3Pt2[i] = pt2[i] - pt3[i];
      pt3X[i] = x[i] - pt3[i];
    }
    pcoords[0] = dot(pt3X, pt3Pt1) / dist2Pt3Pt1;
    pcoords[1] = dot(pt3X, pt3Pt2) / dist2Pt2Pt3;
    return 1;
  }
  pcoords[0] = pcoords[1] = 0.0;
  return 0;
}

int triangleStripEvaluatePosition(const double* pts, int numPts, const double x[3], double* closestPoint, int& subId,
                                  double pcoords[3], double& minDist2, double* weights) {
  double pc[3], dist2, tempWeights[3], activeWeights[3] = {0.0, 0.0, 0.0}, closest[3];
  int ignoreId;
  pcoords[2] = 0.0;
  int returnStatus = 0;
  minDist2 = kDoubleMax;
  int i;
  for (i = 0; i < numPts - 2; i++) {
    weights[i] = 0.0;
    const int status = triangleEvaluatePosition(pts + 3 * i, pts + 3 * (i + 1), pts + 3 * (i + 2), x, closest,
                                                ignoreId, pc, dist2, tempWeights);
    if (status != -1 && dist2 < minDist2) {
      returnStatus = status;
      setClosest(closestPoint, closest);
      subId = i;
      pcoords[0] = pc[0];
      pcoords[1] = pc[1];
      minDist2 = dist2;
      activeWeights[0] = tempWeights[0];
      activeWeights[1] = tempWeights[1];
      activeWeights[2] = tempWeights[2];
    }
  }
  weights[i] = 0.0;
  weights[i + 1] = 0.0;
  // VTK leaves subId unset when no triangle could be evaluated; the first one then.
  if (subId < 0 || subId > numPts - 3) subId = 0;
  weights[subId] = activeWeights[0];
  weights[subId + 1] = activeWeights[1];
  weights[subId + 2] = activeWeights[2];
  return returnStatus;
}

// ---- vtkQuad, vtkPixel ------------------------------------------------------------------------

void quadInterpolationFunctions(const double pcoords[3], double sf[4]) {
  const double rm = 1. - pcoords[0], sm = 1. - pcoords[1];
  sf[0] = rm * sm;
  sf[1] = pcoords[0] * sm;
  sf[2] = pcoords[0] * pcoords[1];
  sf[3] = rm * pcoords[1];
}

void quadInterpolationDerivs(const double pcoords[3], double derivs[8]) {
  const double rm = 1. - pcoords[0], sm = 1. - pcoords[1];
  derivs[0] = -sm;
  derivs[1] = sm;
  derivs[2] = pcoords[1];
  derivs[3] = -pcoords[1];
  derivs[4] = -rm;
  derivs[5] = -pcoords[0];
  derivs[6] = pcoords[0];
  derivs[7] = rm;
}

int quadEvaluatePosition(const double* pts, const double x[3], double* closestPoint, int& subId, double pcoords[3],
                         double& dist2, double* weights) {
  constexpr int kMaxIteration = 20;
  constexpr double kConverged = 1.e-04;
  double n[3], params[2], fcol[2], rcol[2], scol[2], cp[3], derivs[8];
  subId = 0;
  pcoords[0] = pcoords[1] = params[0] = params[1] = 0.5;
  pcoords[2] = 0.0;
  const double* pt1 = pts;
  const double* pt2 = pts + 3;
  const double* pt3 = pts + 6;
  triangleComputeNormal(pt1, pt2, pt3, n);
  if (n[0] == 0.0 && n[1] == 0.0 && n[2] == 0.0) triangleComputeNormal(pt2, pt3, pts + 9, n);
  projectPoint(x, pt1, n, cp);
  double maxComponent = 0.0;
  int idx = 0, indices[2];
  for (int i = 0; i < 3; i++) {
    if (std::fabs(n[i]) > maxComponent) {
      maxComponent = std::fabs(n[i]);
      idx = i;
    }
  }
  for (int j = 0, i = 0; i < 3; i++)
    if (i != idx) indices[j++] = i;
  bool converged = false;
  for (int iteration = 0; !converged && iteration < kMaxIteration; iteration++) {
    quadInterpolationFunctions(pcoords, weights);
    quadInterpolationDerivs(pcoords, derivs);
    for (int i = 0; i < 2; i++) fcol[i] = rcol[i] = scol[i] = 0.0;
    for (int i = 0; i < 4; i++) {
      const double* pt = pts + 3 * i;
      for (int j = 0; j < 2; j++) {
        fcol[j] += pt[indices[j]] * weights[i];
        rcol[j] += pt[indices[j]] * derivs[i];
        scol[j] += pt[indices[j]] * derivs[i + 4];
      }
    }
    for (int j = 0; j < 2; j++) fcol[j] -= cp[indices[j]];
    const double det = determinant2x2(rcol, scol);
    if (det == 0.0) return -1;
    pcoords[0] = params[0] - determinant2x2(fcol, scol) / det;
    pcoords[1] = params[1] - determinant2x2(rcol, fcol) / det;
    if ((std::fabs(pcoords[0] - params[0]) < kConverged) && (std::fabs(pcoords[1] - params[1]) < kConverged)) {
      converged = true;
    } else if ((std::fabs(pcoords[0]) > kDiverged) || (std::fabs(pcoords[1]) > kDiverged)) {
      return -1;
    } else {
      params[0] = pcoords[0];
      params[1] = pcoords[1];
    }
  }
  if (!converged) return -1;
  quadInterpolationFunctions(pcoords, weights);
  if (pcoords[0] >= -0.001 && pcoords[0] <= 1.001 && pcoords[1] >= -0.001 && pcoords[1] <= 1.001) {
    closestIsProjection(cp, x, closestPoint, dist2);
    return 1;
  }
  if (!closestPoint) return 0;
  double t;
  const double* pt4 = pts + 9;
  auto atPoint = [&](const double* p) {
    dist2 = distance2(x, p);
    for (int i = 0; i < 3; i++) closestPoint[i] = p[i];
  };
  if (pcoords[0] < 0.0 && pcoords[1] < 0.0) atPoint(pt1);
  else if (pcoords[0] > 1.0 && pcoords[1] < 0.0) atPoint(pt2);
  else if (pcoords[0] > 1.0 && pcoords[1] > 1.0) atPoint(pt3);
  else if (pcoords[0] < 0.0 && pcoords[1] > 1.0) atPoint(pt4);
  else if (pcoords[0] < 0.0) dist2 = distanceToLine(x, pt1, pt4, t, closestPoint);
  else if (pcoords[0] > 1.0) dist2 = distanceToLine(x, pt2, pt3, t, closestPoint);
  else if (pcoords[1] < 0.0) dist2 = distanceToLine(x, pt1, pt2, t, closestPoint);
  else if (pcoords[1] > 1.0) dist2 = distanceToLine(x, pt3, pt4, t, closestPoint);
  return 0;
}

int quadIntersectWithLine(const double* pts, const int64_t* ids, const double p1[3], const double p2[3], double tol,
                          double& t, double x[3], double pcoords[3], int& subId) {
  // VTK 9.1 measures both diagonals through vtkPoints::GetPoint pointers that share one tuple
  // buffer (face_hit.h): d1 == d2 always, and the point ids decide.
  subId = 0;
  int maxId = 0, maxIdx = 0;
  for (int i = 0; i < 4; i++) {
    const int id = ids ? static_cast<int>(ids[i]) : 0;  // VTK keeps the id in an int here
    if (id > maxId) {
      maxId = id;
      maxIdx = i;
    }
  }
  const double* P[4] = {pts, pts + 3, pts + 6, pts + 9};
  if (maxIdx == 0 || maxIdx == 2) {
    if (triangleIntersectWithLine(P[0], P[1], P[2], p1, p2, tol, t, x, pcoords, subId)) {
      pcoords[0] = pcoords[0] + pcoords[1];
      return 1;
    }
    if (triangleIntersectWithLine(P[2], P[3], P[0], p1, p2, tol, t, x, pcoords, subId)) {
      pcoords[0] = 1.0 - (pcoords[0] + pcoords[1]);
      pcoords[1] = 1.0 - pcoords[1];
      return 1;
    }
    return 0;
  }
  if (triangleIntersectWithLine(P[0], P[1], P[3], p1, p2, tol, t, x, pcoords, subId)) return 1;
  if (triangleIntersectWithLine(P[2], P[3], P[1], p1, p2, tol, t, x, pcoords, subId)) {
    pcoords[0] = 1.0 - pcoords[0];
    pcoords[1] = 1.0 - pcoords[1];
    return 1;
  }
  return 0;
}

int pixelEvaluatePosition(const double* pts, const double x[3], double* closestPoint, int& subId, double pcoords[3],
                          double& dist2, double* weights) {
  double p[3], p21[3], p31[3], cp[3], n[3];
  subId = 0;
  pcoords[2] = 0.0;
  const double* pt1 = pts;
  const double* pt2 = pts + 3;
  const double* pt3 = pts + 6;
  triangleComputeNormal(pt1, pt2, pt3, n);
  projectPoint(x, pt1, n, cp);
  for (int i = 0; i < 3; i++) {
    p21[i] = pt2[i] - pt1[i];
    p31[i] = pt3[i] - pt1[i];
    p[i] = x[i] - pt1[i];
  }
  double l21 = norm(p21), l31 = norm(p31);
  if (l21 == 0.0) l21 = 1.0;
  if (l31 == 0.0) l31 = 1.0;
  pcoords[0] = dot(p21, p) / (l21 * l21);
  pcoords[1] = dot(p31, p) / (l31 * l31);
  auto functions = [](const double pc[3], double sf[4]) {
    const double rm = 1. - pc[0], sm = 1. - pc[1];
    sf[0] = rm * sm;
    sf[1] = pc[0] * sm;
    sf[2] = rm * pc[1];
    sf[3] = pc[0] * pc[1];
  };
  functions(pcoords, weights);
  if (pcoords[0] >= 0.0 && pcoords[0] <= 1.0 && pcoords[1] >= 0.0 && pcoords[1] <= 1.0) {
    closestIsProjection(cp, x, closestPoint, dist2);
    return 1;
  }
  if (closestPoint) {
    double pc[3] = {0, 0, 0};
    for (int i = 0; i < 2; i++) pc[i] = pcoords[i] < 0.0 ? 0.0 : (pcoords[i] > 1.0 ? 1.0 : pcoords[i]);
    for (int i = 0; i < 3; i++)
      closestPoint[i] = pt1[i] + pc[0] * (pt2[i] - pt1[i]) + pc[1] * (pt3[i] - pt1[i]);
    dist2 = distance2(closestPoint, x);
  }
  return 0;
}

int pixelIntersectWithLine(const double* pts, const double p1[3], const double p2[3], double tol, double& t,
                           double x[3], double pcoords[3], int& subId) {
  double n[3], closestPoint[3], dist2, weights[4];
  const double tol2 = tol * tol;
  subId = 0;
  pcoords[0] = pcoords[1] = pcoords[2] = 0.0;
  const double* pt1 = pts;
  const double* pt4 = pts + 9;
  n[0] = n[1] = n[2] = 0.0;
  for (int i = 0; i < 3; i++) {
    if ((pt4[i] - pt1[i]) <= 0.0) {
      n[i] = 1.0;
      break;
    }
  }
  if (!planeIntersectWithLine(p1, p2, n, pt1, t, x)) return 0;
  if (pixelEvaluatePosition(pts, x, closestPoint, subId, pcoords, dist2, weights) && dist2 <= tol2) return 1;
  return 0;
}

// ---- vtkPolygon -------------------------------------------------------------------------------

void polygonComputeNormal(const double* pts, int numPts, double n[3]) {
  n[0] = n[1] = n[2] = 0.0;
  if (numPts < 3) return;
  if (numPts == 3) {
    triangleComputeNormal(pts, pts + 3, pts + 6, n);
    return;
  }
  const double *v0 = nullptr, *v1 = pts, *v2 = pts + 3;
  for (int i = 0; i < numPts; i++) {
    v0 = v1;
    v1 = v2;
    v2 = pts + 3 * ((i + 2) % numPts);
    const double ax = v2[0] - v1[0], ay = v2[1] - v1[1], az = v2[2] - v1[2];
    const double bx = v0[0] - v1[0], by = v0[1] - v1[1], bz = v0[2] - v1[2];
    n[0] += (ay * bz - az * by);
    n[1] += (az * bx - ax * bz);
    n[2] += (ax * by - ay * bx);
  }
  normalize(n);
}

/// vtkPolygon::ParameterizePolygon; false where VTK returns 0 (the outputs are then as VTK
/// leaves them).
bool polygonParameterize(const double* pts, int numPts, double* p0, double* p10, double& l10, double* p20,
                         double& l20, double* n) {
  if (numPts < 3) return false;
  polygonComputeNormal(pts, numPts, n);
  const double* x1 = pts;
  const double* x2 = pts + 3;
  for (int i = 0; i < 3; i++) {
    p0[i] = x1[i];
    p10[i] = x2[i] - x1[i];
  }
  cross(n, p10, p20);
  if ((l10 = dot(p10, p10)) == 0.0 || (l20 = dot(p20, p20)) == 0.0) return false;
  double sbounds[2] = {0.0, 0.0}, tbounds[2] = {0.0, 0.0}, p[3], p1[3], p2[3];
  for (int i = 1; i < numPts; i++) {
    const double* xi = pts + 3 * i;
    for (int j = 0; j < 3; j++) p[j] = xi[j] - p0[j];
    const double s = (p[0] * p10[0] + p[1] * p10[1] + p[2] * p10[2]) / l10;
    const double t = (p[0] * p20[0] + p[1] * p20[1] + p[2] * p20[2]) / l20;
    sbounds[0] = (s < sbounds[0] ? s : sbounds[0]);
    sbounds[1] = (s > sbounds[1] ? s : sbounds[1]);
    tbounds[0] = (t < tbounds[0] ? t : tbounds[0]);
    tbounds[1] = (t > tbounds[1] ? t : tbounds[1]);
  }
  for (int i = 0; i < 3; i++) {
    p1[i] = p0[i] + sbounds[1] * p10[i] + tbounds[0] * p20[i];
    p2[i] = p0[i] + sbounds[0] * p10[i] + tbounds[1] * p20[i];
    p0[i] = p0[i] + sbounds[0] * p10[i] + tbounds[0] * p20[i];
    p10[i] = p1[i] - p0[i];
    p20[i] = p2[i] - p0[i];
  }
  l10 = norm(p10);
  l20 = norm(p20);
  return true;
}

void polygonInterpolateFunctions(const double* pts, int numPts, const double x[3], double* weights) {
  double sum = 0.0;
  for (int i = 0; i < numPts; i++) {
    weights[i] = distance2(x, pts + 3 * i);
    if (weights[i] == 0.0) {
      for (int j = 0; j < numPts; j++) weights[j] = 0.0;
      weights[i] = 1.0;
      return;
    }
    weights[i] = 1.0 / weights[i];
    sum += weights[i];
  }
  for (int i = 0; i < numPts; i++) weights[i] /= sum;
}

/// vtkPolygon::PointInPolygon with VTK's bounds check, ray length and vote rule, its rays in a
/// fixed sequence of directions instead of vtkMath::Random's (see cell_mirror.h): 1 inside,
/// 0 outside, -1 for a normal with no non-zero component.
int polygonPointInPolygon(const double x[3], int numPts, const double* pts, const double bounds[6], const double* n) {
  constexpr int kMaxIter = 10, kVoteThreshold = 2;
  constexpr double kRayTol = 1.e-03;
  if (x[0] < bounds[0] || x[0] > bounds[1] || x[1] < bounds[2] || x[1] > bounds[3] || x[2] < bounds[4] ||
      x[2] > bounds[5])
    return 0;
  double ray[3], xray[3], u, v, mag = 1;
  for (int i = 0; i < 3; i++)
    ray[i] = (bounds[2 * i + 1] - bounds[2 * i]) * 1.1 + std::fabs((bounds[2 * i + 1] + bounds[2 * i]) / 2.0 - x[i]);
  const double rayMag = norm(ray);
  if (rayMag == 0.0) return 0;
  int maxComp, comps[2];
  if (std::fabs(n[0]) > std::fabs(n[1])) {
    if (std::fabs(n[0]) > std::fabs(n[2])) maxComp = 0, comps[0] = 1, comps[1] = 2;
    else maxComp = 2, comps[0] = 0, comps[1] = 1;
  } else {
    if (std::fabs(n[1]) > std::fabs(n[2])) maxComp = 1, comps[0] = 0, comps[1] = 2;
    else maxComp = 2, comps[0] = 0, comps[1] = 1;
  }
  if (n[maxComp] == 0.0) return -1;
  int deltaVotes = 0;
  // The fixed directions: angles of the golden-ratio sequence in the plane of comps.
  double angle = 0.5;
  for (int iterNumber = 1; iterNumber < kMaxIter && std::abs(deltaVotes) < kVoteThreshold; iterNumber++) {
    for (bool rayOK = false; !rayOK;) {
      angle += 2.399963229728653;
      ray[comps[0]] = rayMag * std::cos(angle);
      ray[comps[1]] = rayMag * std::sin(angle);
      ray[maxComp] = -(n[comps[0]] * ray[comps[0]] + n[comps[1]] * ray[comps[1]]) / n[maxComp];
      rayOK = (mag = norm(ray)) > rayMag * kVtkTol;
    }
    for (int i = 0; i < 3; i++) xray[i] = x[i] + (rayMag / mag) * ray[i];
    int numInts = 0;
    bool certain = true;
    for (int i = 0; i < numPts; i++) {
      const double* x1 = pts + 3 * i;
      const double* x2 = pts + 3 * ((i + 1) % numPts);
      const int status = lineIntersection(x, xray, x1, x2, u, v, 1e-6);
      if (status == kIntersect) {
        if ((kRayTol < u) && (u < 1.0 - kRayTol) && (kRayTol < v) && (v < 1.0 - kRayTol)) numInts++;
        else certain = false;
      } else if (status == kOnLine) {
        certain = false;
      }
    }
    if (certain) deltaVotes += numInts % 2 == 0 ? -1 : 1;
  }
  return deltaVotes < 0 ? 0 : 1;
}

int polygonEvaluatePosition(const double* pts, int numPts, const double x[3], double* closestPoint, int& subId,
                            double pcoords[3], double& minDist2, double* weights) {
  double p0[3], p10[3], l10 = 0, p20[3], l20 = 0, n[3], cp[3], ray[3];
  subId = 0;
  polygonParameterize(pts, numPts, p0, p10, l10, p20, l20, n);
  polygonInterpolateFunctions(pts, numPts, x, weights);
  projectPoint(x, p0, n, cp);
  for (int i = 0; i < 3; i++) ray[i] = cp[i] - p0[i];
  pcoords[0] = dot(ray, p10) / (l10 * l10);
  pcoords[1] = dot(ray, p20) / (l20 * l20);
  pcoords[2] = 0.0;
  double bounds[6] = {kDoubleMax, -kDoubleMax, kDoubleMax, -kDoubleMax, kDoubleMax, -kDoubleMax};
  for (int i = 0; i < numPts; i++)
    for (int a = 0; a < 3; a++) {
      bounds[2 * a] = std::min(bounds[2 * a], pts[3 * i + a]);
      bounds[2 * a + 1] = std::max(bounds[2 * a + 1], pts[3 * i + a]);
    }
  if (pcoords[0] >= 0.0 && pcoords[0] <= 1.0 && pcoords[1] >= 0.0 && pcoords[1] <= 1.0 &&
      polygonPointInPolygon(cp, numPts, pts, bounds, n) == 1) {
    closestIsProjection(cp, x, closestPoint, minDist2);
    return 1;
  }
  if (closestPoint) {
    double t, closest[3];
    minDist2 = kDoubleMax;
    for (int i = 0; i < numPts; i++) {
      const double dist2 = distanceToLine(x, pts + 3 * i, pts + 3 * ((i + 1) % numPts), t, closest);
      if (dist2 < minDist2) {
        setClosest(closestPoint, closest);
        minDist2 = dist2;
      }
    }
  }
  return 0;
}

int polygonIntersectWithLine(const double* pts, int npts, const double p1[3], const double p2[3], double tol,
                             double& t, double x[3], double pcoords[3], int& subId) {
  double n[3], closestPoint[3], dist2 = 0;
  const double tol2 = tol * tol;
  subId = 0;
  pcoords[0] = pcoords[1] = pcoords[2] = 0.0;
  const double* pt1 = pts + 3;
  polygonComputeNormal(pts, npts, n);
  if (!planeIntersectWithLine(p1, p2, n, pt1, t, x)) return 0;
  std::vector<double> weights(static_cast<size_t>(npts));
  if (polygonEvaluatePosition(pts, npts, x, closestPoint, subId, pcoords, dist2, weights.data()) >= 0 &&
      dist2 <= tol2)
    return 1;
  return 0;
}

// ---- vtkTetra, vtkVoxel -----------------------------------------------------------------------

int tetraEvaluatePosition(const double* pts, const double x[3], double* closestPoint, int& subId, double pcoords[3],
                          double& minDist2, double* weights) {
  double rhs[3], c1[3], c2[3], c3[3];
  subId = 0;
  pcoords[0] = pcoords[1] = pcoords[2] = 0.0;
  const double* pt1 = pts + 3;
  const double* pt2 = pts + 6;
  const double* pt3 = pts + 9;
  const double* pt4 = pts;
  for (int i = 0; i < 3; i++) {
    rhs[i] = x[i] - pt4[i];
    c1[i] = pt1[i] - pt4[i];
    c2[i] = pt2[i] - pt4[i];
    c3[i] = pt3[i] - pt4[i];
  }
  const double det = cell_eval::det3(c1, c2, c3);
  if (det == 0.0) return -1;
  pcoords[0] = cell_eval::det3(rhs, c2, c3) / det;
  pcoords[1] = cell_eval::det3(c1, rhs, c3) / det;
  pcoords[2] = cell_eval::det3(c1, c2, rhs) / det;
  const double p4 = 1.0 - pcoords[0] - pcoords[1] - pcoords[2];
  weights[0] = p4;
  weights[1] = pcoords[0];
  weights[2] = pcoords[1];
  weights[3] = pcoords[2];
  if (pcoords[0] >= -0.001 && pcoords[0] <= 1.001 && pcoords[1] >= -0.001 && pcoords[1] <= 1.001 &&
      pcoords[2] >= -0.001 && pcoords[2] <= 1.001 && p4 >= -0.001 && p4 <= 1.001) {
    closestIsX(x, closestPoint, minDist2);
    return 1;
  }
  if (closestPoint) {
    const CellTopology& topo = *cellTopology(kTetra);
    // VTK leaves dist2 unset for a face it cannot evaluate (-1) and compares it anyway: here
    // such a face never wins (only a degenerate tetrahedron has one).
    double dist2 = kDoubleMax, w[3], closest[3], pc[3];
    int sub;
    minDist2 = kDoubleMax;
    for (int i = 0; i < 4; i++) {
      const int* f = topo.face[i];
      triangleEvaluatePosition(pts + 3 * f[0], pts + 3 * f[1], pts + 3 * f[2], x, closest, sub, pc, dist2, w);
      if (dist2 < minDist2) {
        setClosest(closestPoint, closest);
        minDist2 = dist2;
      }
    }
  }
  return 0;
}

void voxelInterpolationFunctions(const double pcoords[3], double sf[8]) {
  const double r = pcoords[0], s = pcoords[1], t = pcoords[2];
  const double rm = 1. - r, sm = 1. - s, tm = 1. - t;
  sf[0] = rm * sm * tm;
  sf[1] = r * sm * tm;
  sf[2] = rm * s * tm;
  sf[3] = r * s * tm;
  sf[4] = rm * sm * t;
  sf[5] = r * sm * t;
  sf[6] = rm * s * t;
  sf[7] = r * s * t;
}

int voxelEvaluatePosition(const double* pts, const double x[3], double* closestPoint, int& subId, double pcoords[3],
                          double& dist2, double* weights) {
  subId = 0;
  const double* pt1 = pts;
  const double* pt2 = pts + 3;
  const double* pt3 = pts + 6;
  const double* pt4 = pts + 12;
  pcoords[0] = (x[0] - pt1[0]) / (pt2[0] - pt1[0]);
  pcoords[1] = (x[1] - pt1[1]) / (pt3[1] - pt1[1]);
  pcoords[2] = (x[2] - pt1[2]) / (pt4[2] - pt1[2]);
  if (pcoords[0] >= 0.0 && pcoords[0] <= 1.0 && pcoords[1] >= 0.0 && pcoords[1] <= 1.0 && pcoords[2] >= 0.0 &&
      pcoords[2] <= 1.0) {
    if (closestPoint) {
      closestPoint[0] = x[0];
      closestPoint[1] = x[1];
      closestPoint[2] = x[2];
    }
    dist2 = 0.0;
    voxelInterpolationFunctions(pcoords, weights);
    return 1;
  }
  if (closestPoint) {
    double pc[3];
    for (int i = 0; i < 3; i++) pc[i] = pcoords[i] < 0.0 ? 0.0 : (pcoords[i] > 1.0 ? 1.0 : pcoords[i]);
    for (int i = 0; i < 3; i++)
      closestPoint[i] = pt1[i] + pc[0] * (pt2[i] - pt1[i]) + pc[1] * (pt3[i] - pt1[i]) + pc[2] * (pt4[i] - pt1[i]);
    dist2 = distance2(closestPoint, x);
  }
  return 0;
}

/// vtkBox::IntersectBox (tolerance 0).
bool intersectBox(const double bounds[6], const double origin[3], const double dir[3], double coord[3], double& t) {
  enum { kRight = 0, kLeft = 1, kMiddle = 2 };
  bool inside = true;
  char quadrant[3];
  int whichPlane = 0;
  double maxT[3], candidatePlane[3] = {0, 0, 0};
  for (int i = 0; i < 3; i++) {
    if (origin[i] < bounds[2 * i]) {
      quadrant[i] = kLeft;
      candidatePlane[i] = bounds[2 * i];
      inside = false;
    } else if (origin[i] > bounds[2 * i + 1]) {
      quadrant[i] = kRight;
      candidatePlane[i] = bounds[2 * i + 1];
      inside = false;
    } else {
      quadrant[i] = kMiddle;
    }
  }
  if (inside) {
    coord[0] = origin[0];
    coord[1] = origin[1];
    coord[2] = origin[2];
    t = 0;
    return true;
  }
  for (int i = 0; i < 3; i++)
    maxT[i] = quadrant[i] != kMiddle && dir[i] != 0.0 ? (candidatePlane[i] - origin[i]) / dir[i] : -1.0;
  for (int i = 0; i < 3; i++)
    if (maxT[whichPlane] < maxT[i]) whichPlane = i;
  if (maxT[whichPlane] > 1.0 || maxT[whichPlane] < 0.0) return false;
  t = maxT[whichPlane];
  for (int i = 0; i < 3; i++) {
    if (whichPlane != i) {
      coord[i] = origin[i] + maxT[whichPlane] * dir[i];
      if ((coord[i] < bounds[2 * i] - 0.0) || (coord[i] > bounds[2 * i + 1] + 0.0)) return false;
    } else {
      coord[i] = candidatePlane[i];
    }
  }
  return true;
}

int voxelIntersectWithLine(const double* pts, const double p1[3], const double p2[3], double& t, double x[3],
                           double pcoords[3], int& subId) {
  double bounds[6], p21[3];
  subId = 0;
  const double* minPt = pts;
  const double* maxPt = pts + 21;
  for (int i = 0; i < 3; i++) {
    p21[i] = p2[i] - p1[i];
    bounds[2 * i] = minPt[i];
    bounds[2 * i + 1] = maxPt[i];
  }
  if (!intersectBox(bounds, p1, p21, x, t)) return 0;
  for (int i = 0; i < 3; i++) pcoords[i] = (x[i] - minPt[i]) / (maxPt[i] - minPt[i]);
  return 1;
}

// ---- vtkHexahedron, vtkWedge, vtkPyramid ------------------------------------------------------


int pyramidEvaluatePosition(const double* pts, const double x[3], double* closestPoint, int& subId,
                            double pcoords[3], double& dist2, double* weights) {
  subId = 0;
  if (pyramidAtApex<cell_eval::Pyramid>(pts, x, closestPoint, pcoords, dist2, weights)) return 1;
  const int r = isoparametricEvaluatePosition<PyramidNewton>(pts, x, closestPoint, subId, pcoords, dist2, weights);
  if (r == 1) dist2 = 0.0;  // vtkPyramid writes it with or without a closest point
  return r;
}

/// Face f of a volume cell tested as its IntersectWithLine tests it: a vtkTriangle or a
/// vtkQuad (constructor ids) with the face's points.
int faceTest(const double* pts, const CellTopology& topo, int f, const double p1[3], const double p2[3], double tol,
             double& t, double x[3], double pc[3], int& subId) {
  const int* v = topo.face[f];
  if (topo.faceSize[f] == 3)
    return triangleIntersectWithLine(pts + 3 * v[0], pts + 3 * v[1], pts + 3 * v[2], p1, p2, tol, t, x, pc, subId);
  double q[12];
  for (int k = 0; k < 4; ++k)
    for (int a = 0; a < 3; ++a) q[3 * k + a] = pts[3 * v[k] + a];
  return quadIntersectWithLine(q, nullptr, p1, p2, tol, t, x, pc, subId);
}

/// The cell's pcoords of a hit on face f at the face's pcoords pc (vtkTetra, vtkHexahedron,
/// vtkWedge: face_hit's mapping; vtkPyramid: its quad face only, the triangles go through
/// EvaluatePosition).
void facePcoords(uint8_t type, int f, const double pc[3], double pcoords[3]) {
  if (type == kPyramid) {
    pcoords[0] = pc[0];
    pcoords[1] = pc[1];
    pcoords[2] = 0.0;
    return;
  }
  faceHitPcoords(type, f, pc, pcoords);
}

/// vtkTetra, vtkHexahedron, vtkWedge and vtkPyramid::IntersectWithLine: every face in VTK's
/// order (a pyramid's four triangles before its base), the smallest t kept (the first of
/// equals), subId as the last face test leaves it. only >= 0: that face alone.
int volumeIntersectWithLine(uint8_t type, const double* pts, const double p1[3], const double p2[3], double tol,
                            double& t, double x[3], double pcoords[3], int& subId, int only = -1) {
  const CellTopology& topo = *cellTopology(type);
  int intersection = 0;
  double tTemp, pc[3], xTemp[3];
  t = kDoubleMax;
  const int nf = topo.numFaces;
  for (int k = 0; k < nf; ++k) {
    const int f = type == kPyramid ? (k + 1) % nf : k;
    if (only >= 0 && f != only) continue;
    if (!faceTest(pts, topo, f, p1, p2, tol, tTemp, xTemp, pc, subId)) continue;
    intersection = 1;
    if (tTemp < t) {
      t = tTemp;
      x[0] = xTemp[0];
      x[1] = xTemp[1];
      x[2] = xTemp[2];
      if (type == kPyramid && f != 0) {
        double dist2, weights[5];
        pyramidEvaluatePosition(pts, x, xTemp, subId, pcoords, dist2, weights);
      } else {
        facePcoords(type, f, pc, pcoords);
      }
    }
  }
  return intersection;
}

}  // namespace mirror

bool mirrorCovers(uint8_t type, int64_t n) {
  switch (type) {
    case kVertex: return n == 1;
    case kPolyVertex: return n >= 1;
    case kLine: return n == 2;
    case kPolyLine: return n >= 2;
    case kTriangle: return n == 3;
    case kTriangleStrip: return n >= 3;
    case kPolygon: return n >= 3;
    case kPixel:
    case kQuad:
    case kTetra: return n == 4;
    case kVoxel:
    case kHexahedron: return n == 8;
    case kWedge: return n == 6;
    case kPyramid: return n == 5;
    default: return mirror::quadraticCovers(type, n);
  }
}

int evaluatePosition(const MirrorCell& c, const double x[3], double* closest, int& subId, double pcoords[3],
                     double& dist2, double* weights) {
  using namespace mirror;
  const double* p = c.pts;
  switch (c.type) {
    case kVertex: return vertexEvaluatePosition(p, x, closest, subId, pcoords, dist2, weights);
    case kPolyVertex: return polyVertexEvaluatePosition(p, c.n, x, closest, subId, pcoords, dist2, weights);
    case kLine: return lineEvaluatePosition(p, p + 3, x, closest, subId, pcoords, dist2, weights);
    case kPolyLine: return polyLineEvaluatePosition(p, c.n, x, closest, subId, pcoords, dist2, weights);
    case kTriangle: return triangleEvaluatePosition(p, p + 3, p + 6, x, closest, subId, pcoords, dist2, weights);
    case kTriangleStrip: return triangleStripEvaluatePosition(p, c.n, x, closest, subId, pcoords, dist2, weights);
    case kPolygon: return polygonEvaluatePosition(p, c.n, x, closest, subId, pcoords, dist2, weights);
    case kPixel: return pixelEvaluatePosition(p, x, closest, subId, pcoords, dist2, weights);
    case kQuad: return quadEvaluatePosition(p, x, closest, subId, pcoords, dist2, weights);
    case kTetra: return tetraEvaluatePosition(p, x, closest, subId, pcoords, dist2, weights);
    case kVoxel: return voxelEvaluatePosition(p, x, closest, subId, pcoords, dist2, weights);
    case kHexahedron:
      return isoparametricEvaluatePosition<HexahedronNewton>(p, x, closest, subId, pcoords, dist2, weights);
    case kWedge: return isoparametricEvaluatePosition<WedgeNewton>(p, x, closest, subId, pcoords, dist2, weights);
    case kPyramid: return pyramidEvaluatePosition(p, x, closest, subId, pcoords, dist2, weights);
    default: return quadraticEvaluatePosition(c.type, p, x, closest, subId, pcoords, dist2, weights);
  }
}

int intersectWithLine(const MirrorCell& c, const double p1[3], const double p2[3], double tol, double& t, double x[3],
                      double pcoords[3], int& subId) {
  using namespace mirror;
  const double* p = c.pts;
  switch (c.type) {
    case kVertex: return vertexIntersectWithLine(p, p1, p2, tol, t, x, pcoords, subId);
    case kPolyVertex:
      for (subId = 0; subId < c.n; subId++) {
        int subTest;
        if (vertexIntersectWithLine(p + 3 * subId, p1, p2, tol, t, x, pcoords, subTest)) return 1;
      }
      return 0;
    case kLine: return lineIntersectWithLine(p, p + 3, p1, p2, tol, t, x, pcoords, subId);
    case kPolyLine:
      for (subId = 0; subId < c.n - 1; subId++) {
        int subTest;
        if (lineIntersectWithLine(p + 3 * subId, p + 3 * (subId + 1), p1, p2, tol, t, x, pcoords, subTest)) return 1;
      }
      return 0;
    case kTriangle: return triangleIntersectWithLine(p, p + 3, p + 6, p1, p2, tol, t, x, pcoords, subId);
    case kTriangleStrip:
      for (subId = 0; subId < c.n - 2; subId++) {
        int subTest;
        if (triangleIntersectWithLine(p + 3 * subId, p + 3 * (subId + 1), p + 3 * (subId + 2), p1, p2, tol, t, x,
                                      pcoords, subTest))
          return 1;
      }
      return 0;
    case kPolygon: return polygonIntersectWithLine(p, c.n, p1, p2, tol, t, x, pcoords, subId);
    case kPixel: return pixelIntersectWithLine(p, p1, p2, tol, t, x, pcoords, subId);
    case kQuad: return quadIntersectWithLine(p, c.ids, p1, p2, tol, t, x, pcoords, subId);
    case kVoxel: return voxelIntersectWithLine(p, p1, p2, t, x, pcoords, subId);
    case kTetra:
    case kHexahedron:
    case kWedge:
    case kPyramid: return volumeIntersectWithLine(c.type, p, p1, p2, tol, t, x, pcoords, subId);
    default: return quadraticIntersectWithLine(c.type, p, p1, p2, tol, t, x, pcoords, subId);
  }
}

int intersectFace(const MirrorCell& c, int face, const double p1[3], const double p2[3], double tol, double& t,
                  double x[3], double pcoords[3], int& subId) {
  return mirror::volumeIntersectWithLine(c.type, c.pts, p1, p2, tol, t, x, pcoords, subId, face);
}

}  // namespace vtk91
}  // namespace mtree

#include "mtree/vtk91/cell_geometry.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "mtree/vtk91/cell_eval.h"
#include "mtree/cells/cells.h"

namespace mtree {

namespace {
// VTK 9.1's point-in-cell arithmetic (mtree/vtk91/cell_eval.h) decides the linear volume cells.
using namespace vtk91;

constexpr double kInf = std::numeric_limits<double>::infinity();
/// vtkQuad, vtkTetra, vtkWedge and vtkPyramid accept parametric coordinates this far outside
/// [0, 1].
constexpr double kParamTol = 1e-3;

inline Vec3 pointAt(const double* pts, int i) { return Vec3(pts + 3 * i); }
inline double dist2(Vec3 a, Vec3 b) {
  const Vec3 d = a - b;
  return dot(d, d);
}
inline bool inUnit(double v, double tol) { return v >= -tol && v <= 1.0 + tol; }

/// The coordinate axis along which n is largest: the one dropped to solve in the plane.
inline int dominantAxis(Vec3 n) {
  const double ax = std::fabs(n.x), ay = std::fabs(n.y), az = std::fabs(n.z);
  return ax >= ay && ax >= az ? 0 : (ay >= az ? 1 : 2);
}

/// The projection of x onto the plane through o with normal n (n not zero).
inline Vec3 projectToPlane(Vec3 x, Vec3 o, Vec3 n) { return x - n * (dot(x - o, n) / dot(n, n)); }

void setClosest(CellPoint& r, Vec3 x, Vec3 c) {
  r.closest = c;
  r.dist2 = dist2(x, c);
}

// ---- 0-D and 1-D cells ------------------------------------------------------------------------

CellPoint evaluateVertex(Vec3 p, Vec3 x, double* w) {
  CellPoint r;
  setClosest(r, x, p);
  r.status = r.dist2 == 0 ? 1 : 0;
  if (r.status == 1) w[0] = 1.0;
  return r;
}

CellPoint evaluateLine(Vec3 a, Vec3 b, Vec3 x, double* w) {
  CellPoint r;
  const Vec3 ab = b - a;
  const double l2 = dot(ab, ab);
  if (!(l2 > 0)) {
    r.status = -1;
    setClosest(r, x, a);
    return r;
  }
  const double t = dot(x - a, ab) / l2;
  r.pcoords[0] = t;
  if (t >= 0 && t <= 1) {
    r.status = 1;
    w[0] = 1.0 - t;
    w[1] = t;
    setClosest(r, x, a + ab * t);
  } else {
    setClosest(r, x, t < 0 ? a : b);
  }
  return r;
}

// ---- 2-D cells --------------------------------------------------------------------------------

/// vtkTriangle::EvaluatePosition: the projection's barycentrics, solved in the two coordinates
/// the normal is smallest along.
CellPoint evaluateTriangle(Vec3 a, Vec3 b, Vec3 c, Vec3 x, double* w, bool wantClosest) {
  CellPoint r;
  const Vec3 n = cross(b - a, c - a);
  const double nn = dot(n, n);
  double det = 0;
  Vec3 cp;
  int i0 = 0, i1 = 1;
  if (nn > 0 && std::isfinite(nn)) {
    cp = projectToPlane(x, a, n);
    const int drop = dominantAxis(n);
    i0 = drop == 0 ? 1 : 0;
    i1 = drop == 2 ? 1 : 2;
    det = (b[i0] - a[i0]) * (c[i1] - a[i1]) - (c[i0] - a[i0]) * (b[i1] - a[i1]);
  }
  if (!(det != 0) || !std::isfinite(det)) {
    r.status = -1;
    if (wantClosest) setClosest(r, x, closestPointOnTriangle(x, a, b, c));
    return r;
  }
  const double r0 = cp[i0] - a[i0], r1 = cp[i1] - a[i1];
  const double s = (r0 * (c[i1] - a[i1]) - (c[i0] - a[i0]) * r1) / det;
  const double t = ((b[i0] - a[i0]) * r1 - r0 * (b[i1] - a[i1])) / det;
  const double u = 1.0 - (s + t);
  r.pcoords[0] = s;
  r.pcoords[1] = t;
  if (inUnit(u, 0) && inUnit(s, 0) && inUnit(t, 0)) {
    r.status = 1;
    w[0] = u;
    w[1] = s;
    w[2] = t;
    setClosest(r, x, cp);
  } else if (wantClosest) {
    setClosest(r, x, closestPointOnTriangle(x, a, b, c));
  }
  return r;
}

/// The closest point to x on the quad's two triangles (0, 1, 2), (2, 3, 0).
Vec3 closestOnQuad(Vec3 x, const Vec3 q[4]) {
  const Vec3 c0 = closestPointOnTriangle(x, q[0], q[1], q[2]);
  const Vec3 c1 = closestPointOnTriangle(x, q[2], q[3], q[0]);
  return dist2(x, c0) <= dist2(x, c1) ? c0 : c1;
}

inline void quadFunctions(double r, double s, double w[4]) {
  w[0] = (1 - r) * (1 - s);
  w[1] = r * (1 - s);
  w[2] = r * s;
  w[3] = (1 - r) * s;
}

/// vtkQuad::EvaluatePosition: Newton on the projection onto the quad's plane, from (0.5, 0.5),
/// at most 20 steps, converged when both steps are below 1e-4; inside in [-0.001, 1.001].
CellPoint evaluateQuad(const Vec3 q[4], Vec3 x, double* w, bool wantClosest) {
  CellPoint r;
  Vec3 n = cross(q[1] - q[0], q[2] - q[0]);
  if (n.x == 0 && n.y == 0 && n.z == 0) n = cross(q[2] - q[1], q[3] - q[1]);
  const double nn = dot(n, n);
  bool converged = false;
  double pc[2] = {0.5, 0.5};
  Vec3 cp;
  if (nn > 0 && std::isfinite(nn)) {
    cp = projectToPlane(x, q[0], n);
    const int drop = dominantAxis(n);
    const int i0 = drop == 0 ? 1 : 0, i1 = drop == 2 ? 1 : 2;
    for (int it = 0; it < 20 && !converged; ++it) {
      double sf[4];
      quadFunctions(pc[0], pc[1], sf);
      const double dr[4] = {-(1 - pc[1]), 1 - pc[1], pc[1], -pc[1]};
      const double ds[4] = {-(1 - pc[0]), -pc[0], pc[0], 1 - pc[0]};
      double f[2] = {-cp[i0], -cp[i1]}, rc[2] = {0, 0}, sc[2] = {0, 0};
      for (int k = 0; k < 4; ++k) {
        const double p[2] = {q[k][i0], q[k][i1]};
        for (int j = 0; j < 2; ++j) {
          f[j] += p[j] * sf[k];
          rc[j] += p[j] * dr[k];
          sc[j] += p[j] * ds[k];
        }
      }
      const double det = rc[0] * sc[1] - sc[0] * rc[1];
      if (!(det != 0) || !std::isfinite(det)) break;
      const double nr = pc[0] - (f[0] * sc[1] - sc[0] * f[1]) / det;
      const double ns = pc[1] - (rc[0] * f[1] - f[0] * rc[1]) / det;
      converged = std::fabs(nr - pc[0]) < 1e-4 && std::fabs(ns - pc[1]) < 1e-4;
      pc[0] = nr;
      pc[1] = ns;
      if (!converged && (std::fabs(nr) > 1e6 || std::fabs(ns) > 1e6)) break;
    }
  }
  if (!converged) {
    r.status = -1;
    if (wantClosest) setClosest(r, x, closestOnQuad(x, q));
    return r;
  }
  r.pcoords[0] = pc[0];
  r.pcoords[1] = pc[1];
  if (inUnit(pc[0], kParamTol) && inUnit(pc[1], kParamTol)) {
    r.status = 1;
    quadFunctions(pc[0], pc[1], w);
    setClosest(r, x, cp);
  } else if (wantClosest) {
    setClosest(r, x, closestOnQuad(x, q));
  }
  return r;
}

/// vtkPixel::EvaluatePosition: an axis-aligned rectangle, points (0,0) (1,0) (0,1) (1,1).
CellPoint evaluatePixel(const double* pts, Vec3 x, double* w) {
  CellPoint r;
  const Vec3 p0 = pointAt(pts, 0), p3 = pointAt(pts, 3);
  int axes[2], m = 0, normal = -1;
  for (int a = 0; a < 3; ++a) {
    if (p3[a] != p0[a] && m < 2) axes[m++] = a;
    else normal = a;
  }
  if (m < 2 || normal < 0) {
    r.status = -1;
    const Vec3 q[4] = {p0, pointAt(pts, 1), p3, pointAt(pts, 2)};
    setClosest(r, x, closestOnQuad(x, q));
    return r;
  }
  double pc[2];
  for (int j = 0; j < 2; ++j) pc[j] = (x[axes[j]] - p0[axes[j]]) / (p3[axes[j]] - p0[axes[j]]);
  r.pcoords[0] = pc[0];
  r.pcoords[1] = pc[1];
  Vec3 c = x;
  c[normal] = p0[normal];
  r.status = inUnit(pc[0], 0) && inUnit(pc[1], 0) ? 1 : 0;
  if (r.status == 1) {
    w[0] = (1 - pc[0]) * (1 - pc[1]);
    w[1] = pc[0] * (1 - pc[1]);
    w[2] = (1 - pc[0]) * pc[1];
    w[3] = pc[0] * pc[1];
  } else {
    for (int j = 0; j < 2; ++j) c[axes[j]] = p0[axes[j]] + std::min(1.0, std::max(0.0, pc[j])) * (p3[axes[j]] - p0[axes[j]]);
  }
  setClosest(r, x, c);
  return r;
}

/// Newell's normal of a polygon (n points): exact for planar ones, a best fit otherwise.
Vec3 polygonNormal(const double* pts, int n) {
  Vec3 nrm;
  for (int i = 0; i < n; ++i) nrm = nrm + cross(pointAt(pts, i), pointAt(pts, (i + 1) % n));
  return nrm;
}

/// Whether the in-plane point p lies in the polygon (crossing number in the coordinates i0, i1).
bool pointInPolygon(const double* pts, int n, Vec3 p, int i0, int i1) {
  bool in = false;
  for (int i = 0, j = n - 1; i < n; j = i++) {
    const Vec3 a = pointAt(pts, i), b = pointAt(pts, j);
    if ((a[i1] > p[i1]) != (b[i1] > p[i1]) &&
        p[i0] < (b[i0] - a[i0]) * (p[i1] - a[i1]) / (b[i1] - a[i1]) + a[i0])
      in = !in;
  }
  return in;
}

/// vtkPolygon's interpolation (its default, UseMVCInterpolation off): weights 1 / |x - p_i|^2,
/// normalized; x on a point gets all of that point's weight.
void inverseDistanceWeights(const double* pts, int n, Vec3 x, double* w) {
  double sum = 0;
  for (int i = 0; i < n; ++i) {
    const double d2 = dist2(x, pointAt(pts, i));
    if (d2 == 0) {
      std::fill(w, w + n, 0.0);
      w[i] = 1.0;
      return;
    }
    w[i] = 1.0 / d2;
    sum += w[i];
  }
  for (int i = 0; i < n; ++i) w[i] /= sum;
}

/// The closest point to x on the polygon's boundary.
Vec3 closestOnPolygonEdges(const double* pts, int n, Vec3 x) {
  Vec3 best = pointAt(pts, 0);
  double bd = kInf, t;
  for (int i = 0; i < n; ++i) {
    const Vec3 c = closestPointOnSegment(x, pointAt(pts, i), pointAt(pts, (i + 1) % n), t);
    const double d = dist2(x, c);
    if (d < bd) {
      bd = d;
      best = c;
    }
  }
  return best;
}

/// vtkPolygon::EvaluatePosition: inside when the projection onto the plane (Newell's normal)
/// lies in the polygon; weights as vtkPolygon interpolates (inverseDistanceWeights, at x);
/// pcoords are not defined (0).
CellPoint evaluatePolygon(const double* pts, int n, Vec3 x, double* w, bool wantClosest) {
  CellPoint r;
  const Vec3 nrm = polygonNormal(pts, n);
  const double nn = dot(nrm, nrm);
  if (!(nn > 0) || !std::isfinite(nn)) {
    r.status = -1;
    if (wantClosest) setClosest(r, x, closestOnPolygonEdges(pts, n, x));
    return r;
  }
  const Vec3 cp = projectToPlane(x, pointAt(pts, 0), nrm);
  const int drop = dominantAxis(nrm);
  if (pointInPolygon(pts, n, cp, drop == 0 ? 1 : 0, drop == 2 ? 1 : 2)) {
    r.status = 1;
    inverseDistanceWeights(pts, n, x, w);
    setClosest(r, x, cp);
  } else if (wantClosest) {
    setClosest(r, x, closestOnPolygonEdges(pts, n, x));
  }
  return r;
}

// ---- composite cells: the best of their parts ------------------------------------------------

/// vtkPolyVertex, vtkPolyLine, vtkTriangleStrip: each part (a point, a segment, a triangle of
/// `partPoints` points starting at part index k) is evaluated; the one nearest x (the first of
/// equals) decides, and its weights go to its points.
template <class Part>
CellPoint evaluateParts(int numParts, int partPoints, int n, double* w, Part&& part) {
  CellPoint best;
  best.status = -1;
  best.dist2 = kInf;
  int bestPart = -1;
  double bw[3] = {0, 0, 0}, pw[3];
  for (int k = 0; k < numParts; ++k) {
    const CellPoint r = part(k, pw);
    if (r.status < 0 || !(r.dist2 < best.dist2)) continue;
    best = r;
    bestPart = k;
    std::copy(pw, pw + partPoints, bw);
  }
  if (bestPart < 0) return best;
  if (best.status == 1) {
    std::fill(w, w + n, 0.0);
    std::copy(bw, bw + partPoints, w + bestPart);
  }
  return best;
}

// ---- 3-D cells --------------------------------------------------------------------------------

/// Faces of a voxel (VTK's voxel point order: x fastest), each as a cycle around the face.
const CellTopology& voxelFaces() {
  static const CellTopology t = [] {
    CellTopology v;
    v.numPoints = 8;
    v.numFaces = 6;
    const int f[6][4] = {{0, 2, 6, 4}, {1, 5, 7, 3}, {0, 4, 5, 1}, {2, 3, 7, 6}, {0, 1, 3, 2}, {4, 6, 7, 5}};
    for (int i = 0; i < 6; ++i) {
      v.faceSize[i] = 4;
      for (int k = 0; k < 4; ++k) v.face[i][k] = f[i][k];
    }
    return v;
  }();
  return t;
}

const CellTopology* volumeFaces(uint8_t type) { return type == kVoxel ? &voxelFaces() : cellTopology(type); }

/// Calls f(a, b, c) for every triangle of the cell's boundary (quad faces split (0, 1, 2),
/// (2, 3, 0)); a true return stops.
template <class F>
void forEachBoundaryTriangle(uint8_t type, const double* pts, F&& f) {
  const CellTopology& topo = *volumeFaces(type);
  for (int i = 0; i < topo.numFaces; ++i) {
    const int* v = topo.face[i];
    f(pointAt(pts, v[0]), pointAt(pts, v[1]), pointAt(pts, v[2]));
    if (topo.faceSize[i] == 4) f(pointAt(pts, v[2]), pointAt(pts, v[3]), pointAt(pts, v[0]));
  }
}

/// The closest point to x on the boundary of a volume cell.
Vec3 closestOnBoundary(uint8_t type, const double* pts, Vec3 x) {
  Vec3 best = pointAt(pts, 0);
  double bd = kInf;
  forEachBoundaryTriangle(type, pts, [&](Vec3 a, Vec3 b, Vec3 c) {
    const Vec3 p = closestPointOnTriangle(x, a, b, c);
    const double d = dist2(x, p);
    if (d < bd) {
      bd = d;
      best = p;
    }
  });
  return best;
}

/// vtkTetra::EvaluatePosition (Cramer's rule from point 0), decided without margins.
int tetraPosition(const double* pts, const double x[3], double pc[3], double* w) {
  double rhs[3], c1[3], c2[3], c3[3];
  for (int i = 0; i < 3; ++i) {
    rhs[i] = x[i] - pts[i];
    c1[i] = pts[3 + i] - pts[i];
    c2[i] = pts[6 + i] - pts[i];
    c3[i] = pts[9 + i] - pts[i];
  }
  const double det = cell_eval::det3(c1, c2, c3);
  if (!(det != 0) || !std::isfinite(det)) return -1;
  pc[0] = cell_eval::det3(rhs, c2, c3) / det;
  pc[1] = cell_eval::det3(c1, rhs, c3) / det;
  pc[2] = cell_eval::det3(c1, c2, rhs) / det;
  const double p4 = 1.0 - pc[0] - pc[1] - pc[2];
  if (!(inUnit(pc[0], kParamTol) && inUnit(pc[1], kParamTol) && inUnit(pc[2], kParamTol) && inUnit(p4, kParamTol)))
    return 0;
  w[0] = p4;
  w[1] = pc[0];
  w[2] = pc[1];
  w[3] = pc[2];
  return 1;
}

/// vtkVoxel::EvaluatePosition: pcoords along the edges from point 0, inside in [0, 1].
int voxelPosition(const double* pts, const double x[3], double pc[3], double* w) {
  const double width[3] = {pts[3] - pts[0], pts[7] - pts[1], pts[14] - pts[2]};
  for (int a = 0; a < 3; ++a) {
    if (!(width[a] != 0)) return -1;
    pc[a] = (x[a] - pts[a]) / width[a];
  }
  if (!(inUnit(pc[0], 0) && inUnit(pc[1], 0) && inUnit(pc[2], 0))) return 0;
  const double rm = 1 - pc[0], sm = 1 - pc[1], tm = 1 - pc[2];
  const double v[8] = {rm * sm * tm, pc[0] * sm * tm, rm * pc[1] * tm, pc[0] * pc[1] * tm,
                       rm * sm * pc[2], pc[0] * sm * pc[2], rm * pc[1] * pc[2], pc[0] * pc[1] * pc[2]};
  std::copy(v, v + 8, w);
  return 1;
}

/// VTK's Newton inversion for the isoparametric cell S (cell_eval.h's shape functions and step),
/// decided without margins: at most 10 steps, -1 when the determinant falls below
/// min(1e-20, 1e-5 L^3), a coordinate passes 1e6 or the steps do not converge.
template <class S>
int newtonPosition(const double* pts, const double x[3], double pc[3], double* w) {
  double longest2 = 0;
  for (int i = 0; i < S::kNumScale; ++i)
    longest2 = std::max(longest2, cell_eval::dist2(pts + 3 * S::kScale[i][0], pts + 3 * S::kScale[i][1]));
  const double detTol = std::min(1e-20, 1e-5 * std::pow(longest2, 1.5));
  double params[3] = {S::kStart, S::kStart, S::kStart};
  bool converged = false;
  for (int it = 0; it < 10 && !converged; ++it) {
    double step[4];
    cell_eval::Sse2Step::run<S>(pts, x, params, step);
    const double det = step[0];
    if (!(std::fabs(det) >= detTol) || !std::isfinite(det)) return -1;
    double next[3];
    for (int i = 0; i < 3; ++i) next[i] = params[i] - step[1 + i] / det;
    converged = true;
    for (int i = 0; i < 3; ++i) converged = converged && std::fabs(next[i] - params[i]) < S::kConverged;
    for (int i = 0; i < 3; ++i) params[i] = next[i];
    if (!converged && (std::fabs(next[0]) > 1e6 || std::fabs(next[1]) > 1e6 || std::fabs(next[2]) > 1e6)) return -1;
  }
  std::copy(params, params + 3, pc);
  if (!converged) return -1;
  if (S::accept(pc, 0.0) != PointInCell::kInside) return 0;
  S::functions(pc, w);
  return 1;
}

/// vtkPyramid::EvaluatePosition: at the apex (within 1e-6 of the apex-base distance, squared)
/// pcoords are (0, 0, 1); elsewhere Newton.
int pyramidPosition(const double* pts, const double x[3], double pc[3], double* w) {
  const double* apex = pts + 12;
  double mid[3] = {0, 0, 0};
  for (int i = 0; i < 4; ++i)
    for (int a = 0; a < 3; ++a) mid[a] += pts[3 * i + a] / 4.0;
  const double d2 = cell_eval::dist2(apex, x), len2 = cell_eval::dist2(apex, mid);
  if (d2 == 0 || (len2 != 0 && d2 / len2 < 1e-6)) {
    pc[0] = pc[1] = 0;
    pc[2] = 1;
    cell_eval::Pyramid::functions(pc, w);
    return 1;
  }
  return newtonPosition<cell_eval::Pyramid>(pts, x, pc, w);
}

CellPoint evaluateVolumeCell(uint8_t type, const double* pts, int n, const double x[3], double* w,
                             bool wantClosest) {
  CellPoint r;
  // cell_eval.h first: VTK's own arithmetic, answered where rounding cannot change the verdict.
  const PointInCell fast = cellEvaluable(type, n) ? evaluateLinearCell(type, pts, x, r.pcoords, w)
                                                  : PointInCell::kAskVtk;
  if (fast != PointInCell::kAskVtk) {
    r.status = fast == PointInCell::kInside ? 1 : 0;
  } else {
    switch (type) {
      case kTetra: r.status = tetraPosition(pts, x, r.pcoords, w); break;
      case kVoxel: r.status = voxelPosition(pts, x, r.pcoords, w); break;
      case kHexahedron: r.status = newtonPosition<cell_eval::Hexahedron>(pts, x, r.pcoords, w); break;
      case kWedge: r.status = newtonPosition<cell_eval::Wedge>(pts, x, r.pcoords, w); break;
      default: r.status = pyramidPosition(pts, x, r.pcoords, w); break;
    }
  }
  const Vec3 xv(x);
  if (r.status == 1) setClosest(r, xv, xv);
  else if (wantClosest) setClosest(r, xv, closestOnBoundary(type, pts, xv));
  return r;
}

// ---- segments ---------------------------------------------------------------------------------

/// vtkTriangle::IntersectWithLine: the segment's crossing of the triangle's plane (none when it
/// runs parallel to it, VTK's relative epsilon), hit when inside or within tol of the triangle.
/// A degenerate triangle is its longest edge.
bool segmentTriangle(Vec3 p1, Vec3 p2, Vec3 a, Vec3 b, Vec3 c, double tol, double& t, Vec3& x);
bool segmentSegment(Vec3 p1, Vec3 p2, Vec3 a, Vec3 b, double tol, double& t, Vec3& x);

bool segmentTriangle(Vec3 p1, Vec3 p2, Vec3 a, Vec3 b, Vec3 c, double tol, double& t, Vec3& x) {
  const Vec3 n = normalized(cross(b - a, c - a));
  if (n.x == 0 && n.y == 0 && n.z == 0) {
    const double ab = dist2(a, b), bc = dist2(b, c), ca = dist2(c, a);
    if (ab >= bc && ab >= ca) return segmentSegment(p1, p2, a, b, tol, t, x);
    return bc >= ca ? segmentSegment(p1, p2, b, c, tol, t, x) : segmentSegment(p1, p2, c, a, tol, t, x);
  }
  const Vec3 d = p2 - p1;
  const double num = dot(n, a - p1), den = dot(n, d);
  if (!(std::fabs(den) > std::fabs(num) * std::numeric_limits<double>::epsilon())) return false;
  const double tt = num / den;
  if (!(tt >= 0 && tt <= 1)) return false;
  const Vec3 xx = p1 + d * tt;
  double w[3];
  const CellPoint r = evaluateTriangle(a, b, c, xx, w, tol > 0);
  if (r.status < 0 || !(r.status == 1 || r.dist2 <= tol * tol)) return false;
  t = tt;
  x = xx;
  return true;
}

/// vtkLine::IntersectWithLine: the closest approach of the segment and the line cell ab, a hit
/// when within tol; t along the segment, x on the cell.
bool segmentSegment(Vec3 p1, Vec3 p2, Vec3 a, Vec3 b, double tol, double& t, Vec3& x) {
  // Closest points of two segments (Ericson 5.1.9), clamped to both.
  const Vec3 d1 = p2 - p1, d2 = b - a, r = p1 - a;
  const double aa = dot(d1, d1), ee = dot(d2, d2), ff = dot(d2, r);
  double s = 0, u = 0;
  if (aa <= 0 && ee <= 0) {
    s = u = 0;
  } else if (aa <= 0) {
    u = std::min(1.0, std::max(0.0, ff / ee));
  } else {
    const double cc = dot(d1, r);
    if (ee <= 0) {
      s = std::min(1.0, std::max(0.0, -cc / aa));
    } else {
      const double bb = dot(d1, d2), denom = aa * ee - bb * bb;
      s = denom > 0 ? std::min(1.0, std::max(0.0, (bb * ff - cc * ee) / denom)) : 0.0;
      u = (bb * s + ff) / ee;
      if (u < 0) {
        u = 0;
        s = std::min(1.0, std::max(0.0, -cc / aa));
      } else if (u > 1) {
        u = 1;
        s = std::min(1.0, std::max(0.0, (bb - cc) / aa));
      }
    }
  }
  const Vec3 onSeg = p1 + d1 * s, onCell = a + d2 * u;
  if (!(dist2(onSeg, onCell) <= tol * tol)) return false;
  t = s;
  x = onCell;
  return true;
}

/// vtkVertex::IntersectWithLine: the point's projection onto the segment, a hit when within tol
/// of the point on every axis.
bool segmentVertex(Vec3 p1, Vec3 p2, Vec3 v, double tol, double& t, Vec3& x) {
  const Vec3 d = p2 - p1;
  const double l2 = dot(d, d);
  const double tt = l2 > 0 ? dot(v - p1, d) / l2 : 0.0;
  if (!(tt >= 0 && tt <= 1)) return false;
  const Vec3 q = p1 + d * tt;
  for (int a = 0; a < 3; ++a)
    if (!(std::fabs(q[a] - v[a]) <= tol)) return false;
  t = tt;
  x = v;
  return true;
}

/// vtkPolygon::IntersectWithLine: the crossing of the plane (Newell's normal through point 0),
/// a hit when its projection lies in the polygon or within tol of it.
bool segmentPolygon(const double* pts, int n, Vec3 p1, Vec3 p2, double tol, double& t, Vec3& x) {
  const Vec3 nrm = normalized(polygonNormal(pts, n));
  if (nrm.x == 0 && nrm.y == 0 && nrm.z == 0) return false;
  const Vec3 d = p2 - p1;
  const double num = dot(nrm, pointAt(pts, 0) - p1), den = dot(nrm, d);
  if (!(std::fabs(den) > std::fabs(num) * std::numeric_limits<double>::epsilon())) return false;
  const double tt = num / den;
  if (!(tt >= 0 && tt <= 1)) return false;
  const Vec3 xx = p1 + d * tt;
  std::vector<double> w(static_cast<size_t>(n));
  const CellPoint r = evaluatePolygon(pts, n, xx, w.data(), tol > 0);
  if (r.status < 0 || !(r.status == 1 || r.dist2 <= tol * tol)) return false;
  t = tt;
  x = xx;
  return true;
}

/// Keeps the smallest t among several parts' hits.
struct FirstHit {
  double t = kInf;
  Vec3 x;
  template <class F>
  void offer(F&& test) {
    double tt;
    Vec3 xx;
    if (test(tt, xx) && tt < t) {
      t = tt;
      x = xx;
    }
  }
  bool found(double& tOut, Vec3& xOut) const {
    if (!(t <= 1)) return false;
    tOut = t;
    xOut = x;
    return true;
  }
};

}  // namespace

Vec3 closestPointOnSegment(Vec3 x, Vec3 a, Vec3 b, double& t) {
  const Vec3 ab = b - a;
  const double l2 = dot(ab, ab);
  t = l2 > 0 ? std::min(1.0, std::max(0.0, dot(x - a, ab) / l2)) : 0.0;
  return a + ab * t;
}

Vec3 closestPointOnTriangle(Vec3 p, Vec3 a, Vec3 b, Vec3 c) {
  // Voronoi regions of the vertices, then the edges, then the face.
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = dot(ab, ap), d2 = dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const Vec3 bp = p - b;
  const double d3 = dot(ab, bp), d4 = dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + ab * (d1 / (d1 - d3));
  const Vec3 cp = p - c;
  const double d5 = dot(ab, cp), d6 = dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + ac * (d2 / (d2 - d6));
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
  const double denom = va + vb + vc;
  if (!(denom != 0) || !std::isfinite(denom)) {
    // Degenerate (collinear) triangle: its longest edge.
    double t;
    const Vec3 e0 = closestPointOnSegment(p, a, b, t), e1 = closestPointOnSegment(p, b, c, t),
               e2 = closestPointOnSegment(p, c, a, t);
    const double q0 = dist2(p, e0), q1 = dist2(p, e1), q2 = dist2(p, e2);
    return q0 <= q1 && q0 <= q2 ? e0 : (q1 <= q2 ? e1 : e2);
  }
  const double v = vb / denom, w = vc / denom;
  return a + ab * v + ac * w;
}

bool cellTypeSupported(uint8_t type, int64_t n) {
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
    default: return false;
  }
}

int cellDimension(uint8_t type) {
  switch (type) {
    case kVertex:
    case kPolyVertex: return 0;
    case kLine:
    case kPolyLine: return 1;
    case kTriangle:
    case kTriangleStrip:
    case kPolygon:
    case kPixel:
    case kQuad: return 2;
    case kTetra:
    case kVoxel:
    case kHexahedron:
    case kWedge:
    case kPyramid: return 3;
    default: return -1;
  }
}

CellPoint evaluateCellPoint(uint8_t type, const double* pts, int n, const double x[3], double* w, bool wantClosest) {
  const Vec3 xv(x);
  switch (type) {
    case kVertex: return evaluateVertex(pointAt(pts, 0), xv, w);
    case kPolyVertex:
      return evaluateParts(n, 1, n, w, [&](int k, double* pw) { return evaluateVertex(pointAt(pts, k), xv, pw); });
    case kLine: return evaluateLine(pointAt(pts, 0), pointAt(pts, 1), xv, w);
    case kPolyLine:
      return evaluateParts(n - 1, 2, n, w,
                           [&](int k, double* pw) { return evaluateLine(pointAt(pts, k), pointAt(pts, k + 1), xv, pw); });
    case kTriangle: return evaluateTriangle(pointAt(pts, 0), pointAt(pts, 1), pointAt(pts, 2), xv, w, wantClosest);
    case kTriangleStrip:
      return evaluateParts(n - 2, 3, n, w, [&](int k, double* pw) {
        return evaluateTriangle(pointAt(pts, k), pointAt(pts, k + 1), pointAt(pts, k + 2), xv, pw, true);
      });
    case kPolygon: return evaluatePolygon(pts, n, xv, w, wantClosest);
    case kPixel: return evaluatePixel(pts, xv, w);
    case kQuad: {
      const Vec3 q[4] = {pointAt(pts, 0), pointAt(pts, 1), pointAt(pts, 2), pointAt(pts, 3)};
      return evaluateQuad(q, xv, w, wantClosest);
    }
    default: return evaluateVolumeCell(type, pts, n, x, w, wantClosest);
  }
}

bool intersectCellSegment(uint8_t type, const double* pts, int n, Vec3 p1, Vec3 p2, double tol, double& t, Vec3& x) {
  FirstHit h;
  switch (type) {
    case kVertex:
    case kPolyVertex:
      for (int k = 0; k < n; ++k)
        h.offer([&](double& tt, Vec3& xx) { return segmentVertex(p1, p2, pointAt(pts, k), tol, tt, xx); });
      break;
    case kLine:
    case kPolyLine:
      for (int k = 0; k + 1 < n; ++k)
        h.offer([&](double& tt, Vec3& xx) {
          return segmentSegment(p1, p2, pointAt(pts, k), pointAt(pts, k + 1), tol, tt, xx);
        });
      break;
    case kTriangle:
    case kTriangleStrip:
      for (int k = 0; k + 2 < n; ++k)
        h.offer([&](double& tt, Vec3& xx) {
          return segmentTriangle(p1, p2, pointAt(pts, k), pointAt(pts, k + 1), pointAt(pts, k + 2), tol, tt, xx);
        });
      break;
    case kPolygon:
      h.offer([&](double& tt, Vec3& xx) { return segmentPolygon(pts, n, p1, p2, tol, tt, xx); });
      break;
    case kPixel:
    case kQuad: {
      // A pixel's corners in cyclic order are 0, 1, 3, 2.
      const int c[4] = {0, 1, type == kPixel ? 3 : 2, type == kPixel ? 2 : 3};
      const Vec3 q[4] = {pointAt(pts, c[0]), pointAt(pts, c[1]), pointAt(pts, c[2]), pointAt(pts, c[3])};
      h.offer([&](double& tt, Vec3& xx) { return segmentTriangle(p1, p2, q[0], q[1], q[2], tol, tt, xx); });
      h.offer([&](double& tt, Vec3& xx) { return segmentTriangle(p1, p2, q[2], q[3], q[0], tol, tt, xx); });
      break;
    }
    default:
      forEachBoundaryTriangle(type, pts, [&](Vec3 a, Vec3 b, Vec3 c) {
        h.offer([&](double& tt, Vec3& xx) { return segmentTriangle(p1, p2, a, b, c, tol, tt, xx); });
      });
      break;
  }
  return h.found(t, x);
}

}  // namespace mtree

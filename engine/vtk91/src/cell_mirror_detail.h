// Private to mtvtk91: the pieces the transcriptions of VTK 9.1's cells share (cell_mirror.cpp,
// cell_mirror_quadratic.cpp): vtkMath's and vtkType's constants and helpers, the cells every
// other cell delegates to (triangle, quad, line), and VTK's Newton inversion of isoparametric
// volume cells, written once for the types that each repeat it in VTK.
#pragma once

#include <cmath>
#include <cstdint>

#include "mtree/vtk91/cell_eval.h"

namespace mtree {
namespace vtk91 {
namespace mirror {

constexpr double kDoubleMax = 1.0e+299;   // VTK_DOUBLE_MAX
constexpr double kDoubleMin = -1.0e+299;  // VTK_DOUBLE_MIN
constexpr double kVtkTol = 1.e-05;        // VTK_TOL (vtkCell.h)
constexpr double kDiverged = 1.e6;        // VTK_DIVERGED of every Newton-based cell
enum { kNoIntersect = 0, kIntersect = 2, kOnLine = 3 };  // vtkLine::IntersectionType

inline double dot(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
/// vtkMath::Distance2BetweenPoints.
inline double distance2(const double p1[3], const double p2[3]) {
  return ((p1[0] - p2[0]) * (p1[0] - p2[0]) + (p1[1] - p2[1]) * (p1[1] - p2[1]) + (p1[2] - p2[2]) * (p1[2] - p2[2]));
}
/// vtkMath::Determinant3x3 of three columns.
inline double determinant3x3(const double c1[3], const double c2[3], const double c3[3]) {
  return c1[0] * c2[1] * c3[2] + c2[0] * c3[1] * c1[2] + c3[0] * c1[1] * c2[2] - c1[0] * c3[1] * c2[2] -
         c2[0] * c1[1] * c3[2] - c3[0] * c2[1] * c1[2];
}

/// closestPoint = p where a closest point is asked (the running nearest of VTK's composite
/// cells and of its closest-point loops over edges or faces).
inline void setClosest(double* closestPoint, const double p[3]) {
  if (closestPoint) {
    closestPoint[0] = p[0];
    closestPoint[1] = p[1];
    closestPoint[2] = p[2];
  }
}

/// Where a closest point is asked: x itself at distance 0 (VTK's answer for a point inside a
/// volume cell). dist2 is left alone otherwise, as VTK leaves it.
inline void closestIsX(const double x[3], double* closestPoint, double& dist2) {
  if (closestPoint) {
    closestPoint[0] = x[0];
    closestPoint[1] = x[1];
    closestPoint[2] = x[2];
    dist2 = 0.0;
  }
}

/// Where a closest point is asked: cp, x's projection onto the plane of a 2-D cell x projects
/// into, and its squared distance (VTK's answer inside a triangle, quad, pixel or polygon).
inline void closestIsProjection(const double cp[3], const double x[3], double* closestPoint, double& dist2) {
  if (closestPoint) {
    dist2 = distance2(cp, x);
    closestPoint[0] = cp[0];
    closestPoint[1] = cp[1];
    closestPoint[2] = cp[2];
  }
}

/// The first test of vtkPyramid's and vtkQuadraticPyramid's EvaluatePosition: x at the apex
/// (|x - apex|^2 below 1e-6 of the apex-to-base-centre distance squared) is inside at pcoords
/// (0, 0, 1), with the type's functions S::functions as weights. False otherwise, dist2 then
/// |x - apex|^2 as VTK leaves it.
template <class S>
bool pyramidAtApex(const double* pts, const double x[3], double* closestPoint, double pcoords[3], double& dist2,
                   double* weights) {
  const double* apexPoint = pts + 12;
  dist2 = distance2(apexPoint, x);
  double baseMidpoint[3] = {pts[0], pts[1], pts[2]};
  for (int i = 1; i < 4; i++)
    for (int j = 0; j < 3; j++) baseMidpoint[j] += pts[3 * i + j];
  for (int i = 0; i < 3; i++) baseMidpoint[i] /= 4.;
  const double length2 = distance2(apexPoint, baseMidpoint);
  if (!(dist2 == 0. || (length2 != 0. && dist2 / length2 < 1.e-6))) return false;
  pcoords[0] = pcoords[1] = 0;
  pcoords[2] = 1;
  S::functions(pcoords, weights);
  closestIsX(x, closestPoint, dist2);
  return true;
}

double distanceToLine(const double x[3], const double p1[3], const double p2[3], double& t, double* closestPoint);
int lineEvaluatePosition(const double* a1, const double* a2, const double x[3], double* closestPoint, int& subId,
                         double pcoords[3], double& dist2, double* weights);
int lineIntersectWithLine(const double* a1, const double* a2, const double p1[3], const double p2[3], double tol,
                          double& t, double x[3], double pcoords[3], int& subId);
int triangleEvaluatePosition(const double* q0, const double* q1, const double* q2, const double x[3],
                             double* closestPoint, int& subId, double pcoords[3], double& dist2, double* weights);
int triangleIntersectWithLine(const double* q0, const double* q1, const double* q2, const double p1[3],
                              const double p2[3], double tol, double& t, double x[3], double pcoords[3], int& subId);
/// vtkQuad::IntersectWithLine; ids: the quad's point ids (nullptr: its constructor's, all 0).
int quadIntersectWithLine(const double* pts, const int64_t* ids, const double p1[3], const double p2[3], double tol,
                          double& t, double x[3], double pcoords[3], int& subId);

/// The quadratic volume cells (cell_mirror_quadratic.cpp): whether covered, EvaluatePosition,
/// IntersectWithLine.
bool quadraticCovers(uint8_t type, int64_t n);
int quadraticEvaluatePosition(uint8_t type, const double* pts, const double x[3], double* closestPoint, int& subId,
                              double pcoords[3], double& dist2, double* weights);
int quadraticIntersectWithLine(uint8_t type, const double* pts, const double p1[3], const double p2[3], double tol,
                               double& t, double x[3], double pcoords[3], int& subId);

/// VTK's Newton inversion x(pcoords) = x of an isoparametric volume cell, as vtkHexahedron,
/// vtkWedge, vtkPyramid and the quadratic volume cells each write it (one loop, their
/// constants): from S::start, at most S::kMaxIteration steps of
///   pcoords = params - S::kDamping * det(...) / d
/// (damping 1 for the linear cells, 0.5 for the quadratic ones; a product with 1 is exact),
/// -1 when |d| falls below the determinant tolerance (S::detTolerance(pts): VTK's
/// min(1e-20, 1e-5 L^3) over the type's edges or diagonals, or a constant), when a coordinate
/// passes 1e6 or without convergence (every step below S::kConverged); then S::inside(pcoords)
/// and, outside with a closest point asked, the point at pcoords clamped by S::clamp.
/// S::functions and S::derivs are VTK's (derivatives in r, s, t blocks of N).
/// S::initialize(pts, x, closestPoint, subId, pcoords, dist2, params) sets the start (most types:
/// startAt<S>; the triquadratic hexahedron: its corners' linear hexahedron's pcoords).
template <class S>
int isoparametricEvaluatePosition(const double* pts, const double x[3], double* closestPoint, int& subId,
                                  double pcoords[3], double& dist2, double* weights) {
  constexpr int N = S::N;
  double params[3];
  double derivs[3 * N];
  const double determinantTolerance = S::detTolerance(pts);
  subId = 0;
  S::initialize(pts, x, closestPoint, subId, pcoords, dist2, params);
  int converged = 0;
  for (int iteration = 0; !converged && (iteration < S::kMaxIteration); iteration++) {
    S::functions(pcoords, weights);
    S::derivs(pcoords, derivs);
    double fcol[3] = {0, 0, 0}, rcol[3] = {0, 0, 0}, scol[3] = {0, 0, 0}, tcol[3] = {0, 0, 0};
    for (int i = 0; i < N; i++) {
      const double* pt = pts + 3 * i;
      for (int j = 0; j < 3; j++) {
        fcol[j] += pt[j] * weights[i];
        rcol[j] += pt[j] * derivs[i];
        scol[j] += pt[j] * derivs[i + N];
        tcol[j] += pt[j] * derivs[i + 2 * N];
      }
    }
    for (int i = 0; i < 3; i++) fcol[i] -= x[i];
    const double d = determinant3x3(rcol, scol, tcol);
    if (std::fabs(d) < determinantTolerance) return -1;
    pcoords[0] = params[0] - S::kDamping * determinant3x3(fcol, scol, tcol) / d;
    pcoords[1] = params[1] - S::kDamping * determinant3x3(rcol, fcol, tcol) / d;
    pcoords[2] = params[2] - S::kDamping * determinant3x3(rcol, scol, fcol) / d;
    if ((std::fabs(pcoords[0] - params[0]) < S::kConverged) && (std::fabs(pcoords[1] - params[1]) < S::kConverged) &&
        (std::fabs(pcoords[2] - params[2]) < S::kConverged)) {
      converged = 1;
    } else if ((std::fabs(pcoords[0]) > kDiverged) || (std::fabs(pcoords[1]) > kDiverged) ||
               (std::fabs(pcoords[2]) > kDiverged)) {
      return -1;
    } else {
      params[0] = pcoords[0];
      params[1] = pcoords[1];
      params[2] = pcoords[2];
    }
  }
  if (!converged) return -1;
  S::functions(pcoords, weights);
  if (S::inside(pcoords)) {
    closestIsX(x, closestPoint, dist2);
    return 1;
  }
  if (closestPoint) {
    double pc[3], w[N];
    S::clamp(pcoords, pc);
    // EvaluateLocation: the functions at pc, then sum_i p_i w_i per coordinate.
    S::functions(pc, w);
    closestPoint[0] = closestPoint[1] = closestPoint[2] = 0.0;
    for (int i = 0; i < N; i++)
      for (int j = 0; j < 3; j++) closestPoint[j] += pts[3 * i + j] * w[i];
    dist2 = distance2(closestPoint, x);
  }
  return 0;
}

/// The start of most Newton-based cells: params and pcoords at S::start.
template <class S>
struct StartAt {
  static void initialize(const double*, const double*, double*, int&, double pcoords[3], double&, double params[3]) {
    S::start(params);
    pcoords[0] = params[0];
    pcoords[1] = params[1];
    pcoords[2] = params[2];
  }
};

/// The determinant tolerance most Newton-based cells use: min(1e-20, 1e-5 L^3), L^2 the
/// largest squared distance of the point pairs `pairs` (VTK: pow(L^2, 1.5)).
template <int M>
inline double longestPairTolerance(const double* pts, const int (&pairs)[M][2]) {
  double longest = 0;
  for (int i = 0; i < M; i++) {
    const double d2 = distance2(pts + 3 * pairs[i][0], pts + 3 * pairs[i][1]);
    if (longest < d2) longest = d2;
  }
  const double volumeBound = std::pow(longest, 1.5);
  return 1e-20 < .00001 * volumeBound ? 1e-20 : .00001 * volumeBound;
}

/// Clamping of each pcoord to [0, 1] (VTK's closest point outside most volume cells).
inline void clampUnit(const double pcoords[3], double pc[3]) {
  for (int i = 0; i < 3; i++) pc[i] = pcoords[i] < 0.0 ? 0.0 : (pcoords[i] > 1.0 ? 1.0 : pcoords[i]);
}

/// cell_eval.h's interpolation functions with the constants of VTK's exact loop
/// (isoparametricEvaluatePosition): start, iterations, damping 1, acceptance without margin.
template <class C, int Iterations>
struct LinearNewton : C, StartAt<LinearNewton<C, Iterations>> {
  static constexpr int kMaxIteration = Iterations;
  static constexpr double kDamping = 1.0;
  static void start(double p[3]) { p[0] = p[1] = p[2] = C::kStart; }
  static double detTolerance(const double* pts) { return longestPairTolerance(pts, C::kScale); }
  static bool inside(const double pc[3]) { return C::accept(pc, 0.0) == PointInCell::kInside; }
  static void clamp(const double pcoords[3], double pc[3]) { clampUnit(pcoords, pc); }
};
using HexahedronNewton = LinearNewton<cell_eval::Hexahedron, 10>;
using WedgeNewton = LinearNewton<cell_eval::Wedge, 10>;
using PyramidNewton = LinearNewton<cell_eval::Pyramid, 10>;

}  // namespace mirror
}  // namespace vtk91
}  // namespace mtree

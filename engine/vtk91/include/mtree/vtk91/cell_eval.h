// Point-in-cell evaluation of the linear volume cells (tetrahedron, voxel, hexahedron, wedge,
// pyramid) as VTK 9.1's vtkCell::EvaluatePosition computes it, for the locator's FindCell: the
// same parametric conventions, the same start point, step rule, convergence and divergence tests
// of the Newton iteration, the same acceptance tolerance per type, and the operations in VTK's
// order, so that the parametric coordinates and interpolation weights are VTK's bit for bit (no
// -ffast-math; the build uses no FMA contraction: CMakeLists.txt sets no -march, and the AVX2
// Newton step's target attribute adds AVX2 only, not FMA).
//
// VTK's rules (vtkTetra/vtkVoxel/vtkHexahedron/vtkWedge/vtkPyramid.cxx, 9.1):
//   tetrahedron  Cramer's rule on the edges from point 0; det == 0 -> -1; inside when every
//                barycentric coordinate (pcoords and 1 - their sum) is in [-0.001, 1.001];
//   voxel        pcoords = (x - p0) / (p1.x - p0.x, p2.y - p0.y, p4.z - p0.z); inside when all
//                three are in [0, 1] (no tolerance);
//   hexahedron   Newton from (0.5, 0.5, 0.5), at most 10 steps, converged when every step is
//                < 1e-5, -1 when |det J| < min(1e-20, 1e-5 L^3) (L: the longest diagonal), when
//                a coordinate passes 1e6 or without convergence; inside in [-1e-6, 1 + 1e-6]
//                (not the [-0.001, 1.001] of the other types: checked against VTK 9.1);
//   wedge        the same from (0.5, 0.5, 0.5) with steps < 1e-3, L the longest edge; inside in
//                [-0.001, 1.001] and r + s <= 1.001;
//   pyramid      first the apex: |x - apex|^2 == 0 or < 1e-6 of |apex - base centre|^2 gives
//                (0, 0, 1); else Newton from 0.3333333 with steps < 1e-3, L the longest edge;
//                inside in [-0.001, 1.001].
//
// Certain or not (the segment filter's split for rays, segment_filter.h, applied to points): the
// computation repeats VTK's, so the answer is VTK's whenever both round the same way, as they do
// in this build. An answer is given only where a different rounding could not change it: every
// acceptance coordinate, and every Newton step against the convergence threshold, clear of its
// limit by kDecisionMargin (1e-9) plus a bound on the round-off (roundoff: 64 ulp of the
// coordinates' magnitude through the inverse Jacobian, so cells far from the origin relative to
// their size, 1e12 offsets, get a wide margin), coordinates away from the divergence bound, the
// pyramid's apex ratio away from 1e-6, and a well-conditioned cell (|det| > 1e-9 of the cell's
// size cubed at every Newton step). Everything else — a point on the tolerance boundary, a
// degenerate, flat or tangled cell, no convergence, a NaN — is kAskVtk: the caller asks VTK's
// own EvaluatePosition, so the answers never change. test_cell_eval checks the decisions against
// VTK also when built with FMA contraction (-DMATRIXTREE_CELL_EVAL_ROUNDING_DIFFERS, by hand).
#pragma once

#include <cmath>
#include <cstdint>
#include <algorithm>
#include <initializer_list>
#include <limits>

#include "mtree/cells/cells.h"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif
// The Newton step also has an AVX2 version (four sums per register), compiled for that ISA by a
// target attribute and chosen at run time: the build itself sets no -march.
#if defined(__GNUC__) && defined(__x86_64__)
#define MTREE_CELL_EVAL_AVX2 1
#include <immintrin.h>
#endif

namespace mtree {
namespace vtk91 {

/// The engine's answer for a point and a cell: VTK's EvaluatePosition returns 1 (kInside) or 0
/// or -1 (kOutside: the point is not in the cell), or the engine cannot be sure (kAskVtk).
enum class PointInCell : int { kOutside = 0, kInside = 1, kAskVtk = -1 };

namespace cell_eval {

/// A coordinate this close to an acceptance limit, or a Newton step this close (relative) to the
/// convergence threshold, is left to VTK.
constexpr double kDecisionMargin = 1e-9;
/// |det| below this fraction of the cell's size cubed: the cell is (nearly) degenerate, left to VTK.
constexpr double kConditionRatio = 1e-9;
/// How far outside the unit cell (in pcoords) Newton's first iterate must land before the hull
/// test (faceSeparates) is tried: inside points never pay for it.
constexpr double kFarOutside = 0.1;

/// vtkMath::Determinant3x3 of three columns, in VTK's order of operations.
inline double det3(const double c1[3], const double c2[3], const double c3[3]) {
  return c1[0] * c2[1] * c3[2] + c2[0] * c3[1] * c1[2] + c3[0] * c1[1] * c2[2] - c1[0] * c3[1] * c2[2] -
         c2[0] * c1[1] * c3[2] - c3[0] * c2[1] * c1[2];
}

/// vtkMath::Distance2BetweenPoints.
inline double dist2(const double* a, const double* b) {
  return (a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]);
}

/// v in [lo, hi] surely (kInside), surely not (kOutside), or within the margin of a limit.
/// m: the margin (kDecisionMargin plus the round-off bound of the computation, roundoff).
inline PointInCell classify(double v, double lo, double hi, double m) {
  if (v >= lo + m && v <= hi - m) return PointInCell::kInside;
  if (v < lo - m || v > hi + m) return PointInCell::kOutside;
  return PointInCell::kAskVtk;  // also NaN
}

/// Combines per-coordinate verdicts: any surely-outside coordinate decides (VTK's test is a
/// conjunction), else any uncertain one makes the whole uncertain.
inline PointInCell conjoin(PointInCell a, PointInCell b) {
  if (a == PointInCell::kOutside || b == PointInCell::kOutside) return PointInCell::kOutside;
  if (a == PointInCell::kAskVtk || b == PointInCell::kAskVtk) return PointInCell::kAskVtk;
  return PointInCell::kInside;
}

/// The three parametric coordinates in [lo, hi], the test every type here makes (the wedge adds
/// r + s): their verdicts conjoined.
inline PointInCell inCube(const double pc[3], double lo, double hi, double m) {
  return conjoin(conjoin(classify(pc[0], lo, hi, m), classify(pc[1], lo, hi, m)), classify(pc[2], lo, hi, m));
}

/// Is |step| < threshold decided by more than the margin? Sets `below`; false: too close to call.
/// The threshold's own margin is relative (kDecisionMargin); the round-off bound is
/// roundoff's second term, kml2 / adet, compared multiplied out (no division per step): kml2 =
/// 64 eps mag L^2, adet = |det|.
inline bool stepIsClear(double step, double threshold, double kml2, double adet, bool& below) {
  const double a = std::fabs(step);
  below = a < threshold;
  return (std::fabs(a - threshold) - kDecisionMargin * threshold) * adet > kml2;  // false for NaN
}

/// The largest coordinate magnitude of x and the cell's n points: the scale of the round-off in
/// x - p and in the Newton residual.
inline double magnitude(const double* pts, int n, const double x[3]) {
#if defined(__SSE2__)
  // Two lanes and two registers, so the maxima form a short tree instead of one 3n-long chain
  // of dependent max instructions (that chain cost a tetrahedron test a third of its time).
  const __m128d sign = _mm_set1_pd(-0.0);
  __m128d a = _mm_andnot_pd(sign, _mm_loadu_pd(x)), b = _mm_andnot_pd(sign, _mm_load_sd(x + 2));
  const int m = 3 * n;
  int i = 0;
  for (; i + 4 <= m; i += 4) {
    a = _mm_max_pd(a, _mm_andnot_pd(sign, _mm_loadu_pd(pts + i)));
    b = _mm_max_pd(b, _mm_andnot_pd(sign, _mm_loadu_pd(pts + i + 2)));
  }
  for (; i + 2 <= m; i += 2) a = _mm_max_pd(a, _mm_andnot_pd(sign, _mm_loadu_pd(pts + i)));
  if (i < m) b = _mm_max_pd(b, _mm_andnot_pd(sign, _mm_load_sd(pts + i)));
  a = _mm_max_pd(a, b);
  return std::max(_mm_cvtsd_f64(a), _mm_cvtsd_f64(_mm_unpackhi_pd(a, a)));
#else
  double m = std::max({std::fabs(x[0]), std::fabs(x[1]), std::fabs(x[2])});
  for (int i = 0; i < 3 * n; ++i) m = std::max(m, std::fabs(pts[i]));
  return m;
#endif
}

// roundoff: how far a parametric coordinate computed here can lie from VTK's if the two round
// differently (another compiler, FMA contraction, a VTK built with other flags): the residual
// x - X(p) is off by a few ulp of the coordinates' magnitude `mag`, and the solve turns that
// into pcoords through the inverse Jacobian, whose size is bounded by L^2 / |det| (L^2 the
// cell's squared size; the adjugate's entries are products of two edge vectors). 64 ulp of
// headroom. Where both round the same way (this build: no FMA, VTK's operation order) the
// answers are equal bit for bit and the margin only costs a VTK call near the limits.
// roundoff = kDecisionMargin + 64 eps mag L^2 / |det|; newton() and evaluateTetra() apply it
// multiplied out, so that it costs no division per step.

// Interpolation functions and their derivatives (r, s, t blocks of N), as VTK writes them.
struct Hexahedron {
  static constexpr int N = 8;
  static constexpr double kConverged = 1e-5, kLower = 0.0 - 1e-6, kUpper = 1.0 + 1e-6, kStart = 0.5;
  static constexpr int kScale[4][2] = {{0, 6}, {1, 7}, {2, 4}, {3, 5}};  // the diagonals
  static constexpr int kNumScale = 4;
  static void functions(const double pc[3], double sf[8]) {
    const double rm = 1. - pc[0], sm = 1. - pc[1], tm = 1. - pc[2];
    sf[0] = rm * sm * tm;
    sf[1] = pc[0] * sm * tm;
    sf[2] = pc[0] * pc[1] * tm;
    sf[3] = rm * pc[1] * tm;
    sf[4] = rm * sm * pc[2];
    sf[5] = pc[0] * sm * pc[2];
    sf[6] = pc[0] * pc[1] * pc[2];
    sf[7] = rm * pc[1] * pc[2];
  }
  static void derivs(const double pc[3], double d[24]) {
    const double rm = 1. - pc[0], sm = 1. - pc[1], tm = 1. - pc[2];
    d[0] = -sm * tm;
    d[1] = sm * tm;
    d[2] = pc[1] * tm;
    d[3] = -pc[1] * tm;
    d[4] = -sm * pc[2];
    d[5] = sm * pc[2];
    d[6] = pc[1] * pc[2];
    d[7] = -pc[1] * pc[2];
    d[8] = -rm * tm;
    d[9] = -pc[0] * tm;
    d[10] = pc[0] * tm;
    d[11] = rm * tm;
    d[12] = -rm * pc[2];
    d[13] = -pc[0] * pc[2];
    d[14] = pc[0] * pc[2];
    d[15] = rm * pc[2];
    d[16] = -rm * sm;
    d[17] = -pc[0] * sm;
    d[18] = -pc[0] * pc[1];
    d[19] = -rm * pc[1];
    d[20] = rm * sm;
    d[21] = pc[0] * sm;
    d[22] = pc[0] * pc[1];
    d[23] = rm * pc[1];
  }
  static PointInCell accept(const double pc[3], double m) { return inCube(pc, kLower, kUpper, m); }
  // kHullMargin: x's margin beyond the hull of the points for VTK to reject it (its pcoords
  // tolerance and the residual its convergence test leaves, both far smaller); outsideFace: the
  // face (cellTopology's index) on whose plane the pcoords constraint pc violates by more than
  // kFarOutside holds (r = 0, r = 1, s = 0, ...), or -1.
  static constexpr uint8_t kType = kHexahedron;
  static constexpr double kHullMargin = 1e-3;
  static int outsideFace(const double pc[3]) {
    for (int a = 0; a < 3; ++a) {
      if (pc[a] < -kFarOutside) return 2 * a;
      if (pc[a] > 1 + kFarOutside) return 2 * a + 1;
    }
    return -1;
  }
};

struct Wedge {
  static constexpr int N = 6;
  static constexpr double kConverged = 1e-3, kStart = 0.5;
  static constexpr int kScale[9][2] = {{0, 1}, {1, 2}, {2, 0}, {3, 4}, {4, 5}, {5, 3}, {0, 3}, {1, 4}, {2, 5}};
  static constexpr int kNumScale = 9;
  static void functions(const double pc[3], double sf[6]) {
    sf[0] = (1.0 - pc[0] - pc[1]) * (1.0 - pc[2]);
    sf[1] = pc[0] * (1.0 - pc[2]);
    sf[2] = pc[1] * (1.0 - pc[2]);
    sf[3] = (1.0 - pc[0] - pc[1]) * pc[2];
    sf[4] = pc[0] * pc[2];
    sf[5] = pc[1] * pc[2];
  }
  static void derivs(const double pc[3], double d[18]) {
    d[0] = -1.0 + pc[2];
    d[1] = 1.0 - pc[2];
    d[2] = 0.0;
    d[3] = -pc[2];
    d[4] = pc[2];
    d[5] = 0.0;
    d[6] = -1.0 + pc[2];
    d[7] = 0.0;
    d[8] = 1.0 - pc[2];
    d[9] = -pc[2];
    d[10] = 0.0;
    d[11] = pc[2];
    d[12] = -1.0 + pc[0] + pc[1];
    d[13] = -pc[0];
    d[14] = -pc[1];
    d[15] = 1.0 - pc[0] - pc[1];
    d[16] = pc[0];
    d[17] = pc[1];
  }
  static PointInCell accept(const double pc[3], double m) {
    // r + s <= 1.001: VTK adds, then compares; -inf as the lower limit never decides.
    return conjoin(inCube(pc, -0.001, 1.001, m), classify(pc[0] + pc[1], -HUGE_VAL, 1.001, 2 * m));
  }
  static constexpr uint8_t kType = kWedge;
  static constexpr double kHullMargin = 2e-2;
  static int outsideFace(const double pc[3]) {
    if (pc[2] < -kFarOutside) return 0;                // t = 0: {0, 1, 2}
    if (pc[2] > 1 + kFarOutside) return 1;             // t = 1: {3, 5, 4}
    if (pc[1] < -kFarOutside) return 2;                // s = 0: {0, 3, 4, 1}
    if (pc[0] + pc[1] > 1 + kFarOutside) return 3;     // r + s = 1: {1, 4, 5, 2}
    if (pc[0] < -kFarOutside) return 4;                // r = 0: {2, 5, 3, 0}
    return -1;
  }
};

struct Pyramid {
  static constexpr int N = 5;
  static constexpr double kConverged = 1e-3, kStart = 0.3333333;
  static constexpr int kScale[8][2] = {{0, 1}, {1, 2}, {2, 3}, {3, 0}, {0, 4}, {1, 4}, {2, 4}, {3, 4}};
  static constexpr int kNumScale = 8;
  static void functions(const double pc[3], double sf[5]) {
    const double rm = 1. - pc[0], sm = 1. - pc[1], tm = 1. - pc[2];
    sf[0] = rm * sm * tm;
    sf[1] = pc[0] * sm * tm;
    sf[2] = pc[0] * pc[1] * tm;
    sf[3] = rm * pc[1] * tm;
    sf[4] = pc[2];
  }
  static void derivs(const double pc[3], double d[15]) {
    const double rm = 1. - pc[0], sm = 1. - pc[1], tm = 1. - pc[2];
    d[0] = -sm * tm;
    d[1] = sm * tm;
    d[2] = pc[1] * tm;
    d[3] = -pc[1] * tm;
    d[4] = 0.0;
    d[5] = -rm * tm;
    d[6] = -pc[0] * tm;
    d[7] = pc[0] * tm;
    d[8] = rm * tm;
    d[9] = 0.0;
    d[10] = -rm * sm;
    d[11] = -pc[0] * sm;
    d[12] = -pc[0] * pc[1];
    d[13] = -rm * pc[1];
    d[14] = 1.0;
  }
  static PointInCell accept(const double pc[3], double m) { return inCube(pc, -0.001, 1.001, m); }
  static constexpr uint8_t kType = kPyramid;
  static constexpr double kHullMargin = 2e-2;
  static int outsideFace(const double pc[3]) {
    if (pc[2] < -kFarOutside) return 0;     // t = 0: the base
    if (pc[1] < -kFarOutside) return 1;     // s = 0: {0, 1, 4}
    if (pc[0] > 1 + kFarOutside) return 2;  // r = 1: {1, 2, 4}
    if (pc[1] > 1 + kFarOutside) return 3;  // s = 1: {2, 3, 4}
    if (pc[0] < -kFarOutside) return 4;     // r = 0: {3, 0, 4}
    return -1;  // beyond the apex (t > 1) has no face of its own
  }
};

/// Whether x lies beyond the plane of face f of topo (a quad's normal from its diagonals) by more
/// than mu plus the face's warp, on the side away from every other point of the cell (pts: 3
/// doubles per point): then x is more than mu from the convex hull of the cell's points. False
/// when the other points are not all clearly on one side (a tangled or flat cell), or for NaN.
/// roundoff: the error of a distance here (a few ulp of the coordinates' magnitude).
inline bool faceSeparates(const double* pts, const CellTopology& topo, int f, const double x[3], double mu,
                          double roundoff) {
  auto P = [pts](int i) { return Vec3(pts + 3 * i); };
  const int* face = topo.face[f];
  const int fn = topo.faceSize[f];
  const Vec3 o = P(face[0]);
  Vec3 nrm = fn == 4 ? cross(P(face[2]) - o, P(face[3]) - P(face[1])) : cross(P(face[1]) - o, P(face[2]) - o);
  const double nn = norm(nrm);
  if (!(nn > 0) || !std::isfinite(nn)) return false;
  nrm = nrm * (1.0 / nn);
  unsigned onFace = 0;
  double warp = 0;
  for (int j = 0; j < fn; ++j) {
    onFace |= 1u << face[j];
    warp = std::max(warp, std::fabs(dot(nrm, P(face[j]) - o)));
  }
  // The inner side: every other point's (more than round-off away); the hull then lies within
  // the warp outside the plane.
  double side = 0;
  for (int k = 0; k < topo.numPoints; ++k) {
    if ((onFace >> k) & 1) continue;
    const double dk = dot(nrm, P(k) - o);
    if (!(std::fabs(dk) > warp + roundoff)) return false;
    if (side == 0) side = dk > 0 ? 1 : -1;
    else if ((dk > 0) != (side > 0)) return false;
  }
  return -side * dot(nrm, Vec3(x) - o) > mu + warp + roundoff;  // false for NaN
}

/// The Newton iteration's columns as VTK sums them: f = sum_i p_i w_i, r/s/t = sum_i p_i d_i
/// (the three derivative blocks), i = 0 ... N-1 in order, each a multiply then an add. VTK does
/// the twelve sums (4 columns x 3 coordinates) one after another; they are independent, so here
/// they run two to a SSE2 register: every lane does exactly VTK's sequence of multiplies and
/// adds (no FMA), so the sums are VTK's bit for bit (newtonColumnsScalar is the plain loop; the
/// tests compare both with VTK).
template <int N>
inline void newtonColumnsScalar(const double* pts, const double* w, const double* d, double f[3], double r[3],
                                double s[3], double t[3]) {
  for (int j = 0; j < 3; ++j) f[j] = r[j] = s[j] = t[j] = 0;
  for (int i = 0; i < N; ++i) {
    const double* pt = pts + 3 * i;
    for (int j = 0; j < 3; ++j) {
      f[j] += pt[j] * w[i];
      r[j] += pt[j] * d[i];
      s[j] += pt[j] * d[i + N];
      t[j] += pt[j] * d[i + 2 * N];
    }
  }
}

template <int N>
inline void newtonColumns(const double* pts, const double* w, const double* d, double f[3], double r[3], double s[3],
                          double t[3]) {
#if defined(__SSE2__)
  __m128d fxy = _mm_setzero_pd(), rxy = fxy, sxy = fxy, txy = fxy, frz = fxy, stz = fxy;
  for (int i = 0; i < N; ++i) {
    const __m128d pxy = _mm_loadu_pd(pts + 3 * i), pz = _mm_set1_pd(pts[3 * i + 2]);
    fxy = _mm_add_pd(fxy, _mm_mul_pd(pxy, _mm_set1_pd(w[i])));
    rxy = _mm_add_pd(rxy, _mm_mul_pd(pxy, _mm_set1_pd(d[i])));
    sxy = _mm_add_pd(sxy, _mm_mul_pd(pxy, _mm_set1_pd(d[i + N])));
    txy = _mm_add_pd(txy, _mm_mul_pd(pxy, _mm_set1_pd(d[i + 2 * N])));
    frz = _mm_add_pd(frz, _mm_mul_pd(pz, _mm_set_pd(d[i], w[i])));
    stz = _mm_add_pd(stz, _mm_mul_pd(pz, _mm_set_pd(d[i + 2 * N], d[i + N])));
  }
  _mm_storeu_pd(f, fxy);
  _mm_storeu_pd(r, rxy);
  _mm_storeu_pd(s, sxy);
  _mm_storeu_pd(t, txy);
  alignas(16) double z[4];
  _mm_store_pd(z, frz);
  _mm_store_pd(z + 2, stz);
  f[2] = z[0];
  r[2] = z[1];
  s[2] = z[2];
  t[2] = z[3];
#else
  newtonColumnsScalar<N>(pts, w, d, f, r, s, t);
#endif
}

/// The numbers of one Newton step at pc as VTK computes them: out[0] = det(r, s, t), the
/// Jacobian's determinant, and out[1..3] = det(f, s, t), det(r, f, t), det(r, s, f), the
/// numerators of the step (f = X(pc) - x). Two sums per SSE2 register.
struct Sse2Step {
  template <class S>
  static void run(const double* pts, const double x[3], const double pc[3], double out[4]) {
    constexpr int N = S::N;
    double w[N], d[3 * N];
    S::functions(pc, w);
    S::derivs(pc, d);
    double fcol[3], rcol[3], scol[3], tcol[3];
    newtonColumns<N>(pts, w, d, fcol, rcol, scol, tcol);
    for (int i = 0; i < 3; ++i) fcol[i] -= x[i];
    out[0] = det3(rcol, scol, tcol);
    out[1] = det3(fcol, scol, tcol);
    out[2] = det3(rcol, fcol, tcol);
    out[3] = det3(rcol, scol, fcol);
  }
};

#if MTREE_CELL_EVAL_AVX2
/// Sse2Step with four lanes: per coordinate one register holds the sums (f, r, s, t), each lane
/// VTK's multiply-then-add sequence over the points in order; then the four determinants run
/// one per lane, each with det3's operations in det3's order (lane 0: (r, s, t), lane 1:
/// (f, s, t), lane 2: (r, f, t), lane 3: (r, s, f)). Same bits as Sse2Step (AVX2 brings no FMA:
/// that is a separate target feature, not enabled here).
struct Avx2Step {
  template <class S>
  __attribute__((target("avx2"))) static void run(const double* pts, const double x[3], const double pc[3],
                                                  double out[4]) {
    constexpr int N = S::N;
    double w[N], d[3 * N];
    S::functions(pc, w);
    S::derivs(pc, d);
    __m256d ax = _mm256_setzero_pd(), ay = ax, az = ax;
    for (int i = 0; i < N; ++i) {
      const __m256d c = _mm256_set_pd(d[i + 2 * N], d[i + N], d[i], w[i]);
      ax = _mm256_add_pd(ax, _mm256_mul_pd(_mm256_broadcast_sd(pts + 3 * i), c));
      ay = _mm256_add_pd(ay, _mm256_mul_pd(_mm256_broadcast_sd(pts + 3 * i + 1), c));
      az = _mm256_add_pd(az, _mm256_mul_pd(_mm256_broadcast_sd(pts + 3 * i + 2), c));
    }
    // f -= x (r - 0 is r, also for -0).
    ax = _mm256_sub_pd(ax, _mm256_set_pd(0.0, 0.0, 0.0, x[0]));
    ay = _mm256_sub_pd(ay, _mm256_set_pd(0.0, 0.0, 0.0, x[1]));
    az = _mm256_sub_pd(az, _mm256_set_pd(0.0, 0.0, 0.0, x[2]));
    // det3's columns per lane, from the lanes (f, r, s, t) = (0, 1, 2, 3): c1 = (r, f, r, r),
    // c2 = (s, s, f, s), c3 = (t, t, t, f).
    constexpr int k1 = 1 | 0 << 2 | 1 << 4 | 1 << 6, k2 = 2 | 2 << 2 | 0 << 4 | 2 << 6, k3 = 3 | 3 << 2 | 3 << 4 | 0 << 6;
    const __m256d c1x = _mm256_permute4x64_pd(ax, k1), c1y = _mm256_permute4x64_pd(ay, k1),
                  c1z = _mm256_permute4x64_pd(az, k1);
    const __m256d c2x = _mm256_permute4x64_pd(ax, k2), c2y = _mm256_permute4x64_pd(ay, k2),
                  c2z = _mm256_permute4x64_pd(az, k2);
    const __m256d c3x = _mm256_permute4x64_pd(ax, k3), c3y = _mm256_permute4x64_pd(ay, k3),
                  c3z = _mm256_permute4x64_pd(az, k3);
    // c1[0] c2[1] c3[2] + c2[0] c3[1] c1[2] + c3[0] c1[1] c2[2] - c1[0] c3[1] c2[2]
    //   - c2[0] c1[1] c3[2] - c3[0] c2[1] c1[2], left to right.
    __m256d det = _mm256_mul_pd(_mm256_mul_pd(c1x, c2y), c3z);
    det = _mm256_add_pd(det, _mm256_mul_pd(_mm256_mul_pd(c2x, c3y), c1z));
    det = _mm256_add_pd(det, _mm256_mul_pd(_mm256_mul_pd(c3x, c1y), c2z));
    det = _mm256_sub_pd(det, _mm256_mul_pd(_mm256_mul_pd(c1x, c3y), c2z));
    det = _mm256_sub_pd(det, _mm256_mul_pd(_mm256_mul_pd(c2x, c1y), c3z));
    det = _mm256_sub_pd(det, _mm256_mul_pd(_mm256_mul_pd(c3x, c2y), c1z));
    _mm256_storeu_pd(out, det);
  }
};
#endif

/// Which Newton step newton() uses: kAuto takes AVX2 where the processor has it. Both give the
/// same bits; the tests run each.
enum class NewtonIsa { kAuto, kSse2, kAvx2 };
inline NewtonIsa& newtonIsa() {
  static NewtonIsa isa = NewtonIsa::kAuto;
  return isa;
}
inline bool haveAvx2() {
#if MTREE_CELL_EVAL_AVX2
  // cpu_init: harmless after libgcc's own initialisation, needed if this runs before it.
  static const bool ok = (__builtin_cpu_init(), __builtin_cpu_supports("avx2"));
  return ok;
#else
  return false;
#endif
}

/// VTK's Newton inversion x(pcoords) = x for the isoparametric cell `S` (points `pts`, 3 N
/// doubles), with the step numbers of `Step`. pcoords and weights as VTK leaves them when the
/// verdict is kInside; kOutside where VTK returns 0 or -1.
template <class S, class Step>
inline PointInCell newtonWith(const double* pts, const double x[3], double pcoords[3], double* weights) {
  constexpr int N = S::N;
  // The cell's size: VTK's longest diagonal/edge, squared. VTK turns it into its determinant
  // tolerance, min(1e-20, 1e-5 L^3), which matters only when |det| < 1e-20; the conditioning
  // test below (|det| > 1e-9 L^3) is stricter whenever L^3 > 1e-11 and is checked first.
  double longest2 = 0;
  for (int i = 0; i < S::kNumScale; ++i) {
    const double d2 = dist2(pts + 3 * S::kScale[i][0], pts + 3 * S::kScale[i][1]);
    if (longest2 < d2) longest2 = d2;
  }
  // |det| <= kConditionRatio * L^3, squared: no pow, no sqrt. A NaN or inf size is never clear.
  const double minDet2 = kConditionRatio * kConditionRatio * longest2 * longest2 * longest2;
  if (!(minDet2 < HUGE_VAL)) return PointInCell::kAskVtk;
  const double kml2 = 64 * std::numeric_limits<double>::epsilon() * magnitude(pts, N, x) * longest2;

  double params[3] = {S::kStart, S::kStart, S::kStart};
  double pc[3] = {S::kStart, S::kStart, S::kStart};
  bool converged = false;
  double adet = 0;  // |det| of the last step
  for (int iteration = 0; !converged && iteration < 10; ++iteration) {
    double step[4];
    Step::template run<S>(pts, x, pc, step);
    const double det = step[0];
    // Degenerate at this iterate, or NaN: VTK decides.
    if (!(det * det > minDet2)) return PointInCell::kAskVtk;
    // VTK's own test, |det| < min(1e-20, 1e-5 L^3) -> -1, can only fire below 1e-20 (tiny
    // cells; pow only then).
    if (std::fabs(det) < 1e-20) {
      const double bound = std::pow(longest2, 1.5);
      const double tol = 1e-20 < .00001 * bound ? 1e-20 : .00001 * bound;
      // (det itself is off by a few ulp of L^3-sized products: far below the relative margin.)
      if (!(std::fabs(std::fabs(det) - tol) > kDecisionMargin * tol)) return PointInCell::kAskVtk;
      if (std::fabs(det) < tol) return PointInCell::kOutside;
    }
    pc[0] = params[0] - step[1] / det;
    pc[1] = params[1] - step[2] / det;
    pc[2] = params[2] - step[3] / det;
    adet = std::fabs(det);
    if (iteration == 0) {
      // Far outside after the first step (a candidate whose box, not cell, holds x): a face
      // plane separating x from all the cell's points by the margin settles VTK's "no" without
      // the remaining steps. Points inside the cell never get here.
      const int f = S::outsideFace(pc);
      if (f >= 0 && faceSeparates(pts, *cellTopology(S::kType), f, x, S::kHullMargin * std::sqrt(longest2),
                                  kml2 / longest2))
        return PointInCell::kOutside;
    }
    bool below[3];
    if (!stepIsClear(pc[0] - params[0], S::kConverged, kml2, adet, below[0]) ||
        !stepIsClear(pc[1] - params[1], S::kConverged, kml2, adet, below[1]) ||
        !stepIsClear(pc[2] - params[2], S::kConverged, kml2, adet, below[2]))
      return PointInCell::kAskVtk;
    if (below[0] && below[1] && below[2]) {
      converged = true;
    } else {
      // VTK's divergence test: |pcoords| > 1e6 -> -1 (a coordinate at the bound: VTK decides).
      bool diverged = false;
      for (int i = 0; i < 3; ++i) {
        bool out = false;
        if (!stepIsClear(pc[i], 1e6, kml2, adet, out)) return PointInCell::kAskVtk;
        diverged = diverged || !out;
      }
      if (diverged) return PointInCell::kOutside;
      params[0] = pc[0];
      params[1] = pc[1];
      params[2] = pc[2];
    }
  }
  // Not converged in 10 steps: VTK says -1, but a step at the margin could have converged in
  // VTK's rounding; these are rare (tangled or very warped cells): VTK decides.
  if (!converged) return PointInCell::kAskVtk;
  // The acceptance margin, roundoff of the last step: one division per evaluation.
  const PointInCell v = S::accept(pc, kDecisionMargin + kml2 / adet);
  if (v == PointInCell::kInside) {
    pcoords[0] = pc[0];
    pcoords[1] = pc[1];
    pcoords[2] = pc[2];
    S::functions(pc, weights);
  }
  return v;
}

#if MTREE_CELL_EVAL_AVX2
/// newtonWith<S, Avx2Step> compiled for AVX2 (flatten: the loop and its helpers are inlined
/// here, so they are compiled for AVX2 too).
template <class S>
__attribute__((target("avx2"), flatten)) PointInCell newtonAvx2(const double* pts, const double x[3],
                                                                double pcoords[3], double* weights) {
  return newtonWith<S, Avx2Step>(pts, x, pcoords, weights);
}
#endif

/// VTK's Newton inversion (newtonWith) with the step newtonIsa() selects.
template <class S>
inline PointInCell newton(const double* pts, const double x[3], double pcoords[3], double* weights) {
#if MTREE_CELL_EVAL_AVX2
  const NewtonIsa isa = newtonIsa();
  if (isa != NewtonIsa::kSse2 && haveAvx2()) return newtonAvx2<S>(pts, x, pcoords, weights);
#endif
  return newtonWith<S, Sse2Step>(pts, x, pcoords, weights);
}

}  // namespace cell_eval

/// vtkTetra::EvaluatePosition.
inline PointInCell evaluateTetra(const double* pts, const double x[3], double pcoords[3], double* weights) {
  double rhs[3], c1[3], c2[3], c3[3];
  const double* p0 = pts;
  for (int i = 0; i < 3; ++i) {
    rhs[i] = x[i] - p0[i];
    c1[i] = pts[3 + i] - p0[i];
    c2[i] = pts[6 + i] - p0[i];
    c3[i] = pts[9 + i] - p0[i];
  }
  const double det = cell_eval::det3(c1, c2, c3);
  // Conditioning: |det| against the longest edge from point 0 cubed (flat or degenerate
  // tetrahedra, and det == 0 where VTK returns -1, are VTK's).
  double longest2 = 0;
  for (const double* c : {c1, c2, c3}) {
    const double l2 = c[0] * c[0] + c[1] * c[1] + c[2] * c[2];
    if (longest2 < l2) longest2 = l2;
  }
  const double r = cell_eval::kConditionRatio;
  if (!(det * det > r * r * longest2 * longest2 * longest2) || !std::isfinite(det)) return PointInCell::kAskVtk;
  const double n0 = cell_eval::det3(rhs, c2, c3), n1 = cell_eval::det3(c1, rhs, c3), n2 = cell_eval::det3(c1, c2, rhs);
  // The margin, as roundoff but local: VTK works on x - p0 and p_i - p0 (plain subtractions,
  // rounded the same way by any IEEE compiler), so the round-off that another compiler could
  // add is in the determinants of those differences: a few ulp of max(L, |x - p0|) L^2, over
  // |det| (3 times that for p4, a sum of three). This test runs for every candidate of a
  // tetrahedral grid, so the margin is never formed (no division, no square root): a decision
  // with clearance d stands when 64 eps max(L, |x - p0|) L^2 <= (d - 1e-9) |det|, squared.
  // Most candidates are decided at clearance 1e-6 by the plain comparisons VTK makes; only
  // points within 1e-6 of a limit take the exact clearance.
  const double rhs2 = rhs[0] * rhs[0] + rhs[1] * rhs[1] + rhs[2] * rhs[2];
  const double k = 64 * std::numeric_limits<double>::epsilon() * longest2;
  const double need2 = k * k * std::max(longest2, rhs2);
  const double adet = std::fabs(det);
  auto clearBy = [&](double d) {
    const double e = (d - cell_eval::kDecisionMargin) * adet;
    return e > 0 && need2 <= e * e;
  };
  const double lo = -0.001, hi = 1.001, c = 1e-6, c4 = 3e-6;
  // Most candidates are outside on one of pcoords 0-2: decided without the divisions. n_i is the
  // value VTK divides by det, so s n_i < (lo - c - 1e-12) |det| (s the sign of det) puts the
  // rounded quotient below lo - c (rounding moves it by ~1e-19 here), and above hi + c likewise:
  // the cases where the test below says kOutside at clearance c.
  {
    const double s0 = det < 0 ? -n0 : n0, s1 = det < 0 ? -n1 : n1, s2 = det < 0 ? -n2 : n2;
    const double below = (lo - c - 1e-12) * adet, above = (hi + c + 1e-12) * adet;
    const bool out = (s0 < below) | (s0 > above) | (s1 < below) | (s1 > above) | (s2 < below) | (s2 > above);
    if (out && clearBy(c)) {
      return PointInCell::kOutside;
    }
  }
  double pc[3];
  pc[0] = n0 / det;
  pc[1] = n1 / det;
  pc[2] = n2 / det;
  const double p4 = 1.0 - pc[0] - pc[1] - pc[2];
  PointInCell v = PointInCell::kAskVtk;
  if (pc[0] >= lo + c && pc[0] <= hi - c && pc[1] >= lo + c && pc[1] <= hi - c && pc[2] >= lo + c &&
      pc[2] <= hi - c && p4 >= lo + c4 && p4 <= hi - c4) {
    v = clearBy(c) ? PointInCell::kInside : PointInCell::kAskVtk;
  } else if (pc[0] < lo - c || pc[0] > hi + c || pc[1] < lo - c || pc[1] > hi + c || pc[2] < lo - c ||
             pc[2] > hi + c || p4 < lo - c4 || p4 > hi + c4) {
    v = clearBy(c) ? PointInCell::kOutside : PointInCell::kAskVtk;
  }
  if (v == PointInCell::kAskVtk && !std::isnan(p4)) {
    // Within 1e-6 of a limit (or a cell whose margin exceeds 1e-6): the exact clearance.
    const double third = 1.0 / 3;
    const double dIn = std::min({pc[0] - lo, hi - pc[0], pc[1] - lo, hi - pc[1], pc[2] - lo, hi - pc[2],
                                 (p4 - lo) * third, (hi - p4) * third});
    const double dOut = std::max({lo - pc[0], pc[0] - hi, lo - pc[1], pc[1] - hi, lo - pc[2], pc[2] - hi,
                                  (lo - p4) * third, (p4 - hi) * third});
    v = dIn > 0 && clearBy(dIn) ? PointInCell::kInside
                                : (dOut > 0 && clearBy(dOut) ? PointInCell::kOutside : PointInCell::kAskVtk);
  }
  if (v == PointInCell::kInside) {
    pcoords[0] = pc[0];
    pcoords[1] = pc[1];
    pcoords[2] = pc[2];
    weights[0] = p4;
    weights[1] = pc[0];
    weights[2] = pc[1];
    weights[3] = pc[2];
  }
  return v;
}

/// vtkVoxel::EvaluatePosition (axis-aligned, points in VTK's voxel order: x fastest).
inline PointInCell evaluateVoxel(const double* pts, const double x[3], double pcoords[3], double* weights) {
  double pc[3];
  pc[0] = (x[0] - pts[0]) / (pts[3] - pts[0]);
  pc[1] = (x[1] - pts[1]) / (pts[7] - pts[1]);
  pc[2] = (x[2] - pts[2]) / (pts[14] - pts[2]);
  // Round-off: a few ulp of the magnitude over the voxel's narrowest width (a zero or NaN width
  // gives an infinite or NaN margin: VTK decides).
  const double width = std::min({std::fabs(pts[3] - pts[0]), std::fabs(pts[7] - pts[1]), std::fabs(pts[14] - pts[2])});
  const double m = cell_eval::kDecisionMargin +
                   8 * std::numeric_limits<double>::epsilon() * cell_eval::magnitude(pts, 8, x) / width;
  if (!(m < 1e-3)) return PointInCell::kAskVtk;
  const PointInCell v = cell_eval::inCube(pc, 0.0, 1.0, m);
  if (v == PointInCell::kInside) {
    pcoords[0] = pc[0];
    pcoords[1] = pc[1];
    pcoords[2] = pc[2];
    const double rm = 1. - pc[0], sm = 1. - pc[1], tm = 1. - pc[2];
    weights[0] = rm * sm * tm;
    weights[1] = pc[0] * sm * tm;
    weights[2] = rm * pc[1] * tm;
    weights[3] = pc[0] * pc[1] * tm;
    weights[4] = rm * sm * pc[2];
    weights[5] = pc[0] * sm * pc[2];
    weights[6] = rm * pc[1] * pc[2];
    weights[7] = pc[0] * pc[1] * pc[2];
  }
  return v;
}

/// vtkHexahedron::EvaluatePosition.
inline PointInCell evaluateHexahedron(const double* pts, const double x[3], double pcoords[3], double* weights) {
  return cell_eval::newton<cell_eval::Hexahedron>(pts, x, pcoords, weights);
}

/// vtkWedge::EvaluatePosition.
inline PointInCell evaluateWedge(const double* pts, const double x[3], double pcoords[3], double* weights) {
  return cell_eval::newton<cell_eval::Wedge>(pts, x, pcoords, weights);
}

/// vtkPyramid::EvaluatePosition: the apex first, then Newton.
inline PointInCell evaluatePyramid(const double* pts, const double x[3], double pcoords[3], double* weights) {
  const double* apex = pts + 12;
  const double d2 = cell_eval::dist2(apex, x);
  double mid[3] = {pts[0], pts[1], pts[2]};
  for (int i = 1; i < 4; ++i) {
    mid[0] += pts[3 * i];
    mid[1] += pts[3 * i + 1];
    mid[2] += pts[3 * i + 2];
  }
  for (int i = 0; i < 3; ++i) mid[i] /= 4.;
  const double length2 = cell_eval::dist2(apex, mid);
  // VTK: at the apex when d2 == 0 or (length2 != 0 and d2 / length2 < 1e-6).
  bool atApex = d2 == 0.;
  if (!atApex && length2 != 0.) {
    const double ratio = d2 / length2;
    // Round-off of d2 near the threshold (|x - apex| ~ 1e-3 L): a few ulp of the magnitude over
    // that distance, relative.
    const double rel = cell_eval::kDecisionMargin + 64 * std::numeric_limits<double>::epsilon() *
                                                        cell_eval::magnitude(pts, 5, x) / (1e-3 * std::sqrt(length2));
    if (!(std::fabs(ratio - 1e-6) > rel * 1e-6)) return PointInCell::kAskVtk;  // or NaN
    atApex = ratio < 1e-6;
  }
  if (atApex) {
    pcoords[0] = pcoords[1] = 0;
    pcoords[2] = 1;
    cell_eval::Pyramid::functions(pcoords, weights);
    return PointInCell::kInside;
  }
  return cell_eval::newton<cell_eval::Pyramid>(pts, x, pcoords, weights);
}

/// Whether evaluateLinearCell answers for cells of this VTK type (with this many points).
inline bool cellEvaluable(uint8_t type, int64_t n) {
  return (type == kTetra && n == 4) || (type == kVoxel && n == 8) || (type == kHexahedron && n == 8) ||
         (type == kWedge && n == 6) || (type == kPyramid && n == 5);
}

/// The verdict for point x and a cell of `type` with points `pts` (3 doubles each, VTK's order):
/// pcoords (3) and weights (the cell's point count) are written only when it is kInside, with
/// VTK's values. Types without an evaluation here answer kAskVtk.
inline PointInCell evaluateLinearCell(uint8_t type, const double* pts, const double x[3], double pcoords[3],
                                      double* weights) {
  switch (type) {
    case kTetra: return evaluateTetra(pts, x, pcoords, weights);
    case kVoxel: return evaluateVoxel(pts, x, pcoords, weights);
    case kHexahedron: return evaluateHexahedron(pts, x, pcoords, weights);
    case kWedge: return evaluateWedge(pts, x, pcoords, weights);
    case kPyramid: return evaluatePyramid(pts, x, pcoords, weights);
    default: return PointInCell::kAskVtk;
  }
}

}  // namespace vtk91
}  // namespace mtree

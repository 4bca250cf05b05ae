// Ray/triangle tests the tracers can choose between:
//   MollerTrumbore  mtree::rayTriangleMT (geometry.h): the engine's reference arithmetic;
//                   neighbours share an edge only up to round-off, so a ray through a shared
//                   edge or vertex can pass between them.
//   Watertight      Woop, Benthin & Wald 2013, "Watertight Ray/Triangle Intersection" (JCGT 2:1):
//                   the ray is sheared into a frame where it is the +z axis through the origin;
//                   the three edge functions of the projected triangle are 2x2 determinants of the
//                   transformed vertices. A transformed vertex depends only on the vertex and the
//                   ray, and an edge's function is the exact negative of the same edge's function
//                   in the neighbour (same two products, subtracted the other way), so on a closed
//                   mesh no ray passes between two triangles.
// Both have the same contract: true and t, u, v when the ray o + t d meets the triangle (a, b, c)
// with t in [tmin, tmax]; u, v are the barycentric weights of b and c (the point is
// (1 - u - v) a + u b + v c). Both reject NaN anywhere (comparisons are written as !(inside)).
#pragma once

#include <cmath>
#include <limits>
#include <utility>

#include "mtree/core/geometry.h"

namespace mtree {

enum class TriangleTest : int { MollerTrumbore = 0, Watertight = 1 };

inline const char* triangleTestName(TriangleTest t) {
  return t == TriangleTest::Watertight ? "watertight" : "moller-trumbore";
}

/// Woop, Benthin & Wald 2013. The paper's single-precision version recomputes the edge functions
/// in double when one of them is exactly 0; we compute in double from the start, so there is no
/// wider type to fall back to (and none is needed for watertightness: that comes from the
/// consistent edge functions, not from their precision).
///
/// Watertightness needs the two products of an edge function to be rounded separately (no fused
/// multiply-add): the engine builds with -std=c++17, where GCC and Clang do not contract across
/// statements or expressions unless asked to (-ffp-contract=fast).
MT_ALWAYS_INLINE bool rayTriangleWatertight(Vec3 o, Vec3 d, Vec3 a, Vec3 b, Vec3 c, double tmin, double tmax,
                                  double& t, double& u, double& v) {
  // kz: the axis of the largest |d| component; kx, ky the other two, swapped when d[kz] < 0 so
  // that the triangle's winding (the sign of the edge functions) is preserved.
  const double adx = std::fabs(d.x), ady = std::fabs(d.y), adz = std::fabs(d.z);
  int kz = 2;
  if (adx > ady) {
    if (adx > adz) kz = 0;
  } else if (ady > adz) {
    kz = 1;
  }
  int kx = kz == 2 ? 0 : kz + 1;
  int ky = kx == 2 ? 0 : kx + 1;
  if (d[kz] < 0) std::swap(kx, ky);
  // Shear constants (a zero or NaN direction makes them inf/NaN: rejected below).
  const double sx = d[kx] / d[kz], sy = d[ky] / d[kz], sz = 1.0 / d[kz];
  // Vertices relative to the origin, sheared and projected onto the plane z = 0.
  const Vec3 A = a - o, B = b - o, C = c - o;
  const double ax = A[kx] - sx * A[kz], ay = A[ky] - sy * A[kz];
  const double bx = B[kx] - sx * B[kz], by = B[ky] - sy * B[kz];
  const double cx = C[kx] - sx * C[kz], cy = C[ky] - sy * C[kz];
  // Edge functions: U for edge BC (weight of a), V for CA (weight of b), W for AB (weight of c).
  const double cxby = cx * by, cybx = cy * bx;
  const double U = cxby - cybx;
  const double axcy = ax * cy, aycx = ay * cx;
  const double V = axcy - aycx;
  const double bxay = bx * ay, byax = by * ax;
  const double W = bxay - byax;
  // Mixed signs: the ray passes outside an edge. Zeros (on an edge or vertex) are inside for both
  // neighbours, which is what closes the gaps.
  if ((U < 0 || V < 0 || W < 0) && (U > 0 || V > 0 || W > 0)) return false;
  const double det = U + V + W;
  // det == 0: the ray lies in the triangle's plane, or the triangle is degenerate.
  // Non-finite det: NaN or infinity somewhere in the input (NaN edge functions pass the sign test).
  if (det == 0.0 || !std::isfinite(det)) return false;
  const double az = sz * A[kz], bz = sz * B[kz], cz = sz * C[kz];
  const double T = U * az + V * bz + W * cz;
  const double inv = 1.0 / det;
  const double tt = T * inv;
  if (!(tt >= tmin && tt <= tmax && std::fabs(tt) < std::numeric_limits<double>::infinity())) return false;
  t = tt;
  u = V * inv;
  v = W * inv;
  return true;
}

/// Runtime choice of the test.
inline bool rayTriangle(TriangleTest test, Vec3 o, Vec3 d, Vec3 a, Vec3 b, Vec3 c, double tmin, double tmax,
                        double& t, double& u, double& v) {
  return test == TriangleTest::Watertight ? rayTriangleWatertight(o, d, a, b, c, tmin, tmax, t, u, v)
                                          : rayTriangleMT(o, d, a, b, c, tmin, tmax, t, u, v);
}

/// Compile-time choice, for inner loops templated on the test.
template <TriangleTest Test>
MT_ALWAYS_INLINE bool rayTriangleT(Vec3 o, Vec3 d, Vec3 a, Vec3 b, Vec3 c, double tmin, double tmax, double& t, double& u,
                         double& v) {
  if constexpr (Test == TriangleTest::Watertight)
    return rayTriangleWatertight(o, d, a, b, c, tmin, tmax, t, u, v);
  else
    return rayTriangleMT(o, d, a, b, c, tmin, tmax, t, u, v);
}

}  // namespace mtree

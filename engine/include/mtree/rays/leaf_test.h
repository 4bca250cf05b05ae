// Ray/triangle tests of a leaf's triangles on the pre-gathered payload (leaf_triangles.h), W
// triangles per step in the lanes of a SIMD register:
//   Simd::Scalar  one by one, through rayTriangleMT / rayTriangleWatertight themselves;
//   Simd::Sse2    two lanes of doubles (every x86-64 CPU);
//   Simd::Avx2    four lanes of doubles; compiled only where the translation unit is built for
//                 AVX2 (engine/src/rays/batch_trace_avx2.cpp) and chosen at run time when the
//                 CPU has it (simdSupported()).
// Each lane performs the scalar test's operations in the scalar test's order, in doubles and
// without fused multiply-adds (AVX2 has none; the engine never enables FMA), so t, u, v and every
// accept/reject decision are the scalar test's, bit for bit, whatever the width: the width
// changes the speed, never an answer (test_rays LeafTestsEqualTheScalarTests).
//
// Semantics, per leaf (references [begin, begin + count) of the payload; ids[] the tree's ids):
//   first()  offers every triangle hit with t in [tmin, hit.t] to hit (RayHit::offer: nearest,
//            ties to the smaller id), i.e. the one-by-one loop's outcome;
//   any()    whether a triangle is hit with t in [tmin, tmax]; `tested` gets the number of
//            triangles a one-by-one loop would have tested (up to the first hit in leaf order),
//            so the counters do not depend on the width either.
// A leaf is tested whole, without a mailbox: a triangle tested again in a later leaf of the same
// ray gives the same answer (the interval only shrinks), and a SIMD step costs less than sorting
// the repeats out.
#pragma once

#include <cmath>
#include <cstdint>
#include <limits>
#include <type_traits>
#include <utility>

#if defined(__SSE2__) || defined(_M_X64)
#include <emmintrin.h>
#define MT_LEAF_TEST_SSE2 1
#endif
#if defined(__AVX2__)
#include <immintrin.h>
#define MT_LEAF_TEST_AVX2 1
#endif

#include "mtree/rays/intersect.h"
#include "mtree/rays/leaf_triangles.h"
#include "mtree/rays/raycast.h"

namespace mtree {

enum class Simd : int { Scalar = 0, Sse2 = 1, Avx2 = 2 };

inline const char* simdName(Simd s) {
  return s == Simd::Avx2 ? "avx2" : (s == Simd::Sse2 ? "sse2" : "scalar");
}

/// The widest leaf test this build and this CPU run (AVX2 where the engine has its AVX2 unit and
/// the CPU reports AVX2, else SSE2 on x86-64, else Scalar).
Simd simdSupported();

/// A ray's constants for the leaf tests: its origin and direction, tmin, and for the watertight
/// test its shear (Woop, Benthin & Wald 2013: the axis of largest |d| as z, the other two
/// swapped where d[z] < 0 to keep the winding), computed once per ray as rayTriangleWatertight
/// computes them per triangle.
struct LeafRay {
  Vec3 o, d;
  double tmin = 0;
  int kx = 0, ky = 1, kz = 2;
  double sx = 0, sy = 0, sz = 0;
  /// Sets the ray (the shear only for the watertight test).
  template <TriangleTest Test>
  MT_ALWAYS_INLINE void set(Vec3 oo, Vec3 dd, double t0) {
    o = oo;
    d = dd;
    tmin = t0;
    if constexpr (Test == TriangleTest::Watertight) {
      const double adx = std::fabs(d.x), ady = std::fabs(d.y), adz = std::fabs(d.z);
      kz = 2;
      if (adx > ady) {
        if (adx > adz) kz = 0;
      } else if (ady > adz) {
        kz = 1;
      }
      kx = kz == 2 ? 0 : kz + 1;
      ky = kx == 2 ? 0 : kx + 1;
      if (d[kz] < 0) std::swap(kx, ky);
      sx = d[kx] / d[kz];
      sy = d[ky] / d[kz];
      sz = 1.0 / d[kz];
    }
  }
};

namespace detail {

/// 8 all-ones lanes then 8 zero lanes. Namespace-scope constexpr: internal linkage, so every unit
/// (the AVX2 one included) has its own copy and shares no symbol with the others.
alignas(64) constexpr uint64_t kLaneTable[16] = {~0ull, ~0ull, ~0ull, ~0ull, ~0ull, ~0ull, ~0ull, ~0ull,
                                                 0, 0, 0, 0, 0, 0, 0, 0};

/// W lanes of which the first n (clamped to [0, W]) are all-ones doubles and the rest zero: a
/// window of kLaneTable.
MT_ALWAYS_INLINE const double* laneTable(int n, int W) {
  const int on = n < 0 ? 0 : (n > W ? W : n);
  return reinterpret_cast<const double*>(kLaneTable + 8 - on);
}

/// Lane operations of one SIMD width: V a vector of doubles, masks as vectors of all-ones lanes.
#ifdef MT_LEAF_TEST_SSE2
struct Sse2Lanes {
  using V = __m128d;
  static constexpr int W = 2;
  static MT_ALWAYS_INLINE V load(const double* p) { return _mm_loadu_pd(p); }
  static MT_ALWAYS_INLINE V set1(double x) { return _mm_set1_pd(x); }
  static MT_ALWAYS_INLINE V add(V a, V b) { return _mm_add_pd(a, b); }
  static MT_ALWAYS_INLINE V sub(V a, V b) { return _mm_sub_pd(a, b); }
  static MT_ALWAYS_INLINE V mul(V a, V b) { return _mm_mul_pd(a, b); }
  static MT_ALWAYS_INLINE V div(V a, V b) { return _mm_div_pd(a, b); }
  static MT_ALWAYS_INLINE V lt(V a, V b) { return _mm_cmplt_pd(a, b); }
  static MT_ALWAYS_INLINE V le(V a, V b) { return _mm_cmple_pd(a, b); }
  static MT_ALWAYS_INLINE V gt(V a, V b) { return _mm_cmpgt_pd(a, b); }
  static MT_ALWAYS_INLINE V ge(V a, V b) { return _mm_cmpge_pd(a, b); }
  static MT_ALWAYS_INLINE V eq(V a, V b) { return _mm_cmpeq_pd(a, b); }
  static MT_ALWAYS_INLINE V neq(V a, V b) { return _mm_cmpneq_pd(a, b); }
  static MT_ALWAYS_INLINE V band(V a, V b) { return _mm_and_pd(a, b); }
  static MT_ALWAYS_INLINE V bor(V a, V b) { return _mm_or_pd(a, b); }
  static MT_ALWAYS_INLINE V andnot(V a, V b) { return _mm_andnot_pd(a, b); }  // ~a & b
  static MT_ALWAYS_INLINE int mask(V a) { return _mm_movemask_pd(a); }
  static MT_ALWAYS_INLINE void store(double* p, V a) { _mm_storeu_pd(p, a); }
  /// Lanes i < n on (all-ones), the others off; any n.
  static MT_ALWAYS_INLINE V first(int n) { return _mm_loadu_pd(laneTable(n, W)); }
};
#endif
#ifdef MT_LEAF_TEST_AVX2
struct Avx2Lanes {
  using V = __m256d;
  static constexpr int W = 4;
  static MT_ALWAYS_INLINE V load(const double* p) { return _mm256_loadu_pd(p); }
  static MT_ALWAYS_INLINE V set1(double x) { return _mm256_set1_pd(x); }
  static MT_ALWAYS_INLINE V add(V a, V b) { return _mm256_add_pd(a, b); }
  static MT_ALWAYS_INLINE V sub(V a, V b) { return _mm256_sub_pd(a, b); }
  static MT_ALWAYS_INLINE V mul(V a, V b) { return _mm256_mul_pd(a, b); }
  static MT_ALWAYS_INLINE V div(V a, V b) { return _mm256_div_pd(a, b); }
  static MT_ALWAYS_INLINE V lt(V a, V b) { return _mm256_cmp_pd(a, b, _CMP_LT_OQ); }
  static MT_ALWAYS_INLINE V le(V a, V b) { return _mm256_cmp_pd(a, b, _CMP_LE_OQ); }
  static MT_ALWAYS_INLINE V gt(V a, V b) { return _mm256_cmp_pd(a, b, _CMP_GT_OQ); }
  static MT_ALWAYS_INLINE V ge(V a, V b) { return _mm256_cmp_pd(a, b, _CMP_GE_OQ); }
  static MT_ALWAYS_INLINE V eq(V a, V b) { return _mm256_cmp_pd(a, b, _CMP_EQ_OQ); }
  // Unordered not-equal, as SSE2's cmpneq: true for NaN.
  static MT_ALWAYS_INLINE V neq(V a, V b) { return _mm256_cmp_pd(a, b, _CMP_NEQ_UQ); }
  static MT_ALWAYS_INLINE V band(V a, V b) { return _mm256_and_pd(a, b); }
  static MT_ALWAYS_INLINE V bor(V a, V b) { return _mm256_or_pd(a, b); }
  static MT_ALWAYS_INLINE V andnot(V a, V b) { return _mm256_andnot_pd(a, b); }
  static MT_ALWAYS_INLINE int mask(V a) { return _mm256_movemask_pd(a); }
  static MT_ALWAYS_INLINE void store(double* p, V a) { _mm256_storeu_pd(p, a); }
  static MT_ALWAYS_INLINE V first(int n) { return _mm256_loadu_pd(laneTable(n, W)); }
};
#endif

/// rayTriangleMT (geometry.h) in the lanes of X for references [k, k + X::W) of the payload:
/// the mask of the lanes on in `on` that are hit with t in [tmin, tmax] (t, u, v stored for
/// them). The lanes off are dropped before the first early exit, so that a step with no
/// triangle to test (no lane on) takes that exit every time.
template <class X>
MT_ALWAYS_INLINE int mollerTrumboreLanes(const LeafTriangles& P, size_t k, const LeafRay& r, double tmax,
                                         typename X::V on, double* t, double* u, double* v) {
  using V = typename X::V;
  const V ax = X::load(P.coord(0) + k), ay = X::load(P.coord(1) + k), az = X::load(P.coord(2) + k);
  const V e1x = X::sub(X::load(P.coord(3) + k), ax), e1y = X::sub(X::load(P.coord(4) + k), ay),
          e1z = X::sub(X::load(P.coord(5) + k), az);
  const V e2x = X::sub(X::load(P.coord(6) + k), ax), e2y = X::sub(X::load(P.coord(7) + k), ay),
          e2z = X::sub(X::load(P.coord(8) + k), az);
  const V dx = X::set1(r.d.x), dy = X::set1(r.d.y), dz = X::set1(r.d.z);
  // p = cross(d, e2); det = dot(e1, p)
  const V px = X::sub(X::mul(dy, e2z), X::mul(dz, e2y));
  const V py = X::sub(X::mul(dz, e2x), X::mul(dx, e2z));
  const V pz = X::sub(X::mul(dx, e2y), X::mul(dy, e2x));
  const V det = X::add(X::add(X::mul(e1x, px), X::mul(e1y, py)), X::mul(e1z, pz));
  const V zero = X::set1(0.0), one = X::set1(1.0);
  // det != 0 and finite: |det| <= the largest double (NaN fails the ordered compare).
  const V absDet = X::andnot(X::set1(-0.0), det);
  V ok = X::band(X::neq(det, zero), X::le(absDet, X::set1(std::numeric_limits<double>::max())));
  const V pos = X::gt(det, zero);
  const V sg = X::bor(X::band(pos, one), X::andnot(pos, X::set1(-1.0)));
  const V adet = X::mul(det, sg);
  // s = o - a; un = dot(s, p) * sg
  const V sx = X::sub(X::set1(r.o.x), ax), sy = X::sub(X::set1(r.o.y), ay), sz = X::sub(X::set1(r.o.z), az);
  const V un = X::mul(X::add(X::add(X::mul(sx, px), X::mul(sy, py)), X::mul(sz, pz)), sg);
  ok = X::band(ok, X::band(X::ge(un, zero), X::le(un, adet)));
  // q = cross(s, e1); vn = dot(d, q) * sg
  const V qx = X::sub(X::mul(sy, e1z), X::mul(sz, e1y));
  const V qy = X::sub(X::mul(sz, e1x), X::mul(sx, e1z));
  const V qz = X::sub(X::mul(sx, e1y), X::mul(sy, e1x));
  const V vn = X::mul(X::add(X::add(X::mul(dx, qx), X::mul(dy, qy)), X::mul(dz, qz)), sg);
  ok = X::band(X::band(ok, on), X::band(X::ge(vn, zero), X::le(X::add(un, vn), adet)));
  if (X::mask(ok) == 0) return 0;  // outside an edge in every lane: the common case
  const V inv = X::div(one, det);
  const V tt = X::mul(X::add(X::add(X::mul(e2x, qx), X::mul(e2y, qy)), X::mul(e2z, qz)), inv);
  ok = X::band(ok, X::band(X::ge(tt, X::set1(r.tmin)), X::le(tt, X::set1(tmax))));
  const int m = X::mask(ok);
  if (m == 0) return 0;
  X::store(t, tt);
  X::store(u, X::mul(X::mul(un, sg), inv));
  X::store(v, X::mul(X::mul(vn, sg), inv));
  return m;
}

/// rayTriangleWatertight (intersect.h) in the lanes of X, with the ray's shear from LeafRay.
template <class X>
MT_ALWAYS_INLINE int watertightLanes(const LeafTriangles& P, size_t k, const LeafRay& r, double tmax,
                                     typename X::V on, double* t, double* u, double* v) {
  using V = typename X::V;
  const V ox = X::set1(r.o[r.kx]), oy = X::set1(r.o[r.ky]), oz = X::set1(r.o[r.kz]);
  const V sx = X::set1(r.sx), sy = X::set1(r.sy);
  // Corner c relative to the origin, sheared and projected: (c[kx] - sx c[kz], c[ky] - sy c[kz]).
  V px[3], py[3], pz[3];
  for (int c = 0; c < 3; ++c) {
    const V X0 = X::sub(X::load(P.coord(3 * c + r.kx) + k), ox);
    const V Y0 = X::sub(X::load(P.coord(3 * c + r.ky) + k), oy);
    pz[c] = X::sub(X::load(P.coord(3 * c + r.kz) + k), oz);
    px[c] = X::sub(X0, X::mul(sx, pz[c]));
    py[c] = X::sub(Y0, X::mul(sy, pz[c]));
  }
  const V U = X::sub(X::mul(px[2], py[1]), X::mul(py[2], px[1]));
  const V Vv = X::sub(X::mul(px[0], py[2]), X::mul(py[0], px[2]));
  const V Ww = X::sub(X::mul(px[1], py[0]), X::mul(py[1], px[0]));
  const V zero = X::set1(0.0);
  const V anyNeg = X::bor(X::bor(X::lt(U, zero), X::lt(Vv, zero)), X::lt(Ww, zero));
  const V anyPos = X::bor(X::bor(X::gt(U, zero), X::gt(Vv, zero)), X::gt(Ww, zero));
  const V det = X::add(X::add(U, Vv), Ww);
  const V absDet = X::andnot(X::set1(-0.0), det);
  // Not mixed signs, det != 0 and finite.
  V ok = X::andnot(X::band(anyNeg, anyPos),
                   X::band(X::band(X::neq(det, zero), X::le(absDet, X::set1(std::numeric_limits<double>::max()))), on));
  if (X::mask(ok) == 0) return 0;
  const V sz = X::set1(r.sz);
  const V T = X::add(X::add(X::mul(U, X::mul(sz, pz[0])), X::mul(Vv, X::mul(sz, pz[1]))), X::mul(Ww, X::mul(sz, pz[2])));
  const V inv = X::div(X::set1(1.0), det);
  const V tt = X::mul(T, inv);
  const V absT = X::andnot(X::set1(-0.0), tt);
  ok = X::band(ok, X::band(X::band(X::ge(tt, X::set1(r.tmin)), X::le(tt, X::set1(tmax))),
                           X::lt(absT, X::set1(std::numeric_limits<double>::infinity()))));
  const int m = X::mask(ok);
  if (m == 0) return 0;
  X::store(t, tt);
  X::store(u, X::mul(Vv, inv));
  X::store(v, X::mul(Ww, inv));
  return m;
}

template <class X, TriangleTest Test>
MT_ALWAYS_INLINE int testLanes(const LeafTriangles& P, size_t k, const LeafRay& r, double tmax, typename X::V on,
                               double* t, double* u, double* v) {
  if constexpr (Test == TriangleTest::Watertight)
    return watertightLanes<X>(P, k, r, tmax, on, t, u, v);
  else
    return mollerTrumboreLanes<X>(P, k, r, tmax, on, t, u, v);
}

/// The scalar test of reference k, on the payload's corners.
template <TriangleTest Test>
MT_ALWAYS_INLINE bool testOne(const LeafTriangles& P, size_t k, const LeafRay& r, double tmax, double& t, double& u,
                              double& v) {
  const Vec3 a(P.coord(0)[k], P.coord(1)[k], P.coord(2)[k]);
  const Vec3 b(P.coord(3)[k], P.coord(4)[k], P.coord(5)[k]);
  const Vec3 c(P.coord(6)[k], P.coord(7)[k], P.coord(8)[k]);
  return rayTriangleT<Test>(r.o, r.d, a, b, c, r.tmin, tmax, t, u, v);
}

}  // namespace detail

/// The leaf tests of one width (see the file comment), for count >= 1 (the SIMD widths test one
/// step of lanes, all off, for count = 0). Lanes past the leaf's last triangle are off from the
/// start, so the neighbouring leaf's triangles that fill them never cost a division.
template <Simd S, TriangleTest Test>
struct LeafTest {
  static MT_ALWAYS_INLINE void first(const LeafTriangles& P, const uint32_t* ids, uint32_t begin, uint32_t count,
                                     const LeafRay& r, RayHit& hit) {
    if constexpr (S == Simd::Scalar) {
      for (uint32_t j = 0; j < count; ++j) {
        double t, u, v;
        if (detail::testOne<Test>(P, size_t(begin) + j, r, hit.t, t, u, v)) hit.offer(ids[begin + j], t, u, v);
      }
    } else {
      using X = Lanes;
      uint32_t j = 0;
      do {
        alignas(32) double t[X::W], u[X::W], v[X::W];
        int m = detail::testLanes<X, Test>(P, size_t(begin) + j, r, hit.t, X::first(int(count - j)), t, u, v);
        while (m) {
          const int lane = __builtin_ctz(unsigned(m));
          m &= m - 1;
          hit.offer(ids[begin + j + lane], t[lane], u[lane], v[lane]);
        }
        j += X::W;
      } while (j < count);
    }
  }
  static MT_ALWAYS_INLINE bool any(const LeafTriangles& P, uint32_t begin, uint32_t count, const LeafRay& r,
                                   double tmax, uint32_t& tested) {
    if constexpr (S == Simd::Scalar) {
      for (uint32_t j = 0; j < count; ++j) {
        double t, u, v;
        if (detail::testOne<Test>(P, size_t(begin) + j, r, tmax, t, u, v)) {
          tested = j + 1;
          return true;
        }
      }
    } else {
      using X = Lanes;
      uint32_t j = 0;
      do {
        alignas(32) double t[X::W], u[X::W], v[X::W];
        const int m = detail::testLanes<X, Test>(P, size_t(begin) + j, r, tmax, X::first(int(count - j)), t, u, v);
        if (m) {
          tested = j + uint32_t(__builtin_ctz(unsigned(m))) + 1;
          return true;
        }
        j += X::W;
      } while (j < count);
    }
    tested = count;
    return false;
  }

 private:
  struct NoLanes {};
#if defined(MT_LEAF_TEST_AVX2)
  using Avx2OrNone = detail::Avx2Lanes;
#else
  using Avx2OrNone = NoLanes;
#endif
#if defined(MT_LEAF_TEST_SSE2)
  using Sse2OrNone = detail::Sse2Lanes;
#else
  using Sse2OrNone = NoLanes;
#endif
  using Lanes = std::conditional_t<S == Simd::Avx2, Avx2OrNone, Sse2OrNone>;
};

}  // namespace mtree

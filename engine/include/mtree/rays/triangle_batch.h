// Ray/triangle tests over a list of triangles (a leaf's references), shared by the traversals of
// every tree, so that only the tree and its walk differ between them.
#pragma once

#include <cstdint>
#include <limits>

#if defined(__SSE2__) || defined(_M_X64)
#include <emmintrin.h>
#define MT_TRIANGLE_BATCH_SSE2 1
#endif

#include "mtree/rays/intersect.h"
#include "mtree/core/primitives.h"

namespace mtree {

/// Tests the triangles ids[0..n) in list order and calls hit(k, t, u, v) for each one the ray
/// o + t d meets with t in [tmin, tmax], k its position in the list (the triangle is ids[k]); a
/// true return from hit() stops the list (and the call returns true). `tmax` is read again before every triangle or pair, so a first-hit caller that
/// lowers it in hit() narrows the rest of the list.
///
/// Moller-Trumbore runs two triangles per step in SSE2 lanes: each lane performs rayTriangleMT's
/// operations in rayTriangleMT's order (SSE2 has no fused multiply-add), so t, u, v and every
/// accept/reject decision are rayTriangleMT's bit for bit, and its data-dependent early exits
/// (the edge tests, which most candidates fail) become lane masks instead of branches the
/// predictor cannot learn. Both lanes of a pair see the tmax of the pair's start, so the second
/// may be reported with a t above a hit just found in the first: a first-hit caller keeps the
/// smaller (with the tie rule on ids the outcome is the one-by-one loop's). The watertight test,
/// and builds without SSE2, go one by one.
template <TriangleTest Test, class Hit>
inline bool testTriangles(const TriangleMesh& mesh, Vec3 o, Vec3 d, const uint32_t* ids, uint32_t n, double tmin,
                          const double& tmax, Hit&& hit) {
  uint32_t k = 0;
#ifdef MT_TRIANGLE_BATCH_SSE2
  if constexpr (Test == TriangleTest::MollerTrumbore) {
    const __m128d ox = _mm_set1_pd(o.x), oy = _mm_set1_pd(o.y), oz = _mm_set1_pd(o.z);
    const __m128d dx = _mm_set1_pd(d.x), dy = _mm_set1_pd(d.y), dz = _mm_set1_pd(d.z);
    const __m128d zero = _mm_setzero_pd(), one = _mm_set1_pd(1.0), minusOne = _mm_set1_pd(-1.0);
    const __m128d maxFinite = _mm_set1_pd(std::numeric_limits<double>::max());
    const __m128d absMask = _mm_castsi128_pd(_mm_set1_epi64x(0x7fffffffffffffffLL));
    const __m128d lo = _mm_set1_pd(tmin);
    for (; k + 1 < n; k += 2) {
      const uint32_t i0 = ids[k], i1 = ids[k + 1];
      const Vec3 a0 = mesh.vertex(i0, 0), b0 = mesh.vertex(i0, 1), c0 = mesh.vertex(i0, 2);
      const Vec3 a1 = mesh.vertex(i1, 0), b1 = mesh.vertex(i1, 1), c1 = mesh.vertex(i1, 2);
      const __m128d ax = _mm_set_pd(a1.x, a0.x), ay = _mm_set_pd(a1.y, a0.y), az = _mm_set_pd(a1.z, a0.z);
      // e1 = b - a, e2 = c - a
      const __m128d e1x = _mm_sub_pd(_mm_set_pd(b1.x, b0.x), ax), e1y = _mm_sub_pd(_mm_set_pd(b1.y, b0.y), ay),
                    e1z = _mm_sub_pd(_mm_set_pd(b1.z, b0.z), az);
      const __m128d e2x = _mm_sub_pd(_mm_set_pd(c1.x, c0.x), ax), e2y = _mm_sub_pd(_mm_set_pd(c1.y, c0.y), ay),
                    e2z = _mm_sub_pd(_mm_set_pd(c1.z, c0.z), az);
      // p = cross(d, e2); det = dot(e1, p)
      const __m128d px = _mm_sub_pd(_mm_mul_pd(dy, e2z), _mm_mul_pd(dz, e2y));
      const __m128d py = _mm_sub_pd(_mm_mul_pd(dz, e2x), _mm_mul_pd(dx, e2z));
      const __m128d pz = _mm_sub_pd(_mm_mul_pd(dx, e2y), _mm_mul_pd(dy, e2x));
      const __m128d det =
          _mm_add_pd(_mm_add_pd(_mm_mul_pd(e1x, px), _mm_mul_pd(e1y, py)), _mm_mul_pd(e1z, pz));
      // det != 0 and finite (NaN fails the ordered <=)
      __m128d ok = _mm_and_pd(_mm_cmpneq_pd(det, zero), _mm_cmple_pd(_mm_and_pd(det, absMask), maxFinite));
      const __m128d pos = _mm_cmpgt_pd(det, zero);
      const __m128d sg = _mm_or_pd(_mm_and_pd(pos, one), _mm_andnot_pd(pos, minusOne));
      const __m128d adet = _mm_mul_pd(det, sg);
      // s = o - a; un = dot(s, p) * sg
      const __m128d sx = _mm_sub_pd(ox, ax), sy = _mm_sub_pd(oy, ay), sz = _mm_sub_pd(oz, az);
      const __m128d un =
          _mm_mul_pd(_mm_add_pd(_mm_add_pd(_mm_mul_pd(sx, px), _mm_mul_pd(sy, py)), _mm_mul_pd(sz, pz)), sg);
      ok = _mm_and_pd(ok, _mm_and_pd(_mm_cmpge_pd(un, zero), _mm_cmple_pd(un, adet)));
      // q = cross(s, e1); vn = dot(d, q) * sg
      const __m128d qx = _mm_sub_pd(_mm_mul_pd(sy, e1z), _mm_mul_pd(sz, e1y));
      const __m128d qy = _mm_sub_pd(_mm_mul_pd(sz, e1x), _mm_mul_pd(sx, e1z));
      const __m128d qz = _mm_sub_pd(_mm_mul_pd(sx, e1y), _mm_mul_pd(sy, e1x));
      const __m128d vn =
          _mm_mul_pd(_mm_add_pd(_mm_add_pd(_mm_mul_pd(dx, qx), _mm_mul_pd(dy, qy)), _mm_mul_pd(dz, qz)), sg);
      ok = _mm_and_pd(ok, _mm_and_pd(_mm_cmpge_pd(vn, zero), _mm_cmple_pd(_mm_add_pd(un, vn), adet)));
      if (_mm_movemask_pd(ok) == 0) continue;  // both outside an edge: the common case
      const __m128d inv = _mm_div_pd(one, det);
      const __m128d uu = _mm_mul_pd(_mm_mul_pd(un, sg), inv), vv = _mm_mul_pd(_mm_mul_pd(vn, sg), inv);
      const __m128d tt = _mm_mul_pd(
          _mm_add_pd(_mm_add_pd(_mm_mul_pd(e2x, qx), _mm_mul_pd(e2y, qy)), _mm_mul_pd(e2z, qz)), inv);
      ok = _mm_and_pd(ok, _mm_and_pd(_mm_cmpge_pd(tt, lo), _mm_cmple_pd(tt, _mm_set1_pd(tmax))));
      const int m = _mm_movemask_pd(ok);
      if (m == 0) continue;
      alignas(16) double t[2], u[2], v[2];
      _mm_store_pd(t, tt);
      _mm_store_pd(u, uu);
      _mm_store_pd(v, vv);
      if ((m & 1) && hit(k, t[0], u[0], v[0])) return true;
      if ((m & 2) && hit(k + 1, t[1], u[1], v[1])) return true;
    }
  }
#endif
  for (; k < n; ++k) {
    const uint32_t id = ids[k];
    double t, u, v;
    if (rayTriangleT<Test>(o, d, mesh.vertex(id, 0), mesh.vertex(id, 1), mesh.vertex(id, 2), tmin, tmax, t, u, v) &&
        hit(k, t, u, v))
      return true;
  }
  return false;
}

}  // namespace mtree

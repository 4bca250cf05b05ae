// The batch tracers' walks and leaf loops (batch_trace.h), as templates over the leaf test's
// width. Included by one translation unit per instruction set, each inside its own namespace
// (MT_BATCH_NS), so that the AVX2 unit's code never stands in for the baseline's:
//   batch_trace.cpp       namespace batch_base: Simd::Scalar and Simd::Sse2;
//   batch_trace_avx2.cpp  namespace batch_avx2: Simd::Avx2, the file compiled with -mavx2.
// batch_trace.cpp chooses between them once per batch.
#pragma once

#ifndef MT_BATCH_NS
#error "define MT_BATCH_NS (the namespace of this instruction set's instantiation) before including"
#endif

#include <algorithm>
#include <limits>

#include "mtree/rays/batch_trace.h"

namespace mtree {
namespace MT_BATCH_NS {

#if defined(MT_LEAF_TEST_AVX2)
/// TableWalk::step with the three axes in the lanes of AVX2 registers (lane 3 idle: its mask
/// is -1, its plane +inf, its cell 0): the same operations per axis in the same order on doubles
/// and 32-bit ints, so the same cells, planes and t to the bit (test_rays
/// BatchWalkIsTheSingleRayWalk), in about a third of the scalar step's instructions and
/// without a branch.
struct Avx2Walk {
  const MatrixTree::TableWalk::Tables& k;
  __m256d cs, invLeaf;
  __m128i dim, lanes;
  explicit Avx2Walk(const MatrixTree::TableWalk& w) : k(w.tables()) {
    cs = _mm256_setr_pd(k.cs.x, k.cs.y, k.cs.z, 0.0);
    invLeaf = _mm256_setr_pd(k.invLeaf.x, k.invLeaf.y, k.invLeaf.z, 0.0);
    dim = _mm_setr_epi32(k.dim[0], k.dim[1], k.dim[2], 1);
    lanes = _mm_setr_epi32(0, 1, 2, 3);
  }
  /// A ray's walk: TableRay's fields as lanes.
  struct Ray {
    __m256d o, d, inv, never;
    __m128i L, up;
    double te, t1;
    uint32_t e, p;
    int stepsLeft;
  };
  /// TableWalk::start (detail::RayClip, then the first cell) in lanes, with the same operations:
  /// the reciprocals, which axes move, the slab test (per lane, then reduced over x, y, z in
  /// RayClip's order with its std::min / std::max) and the first cell's clamp.
  MT_ALWAYS_INLINE bool start(Vec3 o3, Vec3 d3, double tmin, double tmax, Ray& r) const {
    const __m256d o = _mm256_setr_pd(o3.x, o3.y, o3.z, 0.0), d = _mm256_setr_pd(d3.x, d3.y, d3.z, 0.0);
    const __m256d zero = _mm256_setzero_pd(), inf = _mm256_set1_pd(std::numeric_limits<double>::infinity());
    const __m256d absMask = _mm256_castsi256_pd(_mm256_set1_epi64x(0x7fffffffffffffffLL));
    const __m256d big = _mm256_set1_pd(std::numeric_limits<double>::max());
    // Finite o and d (NaN fails the ordered compare), tmin <= tmax, d not zero.
    const int finite = _mm256_movemask_pd(_mm256_and_pd(_mm256_cmp_pd(_mm256_and_pd(o, absMask), big, _CMP_LE_OQ),
                                                        _mm256_cmp_pd(_mm256_and_pd(d, absMask), big, _CMP_LE_OQ)));
    const __m256d dNonZero = _mm256_cmp_pd(d, zero, _CMP_NEQ_UQ);
    if (finite != 0xF || !(tmin <= tmax) || (_mm256_movemask_pd(dNonZero) & 7) == 0) return false;
    const __m256d q = _mm256_div_pd(_mm256_set1_pd(1.0), d);
    const __m256d recip = _mm256_and_pd(q, dNonZero);  // d != 0 ? 1 / d : 0
    const __m256d moves = _mm256_and_pd(_mm256_cmp_pd(_mm256_and_pd(recip, absMask), inf, _CMP_LT_OQ), dNonZero);
    r.inv = _mm256_and_pd(recip, moves);
    r.never = _mm256_andnot_pd(moves, inf);
    // The 64-bit lanes' masks as 32-bit lanes (their low halves).
    r.up = _mm256_castsi256_si128(_mm256_permutevar8x32_epi32(_mm256_castpd_si256(_mm256_cmp_pd(d, zero, _CMP_GT_OQ)),
                                                              _mm256_setr_epi32(0, 2, 4, 6, 1, 3, 5, 7)));
    const __m256d lo = _mm256_setr_pd(k.root.lo.x, k.root.lo.y, k.root.lo.z, 0.0);
    const __m256d hi = _mm256_setr_pd(k.root.hi.x, k.root.hi.y, k.root.hi.z, 0.0);
    const int mv = _mm256_movemask_pd(moves);
    // An axis the ray does not move along: the origin must lie in the root's slab.
    const int outside = _mm256_movemask_pd(_mm256_or_pd(_mm256_cmp_pd(o, lo, _CMP_LT_OQ), _mm256_cmp_pd(o, hi, _CMP_GT_OQ)));
    if (outside & ~mv & 7) return false;
    const __m256d tn = _mm256_mul_pd(_mm256_sub_pd(lo, o), r.inv), tf = _mm256_mul_pd(_mm256_sub_pd(hi, o), r.inv);
    alignas(32) double near[4], far[4];
    _mm256_store_pd(near, _mm256_min_pd(tf, tn));  // std::min(tn, tf)
    _mm256_store_pd(far, _mm256_max_pd(tf, tn));   // std::max(tn, tf)
    double t0 = tmin, t1 = tmax;
    for (int a = 0; a < 3; ++a) {
      if (!((mv >> a) & 1)) continue;
      t0 = std::max(t0, near[a]);
      t1 = std::min(t1, far[a]);
    }
    if (!(t0 <= t1)) return false;
    r.o = _mm256_sub_pd(o, lo);
    r.d = d;
    r.te = t0;
    r.t1 = t1;
    // The first cell: cellIndexNonNegative((o + d t0) invLeaf, 0, dim - 1).
    const __m256d pt = _mm256_mul_pd(_mm256_add_pd(r.o, _mm256_mul_pd(d, _mm256_set1_pd(t0))), invLeaf);
    const __m256d c = _mm256_min_pd(_mm256_max_pd(pt, zero), _mm256_cvtepi32_pd(_mm_sub_epi32(dim, _mm_set1_epi32(1))));
    r.L = _mm256_cvttpd_epi32(c);
    place(r);
    r.stepsLeft = k.maxSteps;
    return true;
  }
  /// r.p and r.e of the cell r.L.
  MT_ALWAYS_INLINE void place(Ray& r) const {
    const uint32_t x = uint32_t(_mm_cvtsi128_si32(r.L)), y = uint32_t(_mm_extract_epi32(r.L, 1)),
                   z = uint32_t(_mm_extract_epi32(r.L, 2));
    r.p = ((z >> 3) << (k.logPx + k.logPy)) | ((y >> 3) << k.logPx) | (x >> 3);
    r.e = k.blocks[r.p] + (((z & 7) << 6) | ((y & 7) << 3) | (x & 7));
  }
  MT_ALWAYS_INLINE TableStep step(Ray& r) const {
    const uint8_t v = k.bytes[r.e];
    const int level = v & 0x7F;
    const __m128i m = _mm_loadu_si128(reinterpret_cast<const __m128i*>(k.mask[level].data()));
    const __m128i ones = _mm_set1_epi32(-1);
    // The node, or in an absent block its empty box (bytes 0-2 low, 4-6 high corner, in blocks).
    const __m128i box = _mm_loadl_epi64(reinterpret_cast<const __m128i*>(k.boxes + r.p));
    const __m128i inBox = _mm_set1_epi32(level <= k.boxLevel ? -1 : 0);
    const __m128i boxLo = _mm_slli_epi32(_mm_cvtepu8_epi32(box), 3);
    const __m128i boxHi = _mm_or_si128(_mm_slli_epi32(_mm_cvtepu8_epi32(_mm_srli_si128(box, 4)), 3), _mm_set1_epi32(7));
    const __m128i lo = _mm_blendv_epi8(_mm_and_si128(r.L, m), boxLo, inBox);
    const __m128i hi = _mm_blendv_epi8(_mm_or_si128(r.L, _mm_xor_si128(m, ones)), boxHi, inBox);
    const __m128i hi1 = _mm_sub_epi32(hi, ones), lo1 = _mm_add_epi32(lo, ones);  // hi + 1, lo - 1
    // planeCrossing: (edge * cs - o) * inv + never
    const __m256d edge = _mm256_cvtepi32_pd(_mm_blendv_epi8(lo, hi1, r.up));
    const __m256d t = _mm256_add_pd(_mm256_mul_pd(_mm256_sub_pd(_mm256_mul_pd(edge, cs), r.o), r.inv), r.never);
    // nearestExit: the least t (lane 3 is +inf), the lowest axis among equals.
    const __m256d m1 = _mm256_min_pd(t, _mm256_permute_pd(t, 0x5));
    const __m256d tm4 = _mm256_min_pd(m1, _mm256_permute2f128_pd(m1, m1, 1));
    const int ax0 = __builtin_ctz(unsigned(_mm256_movemask_pd(_mm256_cmp_pd(t, tm4, _CMP_EQ_OQ))) | 8u);
    const double tm = _mm256_cvtsd_f64(tm4);
    const bool ends = !(tm < r.t1);
    TableStep out;
    out.tExit = std::max(ends ? r.t1 : tm, r.te);
    out.tEnter = r.te;
    out.here = r.e;
    out.leaf = (v & 0x80) != 0;
    out.L[0] = _mm_cvtsi128_si32(r.L);
    out.L[1] = _mm_extract_epi32(r.L, 1);
    out.L[2] = _mm_extract_epi32(r.L, 2);
    // The next cell: clampCell((o + d tExit) invLeaf, lo, hi), then the integer step on the axis.
    const __m256d p = _mm256_mul_pd(_mm256_add_pd(r.o, _mm256_mul_pd(r.d, _mm256_set1_pd(out.tExit))), invLeaf);
    const __m256d c = _mm256_min_pd(_mm256_max_pd(p, _mm256_cvtepi32_pd(lo)), _mm256_cvtepi32_pd(hi));
    const __m128i onAxis = _mm_cmpeq_epi32(lanes, _mm_set1_epi32(ax0));
    const __m128i n = _mm_blendv_epi8(_mm256_cvttpd_epi32(c), _mm_blendv_epi8(lo1, hi1, r.up), onAxis);
    // Outside the root: some coordinate < 0 or >= its dimension.
    const __m128i bad = _mm_or_si128(_mm_cmpgt_epi32(_mm_setzero_si128(), n), _mm_cmpgt_epi32(_mm_add_epi32(n, _mm_set1_epi32(1)), dim));
    out.next = !ends & (_mm_movemask_epi8(bad) == 0) & (--r.stepsLeft > 0);
    if (out.next) {
      r.L = n;
      place(r);
      __builtin_prefetch(k.ranges + r.e);
    }
    r.te = out.tExit;
    return out;
  }
};
#endif

/// TableWalk::step itself, as the interleaved walk's walker.
struct ScalarWalk {
  const MatrixTree::TableWalk& w;
  explicit ScalarWalk(const MatrixTree::TableWalk& walk) : w(walk) {}
  using Ray = TableRay;
  MT_ALWAYS_INLINE bool start(Vec3 o, Vec3 d, double tmin, double tmax, Ray& r) const {
    return w.start(o, d, tmin, tmax, r);
  }
  MT_ALWAYS_INLINE TableStep step(Ray& r) const { return w.step(r); }
};

/// One ray's place in the interleaved matrix walk, with its leaf-test constants and its answer.
template <class Walker>
struct MatrixSlot {
  typename Walker::Ray walk;
  LeafRay ray;
  RayHit hit;      // first hit so far (hit.t: the interval's end while nothing is hit)
  double tmax;     // any-hit: the interval's end
  size_t index;    // the ray's place in the batch
  uint32_t visits, tests;
  bool live;
};

/// The matrix tree's table walk over a batch, K rays in flight: each slot holds one ray, every
/// round steps every live slot once (the walker's step, then the leaf's tests), and a slot whose
/// ray ends takes the batch's next ray. A ray's steps are exactly its steps alone (the slots
/// share nothing but the tree); K only changes how the core overlaps them.
template <Simd S, TriangleTest T, bool Any, bool Count, int K>
void matrixBatch(const MatrixTree& tree, const LeafTriangles& P, const RayBatch& b, RayHit* hits, uint8_t* blocked,
                 RayCounters ctr) {
  const MatrixTree::TableWalk w(tree);
#if defined(MT_LEAF_TEST_AVX2)
  using Walker = std::conditional_t<S == Simd::Avx2, Avx2Walk, ScalarWalk>;
#else
  using Walker = ScalarWalk;
#endif
  const Walker walker(w);
  const uint32_t* ids = tree.primitiveIndices().data();
  constexpr double kInf = std::numeric_limits<double>::infinity();
  MatrixSlot<Walker> slot[K];
  size_t next = 0;
  auto finish = [&](const MatrixSlot<Walker>& x) {
    if constexpr (Any) {
      blocked[x.index] = x.hit.prim != MT_NULL;
    } else {
      hits[x.index] = x.hit;
      if (!x.hit.hit()) hits[x.index].t = kInf;
    }
    if constexpr (Count) {
      ctr.visits[x.index] += x.visits;
      ctr.tests[x.index] += x.tests;
    }
  };
  // The batch's next ray that enters the root box into x; rays that miss it are answered here.
  auto load = [&](MatrixSlot<Walker>& x) -> bool {
    while (next < b.n) {
      const size_t i = next++;
      const double tmax = b.tMax(i);
      if (walker.start(b.o[i], b.d[i], b.tMin(i), tmax, x.walk)) {
        x.ray.template set<T>(b.o[i], b.d[i], b.tMin(i));
        x.hit.prim = MT_NULL;
        x.hit.t = tmax;
        x.hit.u = x.hit.v = 0;
        x.tmax = tmax;
        x.index = i;
        x.visits = x.tests = 0;
        x.live = true;
        return true;
      }
      if constexpr (Any) {
        blocked[i] = 0;
      } else {
        hits[i] = RayHit{};
      }
    }
    x.live = false;
    return false;
  };
  int live = 0;
  for (int k = 0; k < K; ++k) live += load(slot[k]);
  while (live > 0) {
    for (int k = 0; k < K; ++k) {
      MatrixSlot<Walker>& x = slot[k];
      if (!x.live) continue;  // only once the batch runs out of rays
      const TableStep st = walker.step(x.walk);
      if constexpr (Count) ++x.visits;
      bool done = !st.next;
      if (st.leaf) {
        const MtLeafRange r = w.leafRange(st.here);
        const uint32_t count = r.end - r.begin;
        if constexpr (Any) {
          uint32_t tested;
          if (LeafTest<S, T>::any(P, r.begin, count, x.ray, x.tmax, tested)) {
            x.hit.prim = 0;  // found: any id marks it
            done = true;
          }
          if constexpr (Count) x.tests += tested;
        } else {
          LeafTest<S, T>::first(P, ids, r.begin, count, x.ray, x.hit);
          if constexpr (Count) x.tests += count;
          // A hit inside this node (t <= tExit) cannot be beaten by a later node.
          done = done || (x.hit.prim != MT_NULL && x.hit.t <= st.tExit);
        }
      }
      if (done) {
        finish(x);
        live -= !load(x);
      }
    }
  }
}

/// The payload's leaf tests for one ray: the SAH walks' visitor (SahKdTree::walk), and the leaf
/// callback of MatrixTree::traverseRay.
template <Simd S, TriangleTest T, bool Any>
struct PayloadVisitor {
  const LeafTriangles& P;
  const uint32_t* ids;
  LeafRay ray;
  RayHit hit;
  double tmax;
  uint64_t tests = 0;
  bool found = false;
  /// Ray k of the batch, no hit yet.
  PayloadVisitor(const LeafTriangles& payload, const uint32_t* treeIds, const RayBatch& b, size_t k)
      : P(payload), ids(treeIds), tmax(b.tMax(k)) {
    ray.template set<T>(b.o[k], b.d[k], b.tMin(k));
    hit.t = tmax;
  }
  double cutoff() const {
    if constexpr (Any) return std::numeric_limits<double>::infinity();
    return hit.prim != MT_NULL ? hit.t : std::numeric_limits<double>::infinity();
  }
  bool leaf(const uint32_t* leafIds, uint32_t count) {
    const uint32_t begin = static_cast<uint32_t>(leafIds - ids);
    if constexpr (Any) {
      uint32_t tested;
      found = LeafTest<S, T>::any(P, begin, count, ray, tmax, tested);
      tests += tested;
      return found;
    } else {
      LeafTest<S, T>::first(P, ids, begin, count, ray, hit);
      tests += count;
      return false;
    }
  }
  /// Ray i's answer into blocked (any hit) or hits (first hit, t = inf on a miss); with Count,
  /// its node visits and tests added to ctr.
  template <bool Count>
  void store(size_t i, uint64_t visits, RayHit* hits, uint8_t* blocked, const RayCounters& ctr) {
    if constexpr (Any) {
      blocked[i] = found;
    } else {
      if (!hit.hit()) hit.t = std::numeric_limits<double>::infinity();
      hits[i] = hit;
    }
    if constexpr (Count) {
      ctr.visits[i] += static_cast<uint32_t>(visits);
      ctr.tests[i] += static_cast<uint32_t>(tests);
    }
  }
};

/// One ray at a time through MatrixTree::traverseRay (a tree without a step table), with the
/// payload's leaf tests.
template <Simd S, TriangleTest T, bool Any, bool Count>
void matrixSingle(const MatrixTree& tree, const LeafTriangles& P, const RayBatch& b, RayHit* hits, uint8_t* blocked,
                  RayCounters ctr) {
  for (size_t i = 0; i < b.n; ++i) {
    PayloadVisitor<S, T, Any> vis(P, tree.primitiveIndices().data(), b, i);
    TraversalStats st;
    tree.traverseRay(
        b.o[i], b.d[i], b.tMin(i), vis.tmax,
        [&](const uint32_t* leafIds, uint32_t count, double, double tExit) {
          if constexpr (Any) {
            return vis.leaf(leafIds, count);
          } else {
            vis.leaf(leafIds, count);
            // A hit inside this node (t <= tExit) cannot be beaten by a later node.
            return vis.hit.prim != MT_NULL && vis.hit.t <= tExit;
          }
        },
        Count ? &st : nullptr);
    vis.template store<Count>(i, st.nodeVisits, hits, blocked, ctr);
  }
}

template <Simd S, TriangleTest T, bool Any, bool Count>
void sahBatch(const SahKdTree& tree, SahTraversal trav, int shortStack, const LeafTriangles& P, const RayBatch& b,
              RayHit* hits, uint8_t* blocked, RayCounters ctr) {
  for (size_t i = 0; i < b.n; ++i) {
    PayloadVisitor<S, T, Any> vis(P, tree.primitiveIndices().data(), b, i);
    TraversalStats st;
    tree.walk(trav, b.o[i], b.d[i], b.tMin(i), vis.tmax, vis, Count ? &st : nullptr, shortStack);
    vis.template store<Count>(i, st.nodeVisits, hits, blocked, ctr);
  }
}

/// The entry points of this instruction set: the test, any/first and counting resolved here.
template <Simd S>
struct Kernels {
  template <bool Any>
  static void matrix(const MatrixTree& tree, const LeafTriangles& P, TriangleTest test, const RayBatch& b,
                     RayHit* hits, uint8_t* blocked, RayCounters ctr, int inFlight) {
    auto go = [&](auto testTag, auto countTag) {
      constexpr TriangleTest T = decltype(testTag)::value;
      constexpr bool C = decltype(countTag)::value;
      if (!tree.hasStepTable()) {
        // The walk without the table (batch_trace.cpp never sends it to the AVX2 unit, whose
        // copies of the tree's out-of-line search functions must not exist).
        if constexpr (S != Simd::Avx2) matrixSingle<S, T, Any, C>(tree, P, b, hits, blocked, ctr);
      } else if (inFlight >= 8) {
        matrixBatch<S, T, Any, C, 8>(tree, P, b, hits, blocked, ctr);
      } else if (inFlight >= 4) {
        matrixBatch<S, T, Any, C, 4>(tree, P, b, hits, blocked, ctr);
      } else if (inFlight >= 2) {
        matrixBatch<S, T, Any, C, 2>(tree, P, b, hits, blocked, ctr);
      } else {
        matrixBatch<S, T, Any, C, 1>(tree, P, b, hits, blocked, ctr);
      }
    };
    dispatch(test, ctr, go);
  }
  template <bool Any>
  static void sah(const SahKdTree& tree, SahTraversal trav, int shortStack, const LeafTriangles& P, TriangleTest test,
                  const RayBatch& b, RayHit* hits, uint8_t* blocked, RayCounters ctr) {
    auto go = [&](auto testTag, auto countTag) {
      sahBatch<S, decltype(testTag)::value, Any, decltype(countTag)::value>(tree, trav, shortStack, P, b, hits,
                                                                          blocked, ctr);
    };
    dispatch(test, ctr, go);
  }

 private:
  template <class Go>
  static void dispatch(TriangleTest test, RayCounters ctr, Go& go) {
    using MT = std::integral_constant<TriangleTest, TriangleTest::MollerTrumbore>;
    using WT = std::integral_constant<TriangleTest, TriangleTest::Watertight>;
    if (test == TriangleTest::Watertight) {
      if (ctr.on()) go(WT{}, std::true_type{});
      else go(WT{}, std::false_type{});
    } else {
      if (ctr.on()) go(MT{}, std::true_type{});
      else go(MT{}, std::false_type{});
    }
  }
};

}  // namespace MT_BATCH_NS
}  // namespace mtree

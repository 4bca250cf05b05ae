// The batch tracers' dispatch (batch_trace.h): payload or not, then the widest leaf test this CPU
// runs, once per batch. The baseline instruction set's instantiations (Scalar, SSE2) live here.
#include "mtree/rays/batch_trace.h"

#include <algorithm>
#include <limits>

#include "batch_trace_kernels.h"
#define MT_BATCH_NS batch_base
#include "batch_trace_impl.h"

namespace mtree {

Simd simdSupported() {
  static const Simd best = [] {
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
    if (batch_avx2::compiled() && __builtin_cpu_supports("avx2")) return Simd::Avx2;
#endif
#if defined(MT_LEAF_TEST_SSE2)
    return Simd::Sse2;
#else
    return Simd::Scalar;
#endif
  }();
  return best;
}

namespace {

Simd chosen(const TraceTuning& tuning) { return std::min(tuning.simd, simdSupported()); }

// Without a payload: raycast.h's single-ray queries (the leaf tests read the mesh).
template <class First, class Any>
void meshPath(bool any, const RayBatch& b, RayHit* hits, uint8_t* blocked, RayCounters ctr, First&& first,
              Any&& anyHit) {
  for (size_t i = 0; i < b.n; ++i) {
    const double tmax = b.tMax(i);
    TraversalStats st;
    TraversalStats* sp = ctr.on() ? &st : nullptr;
    if (any) {
      blocked[i] = anyHit(b.o[i], b.d[i], b.tMin(i), tmax, sp);
    } else {
      first(b.o[i], b.d[i], b.tMin(i), tmax, hits[i], sp);
    }
    if (sp) {
      ctr.visits[i] += static_cast<uint32_t>(st.nodeVisits);
      ctr.tests[i] += static_cast<uint32_t>(st.primTests);
    }
  }
}

void matrixTrace(bool any, const MatrixTree& tree, const TriangleMesh& mesh, const LeafTriangles* payload,
                 TriangleTest test, const RayBatch& b, RayHit* hits, uint8_t* blocked, RayCounters ctr,
                 const TraceTuning& tuning) {
  if (!payload) {
    const bool wt = test == TriangleTest::Watertight;
    meshPath(
        any, b, hits, blocked, ctr,
        [&](Vec3 o, Vec3 d, double t0, double t1, RayHit& h, TraversalStats* st) {
          wt ? intersectFirst<TriangleTest::Watertight>(tree, mesh, o, d, t0, t1, h, st)
             : intersectFirst<TriangleTest::MollerTrumbore>(tree, mesh, o, d, t0, t1, h, st);
        },
        [&](Vec3 o, Vec3 d, double t0, double t1, TraversalStats* st) {
          return wt ? intersectAny<TriangleTest::Watertight>(tree, mesh, o, d, t0, t1, st)
                    : intersectAny<TriangleTest::MollerTrumbore>(tree, mesh, o, d, t0, t1, st);
        });
    return;
  }
  // The AVX2 unit walks by the step table only (batch_trace_impl.h).
  const Simd simd =
      chosen(tuning) == Simd::Avx2 && !tree.hasStepTable() ? std::min(Simd::Sse2, simdSupported()) : chosen(tuning);
  switch (simd) {
    case Simd::Avx2:
      batch_avx2::matrix(any, tree, *payload, test, b, hits, blocked, ctr, tuning.inFlight);
      return;
    case Simd::Sse2:
#ifdef MT_LEAF_TEST_SSE2
      any ? batch_base::Kernels<Simd::Sse2>::matrix<true>(tree, *payload, test, b, hits, blocked, ctr, tuning.inFlight)
          : batch_base::Kernels<Simd::Sse2>::matrix<false>(tree, *payload, test, b, hits, blocked, ctr, tuning.inFlight);
#endif
      return;
    case Simd::Scalar:
      any ? batch_base::Kernels<Simd::Scalar>::matrix<true>(tree, *payload, test, b, hits, blocked, ctr,
                                                              tuning.inFlight)
          : batch_base::Kernels<Simd::Scalar>::matrix<false>(tree, *payload, test, b, hits, blocked, ctr,
                                                               tuning.inFlight);
      return;
  }
}

void sahTrace(bool any, const SahKdTree& tree, SahTraversal trav, int shortStack, const TriangleMesh& mesh,
              const LeafTriangles* payload, TriangleTest test, const RayBatch& b, RayHit* hits, uint8_t* blocked,
              RayCounters ctr, const TraceTuning& tuning) {
  if (!payload) {
    meshPath(
        any, b, hits, blocked, ctr,
        [&](Vec3 o, Vec3 d, double t0, double t1, RayHit& h, TraversalStats* st) {
          tree.intersectFirst(mesh, o, d, t0, t1, h, trav, test, st, shortStack);
        },
        [&](Vec3 o, Vec3 d, double t0, double t1, TraversalStats* st) {
          return tree.intersectAny(mesh, o, d, t0, t1, trav, test, st, shortStack);
        });
    return;
  }
  switch (chosen(tuning)) {
    case Simd::Avx2:
      batch_avx2::sah(any, tree, trav, shortStack, *payload, test, b, hits, blocked, ctr);
      return;
    case Simd::Sse2:
#ifdef MT_LEAF_TEST_SSE2
      any ? batch_base::Kernels<Simd::Sse2>::sah<true>(tree, trav, shortStack, *payload, test, b, hits, blocked, ctr)
          : batch_base::Kernels<Simd::Sse2>::sah<false>(tree, trav, shortStack, *payload, test, b, hits, blocked, ctr);
#endif
      return;
    case Simd::Scalar:
      any ? batch_base::Kernels<Simd::Scalar>::sah<true>(tree, trav, shortStack, *payload, test, b, hits, blocked, ctr)
          : batch_base::Kernels<Simd::Scalar>::sah<false>(tree, trav, shortStack, *payload, test, b, hits, blocked,
                                                           ctr);
      return;
  }
}

}  // namespace

void traceFirst(const MatrixTree& tree, const TriangleMesh& mesh, const LeafTriangles* payload, TriangleTest test,
                const RayBatch& rays, RayHit* hits, RayCounters counters, const TraceTuning& tuning) {
  matrixTrace(false, tree, mesh, payload, test, rays, hits, nullptr, counters, tuning);
}
void traceAny(const MatrixTree& tree, const TriangleMesh& mesh, const LeafTriangles* payload, TriangleTest test,
              const RayBatch& rays, uint8_t* blocked, RayCounters counters, const TraceTuning& tuning) {
  matrixTrace(true, tree, mesh, payload, test, rays, nullptr, blocked, counters, tuning);
}
void traceFirst(const SahKdTree& tree, SahTraversal traversal, int shortStack, const TriangleMesh& mesh,
                const LeafTriangles* payload, TriangleTest test, const RayBatch& rays, RayHit* hits,
                RayCounters counters, const TraceTuning& tuning) {
  sahTrace(false, tree, traversal, shortStack, mesh, payload, test, rays, hits, nullptr, counters, tuning);
}
void traceAny(const SahKdTree& tree, SahTraversal traversal, int shortStack, const TriangleMesh& mesh,
              const LeafTriangles* payload, TriangleTest test, const RayBatch& rays, uint8_t* blocked,
              RayCounters counters, const TraceTuning& tuning) {
  sahTrace(true, tree, traversal, shortStack, mesh, payload, test, rays, nullptr, blocked, counters, tuning);
}

}  // namespace mtree

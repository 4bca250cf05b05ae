// The batch tracers with the AVX2 leaf test (4 lanes of doubles). This file alone is compiled with
// -mavx2 (never -mfma: the lanes must round as the scalar test does) where the compiler targets
// x86-64; batch_trace.cpp calls it only when simdSupported() says the CPU has AVX2. Everything it
// defines lives in namespace batch_avx2, so no AVX2 code is shared with the rest of the engine.
#include "batch_trace_kernels.h"

#if defined(__AVX2__)
#define MT_BATCH_NS batch_avx2
#include "batch_trace_impl.h"

namespace mtree {
namespace batch_avx2 {
bool compiled() { return true; }
void matrix(bool any, const MatrixTree& tree, const LeafTriangles& P, TriangleTest test, const RayBatch& b,
            RayHit* hits, uint8_t* blocked, RayCounters ctr, int inFlight) {
  if (any)
    Kernels<Simd::Avx2>::matrix<true>(tree, P, test, b, hits, blocked, ctr, inFlight);
  else
    Kernels<Simd::Avx2>::matrix<false>(tree, P, test, b, hits, blocked, ctr, inFlight);
}
void sah(bool any, const SahKdTree& tree, SahTraversal trav, int shortStack, const LeafTriangles& P,
         TriangleTest test, const RayBatch& b, RayHit* hits, uint8_t* blocked, RayCounters ctr) {
  if (any)
    Kernels<Simd::Avx2>::sah<true>(tree, trav, shortStack, P, test, b, hits, blocked, ctr);
  else
    Kernels<Simd::Avx2>::sah<false>(tree, trav, shortStack, P, test, b, hits, blocked, ctr);
}
}  // namespace batch_avx2
}  // namespace mtree
#else
#include <stdexcept>

namespace mtree {
namespace batch_avx2 {
// Not compiled for AVX2: simdSupported() never reports it, so these are never called.
bool compiled() { return false; }
void matrix(bool, const MatrixTree&, const LeafTriangles&, TriangleTest, const RayBatch&, RayHit*, uint8_t*,
            RayCounters, int) {
  throw std::logic_error("batch_avx2::matrix: this build has no AVX2 unit");
}
void sah(bool, const SahKdTree&, SahTraversal, int, const LeafTriangles&, TriangleTest, const RayBatch&, RayHit*,
         uint8_t*, RayCounters) {
  throw std::logic_error("batch_avx2::sah: this build has no AVX2 unit");
}
}  // namespace batch_avx2
}  // namespace mtree
#endif

// The per-instruction-set entry points of the batch tracers (batch_trace_impl.h), as batch_trace.cpp
// calls them.
#pragma once

#include "mtree/rays/batch_trace.h"

namespace mtree {
namespace batch_avx2 {
/// Whether this build has the AVX2 unit (x86-64 with GCC or Clang).
bool compiled();
void matrix(bool any, const MatrixTree& tree, const LeafTriangles& P, TriangleTest test, const RayBatch& b,
            RayHit* hits, uint8_t* blocked, RayCounters ctr, int inFlight);
void sah(bool any, const SahKdTree& tree, SahTraversal trav, int shortStack, const LeafTriangles& P,
         TriangleTest test, const RayBatch& b, RayHit* hits, uint8_t* blocked, RayCounters ctr);
}  // namespace batch_avx2
}  // namespace mtree

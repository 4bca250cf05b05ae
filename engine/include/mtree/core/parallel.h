// Parallel building blocks of the §5.1 build: exclusive scan and a stable LSD radix sort of
// (key, value) pairs. Both are deterministic: the result does not depend on the thread count,
// because every thread works on a fixed contiguous chunk and chunks are combined in order.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "mtree/core/memory.h"

namespace mtree {

/// Passes with about a nanosecond of work per item (bounds, scans, copies, existence marks) run
/// on one thread below this many items (a few ms): a parallel region's start and barriers cost
/// microseconds on an idle machine but scheduler time slices (4-8 ms each) on a loaded one. At
/// 2^20, the surfaces' leaf levels (1-4 million entries) still took the parallel passes: lucy,
/// two threads, loaded: leaf scan 20 ms where one thread takes 2.
constexpr int64_t kSerialBelow = int64_t{1} << 22;

/// Number of OpenMP threads to use: `requested` if > 0, else OpenMP's default.
int resolveThreads(int requested);

/// out[i] = sum of in[0..i-1]; returns the total. `out` may alias `in`.
/// Blelloch-style two-pass scan over per-thread chunks (Harris et al., GPU Gems 3 ch. 39).
uint64_t exclusiveScan(const uint32_t* in, uint32_t* out, size_t n, int threads);
uint64_t exclusiveScan(const uint8_t* in, uint32_t* out, size_t n, int threads);

/// Stable LSD radix sort of keys[] with values[] carried along, over the low `keyBits` bits.
/// Digits of at most 11 bits, per-thread histograms, scatter by chunk: Satish, Harris & Garland
/// 2009 on a CPU.
/// tmpKeys/tmpValues are scratch buffers (resized as needed, reusable across calls).
void radixSortPairs(LargeVector<uint32_t>& keys, LargeVector<uint32_t>& values, int keyBits, int threads,
                    LargeVector<uint32_t>& tmpKeys, LargeVector<uint32_t>& tmpValues);

}  // namespace mtree

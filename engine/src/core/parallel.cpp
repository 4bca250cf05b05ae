#include "mtree/core/parallel.h"

#include <algorithm>
#include <cstring>

#include <omp.h>

namespace mtree {

int resolveThreads(int requested) {
  return requested > 0 ? requested : std::max(1, omp_get_max_threads());
}

namespace {

// Chunk c of n items over `parts` chunks: [n*c/parts, n*(c+1)/parts).
inline size_t chunkBegin(size_t n, int c, int parts) {
  return static_cast<size_t>((static_cast<unsigned __int128>(n) * c) / parts);
}

template <typename In>
uint64_t scanImpl(const In* in, uint32_t* out, size_t n, int threads) {
  if (n == 0) return 0;
  // Small inputs: the serial loop beats the thread start-up.
  if (n < (1u << 15) || threads <= 1) {
    uint64_t sum = 0;
    for (size_t i = 0; i < n; ++i) {
      const uint64_t v = in[i];
      out[i] = static_cast<uint32_t>(sum);
      sum += v;
    }
    return sum;
  }
  std::vector<uint64_t> partial(threads + 1, 0);
  int used = 1;
#pragma omp parallel num_threads(threads)
  {
    const int t = omp_get_thread_num();
    const int nt = omp_get_num_threads();
    const size_t b = chunkBegin(n, t, nt), e = chunkBegin(n, t + 1, nt);
    uint64_t sum = 0;
    for (size_t i = b; i < e; ++i) sum += in[i];
    partial[t + 1] = sum;
#pragma omp barrier
#pragma omp single
    {
      used = nt;
      for (int i = 1; i <= nt; ++i) partial[i] += partial[i - 1];
    }
    uint64_t run = partial[t];
    for (size_t i = b; i < e; ++i) {
      const uint64_t v = in[i];
      out[i] = static_cast<uint32_t>(run);
      run += v;
    }
  }
  return partial[used];
}

}  // namespace

uint64_t exclusiveScan(const uint32_t* in, uint32_t* out, size_t n, int threads) {
  return scanImpl(in, out, n, threads);
}
uint64_t exclusiveScan(const uint8_t* in, uint32_t* out, size_t n, int threads) {
  return scanImpl(in, out, n, threads);
}

void radixSortPairs(LargeVector<uint32_t>& keys, LargeVector<uint32_t>& values, int keyBits, int threads,
                    LargeVector<uint32_t>& tmpKeys, LargeVector<uint32_t>& tmpValues) {
  const size_t n = keys.size();
  if (n < 2 || keyBits <= 0) return;
  tmpKeys.resize(n);
  tmpValues.resize(n);
  // Digits of at most 11 bits (2048 buckets: the per-thread histograms stay in L1/L2), as few
  // passes as that allows: 20-bit keys sort in 2 passes of 10 bits instead of 3 of 8.
  keyBits = std::min(keyBits, 32);
  const int passes = (keyBits + 10) / 11;
  const int kDigitBits = (keyBits + passes - 1) / passes;
  const int kRadix = 1 << kDigitBits;
  if (n < (1u << 14)) threads = 1;
  std::vector<uint32_t> hist(static_cast<size_t>(threads) * kRadix);

  uint32_t* srcK = keys.data();
  uint32_t* srcV = values.data();
  uint32_t* dstK = tmpKeys.data();
  uint32_t* dstV = tmpValues.data();
  for (int pass = 0; pass < passes; ++pass) {
    const int shift = pass * kDigitBits;
    std::fill(hist.begin(), hist.end(), 0u);
#pragma omp parallel num_threads(threads)
    {
      const int t = omp_get_thread_num();
      const int nt = omp_get_num_threads();
      const size_t b = chunkBegin(n, t, nt), e = chunkBegin(n, t + 1, nt);
      uint32_t* h = &hist[static_cast<size_t>(t) * kRadix];
      for (size_t i = b; i < e; ++i) ++h[(srcK[i] >> shift) & (kRadix - 1)];
#pragma omp barrier
#pragma omp single
      {
        // Column-major prefix: digit d of thread t starts after all smaller digits and after
        // digit d of threads < t. This ordering is what makes the sort stable.
        uint32_t run = 0;
        for (int d = 0; d < kRadix; ++d)
          for (int tt = 0; tt < nt; ++tt) {
            uint32_t& c = hist[static_cast<size_t>(tt) * kRadix + d];
            const uint32_t v = c;
            c = run;
            run += v;
          }
      }
      for (size_t i = b; i < e; ++i) {
        const uint32_t pos = h[(srcK[i] >> shift) & (kRadix - 1)]++;
        dstK[pos] = srcK[i];
        dstV[pos] = srcV[i];
      }
    }
    std::swap(srcK, dstK);
    std::swap(srcV, dstV);
  }
  if (srcK != keys.data()) {
    keys.swap(tmpKeys);
    values.swap(tmpValues);
  }
}

}  // namespace mtree

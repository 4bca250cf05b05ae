// exclusiveScan and radixSortPairs against std::partial_sum / std::stable_sort, on random data of
// sizes on both sides of the serial/parallel switch-overs, with 1, 2, 3 and 7 threads; and
// LargeVector (memory.h), the build's arrays, on both sides of its mapping threshold.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <numeric>
#include <string>
#include <tuple>
#include <vector>

#include "mtree/core/parallel.h"
#include "test_util.h"

namespace {

const std::vector<size_t> kSizes = {
    0, 1, 2, 3, 17, 1000, 16383, 16384, 32767, 32768, 70001, (1u << 16) + 3, 300007};
const std::vector<int> kThreads = {1, 2, 3, 7};

template <typename T>
std::vector<uint32_t> referenceScan(const std::vector<T>& in, uint64_t& total) {
  // Exclusive scan = inclusive partial_sum shifted by one; sums in 64 bits, stored mod 2^32.
  // (std::partial_sum accumulates in the input's value type: widen the input first.)
  std::vector<uint64_t> incl(in.begin(), in.end());
  std::partial_sum(incl.begin(), incl.end(), incl.begin());
  std::vector<uint32_t> out(in.size());
  for (size_t i = 0; i < in.size(); ++i) out[i] = static_cast<uint32_t>(i == 0 ? 0 : incl[i - 1]);
  total = in.empty() ? 0 : incl.back();
  return out;
}

class ScanTest : public ::testing::TestWithParam<size_t> {};

TEST_P(ScanTest, Uint32MatchesPartialSum) {
  const size_t n = GetParam();
  for (const int threads : kThreads) {
    SCOPED_TRACE(std::to_string(threads) + " threads");
    mtest::Rng rng(n * 31 + threads);
    // Small values (counts, the builder's case) and huge ones (the 64-bit total must not wrap).
    for (const uint32_t range : {7u, 0xFFFFFFFFu}) {
      std::vector<uint32_t> in(n);
      for (auto& v : in) v = range == 7u ? rng.below(8) : static_cast<uint32_t>(rng.next());
      uint64_t wantTotal = 0;
      const std::vector<uint32_t> want = referenceScan(in, wantTotal);
      std::vector<uint32_t> out(n, 0xDEADBEEFu);
      const uint64_t total = mtree::exclusiveScan(in.data(), out.data(), n, threads);
      EXPECT_EQ(total, wantTotal) << "range " << range;
      EXPECT_TRUE(out == want) << "range " << range;
      // In place (out aliases in) gives the same.
      std::vector<uint32_t> inplace = in;
      const uint64_t total2 = mtree::exclusiveScan(inplace.data(), inplace.data(), n, threads);
      EXPECT_EQ(total2, wantTotal);
      EXPECT_TRUE(inplace == want) << "in place, range " << range;
    }
  }
}

TEST_P(ScanTest, Uint8MatchesPartialSum) {
  const size_t n = GetParam();
  for (const int threads : kThreads) {
    SCOPED_TRACE(std::to_string(threads) + " threads");
    mtest::Rng rng(n * 17 + threads);
    std::vector<uint8_t> in(n);
    for (auto& v : in) v = static_cast<uint8_t>(rng.uniform() < 0.5 ? rng.below(2) : rng.below(256));
    uint64_t wantTotal = 0;
    const std::vector<uint32_t> want = referenceScan(in, wantTotal);
    std::vector<uint32_t> out(n, 0xDEADBEEFu);
    EXPECT_EQ(mtree::exclusiveScan(in.data(), out.data(), n, threads), wantTotal);
    EXPECT_TRUE(out == want);
  }
}

INSTANTIATE_TEST_SUITE_P(Sizes, ScanTest, ::testing::ValuesIn(kSizes),
                         [](const ::testing::TestParamInfo<size_t>& info) {
                           return "n" + std::to_string(info.param);
                         });

TEST(Scan, TotalBeyond32Bits) {
  // 2^17 entries of 2^31: the total is 2^48 while every output wraps modulo 2^32.
  const size_t n = size_t{1} << 17;
  std::vector<uint32_t> in(n, 1u << 31), out(n);
  for (int threads : kThreads) {
    EXPECT_EQ(mtree::exclusiveScan(in.data(), out.data(), n, threads), uint64_t{1} << 48);
    for (size_t i = 0; i < n; i += 4099) ASSERT_EQ(out[i], i % 2 ? 1u << 31 : 0u) << i;
  }
}

// ---- radix sort ----

class RadixTest : public ::testing::TestWithParam<std::tuple<size_t, int>> {};

TEST_P(RadixTest, MatchesStableSort) {
  const size_t n = std::get<0>(GetParam());
  const int keyBits = std::get<1>(GetParam());
  for (const int threads : kThreads) {
    SCOPED_TRACE(std::to_string(threads) + " threads");
    mtest::Rng rng(n * 131 + keyBits * 7 + threads);
    const uint64_t mask = keyBits >= 32 ? 0xFFFFFFFFull : ((uint64_t{1} << keyBits) - 1);
    mtree::LargeVector<uint32_t> keys(n), values(n);
    for (size_t i = 0; i < n; ++i) {
      keys[i] = static_cast<uint32_t>(rng.next() & mask);
      values[i] = static_cast<uint32_t>(i);  // the original position: checks stability
    }
    std::vector<std::pair<uint32_t, uint32_t>> ref(n);
    for (size_t i = 0; i < n; ++i) ref[i] = {keys[i], values[i]};
    std::stable_sort(ref.begin(), ref.end(), [](const auto& a, const auto& b) { return a.first < b.first; });

    mtree::LargeVector<uint32_t> tk, tv;
    mtree::radixSortPairs(keys, values, keyBits, threads, tk, tv);
    ASSERT_EQ(keys.size(), n);
    ASSERT_EQ(values.size(), n);
    size_t wrong = 0;
    for (size_t i = 0; i < n; ++i) wrong += keys[i] != ref[i].first || values[i] != ref[i].second;
    EXPECT_EQ(wrong, 0u);
  }
}

INSTANTIATE_TEST_SUITE_P(Sizes, RadixTest,
                         ::testing::Combine(::testing::Values(0, 1, 2, 100, 16383, 16384, (1u << 16) + 5,
                                                              200003),
                                            ::testing::Values(1, 2, 7, 8, 9, 13, 16, 17, 24, 31, 32)),
                         [](const ::testing::TestParamInfo<std::tuple<size_t, int>>& info) {
                           return "n" + std::to_string(std::get<0>(info.param)) + "_bits" +
                                  std::to_string(std::get<1>(info.param));
                         });

TEST(Radix, StableWithFewDistinctKeysAndReusedScratch) {
  // Three key values over 100k pairs: every run of equal keys must keep its input order.
  const size_t n = 100000;
  mtree::LargeVector<uint32_t> tk(7), tv(3);  // scratch of the wrong size: resized by the sort
  for (int threads : kThreads) {
    mtree::LargeVector<uint32_t> keys(n), values(n);
    mtest::Rng rng(threads);
    for (size_t i = 0; i < n; ++i) {
      keys[i] = rng.below(3) * 1000;  // 0, 1000, 2000: keyBits 11
      values[i] = static_cast<uint32_t>(i);
    }
    mtree::LargeVector<uint32_t> k0 = keys;
    mtree::radixSortPairs(keys, values, 11, threads, tk, tv);
    ASSERT_TRUE(std::is_sorted(keys.begin(), keys.end()));
    for (size_t i = 1; i < n; ++i)
      if (keys[i] == keys[i - 1]) {
        ASSERT_LT(values[i - 1], values[i]) << "unstable at " << i;
      }
    for (size_t i = 0; i < n; ++i) ASSERT_EQ(k0[values[i]], keys[i]) << "value not carried with its key";
  }
}

TEST(Radix, ResultDoesNotDependOnThreads) {
  const size_t n = 250000;
  mtree::LargeVector<uint32_t> k1(n), v1(n);
  mtest::Rng rng(99);
  for (size_t i = 0; i < n; ++i) {
    k1[i] = rng.below(1u << 20);
    v1[i] = rng.below(1000);  // values need not be distinct
  }
  mtree::LargeVector<uint32_t> tk, tv;
  mtree::LargeVector<uint32_t> kr = k1, vr = v1;
  mtree::radixSortPairs(kr, vr, 20, 1, tk, tv);
  for (int threads : {2, 3, 4, 7, 16}) {
    mtree::LargeVector<uint32_t> k = k1, v = v1;
    mtree::radixSortPairs(k, v, 20, threads, tk, tv);
    EXPECT_TRUE(k == kr) << threads << " threads";
    EXPECT_TRUE(v == vr) << threads << " threads";
  }
}

TEST(Radix, ZeroKeyBitsLeavesInputAlone) {
  mtree::LargeVector<uint32_t> keys = {3, 1, 2}, values = {0, 1, 2}, tk, tv;
  mtree::radixSortPairs(keys, values, 0, 2, tk, tv);
  EXPECT_EQ(keys, (mtree::LargeVector<uint32_t>{3, 1, 2}));
  EXPECT_EQ(values, (mtree::LargeVector<uint32_t>{0, 1, 2}));
}

TEST(LargeVector, MappingLengthRule) {
  using mtree::detail::mappedLength;
  const size_t M = size_t{1} << 20;
  EXPECT_EQ(mappedLength(2 * M), 2 * M);
  // A whole huge page more would be 50%: the size class, 1/32 of 2 MiB.
  EXPECT_EQ(mappedLength(2 * M + 1), 2 * M + 64 * 1024);
  EXPECT_EQ(mappedLength(4 * M - 100), 4 * M);              // rounding up adds 100 bytes
  EXPECT_EQ(mappedLength(16 * M + 1), 18 * M);              // adds just under an eighth
  EXPECT_EQ(mappedLength(10 * M + 1), 10 * M + 256 * 1024); // would add more than an eighth
  // Blocks of about the same size share a length (a deforming mesh's arrays, build to build).
  EXPECT_EQ(mappedLength(3 * M + 1000), mappedLength(3 * M + 60000));
  for (size_t b : {2 * M + 1, 3 * M + 7, 5 * M + 12345, 10 * M + 1, 33 * M + 5}) {
    EXPECT_GE(mappedLength(b), b);
    EXPECT_LE(mappedLength(b) - b, b / 8) << b;
    EXPECT_EQ(mappedLength(b) % 4096, 0u) << b;
  }
}

#if defined(__linux__)
TEST(LargeVector, FreedMappingsAreReusedForTheSameLength) {
  if (!mtree::detail::mappingCacheWanted()) GTEST_SKIP() << "MATRIXTREE_MAP_CACHE=0";
  mtree::releaseCachedMemory();
  EXPECT_EQ(mtree::cachedMemoryBytes(), 0u);
  const size_t n = (size_t{3} << 20) + 1000;
  const size_t len = mtree::detail::mappedLength(n);
  const void* first;
  {
    mtree::LargeVector<uint8_t> v(n, 1);
    first = v.data();
  }
  EXPECT_EQ(mtree::cachedMemoryBytes(), len);
  {
    mtree::LargeVector<uint8_t> other(size_t{7} << 20);  // another length: a new mapping
    EXPECT_NE(static_cast<const void*>(other.data()), first);
    EXPECT_EQ(mtree::cachedMemoryBytes(), len);
    mtree::LargeVector<uint8_t> again(n + 20000);  // the same size class: the kept mapping
    EXPECT_EQ(static_cast<const void*>(again.data()), first);
    EXPECT_EQ(mtree::cachedMemoryBytes(), 0u);
    again.assign(again.size(), 5);  // usable memory
    EXPECT_EQ(std::count(again.begin(), again.end(), uint8_t{5}), static_cast<std::ptrdiff_t>(again.size()));
  }
  EXPECT_EQ(mtree::cachedMemoryBytes(), len + mtree::detail::mappedLength(size_t{7} << 20));
  EXPECT_EQ(mtree::releaseCachedMemory(), len + mtree::detail::mappedLength(size_t{7} << 20));
  EXPECT_EQ(mtree::cachedMemoryBytes(), 0u);
}

TEST(LargeVector, TheCacheKeepsAtMostSixteenMappings) {
  if (!mtree::detail::mappingCacheWanted()) GTEST_SKIP() << "MATRIXTREE_MAP_CACHE=0";
  mtree::releaseCachedMemory();
  {
    std::vector<mtree::LargeVector<uint8_t>> many;
    for (int i = 0; i < 20; ++i) many.emplace_back(size_t{2} << 20);
  }
  EXPECT_EQ(mtree::cachedMemoryBytes(), mtree::detail::MappingCache::kMaxEntries * (size_t{2} << 20));
  {
    // Freed from threads at once (the build's per-thread arrays): the count stays consistent.
    std::vector<mtree::LargeVector<uint8_t>> many(8);
#pragma omp parallel for num_threads(4)
    for (int i = 0; i < 8; ++i) many[size_t(i)].resize(size_t{2} << 20);
#pragma omp parallel for num_threads(4)
    for (int i = 0; i < 8; ++i) mtree::LargeVector<uint8_t>().swap(many[size_t(i)]);
  }
  EXPECT_EQ(mtree::cachedMemoryBytes(), mtree::detail::MappingCache::kMaxEntries * (size_t{2} << 20));
  mtree::releaseCachedMemory();
}
#endif

TEST(LargeVector, BehavesAsAVectorAcrossTheMappingThreshold) {
  // Sizes below, at and above kLargeBytes (2 MiB), grown by push_back (reallocations that move
  // between operator new and mappings), copied, swapped, shrunk and freed: the contents stay.
  const size_t big = (size_t{3} << 20) / sizeof(uint32_t) + 5;
  mtree::LargeVector<uint32_t> v;
  for (size_t i = 0; i < big; ++i) v.push_back(static_cast<uint32_t>(i * 2654435761u));
  ASSERT_EQ(v.size(), big);
#if defined(__linux__)
  EXPECT_EQ(reinterpret_cast<uintptr_t>(v.data()) % (size_t{2} << 20), 0u) << "a mapping starts on a huge page";
#endif
  size_t bad = 0;
  for (size_t i = 0; i < big; ++i) bad += v[i] != static_cast<uint32_t>(i * 2654435761u);
  EXPECT_EQ(bad, 0u);
  mtree::LargeVector<uint32_t> copy = v, small(10, 7u);
  EXPECT_TRUE(copy == v);
  copy.swap(small);
  EXPECT_EQ(copy, mtree::LargeVector<uint32_t>(10, 7u));
  EXPECT_TRUE(small == v);
  small.resize(3);
  small.shrink_to_fit();
  EXPECT_EQ(small, (mtree::LargeVector<uint32_t>{v[0], v[1], v[2]}));
  // resize(n, value) and assign fill, also into a fresh mapping.
  mtree::LargeVector<uint8_t> bytes;
  bytes.resize(size_t{5} << 20, 0xAB);
  EXPECT_EQ(std::count(bytes.begin(), bytes.end(), uint8_t{0xAB}), static_cast<std::ptrdiff_t>(bytes.size()));
  bytes.assign(size_t{9} << 20, 0x3C);
  EXPECT_EQ(std::count(bytes.begin(), bytes.end(), uint8_t{0x3C}), static_cast<std::ptrdiff_t>(bytes.size()));
  // resize(n) keeps what was there (the new elements are default-initialised: written by the
  // caller before they are read).
  mtree::LargeVector<uint32_t> keep(4, 9u);
  keep.resize(size_t{1} << 20);
  keep[keep.size() - 1] = 1;
  EXPECT_EQ(keep[0], 9u);
  EXPECT_EQ(keep[3], 9u);
  EXPECT_EQ(keep.back(), 1u);
}

TEST(Parallel, ResolveThreads) {
  EXPECT_EQ(mtree::resolveThreads(3), 3);
  EXPECT_EQ(mtree::resolveThreads(1), 1);
  EXPECT_GE(mtree::resolveThreads(0), 1);
  EXPECT_GE(mtree::resolveThreads(-2), 1);
}

}  // namespace

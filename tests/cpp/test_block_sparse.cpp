// BlockSparseMatrix<T> against a dense std::vector reference: random inserts on odd sizes and
// every block edge, memory that follows the allocated blocks only, the bulk allocation of the
// parallel build (blocks numbered in scan order), and argument checking.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <numeric>
#include <set>
#include <stdexcept>
#include <string>
#include <tuple>
#include <vector>

#include "mtree/core/block_sparse.h"
#include "test_util.h"

namespace {

using mtree::BlockSparseMatrix;
using mtree::ceilLog2;

int nextPow2(int n) {
  int p = 1;
  while (p < n) p *= 2;
  return p;
}

// Expected block edge along an axis of n entries: the requested edge, shrunk to the smallest
// power of two >= n on a short axis.
int expectedEdge(int n, int blockEdge) { return std::min(blockEdge, nextPow2(n)); }

struct Shape {
  int nx, ny, nz;
};

std::string shapeName(const Shape& s) {
  return std::to_string(s.nx) + "x" + std::to_string(s.ny) + "x" + std::to_string(s.nz);
}

class BlockSparseRandom : public ::testing::TestWithParam<std::tuple<Shape, int>> {};

TEST_P(BlockSparseRandom, MatchesDenseReference) {
  const Shape s = std::get<0>(GetParam());
  const int B = std::get<1>(GetParam());
  const int32_t empty = -7;
  BlockSparseMatrix<int32_t> m(s.nx, s.ny, s.nz, B, empty);

  const int ex = expectedEdge(s.nx, B), ey = expectedEdge(s.ny, B), ez = expectedEdge(s.nz, B);
  const int px = (s.nx + ex - 1) / ex, py = (s.ny + ey - 1) / ey, pz = (s.nz + ez - 1) / ez;
  ASSERT_EQ(m.desc().logBlock[0], ceilLog2(ex));
  ASSERT_EQ(m.desc().logBlock[1], ceilLog2(ey));
  ASSERT_EQ(m.desc().logBlock[2], ceilLog2(ez));
  ASSERT_EQ(m.desc().ptrDims[0], px);
  ASSERT_EQ(m.desc().ptrDims[1], py);
  ASSERT_EQ(m.desc().ptrDims[2], pz);
  ASSERT_EQ(m.blockVolume(), static_cast<uint32_t>(ex * ey * ez));
  ASSERT_EQ(m.pointerCount(), static_cast<size_t>(px) * py * pz);
  ASSERT_EQ(m.pointerBytes(), m.pointerCount() * sizeof(uint32_t));
  ASSERT_EQ(m.numBlocks(), 0u);
  ASSERT_EQ(m.bytes(), m.pointerBytes());
  for (int a = 0; a < 3; ++a) EXPECT_EQ(m.dim(a), (&s.nx)[a]);
  EXPECT_EQ(m.emptyValue(), empty);

  const size_t n = static_cast<size_t>(s.nx) * s.ny * s.nz;
  std::vector<int32_t> dense(n, empty);
  std::set<std::tuple<int, int, int>> blocks;
  auto flat = [&](int i, int j, int k) { return (static_cast<size_t>(k) * s.ny + j) * s.nx + i; };

  mtest::Rng rng(mtest::seedFor(shapeName(s), static_cast<uint64_t>(B)));
  // About a third of the entries, with repeats; for the big shapes a few thousand.
  const size_t inserts = std::min<size_t>(n / 3 + 1, 4000);
  for (size_t step = 0; step < inserts; ++step) {
    const int i = static_cast<int>(rng.below(static_cast<uint32_t>(s.nx)));
    const int j = static_cast<int>(rng.below(static_cast<uint32_t>(s.ny)));
    const int k = static_cast<int>(rng.below(static_cast<uint32_t>(s.nz)));
    const int32_t value = static_cast<int32_t>(rng.below(1000000));
    const bool newBlock = blocks.insert({i / ex, j / ey, k / ez}).second;
    const size_t before = m.bytes();
    m.insert(i, j, k) = value;
    dense[flat(i, j, k)] = value;
    // Memory grows by one block exactly when a new block is touched, and never otherwise.
    ASSERT_EQ(m.bytes(), before + (newBlock ? m.blockVolume() * sizeof(int32_t) : 0u))
        << "insert (" << i << "," << j << "," << k << ")";
    ASSERT_EQ(m.numBlocks(), blocks.size());
    ASSERT_EQ(m.bytes(), m.pointerBytes() + size_t(m.numBlocks()) * m.blockVolume() * sizeof(int32_t));
  }
  EXPECT_EQ(m.data().size(), size_t(m.numBlocks()) * m.blockVolume());
  EXPECT_EQ(m.blockBytes(), m.data().size() * sizeof(int32_t));

  // Every entry: get() equals the dense array; find() is null exactly outside allocated blocks;
  // storage indices are distinct and inside the data array.
  std::vector<uint8_t> used(m.data().size(), 0);
  size_t mismatches = 0, findMismatches = 0;
  for (int k = 0; k < s.nz; ++k)
    for (int j = 0; j < s.ny; ++j)
      for (int i = 0; i < s.nx; ++i) {
        ASSERT_TRUE(m.inRange(i, j, k));
        const bool allocated = blocks.count({i / ex, j / ey, k / ez}) > 0;
        const int32_t* p = m.find(i, j, k);
        if ((p != nullptr) != allocated) ++findMismatches;
        if (m.get(i, j, k) != dense[flat(i, j, k)]) ++mismatches;
        if (p) {
          if (*p != dense[flat(i, j, k)]) ++mismatches;
          const uint32_t si = m.storageIndex(i, j, k);
          ASSERT_LT(si, m.data().size());
          ASSERT_EQ(p, &m.data()[si]);
          ASSERT_EQ(used[si], 0) << "two entries share storage " << si;
          used[si] = 1;
          int c[3];
          m.entryCoords(si, c);  // the inverse of storageIndex
          ASSERT_TRUE(c[0] == i && c[1] == j && c[2] == k)
              << "entryCoords(" << si << ") = (" << c[0] << "," << c[1] << "," << c[2] << ")";
        } else {
          ASSERT_EQ(m.storageIndex(i, j, k), MT_NULL);
        }
      }
  EXPECT_EQ(mismatches, 0u);
  EXPECT_EQ(findMismatches, 0u);
  // Allocated blocks cover the data array, except the entries of blocks that stick out past the
  // matrix edge.
  const size_t allocatedEntries = std::count(used.begin(), used.end(), uint8_t{1});
  size_t expectedEntries = 0;
  for (const auto& b : blocks) {
    const int bi = std::get<0>(b), bj = std::get<1>(b), bk = std::get<2>(b);
    expectedEntries +=
        size_t(std::min(ex, s.nx - bi * ex)) * std::min(ey, s.ny - bj * ey) * std::min(ez, s.nz - bk * ez);
  }
  EXPECT_EQ(allocatedEntries, expectedEntries);

  // Out-of-range probes are reported by inRange.
  EXPECT_FALSE(m.inRange(-1, 0, 0));
  EXPECT_FALSE(m.inRange(s.nx, 0, 0));
  EXPECT_FALSE(m.inRange(0, s.ny, 0));
  EXPECT_FALSE(m.inRange(0, 0, s.nz));
}

INSTANTIATE_TEST_SUITE_P(OddSizes, BlockSparseRandom,
                         ::testing::Combine(::testing::Values(Shape{37, 5, 64}, Shape{1, 1, 1},
                                                              Shape{100, 100, 3}, Shape{3, 1, 7},
                                                              Shape{33, 17, 9}, Shape{64, 64, 64}),
                                            ::testing::Values(1, 2, 4, 8, 16, 32)),
                         [](const ::testing::TestParamInfo<std::tuple<Shape, int>>& info) {
                           return shapeName(std::get<0>(info.param)) + "_B" +
                                  std::to_string(std::get<1>(info.param));
                         });

TEST(BlockSparse, InsertReturnsAStableReferenceAndKeepsOtherValues) {
  BlockSparseMatrix<uint8_t> m(20, 20, 20, 4, 0);
  m.insert(0, 0, 0) = 5;
  m.insert(19, 19, 19) = 9;  // a second block: the storage grows
  m.insert(1, 0, 0) += 3;    // same block as (0,0,0): starts at the empty value
  EXPECT_EQ(m.get(0, 0, 0), 5);
  EXPECT_EQ(m.get(1, 0, 0), 3);
  EXPECT_EQ(m.get(19, 19, 19), 9);
  EXPECT_EQ(m.get(2, 2, 2), 0);  // allocated block, never written
  EXPECT_NE(m.find(2, 2, 2), nullptr);
  EXPECT_EQ(m.find(10, 10, 10), nullptr);
  EXPECT_EQ(m.get(10, 10, 10), 0);
  EXPECT_EQ(m.numBlocks(), 2u);
}

TEST(BlockSparse, StructValues) {
  const MtLeafRange none{MT_NULL, MT_NULL};
  BlockSparseMatrix<MtLeafRange> m(9, 9, 9, 8, none);
  m.insert(8, 0, 3) = MtLeafRange{4, 11};
  EXPECT_EQ(m.get(8, 0, 3).begin, 4u);
  EXPECT_EQ(m.get(8, 0, 3).end, 11u);
  EXPECT_EQ(m.get(0, 0, 0).begin, MT_NULL);  // other block
  EXPECT_EQ(m.get(8, 1, 3).begin, MT_NULL);  // same block, never written
  EXPECT_EQ(m.numBlocks(), 1u);
  // The block along x is 1 wide past entry 7: 9 entries need 2 blocks of 8.
  EXPECT_EQ(m.desc().ptrDims[0], 2);
  EXPECT_EQ(m.bytes(), m.pointerCount() * 4 + size_t(512) * sizeof(MtLeafRange));
}

TEST(BlockSparse, CeilLog2) {
  EXPECT_EQ(ceilLog2(1), 0);
  EXPECT_EQ(ceilLog2(2), 1);
  EXPECT_EQ(ceilLog2(3), 2);
  EXPECT_EQ(ceilLog2(4), 2);
  EXPECT_EQ(ceilLog2(5), 3);
  EXPECT_EQ(ceilLog2(1000), 10);
  EXPECT_EQ(ceilLog2(uint64_t{1} << 40), 40);
  EXPECT_EQ(ceilLog2((uint64_t{1} << 40) + 1), 41);
}

// allocateMarked: the marked blocks get storage indices 0, 1, 2, ... in pointer-matrix (scan)
// order, unmarked ones MT_NULL; any previous content is dropped. Sizes on both sides of the
// serial/parallel thresholds of the scan (2^15) and of the MT_NULL fix-up loop (65536).
class BlockSparseAllocate : public ::testing::TestWithParam<std::tuple<Shape, int, int>> {};

TEST_P(BlockSparseAllocate, BlocksInScanOrder) {
  const Shape s = std::get<0>(GetParam());
  const int B = std::get<1>(GetParam());
  const int threads = std::get<2>(GetParam());
  BlockSparseMatrix<uint16_t> m(s.nx, s.ny, s.nz, B, 77);
  m.insert(0, 0, 0) = 1;
  m.insert(s.nx - 1, s.ny - 1, s.nz - 1) = 2;

  const size_t np = m.pointerCount();
  std::vector<uint8_t> marks(np);
  mtest::Rng rng(mtest::seedFor(shapeName(s), static_cast<uint64_t>(B * 16 + threads)));
  for (auto& v : marks) v = rng.uniform() < 0.3 ? 1 : 0;
  if (np > 2) marks[0] = 0, marks[np - 1] = 1;

  const uint32_t total = m.allocateMarked(marks.data(), threads);
  uint32_t expected = 0;
  size_t wrong = 0;
  for (size_t p = 0; p < np; ++p) {
    const uint32_t want = marks[p] ? expected++ : MT_NULL;
    wrong += m.pointers()[p] != want;
  }
  EXPECT_EQ(wrong, 0u);
  EXPECT_EQ(total, expected);
  EXPECT_EQ(m.numBlocks(), expected);
  EXPECT_EQ(m.data().size(), size_t(expected) * m.blockVolume());
  EXPECT_TRUE(std::all_of(m.data().begin(), m.data().end(), [](uint16_t v) { return v == 77; }));
  EXPECT_EQ(m.bytes(), m.pointerBytes() + size_t(expected) * m.blockVolume() * sizeof(uint16_t));
  // Entries read through the new pointers: empty value where marked, absent elsewhere; the
  // values inserted before are gone.
  EXPECT_EQ(m.get(0, 0, 0), 77);
  EXPECT_EQ(m.get(s.nx - 1, s.ny - 1, s.nz - 1), 77);
  // entryCoords inverts storageIndex over the allocated entries (sampled).
  size_t badCoords = 0, checked = 0;
  for (int k = 0; k < s.nz; k += 3)
    for (int j = 0; j < s.ny; j += 2)
      for (int i = 0; i < s.nx; ++i) {
        const uint32_t si = m.storageIndex(i, j, k);
        if (si == MT_NULL) continue;
        int c[3];
        m.entryCoords(si, c);
        badCoords += c[0] != i || c[1] != j || c[2] != k;
        ++checked;
      }
  EXPECT_EQ(badCoords, 0u);
  EXPECT_GT(checked, 0u);
  EXPECT_EQ(m.find(0, 0, 0), nullptr) << "block 0 was not marked";
  EXPECT_NE(m.find(s.nx - 1, s.ny - 1, s.nz - 1), nullptr) << "the last block was marked";
  // After allocation, inserting into an allocated block does not grow the storage.
  const size_t before = m.bytes();
  m.insert(s.nx - 1, s.ny - 1, s.nz - 1) = 5;
  EXPECT_EQ(m.bytes(), before);
  EXPECT_EQ(m.get(s.nx - 1, s.ny - 1, s.nz - 1), 5);
}

INSTANTIATE_TEST_SUITE_P(Sizes, BlockSparseAllocate,
                         ::testing::Combine(::testing::Values(Shape{37, 5, 64}, Shape{128, 128, 64},
                                                              Shape{300, 200, 3}),
                                            ::testing::Values(1, 8), ::testing::Values(1, 2, 3)),
                         [](const ::testing::TestParamInfo<std::tuple<Shape, int, int>>& info) {
                           return shapeName(std::get<0>(info.param)) + "_B" +
                                  std::to_string(std::get<1>(info.param)) + "_T" +
                                  std::to_string(std::get<2>(info.param));
                         });

TEST(BlockSparse, AllocateNothing) {
  BlockSparseMatrix<int> m(10, 10, 10, 2, -1);
  m.insert(3, 3, 3) = 4;
  std::vector<uint8_t> marks(m.pointerCount(), 0);
  EXPECT_EQ(m.allocateMarked(marks.data(), 2), 0u);
  EXPECT_EQ(m.numBlocks(), 0u);
  EXPECT_EQ(m.bytes(), m.pointerBytes());
  EXPECT_EQ(m.get(3, 3, 3), -1);
}

TEST(BlockSparse, BadArgumentsThrow) {
  using M = BlockSparseMatrix<int>;
  EXPECT_THROW(M(0, 1, 1), std::invalid_argument);
  EXPECT_THROW(M(1, 0, 1), std::invalid_argument);
  EXPECT_THROW(M(1, 1, 0), std::invalid_argument);
  EXPECT_THROW(M(-4, 1, 1), std::invalid_argument);
  for (int edge : {0, -8, 3, 6, 12, 64, 1 << 20})
    EXPECT_THROW(M(4, 4, 4, edge), std::invalid_argument) << "block edge " << edge;
  for (int edge : {1, 2, 4, 8, 16, 32}) EXPECT_NO_THROW(M(4, 4, 4, edge)) << "block edge " << edge;
  // A pointer matrix with 2^32 or more cells cannot be addressed by 32-bit indices.
  EXPECT_THROW(BlockSparseMatrix<uint8_t>(1 << 20, 1 << 20, 1 << 10, 1), std::length_error);
  // ... also where the cell count would wrap around 2^64 (2^66 cells).
  EXPECT_THROW(BlockSparseMatrix<uint8_t>(1 << 22, 1 << 22, 1 << 22, 1), std::length_error);
  EXPECT_THROW(BlockSparseMatrix<uint8_t>(0x7FFFFFFF, 0x7FFFFFFF, 0x7FFFFFFF, 2), std::length_error);
  EXPECT_NO_THROW(BlockSparseMatrix<uint8_t>(0x7FFFFFFF, 1, 1, 32));  // 2^26 cells: fine

  M m(5, 6, 7, 4, 0);
  EXPECT_THROW(m.insert(-1, 0, 0), std::out_of_range);
  EXPECT_THROW(m.insert(0, -1, 0), std::out_of_range);
  EXPECT_THROW(m.insert(0, 0, -1), std::out_of_range);
  EXPECT_THROW(m.insert(5, 0, 0), std::out_of_range);
  EXPECT_THROW(m.insert(0, 6, 0), std::out_of_range);
  EXPECT_THROW(m.insert(0, 0, 7), std::out_of_range);
  EXPECT_EQ(m.numBlocks(), 0u) << "a rejected insert must not allocate";
  EXPECT_THROW(m.reset(3, 3, 3, 5, 0), std::invalid_argument);
}

TEST(BlockSparse, ResetDropsEverything) {
  BlockSparseMatrix<int> m(8, 8, 8, 2, 0);
  for (int i = 0; i < 8; ++i) m.insert(i, i, i) = i + 1;
  EXPECT_EQ(m.numBlocks(), 4u);
  m.reset(3, 2, 1, 4, 9);
  EXPECT_EQ(m.numBlocks(), 0u);
  EXPECT_EQ(m.data().size(), 0u);
  EXPECT_EQ(m.get(0, 0, 0), 9);
  EXPECT_EQ(m.dim(0), 3);
  EXPECT_EQ(m.desc().logBlock[0], 2);  // 3 entries -> a block of 4
  EXPECT_EQ(m.desc().logBlock[1], 1);  // 2 entries -> 2
  EXPECT_EQ(m.desc().logBlock[2], 0);  // 1 entry -> 1
  EXPECT_EQ(m.blockVolume(), 8u);
}

}  // namespace

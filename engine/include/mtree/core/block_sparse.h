// BlockSparseMatrix (paper §3): a 3-D matrix split into blocks of B^3 entries, with a dense
// *pointer matrix* that holds, per block, the index of its allocated storage or MT_NULL.
// Insert and access are O(1): one read of the pointer matrix, one read of the block.
// Storage is flat and pointer-free (32-bit block indices into one array), so it uploads to an
// OpenCL device as it is. Memory: 4 bytes per pointer-matrix cell + B^3 * sizeof(T) per
// allocated block, i.e. it follows the occupied space, not the bounding box.
#pragma once

#include <algorithm>
#include <cassert>
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <vector>

#include "mtree/core/layout.h"
#include "mtree/core/memory.h"
#include "mtree/core/parallel.h"

namespace mtree {

/// log2 of the smallest power of two >= n (n >= 1).
inline int ceilLog2(uint64_t n) {
  int l = 0;
  while ((uint64_t{1} << l) < n) ++l;
  return l;
}

template <typename T>
class BlockSparseMatrix {
 public:
  BlockSparseMatrix() { reset(1, 1, 1, 8, T{}); }
  /// dims: entries per axis (any positive size); blockEdge: a power of two in [1, 32]. Along an
  /// axis shorter than blockEdge the block is shrunk to the axis (a 1-node level has 1-entry blocks).
  BlockSparseMatrix(int nx, int ny, int nz, int blockEdge = 8, T emptyValue = T{}) {
    reset(nx, ny, nz, blockEdge, emptyValue);
  }

  void reset(int nx, int ny, int nz, int blockEdge, T emptyValue) {
    if (blockEdge < 1 || blockEdge > (1 << MT_MAX_LOG_BLOCK) || (blockEdge & (blockEdge - 1)))
      throw std::invalid_argument("BlockSparseMatrix: block edge must be a power of two in [1, 32]");
    const int lb = ceilLog2(static_cast<uint64_t>(blockEdge));
    const int logBlock[3] = {lb, lb, lb};
    resetShape(nx, ny, nz, logBlock, emptyValue);
  }
  /// reset() with a block shape of 2^logBlock[a] entries along axis a (each in
  /// [0, MT_MAX_LOG_BLOCK], shrunk to the axis as in reset()): blocks need not be cubes.
  void resetShape(int nx, int ny, int nz, const int logBlock[3], T emptyValue) {
    if (nx < 1 || ny < 1 || nz < 1) throw std::invalid_argument("BlockSparseMatrix: dims must be >= 1");
    for (int a = 0; a < 3; ++a)
      if (logBlock[a] < 0 || logBlock[a] > MT_MAX_LOG_BLOCK)
        throw std::invalid_argument("BlockSparseMatrix: log2 of a block edge must be in [0, 5]");
    const int n[3] = {nx, ny, nz};
    desc_ = MtSparseDesc{};
    uint64_t ptrCount = 1;
    for (int a = 0; a < 3; ++a) {
      desc_.dims[a] = n[a];
      desc_.logBlock[a] = std::min(logBlock[a], ceilLog2(static_cast<uint64_t>(n[a])));
      desc_.ptrDims[a] = static_cast<int>((int64_t(n[a]) + (int64_t(1) << desc_.logBlock[a]) - 1) >> desc_.logBlock[a]);
      // Checked before multiplying, so a huge matrix cannot wrap around 2^64.
      if (ptrCount > (uint64_t(MT_NULL) - 1) / static_cast<uint64_t>(desc_.ptrDims[a]))
        throw std::length_error("BlockSparseMatrix: pointer matrix too large (more than 2^32 blocks)");
      ptrCount *= static_cast<uint64_t>(desc_.ptrDims[a]);
    }
    desc_.blockVolume = 1u << (desc_.logBlock[0] + desc_.logBlock[1] + desc_.logBlock[2]);
    if (ptrCount >= MT_NULL) throw std::length_error("BlockSparseMatrix: pointer matrix too large");
    empty_ = emptyValue;
    ptr_.assign(static_cast<size_t>(ptrCount), MT_NULL);
    data_.clear();
    blockPos_.clear();
    desc_.numBlocks = 0;
  }

  const MtSparseDesc& desc() const { return desc_; }
  int dim(int a) const { return desc_.dims[a]; }
  uint32_t numBlocks() const { return desc_.numBlocks; }
  uint32_t blockVolume() const { return desc_.blockVolume; }
  size_t pointerCount() const { return ptr_.size(); }
  const T& emptyValue() const { return empty_; }

  bool inRange(int i, int j, int k) const {
    return i >= 0 && j >= 0 && k >= 0 && i < desc_.dims[0] && j < desc_.dims[1] && k < desc_.dims[2];
  }
  size_t pointerIndex(int i, int j, int k) const {
    return (static_cast<size_t>(k >> desc_.logBlock[2]) * desc_.ptrDims[1] + (j >> desc_.logBlock[1])) *
               desc_.ptrDims[0] +
           (i >> desc_.logBlock[0]);
  }
  uint32_t localIndex(int i, int j, int k) const {
    const int mx = (1 << desc_.logBlock[0]) - 1, my = (1 << desc_.logBlock[1]) - 1,
              mz = (1 << desc_.logBlock[2]) - 1;
    return (static_cast<uint32_t>(k & mz) << (desc_.logBlock[0] + desc_.logBlock[1])) |
           (static_cast<uint32_t>(j & my) << desc_.logBlock[0]) | static_cast<uint32_t>(i & mx);
  }
  /// Index of entry (i,j,k) in the flat block storage, or MT_NULL if its block is absent.
  uint32_t storageIndex(int i, int j, int k) const {
    assert(inRange(i, j, k));
    const uint32_t b = ptr_[pointerIndex(i, j, k)];
    return b == MT_NULL ? MT_NULL : b * desc_.blockVolume + localIndex(i, j, k);
  }
  /// Pointer to entry (i,j,k), or nullptr if its block is not allocated. Two reads.
  const T* find(int i, int j, int k) const {
    const uint32_t s = storageIndex(i, j, k);
    return s == MT_NULL ? nullptr : &data_[s];
  }
  /// Value at (i,j,k); the empty value where no block is allocated.
  const T& get(int i, int j, int k) const {
    const T* p = find(i, j, k);
    return p ? *p : empty_;
  }
  /// Entry (i,j,k), allocating its block (filled with the empty value) if needed. Serial.
  T& insert(int i, int j, int k) {
    if (!inRange(i, j, k)) throw std::out_of_range("BlockSparseMatrix::insert: index out of range");
    uint32_t& b = ptr_[pointerIndex(i, j, k)];
    if (b == MT_NULL) {
      blockPos_.push_back(static_cast<uint32_t>(pointerIndex(i, j, k)));
      b = desc_.numBlocks++;
      data_.resize(static_cast<size_t>(desc_.numBlocks) * desc_.blockVolume, empty_);
    }
    return data_[static_cast<size_t>(b) * desc_.blockVolume + localIndex(i, j, k)];
  }

  /// Bulk allocation of the §5.1 build, steps 3-4: `marks` has one byte per pointer-matrix cell;
  /// an exclusive scan of the marks gives each marked block its storage index. Any previous
  /// content is dropped. Returns the number of blocks.
  uint32_t allocateMarked(const uint8_t* marks, int threads) {
    const size_t n = ptr_.size();
    const uint64_t total = exclusiveScan(marks, ptr_.data(), n, threads);
    if (total * desc_.blockVolume >= MT_NULL) throw std::length_error("BlockSparseMatrix: too many blocks");
    blockPos_.resize(static_cast<size_t>(total));
#pragma omp parallel for num_threads(threads) schedule(static) if (n > 65536)
    for (int64_t i = 0; i < static_cast<int64_t>(n); ++i) {
      if (marks[i]) blockPos_[ptr_[i]] = static_cast<uint32_t>(i);
      else ptr_[i] = MT_NULL;
    }
    desc_.numBlocks = static_cast<uint32_t>(total);
    data_.assign(static_cast<size_t>(total) * desc_.blockVolume, empty_);
    return desc_.numBlocks;
  }

  /// Coordinates of the entry at flat storage index s (inverse of storageIndex). Only for
  /// matrices filled by allocateMarked(), which records every block's pointer-matrix position.
  void entryCoords(uint32_t s, int c[3]) const {
    const uint32_t b = s / desc_.blockVolume, local = s % desc_.blockVolume;
    const uint32_t p = blockPos_[b];
    const int bx = static_cast<int>(p % desc_.ptrDims[0]);
    const int by = static_cast<int>((p / desc_.ptrDims[0]) % desc_.ptrDims[1]);
    const int bz = static_cast<int>(p / (uint32_t(desc_.ptrDims[0]) * desc_.ptrDims[1]));
    const uint32_t mx = (1u << desc_.logBlock[0]) - 1, my = (1u << desc_.logBlock[1]) - 1;
    c[0] = (bx << desc_.logBlock[0]) | static_cast<int>(local & mx);
    c[1] = (by << desc_.logBlock[1]) | static_cast<int>((local >> desc_.logBlock[0]) & my);
    c[2] = (bz << desc_.logBlock[2]) | static_cast<int>(local >> (desc_.logBlock[0] + desc_.logBlock[1]));
  }

  const std::vector<uint32_t>& pointers() const { return ptr_; }
  const LargeVector<T>& data() const { return data_; }
  LargeVector<T>& data() { return data_; }

  size_t pointerBytes() const { return ptr_.size() * sizeof(uint32_t); }
  size_t blockBytes() const { return data_.size() * sizeof(T); }
  size_t bytes() const { return pointerBytes() + blockBytes(); }

 private:
  MtSparseDesc desc_{};
  std::vector<uint32_t> ptr_;
  LargeVector<T> data_;
  std::vector<uint32_t> blockPos_;  // pointer-matrix position of every allocated block
  T empty_{};
};

}  // namespace mtree

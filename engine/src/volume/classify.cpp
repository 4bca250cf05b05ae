// BlockSparseVolume's classification (paper §3 applied to volumes): which cells a visible sample
// can read, the blocks or apron bricks that hold them, the matrix-tree levels over the bricks and
// the bricks' empty cubes per ray octant; and the trilinear point sample. See
// engine/include/mtree/volume/volume.h for the layouts and why skipping is exact.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <vector>

#include "march.h"
#include "mtree/core/parallel.h"
#include "mtree/volume/volume.h"

namespace mtree {

void BlockSparseVolume::classify(const TransferTable& tf, const VolumeBuildOptions& opt, std::vector<float>& dense) {
  const auto start = std::chrono::steady_clock::now();
  const int threads = resolveThreads(opt.threads);
  const int n[3] = {n_[0], n_[1], n_[2]};
  const int nb[3] = {(n[0] - 1 + DIM - 1) / DIM, (n[1] - 1 + DIM - 1) / DIM, (n[2] - 1 + DIM - 1) / DIM};
  const int64_t nBricks = int64_t(nb[0]) * nb[1] * nb[2];
  const size_t sx = 1, sy = size_t(n[0]), sz = size_t(n[0]) * n[1];
  auto at = [&](int i, int j, int k) { return dense[size_t(k) * sz + size_t(j) * sy + size_t(i) * sx]; };
  const bool compact = storage_ != VoxelStorage::Float32;
  // From here on `dense` holds stored values (UInt8/UInt16: value - offset, exact for integer
  // input; quantised input rounded to the nearest step), and the visibility is that of the values
  // they stand for, value(s) = s * scale_ + offset_ (monotone; s itself for Float32), i.e. of
  // what the marchers will read.
  if (compact) {
    const float off = offset_;
    const double scale = scale_;
    const bool quantized = quantized_;
    const int64_t total = int64_t(n[0]) * n[1] * n[2];
#pragma omp parallel for num_threads(threads) schedule(static)
    for (int64_t i = 0; i < total; ++i) {
      float& v = dense[size_t(i)];
      v = quantized ? float(std::min(65535.0, std::max(0.0, std::nearbyint((double(v) - off) / scale)))) : v - off;
    }
  }
  const float scale = scale_, offset = offset_;
  const auto value = [scale, offset](float s) { return s * scale + offset; };

  brickMin_.assign(size_t(nBricks), 0.f);
  brickMax_.assign(size_t(nBricks), 0.f);
  levels_.assign(1, LevelGrid{});
  LevelGrid& l0 = levels_[0];
  for (int a = 0; a < 3; ++a) l0.n[a] = nb[a];
  l0.occ.assign(size_t(nBricks), 0);
  std::vector<uint8_t> marks(vox_.pointerCount(), opt.sparse ? 0 : 1);
  cellMask_.assign(compact ? size_t(nBricks) * DIM : 0, 0);
  uint64_t visibleCells = 0;
  const float tfMag = scale_ != 1.f ? float(std::fabs(tf.lo()) + std::fabs(tf.hi())) : 0.f;

#pragma omp parallel for num_threads(threads) schedule(dynamic, 4) reduction(+ : visibleCells)
  for (int64_t b = 0; b < nBricks; ++b) {
    const int bi = int(b % nb[0]), bj = int((b / nb[0]) % nb[1]), bk = int(b / (int64_t(nb[0]) * nb[1]));
    const int c0[3] = {bi * DIM, bj * DIM, bk * DIM};
    const int c1[3] = {std::min(c0[0] + DIM, n[0] - 1), std::min(c0[1] + DIM, n[1] - 1),
                       std::min(c0[2] + DIM, n[2] - 1)};  // cells [c0, c1), voxels [c0, c1]
    float mn = std::numeric_limits<float>::infinity(), mx = -mn;
    for (int k = c0[2]; k <= c1[2]; ++k)
      for (int j = c0[1]; j <= c1[1]; ++j)
        for (int i = c0[0]; i <= c1[0]; ++i) {
          const float v = at(i, j, k);
          mn = std::min(mn, v);
          mx = std::max(mx, v);
        }
    mn = value(mn);
    mx = value(mx);
    brickMin_[size_t(b)] = mn;
    brickMax_[size_t(b)] = mx;
    // Round-off bound of an interpolation (of stored values, then + offset_: see maxOpacity); in
    // sample units (scale_ != 1) the table's origin and scale are rounded too, hence its range.
    const auto tol = [&](float a, float b) { return 1e-5f * (std::fabs(a) + std::fabs(b) + 2.f * std::fabs(offset_) + tfMag) + 1e-30f; };
    if (tf.maxOpacity(mn, mx, tol(mn, mx)) <= 0.f) continue;  // the whole brick is transparent
    uint64_t vis = 0;
    for (int k = c0[2]; k < c1[2]; ++k)
      for (int j = c0[1]; j < c1[1]; ++j)
        for (int i = c0[0]; i < c1[0]; ++i) {
          float lo = at(i, j, k), hi = lo;
          for (int c = 1; c < 8; ++c) {
            const float v = at(i + (c & 1), j + ((c >> 1) & 1), k + (c >> 2));
            lo = std::min(lo, v);
            hi = std::max(hi, v);
          }
          lo = value(lo);
          hi = value(hi);
          if (tf.maxOpacity(lo, hi, tol(lo, hi)) <= 0.f) continue;
          ++vis;
          if (compact) cellMask_[size_t(b) * DIM + (k - c0[2])] |= uint64_t(1) << ((i - c0[0]) + DIM * (j - c0[1]));
          if (!opt.sparse) continue;
          for (int c = 0; c < 8; ++c) {
            const size_t p = vox_.pointerIndex(i + (c & 1), j + ((c >> 1) & 1), k + (c >> 2));
            // Bricks share their face voxels' blocks: every access to marks is atomic.
            uint8_t seen;
#pragma omp atomic read
            seen = marks[p];
            if (!seen) {
#pragma omp atomic write
              marks[p] = 1;
            }
          }
        }
    if (vis) l0.occ[size_t(b)] = 1;
    visibleCells += vis;
  }

  uint32_t marked = 0;
  for (uint8_t m : marks) marked += m;
  const uint32_t blockVolume = vox_.desc().blockVolume;
  const uint32_t blocksDense = static_cast<uint32_t>(vox_.pointerCount());
  brickPtr_.clear();
  b8_.clear();
  b16_.clear();
  if (storage_ != VoxelStorage::Float32) {
    // Apron bricks in the input's width: brick b holds voxels [DIM b, DIM b + DIM] per axis
    // (clamped at the far faces), i.e. every corner of its cells. Stored: the visible bricks.
    brickPtr_.assign(size_t(nBricks), MT_NULL);
    uint32_t count = 0;
    for (int64_t b = 0; b < nBricks; ++b)
      if (!opt.sparse || l0.occ[size_t(b)]) brickPtr_[size_t(b)] = count++;
    paired_ = storage_ == VoxelStorage::UInt8 && nBricks <= PAIRED_MAX_BRICKS;
    if (storage_ == VoxelStorage::UInt8) b8_.assign(size_t(count) * (paired_ ? BRICK_BYTES8 : BRICK_VOLUME) + BRICK_PAD, 0);
    else b16_.assign(size_t(count) * BRICK_VOLUME, 0);
#pragma omp parallel for num_threads(threads) schedule(static)
    for (int64_t b = 0; b < nBricks; ++b) {
      const uint32_t s = brickPtr_[size_t(b)];
      if (s == MT_NULL) continue;
      const int o[3] = {int(b % nb[0]) * DIM, int((b / nb[0]) % nb[1]) * DIM, int(b / (int64_t(nb[0]) * nb[1])) * DIM};
      const size_t base = size_t(s) * BRICK_VOLUME;
      for (int k = 0; k < APRON; ++k)
        for (int j = 0; j < APRON; ++j)
          for (int i = 0; i < APRON; ++i) {
            const float v = at(std::min(o[0] + i, n[0] - 1), std::min(o[1] + j, n[1] - 1), std::min(o[2] + k, n[2] - 1));
            const size_t e = base + size_t(k) * APRON * APRON + size_t(j) * APRON + size_t(i);
            if (paired_) {
              // Rows of y pairs: voxel row j is the first of pair row j and the second of j - 1.
              const size_t pb = size_t(s) * BRICK_BYTES8;
              const uint8_t u = static_cast<uint8_t>(v);
              if (j < DIM) b8_[pb + size_t(pairOffset(i, j, k))] = u;
              if (j > 0) b8_[pb + size_t(pairOffset(i, j - 1, k)) + 1] = u;
            } else if (storage_ == VoxelStorage::UInt8) {
              b8_[e] = static_cast<uint8_t>(v);
            } else {
              b16_[e] = static_cast<uint16_t>(v);
            }
          }
    }
    stats_.bricksStored = count;
    vox_.reset(1, 1, 1, 1, 0.f);  // the float matrix is not held in this layout
  } else {
  // §5.1 steps 3-4: scan the marks into block indices, then fill the blocks from the dense copy.
  vox_.allocateMarked(marks.data(), threads);
  const MtSparseDesc& d = vox_.desc();
  LargeVector<float>& data = vox_.data();
  const int e[3] = {1 << d.logBlock[0], 1 << d.logBlock[1], 1 << d.logBlock[2]};
#pragma omp parallel for num_threads(threads) schedule(static)
  for (int64_t b = 0; b < int64_t(d.numBlocks); ++b) {
    int o[3];
    vox_.entryCoords(uint32_t(b) * d.blockVolume, o);
    float* dst = data.data() + size_t(b) * d.blockVolume;
    for (int k = 0; k < e[2]; ++k)
      for (int j = 0; j < e[1]; ++j)
        for (int i = 0; i < e[0]; ++i) {
          const int x = o[0] + i, y = o[1] + j, z = o[2] + k;
          if (x < n[0] && y < n[1] && z < n[2])
            dst[(size_t(k) * e[1] + j) * e[0] + i] = at(x, y, z);
        }
  }
  }
  ptr_ = vox_.pointers().data();
  data_ = vox_.data().data();
  std::vector<float>().swap(dense);

  // Per octant, the edge of the largest invisible cube of bricks with each brick at its corner:
  // r(b) = 1 + min of r over the 7 neighbours ahead of b in that octant (the 3-d form of the
  // largest-empty-square recurrence), 0 at a visible brick, 255 beyond the grid.
  // Held for the 8/16-bit layouts only (their float marcher walks by it).
  dist_.assign(compact ? size_t(nBricks) * 8 : 0, 0);
  for (int oct = 0; oct < (compact ? 8 : 0); ++oct) {
    const int s0 = oct & 1 ? -1 : 1, s1 = oct & 2 ? -1 : 1, s2 = oct & 4 ? -1 : 1;
    const auto at = [&](int i, int j, int k) -> int {
      if (i < 0 || j < 0 || k < 0 || i >= nb[0] || j >= nb[1] || k >= nb[2]) return 255;
      return dist_[size_t((int64_t(k) * nb[1] + j) * nb[0] + i) * 8 + oct];
    };
    for (int kk = 0; kk < nb[2]; ++kk)
      for (int jj = 0; jj < nb[1]; ++jj)
        for (int ii = 0; ii < nb[0]; ++ii) {
          // The neighbours ahead first: ascending against the octant's sign.
          const int i = s0 > 0 ? nb[0] - 1 - ii : ii, j = s1 > 0 ? nb[1] - 1 - jj : jj, k = s2 > 0 ? nb[2] - 1 - kk : kk;
          const int64_t bidx = (int64_t(k) * nb[1] + j) * nb[0] + i;
          if (l0.occ[size_t(bidx)]) continue;  // 0
          int m = 255;
          for (int c = 1; c < 8; ++c) m = std::min(m, at(i + (c & 1) * s0, j + ((c >> 1) & 1) * s1, k + (c >> 2) * s2));
          dist_[size_t(bidx) * 8 + oct] = uint8_t(std::min(255, m + 1));
        }
  }

  // Matrix-tree levels above the bricks: level l+1 node = OR of its 2x2x2 children.
  while (levels_.back().n[0] > 1 || levels_.back().n[1] > 1 || levels_.back().n[2] > 1) {
    const LevelGrid& c = levels_.back();
    LevelGrid p;
    for (int a = 0; a < 3; ++a) p.n[a] = (c.n[a] + 1) / 2;
    p.occ.assign(size_t(p.n[0]) * p.n[1] * p.n[2], 0);
    for (int k = 0; k < c.n[2]; ++k)
      for (int j = 0; j < c.n[1]; ++j)
        for (int i = 0; i < c.n[0]; ++i)
          if (c.occ[(size_t(k) * c.n[1] + j) * c.n[0] + i])
            p.occ[(size_t(k / 2) * p.n[1] + j / 2) * p.n[0] + i / 2] = 1;
    levels_.push_back(std::move(p));
  }

  VolumeStats& s = stats_;
  s.voxels = uint64_t(n[0]) * n[1] * n[2];
  s.cells = uint64_t(n[0] - 1) * (n[1] - 1) * (n[2] - 1);
  s.visibleCells = visibleCells;
  s.blocksAllocated = marked;
  s.blocksDense = blocksDense;
  s.storage = storage_;
  s.bricks = static_cast<uint32_t>(nBricks);
  s.bricksVisible = 0;
  for (uint8_t o : levels_[0].occ) s.bricksVisible += o;  // (l0 dangles after the push_backs)
  s.blockBytes = uint64_t(marked) * blockVolume * sizeof(float);
  uint64_t levelBytes = 0;
  for (const LevelGrid& g : levels_) levelBytes += g.occ.size();
  const uint64_t voxelBytes = storage_ == VoxelStorage::Float32
                                  ? vox_.bytes()
                                  : brickPtr_.size() * sizeof(uint32_t) + b8_.size() + b16_.size() * sizeof(uint16_t) +
                                        cellMask_.size() * sizeof(uint64_t);
  s.bytes = voxelBytes + (brickMin_.size() + brickMax_.size()) * sizeof(float) + levelBytes + dist_.size();
  s.denseBytes = s.voxels * sizeof(float);
  s.levels = levelCount();
  s.buildMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

bool BlockSparseVolume::sample(double x, double y, double z, double& v) const {
  using volume_detail::clampCell;
  double f[3];
  const int i = clampCell(x, dim(0), f[0]), j = clampCell(y, dim(1), f[1]), k = clampCell(z, dim(2), f[2]);
  float c[8];
  if (!cellCorners(i, j, k, c)) return false;
  v = volume_detail::trilinear<double>(c, f[0], f[1], f[2]);
  return true;
}

}  // namespace mtree

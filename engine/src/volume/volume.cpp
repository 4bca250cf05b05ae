// Block-sparse volume: classification, the matrix-tree levels over the bricks, and the ray
// marcher. See engine/include/mtree/volume/volume.h for the design and why skipping is exact.
#include "mtree/volume/volume.h"

#include <chrono>
#include <cstdlib>
#include <cstring>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif
// The AVX2 marcher needs GCC/Clang function targets on x86 (runtime dispatch, no -march).
#if defined(__SSE2__) && defined(__GNUC__) && (defined(__x86_64__) || defined(__i386__))
#define MT_VOLUME_AVX2 1
#include <immintrin.h>
#else
#define MT_VOLUME_AVX2 0
#endif

#include <omp.h>

#include "mtree/core/parallel.h"

namespace mtree {

// ------------------------------------------------------------------------------- TransferTable

TransferTable::TransferTable(double lo, double hi, std::vector<float> rgba, double unitDistance)
    : lo_(lo), hi_(hi), unit_(unitDistance), rgba_(std::move(rgba)) {
  if (rgba_.size() < 8 || rgba_.size() % 4)
    throw std::invalid_argument("TransferTable: need 4 floats per entry and at least 2 entries");
  if (!std::isfinite(lo) || !std::isfinite(hi) || !(hi > lo))
    throw std::invalid_argument("TransferTable: need finite lo < hi");
  if (!(unitDistance > 0) || !std::isfinite(unitDistance))
    throw std::invalid_argument("TransferTable: unit distance must be positive");
  for (float& f : rgba_) f = std::isfinite(f) ? std::min(1.f, std::max(0.f, f)) : 0.f;
  const int n = size();
  last_ = n - 1;
  flo_ = static_cast<float>(lo);
  fscale_ = static_cast<float>(last_ / (hi - lo));
  rangeMax_.clear();
  rangeMax_.emplace_back(n);
  for (int i = 0; i < n; ++i) rangeMax_[0][i] = rgba_[4 * size_t(i) + 3];
  for (int l = 1; (1 << l) <= n; ++l) {
    const std::vector<float>& prev = rangeMax_[l - 1];
    std::vector<float> cur(size_t(n - (1 << l) + 1));
    for (size_t i = 0; i < cur.size(); ++i) cur[i] = std::max(prev[i], prev[i + (size_t(1) << (l - 1))]);
    rangeMax_.push_back(std::move(cur));
  }
}

float TransferTable::maxOpacity(float a, float b, float tol) const {
  if (rgba_.empty()) return 0.f;
  const float lo = std::min(a, b), hi = std::max(a, b);
  if (!(tol >= 0.f)) tol = 1e-5f * (std::fabs(lo) + std::fabs(hi)) + 1e-30f;
  const int i = std::max(index(lo - tol), 0), j = std::min(index(hi + tol), last_);
  int l = 0;
  while ((2 << l) <= j - i + 1) ++l;
  return std::max(rangeMax_[l][i], rangeMax_[l][j - (1 << l) + 1]);
}

// --------------------------------------------------------------------------- BlockSparseVolume

void BlockSparseVolume::classify(const TransferTable& tf, const VolumeBuildOptions& opt, std::vector<float>& dense) {
  const auto start = std::chrono::steady_clock::now();
  const int threads = resolveThreads(opt.threads);
  const int n[3] = {n_[0], n_[1], n_[2]};
  const int nb[3] = {(n[0] - 1 + DIM - 1) / DIM, (n[1] - 1 + DIM - 1) / DIM, (n[2] - 1 + DIM - 1) / DIM};
  const int64_t nBricks = int64_t(nb[0]) * nb[1] * nb[2];
  const size_t sx = 1, sy = size_t(n[0]), sz = size_t(n[0]) * n[1];
  auto at = [&](int i, int j, int k) { return dense[size_t(k) * sz + size_t(j) * sy + size_t(i) * sx]; };

  brickMin_.assign(size_t(nBricks), 0.f);
  brickMax_.assign(size_t(nBricks), 0.f);
  levels_.assign(1, LevelGrid{});
  LevelGrid& l0 = levels_[0];
  for (int a = 0; a < 3; ++a) l0.n[a] = nb[a];
  l0.occ.assign(size_t(nBricks), 0);
  std::vector<uint8_t> marks(vox_.pointerCount(), opt.sparse ? 0 : 1);
  const bool compact = storage_ != VoxelStorage::Float32;
  cellMask_.assign(compact ? size_t(nBricks) * DIM : 0, 0);
  uint64_t visibleCells = 0;

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
    brickMin_[size_t(b)] = mn;
    brickMax_[size_t(b)] = mx;
    // Round-off bound of an interpolation (of stored values, then + offset_: see maxOpacity).
    const auto tol = [&](float a, float b) { return 1e-5f * (std::fabs(a) + std::fabs(b) + 2.f * std::fabs(offset_)) + 1e-30f; };
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
          if (tf.maxOpacity(lo, hi, tol(lo, hi)) <= 0.f) continue;
          ++vis;
          if (compact) cellMask_[size_t(b) * DIM + (k - c0[2])] |= uint64_t(1) << ((i - c0[0]) + DIM * (j - c0[1]));
          if (!opt.sparse) continue;
          for (int c = 0; c < 8; ++c) {
            const size_t p = vox_.pointerIndex(i + (c & 1), j + ((c >> 1) & 1), k + (c >> 2));
            if (!marks[p]) {
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
    const float off = offset_;
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
              const uint8_t u = static_cast<uint8_t>(v - off);
              if (j < DIM) b8_[pb + size_t(pairOffset(i, j, k))] = u;
              if (j > 0) b8_[pb + size_t(pairOffset(i, j - 1, k)) + 1] = u;
            } else if (storage_ == VoxelStorage::UInt8) {
              b8_[e] = static_cast<uint8_t>(v - off);
            } else {
              b16_[e] = static_cast<uint16_t>(v - off);
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

namespace {

inline int clampCell(double q, int n, double& f) {
  // floor without a libm call (no SSE4.1 round instruction in baseline x86-64); q is clamped
  // first so the conversion cannot overflow.
  const double qc = std::min(std::max(q, -1.0), double(n));
  int c = static_cast<int>(qc);
  c -= (qc < c);
  c = std::min(std::max(c, 0), n - 2);
  f = std::min(1.0, std::max(0.0, q - c));
  return c;
}

template <typename R>
inline R trilinear(const float c[8], R fx, R fy, R fz) {
  const R x00 = c[0] + fx * (c[1] - c[0]), x10 = c[2] + fx * (c[3] - c[2]);
  const R x01 = c[4] + fx * (c[5] - c[4]), x11 = c[6] + fx * (c[7] - c[6]);
  const R y0 = x00 + fy * (x10 - x00), y1 = x01 + fy * (x11 - x01);
  return y0 + fz * (y1 - y0);
}

}  // namespace

bool BlockSparseVolume::sample(double x, double y, double z, double& v) const {
  double f[3];
  const int i = clampCell(x, dim(0), f[0]), j = clampCell(y, dim(1), f[1]), k = clampCell(z, dim(2), f[2]);
  float c[8];
  if (!cellCorners(i, j, k, c)) return false;
  v = trilinear<double>(c, f[0], f[1], f[2]);
  return true;
}

// --------------------------------------------------------------------------------- renderVolume

namespace {

constexpr int LOG2DIM = BlockSparseVolume::LOG2DIM;
constexpr int DIM = BlockSparseVolume::DIM;

/// Per-frame constants of the marcher (copied by value into each ray's loop).
struct Frame {
  const BlockSparseVolume* vol;
  int n[3];          // points per axis
  int nb[3];         // level-0 bricks per axis
  const float* table;  // premultiplied, opacity corrected for the step: 4 per entry, 16-byte aligned
  const float* table8;  // AVX2 marcher: 8 per entry, the 4 above and 1 - opacity 4 times (the factor
                        // of the transmittance, computed once per frame instead of per sample), 32-byte aligned
  float tlo, tscale;
  int tlast;
  float offset;      // added to an interpolated stored value
  double dt;         // world units per step
  float threshold;
  int lanes;         // 8: the unshaded UInt8/UInt16 float rays take the AVX2 marcher; 1: the SSE2 one
  bool setup4;       // perspective rays are set up 4 at a time with AVX2 (setupRays4: the same rays)
  const uint8_t* dist;        // BlockSparseVolume::brickDistances
  const uint32_t* runBricks;  // AVX2 marcher: per level-0 brick its stored brick's first entry where the walk may
                              // march through it, MT_NULL where it stops (absent; skipping: invisible)
  double spacing[3];
  double ambient, diffuse, specular, specularPower;
};

/// A ray of a tile queued for marchApronAvx2Pair (index-space origin and direction, entry, last
/// sample, its pixel), and a tile's queue.
struct PendingRay {
  double ro[3], rd[3], t0;
  int64_t kEnd;
  float* out;
};
struct PendingRayList {
  static constexpr int CAPACITY = 64;
  PendingRay rays[CAPACITY];
  int count = 0;
};

/// Fetch policies: enter(brick) resolves a brick's storage once; corners(local cell) reads the 8
/// corners (x fastest) of a cell of that brick as floats (offset not applied). false: the cell
/// reads an absent block, so it is invisible (opacity 0).

/// An 8-bit voxel of bricks held in rows of y pairs (BlockSparseVolume::pairedRows): its own type,
/// so that the marchers pick that layout at compile time.
struct Paired8 {
  uint8_t v;
};
inline float voxelValue(uint8_t x) { return float(x); }
inline float voxelValue(uint16_t x) { return float(x); }
inline float voxelValue(Paired8 x) { return float(x.v); }

/// Where the corners of a brick's local cell (lx, ly, lz) are: corner 0 at entry cell(l), corner n
/// (x fastest, then y, then z) at cell(l) + corner[n]; BRICK entries a brick.
template <typename T>
struct ApronLayout {  // uint8_t, uint16_t: APRON^3 entries, x fastest
  static constexpr int SY = BlockSparseVolume::APRON, SZ = SY * SY, BRICK = BlockSparseVolume::BRICK_VOLUME;
  static constexpr int corner[8] = {0, 1, SY, SY + 1, SZ, SZ + 1, SZ + SY, SZ + SY + 1};
  static int cell(int lx, int ly, int lz) { return lx + SY * ly + SZ * lz; }
};
template <>
struct ApronLayout<Paired8> {  // rows of y pairs
  static constexpr int SZ = BlockSparseVolume::PAIR_SZ, BRICK = BlockSparseVolume::BRICK_BYTES8;
  static constexpr int corner[8] = {0, 2, 1, 3, SZ, SZ + 2, SZ + 1, SZ + 3};
  static int cell(int lx, int ly, int lz) { return BlockSparseVolume::pairOffset(lx, ly, lz); }
};

/// UInt8/UInt16 apron bricks: every corner inside the brick, fixed offsets.
template <typename T>
struct ApronFetch {
  using Layout = ApronLayout<T>;
  const uint32_t* ptr;
  const T* data;
  const uint64_t* masks;
  int nb0, nb1;
  const T* base = nullptr;
  const uint64_t* mask = nullptr;  // the brick's visible cells, one word per z layer
  ApronFetch(const uint32_t* p, const T* d, const uint64_t* m, int n0, int n1)
      : ptr(p), data(d), masks(m), nb0(n0), nb1(n1) {}
  bool enter(int bi, int bj, int bk) {
    const size_t i = (size_t(bk) * nb1 + bj) * nb0 + bi;
    const uint32_t b = ptr[i];
    if (b == MT_NULL) return false;
    base = data + size_t(b) * Layout::BRICK;
    mask = masks + i * DIM;
    return true;
  }
  bool corners(int lx, int ly, int lz, float c[8]) const {
    if (!((mask[lz] >> (lx + DIM * ly)) & 1)) return false;  // invisible cell: opacity 0
    const T* p = base + Layout::cell(lx, ly, lz);
    for (int n = 0; n < 8; ++n) c[n] = voxelValue(p[Layout::corner[n]]);
    return true;
  }
};

/// Float32 block-sparse matrix (no apron): on entry, the brick's block and its 7 neighbours
/// towards +x/+y/+z; a cell whose corners all lie in the brick's block (7/8 per axis) reads them
/// at fixed offsets, the others pick each corner's block by the carry of its local index.
struct FloatFetch {
  const uint32_t* ptr;
  const float* data;
  int lb0, lb1, lb2, pd0, pd1, pd2, e0, e1, e2;
  uint32_t bv;
  const float* nbr[8] = {nullptr, nullptr, nullptr, nullptr, nullptr, nullptr, nullptr, nullptr};
  explicit FloatFetch(const BlockSparseMatrix<float>& m)
      : ptr(m.pointers().data()), data(m.data().data()), lb0(m.desc().logBlock[0]), lb1(m.desc().logBlock[1]),
        lb2(m.desc().logBlock[2]), pd0(m.desc().ptrDims[0]), pd1(m.desc().ptrDims[1]), pd2(m.desc().ptrDims[2]),
        e0((1 << lb0) - 1), e1((1 << lb1) - 1), e2((1 << lb2) - 1), bv(m.desc().blockVolume) {}
  bool enter(int bi, int bj, int bk) {
    // A block edge below DIM only happens on an axis that has a single block: brick = block.
    for (int n = 0; n < 8; ++n) {
      const int x = bi + (n & 1), y = bj + ((n >> 1) & 1), z = bk + (n >> 2);
      const uint32_t b = (x < pd0 && y < pd1 && z < pd2) ? ptr[(size_t(z) * pd1 + y) * pd0 + x] : MT_NULL;
      nbr[n] = b == MT_NULL ? nullptr : data + size_t(b) * bv;
    }
    return nbr[0] != nullptr;  // every cell of the brick has a corner in its own block
  }
  bool corners(int lx, int ly, int lz, float c[8]) const {
    const int sy = 1 << lb0, sz = 1 << (lb0 + lb1);
    if (lx < e0 && ly < e1 && lz < e2) {
      const float* p = nbr[0] + ((lz << (lb0 + lb1)) | (ly << lb0) | lx);
      c[0] = p[0]; c[1] = p[1]; c[2] = p[sy]; c[3] = p[sy + 1];
      c[4] = p[sz]; c[5] = p[sz + 1]; c[6] = p[sz + sy]; c[7] = p[sz + sy + 1];
      return true;
    }
    const int cx = lx == e0, cy = ly == e1, cz = lz == e2;
    const int ox[2] = {lx, (lx + 1) & e0}, oy[2] = {ly << lb0, ((ly + 1) & e1) << lb0},
              oz[2] = {lz << (lb0 + lb1), ((lz + 1) & e2) << (lb0 + lb1)};
    for (int n = 0; n < 8; ++n) {
      const int dx = n & 1, dy = (n >> 1) & 1, dz = n >> 2;
      const float* b = nbr[(dx & cx) | ((dy & cy) << 1) | ((dz & cz) << 2)];
      if (!b) return false;
      c[n] = b[oz[dz] | oy[dy] | ox[dx]];
    }
    return true;
  }
};

/// Front-to-back accumulator: premultiplied colour and opacity.
template <typename R>
struct Acc {
  R c[4] = {0, 0, 0, 0};
  R alpha() const { return c[3]; }
  void add(R r, R g, R b, R a) {
    const R w = 1 - c[3];
    c[0] += w * r;
    c[1] += w * g;
    c[2] += w * b;
    c[3] += w * a;
  }
  void add(const float* e) { add(R(e[0]), R(e[1]), R(e[2]), R(e[3])); }
  void store(float out[4]) const {
    for (int ch = 0; ch < 4; ++ch) out[ch] = float(c[ch]);
  }
};

#if defined(__GNUC__)
typedef float v4f __attribute__((vector_size(16)));
/// float: the four channels in one SSE register, one multiply-add per sample.
template <>
struct Acc<float> {
  v4f c = {0, 0, 0, 0};
  float alpha() const { return c[3]; }
  void add(const float* e) {
    v4f v;
    __builtin_memcpy(&v, e, sizeof v);
    c += (1.f - c[3]) * v;
  }
  void add(float r, float g, float b, float a) {
    const v4f v = {r, g, b, a};
    c += (1.f - c[3]) * v;
  }
  void store(float out[4]) const { __builtin_memcpy(out, &c, sizeof c); }
};
#endif

/// The shaded colour of a sample (headlight, two-sided), from the trilinear interpolant's gradient.
template <typename R, typename Accumulator>
inline void shadeSample(const Frame& F, const float cc[8], R fx, R fy, R fz, const float* e, const double viewDir[3],
                        Accumulator& acc) {
  const R gx = (1 - fy) * (1 - fz) * (cc[1] - cc[0]) + fy * (1 - fz) * (cc[3] - cc[2]) +
               (1 - fy) * fz * (cc[5] - cc[4]) + fy * fz * (cc[7] - cc[6]);
  const R gy = (1 - fx) * (1 - fz) * (cc[2] - cc[0]) + fx * (1 - fz) * (cc[3] - cc[1]) +
               (1 - fx) * fz * (cc[6] - cc[4]) + fx * fz * (cc[7] - cc[5]);
  const R gz = (1 - fx) * (1 - fy) * (cc[4] - cc[0]) + fx * (1 - fy) * (cc[5] - cc[1]) +
               (1 - fx) * fy * (cc[6] - cc[2]) + fx * fy * (cc[7] - cc[3]);
  const R wx = gx / R(F.spacing[0]), wy = gy / R(F.spacing[1]), wz = gz / R(F.spacing[2]);
  const R len = std::sqrt(wx * wx + wy * wy + wz * wz);
  R r = e[0], g = e[1], b = e[2];
  const R a = e[3];
  if (len > 0) {
    const R ndl = std::fabs(wx * R(viewDir[0]) + wy * R(viewDir[1]) + wz * R(viewDir[2])) / len;
    const R s = R(F.ambient) + R(F.diffuse) * ndl;
    const R spec = R(F.specular) * std::pow(ndl, R(F.specularPower)) * a;
    r = r * s + spec;
    g = g * s + spec;
    b = b * s + spec;
  }
  acc.add(r, g, b, a);
}

inline int tableIndex(const Frame& F, float v) {
  const float x = (v - F.tlo) * F.tscale + 0.5f;
  if (!(x > 0.f)) return 0;
  const int i = static_cast<int>(x);
  return i < F.tlast ? i : F.tlast;
}

/// The t where the index-space ray (o, d) leaves the box [lo, hi] (it is inside at some t).
inline double exitT(const double o[3], const double d[3], const double lo[3], const double hi[3]) {
  double t = std::numeric_limits<double>::infinity();
  for (int a = 0; a < 3; ++a) {
    if (d[a] > 0) t = std::min(t, (hi[a] - o[a]) / d[a]);
    else if (d[a] < 0) t = std::min(t, (lo[a] - o[a]) / d[a]);
  }
  return t;
}

/// Classifies and composites one sample of cell corners `cc` at fractions (fx, fy, fz).
/// Returns true when the ray is opaque (early termination).
template <typename R, bool Shade>
inline bool composite(const Frame& F, const float cc[8], R fx, R fy, R fz, const double viewDir[3], Acc<R>& acc,
                      float offset) {
  const float v = float(trilinear<R>(cc, fx, fy, fz) + R(offset));
  const float* e = F.table + 4 * tableIndex(F, v);
  if (Shade) {
    if (!(e[3] > 0.f)) return false;
    shadeSample<R>(F, cc, fx, fy, fz, e, viewDir, acc);
  } else {
    // No branch on a transparent entry (it is 0 0 0 0: adding (1 - A) * 0 leaves the sums
    // exactly as they are), so a ray crossing the opacity threshold costs no mispredictions.
    acc.add(e);
  }
  return acc.alpha() >= R(F.threshold);
}

/// The coarsest empty ancestor of brick (bi, bj, bk) as a level (0: the brick itself), or -1 when
/// the brick may be visible. Levels are ORs of their children: climb while empty.
inline int coarsestInvisible(const BlockSparseVolume& vol, int levels, int bi, int bj, int bk) {
  if (vol.nodeVisible(0, bi, bj, bk)) return -1;
  int empty = 0;
  while (empty + 1 < levels && !vol.nodeVisible(empty + 1, bi >> (empty + 1), bj >> (empty + 1), bk >> (empty + 1)))
    ++empty;
  return empty;
}

/// Marches one ray over samples k = 0..kEnd at t_k = t0 + k dt, position o + d t_k (index
/// space, double, the arithmetic of opencl/volume.cl, so both back ends see the same samples).
/// The ray is walked brick by brick: at sample k the brick is looked up (and, skipping, its
/// coarsest empty ancestor is left at its exit); samples up to the brick's exit then read the
/// brick's storage directly, without clamping or pointer-matrix reads.
template <typename R, typename Fetch, bool Skip, bool Shade>
void march(const Frame& F, Fetch fetch, const double o[3], const double d[3], double t0, int64_t kEnd,
           const double viewDir[3], float out[4], uint64_t& samplesOut, uint64_t& skipsOut) {
  const BlockSparseVolume& vol = *F.vol;
  uint64_t samples = 0, skips = 0;
  Acc<R> acc;
  const double dt = F.dt;
  const int levels = vol.levelCount();
  int64_t k = 0;
  while (k <= kEnd) {
    const double t = t0 + double(k) * dt;
    int cell[3];
    for (int a = 0; a < 3; ++a) {
      double f;
      cell[a] = clampCell(o[a] + d[a] * t, F.n[a], f);
    }
    const int bi = cell[0] >> LOG2DIM, bj = cell[1] >> LOG2DIM, bk = cell[2] >> LOG2DIM;
    const int empty = Skip ? coarsestInvisible(vol, levels, bi, bj, bk) : -1;
    const int L = empty < 0 ? 0 : empty;
    const double edge = double(DIM << L);
    const double lo[3] = {double(bi >> L) * edge, double(bj >> L) * edge, double(bk >> L) * edge};
    const double hi[3] = {lo[0] + edge, lo[1] + edge, lo[2] + edge};
    // Last sample at or before the node's exit (floor: never jump over a sample that might lie
    // beyond it in a visible node; an extra sample in an empty node adds exactly 0).
    const double kx = std::floor((exitT(o, d, lo, hi) - t0) / dt);
    const int64_t kLast = kx >= double(kEnd) ? kEnd : std::max<int64_t>(k, static_cast<int64_t>(kx));
    if (empty >= 0) {
      ++skips;
      k = std::max(k + 1, kLast);
      continue;
    }
    if (!fetch.enter(bi, bj, bk)) {  // an absent brick (not skipping): every cell is invisible
      k = kLast + 1;
      continue;
    }
    const int ox = bi << LOG2DIM, oy = bj << LOG2DIM, oz = bk << LOG2DIM;
    const unsigned mx = unsigned(std::min(DIM - 1, F.n[0] - 2 - ox)), my = unsigned(std::min(DIM - 1, F.n[1] - 2 - oy)),
                   mz = unsigned(std::min(DIM - 1, F.n[2] - 2 - oz));
    double kd = double(k);
    for (; k <= kLast; ++k, kd += 1.0) {
      const double ts = t0 + kd * dt;
      const double x = o[0] + d[0] * ts, y = o[1] + d[1] * ts, z = o[2] + d[2] * ts;
      const int ix = static_cast<int>(x), iy = static_cast<int>(y), iz = static_cast<int>(z);
      const int lx = ix - ox, ly = iy - oy, lz = iz - oz;
      float cc[8];
      R fx, fy, fz;
      float offset = F.offset;  // the fetch reads stored values; cellCorners() adds the offset
      if (((unsigned(lx) > mx) | (unsigned(ly) > my) | (unsigned(lz) > mz)) == 0) {
        // In the brick and in [0, n-1): clampCell's cell is the truncation (x in (-1, 0)
        // truncates to 0 with fraction 0) and its fraction x - cell.
        fx = R(std::max(x - double(ix), 0.0));
        fy = R(std::max(y - double(iy), 0.0));
        fz = R(std::max(z - double(iz), 0.0));
        if (!fetch.corners(lx, ly, lz, cc)) continue;
      } else {
        // Round-off put the sample in a neighbouring brick, or it needs clamping: general path.
        double f[3];
        const int ci = clampCell(x, F.n[0], f[0]), cj = clampCell(y, F.n[1], f[1]), ck = clampCell(z, F.n[2], f[2]);
        if (!vol.cellCorners(ci, cj, ck, cc)) continue;
        fx = R(f[0]), fy = R(f[1]), fz = R(f[2]);
        offset = 0.f;
      }
      ++samples;
      if (composite<R, Shade>(F, cc, fx, fy, fz, viewDir, acc, offset)) {
        k = kEnd + 1;
        break;
      }
    }
    k = std::max(k, kLast + 1);
  }
  samplesOut += samples;
  skipsOut += skips;
  acc.store(out);
}

#if defined(__SSE2__)
/// Transmittance-form accumulator: C += T e, T *= 1 - a. The loop-carried chain is one multiply
/// (the A += (1 - A) a form is a subtract, a multiply and an add), which bounds a ray's rate.
struct AccT {
  __m128 c = _mm_setzero_ps();
  float T = 1.f;
  void add(const float* e) {
    c = _mm_add_ps(c, _mm_mul_ps(_mm_set1_ps(T), _mm_loadu_ps(e)));
    T *= 1.f - e[3];
  }
  void add(float r, float g, float b, float a) {
    c = _mm_add_ps(c, _mm_mul_ps(_mm_set1_ps(T), _mm_setr_ps(r, g, b, a)));
    T *= 1.f - a;
  }
};

/// The 8 corners of local cell `off` of an apron brick as two vectors: z = 0 (x fastest, then y)
/// and z = 1.
inline void apronCorners(const uint8_t* p, __m128& lo, __m128& hi) {
  constexpr int SY = BlockSparseVolume::APRON, SZ = SY * SY;
  uint16_t a, b, c, d;
  std::memcpy(&a, p, 2);
  std::memcpy(&b, p + SY, 2);
  std::memcpy(&c, p + SZ, 2);
  std::memcpy(&d, p + SZ + SY, 2);
  const __m128i z = _mm_setzero_si128();
  __m128i v = _mm_cvtsi32_si128(int(uint32_t(a) | (uint32_t(b) << 16)));
  v = _mm_insert_epi16(v, c, 2);
  v = _mm_insert_epi16(v, d, 3);
  const __m128i w = _mm_unpacklo_epi8(v, z);
  lo = _mm_cvtepi32_ps(_mm_unpacklo_epi16(w, z));
  hi = _mm_cvtepi32_ps(_mm_unpackhi_epi16(w, z));
}
inline void apronCorners(const Paired8* q, __m128& lo, __m128& hi) {
  const uint8_t* p = &q->v;
  uint32_t a, b;  // bytes (x, y), (x, y + 1), (x + 1, y), (x + 1, y + 1) of planes z and z + 1
  std::memcpy(&a, p, 4);
  std::memcpy(&b, p + BlockSparseVolume::PAIR_SZ, 4);
  const __m128i z = _mm_setzero_si128();
  const __m128i w = _mm_unpacklo_epi8(_mm_unpacklo_epi32(_mm_cvtsi32_si128(int(a)), _mm_cvtsi32_si128(int(b))), z);
  const __m128 l = _mm_cvtepi32_ps(_mm_unpacklo_epi16(w, z)), h = _mm_cvtepi32_ps(_mm_unpackhi_epi16(w, z));
  lo = _mm_shuffle_ps(l, l, _MM_SHUFFLE(3, 1, 2, 0));  // (x, y), (x + 1, y), (x, y + 1), (x + 1, y + 1)
  hi = _mm_shuffle_ps(h, h, _MM_SHUFFLE(3, 1, 2, 0));
}
inline void apronCorners(const uint16_t* p, __m128& lo, __m128& hi) {
  constexpr int SY = BlockSparseVolume::APRON, SZ = SY * SY;
  uint32_t a, b, c, d;
  std::memcpy(&a, p, 4);
  std::memcpy(&b, p + SY, 4);
  std::memcpy(&c, p + SZ, 4);
  std::memcpy(&d, p + SZ + SY, 4);
  const __m128i z = _mm_setzero_si128();
  const __m128i v0 = _mm_unpacklo_epi32(_mm_cvtsi32_si128(int(a)), _mm_cvtsi32_si128(int(b)));
  const __m128i v1 = _mm_unpacklo_epi32(_mm_cvtsi32_si128(int(c)), _mm_cvtsi32_si128(int(d)));
  lo = _mm_cvtepi32_ps(_mm_unpacklo_epi16(v0, z));
  hi = _mm_cvtepi32_ps(_mm_unpacklo_epi16(v1, z));
}

/// x * s per 32-bit lane for s in {-1, 1} (SSE2 has no pmulld): x, or -x where s is -1.
inline __m128i _mm_mullo_epi32_sse2(__m128i x, __m128i s) {
  const __m128i neg = _mm_srai_epi32(s, 31);
  return _mm_sub_epi32(_mm_xor_si128(x, neg), neg);
}

/// Per-ray constants of the UInt8/UInt16 float marchers: sample k sits at P0 + k S, each axis in
/// float (a multiply, then an add: never fused, so every marcher and the OpenCL kernel agree).
struct ApronRay {
  float P0s[3], Ss[3];
  __m128 P0, S;
  __m128 nf;     // points per axis (float; 1 in lane 3)
  __m128i nm2;   // the last cell per axis, n - 2 (0 in lane 3)
  __m128i sign;  // per axis -1 where the ray runs towards lower indices, else 1 (1 in lane 3)
  int octant;    // bit a set: negative along axis a (BlockSparseVolume::brickDistances)
  ApronRay() = default;
  ApronRay(const Frame& F, const double o[3], const double d[3], double t0) { set(F, o, d, t0); }
  void set(const Frame& F, const double o[3], const double d[3], double t0) {
    for (int a = 0; a < 3; ++a) {
      P0s[a] = float(o[a] + d[a] * t0);
      Ss[a] = float(d[a] * F.dt);
    }
    P0 = _mm_setr_ps(P0s[0], P0s[1], P0s[2], 0.f);
    S = _mm_setr_ps(Ss[0], Ss[1], Ss[2], 0.f);
    nf = _mm_setr_ps(float(F.n[0]), float(F.n[1]), float(F.n[2]), 1.f);
    nm2 = _mm_setr_epi32(F.n[0] - 2, F.n[1] - 2, F.n[2] - 2, 0);
    octant = (Ss[0] < 0 ? 1 : 0) | (Ss[1] < 0 ? 2 : 0) | (Ss[2] < 0 ? 4 : 0);
    sign = _mm_setr_epi32(Ss[0] < 0 ? -1 : 1, Ss[1] < 0 ? -1 : 1, Ss[2] < 0 ? -1 : 1, 1);
  }
  __m128 at(float kf) const { return _mm_add_ps(P0, _mm_mul_ps(_mm_set1_ps(kf), S)); }
  /// clampCell's cells of a position's three coordinates at once, in float (exact: the input is a
  /// float, the points per axis < 2^24): clamped into [-1, n], floor, clamped into [0, n - 2];
  /// NaN gives cell 0 as there.
  __m128i cells(__m128 p) const {
    const __m128 pc = _mm_min_ps(_mm_max_ps(p, _mm_set1_ps(-1.f)), nf);  // maxps(NaN, -1) = -1
    __m128i c = _mm_cvttps_epi32(pc);
    c = _mm_add_epi32(c, _mm_castps_si128(_mm_cmplt_ps(pc, _mm_cvtepi32_ps(c))));  // truncation -> floor
    c = _mm_and_si128(c, _mm_cmpgt_epi32(c, _mm_set1_epi32(-1)));                   // max(c, 0)
    const __m128i over = _mm_cmpgt_epi32(c, nm2);
    return _mm_or_si128(_mm_and_si128(over, nm2), _mm_andnot_si128(over, c));      // min(c, n - 2)
  }
};

/// One step of the apron walk at sample k: looks up the brick holding it (clamped into the grid).
/// True when that brick is stored and visible (`fetch` has entered it; its first cell is returned
/// in o). Otherwise the ray is in an empty node (with skipping: the brick's coarsest empty
/// ancestor; without: the absent brick) and k moves to the last sample at or before the node's
/// exit (floor, as march(); at least k + 1).
template <typename T, bool Skip>
inline bool apronEnter(const Frame& F, const ApronRay& ray, int64_t kEnd, ApronFetch<T>& fetch,
                       int64_t& k, uint64_t& skips, int o[3]) {
  const __m128i brick = _mm_srai_epi32(ray.cells(ray.at(float(k))), LOG2DIM);
  const int bi = _mm_cvtsi128_si32(brick), bj = _mm_cvtsi128_si32(_mm_shuffle_epi32(brick, 0x55)),
            bk = _mm_cvtsi128_si32(_mm_shuffle_epi32(brick, 0xAA));
  int r = Skip ? F.dist[((size_t(bk) * F.nb[1] + bj) * F.nb[0] + bi) * 8 + ray.octant] : 0;
  if (r == 0 && !fetch.enter(bi, bj, bk)) r = 1;  // visible, but no brick stored
  if (r == 0) {
    o[0] = bi << LOG2DIM;
    o[1] = bj << LOG2DIM;
    o[2] = bk << LOG2DIM;
    return true;
  }
  // The cube of r^3 invisible bricks from b towards the ray's octant: its far faces.
  const int node[3] = {bi, bj, bk};
  double kx = std::numeric_limits<double>::infinity();
  for (int a = 0; a < 3; ++a) {
    const double s = double(ray.Ss[a]);
    if (s > 0) kx = std::min(kx, (double((node[a] + r) * DIM) - double(ray.P0s[a])) / s);
    else if (s < 0) kx = std::min(kx, (double((node[a] - r + 1) * DIM) - double(ray.P0s[a])) / s);
  }
  const double kf = std::floor(kx);
  const int64_t kLast = kf >= double(kEnd) ? kEnd : std::max<int64_t>(k, static_cast<int64_t>(kf));
  if (Skip) ++skips;
  if (kLast > k) {
    // The exit is rounded down, so sample kLast is usually still in the cube (its brick at most
    // r - 1 ahead on every axis): then it is skipped too, counted as one more skip.
    const __m128i ahead = _mm_mullo_epi32_sse2(_mm_sub_epi32(_mm_srai_epi32(ray.cells(ray.at(float(kLast))), LOG2DIM), brick), ray.sign);
    if ((_mm_movemask_epi8(_mm_cmpgt_epi32(ahead, _mm_set1_epi32(r - 1))) & 0xFFF) == 0) {
      if (Skip) ++skips;
      k = kLast + 1;
      return false;
    }
  }
  k = std::max(k + 1, kLast);
  return false;
}

/// Sample k where it needs clamping (the grid's far face, or outside it by round-off): the
/// general path (clampCell, cellCorners, x-first interpolation). True when the ray is opaque.
template <bool Shade>
inline bool apronClampedSample(const Frame& F, const ApronRay& ray, int64_t k, const double viewDir[3], AccT& acc,
                               uint64_t& samples) {
  alignas(16) float p[4];
  _mm_store_ps(p, ray.at(float(k)));
  double f[3];
  int c[3];
  for (int a = 0; a < 3; ++a) c[a] = clampCell(double(p[a]), F.n[a], f[a]);
  float cc[8];
  if (!F.vol->cellCorners(c[0], c[1], c[2], cc)) return false;
  ++samples;
  const float v = trilinear<float>(cc, float(f[0]), float(f[1]), float(f[2]));  // offset is in cc
  const float* e = F.table + 4 * std::min(std::max(static_cast<int>((v - F.tlo) * F.tscale + 0.5f), 0), F.tlast);
  if (Shade) {
    if (e[3] > 0.f) shadeSample<float>(F, cc, float(f[0]), float(f[1]), float(f[2]), e, viewDir, acc);
  } else {
    acc.add(e);
  }
  return acc.T <= 1.f - F.threshold;
}

/// The UInt8/UInt16 marcher (float accumulation): positions P0 + k S in float, 4-wide (x, y, z in
/// one register: one multiply-add, one conversion, one bounds test per sample), corners fetched
/// and interpolated as vectors, branch-free classification. Same walk as march(): brick lookup
/// and coarsest-empty-ancestor skipping at sample k, samples inside a stored brick read it
/// directly, a sample needing clamping takes the general path.
template <typename T, bool Skip, bool Shade>
void marchApron(const Frame& F, ApronFetch<T> fetch, const double o[3], const double d[3], double t0, int64_t kEnd,
                const double viewDir[3], float out[4], uint64_t& samplesOut, uint64_t& skipsOut) {
  uint64_t samples = 0, skips = 0;
  AccT acc;
  const float Tmin = 1.f - F.threshold;  // stop when the transmittance falls to this
  const ApronRay ray(F, o, d, t0);
  const __m128 zero = _mm_setzero_ps();
  const __m128 tlo = _mm_set_ss(F.tlo), tscale = _mm_set_ss(F.tscale), half = _mm_set_ss(0.5f);
  const int tlast = F.tlast;
  const float* const table = F.table;
  const float offset = F.offset;
  int64_t k = 0;
  while (k <= kEnd) {
    int bo[3];
    if (!apronEnter<T, Skip>(F, ray, kEnd, fetch, k, skips, bo)) continue;
    const __m128i org = _mm_setr_epi32(bo[0], bo[1], bo[2], 0);
    const __m128i lim = _mm_setr_epi32(std::min(DIM - 1, F.n[0] - 2 - bo[0]), std::min(DIM - 1, F.n[1] - 2 - bo[1]),
                                       std::min(DIM - 1, F.n[2] - 2 - bo[2]), 0);
    const __m128i zeroi = _mm_setzero_si128();
    const int64_t kStart = k;
    bool done = false;
    float kf = float(k);
    for (; k <= kEnd; ++k, kf += 1.f) {
      const __m128 pos = ray.at(kf);
      const __m128i ip = _mm_cvttps_epi32(pos);
      const __m128i l = _mm_sub_epi32(ip, org);
      const __m128i out4 = _mm_or_si128(_mm_cmpgt_epi32(l, lim), _mm_cmpgt_epi32(zeroi, l));
      if (_mm_movemask_epi8(out4)) break;  // left the brick (or needs clamping)
      // x in (-1, 0) truncates to cell 0: the clamped fraction is 0, as clampCell gives.
      const __m128 f = _mm_max_ps(_mm_sub_ps(pos, _mm_cvtepi32_ps(ip)), zero);
      const int lx = _mm_cvtsi128_si32(l), ly = _mm_cvtsi128_si32(_mm_shuffle_epi32(l, 0x55)),
                lz = _mm_cvtsi128_si32(_mm_shuffle_epi32(l, 0xAA));
      // An invisible cell (opacity 0 on its whole value range, see the header) adds exactly 0.
      if (!((fetch.mask[lz] >> (lx + DIM * ly)) & 1)) continue;
      __m128 c0, c1;
      apronCorners(fetch.base + ApronFetch<T>::Layout::cell(lx, ly, lz), c0, c1);
      const __m128 fz = _mm_shuffle_ps(f, f, 0xAA), fy = _mm_shuffle_ps(f, f, 0x55);
      const __m128 zl = _mm_add_ps(c0, _mm_mul_ps(fz, _mm_sub_ps(c1, c0)));  // (x0y0, x1y0, x0y1, x1y1)
      const __m128 yl = _mm_add_ps(zl, _mm_mul_ps(fy, _mm_sub_ps(_mm_movehl_ps(zl, zl), zl)));  // (x0, x1)
      const __m128 x1 = _mm_shuffle_ps(yl, yl, 0x55);
      const __m128 v = _mm_add_ss(_mm_add_ss(yl, _mm_mul_ss(f, _mm_sub_ss(x1, yl))), _mm_set_ss(offset));
      ++samples;
      // TransferTable::index, branch-free: truncation, then clamped into [0, last].
      const int raw = _mm_cvttss_si32(_mm_add_ss(_mm_mul_ss(_mm_sub_ss(v, tlo), tscale), half));
      const int idx = std::min(std::max(raw, 0), tlast);
      const float* e = table + 4 * idx;
      if (Shade) {
        if (!(e[3] > 0.f)) continue;
        alignas(16) float cc[8], fs[4];
        _mm_store_ps(cc, c0);
        _mm_store_ps(cc + 4, c1);
        _mm_store_ps(fs, f);
        shadeSample<float>(F, cc, fs[0], fs[1], fs[2], e, viewDir, acc);
      } else {
        acc.add(e);  // a transparent entry is 0 0 0 0: no change
      }
      if (acc.T <= Tmin) {
        done = true;
        break;
      }
    }
    if (done) break;
    if (k == kStart) {
      if (apronClampedSample<Shade>(F, ray, k, viewDir, acc, samples)) break;
      ++k;
    }
  }
  samplesOut += samples;
  skipsOut += skips;
  _mm_storeu_ps(out, acc.c);
}

#if MT_VOLUME_AVX2
// The AVX2 marcher: compiled for AVX2 with a function attribute (the build sets no -march) and
// chosen at run time (renderVolume: cpuHasAvx2). "avx2" only, never "fma" or "avx512f" (which
// implies it): GCC would fuse the multiply-adds and the image would differ from the SSE2 one.
#define MT_AVX2 __attribute__((target("avx2")))

/// The 8 corners (x fastest, then y, then z) of 8 cells of apron bricks, corner 0 of lane j at
/// entry off[j] of `base` (ApronLayout), as floats. uint8_t/uint16_t: one 32-bit gather per
/// corner pair (x, x + 1) (8-bit: it reads 2 bytes past the pair; the brick array is padded for
/// it, see BlockSparseVolume::BRICK_PAD); Paired8: one per z plane (its 4 corners are
/// consecutive bytes).
MT_AVX2 __attribute__((always_inline)) inline void gatherCorners(const uint8_t* base, __m256i off, __m256 c[8]) {
  constexpr int SY = BlockSparseVolume::APRON, SZ = SY * SY;
  const int rows[4] = {0, SY, SZ, SZ + SY};
  const __m256i m = _mm256_set1_epi32(0xFF);
  // Byte 1 of each 32-bit lane into byte 0, zeros above (one shuffle for a shift and a mask).
  const __m256i byte1 = _mm256_setr_epi8(1, -1, -1, -1, 5, -1, -1, -1, 9, -1, -1, -1, 13, -1, -1, -1,
                                         1, -1, -1, -1, 5, -1, -1, -1, 9, -1, -1, -1, 13, -1, -1, -1);
  for (int r = 0; r < 4; ++r) {
    const __m256i w = _mm256_i32gather_epi32(reinterpret_cast<const int*>(base),
                                             r ? _mm256_add_epi32(off, _mm256_set1_epi32(rows[r])) : off, 1);
    c[2 * r] = _mm256_cvtepi32_ps(_mm256_and_si256(w, m));
    c[2 * r + 1] = _mm256_cvtepi32_ps(_mm256_shuffle_epi8(w, byte1));
  }
}
MT_AVX2 __attribute__((always_inline)) inline void gatherCorners(const uint16_t* base, __m256i off, __m256 c[8]) {
  constexpr int SY = BlockSparseVolume::APRON, SZ = SY * SY;
  const int rows[4] = {0, SY, SZ, SZ + SY};
  for (int r = 0; r < 4; ++r) {
    const __m256i w = _mm256_i32gather_epi32(reinterpret_cast<const int*>(base),
                                             r ? _mm256_add_epi32(off, _mm256_set1_epi32(rows[r])) : off, 2);
    c[2 * r] = _mm256_cvtepi32_ps(_mm256_and_si256(w, _mm256_set1_epi32(0xFFFF)));
    c[2 * r + 1] = _mm256_cvtepi32_ps(_mm256_srli_epi32(w, 16));
  }
}
MT_AVX2 __attribute__((always_inline)) inline void gatherCorners(const Paired8* base, __m256i off, __m256 c[8]) {
  const __m256i m = _mm256_set1_epi32(0xFF);
  const __m256i byte1 = _mm256_setr_epi8(1, -1, -1, -1, 5, -1, -1, -1, 9, -1, -1, -1, 13, -1, -1, -1,
                                         1, -1, -1, -1, 5, -1, -1, -1, 9, -1, -1, -1, 13, -1, -1, -1);
  const __m256i byte2 = _mm256_setr_epi8(2, -1, -1, -1, 6, -1, -1, -1, 10, -1, -1, -1, 14, -1, -1, -1,
                                         2, -1, -1, -1, 6, -1, -1, -1, 10, -1, -1, -1, 14, -1, -1, -1);
  for (int z = 0; z < 2; ++z) {
    const __m256i w = _mm256_i32gather_epi32(
        reinterpret_cast<const int*>(base), z ? _mm256_add_epi32(off, _mm256_set1_epi32(BlockSparseVolume::PAIR_SZ)) : off, 1);
    c[4 * z + 0] = _mm256_cvtepi32_ps(_mm256_and_si256(w, m));         // (x, y)
    c[4 * z + 2] = _mm256_cvtepi32_ps(_mm256_shuffle_epi8(w, byte1));  // (x, y + 1)
    c[4 * z + 1] = _mm256_cvtepi32_ps(_mm256_shuffle_epi8(w, byte2));  // (x + 1, y)
    c[4 * z + 3] = _mm256_cvtepi32_ps(_mm256_srli_epi32(w, 24));       // (x + 1, y + 1)
  }
}

/// Entry of corner 0 of local cell (lx, ly, lz) of the stored brick whose first entry is `first`
/// (Frame::runBricks), bit = lx + 8 ly + 64 lz (ApronLayout, 8 lanes). 9^3 entries: first + lx +
/// 9 ly + 81 lz = first + bit + ly + 17 lz; Paired8: first + 2 lx + 18 ly + 144 lz = first + 2 (bit +
/// ly + 8 lz).
template <typename T>
MT_AVX2 __attribute__((always_inline)) inline __m256i cornerEntry(const T*, __m256i first, __m256i bit, __m256i ly,
                                                                 __m256i lz) {
  return _mm256_add_epi32(first, _mm256_add_epi32(bit, _mm256_add_epi32(ly, _mm256_add_epi32(_mm256_slli_epi32(lz, 4), lz))));
}
MT_AVX2 __attribute__((always_inline)) inline __m256i cornerEntry(const Paired8*, __m256i first, __m256i bit, __m256i ly,
                                                                 __m256i lz) {
  return _mm256_add_epi32(first, _mm256_slli_epi32(_mm256_add_epi32(bit, _mm256_add_epi32(ly, _mm256_slli_epi32(lz, 3))), 1));
}

/// The per-ray constants of marchApronAvx2's chunks (broadcast once per ray).
template <typename T>
struct Avx2Ray {  // scalars, broadcast where used (a load each, like a vector constant's)
  float P0x, P0y, P0z, Sx, Sy, Sz;
  int mx, my, mz;  // n - 2 per axis: cells that need no clamping are 0..n-2
  int nb0, nb01;   // level-0 bricks along x, in an xy layer
  float tlo, tscale, offset;
  int tlast, zeroEntry;
  const int* bricks;  // F.runBricks: MT_NULL (-1) where the walk takes over
  const int* words;   // per level-0 brick 16 mask words: bit x + 8 y + 64 z
  const T* data;
};

/// One chunk of 8 consecutive samples k..k+7 (kf = k as a float): how many leading lanes are
/// taken (n: the cell needs no clamping, its brick is stored and visible, and the sample is one of
/// the ray's, i.e. lane <= left = kEnd - k), which of those lanes' cells are visible (vis), and
/// each lane's offset into Frame::table8 (idx; the all-zero entry for an invisible cell). Only computed
/// when vis != 0.
struct Avx2Chunk {
  int n;
  unsigned vis;
  __m256i idx;
};

template <typename T>
MT_AVX2 __attribute__((always_inline)) inline void avx2Chunk(const Avx2Ray<T>& R, float kf, int64_t left,
                                                              Avx2Chunk& out) {
  static_assert(BlockSparseVolume::APRON == 9 && DIM == 8, "the offsets below assume 9^3-voxel bricks of 8^3 cells");
  const __m256i zeroi = _mm256_setzero_si256(), seven = _mm256_set1_epi32(DIM - 1);
  const __m256 P0x = _mm256_set1_ps(R.P0x), P0y = _mm256_set1_ps(R.P0y), P0z = _mm256_set1_ps(R.P0z);
  const __m256 Sx = _mm256_set1_ps(R.Sx), Sy = _mm256_set1_ps(R.Sy), Sz = _mm256_set1_ps(R.Sz);
  const __m256i mx = _mm256_set1_epi32(R.mx), my = _mm256_set1_epi32(R.my), mz = _mm256_set1_epi32(R.mz);
  const __m256 kv = _mm256_add_ps(_mm256_set1_ps(kf), _mm256_setr_ps(0.f, 1.f, 2.f, 3.f, 4.f, 5.f, 6.f, 7.f));
  const __m256 px = _mm256_add_ps(P0x, _mm256_mul_ps(kv, Sx));
  const __m256 py = _mm256_add_ps(P0y, _mm256_mul_ps(kv, Sy));
  const __m256 pz = _mm256_add_ps(P0z, _mm256_mul_ps(kv, Sz));
  const __m256i ix = _mm256_cvttps_epi32(px), iy = _mm256_cvttps_epi32(py), iz = _mm256_cvttps_epi32(pz);
  // Cells that need no clamping: 0 <= i <= n - 2 per axis, i.e. i <= n - 2 as unsigned.
  const __m256i inside = _mm256_and_si256(
      _mm256_and_si256(_mm256_cmpeq_epi32(_mm256_min_epu32(ix, mx), ix), _mm256_cmpeq_epi32(_mm256_min_epu32(iy, my), iy)),
      _mm256_cmpeq_epi32(_mm256_min_epu32(iz, mz), iz));
  // Level-0 brick of each cell (brick 0 where the cell needs clamping: read, then ignored).
  const __m256i bz = _mm256_srli_epi32(iz, LOG2DIM), by = _mm256_srli_epi32(iy, LOG2DIM), bx = _mm256_srli_epi32(ix, LOG2DIM);
  // bx + nb0 by + nb0 nb1 bz: the two products side by side, not nested (the index is on the
  // path to every gather).
  const __m256i b = _mm256_and_si256(
      inside, _mm256_add_epi32(_mm256_add_epi32(_mm256_mullo_epi32(bz, _mm256_set1_epi32(R.nb01)), bx),
                               _mm256_mullo_epi32(by, _mm256_set1_epi32(R.nb0))));
  const __m256i ptr = _mm256_i32gather_epi32(R.bricks, b, 4);
  // Visible-cell bit of each cell (clamped lanes read brick 0's, ignored): word 16 b + bit / 32
  // of the masks, issued without waiting for the brick pointers; shifted into the sign bit.
  const __m256i lx = _mm256_and_si256(ix, seven), ly = _mm256_and_si256(iy, seven), lz = _mm256_and_si256(iz, seven);
  const __m256i bit = _mm256_add_epi32(lx, _mm256_add_epi32(_mm256_slli_epi32(ly, 3), _mm256_slli_epi32(lz, 6)));
  const __m256i word = _mm256_i32gather_epi32(R.words, _mm256_add_epi32(_mm256_slli_epi32(b, 4), _mm256_srli_epi32(bit, 5)), 4);
  const __m256 vbit = _mm256_castsi256_ps(_mm256_sllv_epi32(word, _mm256_andnot_si256(bit, _mm256_set1_epi32(31))));
  // Lanes taken: no clamping, and a brick marched through.
  const __m256i take = _mm256_andnot_si256(_mm256_cmpeq_epi32(ptr, _mm256_set1_epi32(-1)), inside);
  unsigned go = unsigned(_mm256_movemask_ps(_mm256_castsi256_ps(take)));
  if (left < 7) go &= (2u << left) - 1u;  // lanes 0..left are samples of the ray
  const int n = __builtin_ctz(~go);       // leading lanes taken (go < 256: at most 8)
  out.n = n;
  out.vis = n == 0 ? 0u : unsigned(_mm256_movemask_ps(vbit)) & ((2u << (n - 1)) - 1u);
  if (!out.vis) return;
  const __m256 zero = _mm256_setzero_ps();
  const __m256 fx = _mm256_max_ps(_mm256_sub_ps(px, _mm256_cvtepi32_ps(ix)), zero);
  const __m256 fy = _mm256_max_ps(_mm256_sub_ps(py, _mm256_cvtepi32_ps(iy)), zero);
  const __m256 fz = _mm256_max_ps(_mm256_sub_ps(pz, _mm256_cvtepi32_ps(iz)), zero);
  // Entry of corner 0 (0 in the lanes without a brick), then the 8 corners.
  const __m256i off = _mm256_and_si256(take, cornerEntry(R.data, ptr, bit, ly, lz));
  __m256 c[8];  // corner dx + 2 dy + 4 dz
  gatherCorners(R.data, off, c);
  const __m256 c0 = c[0], c1 = c[1], c2 = c[2], c3 = c[3], c4 = c[4], c5 = c[5], c6 = c[6], c7 = c[7];
  const __m256 z0 = _mm256_add_ps(c0, _mm256_mul_ps(fz, _mm256_sub_ps(c4, c0)));
  const __m256 z1 = _mm256_add_ps(c1, _mm256_mul_ps(fz, _mm256_sub_ps(c5, c1)));
  const __m256 z2 = _mm256_add_ps(c2, _mm256_mul_ps(fz, _mm256_sub_ps(c6, c2)));
  const __m256 z3 = _mm256_add_ps(c3, _mm256_mul_ps(fz, _mm256_sub_ps(c7, c3)));
  const __m256 y0 = _mm256_add_ps(z0, _mm256_mul_ps(fy, _mm256_sub_ps(z2, z0)));
  const __m256 y1 = _mm256_add_ps(z1, _mm256_mul_ps(fy, _mm256_sub_ps(z3, z1)));
  const __m256 v = _mm256_add_ps(_mm256_add_ps(y0, _mm256_mul_ps(fx, _mm256_sub_ps(y1, y0))), _mm256_set1_ps(R.offset));
  const __m256i raw = _mm256_cvttps_epi32(
      _mm256_add_ps(_mm256_mul_ps(_mm256_sub_ps(v, _mm256_set1_ps(R.tlo)), _mm256_set1_ps(R.tscale)), _mm256_set1_ps(0.5f)));
  // Entry offsets into Frame::table8 (8 floats an entry); an invisible cell reads the all-zero
  // entry renderVolume appends to the table (1 - 0 = 1 in its second half): C + T * 0 = C and
  // T * 1 = T exactly, as when marchApron skips the cell.
  const __m256i e4 = _mm256_slli_epi32(_mm256_min_epi32(_mm256_max_epi32(raw, zeroi), _mm256_set1_epi32(R.tlast)), 3);
  const __m256 zeroEntry = _mm256_castsi256_ps(_mm256_set1_epi32(R.zeroEntry));
  out.idx = _mm256_castps_si256(_mm256_blendv_ps(zeroEntry, _mm256_castsi256_ps(e4), vbit));
}

/// One ray of marchApronAvx2 as a resumable state: start() sets it up, each step() does one
/// step of the walk or one chunk and returns false once the ray is done (its pixel written), so
/// that two rays can be marched in turns (marchApronAvx2Pair): the serial latency of one ray's
/// walk and compositing then overlaps the other ray's work.
template <typename T, bool Skip>
struct Avx2RayMarch {
  Avx2Ray<T> R;
  ApronRay ray;
  ApronFetch<T> fetch;
  __m128 C, T4;  // AccT's sums with the transmittance broadcast (the same float operations lane by lane)
  Avx2Chunk cur;
  const Frame* F;
  float* out;
  int64_t k, kEnd;
  uint64_t samples, skips;
  float kf, Tmin;
  bool chunk;  // in a run of chunks (cur is the next one to composite); else the walk is next

  explicit Avx2RayMarch(const ApronFetch<T>& f) : fetch(f) {}

  MT_AVX2 __attribute__((always_inline)) inline void start(const Frame& Fr, const double o[3], const double d[3],
                                                           double t0, int64_t kEnd_, float* out_) {
    F = &Fr;
    out = out_;
    kEnd = kEnd_;
    k = 0;
    samples = skips = 0;
    chunk = false;
    Tmin = 1.f - Fr.threshold;
    ray.set(Fr, o, d, t0);
    R.P0x = ray.P0s[0], R.P0y = ray.P0s[1], R.P0z = ray.P0s[2];
    R.Sx = ray.Ss[0], R.Sy = ray.Ss[1], R.Sz = ray.Ss[2];
    R.mx = Fr.n[0] - 2, R.my = Fr.n[1] - 2, R.mz = Fr.n[2] - 2;
    R.nb0 = Fr.nb[0], R.nb01 = Fr.nb[0] * Fr.nb[1];
    R.tlo = Fr.tlo, R.tscale = Fr.tscale, R.offset = Fr.offset;
    R.tlast = Fr.tlast;
    R.zeroEntry = 8 * (Fr.tlast + 1);
    R.bricks = reinterpret_cast<const int*>(Fr.runBricks);
    R.words = reinterpret_cast<const int*>(fetch.masks);
    R.data = fetch.data;
    C = _mm_setzero_ps();
    T4 = _mm_set1_ps(1.f);
  }

  /// The ray is done: its pixel and counts.
  MT_AVX2 __attribute__((always_inline)) inline bool finish(uint64_t& samplesOut, uint64_t& skipsOut) {
    _mm_storeu_ps(out, C);
    samplesOut += samples;
    skipsOut += skips;
    return false;
  }

  MT_AVX2 __attribute__((noinline)) bool step(uint64_t& samplesOut, uint64_t& skipsOut) {
    const Frame& Fr = *F;
    if (!chunk) {
      // The walk: to the first sample in a stored visible brick (or one that needs clamping).
      if (k > kEnd) return finish(samplesOut, skipsOut);
      int bo[3];
      if (!apronEnter<T, Skip>(Fr, ray, kEnd, fetch, k, skips, bo)) return true;
      kf = float(k);
      avx2Chunk(R, kf, kEnd - k, cur);
      if (cur.n == 0) {  // sample k needs clamping: the general path
        AccT acc;
        acc.c = C;
        acc.T = _mm_cvtss_f32(T4);
        const bool opaque = apronClampedSample<false>(Fr, ray, k, nullptr, acc, samples);
        C = acc.c;
        T4 = _mm_set1_ps(acc.T);
        if (opaque) return finish(samplesOut, skipsOut);
        ++k;
        return true;
      }
      chunk = true;
    }
    // The run of chunks (in locals: registers): each one's successor is prepared first (nothing
    // in it depends on this one's compositing), so that its gathers' latency overlaps the serial
    // compositing.
    __m128 Cr = C, Tr = T4;
    int64_t kr = k;
    float kfr = kf;
    Avx2Chunk c = cur;
    const float* const table = Fr.table8;
    const float Tm = Tmin;
    const int64_t ke = kEnd;
    alignas(32) int32_t idx[8];
    for (;;) {
      const bool more = c.n == 8 && ke - kr >= 8;
      Avx2Chunk next{};  // (idx unset when vis is 0)
      if (more) avx2Chunk(R, kfr + 8.f, ke - kr - 8, next);
      if (c.vis) {
        _mm256_store_si256(reinterpret_cast<__m256i*>(idx), c.idx);
        const int n = c.n;
        // The lanes without a termination test: T never grows (each factor 1 - a is in [0, 1] and
        // rounding is monotone), so it fell to Tmin within the chunk iff it is there at its end;
        // only then is the chunk composited again from its start, lane by lane with the test.
        const __m128 C0 = Cr, T0 = Tr;
        const auto add = [&](int j) __attribute__((always_inline)) {
          const float* e = table + idx[j];  // colour and opacity, then 1 - opacity 4 times
          Cr = _mm_add_ps(Cr, _mm_mul_ps(Tr, _mm_load_ps(e)));
          Tr = _mm_mul_ps(Tr, _mm_load_ps(e + 4));
        };
        if (n == 8) {
          for (int j = 0; j < 8; ++j) add(j);
        } else {
          for (int j = 0; j < n; ++j) add(j);
        }
        if (_mm_cvtss_f32(Tr) <= Tm) {
          Cr = C0;
          Tr = T0;
          int j = 0;
          for (; j < n - 1; ++j) {
            add(j);
            if (_mm_cvtss_f32(Tr) <= Tm) break;
          }
          if (j == n - 1) add(j);  // (the last lane: where the end test found it)
          samples += __builtin_popcount(c.vis & ((2u << j) - 1u));
          C = Cr;
          return finish(samplesOut, skipsOut);
        }
        samples += __builtin_popcount(c.vis);
      }
      if (!more) {
        kr += c.n;
        break;
      }
      kr += 8;  // not k += n: the next chunk's positions need not wait for this one's gathers
      kfr += 8.f;
      c = next;
    }
    C = Cr;
    T4 = Tr;
    k = kr;
    chunk = false;
    return true;
  }
};

/// marchApron<T, Skip, false> for 8 consecutive samples at a time. The same walk (apronEnter,
/// apronClampedSample) finds the first sample in a stored visible brick; from there samples
/// k..k+7 get their positions (lane j: P0 + (kf + j) S, the same float operations as the SSE2
/// marcher), cells, bricks (F.runBricks), and visible-cell bits at once, across brick faces. The
/// leading lanes whose cell needs no clamping and whose brick is stored and visible, up to kEnd,
/// are taken; at the first other lane the walk takes over again, as the SSE2 marcher does when it
/// leaves a brick (its next brick lookup then lands in the same place, so it skips the same
/// nodes). A chunk whose taken cells are all invisible costs no corner reads; otherwise their
/// corners are gathered and interpolated (z, then y, then x, as marchApron), the table indices
/// computed, and the taken lanes composited one after the other, in order, an invisible cell's
/// lane with an all-zero entry (which changes nothing, exactly; it is not counted as a sample):
/// the image, the early-termination point and the sample and skip counts are marchApron's
/// exactly. Rays with more than 2^24 - 8 samples are not sent here (kf + j must be exact).
template <typename T, bool Skip>
MT_AVX2 void marchApronAvx2(const Frame& F, ApronFetch<T> fetch, const double o[3], const double d[3], double t0,
                            int64_t kEnd, float out[4], uint64_t& samplesOut, uint64_t& skipsOut) {
  Avx2RayMarch<T, Skip> m(fetch);
  m.start(F, o, d, t0, kEnd, out);
  while (m.step(samplesOut, skipsOut)) {
  }
}


/// marchApronAvx2 for `count` rays, SLOTS at a time in turns (a finished ray's slot takes the
/// next one): every ray's steps are exactly those marchApronAvx2 takes, only their order across
/// rays changes, so the images and counts are the same. A step (one walk step, or one run of
/// chunks) is a call, so the rays' latency chains overlap across calls.
template <typename T, bool Skip, int SLOTS = 2>
MT_AVX2 void marchApronAvx2Pair(const Frame& F, const ApronFetch<T>& fetch, const PendingRay* rays, int count,
                                uint64_t& samplesOut, uint64_t& skipsOut) {
  Avx2RayMarch<T, Skip> m[SLOTS] = {Avx2RayMarch<T, Skip>(fetch), Avx2RayMarch<T, Skip>(fetch)};
  bool live[SLOTS];
  int next = 0, active = 0;
  for (int i = 0; i < SLOTS; ++i) {
    live[i] = next < count;
    if (live[i]) {
      m[i].start(F, rays[next].ro, rays[next].rd, rays[next].t0, rays[next].kEnd, rays[next].out);
      ++next;
      ++active;
    }
  }
  while (active) {
    for (int i = 0; i < SLOTS; ++i) {
      if (live[i] && !m[i].step(samplesOut, skipsOut)) {
        live[i] = next < count;
        if (live[i]) {
          m[i].start(F, rays[next].ro, rays[next].rd, rays[next].t0, rays[next].kEnd, rays[next].out);
          ++next;
        } else {
          --active;
        }
      }
    }
  }
}
#endif  // MT_VOLUME_AVX2
#endif


/// march() for every storage; for UInt8/UInt16 in float the SSE2 marcher, or unshaded the AVX2
/// one where renderVolume chose it (F.lanes == 8).
template <typename R, bool Skip, bool Shade, typename Fetch>
inline void marchRay(const Frame& F, const Fetch& fetch, const double o[3], const double d[3], double t0,
                     int64_t kEnd, const double viewDir[3], float out[4], uint64_t& samples, uint64_t& skips) {
  march<R, Fetch, Skip, Shade>(F, fetch, o, d, t0, kEnd, viewDir, out, samples, skips);
}
#if defined(__SSE2__)
template <typename R, bool Skip, bool Shade, typename T>
inline void marchRay(const Frame& F, const ApronFetch<T>& fetch, const double o[3], const double d[3], double t0,
                     int64_t kEnd, const double viewDir[3], float out[4], uint64_t& samples, uint64_t& skips) {
  if (!std::is_same<R, float>::value) {
    march<R, ApronFetch<T>, Skip, Shade>(F, fetch, o, d, t0, kEnd, viewDir, out, samples, skips);
    return;
  }
#if MT_VOLUME_AVX2
  if (!Shade && F.lanes == 8 && kEnd < (int64_t(1) << 24) - 8) {
    marchApronAvx2<T, Skip>(F, fetch, o, d, t0, kEnd, out, samples, skips);
    return;
  }
#endif
  marchApron<T, Skip, Shade>(F, fetch, o, d, t0, kEnd, viewDir, out, samples, skips);
}
#endif

/// Whether marchImage queues a ray for marchApronAvx2Pair (the rays marchRay sends to
/// marchApronAvx2), and the queue's consumer: nothing for other storages or settings.
template <typename R, bool Shade, typename Fetch>
inline bool pairable(const Frame&, const Fetch&, int64_t) {
  return false;
}
template <typename R, bool Skip, bool Shade, typename Fetch>
inline void marchPending(const Frame&, const Fetch&, const PendingRayList&, uint64_t&, uint64_t&) {}
#if MT_VOLUME_AVX2
template <typename R, bool Shade, typename T>
inline bool pairable(const Frame& F, const ApronFetch<T>&, int64_t kEnd) {
  return std::is_same<R, float>::value && !Shade && F.lanes == 8 && kEnd < (int64_t(1) << 24) - 8;
}
template <typename R, bool Skip, bool Shade, typename T>
inline void marchPending(const Frame& F, const ApronFetch<T>& fetch, const PendingRayList& list, uint64_t& samples,
                         uint64_t& skips) {
  marchApronAvx2Pair<T, Skip>(F, fetch, list.rays, list.count, samples, skips);
}
#endif

/// The CPU runs AVX2 (and the OS saves its registers: GCC's cpu model checks both).
bool cpuHasAvx2() {
#if MT_VOLUME_AVX2
  static const bool has = [] {
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx2") != 0;
  }();
  return has;
#else
  return false;
#endif
}

/// The pixels whose rays can meet the volume's box, conservatively: the rectangle around its 8
/// corners projected onto the image, widened by 2 pixels (round-off of the projection is far
/// below that); the whole image when a corner is not in front of a perspective eye. A pixel
/// outside it is not set up at all: its ray would miss the box anyway (the box is convex, so it
/// projects into the corners' hull), and its pixel stays 0 as a missing ray leaves it.
struct PixelRect {
  int x0, x1, y0, y1;  // inclusive
};
PixelRect hitRect(const VolumeGeometry& geo, const VolumeCamera& cam, const int n[3], int w, int h, double aspect,
                  double th, Vec3 fwd, Vec3 right, Vec3 up) {
  const PixelRect all{0, w - 1, 0, h - 1};
  double nx0 = std::numeric_limits<double>::infinity(), nx1 = -nx0, ny0 = nx0, ny1 = -nx0;
  for (int c = 0; c < 8; ++c) {
    Vec3 p;
    for (int a = 0; a < 3; ++a) p[a] = geo.origin[a] + ((c >> a) & 1 ? double(n[a] - 1) : 0.0) * geo.spacing[a];
    const Vec3 v = p - cam.position;
    double sx, sy;  // the corner's normalized image coordinates (-1..1 across the image)
    if (cam.parallel) {
      sx = dot(v, right) / (cam.parallelScale * aspect);
      sy = dot(v, up) / cam.parallelScale;
    } else {
      const double z = dot(v, fwd);
      if (!(z > 1e-6 * norm(v))) return all;  // behind or beside the eye: no bound from this view
      sx = dot(v, right) / (z * th * aspect);
      sy = dot(v, up) / (z * th);
    }
    nx0 = std::min(nx0, sx), nx1 = std::max(nx1, sx), ny0 = std::min(ny0, sy), ny1 = std::max(ny1, sy);
  }
  if (!std::isfinite(nx0 + nx1 + ny0 + ny1)) return all;
  // Pixel x has nx = 2 (x + 0.5) / w - 1, so x = (nx + 1) w / 2 - 0.5.
  const auto lo = [](double v, int size) { return int(std::max(-1.0, std::min(double(size), std::floor(v) - 2))); };
  const auto hi = [](double v, int size) { return int(std::max(-1.0, std::min(double(size), std::ceil(v) + 2))); };
  PixelRect r;
  r.x0 = std::max(0, lo((nx0 + 1) * w / 2 - 0.5, w));
  r.x1 = std::min(w - 1, hi((nx1 + 1) * w / 2 - 0.5, w));
  r.y0 = std::max(0, lo((ny0 + 1) * h / 2 - 0.5, h));
  r.y1 = std::min(h - 1, hi((ny1 + 1) * h / 2 - 0.5, h));
  return r;
}

/// A perspective ray in index space as marchImage sets it up: origin (the eye, the same for all),
/// direction rd, entry t0 and last sample kEnd; d the unit world direction (the headlight).
struct PixelRay {
  double rd[3], t0, d[3];
  int64_t kEnd;
  bool hit;  // false: the ray misses the box (its pixel stays 0)
};

/// The last part of every camera's ray set-up: the interval of the ray ro + t r.rd (index space)
/// inside the volume's box [0, hiIdx] (an axis the ray is parallel to sets no bound, and misses
/// when ro lies outside it), then r.t0, r.hit and r.kEnd, the number of steps dt that fit.
inline void clipPixelRay(const double ro[3], const double hiIdx[3], double dt, PixelRay& r) {
  double t0 = 0, t1 = std::numeric_limits<double>::infinity();
  bool miss = false;
  for (int a = 0; a < 3; ++a) {
    if (r.rd[a] == 0) {
      if (ro[a] < 0 || ro[a] > hiIdx[a]) miss = true;
      continue;
    }
    double ta = (0 - ro[a]) / r.rd[a], tb = (hiIdx[a] - ro[a]) / r.rd[a];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
  }
  r.t0 = t0;
  r.hit = !miss && t0 <= t1;
  r.kEnd = 0;
  if (r.hit) {
    const double kx = std::floor((t1 - t0) / dt);
    r.kEnd = kx > 4e15 ? int64_t(4e15) : static_cast<int64_t>(kx);
  }
}

/// The per-frame numbers of a perspective ray's set-up (marchImage's expressions).
struct RaySetupFrame {
  double fwd[3], spacing[3], roEye[3], hiIdx[3], dt;
  const double* rightX[3];  // per column: right * (nx th aspect), one array per axis (padded by 3)
  double upY[3];            // the row's up * (ny th)
};

/// The scalar set-up of pixel column x of the row in S: marchImage's per-pixel arithmetic.
inline PixelRay setupRay(const RaySetupFrame& S, int x) {
  PixelRay r;
  const Vec3 d = normalized(Vec3(S.fwd[0], S.fwd[1], S.fwd[2]) + Vec3(S.rightX[0][x], S.rightX[1][x], S.rightX[2][x]) +
                            Vec3(S.upY[0], S.upY[1], S.upY[2]));
  for (int a = 0; a < 3; ++a) {
    r.d[a] = d[a];
    r.rd[a] = d[a] / S.spacing[a];
  }
  clipPixelRay(S.roEye, S.hiIdx, S.dt, r);
  return r;
}

#if MT_VOLUME_AVX2
/// setupRay for columns x..x+3 at once, in AVX2 doubles: the same operations in the same order
/// (additions, products, the square root and the divisions are correctly rounded in every lane;
/// nothing is fused), so every lane is setupRay's ray bit for bit. max/min keep std::max/min's
/// operand choice on ties (vmaxpd/vminpd return the second operand then), and an axis the ray
/// is parallel to sets no bound, as there.
MT_AVX2 void setupRays4(const RaySetupFrame& S, int x, PixelRay r[4]) {
  __m256d d[3];
  for (int a = 0; a < 3; ++a)
    d[a] = _mm256_add_pd(_mm256_add_pd(_mm256_set1_pd(S.fwd[a]), _mm256_loadu_pd(S.rightX[a] + x)),
                         _mm256_set1_pd(S.upY[a]));
  const __m256d n = _mm256_sqrt_pd(_mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(d[0], d[0]), _mm256_mul_pd(d[1], d[1])),
                                                 _mm256_mul_pd(d[2], d[2])));
  const __m256d inv = _mm256_div_pd(_mm256_set1_pd(1.0), n);
  const __m256d pos = _mm256_cmp_pd(n, _mm256_setzero_pd(), _CMP_GT_OQ);
  __m256d t0 = _mm256_setzero_pd(), t1 = _mm256_set1_pd(std::numeric_limits<double>::infinity());
  __m256d miss = _mm256_setzero_pd();
  const __m256d inf = _mm256_set1_pd(std::numeric_limits<double>::infinity());
  const __m256d ninf = _mm256_set1_pd(-std::numeric_limits<double>::infinity());
  alignas(32) double dd[3][4], rdd[3][4];
  for (int a = 0; a < 3; ++a) {
    d[a] = _mm256_blendv_pd(d[a], _mm256_mul_pd(d[a], inv), pos);
    const __m256d rd = _mm256_div_pd(d[a], _mm256_set1_pd(S.spacing[a]));
    _mm256_store_pd(dd[a], d[a]);
    _mm256_store_pd(rdd[a], rd);
    const __m256d zero = _mm256_cmp_pd(rd, _mm256_setzero_pd(), _CMP_EQ_OQ);
    if (S.roEye[a] < 0 || S.roEye[a] > S.hiIdx[a]) miss = _mm256_or_pd(miss, zero);
    const __m256d ta = _mm256_div_pd(_mm256_set1_pd(0 - S.roEye[a]), rd);
    const __m256d tb = _mm256_div_pd(_mm256_set1_pd(S.hiIdx[a] - S.roEye[a]), rd);
    const __m256d swap = _mm256_cmp_pd(ta, tb, _CMP_GT_OQ);
    const __m256d lo = _mm256_blendv_pd(_mm256_blendv_pd(ta, tb, swap), ninf, zero);
    const __m256d hi = _mm256_blendv_pd(_mm256_blendv_pd(tb, ta, swap), inf, zero);
    t0 = _mm256_max_pd(lo, t0);  // std::max(t0, lo): lo only when t0 < lo
    t1 = _mm256_min_pd(hi, t1);  // std::min(t1, hi): hi only when hi < t1
  }
  const int hit = _mm256_movemask_pd(_mm256_andnot_pd(miss, _mm256_cmp_pd(t0, t1, _CMP_LE_OQ)));
  alignas(32) double t0s[4], kx[4];
  _mm256_store_pd(t0s, t0);
  _mm256_store_pd(kx, _mm256_floor_pd(_mm256_div_pd(_mm256_sub_pd(t1, t0), _mm256_set1_pd(S.dt))));
  for (int l = 0; l < 4; ++l) {
    for (int a = 0; a < 3; ++a) {
      r[l].d[a] = dd[a][l];
      r[l].rd[a] = rdd[a][l];
    }
    r[l].t0 = t0s[l];
    r[l].hit = (hit >> l) & 1;
    r[l].kEnd = !r[l].hit ? 0 : kx[l] > 4e15 ? int64_t(4e15) : static_cast<int64_t>(kx[l]);
  }
}
#endif

template <typename R, typename Fetch, bool Skip, bool Shade>
void marchImage(const Frame& F, const Fetch& fetch, const VolumeGeometry& geo, const VolumeCamera& cam, int w, int h,
                double aspect, int threads, float* rgba, uint64_t& samples, uint64_t& skips,
                uint64_t& rays) {
  const Vec3 pos = cam.position;
  const Vec3 fwd = normalized(cam.focalPoint - cam.position);
  const Vec3 right = normalized(cross(fwd, cam.viewUp));
  const Vec3 up = cross(right, fwd);
  const double th = std::tan(cam.viewAngle * 0.5 * 3.14159265358979323846 / 180.0);
  const double hiIdx[3] = {double(F.n[0] - 1), double(F.n[1] - 1), double(F.n[2] - 1)};
  const PixelRect hit = hitRect(geo, cam, F.n, w, h, aspect, th, fwd, right, up);
  // What depends on the column or the row only, computed once (the same expressions as per pixel):
  // nx, ny; a perspective ray's direction terms right * (nx th aspect), up * (ny th); its origin.
  std::vector<double> nxs(static_cast<size_t>(w)), nys(static_cast<size_t>(h));
  std::vector<Vec3> rightX(static_cast<size_t>(w)), upY(static_cast<size_t>(h));
  std::vector<double> rightXa[3];  // the same per axis, padded by 3 columns for setupRays4
  for (int a = 0; a < 3; ++a) rightXa[a].assign(size_t(w) + 3, 0.0);
  for (int x = 0; x < w; ++x) {
    nxs[size_t(x)] = 2.0 * (x + 0.5) / w - 1.0;
    rightX[size_t(x)] = right * (nxs[size_t(x)] * th * aspect);
    for (int a = 0; a < 3; ++a) rightXa[a][size_t(x)] = rightX[size_t(x)][a];
  }
  for (int y = 0; y < h; ++y) {
    nys[size_t(y)] = 2.0 * (y + 0.5) / h - 1.0;
    upY[size_t(y)] = up * (nys[size_t(y)] * th);
  }
  double roEye[3];
  for (int a = 0; a < 3; ++a) roEye[a] = (pos[a] - geo.origin[a]) / geo.spacing[a];
  RaySetupFrame S0;
  for (int a = 0; a < 3; ++a) {
    S0.fwd[a] = fwd[a];
    S0.spacing[a] = geo.spacing[a];
    S0.roEye[a] = roEye[a];
    S0.hiIdx[a] = hiIdx[a];
    S0.rightX[a] = rightXa[a].data();
  }
  S0.dt = F.dt;
#if MT_VOLUME_AVX2
  const bool setup4 = F.setup4 && !cam.parallel;
#else
  const bool setup4 = false;
#endif
  constexpr int TILE = 8;
  static_assert(TILE * TILE <= PendingRayList::CAPACITY, "a tile's rays must fit the queue");
  const int tx = (w + TILE - 1) / TILE, ty = (h + TILE - 1) / TILE;
  constexpr int GROUP = 4;
  const int gx = (tx + GROUP - 1) / GROUP, gy = (ty + GROUP - 1) / GROUP;
  uint64_t sTotal = 0, kTotal = 0, rTotal = 0;
#pragma omp parallel for num_threads(threads) schedule(dynamic, 1) reduction(+ : sTotal, kTotal, rTotal)
  for (int tile = 0; tile < gx * gy * GROUP * GROUP; ++tile) {
    // Tiles in groups of GROUP x GROUP (32 x 32 pixels), the groups row by row: consecutive tiles'
    // rays cross the same bricks, which then stay cached (avg152T1 -2.6%, embryo -1.6%).
    const int group = tile / (GROUP * GROUP), in = tile % (GROUP * GROUP);
    const int tix = (group % gx) * GROUP + in % GROUP, tiy = (group / gx) * GROUP + in / GROUP;
    if (tix >= tx || tiy >= ty) continue;
    const int x0 = tix * TILE, y0 = tiy * TILE;
    const int x1 = std::min(w, x0 + TILE), y1 = std::min(h, y0 + TILE);
    RaySetupFrame S = S0;
    PendingRayList pending;  // this tile's rays for marchApronAvx2Pair (at most TILE^2 = 64)
    for (int y = y0; y < y1; ++y) {
      for (int a = 0; a < 3; ++a) S.upY[a] = upY[size_t(y)][a];
      const bool rowHit = y >= hit.y0 && y <= hit.y1;
      for (int xg = x0; xg < x1; xg += 4) {
        PixelRay group[4];
        const bool grouped = setup4 && rowHit && xg + 3 >= hit.x0 && xg <= hit.x1;
#if MT_VOLUME_AVX2
        if (grouped) setupRays4(S, xg, group);
#endif
        for (int x = xg; x < std::min(x1, xg + 4); ++x) {
          float* out = rgba + (size_t(y) * w + x) * 4;
          ++rTotal;
          if (!rowHit || x < hit.x0 || x > hit.x1) {  // misses the box: left 0
            out[0] = out[1] = out[2] = out[3] = 0.f;
            continue;
          }
          double ro[3];
          PixelRay r;
          if (cam.parallel) {
            const double nx = nxs[size_t(x)], ny = nys[size_t(y)];
            const Vec3 o = pos + right * (nx * cam.parallelScale * aspect) + up * (ny * cam.parallelScale);
            for (int a = 0; a < 3; ++a) {
              r.d[a] = fwd[a];
              ro[a] = (o[a] - geo.origin[a]) / geo.spacing[a];
              r.rd[a] = fwd[a] / geo.spacing[a];
            }
            clipPixelRay(ro, hiIdx, F.dt, r);
          } else {
            for (int a = 0; a < 3; ++a) ro[a] = roEye[a];
            r = grouped ? group[x - xg] : setupRay(S, x);
          }
          if (!r.hit) {
            out[0] = out[1] = out[2] = out[3] = 0.f;
            continue;
          }
          if (pairable<R, Shade>(F, fetch, r.kEnd)) {
            PendingRay& q = pending.rays[pending.count++];
            for (int a = 0; a < 3; ++a) {
              q.ro[a] = ro[a];
              q.rd[a] = r.rd[a];
            }
            q.t0 = r.t0;
            q.kEnd = r.kEnd;
            q.out = out;
            continue;
          }
          marchRay<R, Skip, Shade>(F, fetch, ro, r.rd, r.t0, r.kEnd, r.d, out, sTotal, kTotal);
        }
      }
    }
    if (pending.count) marchPending<R, Skip, Shade>(F, fetch, pending, sTotal, kTotal);
  }
  samples += sTotal;
  skips += kTotal;
  rays += rTotal;
}

template <typename R, typename Fetch>
void dispatch(bool skip, bool shade, const Frame& F, const Fetch& fetch, const VolumeGeometry& geo,
              const VolumeCamera& cam, int w, int h, double aspect, int threads, VolumeImage& img,
              float* rgba) {
  if (skip && shade)
    marchImage<R, Fetch, true, true>(F, fetch, geo, cam, w, h, aspect, threads, rgba, img.samples, img.skips, img.rays);
  else if (skip)
    marchImage<R, Fetch, true, false>(F, fetch, geo, cam, w, h, aspect, threads, rgba, img.samples, img.skips, img.rays);
  else if (shade)
    marchImage<R, Fetch, false, true>(F, fetch, geo, cam, w, h, aspect, threads, rgba, img.samples, img.skips, img.rays);
  else
    marchImage<R, Fetch, false, false>(F, fetch, geo, cam, w, h, aspect, threads, rgba, img.samples, img.skips, img.rays);
}

template <typename R>
void dispatchStorage(const BlockSparseVolume& vol, bool skip, bool shade, const Frame& F, const VolumeGeometry& geo,
                     const VolumeCamera& cam, int w, int h, double aspect, int threads, VolumeImage& img,
                     float* rgba) {
  const int nb0 = vol.levelDim(0, 0), nb1 = vol.levelDim(0, 1);
  switch (vol.storage()) {
    case VoxelStorage::UInt8:
      if (vol.pairedRows())
        dispatch<R>(skip, shade, F,
                    ApronFetch<Paired8>(vol.brickPointers().data(), reinterpret_cast<const Paired8*>(vol.bricks8().data()),
                                        vol.cellMasks().data(), nb0, nb1),
                    geo, cam, w, h, aspect, threads, img, rgba);
      else
        dispatch<R>(skip, shade, F,
                    ApronFetch<uint8_t>(vol.brickPointers().data(), vol.bricks8().data(), vol.cellMasks().data(), nb0,
                                        nb1),
                    geo, cam, w, h, aspect, threads, img, rgba);
      break;
    case VoxelStorage::UInt16:
      dispatch<R>(skip, shade, F,
                  ApronFetch<uint16_t>(vol.brickPointers().data(), vol.bricks16().data(), vol.cellMasks().data(), nb0,
                                       nb1),
                  geo, cam, w, h, aspect, threads, img, rgba);
      break;
    default:
      dispatch<R>(skip, shade, F, FloatFetch(vol.voxels()), geo, cam, w, h, aspect, threads, img, rgba);
  }
}

}  // namespace

std::vector<float> upsampleRGBA(const std::vector<float>& small, int w, int h, int W, int H, int threads) {
  std::vector<float> out(size_t(W) * H * 4, 0.f);
#pragma omp parallel for num_threads(threads) schedule(static)
  for (int y = 0; y < H; ++y) {
    const double sy = std::min(std::max((y + 0.5) * h / H - 0.5, 0.0), double(h - 1));
    const int y0 = std::min(static_cast<int>(sy), h - 1), y1 = std::min(y0 + 1, h - 1);
    const float fy = float(sy - y0);
    for (int x = 0; x < W; ++x) {
      const double sx = std::min(std::max((x + 0.5) * w / W - 0.5, 0.0), double(w - 1));
      const int x0 = std::min(static_cast<int>(sx), w - 1), x1 = std::min(x0 + 1, w - 1);
      const float fx = float(sx - x0);
      for (int ch = 0; ch < 4; ++ch) {
        const float a = small[(size_t(y0) * w + x0) * 4 + ch], b = small[(size_t(y0) * w + x1) * 4 + ch];
        const float cc = small[(size_t(y1) * w + x0) * 4 + ch], d = small[(size_t(y1) * w + x1) * 4 + ch];
        out[(size_t(y) * W + x) * 4 + ch] = (a + fx * (b - a)) * (1 - fy) + (cc + fx * (d - cc)) * fy;
      }
    }
  }
  return out;
}

void checkVolumeRenderArguments(const VolumeGeometry& geo, const TransferTable& tf, const VolumeCamera& cam,
                                const VolumeRenderOptions& opt, const char* who) {
  const std::string w(who);
  if (tf.size() < 2) throw std::invalid_argument(w + ": empty transfer table");
  for (int a = 0; a < 3; ++a)
    if (!(geo.spacing[a] != 0) || !std::isfinite(geo.spacing[a]) || !std::isfinite(geo.origin[a]))
      throw std::invalid_argument(w + ": spacing must be finite and non-zero, origin finite");
  if (!(opt.sampleDistance > 0) || !std::isfinite(opt.sampleDistance))
    throw std::invalid_argument(w + ": sample distance must be positive");
  if (!(opt.imageSampleDistance >= 1) || !std::isfinite(opt.imageSampleDistance))
    throw std::invalid_argument(w + ": image sample distance must be >= 1");
  if (cam.width < 1 || cam.height < 1 || cam.width > 16384 || cam.height > 16384)
    throw std::invalid_argument(w + ": image size must be in 1..16384");
  const Vec3 fwd = cam.focalPoint - cam.position;
  if (!isFinite(cam.position) || !isFinite(cam.focalPoint) || norm(fwd) == 0 || norm(cross(fwd, cam.viewUp)) == 0 ||
      (!cam.parallel && !(cam.viewAngle > 0 && cam.viewAngle < 180)) || (cam.parallel && !(cam.parallelScale > 0)))
    throw std::invalid_argument(w + ": degenerate camera (position = focal point, view up along the view, "
                                    "or view angle/parallel scale out of range)");
}

std::vector<float> stepCorrectedTable(const TransferTable& tf, double sampleDistance) {
  const int ne = tf.size();
  std::vector<float> table(size_t(ne) * 4);
  const double ratio = sampleDistance / tf.unitDistance();
  for (int i = 0; i < ne; ++i) {
    const float* e = tf.rgba().data() + 4 * size_t(i);
    const double a = e[3] >= 1.f ? 1.0 : 1.0 - std::pow(1.0 - double(e[3]), ratio);
    for (int ch = 0; ch < 3; ++ch) table[4 * size_t(i) + ch] = static_cast<float>(e[ch] * a);
    table[4 * size_t(i) + 3] = static_cast<float>(a);
  }
  return table;
}

VolumeImage renderVolume(const BlockSparseVolume& vol, const VolumeGeometry& geo, const TransferTable& tf,
                         const VolumeCamera& cam, const VolumeRenderOptions& opt) {
  checkVolumeRenderArguments(geo, tf, cam, opt, "renderVolume");  // before sizing the image
  std::vector<float> rgba(size_t(cam.width) * cam.height * 4);
  VolumeImage img = renderVolume(vol, geo, tf, cam, opt, rgba.data());
  img.rgba = std::move(rgba);
  return img;
}

VolumeImage renderVolume(const BlockSparseVolume& vol, const VolumeGeometry& geo, const TransferTable& tf,
                         const VolumeCamera& cam, const VolumeRenderOptions& opt, float* rgba) {
  const auto start = std::chrono::steady_clock::now();
  if (vol.levelCount() == 0) throw std::invalid_argument("renderVolume: the volume was not built");
  checkVolumeRenderArguments(geo, tf, cam, opt, "renderVolume");
  std::vector<float> table = stepCorrectedTable(tf, opt.sampleDistance);
  table.insert(table.end(), 4, 0.f);  // an all-zero entry past the last one (the AVX2 marcher's invisible cells)

  Frame F;
  F.vol = &vol;
  for (int a = 0; a < 3; ++a) {
    F.n[a] = vol.dim(a);
    F.nb[a] = vol.levelDim(0, a);
    F.spacing[a] = geo.spacing[a];
  }
  F.table = table.data();
  F.table8 = nullptr;
  F.tlo = tf.indexLo();
  F.tscale = tf.indexScale();
  F.tlast = tf.lastIndex();
  F.offset = vol.storageOffset();
  F.dt = opt.sampleDistance;
  F.threshold = earlyTerminationThreshold(opt);
  F.dist = vol.brickDistances().data();
  F.ambient = opt.ambient;
  F.diffuse = opt.diffuse;
  F.specular = opt.specular;
  F.specularPower = opt.specularPower;
  // MATRIXTREE_VOLUME_SIMD=sse2 forces the SSE2 marcher (as opt.vectorized = false) for a whole
  // process, e.g. to time both from Python.
  const char* simd = std::getenv("MATRIXTREE_VOLUME_SIMD");
  const bool forceSse2 = simd && std::strcmp(simd, "sse2") == 0;
  const bool apron = vol.storage() != VoxelStorage::Float32;
  // The AVX2 marcher indexes voxels (stored brick * 9^3 or BRICK_BYTES8 + offset) and mask words (level-0 brick
  // * 16 + word) with 32-bit integers.
  const bool indexable = uint64_t(vol.stats().bricksStored + 1) * BlockSparseVolume::BRICK_BYTES8 < (uint64_t(1) << 31) &&
                         uint64_t(vol.stats().bricks) * 2 * DIM < (uint64_t(1) << 31);
  F.setup4 = opt.vectorized && !forceSse2 && cpuHasAvx2();
  F.lanes = apron && !opt.doublePrecision && !opt.shade && indexable && opt.vectorized && !forceSse2 && cpuHasAvx2() ? 8 : 1;
  // The AVX2 marcher's table: entry e at float 8 e, 32-byte aligned. 1 - a is the same float
  // operation the SSE2 marcher does per sample, so the transmittance gets the same bits.
  std::vector<float> table8Store;
  if (F.lanes == 8) {
    const size_t ne = table.size() / 4;  // with the all-zero entry
    table8Store.assign(ne * 8 + 8, 0.f);
    float* t8 = table8Store.data() + (8 - (reinterpret_cast<uintptr_t>(table8Store.data()) / 4) % 8) % 8;
    for (size_t e = 0; e < ne; ++e) {
      for (int c = 0; c < 4; ++c) t8[8 * e + c] = table[4 * e + c];
      for (int c = 4; c < 8; ++c) t8[8 * e + c] = 1.f - table[4 * e + 3];
    }
    F.table8 = t8;
  }
  // The bricks the AVX2 marcher may march through, as the entry of their first voxel (stored brick
  // times the brick's entries: no multiply between the gather of it and the corner gathers): the
  // stored ones, but with skipping only the visible ones (all bricks are stored when the volume
  // was built dense); MT_NULL elsewhere.
  std::vector<uint32_t> runBricks;
  F.runBricks = nullptr;
  if (F.lanes == 8) {
    const uint32_t entries = vol.pairedRows() ? BlockSparseVolume::BRICK_BYTES8 : BlockSparseVolume::BRICK_VOLUME;
    runBricks = vol.brickPointers();
    for (int k = 0; k < F.nb[2]; ++k)
      for (int j = 0; j < F.nb[1]; ++j)
        for (int i = 0; i < F.nb[0]; ++i) {
          uint32_t& b = runBricks[(size_t(k) * F.nb[1] + j) * F.nb[0] + i];
          if (b != MT_NULL) b = opt.emptySpaceSkipping && !vol.nodeVisible(0, i, j, k) ? MT_NULL : b * entries;
        }
    F.runBricks = runBricks.data();
  }

  VolumeImage img;
  img.lanes = F.lanes;
  img.width = cam.width;
  img.height = cam.height;
  const int w = std::max(1, static_cast<int>(std::lround(cam.width / opt.imageSampleDistance)));
  const int h = std::max(1, static_cast<int>(std::lround(cam.height / opt.imageSampleDistance)));
  const double aspect = double(cam.width) / cam.height;
  const int threads = resolveThreads(opt.threads);
  // Full size: straight into rgba; else a small image, then upsampled into it.
  const bool full = w == cam.width && h == cam.height;
  std::vector<float> small(full ? 0 : size_t(w) * h * 4);
  float* target = full ? rgba : small.data();
  if (opt.doublePrecision)
    dispatchStorage<double>(vol, opt.emptySpaceSkipping, opt.shade, F, geo, cam, w, h, aspect, threads, img, target);
  else
    dispatchStorage<float>(vol, opt.emptySpaceSkipping, opt.shade, F, geo, cam, w, h, aspect, threads, img, target);
  if (!full) {
    const std::vector<float> up = upsampleRGBA(small, w, h, cam.width, cam.height, threads);
    std::copy(up.begin(), up.end(), rgba);
  }
  img.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return img;
}

}  // namespace mtree

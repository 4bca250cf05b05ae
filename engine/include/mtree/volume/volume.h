// Volume ray casting on the block-sparse encoding (paper §3 and its volume-rendering result:
// replacing the matrix-tree CSR encoding by block-sparse matrices made ray casting 75-280%
// faster, because a sample costs two memory reads: the pointer matrix, then the block).
//
//   BlockSparseVolume  the scalar field, block-sparse, in one of two layouts (VoxelStorage):
//                      Float32: a BlockSparseMatrix<float> of DIM^3-voxel blocks (any input type);
//                      UInt8/UInt16 (8/16-bit integer input, the default for it; floating-point
//                      input holding integers, or quantised: VolumeBuildOptions): bricks of DIM^3
//                      cells stored as (DIM+1)^3 voxels in the input's width, i.e. with a 1-voxel
//                      apron towards +x/+y/+z, so all 8 corners of every cell of a brick are in
//                      the brick (no neighbour lookup per sample); signed input is offset.
//                      8-bit bricks of small grids are held in rows of y pairs (BRICK_BYTES8): a
//                      cell's 4 corners in a z plane are 4 consecutive bytes.
//                      Only blocks that a visible sample can read are allocated ("model only
//                      what a scene requires"): a cell (8 voxels) is visible when the opacity
//                      function is non-zero somewhere on [min, max] of its corners; every voxel
//                      block holding a corner of a visible cell is allocated, nothing else.
//                      Above the blocks, the matrix-tree levels: level 0 marks the bricks of
//                      DIM^3 cells that hold a visible cell, level l groups 2^l x 2^l x 2^l bricks
//                      (an implicit octree: parents are computed, not stored). The 8/16-bit
//                      layouts also hold, per level-0 brick and ray octant, the largest cube of
//                      invisible bricks with that brick at its corner, extending the way the ray
//                      goes (brickDistances).
//   TransferTable      post-classification lookup table (colour + opacity per unit length) with
//                      O(1) range-max opacity queries (a sparse table), used to classify cells.
//   renderVolume       ray marching with trilinear interpolation, front-to-back compositing with
//                      opacity corrected for the step length (premultiplied table, once per frame),
//                      early ray termination, optional gradient shading, hierarchical empty-space
//                      skipping, OpenMP over 8x8-pixel tiles (in groups of 4x4). A ray is walked brick by brick: on
//                      entry the brick's storage is resolved once, then samples inside it need no
//                      clamping, no bounds checks and no pointer-matrix reads. In an invisible
//                      brick the walk leaves, in one step, the coarsest empty octree node (Float32
//                      layout, double accumulation) or the brick's empty cube for the ray's octant
//                      (8/16-bit layouts in float: it starts at the ray's own brick and extends
//                      only ahead, so it reaches further than an aligned octree node does).
//
// Exactness of the skipping: a cell that is not visible yields opacity exactly 0 at every sample
// (the interpolated value lies in [min, max] of the corners up to round-off, the table lookup is
// monotone, and the range query is widened by a bound on that round-off), so skipping it, or
// reading it from an
// absent block, changes nothing. Sample k sits at P0 + k * S (index space, computed the same way
// in both modes), so rendering with and without skipping gives the same image bit for bit.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

#include "mtree/core/block_sparse.h"
#include "mtree/core/geometry.h"

namespace mtree {

/// Colour and opacity sampled at `size` evenly spaced scalars over [lo, hi] (entry 0 at lo,
/// entry size-1 at hi); alpha is the opacity of a segment of length `unitDistance`.
/// Scalars outside [lo, hi] are clamped to the end entries (VTK's clamping behaviour).
class TransferTable {
 public:
  TransferTable() = default;
  /// rgba: 4 floats per entry in [0, 1]. Throws std::invalid_argument on bad input.
  TransferTable(double lo, double hi, std::vector<float> rgba, double unitDistance = 1.0);

  int size() const { return static_cast<int>(rgba_.size() / 4); }
  double lo() const { return lo_; }
  double hi() const { return hi_; }
  double unitDistance() const { return unit_; }
  const std::vector<float>& rgba() const { return rgba_; }

  /// Entry of scalar v: nearest entry, clamped. Monotone in v (each float op is), which the
  /// visibility classification relies on.
  int index(float v) const {
    const float x = (v - flo_) * fscale_ + 0.5f;
    if (!(x > 0.f)) return 0;  // also catches NaN
    if (!(x < float(last_))) return last_;  // before the cast: a float past INT_MAX has no int
    return static_cast<int>(x);
  }
  int index(double v) const { return index(static_cast<float>(v)); }
  /// The three numbers index() uses, for copying into an inner loop.
  float indexLo() const { return flo_; }
  float indexScale() const { return fscale_; }
  int lastIndex() const { return last_; }
  /// Largest alpha over every entry a scalar in [a - tol, b + tol] maps to: the values an
  /// interpolation of corners in [a, b] can round to (index() is monotone, so this is exact).
  /// tol < 0: 1e-5 (|a| + |b|) + 1e-30, far above the round-off of a trilinear interpolation in
  /// float (a few ulps of max(|a|, |b|)). O(1) (sparse table of range maxima).
  float maxOpacity(float a, float b, float tol = -1.f) const;

 private:
  double lo_ = 0, hi_ = 1, unit_ = 1;
  float flo_ = 0, fscale_ = 1;
  int last_ = 0;
  std::vector<float> rgba_;
  std::vector<std::vector<float>> rangeMax_;  // rangeMax_[l][i] = max alpha over [i, i + 2^l)
};

/// Build settings of a BlockSparseVolume.
struct VolumeBuildOptions {
  bool sparse = true;   // false: allocate every block (the dense reference, same code path)
  bool compact = true;  // 8/16-bit integer input: keep its width, bricks with an apron (UInt8/UInt16)
  /// Input of any other type (float, or integers wider than 16 bits, or any input with compact
  /// off) whose values are all integers spanning at most 65535: store it as UInt8/UInt16 too
  /// (lossless; both back ends read those bricks). false: such input keeps Float32 blocks.
  bool compactIntegralFloat = true;
  /// Other floating-point input: quantise it into UInt16 bricks, value = stored * q + min with
  /// q = (max - min) / 65535, when the transfer table is at least QUANTIZE_RATIO times coarser
  /// (its entry spacing (hi - lo) / (size - 1) >= QUANTIZE_RATIO q). Error bound: a sample is a
  /// convex combination of its 8 corners, so it moves by at most q / 2 (<= 1/32 of an entry
  /// spacing): its table entry is the exact path's or a neighbour of it, the neighbour only for a
  /// sample within q / 2 of the midpoint between two entries. A pixel then differs from the exact
  /// path's by at most the sum, over its samples that change entry, of that entry step's change in
  /// premultiplied colour plus opacity (compositing is 1-Lipschitz in each sample's entry: its
  /// weight T_k <= 1 and the colour behind it is at most T_k). docs/bench_volume.md states it and
  /// tests/cpp/test_volume.cpp checks it against the exact path (false here).
  bool quantizeFloat = true;
  static constexpr double QUANTIZE_RATIO = 16.0;
  int threads = 0;      // 0 = OpenMP's default
};

/// How the voxels are held (see the top of this file).
enum class VoxelStorage : int { Float32 = 0, UInt8 = 1, UInt16 = 2 };

/// Memory and classification statistics, the paper's currency.
struct VolumeStats {
  uint64_t voxels = 0, cells = 0, visibleCells = 0;
  uint32_t blocksAllocated = 0;  // DIM^3 voxel blocks holding a corner of a visible cell
  uint32_t blocksDense = 0;      // voxel blocks of the whole grid (the pointer matrix size)
  uint32_t bricksVisible = 0;    // level-0 bricks (DIM^3 cells) holding a visible cell
  uint32_t bricks = 0;
  uint32_t bricksStored = 0;     // UInt8/UInt16: apron bricks held (the visible ones); Float32: 0
  VoxelStorage storage = VoxelStorage::Float32;
  uint64_t blockBytes = 0;       // blocksAllocated * DIM^3 * 4: the visible blocks as float (the
                                 // Float32 payload; the reference the memory target is set against)
  uint64_t bytes = 0;            // everything held: voxels + pointers + ranges + levels
  uint64_t denseBytes = 0;       // voxels * 4: a dense float copy
  int levels = 0;                // matrix-tree levels above the blocks, level 0 included
  uint64_t nonFinite = 0;        // NaN/inf voxels replaced by the lowest finite value
  double buildMs = 0;
};

class BlockSparseVolume {
 public:
  static constexpr int LOG2DIM = 3;
  static constexpr int DIM = 1 << LOG2DIM;  // voxels per block edge, cells per brick edge

  /// Classifies `values` (x fastest, dims[0]*dims[1]*dims[2] of them) with `tf` and stores
  /// the blocks visible cells read. Any arithmetic type. Non-finite values are replaced by the
  /// lowest finite value (counted in stats().nonFinite). Throws std::invalid_argument for
  /// fewer than 2 points along an axis (no cell to interpolate in) or no finite value.
  template <typename T>
  void build(const T* values, const int dims[3], const TransferTable& tf,
             const VolumeBuildOptions& opt = VolumeBuildOptions());

  int dim(int a) const { return n_[a]; }
  VoxelStorage storage() const { return storage_; }
  /// The Float32 layout's matrix (a 1x1x1 placeholder when the storage is UInt8/UInt16).
  const BlockSparseMatrix<float>& voxels() const { return vox_; }
  /// UInt8/UInt16 layout: brick pointers (level-0 order, MT_NULL = absent), the bricks, and the
  /// offset added to a stored value (signed input). A brick holds APRON^3 voxels (its 8^3 cells'
  /// corners) as APRON^3 entries, x fastest, then y, then z (BRICK_VOLUME); except 8-bit bricks
  /// of a grid of at most PAIRED_MAX_BRICKS level-0 bricks (pairedRows()), held in rows of y
  /// pairs (BRICK_BYTES8 bytes): for z = 0..8 and y = 0..7, the 9 voxels (x, y) and (x, y + 1)
  /// interleaved, byte 2 x + dy of row (y, z) at pairOffset(0, y, z). The 4 corners of a cell in
  /// a z plane are then 4 consecutive bytes, (x, y), (x, y + 1), (x + 1, y), (x + 1, y + 1), read
  /// at once (rows y = 1..7 are held twice: 1296 bytes a brick instead of 729, so only where the
  /// bricks stay small enough to be cached; the rule depends on the dimensions only, so the
  /// OpenCL kernel derives it too).
  static constexpr int APRON = DIM + 1;
  static constexpr int BRICK_VOLUME = APRON * APRON * APRON;
  static constexpr int PAIR_SY = 2 * APRON, PAIR_SZ = PAIR_SY * DIM;
  static constexpr int BRICK_BYTES8 = PAIR_SZ * APRON;
  static constexpr int PAIRED_MAX_BRICKS = 4096;
  static constexpr int pairOffset(int x, int y, int z) { return 2 * x + PAIR_SY * y + PAIR_SZ * z; }
  bool pairedRows() const { return paired_; }
  /// bricks8() holds BRICK_PAD zero bytes after its last brick: the AVX2 marcher reads a cell's
  /// corner pair (2 bytes) with a 4-byte gather.
  static constexpr int BRICK_PAD = 4;
  const std::vector<uint32_t>& brickPointers() const { return brickPtr_; }
  const std::vector<uint8_t>& bricks8() const { return b8_; }
  const std::vector<uint16_t>& bricks16() const { return b16_; }
  /// A stored UInt8/UInt16 value s stands for s * storageScale() + storageOffset() (scale 1 but for
  /// quantised floating-point input, VolumeBuildOptions::quantizeFloat; Float32: scale 1, offset 0).
  float storageOffset() const { return offset_; }
  float storageScale() const { return scale_; }
  /// The quantisation step of the stored values (0: they are the input's values exactly).
  float quantizationStep() const { return quantized_ ? scale_ : 0.f; }
  /// UInt8/UInt16 layout: per level-0 brick, DIM 64-bit words (one per z layer, bit x + DIM y) marking
  /// its visible cells; a sample in an unmarked cell has opacity exactly 0 and is not taken.
  const std::vector<uint64_t>& cellMasks() const { return cellMask_; }
  const VolumeStats& stats() const { return stats_; }
  float minValue() const { return vmin_; }
  float maxValue() const { return vmax_; }

  /// The 8 corner values of cell (i, j, k) (x fastest: c[dx + 2 dy + 4 dz]). False when a
  /// corner's block is absent: such a cell is invisible, its samples have opacity 0.
  bool cellCorners(int i, int j, int k, float c[8]) const { return corners<false>(i, j, k, c); }
  /// The same in sample units, the units the marchers interpolate in: value / storageScale(), i.e.
  /// stored + storageOffset() / storageScale() (the values themselves where the scale is 1).
  bool cellCornersInSampleUnits(int i, int j, int k, float c[8]) const { return corners<true>(i, j, k, c); }

  /// Trilinear value at continuous index position (x, y, z), clamped into the grid. False
  /// where the cell is invisible (an absent block); `v` is then unset.
  bool sample(double x, double y, double z, double& v) const;

 private:
  template <bool SampleUnits>
  bool corners(int i, int j, int k, float c[8]) const {
    if (storage_ != VoxelStorage::Float32) {
      const float scale = SampleUnits ? 1.f : scale_, offset = SampleUnits ? sampleOffset_ : offset_;
      const uint32_t b = brickPtr_[(size_t(k >> LOG2DIM) * levels_[0].n[1] + (j >> LOG2DIM)) * levels_[0].n[0] +
                                   (i >> LOG2DIM)];
      if (b == MT_NULL) return false;
      const int lx = i & (DIM - 1), ly = j & (DIM - 1), lz = k & (DIM - 1);
      if (paired_) {
        const size_t o = size_t(b) * BRICK_BYTES8 + pairOffset(lx, ly, lz);
        for (int n = 0; n < 8; ++n)
          c[n] = float(b8_[o + 2 * (n & 1) + ((n >> 1) & 1) + PAIR_SZ * (n >> 2)]) * scale + offset;
        return true;
      }
      const size_t o = size_t(b) * BRICK_VOLUME + lx + APRON * ly + APRON * APRON * lz;
      for (int n = 0; n < 8; ++n) {
        const size_t e = o + (n & 1) + APRON * ((n >> 1) & 1) + APRON * APRON * (n >> 2);
        c[n] = (storage_ == VoxelStorage::UInt8 ? float(b8_[e]) : float(b16_[e])) * scale + offset;
      }
      return true;
    }
    const MtSparseDesc& d = vox_.desc();
    const int m0 = (1 << d.logBlock[0]) - 1, m1 = (1 << d.logBlock[1]) - 1, m2 = (1 << d.logBlock[2]) - 1;
    if ((i & m0) != m0 && (j & m1) != m1 && (k & m2) != m2) {
      // Fast path (7/8 of the cells per axis): all corners in one block, one pointer read.
      const uint32_t b = ptr_[vox_.pointerIndex(i, j, k)];
      if (b == MT_NULL) return false;
      const float* p = data_ + size_t(b) * d.blockVolume + vox_.localIndex(i, j, k);
      const int sy = 1 << d.logBlock[0], sz = 1 << (d.logBlock[0] + d.logBlock[1]);
      c[0] = p[0]; c[1] = p[1]; c[2] = p[sy]; c[3] = p[sy + 1];
      c[4] = p[sz]; c[5] = p[sz + 1]; c[6] = p[sz + sy]; c[7] = p[sz + sy + 1];
      return true;
    }
    for (int n = 0; n < 8; ++n) {
      const float* p = vox_.find(i + (n & 1), j + ((n >> 1) & 1), k + (n >> 2));
      if (!p) return false;
      c[n] = *p;
    }
    return true;
  }

 public:
  /// Level-l node (i, j, k) of the empty-space hierarchy holds a visible cell.
  bool nodeVisible(int level, int i, int j, int k) const {
    const LevelGrid& g = levels_[level];
    return g.occ[(size_t(k) * g.n[1] + j) * g.n[0] + i] != 0;
  }
  int levelCount() const { return static_cast<int>(levels_.size()); }
  /// Per level-0 brick b (x fastest), 8 bytes, one per octant o of directions (bit a of o set:
  /// negative along axis a): 0 where b holds a visible cell, else the edge r (at most 255) of the
  /// largest cube of invisible bricks with b at its corner and extending from it towards octant o
  /// (bricks b + (i, j, k), 0 <= i, j, k < r, signs of o; the grid's outside counts as invisible).
  /// A ray in b going that way leaves the cube in one step of the walk.
  const std::vector<uint8_t>& brickDistances() const { return dist_; }
  int levelDim(int level, int a) const { return levels_[level].n[a]; }
  /// Per-brick value range [min, max] over the brick's cells' corners (level-0 index).
  float brickMin(int i, int j, int k) const { return brickMin_[(size_t(k) * levels_[0].n[1] + j) * levels_[0].n[0] + i]; }
  float brickMax(int i, int j, int k) const { return brickMax_[(size_t(k) * levels_[0].n[1] + j) * levels_[0].n[0] + i]; }

 private:
  struct LevelGrid {
    int n[3] = {1, 1, 1};
    std::vector<uint8_t> occ;
  };
  void classify(const TransferTable& tf, const VolumeBuildOptions& opt, std::vector<float>& dense);

  BlockSparseMatrix<float> vox_;
  int n_[3] = {1, 1, 1};
  VoxelStorage storage_ = VoxelStorage::Float32;
  bool paired_ = false;  // UInt8 bricks in rows of y pairs (see BRICK_BYTES8)
  float offset_ = 0, scale_ = 1;
  float sampleOffset_ = 0;  // offset_ / scale_: sample units (cellCornersInSampleUnits)
  bool quantized_ = false;  // UInt16 bricks of quantised floating-point input
  std::vector<uint32_t> brickPtr_;
  std::vector<uint8_t> b8_;
  std::vector<uint16_t> b16_;
  std::vector<uint64_t> cellMask_;
  const uint32_t* ptr_ = nullptr;
  const float* data_ = nullptr;
  std::vector<LevelGrid> levels_;
  std::vector<uint8_t> dist_;
  std::vector<float> brickMin_, brickMax_;
  float vmin_ = 0, vmax_ = 0;
  VolumeStats stats_;
};

/// A pinhole (or parallel) camera as vtkCamera describes one: position, focal point, view up,
/// vertical view angle; ParallelProjection with ParallelScale (half the view height).
struct VolumeCamera {
  Vec3 position{0, 0, 1}, focalPoint{0, 0, 0}, viewUp{0, 1, 0};
  double viewAngle = 30;  // degrees, vertical
  bool parallel = false;
  double parallelScale = 1;
  int width = 512, height = 512;
};

/// Where the volume sits in the world: point (i, j, k) is at origin + (i, j, k) * spacing
/// (axis-aligned, as vtkImageData without a direction matrix). Spacing may be negative, not 0.
struct VolumeGeometry {
  double origin[3] = {0, 0, 0};
  double spacing[3] = {1, 1, 1};
};

/// Speed/accuracy controls (docs/guide.md, "Volume ray casting", lists their measured effect).
struct VolumeRenderOptions {
  double sampleDistance = 1.0;       // world units between samples along a ray; smaller: slower, more exact
  double imageSampleDistance = 1.0;  // >1 casts (W/isd) x (H/isd) rays and interpolates bilinearly
  double earlyTermination = 0.99;    // stop a ray when its opacity reaches this; >= 1: never
  bool doublePrecision = false;      // accumulate (interpolation + compositing) in double
  bool emptySpaceSkipping = true;    // skip invisible nodes of the matrix-tree levels
  bool shade = false;                // gradient (of the trilinear interpolant) shading, headlight
  double ambient = 0.2, diffuse = 0.7, specular = 0.2, specularPower = 10;
  int threads = 0;                   // 0 = OpenMP's default
  /// UInt8/UInt16 storage, float, unshaded: march 8 samples at a time with AVX2 where the CPU has
  /// it (chosen at run time); every storage: set perspective rays up 4 at a time with AVX2. false:
  /// the SSE2 marcher and the scalar set-up. Both give the same image bit for bit.
  bool vectorized = true;
};

struct VolumeImage {
  int width = 0, height = 0;
  int lanes = 1;  // samples per step of the marcher that ran: 8 (AVX2, see vectorized) or 1
  std::vector<float> rgba;  // premultiplied colour + opacity, 4 per pixel, row 0 at the bottom
  uint64_t rays = 0, samples = 0, skips = 0;  // rays cast, samples classified, nodes skipped
  double ms = 0;
};

/// Renders `vol` (classified with `tf`) seen through `cam`. Throws std::invalid_argument on
/// a zero spacing, a non-positive sample distance or image size, or a degenerate camera.
VolumeImage renderVolume(const BlockSparseVolume& vol, const VolumeGeometry& geo, const TransferTable& tf,
                         const VolumeCamera& cam, const VolumeRenderOptions& opt);
/// The same into `rgba`, cam.width * cam.height * 4 floats owned by the caller (e.g. a buffer kept
/// across frames: no allocation and no fresh pages per frame); the returned image's rgba is empty.
VolumeImage renderVolume(const BlockSparseVolume& vol, const VolumeGeometry& geo, const TransferTable& tf,
                         const VolumeCamera& cam, const VolumeRenderOptions& opt, float* rgba);

/// renderVolume's argument checks, shared by the CPU and the OpenCL renderers: throws
/// std::invalid_argument, the message starting with `who`, on an empty table, a zero or
/// non-finite spacing, a non-finite origin, a non-positive sample distance, an image sample
/// distance < 1, an image size outside 1..16384, or a degenerate camera.
void checkVolumeRenderArguments(const VolumeGeometry& geo, const TransferTable& tf, const VolumeCamera& cam,
                                const VolumeRenderOptions& opt, const char* who);

/// The table the marchers read: each entry's opacity corrected for the step,
/// alpha' = 1 - (1 - alpha)^(sampleDistance / unit distance), and its colour premultiplied by it
/// (4 floats per entry).
std::vector<float> stepCorrectedTable(const TransferTable& tf, double sampleDistance);

/// The numbers a marcher classifies a sample with: it interpolates in sample units
/// (BlockSparseVolume::cellCornersInSampleUnits, stored + offset), and the table's index map
/// (TransferTable::index) is carried into those units: index = (u - tableLo) * tableScale + 0.5.
/// Where the storage scale is 1 these are the table's own numbers, bit for bit.
struct SampleUnits {
  float offset, tableLo, tableScale;
};
inline SampleUnits sampleUnits(const BlockSparseVolume& vol, const TransferTable& tf) {
  const float s = vol.storageScale();
  return SampleUnits{vol.storageOffset() / s, tf.indexLo() / s, tf.indexScale() * s};
}

/// The accumulated opacity at which a ray stops, as the marchers compare it (a float; 2 = never).
inline float earlyTerminationThreshold(const VolumeRenderOptions& opt) {
  return opt.earlyTermination >= 1 ? 2.f : static_cast<float>(std::max(0.0, opt.earlyTermination));
}

/// The full-size image from one rendered at w x h pixels (an image sample distance > 1): bilinear
/// reconstruction with pixel centres aligned, as VTK's ImageSampleDistance. Shared by the CPU and
/// the OpenCL renderers.
std::vector<float> upsampleRGBA(const std::vector<float>& small, int w, int h, int W, int H, int threads);

// --------------------------------------------------------------------------------------------
// BlockSparseVolume::build: the typed part (conversion); the classification is in
// engine/src/volume/classify.cpp.

template <typename T>
void BlockSparseVolume::build(const T* values, const int dims[3], const TransferTable& tf,
                              const VolumeBuildOptions& opt) {
  static_assert(std::is_arithmetic<T>::value, "BlockSparseVolume::build: arithmetic scalars only");
  if (!values) throw std::invalid_argument("BlockSparseVolume: no scalars");
  for (int a = 0; a < 3; ++a)
    if (dims[a] < 2)
      throw std::invalid_argument("BlockSparseVolume: need at least 2 points along every axis (got " +
                                  std::to_string(dims[0]) + "x" + std::to_string(dims[1]) + "x" +
                                  std::to_string(dims[2]) + "): a 1-voxel-thick volume has no cell");
  if (tf.size() < 2) throw std::invalid_argument("BlockSparseVolume: empty transfer table");
  const int64_t n = int64_t(dims[0]) * dims[1] * dims[2];
  // The conversion to float runs once per build; classify() reads it and copies only the
  // visible blocks into the block-sparse matrix, then it is freed.
  std::vector<float> dense(static_cast<size_t>(n));
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  uint64_t bad = 0;
#pragma omp parallel for num_threads(resolveThreads(opt.threads)) \
    reduction(min : lo) reduction(max : hi) reduction(+ : bad) schedule(static)
  for (int64_t i = 0; i < n; ++i) {
    const float f = static_cast<float>(values[i]);
    dense[size_t(i)] = f;
    if (std::isfinite(f)) {
      lo = std::min(lo, double(f));
      hi = std::max(hi, double(f));
    } else {
      ++bad;
    }
  }
  if (!(lo <= hi)) throw std::invalid_argument("BlockSparseVolume: no finite scalar value");
  if (bad) {
    for (float& f : dense)
      if (!std::isfinite(f)) f = static_cast<float>(lo);
  }
  vmin_ = static_cast<float>(lo);
  vmax_ = static_cast<float>(hi);
  for (int a = 0; a < 3; ++a) n_[a] = dims[a];
  // 8/16-bit integers are held in their own width (exactly: float holds them all); signed ones
  // shifted to unsigned by offset_, which the sampler adds back.
  storage_ = VoxelStorage::Float32;
  offset_ = 0;
  scale_ = 1;
  quantized_ = false;
  if (opt.compact && std::is_integral<T>::value && sizeof(T) <= 2) {
    storage_ = sizeof(T) == 1 ? VoxelStorage::UInt8 : VoxelStorage::UInt16;
    offset_ = std::is_signed<T>::value ? vmin_ : 0.f;  // stored = value - offset >= 0
  } else if (opt.compactIntegralFloat && !bad && hi - lo <= 65535.0) {
    // Floating-point input that holds only integers: kept losslessly as 8/16-bit integers.
    bool integral = true;
#pragma omp parallel for num_threads(resolveThreads(opt.threads)) reduction(&& : integral) schedule(static)
    for (int64_t i = 0; i < n; ++i) integral = integral && dense[size_t(i)] == std::floor(dense[size_t(i)]);
    if (integral) {
      offset_ = lo >= 0 && hi <= 65535.0 ? 0.f : vmin_;
      storage_ = hi - offset_ <= 255.0 ? VoxelStorage::UInt8 : VoxelStorage::UInt16;
    }
  }
  if (storage_ == VoxelStorage::Float32 && opt.compact && opt.quantizeFloat && hi > lo) {
    // Quantised into 16 bits where the table cannot resolve the step (see quantizeFloat).
    const double step = (hi - lo) / 65535.0, spacing = (tf.hi() - tf.lo()) / double(tf.size() - 1);
    if (spacing >= VolumeBuildOptions::QUANTIZE_RATIO * step) {
      storage_ = VoxelStorage::UInt16;
      offset_ = vmin_;
      scale_ = static_cast<float>(step);
      quantized_ = true;
    }
  }
  sampleOffset_ = offset_ / scale_;
  vox_.reset(dims[0], dims[1], dims[2], DIM, 0.f);
  stats_ = VolumeStats{};
  stats_.nonFinite = bad;
  classify(tf, opt, dense);
}

}  // namespace mtree

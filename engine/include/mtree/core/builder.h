// The parallel bottom-up build of Andrysco & Tricoche §5.1 (after Kalojanov & Slusallek 2009),
// on OpenMP. MatrixTreeBuilder::build runs one member of MatrixTreeBuilder::Run per phase, each
// timed under its name in BuildStats::phasesMs:
//   setup        step 1, the one serial step: root box, height, level shapes
//   count+mark   step 2: per primitive, count the overlapped leaves and mark their blocks
//   alloc        steps 3-4: exclusive scan of the block marks, block pointers set
// then, with BuildSort::Radix (the paper's; the default):
//   scan         step 5: exclusive scan of the per-primitive counts
//   pairs        step 6: (leaf, primitive) pairs written at the scanned offsets, no atomics
//   sort         step 7: stable radix sort of the pairs by leaf
//   offsets      step 8: leaf ranges from neighbouring keys in the sorted array
//   refdata      only with per-reference data: a pass over the leaves, one call per reference
// or with BuildSort::Counting (the leaf storage is dense after alloc: a leaf's storage index is
// its counter):
//   leaf counts  references per leaf, counted by count+mark (each thread in its own first-touch
//                numbering of the blocks) and copied or added to their final places; with more
//                than two threads on a large leaf level, a pass with atomic increments
//   leaf scan    exclusive scan over the leaf storage; leaf ranges from it
//   scatter      each reference's primitive id (and its data) at its leaf's next slot
//   leaf order   with more than two threads only: each leaf's ids sorted ascending
// and in both
//   propagate    step 9: existence up to the root, level by level
//   walk caches  MatrixTree::buildWalkCaches
// pairs and scatter repeat no overlap test that count+mark made: its verdicts for a primitive's
// first 64 candidate leaves are kept as a bit mask.
//
// Determinism: the tree depends only on the primitives and the options, never on the thread
// count or the sort. Every parallel step writes to positions fixed by a scan, or stores the same
// byte from every writer; the radix sort is stable; the counting sort writes ascending ids per
// leaf (one thread, or two filling each leaf from both ends) or restores that order (leaf
// order); the per-reference data depends on the primitive and the leaf only. So both sorts give
// the same leaf ranges, primitive order and data (tests/cpp/test_build_sort.cpp holds every sort
// and thread count to the one-thread radix tree).
#pragma once

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include <omp.h>

#include "mtree/core/matrix_tree.h"
#include "mtree/core/memory.h"
#include "mtree/core/parallel.h"

namespace mtree {

namespace detail {
struct NoReferenceData {
  template <class... A>
  void operator()(A&&...) const {}
};
}  // namespace detail

template <class Prims>
class MatrixTreeBuilder {
 public:
  /// Builds `tree` over `prims`. Throws std::invalid_argument on bad options or input
  /// (non-finite bounds); an empty primitive set gives an empty tree (every query misses).
  static void build(const Prims& prims, const BuildOptions& opt, MatrixTree& tree, BuildStats* stats) {
    build<0>(prims, opt, tree, stats, nullptr, detail::NoReferenceData{});
  }
  /// The same, and `Bytes` bytes of data per reference, fused into the build: `refData` gets
  /// Bytes x references bytes, those of reference k (primitiveIndices()[k] in its leaf) written
  /// by fn(uint8_t* out, const Prims::Local& prim, const Box& leafBox) — once per reference;
  /// every thread calls its own copy of fn (so fn may keep a cache, e.g. of divisions).
  /// Counting: at the scatter, where the primitive is in hand;
  /// Radix: a pass over the leaves after the ranges ("refdata"), fetching each primitive again.
  /// The bytes must depend on the primitive and the leaf only: both orders give the same data.
  template <size_t Bytes, class RefFn>
  static void build(const Prims& prims, const BuildOptions& opt, MatrixTree& tree, BuildStats* stats,
                    LargeVector<uint8_t>* refData, RefFn&& fn);

 private:
  template <size_t Bytes, class RefFn>
  class Run;
};

namespace detail {
/// A reference with its data, for sorting a leaf's references by primitive id.
template <size_t Bytes>
struct Reference {
  uint32_t id;
  std::array<uint8_t, Bytes> data;
};

/// Sorts the distinct ids [b, e) ascending and their Bytes-byte data along with them: an
/// insertion sort for the common few per leaf (nearly in order: threads take chunks of
/// ascending ids), std::sort through `buf` for long leaves.
template <size_t Bytes>
void sortLeaf(uint32_t* ids, uint8_t* data, uint32_t b, uint32_t e, std::vector<Reference<Bytes>>& buf) {
  if (e - b <= 32) {
    for (uint32_t k = b + 1; k < e; ++k) {
      const uint32_t v = ids[k];
      if (ids[k - 1] < v) continue;
      std::array<uint8_t, Bytes> d{};
      if constexpr (Bytes > 0) std::memcpy(d.data(), data + size_t(k) * Bytes, Bytes);
      uint32_t j = k;
      for (; j > b && ids[j - 1] > v; --j) {
        ids[j] = ids[j - 1];
        if constexpr (Bytes > 0) std::memcpy(data + size_t(j) * Bytes, data + size_t(j - 1) * Bytes, Bytes);
      }
      ids[j] = v;
      if constexpr (Bytes > 0) std::memcpy(data + size_t(j) * Bytes, d.data(), Bytes);
    }
    return;
  }
  if (std::is_sorted(ids + b, ids + e)) return;
  buf.resize(e - b);
  for (uint32_t k = b; k < e; ++k) {
    buf[k - b].id = ids[k];
    if constexpr (Bytes > 0) std::memcpy(buf[k - b].data.data(), data + size_t(k) * Bytes, Bytes);
  }
  std::sort(buf.begin(), buf.end(), [](const Reference<Bytes>& x, const Reference<Bytes>& y) { return x.id < y.id; });
  for (uint32_t k = b; k < e; ++k) {
    ids[k] = buf[k - b].id;
    if constexpr (Bytes > 0) std::memcpy(data + size_t(k) * Bytes, buf[k - b].data.data(), Bytes);
  }
}

/// prims.prefetch(i) where the primitive set offers it (a hint before a random gather).
template <class P, class = void>
struct HasPrefetch : std::false_type {};
template <class P>
struct HasPrefetch<P, std::void_t<decltype(std::declval<const P&>().prefetch(size_t{0}))>> : std::true_type {};
template <class P>
inline void prefetchPrimitive(const P& prims, size_t i) {
  if constexpr (HasPrefetch<P>::value) prims.prefetch(i);
}

/// Per-reference data that is three per-axis parts, each depending on the primitive and the
/// leaf's interval on that axis only: fn.axisKey(leafLo, leafHi) -> double is a value of the
/// interval alone, which the builder computes once per build for every leaf interval of each
/// axis, and fn.axis(uint8_t* out, prim, a, leafLo, key) writes Bytes / 3 bytes from it; the
/// reference's data is the parts of axes 0, 1, 2 in a row. The counting build's scatter then
/// computes each part once per cell and candidate row/column/slab (a few per axis) and copies
/// three parts per reference, instead of calling fn per reference.
template <class F, class P, class = void>
struct HasAxisData : std::false_type {};
template <class F, class P>
struct HasAxisData<F, P,
                   std::void_t<decltype(std::declval<F&>().axisKey(0.0, 0.0)),
                               decltype(std::declval<F&>().axis(std::declval<uint8_t*>(), std::declval<const P&>(), 0,
                                                                0.0, 0.0))>> : std::true_type {};

/// Primitives that give their points (prim.vertices(Vec3* out) -> count, at most 8; 0 when
/// unknown) and a tester from them (prim.tester(half, points, count)): count+mark then takes a
/// candidate leaf that contains a point of the primitive as overlapped without a separating-
/// axis test, and builds no tester when those leaves are all the candidates (see there).
template <class L, class = void>
struct HasVertices : std::false_type {};
template <class L>
struct HasVertices<L, std::void_t<decltype(std::declval<const L&>().vertices(std::declval<Vec3*>())),
                                  decltype(std::declval<const L&>().tester(Vec3(), std::declval<const Vec3*>(), 0))>>
    : std::true_type {};

/// Primitive sets that keep the union of their bounds (prims.totalBounds(), the union of every
/// prims.bounds(i)): the setup takes it as the root box instead of a pass over the primitives.
template <class P, class = void>
struct HasTotalBounds : std::false_type {};
template <class P>
struct HasTotalBounds<P, std::void_t<decltype(std::declval<const P&>().totalBounds())>> : std::true_type {};

/// f(x, y, z) for each set bit b of `mask`, ascending, where b numbers the candidates of the box
/// [lo, lo + (w0, w1, *)) x fastest, then y, then z (w0 x w1 x w2 <= 64). The quotients by w0
/// and w1 are (b * ceil(2^16 / w)) >> 16, exact for b < 64 and w <= 64 (the error stays below
/// 64 / 2^16 < 1 / w). An empty mask (a primitive with an empty box, e.g. a cell without points,
/// whose candidate range is empty: w0 or w1 may then be 0) visits nothing.
template <class F>
inline void forEachBit(uint64_t mask, const int lo[3], int w0, int w1, F&& f) {
  if (!mask) return;
  const uint32_t m0 = (65536u + uint32_t(w0) - 1) / uint32_t(w0), m1 = (65536u + uint32_t(w1) - 1) / uint32_t(w1);
  while (mask) {
    const uint32_t b = static_cast<uint32_t>(__builtin_ctzll(mask));
    mask &= mask - 1;
    const uint32_t row = (b * m0) >> 16, z = (row * m1) >> 16;
    f(lo[0] + int(b - row * uint32_t(w0)), lo[1] + int(row - z * uint32_t(w1)), lo[2] + int(z));
  }
}

/// Two threads over [0, n) from both ends, inside a parallel region: thread 0 takes chunks of
/// kBothEndsChunk primitives from the front and runs body(i) ascending over each, thread 1 takes
/// them from the back and runs body(i) descending, until the chunks meet (`taken` counts the
/// chunks handed out, 0 on entry). Each thread sees one contiguous run of primitives, and a team
/// of one takes every chunk from the front.
constexpr int64_t kBothEndsChunk = 512;
template <class F>
void fromBothEnds(int64_t n, std::atomic<int64_t>& taken, F&& body) {
  const int64_t chunks = (n + kBothEndsChunk - 1) / kBothEndsChunk;
  const bool back = omp_get_thread_num() == 1;
  for (int64_t k = 0; taken.fetch_add(1, std::memory_order_relaxed) < chunks; ++k) {
    const int64_t b = (back ? chunks - 1 - k : k) * kBothEndsChunk, e = std::min(n, b + kBothEndsChunk);
    if (back) {
      for (int64_t i = e - 1; i >= b; --i) body(i);
    } else {
      for (int64_t i = b; i < e; ++i) body(i);
    }
  }
}

struct PhaseClock {
  using clock = std::chrono::steady_clock;
  clock::time_point start = clock::now(), last = start;
  BuildStats* stats;
  explicit PhaseClock(BuildStats* s) : stats(s) {}
  void lap(const char* name) {
    const auto now = clock::now();
    if (stats) stats->phasesMs.emplace_back(name, std::chrono::duration<double, std::milli>(now - last).count());
    last = now;
  }
  void finish() {
    if (stats) stats->totalMs = std::chrono::duration<double, std::milli>(clock::now() - start).count();
  }
};

/// The root box from the primitives' bounds: a flat or point-like scene gets a non-zero extent on
/// every axis, and the box is padded by a relative 1e-9 so that points on the bounding box map
/// inside after round-off. Shared by the CPU and the OpenCL builders (identical trees).
inline Box padRootBox(Box root) {
  const Vec3 e = root.extent();
  const double m = std::max(e.x, std::max(e.y, e.z));
  const double scale = std::max({m, std::fabs(root.lo.x), std::fabs(root.lo.y), std::fabs(root.lo.z),
                                 std::fabs(root.hi.x), std::fabs(root.hi.y), std::fabs(root.hi.z)});
  const double minExt = m > 0 ? m * 1e-6 : (scale > 0 ? scale * 1e-9 : 1e-9);
  for (int a = 0; a < 3; ++a) {
    const double ext = std::max(e[a], minExt);
    const double c = 0.5 * (root.lo[a] + root.hi[a]);
    const double half = 0.5 * ext * (1 + 2e-9) + 4 * std::numeric_limits<double>::epsilon() * std::fabs(c);
    root.lo[a] = c - half;
    root.hi[a] = c + half;
  }
  return root;
}

/// The automatic height (BuildOptions::height == 0) over a padded root box: chooseHeight() from
/// the median primitive extent of a deterministic sample (every (n / 2048)-th primitive: all of
/// them below 2048, else 2048 to 4095; the median's standard error is ~2% of the spread, far
/// below the factor 2 between heights), then one level up at a time while the sampled bounding
/// boxes cover more than opt.maxCandidates leaves on average. `median` receives the median
/// extent. Shared by the CPU and the OpenCL builders.
template <class Prims>
int autoHeight(const Prims& prims, const BuildOptions& opt, const Box& root, double& median) {
  const Vec3 ext = root.extent();
  const int64_t n = static_cast<int64_t>(prims.size());
  const int64_t stride = std::max<int64_t>(1, n / 2048);
  std::vector<double> sizes;
  std::vector<Box> sample;
  sizes.reserve(static_cast<size_t>(n / stride + 1));
  sample.reserve(sizes.capacity());
  for (int64_t i = 0; i < n; i += stride) {
    // Primitives with an empty box (cells without points, VTK_EMPTY_CELL) have neither an extent
    // nor candidate leaves: they stay out of the sample (their -inf extents and negative
    // candidate counts would send the height to its maximum, and the other cells over 10^8 leaves).
    const Box b = prims.bounds(static_cast<size_t>(i));
    if (b.empty()) continue;
    sample.push_back(b);
    const Vec3 e = b.extent();
    sizes.push_back(std::max(e.x, std::max(e.y, e.z)));
  }
  median = 0;
  if (sizes.empty()) return 0;
  std::nth_element(sizes.begin(), sizes.begin() + sizes.size() / 2, sizes.end());
  double med = sizes[sizes.size() / 2];
  if (!(med > 0)) med = std::max(ext.x, std::max(ext.y, ext.z)) * 1e-3;  // degenerate primitives
  median = med;
  int H = chooseHeight(opt.kind, ext, med, opt.leafScale, opt.blockEdge);
  // Mean number of candidate leaves (bounding-box cells) of the sampled primitives at height h.
  auto meanCandidates = [&](int h) {
    const std::array<int, 3> ld = levelShapes(opt.kind, ext, h)[h];
    // Per axis once, not per sample (ldexp and the division were most of this loop).
    double inv[3], top[3];
    for (int a = 0; a < 3; ++a) {
      inv[a] = std::ldexp(1.0, ld[a]) / ext[a];
      top[a] = double((1 << ld[a]) - 1);
    }
    // cellIndexNonNegative(x, 0, top) as a clamp in doubles and a truncation: the same index for
    // every x (NaN and negatives give 0), without a floor call or a branch per bound.
    auto index = [](double x, double hi) { return static_cast<int>(std::min(std::max(0.0, x), hi)); };
    const double o[3] = {root.lo.x, root.lo.y, root.lo.z};
    double sum = 0;
    for (const Box& b : sample) {
      double c = 1;
      const double bl[3] = {b.lo.x, b.lo.y, b.lo.z}, bh[3] = {b.hi.x, b.hi.y, b.hi.z};
      for (int a = 0; a < 3; ++a)
        c *= index((bh[a] - o[a]) * inv[a], top[a]) - index((bl[a] - o[a]) * inv[a], top[a]) + 1;
      sum += c;
    }
    return sum / static_cast<double>(sample.size());
  };
  while (H > 0 && meanCandidates(H) > opt.maxCandidates) --H;
  return H;
}
/// The build's argument checks, shared by the CPU and the OpenCL builders: std::invalid_argument
/// for a height outside [0, MT_MAX_LEVELS), a block edge that is not a power of two in [1, 32],
/// leafScale <= 0 or maxCandidates < 1; std::length_error past 32-bit primitive indices.
inline void checkBuildOptions(const BuildOptions& opt, size_t numPrimitives) {
  if (opt.height < 0 || opt.height >= MT_MAX_LEVELS)
    throw std::invalid_argument("MatrixTree: height must be in [0, " + std::to_string(MT_MAX_LEVELS - 1) +
                                "] (0 = automatic), got " + std::to_string(opt.height));
  if (opt.blockEdge < 1 || opt.blockEdge > 32 || (opt.blockEdge & (opt.blockEdge - 1)))
    throw std::invalid_argument("MatrixTree: block edge must be a power of two in [1, 32], got " +
                                std::to_string(opt.blockEdge));
  if (!(opt.leafScale > 0)) throw std::invalid_argument("MatrixTree: leafScale must be > 0");
  if (!(opt.maxCandidates >= 1)) throw std::invalid_argument("MatrixTree: maxCandidates must be >= 1");
  if (opt.sort != BuildSort::Radix && opt.sort != BuildSort::Counting)
    throw std::invalid_argument("MatrixTree: unknown sort " + std::to_string(static_cast<int>(opt.sort)));
  if (numPrimitives >= MT_NULL) throw std::length_error("MatrixTree: too many primitives for 32-bit indices");
}
}  // namespace detail

/// One build: what the phases share, and one member per phase of the list at the top of this
/// file, in the order build() calls them. Each phase ends with its lap of the phase clock.
template <class Prims>
template <size_t Bytes, class RefFn>
class MatrixTreeBuilder<Prims>::Run {
 public:
  Run(const Prims& prims, const BuildOptions& opt, MatrixTree& tree, BuildStats* stats,
      LargeVector<uint8_t>* refData, RefFn& fn)
      : prims_(prims),
        opt_(opt),
        tree_(tree),
        stats_(stats),
        refData_(refData),
        fn_(fn),
        scratch_(tree.scratch_),
        threads_(resolveThreads(opt.threads)),
        n_(static_cast<int64_t>(prims.size())),
        exact_(opt.overlap == OverlapMode::Exact),
        clock_(stats) {}

  /// Step 1, the one serial step: the root box (the union of the primitives' bounds, padded by
  /// padRootBox), the height (BuildOptions::height, or autoHeight) and every level's shape. The
  /// tree is reset first, keeping its storage and work arrays for their capacity, and stays empty
  /// until finish(): a build that throws leaves an empty tree. False when there is no primitive
  /// (the tree is then complete and empty).
  bool setup() {
    const int64_t n = n_;
    Box root;
    if constexpr (detail::HasTotalBounds<Prims>::value) {
      root = prims_.totalBounds();
    } else {
      std::vector<Box> partial(threads_);
#pragma omp parallel num_threads(lightThreads(n))
      {
        Box b;
#pragma omp for schedule(static)
        for (int64_t i = 0; i < n; ++i) b.extend(prims_.bounds(i));
        partial[omp_get_thread_num()] = b;
      }
      for (const Box& b : partial) root.extend(b);
    }
    if (n > 0 && !(isFinite(root.lo) && isFinite(root.hi)))
      throw std::invalid_argument("MatrixTree: a primitive has non-finite coordinates (NaN or inf)");

    MatrixTree& tree = tree_;
    scratch_.values.swap(tree.prims_);
    tree.prims_.clear();
    tree.root_ = Box{};
    tree.invLeaf_ = Vec3();
    tree.empty_ = true;
    tree.buildWalkCaches(0);  // cleared until the build completes
    tree.kind_ = opt_.kind;
    tree.blockEdge_ = opt_.blockEdge;
    if (stats_) stats_->primitives = static_cast<uint64_t>(n);
    if (n == 0) {
      tree.height_ = 0;
      tree.inner_.clear();
      tree.logDims_.assign(1, {0, 0, 0});
      tree.cellSize_.assign(1, Vec3(1, 1, 1));
      tree.leaves_.reset(1, 1, 1, opt_.blockEdge, MtLeafRange{MT_NULL, MT_NULL});
      clock_.lap("setup");
      clock_.finish();
      return false;
    }
    root = detail::padRootBox(root);
    tree.root_ = root;
    const Vec3 ext = root.extent();

    int H = opt_.height;
    if (H == 0) {
      double med = 0;
      H = detail::autoHeight(prims_, opt_, root, med);
      if (stats_) {
        stats_->autoHeight = true;
        stats_->medianPrimitiveExtent = med;
      }
    }
    H_ = H;
    tree.height_ = H;
    tree.logDims_ = levelShapes(opt_.kind, ext, H);
    {
      // The bottom level's pointer matrix is dense over the root box: refuse heights whose pointer
      // matrix alone would pass 1 GiB rather than exhaust memory.
      const int lb = ceilLog2(static_cast<uint64_t>(opt_.blockEdge));
      int logPtr = 0, logAxis = 0;
      for (int a = 0; a < 3; ++a) {
        logPtr += std::max(0, tree.logDims_[H][a] - lb);
        logAxis = std::max(logAxis, tree.logDims_[H][a]);
      }
      if (logPtr + 2 > 30 || logAxis > 30)  // 4-byte pointers: 2^(logPtr+2) bytes
        throw std::length_error("MatrixTree: height " + std::to_string(H) + " needs a 2^" +
                                std::to_string(logPtr + 2) +
                                "-byte pointer matrix at the leaf level (limit 1 GiB, and at most 2^30 nodes per "
                                "axis); lower the height or raise the block edge");
    }
    tree.cellSize_.resize(H + 1);
    for (int l = 0; l <= H; ++l)
      for (int a = 0; a < 3; ++a) tree.cellSize_[l][a] = std::ldexp(ext[a], -tree.logDims_[l][a]);
    for (int a = 0; a < 3; ++a) tree.invLeaf_[a] = std::ldexp(1.0, tree.logDims_[H][a]) / ext[a];
    LeafGrid& g = grid_;
    for (int a = 0; a < 3; ++a) g.dims[a] = 1 << tree.logDims_[H][a];
    tree.leaves_.reset(g.dims[0], g.dims[1], g.dims[2], opt_.blockEdge, MtLeafRange{MT_NULL, MT_NULL});
    tree.inner_.resize(H);
    g.leafSize = tree.cellSize_[H];
    // Boxes are padded by round-off of the coordinates so the exact test stays conservative.
    const double pad = 64 * std::numeric_limits<double>::epsilon() *
                       std::max({std::fabs(root.lo.x), std::fabs(root.lo.y), std::fabs(root.lo.z),
                                 std::fabs(root.hi.x), std::fabs(root.hi.y), std::fabs(root.hi.z)});
    g.half = Vec3(0.5 * g.leafSize.x + pad, 0.5 * g.leafSize.y + pad, 0.5 * g.leafSize.z + pad);
    g.invLeaf = tree.invLeaf_;
    g.org = root.lo;
    if (stats_) stats_->height = H;
    clock_.lap("setup");
    return true;
  }

  /// Step 2: per primitive, the leaves it overlaps among its candidates (the leaves its bounding
  /// box touches; with OverlapMode::Exact each tested by a separating-axis test) are counted
  /// (counts) and their blocks marked (marks: a byte store of 1 by every writer). The verdicts of
  /// the first 64 candidates are kept as a bit mask (masks), so that the pair writing (step 6)
  /// and the scatter repeat no overlap test for all but the largest primitives.
  ///
  /// Counting builds also count the references per leaf here, where every overlapped leaf is in
  /// hand, instead of enumerating them all again after the allocation: each thread gives a block
  /// a provisional number of its own when it first touches it (blockOrder, per pointer-matrix
  /// entry) and counts its leaves in that numbering (leafCounts), without atomics; countLeaves()
  /// copies (one thread) or adds up each block's counts into its final place. The counts, hence
  /// the tree, are those of a separate pass. Two threads split the primitives into two contiguous
  /// runs (fromBothEnds), so each touches about its own half of the blocks. With more threads
  /// each thread touches most blocks and holds counts for most of the leaf storage: that pays on
  /// small leaf levels (volume grids) but not on surfaces, whose leaf storage is ~10^6 entries;
  /// past 2^21 leaves in the dense level countLeaves() counts in a pass of its own.
  void countMark() {
    MatrixTree& tree = tree_;
    const int64_t n = n_;
    const bool exact = exact_;
    scratch_.counts.resize(static_cast<size_t>(n));
    scratch_.masks.resize(exact ? static_cast<size_t>(n) : 0);
    scratch_.marks.assign(tree.leaves_.pointerCount(), 0);
    countHere_ = opt_.sort == BuildSort::Counting &&
                 (threads_ <= 2 ||
                  uint64_t(tree.leaves_.pointerCount()) * tree.leaves_.blockVolume() <= (uint64_t{1} << 21));
    bothEnds_ = threads_ == 2;
    blockVolume_ = tree.leaves_.blockVolume();
    perThread_.resize(countHere_ ? static_cast<size_t>(threads_) : 0);
    if (countHere_) {
      perThread_[0].blockOrder = &scratch_.tmpKeys;  // thread 0 reuses the tree's work arrays
      perThread_[0].leafCounts = &scratch_.tmpValues;
      for (ThreadCounts& t : perThread_) {
        t.blockOrder->assign(tree.leaves_.pointerCount(), MT_NULL);
        t.leafCounts->clear();
      }
    }
    const BlockSparseMatrix<MtLeafRange>& leaves = tree.leaves_;
    const LeafGrid g = grid_;  // in locals: the block marks are byte stores
    uint32_t* const counts = scratch_.counts.data();
    uint64_t* const masks = scratch_.masks.data();
    uint8_t* const marks = scratch_.marks.data();
    const bool countHere = countHere_;
    const uint32_t blockVolume = blockVolume_;
    auto countOne = [&](int64_t i) {
      const auto prim = prims_.local(i);
      ThreadCounts* tc = countHere ? &perThread_[static_cast<size_t>(omp_get_thread_num())] : nullptr;
      int lo[3], hi[3];
      g.cellRange(prim.bounds(), lo, hi);
      // A candidate range one cell thick along two axes needs no test: the primitive is convex,
      // so it meets every slab of the third axis within its range, inside the one cell of the
      // others.
      const int thin = (lo[0] == hi[0]) + (lo[1] == hi[1]) + (lo[2] == hi[2]);
      const bool test = exact && thin < 2;
      uint32_t c = 0, cand = 0;
      uint64_t mask = 0;
      size_t lastBlock = ~size_t{0};
      uint32_t* blockCounts = nullptr;  // countHere: the counts of block lastBlock
      auto visit = [&](auto&& overlaps) {
        for (int k = lo[2]; k <= hi[2]; ++k)
          for (int j = lo[1]; j <= hi[1]; ++j)
            for (int ii = lo[0]; ii <= hi[0]; ++ii, ++cand) {
              if (!overlaps(ii, j, k, cand)) continue;
              if (cand < 64) mask |= uint64_t{1} << cand;
              ++c;
              const size_t blk = leaves.pointerIndex(ii, j, k);
              if (blk != lastBlock) {
#pragma omp atomic write
                marks[blk] = 1;
                lastBlock = blk;
                if (countHere) {
                  LargeVector<uint32_t>& order = *tc->blockOrder;
                  if (order[blk] == MT_NULL) {
                    order[blk] = tc->touched++;
                    tc->leafCounts->resize(size_t(tc->touched) * blockVolume, 0);
                  }
                  blockCounts = tc->leafCounts->data() + size_t(order[blk]) * blockVolume;
                }
              }
              if (countHere) ++blockCounts[leaves.localIndex(ii, j, k)];
            }
      };
      if (!test) {
        visit([](int, int, int, uint32_t) { return true; });
      } else if constexpr (detail::HasVertices<Local>::value) {
        // A candidate leaf that contains a point of the primitive overlaps it: the leaf's padded
        // box holds the point (its index is computed as the candidate range's, and its round-off
        // is far below the pad), so no separating axis exists and the test would say "overlap"
        // too: the same verdicts, for a few multiplications per point instead of a dot product
        // per axis. When those leaves are every candidate (a hexahedron about one leaf wide over
        // its 2x2x2 leaves), no tester is built at all. Tried only where it can be the case (no
        // more candidates than points).
        const int w0 = hi[0] - lo[0] + 1, w1 = hi[1] - lo[1] + 1;
        const uint64_t numCand = uint64_t(w0) * uint64_t(w1) * uint64_t(hi[2] - lo[2] + 1);
        // Uninitialised (a Vec3 array would be zeroed per cell): vertices() writes what is read.
        union Points {
          Points() {}
          Vec3 at[8];
        } pts;
        Vec3* const v = pts.at;
        const int nv = prim.vertices(v);
        uint64_t known = 0;
        if (numCand <= uint64_t(nv)) {
          for (int q = 0; q < nv; ++q) {
            int cc[3];
            for (int a = 0; a < 3; ++a)
              cc[a] = std::min(
                  std::max(cellIndexNonNegative((v[q][a] - g.org[a]) * g.invLeaf[a], 0, g.dims[a] - 1), lo[a]),
                  hi[a]);
            known |= uint64_t{1} << (((cc[2] - lo[2]) * w1 + (cc[1] - lo[1])) * w0 + (cc[0] - lo[0]));
          }
        }
        const uint64_t all = numCand >= 64 ? ~uint64_t{0} : (uint64_t{1} << numCand) - 1;
        if (numCand <= uint64_t(nv) && known == all) {
          visit([](int, int, int, uint32_t) { return true; });
        } else {
          const auto tester = prim.tester(g.half, v, nv);
          visit([&](int x, int y, int z, uint32_t cd) {
            return (cd < 64 && ((known >> cd) & 1)) || tester.overlaps(g.cellCentre(x, y, z));
          });
        }
      } else {
        // The separating-axis tester is built only for primitives that need it.
        const auto tester = prim.tester(g.half);
        visit([&](int x, int y, int z, uint32_t) { return tester.overlaps(g.cellCentre(x, y, z)); });
      }
      counts[i] = c;
      if (exact) masks[i] = mask;
    };
    if (bothEnds_) {
      std::atomic<int64_t> taken{0};
#pragma omp parallel num_threads(2)
      detail::fromBothEnds(n, taken, countOne);
    } else {
#pragma omp parallel for num_threads(threads_) schedule(dynamic, 512)
      for (int64_t i = 0; i < n; ++i) countOne(i);
    }
    clock_.lap("count+mark");
  }

  /// Steps 3-4: the exclusive scan of the block marks numbers the marked blocks; their pointers
  /// are set and the blocks allocated (BlockSparseMatrix::allocateMarked).
  void allocateBlocks() {
    tree_.leaves_.allocateMarked(scratch_.marks.data(), lightThreads(int64_t(scratch_.marks.size())));
    clock_.lap("alloc");
  }

  /// Step 5 (BuildSort::Radix): the exclusive scan of the per-primitive counts gives each
  /// primitive the offset of its first pair.
  void scanCounts() {
    scratch_.offsets.resize(static_cast<size_t>(n_));
    numPairs_ = exclusiveScan(scratch_.counts.data(), scratch_.offsets.data(), static_cast<size_t>(n_), threads_);
    checkPairCount();
    clock_.lap("scan");
  }

  /// Step 6: each primitive writes its (leaf storage index, primitive) pairs from its scanned
  /// offset on, in the order of step 2 (no atomics).
  void writePairs() {
    LargeVector<uint32_t>& keys = scratch_.keys;
    LargeVector<uint32_t>& values = scratch_.values;
    keys.resize(numPairs_);
    values.resize(numPairs_);
    const BlockSparseMatrix<MtLeafRange>& leaves = tree_.leaves_;
    const uint32_t* const offsets = scratch_.offsets.data();
    const int64_t n = n_;
#pragma omp parallel for num_threads(threads_) schedule(dynamic, 512)
    for (int64_t i = 0; i < n; ++i) {
      uint32_t out = offsets[i];
      forEachLeaf(i, prims_.local(i), [&](int x, int y, int z) {
        keys[out] = leaves.storageIndex(x, y, z);
        values[out] = static_cast<uint32_t>(i);
        ++out;
      });
    }
    clock_.lap("pairs");
  }

  /// Step 7: stable radix sort of the pairs by leaf (the primitives of a leaf stay ascending).
  void sortPairs() {
    const uint64_t maxKey = uint64_t(tree_.leaves_.numBlocks()) * tree_.leaves_.blockVolume();
    radixSortPairs(scratch_.keys, scratch_.values, ceilLog2(std::max<uint64_t>(maxKey, 2)), threads_,
                   scratch_.tmpKeys, scratch_.tmpValues);
    clock_.lap("sort");
  }

  /// Step 8: a leaf's range begins where its key differs from the previous one in the sorted
  /// array and ends where the next leaf's begins; leaves with no pair keep begin = MT_NULL.
  void leafRanges() {
    MtLeafRange* data = tree_.leaves_.data().data();
    const uint32_t* const keys = scratch_.keys.data();
    const int64_t m = static_cast<int64_t>(numPairs_);
    uint64_t leafCount = 0;
#pragma omp parallel for num_threads(threads_) schedule(static) reduction(+ : leafCount)
    for (int64_t i = 0; i < m; ++i) {
      if (i == 0 || keys[i] != keys[i - 1]) {
        ++leafCount;
        data[keys[i]].begin = static_cast<uint32_t>(i);
        if (i > 0) data[keys[i - 1]].end = static_cast<uint32_t>(i);
      }
    }
    if (m > 0) data[keys[m - 1]].end = static_cast<uint32_t>(m);
    if (stats_) stats_->leaves = leafCount;
    clock_.lap("offsets");
  }

  /// BuildSort::Radix with per-reference data: a pass over the leaves, fetching each reference's
  /// primitive again (the primitives of a leaf are scattered over the input: fetched ahead).
  void referenceData() {
    refData_->resize(static_cast<size_t>(numPairs_) * Bytes);
    uint8_t* out = refData_->data();
    const MtLeafRange* data = tree_.leaves_.data().data();
    const uint32_t* const values = scratch_.values.data();
    const int64_t ne = static_cast<int64_t>(tree_.leaves_.data().size());
    const int H = H_;
#pragma omp parallel num_threads(threads_)
    {
      auto f = fn_;  // one copy per thread
#pragma omp for schedule(dynamic, 256)
      for (int64_t e = 0; e < ne; ++e) {
        const MtLeafRange r = data[e];
        if (r.begin == MT_NULL) continue;
        int c[3];
        tree_.leaves_.entryCoords(static_cast<uint32_t>(e), c);
        const Box lb = tree_.nodeBox(H, c);
        for (uint32_t k = r.begin; k < r.end; ++k) {
          if (k + 16 < r.end) detail::prefetchPrimitive(prims_, values[k + 16]);
          f(out + size_t(k) * Bytes, prims_.local(values[k]), lb);
        }
      }
    }
    clock_.lap("refdata");
  }

  /// BuildSort::Counting: after the allocation every leaf has a fixed storage index in
  /// [0, blocks x B^3), so the references per leaf are counted into the leaf storage: from
  /// count+mark's per-thread counts (each allocated block was touched by some thread; one
  /// thread's counts are copied, several threads' added), or by a pass of atomic increments.
  void countLeaves() {
    MatrixTree& tree = tree_;
    const size_t L = tree.leaves_.data().size();
    const int64_t nl = static_cast<int64_t>(L);
    LargeVector<uint32_t>& perLeaf = scratch_.keys;  // references per leaf
    scratch_.offsets.resize(L);                       // scanLeaves(): the next free slot per leaf
    const int threads = threads_;
    if (countHere_) {
      const std::vector<uint32_t>& ptr = tree.leaves_.pointers();
      const int64_t np = static_cast<int64_t>(ptr.size());
      if (threads == 1) {
        perLeaf.resize(L);
      } else {
        perLeaf.assign(L, 0);
      }
      const uint32_t blockVolume = blockVolume_;
#pragma omp parallel for num_threads(lightThreads(nl)) schedule(static) if (threads > 1)
      for (int64_t p = 0; p < np; ++p) {
        if (ptr[p] == MT_NULL) continue;
        uint32_t* dst = perLeaf.data() + size_t(ptr[p]) * blockVolume;
        for (const ThreadCounts& t : perThread_) {
          const uint32_t b = (*t.blockOrder)[p];
          if (b == MT_NULL) continue;
          const uint32_t* src = t.leafCounts->data() + size_t(b) * blockVolume;
          if (threads == 1) {
            std::memcpy(dst, src, blockVolume * sizeof(uint32_t));
          } else {
            for (uint32_t q = 0; q < blockVolume; ++q) dst[q] += src[q];
          }
        }
      }
    } else {
      perLeaf.assign(L, 0);
      const BlockSparseMatrix<MtLeafRange>& leaves = tree.leaves_;
      const int64_t n = n_;
#pragma omp parallel for num_threads(threads) schedule(dynamic, 512)
      for (int64_t i = 0; i < n; ++i) {
        forEachLeaf(i, prims_.local(i), [&](int x, int y, int z) {
          uint32_t& c = perLeaf[leaves.storageIndex(x, y, z)];
#pragma omp atomic update
          ++c;
        });
      }
    }
    clock_.lap("leaf counts");
  }

  /// BuildSort::Counting: the exclusive scan over the leaf storage gives each leaf its range;
  /// the scan is the first free slot of each leaf (its cursor). With two threads, thread 1 fills
  /// each leaf from its end: its cursor, kept in the counts, becomes the slot above its next one.
  void scanLeaves() {
    LargeVector<uint32_t>& perLeaf = scratch_.keys;
    LargeVector<uint32_t>& cursor = scratch_.offsets;
    const size_t L = tree_.leaves_.data().size();
    const int64_t nl = static_cast<int64_t>(L);
    numPairs_ = exclusiveScan(perLeaf.data(), cursor.data(), L, lightThreads(nl));
    checkPairCount();
    MtLeafRange* data = tree_.leaves_.data().data();
    const bool bothEnds = bothEnds_;
    uint64_t leafCount = 0;
#pragma omp parallel for num_threads(lightThreads(nl)) schedule(static) reduction(+ : leafCount)
    for (int64_t e = 0; e < nl; ++e) {
      if (perLeaf[e] == 0) continue;
      ++leafCount;
      data[e] = MtLeafRange{cursor[e], cursor[e] + perLeaf[e]};
      if (bothEnds) perLeaf[e] = data[e].end;
    }
    if (stats_) stats_->leaves = leafCount;
    clock_.lap("leaf scan");
  }

  /// BuildSort::Counting: each reference takes the next slot of its leaf; the primitive is in
  /// hand, so its per-reference data is written here too, next to its id. One thread takes the
  /// primitives in ascending order; two take them from both ends (fromBothEnds), thread 0 filling
  /// each leaf from its start with ascending ids and thread 1 from its end with descending ones,
  /// plain stores that meet where the leaf is full, in ascending order again; more threads take
  /// shared (atomic) cursors and orderLeaves() sorts each leaf afterwards.
  void scatter() {
    const bool shared = threads_ > 2;
    const bool bothEnds = bothEnds_;
    LargeVector<uint32_t>& perLeaf = scratch_.keys;
    LargeVector<uint32_t>& cursor = scratch_.offsets;
    LargeVector<uint32_t>& values = scratch_.values;
    values.resize(numPairs_);
    uint8_t* out = nullptr;
    if constexpr (Bytes > 0) {
      refData_->resize(static_cast<size_t>(numPairs_) * Bytes);
      out = refData_->data();
    }
    constexpr bool byAxis = Bytes > 0 && Bytes % 3 == 0 && detail::HasAxisData<std::decay_t<RefFn>, Local>::value;
    constexpr size_t axisBytes = Bytes / 3;
    // Per-axis parts of a cell's candidate range, kept for ranges up to this many leaves per axis.
    constexpr int kAxisTable = 32;
    // The leaf grid in locals: the per-reference data is written through byte pointers, after
    // which members would be reloaded.
    const LeafGrid g = grid_;
    const BlockSparseMatrix<MtLeafRange>& leaves = tree_.leaves_;
    // Every leaf interval's lower end and key, per axis (fn.axisKey once per interval and build,
    // not once per cell and interval: it divides), up to 2^16 intervals per axis.
    std::vector<double> intervalLo[3], intervalKey[3];
    [[maybe_unused]] bool keyed = false;
    if constexpr (byAxis) {
      keyed = g.dims[0] <= 65536 && g.dims[1] <= 65536 && g.dims[2] <= 65536;
      for (int a = 0; keyed && a < 3; ++a) {
        intervalLo[a].resize(size_t(g.dims[a]));
        intervalKey[a].resize(size_t(g.dims[a]));
        for (int c = 0; c < g.dims[a]; ++c) {
          // LeafGrid::leafBox's arithmetic: org + c * size to org + (c + 1) * size.
          const double lo = g.org[a] + c * g.leafSize[a], hi = g.org[a] + (c + 1) * g.leafSize[a];
          intervalLo[a][size_t(c)] = lo;
          intervalKey[a][size_t(c)] = fn_.axisKey(lo, hi);
        }
      }
    }
    const int64_t n = n_;
    std::atomic<int64_t> taken{0};  // fromBothEnds' chunks
#pragma omp parallel num_threads(threads_)
    {
      auto f = fn_;  // one copy per thread
      uint8_t table[3][kAxisTable][byAxis ? axisBytes : 1];
      const bool fromEnd = bothEnds && omp_get_thread_num() == 1;
      auto scatterOne = [&](int64_t i) {
        const auto prim = prims_.local(i);
        auto takeSlot = [&](int x, int y, int z) {
          const uint32_t e = leaves.storageIndex(x, y, z);
          uint32_t slot;
          if (shared) {
            uint32_t& c = cursor[e];
#pragma omp atomic capture
            slot = c++;
          } else if (fromEnd) {
            slot = --perLeaf[e];
          } else {
            slot = cursor[e]++;
          }
          values[slot] = static_cast<uint32_t>(i);
          return slot;
        };
        if constexpr (byAxis) {
          int lo[3], hi[3];
          g.cellRange(prim.bounds(), lo, hi);
          if (hi[0] - lo[0] < kAxisTable && hi[1] - lo[1] < kAxisTable && hi[2] - lo[2] < kAxisTable) {
            for (int a = 0; a < 3; ++a)
              for (int c = lo[a]; c <= hi[a]; ++c) {
                if (keyed) {
                  f.axis(table[a][c - lo[a]], prim, a, intervalLo[a][size_t(c)], intervalKey[a][size_t(c)]);
                } else {
                  const double l = g.org[a] + c * g.leafSize[a], h = g.org[a] + (c + 1) * g.leafSize[a];
                  f.axis(table[a][c - lo[a]], prim, a, l, f.axisKey(l, h));
                }
              }
            forEachLeafIn(i, prim, lo, hi, [&](int x, int y, int z) {
              uint8_t* o = out + size_t(takeSlot(x, y, z)) * Bytes;
              std::memcpy(o, table[0][x - lo[0]], axisBytes);
              std::memcpy(o + axisBytes, table[1][y - lo[1]], axisBytes);
              std::memcpy(o + 2 * axisBytes, table[2][z - lo[2]], axisBytes);
            });
            return;
          }
        }
        forEachLeaf(i, prim, [&](int x, int y, int z) {
          const uint32_t slot = takeSlot(x, y, z);
          if constexpr (Bytes > 0) f(out + size_t(slot) * Bytes, prim, g.leafBox(x, y, z));
        });
      };
      if (bothEnds) {
        detail::fromBothEnds(n, taken, scatterOne);
      } else {
#pragma omp for schedule(dynamic, 512)
        for (int64_t i = 0; i < n; ++i) scatterOne(i);
      }
    }
    clock_.lap("scatter");
  }

  /// BuildSort::Counting with more than two threads: a leaf's slots were taken in any order, so
  /// each leaf's (distinct) ids are sorted back to ascending, the radix sort's stable order,
  /// their per-reference data along with them.
  void orderLeaves() {
    if (threads_ <= 2) return;
    const MtLeafRange* data = tree_.leaves_.data().data();
    const int64_t nl = static_cast<int64_t>(tree_.leaves_.data().size());
    uint32_t* const values = scratch_.values.data();
    uint8_t* payload = Bytes > 0 ? refData_->data() : nullptr;
#pragma omp parallel num_threads(threads_)
    {
      std::vector<detail::Reference<Bytes>> buf;
#pragma omp for schedule(dynamic, 1024)
      for (int64_t e = 0; e < nl; ++e) {
        const MtLeafRange r = data[e];
        if (r.begin != MT_NULL && r.end - r.begin > 1) detail::sortLeaf<Bytes>(values, payload, r.begin, r.end, buf);
      }
    }
    clock_.lap("leaf order");
  }

  /// The sorted pairs' primitive half is the tree's primitive list (§5.1: "The triangle portion
  /// can be directly copied"); the tree's previous list becomes the work array.
  void keepPrimitiveList() { tree_.prims_.swap(scratch_.values); }

  /// Step 9: existence up to the root, level by level: each allocated child block marks the one
  /// parent block it maps into (scan and allocation as in steps 3-4), then every existing child
  /// entry sets its parent's existence byte (a byte store of 1 by every writer: the result does
  /// not depend on their order). Only allocated child entries are read, contiguously.
  void propagate() {
    MatrixTree& tree = tree_;
    const int H = H_;
    for (int l = H - 1; l >= 0; --l) {
      const auto& pl = tree.logDims_[l];
      const auto& cl = tree.logDims_[l + 1];
      const int sh[3] = {cl[0] - pl[0], cl[1] - pl[1], cl[2] - pl[2]};
      BlockSparseMatrix<uint8_t>& parent = tree.inner_[l];
      parent.reset(1 << pl[0], 1 << pl[1], 1 << pl[2], opt_.blockEdge, 0);
      const MtSparseDesc& cd = (l + 1 == H) ? tree.leaves_.desc() : tree.inner_[l + 1].desc();
      const std::vector<uint32_t>& cptr = (l + 1 == H) ? tree.leaves_.pointers() : tree.inner_[l + 1].pointers();
      std::vector<uint8_t> pmarks(parent.pointerCount(), 0);
      const int64_t ncp = static_cast<int64_t>(cptr.size());
#pragma omp parallel for num_threads(lightThreads(ncp)) schedule(static)
      for (int64_t p = 0; p < ncp; ++p) {
        if (cptr[p] == MT_NULL) continue;
        const int bx = static_cast<int>(p % cd.ptrDims[0]);
        const int by = static_cast<int>((p / cd.ptrDims[0]) % cd.ptrDims[1]);
        const int bz = static_cast<int>(p / (int64_t(cd.ptrDims[0]) * cd.ptrDims[1]));
        const int i = (bx << cd.logBlock[0]) >> sh[0], j = (by << cd.logBlock[1]) >> sh[1],
                  k = (bz << cd.logBlock[2]) >> sh[2];
#pragma omp atomic write
        pmarks[parent.pointerIndex(i, j, k)] = 1;
      }
      parent.allocateMarked(pmarks.data(), lightThreads(int64_t(pmarks.size())));
      // Block by block: a block's first entry gives its origin (entryCoords' divisions once per
      // block, not per entry: a surface's leaf level has ~10^6 entries), its entries' coordinates
      // are the origin plus the bits of the local index.
      uint8_t* pdata = parent.data().data();
      const int64_t ncb = int64_t(l + 1 == H ? tree.leaves_.numBlocks() : tree.inner_[l + 1].numBlocks());
      const uint32_t cbv = cd.blockVolume;
      const int lbx = cd.logBlock[0], lby = cd.logBlock[1];
      const uint32_t mx = (1u << lbx) - 1, my = (1u << lby) - 1;
      const MtLeafRange* leafData = tree.leaves_.data().data();
      const uint8_t* innerData = l + 1 == H ? nullptr : tree.inner_[l + 1].data().data();
#pragma omp parallel for num_threads(lightThreads(ncb * cbv)) schedule(static)
      for (int64_t b = 0; b < ncb; ++b) {
        int o[3];
        const uint32_t first = static_cast<uint32_t>(b) * cbv;
        if (innerData) tree.inner_[l + 1].entryCoords(first, o);
        else tree.leaves_.entryCoords(first, o);
        for (uint32_t q = 0; q < cbv; ++q) {
          const bool exists = innerData ? innerData[first + q] != 0 : leafData[first + q].begin != MT_NULL;
          if (!exists) continue;
          const int c[3] = {o[0] | int(q & mx), o[1] | int((q >> lbx) & my), o[2] | int(q >> (lbx + lby))};
          const uint32_t s = parent.storageIndex(c[0] >> sh[0], c[1] >> sh[1], c[2] >> sh[2]);
#pragma omp atomic write
          pdata[s] = 1;
        }
      }
    }
    tree.empty_ = false;
    clock_.lap("propagate");
  }

  /// The ray walk's caches (MatrixTree::buildWalkCaches), then the totals.
  void finish() {
    tree_.buildWalkCaches(lightThreads(int64_t(tree_.leaves_.data().size())));
    clock_.lap("walk caches");
    if (stats_) stats_->references = numPairs_;
    clock_.finish();
  }

 private:
  using Local = std::decay_t<decltype(std::declval<const Prims&>().local(int64_t{0}))>;

  /// The leaf level's grid as the passes over the primitives compute with it: origin (the root
  /// box's lo), 1 / leaf size (MatrixTree::invLeaf_), leaf size, the padded half size of a
  /// candidate leaf, and the leaves per axis.
  struct LeafGrid {
    Vec3 org, invLeaf, leafSize, half;
    int dims[3] = {1, 1, 1};
    /// The candidate leaves of a box (clamped): the floor of the local coordinate by
    /// cellIndexNonNegative (negatives and NaN clamp to 0), without a floor call per coordinate.
    void cellRange(const Box& b, int lo[3], int hi[3]) const {
      for (int a = 0; a < 3; ++a) {
        lo[a] = cellIndexNonNegative((b.lo[a] - org[a]) * invLeaf[a], 0, dims[a] - 1);
        hi[a] = cellIndexNonNegative((b.hi[a] - org[a]) * invLeaf[a], 0, dims[a] - 1);
      }
    }
    /// Candidate leaves are tested as boxes of one padded half size, given by their centres.
    Vec3 cellCentre(int i, int j, int k) const {
      return Vec3(org.x + (i + 0.5) * leafSize.x, org.y + (j + 0.5) * leafSize.y, org.z + (k + 0.5) * leafSize.z);
    }
    /// MatrixTree::nodeBox(H, {i, j, k}), the same arithmetic.
    Box leafBox(int i, int j, int k) const {
      Box b;
      const int c[3] = {i, j, k};
      for (int a = 0; a < 3; ++a) {
        b.lo[a] = org[a] + c[a] * leafSize[a];
        b.hi[a] = org[a] + (c[a] + 1) * leafSize[a];
      }
      return b;
    }
  };

  /// A thread's counts of count+mark for the counting sort (see countMark()).
  struct ThreadCounts {
    LargeVector<uint32_t> ownOrder, ownCounts;
    LargeVector<uint32_t>* blockOrder = &ownOrder;
    LargeVector<uint32_t>* leafCounts = &ownCounts;
    uint32_t touched = 0;
  };

  /// Threads for a light pass over m items (see kSerialBelow).
  int lightThreads(int64_t m) const { return m >= kSerialBelow ? threads_ : 1; }

  void checkPairCount() const {
    if (numPairs_ >= MT_NULL)
      throw std::length_error("MatrixTree: more than 2^32 (leaf, primitive) pairs; lower the height");
  }

  /// The overlapped leaves of primitive i (local data `prim`) in its candidate range [lo, hi],
  /// in the order of count+mark: f(x, y, z) per leaf, from the primitive's bit mask, by the same
  /// decision rule; beyond the 64 masked candidates the test is repeated (only for the largest
  /// primitives). Up to 64 candidates, the mask's set bits are walked (forEachBit) instead of
  /// every candidate with a branch on its bit.
  template <class P, class F>
  void forEachLeafIn(int64_t i, const P& prim, const int lo[3], const int hi[3], F&& f) const {
    if (!exact_) {
      // Bounding-box overlap: every candidate, x fastest (the mask's bit order).
      for (int z = lo[2]; z <= hi[2]; ++z)
        for (int y = lo[1]; y <= hi[1]; ++y)
          for (int x = lo[0]; x <= hi[0]; ++x) f(x, y, z);
      return;
    }
    const int w0 = hi[0] - lo[0] + 1, w1 = hi[1] - lo[1] + 1;
    const uint64_t numCand = uint64_t(w0) * uint64_t(w1) * uint64_t(hi[2] - lo[2] + 1);
    const uint64_t mask = scratch_.masks[i];
    if (numCand <= 64) {
      detail::forEachBit(numCand == 64 ? mask : mask & ((uint64_t{1} << numCand) - 1), lo, w0, w1, f);
      return;
    }
    // More than 64 candidates: the ones beyond the mask are tested again if count+mark tested them.
    uint32_t cand = 0;
    const int thin = (lo[0] == hi[0]) + (lo[1] == hi[1]) + (lo[2] == hi[2]);
    const bool test = thin < 2;
    auto emit = [&](auto&& beyondMask) {
      for (int k = lo[2]; k <= hi[2]; ++k)
        for (int j = lo[1]; j <= hi[1]; ++j)
          for (int ii = lo[0]; ii <= hi[0]; ++ii, ++cand) {
            const bool in = cand < 64 ? ((mask >> cand) & 1) != 0 : beyondMask(ii, j, k);
            if (in) f(ii, j, k);
          }
    };
    if (test) {
      const auto tester = prim.tester(grid_.half);
      emit([&](int x, int y, int z) { return tester.overlaps(grid_.cellCentre(x, y, z)); });
    } else {
      emit([](int, int, int) { return true; });
    }
  }
  /// forEachLeafIn over the primitive's own candidate range.
  template <class P, class F>
  void forEachLeaf(int64_t i, const P& prim, F&& f) const {
    int lo[3], hi[3];
    grid_.cellRange(prim.bounds(), lo, hi);
    forEachLeafIn(i, prim, lo, hi, f);
  }

  const Prims& prims_;
  const BuildOptions& opt_;
  MatrixTree& tree_;
  BuildStats* stats_;
  LargeVector<uint8_t>* refData_;
  RefFn& fn_;
  MatrixTree::BuildScratch& scratch_;
  const int threads_;
  const int64_t n_;
  const bool exact_;
  detail::PhaseClock clock_;
  int H_ = 0;
  LeafGrid grid_;
  bool countHere_ = false;  // BuildSort::Counting: count+mark counts the references per leaf
  bool bothEnds_ = false;   // two threads: the primitives from both ends (fromBothEnds)
  uint32_t blockVolume_ = 0;
  std::vector<ThreadCounts> perThread_;
  uint64_t numPairs_ = 0;
};

template <class Prims>
template <size_t Bytes, class RefFn>
void MatrixTreeBuilder<Prims>::build(const Prims& prims, const BuildOptions& opt, MatrixTree& tree,
                                     BuildStats* stats, LargeVector<uint8_t>* refData, RefFn&& fn) {
  detail::checkBuildOptions(opt, prims.size());
  if constexpr (Bytes > 0) {
    if (!refData) throw std::invalid_argument("MatrixTree: per-reference data needs an output vector");
    refData->clear();
  }
  if (stats) *stats = BuildStats{};
  Run<Bytes, std::remove_reference_t<RefFn>> run(prims, opt, tree, stats, refData, fn);
  if (!run.setup()) return;  // no primitive: the tree is empty
  run.countMark();
  run.allocateBlocks();
  if (opt.sort == BuildSort::Radix) {
    run.scanCounts();
    run.writePairs();
    run.sortPairs();
    run.leafRanges();
    if constexpr (Bytes > 0) run.referenceData();
  } else {
    run.countLeaves();
    run.scanLeaves();
    run.scatter();
    run.orderLeaves();
  }
  run.keepPrimitiveList();
  run.propagate();
  run.finish();
}

}  // namespace mtree

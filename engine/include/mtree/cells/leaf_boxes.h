// Quantized leaf boxes: per reference (leaf, cell) of a locator's tree, 6 bytes (xlo xhi ylo yhi
// zlo zhi) that bound the part of the cell inside the leaf in 1/255 steps of the leaf's extent.
// The queries scan a leaf's boxes in order (sequential bytes, in the order of the leaf's cell
// ids) before they read any cell: point location keeps the cells whose box holds the point,
// the ray queries those whose box the segment crosses (leaf_segment_filter.h).
//
// Invariant (no false rejection): a box is rounded outwards from the cell's padded bounds, and a
// query point is mapped with the same monotone expression, (x - leaf.lo) * leafBoxScale(leaf),
// so a point inside the padded bounds always lies within its cell's box: a rejection is final,
// a pass is only a candidate for the exact test.
//
// Encoding: quantizeLeafBox / LeafBoxQuantizer (the builder's per-reference data, build<6>).
// Decoding: quantizePoint gives a point's byte range; LeafBoxTest tests boxes against a byte
// range, eight at a time with SSE2.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "mtree/cells/cells.h"
#include "mtree/core/geometry.h"

namespace mtree {

/// The point-location pre-test box of a cell in a leaf, 6 bytes (xlo xhi ylo yhi zlo zhi): the
/// cell's cached bounds `cell` (CellSet::bounds), padded by 1e-3 of their largest extent (VTK's
/// EvaluatePosition accepts points a little outside), clipped to the leaf box `leaf` and
/// quantized outwards to 1/255 of the leaf. A point is mapped with the same arithmetic,
/// (x - leaf.lo) * (255 / (leaf.hi - leaf.lo)), which is monotone, so a point inside the padded
/// bounds is never rejected. Empty cells (NaN or inverted arithmetic) keep the full range.
namespace detail {
/// The padding of the point-location box: 1e-3 of the bounds' largest extent.
inline double leafBoxPad(const Box& cell) {
  const Vec3 e = cell.hi - cell.lo;
  return 1e-3 * std::max({e.x, e.y, e.z});
}
/// The quantization scale of a leaf's interval [lo, hi] on one axis, 255 / (hi - lo): one
/// expression for the cells' boxes (build) and the query points (FindCell), whose bytes are
/// compared, so they must round alike. (opencl/query_cells.cl repeats it on the device.)
inline double leafBoxScale(double lo, double hi) { return 255.0 / (hi - lo); }
/// One axis of quantizeLeafBox: [lo, hi] padded by `pad`, relative to `leafLo`, times `scale`
/// (255 / leaf width), rounded outwards and clamped to [0, 255].
inline void quantizeLeafAxis(double lo, double hi, double pad, double leafLo, double scale, uint8_t q[2]) {
  const double vlo = (lo - pad - leafLo) * scale;
  const double vhi = (hi + pad - leafLo) * scale;
  if (vlo <= vhi) {
    // Not NaN, and floor(vlo) <= ceil(vhi). Clamping to [0, 255] commutes with floor and ceil,
    // and on [0, 255] truncation is floor: no branch on where the cell lies in the leaf (those
    // are coin flips, and mispredicted branches were most of the cost).
    const double l = std::min(std::max(vlo, 0.0), 255.0), h = std::min(std::max(vhi, 0.0), 255.0);
    const int ih = static_cast<int>(h);
    q[0] = static_cast<uint8_t>(static_cast<int>(l));
    q[1] = static_cast<uint8_t>(ih + (static_cast<double>(ih) < h));
    return;
  }
  const double fl = std::floor(vlo), ch = std::ceil(vhi);
  q[0] = static_cast<uint8_t>(fl > 0 ? (fl < 255 ? fl : 255) : 0);
  q[1] = static_cast<uint8_t>(ch < 255 ? (ch > 0 ? ch : 0) : 255);
  if (!(fl <= ch)) {
    q[0] = 0;
    q[1] = 255;
  }
}
}  // namespace detail

inline void quantizeLeafBox(const Box& cell, const Box& leaf, uint8_t q[6]) {
  const double pad = detail::leafBoxPad(cell);
  for (int a = 0; a < 3; ++a)
    detail::quantizeLeafAxis(cell.lo[a], cell.hi[a], pad, leaf.lo[a], detail::leafBoxScale(leaf.lo[a], leaf.hi[a]),
                             q + 2 * a);
}

/// quantizeLeafBox as the builder's per-reference function (MatrixTreeBuilder::build<6>): the
/// same bytes, computed once per cell and leaf column. Each axis's two bytes depend on the cell
/// and the leaf's interval on that axis only, and the builder's scatter gives all references
/// of a cell in a row, so they are kept per axis for the current cell (a cell overlaps a few
/// leaves per axis); and the leaves of a level have a handful of distinct widths per axis
/// (round-off of root.lo + c * size), so the last width's 255 / width is kept too. Each build
/// thread has its own copy.
struct LeafBoxQuantizer {
  static constexpr int kSlots = 8;
  const CellSet* set = nullptr;
  size_t cell = ~size_t{0};
  double pad = 0;
  double width[3] = {0, 0, 0}, scale[3] = {0, 0, 0};
  double keyLo[3][kSlots], keyHi[3][kSlots];
  uint8_t bytes[3][kSlots][2];
  int used[3] = {0, 0, 0};

  /// The leaf interval [lo, hi]'s key for axis(): its scale, 255 / (hi - lo), as operator()
  /// computes it. The builder computes it once per interval and build.
  static double axisKey(double lo, double hi) { return detail::leafBoxScale(lo, hi); }
  /// One axis's two bytes (q[0], q[1]) for the leaf interval starting at lo on axis a, with
  /// scale = axisKey(lo, hi): the builder's counting scatter calls this once per cell and
  /// candidate leaf row/column/slab and copies the three axes' bytes to each reference (see
  /// detail::HasAxisData); the same bytes as operator().
  void axis(uint8_t* q, const CellSet::Local& c, int a, double lo, double scale) {
    startCell(c);
    detail::quantizeLeafAxis(c.box.lo[a], c.box.hi[a], pad, lo, scale, q);
  }

  void operator()(uint8_t* q, const CellSet::Local& c, const Box& leaf) {
    startCell(c);
    for (int a = 0; a < 3; ++a) {
      const double lo = leaf.lo[a], hi = leaf.hi[a];
      int s = 0;
      while (s < used[a] && !(keyLo[a][s] == lo && keyHi[a][s] == hi)) ++s;
      if (s == used[a]) {
        const double w = hi - lo;
        if (w != width[a]) {
          width[a] = w;
          scale[a] = detail::leafBoxScale(lo, hi);
        }
        uint8_t b[2];
        detail::quantizeLeafAxis(c.box.lo[a], c.box.hi[a], pad, lo, scale[a], b);
        q[2 * a] = b[0];
        q[2 * a + 1] = b[1];
        if (s < kSlots) {
          keyLo[a][s] = lo;
          keyHi[a][s] = hi;
          bytes[a][s][0] = b[0];
          bytes[a][s][1] = b[1];
          ++used[a];
        }
        continue;
      }
      q[2 * a] = bytes[a][s][0];
      q[2 * a + 1] = bytes[a][s][1];
    }
  }

 private:
  void startCell(const CellSet::Local& c) {
    if (c.cell != cell || c.set != set) {
      set = c.set;
      cell = c.cell;
      pad = detail::leafBoxPad(c.box);
      used[0] = used[1] = used[2] = 0;
    }
  }
};


/// A point's byte range in the leaf box `leaf`: q = (x - leaf.lo) * leafBoxScale per axis,
/// clamped to [0, 255] (round-off of the leaf search may put x a hair outside its leaf, where only
/// clipped boxes reach); qmax = floor(q), qmin = ceil(q). A box [lo, hi] holds q exactly when
/// lo <= qmax and hi >= qmin (lo, hi integers), the test LeafBoxTest makes.
inline void quantizePoint(const double x[3], const Box& leaf, uint8_t qmax[3], uint8_t qmin[3]) {
  for (int a = 0; a < 3; ++a) {
    const double q =
        std::min(255.0, std::max(0.0, (x[a] - leaf.lo[a]) * detail::leafBoxScale(leaf.lo[a], leaf.hi[a])));
    const int fl = static_cast<int>(q);  // floor: q >= 0
    qmax[a] = static_cast<uint8_t>(fl);
    qmin[a] = static_cast<uint8_t>(fl + (fl < q ? 1 : 0));
  }
}

/// Quantized boxes (6 bytes each, xlo xhi ylo yhi zlo zhi) against a byte range [qmin, qmax] per
/// axis: a box passes when lo <= qmax and hi >= qmin on every axis. Point location asks with a
/// point's range (quantizePoint: the box holds the point); the ray queries with the range of the
/// segment's part in the leaf.
class LeafBoxTest {
 public:
  /// n: how many boxes will be tested; the eight-at-a-time path is set up only when it runs.
  LeafBoxTest(const uint8_t qmax[3], const uint8_t qmin[3], uint32_t n) {
    for (int a = 0; a < 3; ++a) {
      max_[a] = qmax[a];
      min_[a] = qmin[a];
    }
#if defined(__SSE2__)
    simd_ = n >= 8;
    if (!simd_) {
      // Never read on this path; set so the compiler need not prove it (-Wmaybe-uninitialized).
      for (int v = 0; v < 3; ++v) thr_[v] = flip_[v] = _mm_setzero_si128();
      return;
    }
    // Eight boxes are 48 bytes, three 16-byte loads. A byte at offset p is field p % 6 of box
    // p / 6: a lower bound (even field) passes when it is <= qmax, an upper bound (odd) when it
    // is >= qmin, i.e. when its complement is <= 255 - qmin. So the upper bounds are
    // complemented (xor) and every byte compared with one threshold: max(y, T) == T.
    alignas(16) static const uint8_t kFlip[48] = {
        0, 0xff, 0, 0xff, 0, 0xff, 0, 0xff, 0, 0xff, 0, 0xff, 0, 0xff, 0, 0xff, 0, 0xff, 0, 0xff, 0, 0xff, 0, 0xff,
        0, 0xff, 0, 0xff, 0, 0xff, 0, 0xff, 0, 0xff, 0, 0xff, 0, 0xff, 0, 0xff, 0, 0xff, 0, 0xff, 0, 0xff, 0, 0xff};
    // The thresholds repeat the 6-byte pattern; the 8-byte words of the 48 start at bytes 0, 8,
    // ... 40, i.e. at pattern offsets 0, 2, 4, 0, 2, 4. They are formed in registers (written to
    // memory byte by byte and read back as vectors they would stall on store forwarding).
    const uint64_t p = uint64_t{qmax[0]} | uint64_t{static_cast<uint8_t>(255 - qmin[0])} << 8 |
                       uint64_t{qmax[1]} << 16 | uint64_t{static_cast<uint8_t>(255 - qmin[1])} << 24 |
                       uint64_t{qmax[2]} << 32 | uint64_t{static_cast<uint8_t>(255 - qmin[2])} << 40;
    const long long w0 = static_cast<long long>(p | p << 48);
    const long long w2 = static_cast<long long>(p >> 16 | p << 32);
    const long long w4 = static_cast<long long>(p >> 32 | p << 16);
    thr_[0] = _mm_set_epi64x(w2, w0);
    thr_[1] = _mm_set_epi64x(w0, w4);
    thr_[2] = _mm_set_epi64x(w4, w2);
    for (int v = 0; v < 3; ++v) flip_[v] = _mm_load_si128(reinterpret_cast<const __m128i*>(kFlip + 16 * v));
#else
    (void)n;
#endif
  }

  /// The k in [k, stop) whose box (at boxes + 6 k) passes, ascending, into out; their number.
  int gather(const uint8_t* boxes, uint32_t k, uint32_t stop, uint32_t* out) const {
    int n = 0;
#if defined(__SSE2__)
    for (; simd_ && k + 8 <= stop; k += 8) {
      const uint8_t* qb = boxes + 6 * static_cast<size_t>(k);
      uint64_t m = 0;
      for (int v = 0; v < 3; ++v) {
        const __m128i y = _mm_xor_si128(_mm_loadu_si128(reinterpret_cast<const __m128i*>(qb + 16 * v)), flip_[v]);
        const __m128i ok = _mm_cmpeq_epi8(_mm_max_epu8(y, thr_[v]), thr_[v]);
        m |= static_cast<uint64_t>(static_cast<uint32_t>(_mm_movemask_epi8(ok))) << (16 * v);
      }
      // Box i passes when its six bits are all set; written unconditionally, counted if so.
      for (int i = 0; i < 8; ++i) {
        out[n] = k + i;
        n += ((m >> (6 * i)) & 63) == 63 ? 1 : 0;
      }
    }
#endif
    for (; k < stop; ++k) {
      const uint8_t* qb = boxes + 6 * static_cast<size_t>(k);
      const bool pass = (qb[0] <= max_[0]) & (qb[1] >= min_[0]) & (qb[2] <= max_[1]) & (qb[3] >= min_[1]) &
                        (qb[4] <= max_[2]) & (qb[5] >= min_[2]);
      out[n] = k;
      n += pass ? 1 : 0;
    }
    return n;
  }

 private:
  uint8_t max_[3], min_[3];
#if defined(__SSE2__)
  bool simd_ = false;
  __m128i flip_[3], thr_[3];
#endif
};

}  // namespace mtree

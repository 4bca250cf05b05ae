// The ray queries' first test of a leaf's candidates: the segment o + t d, t in [0, bound],
// against each candidate's quantized box in this leaf (leaf_boxes.h, read in order), in double
// precision and grown by a margin. Those that pass come back sorted by the t at which the
// segment enters their box, so a first-hit query can stop at the first entry beyond its best
// hit so far.
//
// Invariants (tolerance 0 only):
// - The quantized box contains the part of the cell's bounds (padded by 1e-3 of their extent)
//   inside the leaf, so a hit of the cell at a point of this leaf lies in it.
// - A candidate that fails is only not tested in this leaf: a hit elsewhere lies in another leaf
//   that references the cell (a cell is referenced in every leaf it overlaps), which a front-to-
//   back walk visits before it can stop past that t.
// - The margin (1e-7 of the leaf plus round-off in the coordinates' magnitude) keeps a hit that
//   round-off puts on the other side of a leaf face in both leaves.
// With a tolerance > 0 a hit may lie up to tol outside the cell, in a leaf that does not
// reference it: the filter then declines (candidates() returns -1) and every candidate is tested.
//
// The box test is a slab test (Kay & Kajiya) per box, after a byte test (LeafBoxTest) of all the
// leaf's boxes against the quantized range of the segment's part in the leaf.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>

#include "mtree/cells/cells.h"
#include "mtree/cells/leaf_boxes.h"
#include "mtree/core/geometry.h"
#include "mtree/core/matrix_tree.h"

namespace mtree {

class LeafSegmentFilter {
 public:
  struct Candidate {
    double t;    // where the segment enters the candidate's (grown) box, >= 0
    uint32_t k;  // index into the leaf's candidates
  };

  /// tree: the tree whose primitive indices the walk hands out; boxes: its quantized leaf boxes
  /// (6 bytes per primitive index, in the same order; any other size disables the filter);
  /// cells: the indexed cells (their point ids are prefetched for the first survivors).
  LeafSegmentFilter(const MatrixTree& tree, const uint8_t* boxes, size_t boxBytes, const CellSet& cells, Vec3 o,
                    Vec3 d, double tol)
      : tree_(tree), cells_(cells), boxes_(boxes), o_(o), d_(d) {
    const auto& prims = tree.primitiveIndices();
    enabled_ = tol == 0.0 && !tree.empty() && isFinite(o) && isFinite(d) && !(d.x == 0 && d.y == 0 && d.z == 0) &&
               boxBytes == 6 * prims.size();
    prims_ = prims.data();
    numPrims_ = prims.size();
    height_ = tree.height();
    const Vec3 e = o + d;
    mag_ = std::max({std::fabs(o.x), std::fabs(o.y), std::fabs(o.z), std::fabs(e.x), std::fabs(e.y), std::fabs(e.z)});
    // Per ray, not per leaf: the direction's reciprocals (0 on an axis the segment does not move along).
    for (int a = 0; a < 3; ++a) inv_[a] = d[a] != 0 ? 1.0 / d[a] : 0.0;
  }

  /// The candidates of the leaf at bottom-level coordinates `leaf` (as the walk gives them), whose
  /// primitive indices start at `ids`, that the segment may hit in this leaf at t <= bound, into
  /// `out` (room for `count`) sorted by entry t; their number, or -1 where the filter cannot
  /// decide (then every candidate must be tested).
  int candidates(const uint32_t* ids, uint32_t count, const int leaf[3], double bound, Candidate* out) const {
    if (!enabled_ || count == 0 || ids < prims_ || ids + count > prims_ + numPrims_) return -1;
    const uint32_t begin = static_cast<uint32_t>(ids - prims_);
    const int L[3] = {leaf[0], leaf[1], leaf[2]};
    const Box lb = tree_.nodeBox(height_, L);
    constexpr double eps = std::numeric_limits<double>::epsilon();
    const double mag = std::max({mag_, std::fabs(lb.lo.x), std::fabs(lb.lo.y), std::fabs(lb.lo.z), std::fabs(lb.hi.x),
                                 std::fabs(lb.hi.y), std::fabs(lb.hi.z)});
    // Per axis: t of quantized coordinate q is A + q B (moving axes), within +-M; a static axis
    // needs its coordinate's q within [qlo, qhi] grown by the margin. One division per axis (the
    // quantum's reciprocal): the products that replace quotients differ from them by an ulp or
    // two, a relative 1e-15 against margins of 1e-7 of the leaf and 1e-3 of a quantum.
    double A[3], B[3], M[3], SLo[3], SHi[3], Margin[3], PerUnit[3];
    bool moving[3];
    bool anyStatic = false;
    for (int a = 0; a < 3; ++a) {
      const double w = lb.hi[a] - lb.lo[a];
      if (!(w > 0) || !std::isfinite(w)) return -1;
      const double unit = w * (1.0 / 255.0);
      PerUnit[a] = 255.0 / w;
      const double margin = 1e-7 * w + 16 * eps * mag;  // world units
      Margin[a] = margin;
      moving[a] = d_[a] != 0;
      if (moving[a]) {
        const double inv = inv_[a];
        A[a] = (lb.lo[a] - o_[a]) * inv;
        B[a] = unit * inv;
        M[a] = margin * std::fabs(inv) + 8 * eps * (std::fabs(A[a]) + 255 * std::fabs(B[a]));
        if (!std::isfinite(A[a]) || !std::isfinite(B[a]) || !std::isfinite(M[a])) return -1;
      } else {
        anyStatic = true;
        const double q = (o_[a] - lb.lo[a]) * PerUnit[a], mq = margin * PerUnit[a] + 1e-9;
        SLo[a] = q - mq;  // passes when qhi >= SLo and qlo <= SHi
        SHi[a] = q + mq;
      }
    }
    const uint8_t* boxes = boxes_ + 6 * static_cast<size_t>(begin);
    // First the boxes against the bounds of the segment's part in the leaf (a byte test, eight
    // boxes at a time): t in [0, bound] clipped to the leaf grown by the margin (every grown box
    // lies in it), then that part's quantized range per axis, grown by the margin (and 1e-3 of a
    // quantum for round-off), rounded outwards. NaN gives the full range.
    double ta = 0.0, tb = bound;
    for (int a = 0; a < 3; ++a) {
      if (moving[a]) {
        const double t1 = A[a], t2 = A[a] + 255 * B[a];
        ta = std::max(ta, std::min(t1, t2) - M[a]);
        tb = std::min(tb, std::max(t1, t2) + M[a]);
      } else if (SHi[a] < 0 || SLo[a] > 255) {
        return 0;
      }
    }
    if (!(ta <= tb)) return 0;
    uint8_t qmin[3], qmax[3];
    for (int a = 0; a < 3; ++a) {
      const double q0 = (o_[a] + d_[a] * ta - lb.lo[a]) * PerUnit[a];
      const double q1 = (o_[a] + d_[a] * tb - lb.lo[a]) * PerUnit[a];
      const double mq = Margin[a] * PerUnit[a] + 1e-3;
      const double lo = std::min(q0, q1) - mq, hi = std::max(q0, q1) + mq;
      // floor(lo) and ceil(hi), clamped to [0, 255], by truncation of the clamped values (floor
      // for non-negatives; std::floor and std::ceil are libm calls in a build without SSE4.1),
      // without branches on where the segment lies. A NaN gives the full range: max(0, NaN) is 0
      // and min(255, NaN) is 255 in this argument order.
      const double l = std::min(255.0, std::max(0.0, lo)), h = std::max(0.0, std::min(255.0, hi));
      const int th = static_cast<int>(h);
      qmin[a] = static_cast<uint8_t>(static_cast<int>(l));
      qmax[a] = static_cast<uint8_t>(th + (th < h ? 1 : 0));
    }
    const LeafBoxTest boxTest(qmax, qmin, count);
    constexpr uint32_t kChunk = 64;
    uint32_t idx[kChunk];
    int n = 0;
    for (uint32_t k0 = 0; k0 < count; k0 += kChunk) {
      const int ng = boxTest.gather(boxes, k0, std::min(count, k0 + kChunk), idx);
      // The first survivors' point ids are asked for now, while their entry t are computed and
      // sorted: the first cell test waits on them, then on the points.
      for (int g = 0, e = std::min(ng, 8); g < e; ++g) cells_.prefetchPointIds(ids[idx[g]]);
      for (int g = 0; g < ng; ++g) {
        const uint32_t k = idx[g];
        const uint8_t* qb = boxes + 6 * static_cast<size_t>(k);
        double te = 0.0, tx = bound;
        for (int a = 0; a < 3; ++a) {
          if (moving[a]) {
            const double t1 = A[a] + qb[2 * a] * B[a], t2 = A[a] + qb[2 * a + 1] * B[a];
            te = std::max(te, std::min(t1, t2) - M[a]);
            tx = std::min(tx, std::max(t1, t2) + M[a]);
          } else if (anyStatic && (qb[2 * a + 1] < SLo[a] || qb[2 * a] > SHi[a])) {
            tx = -1.0;
          }
        }
        if (te <= tx) {
          out[n].t = te;
          out[n].k = k;
          ++n;
        }
      }
    }
    // Insertion sort by entry t (a handful of survivors; stable, so equal entries keep the
    // leaf's order).
    for (int i = 1; i < n; ++i) {
      const Candidate c = out[i];
      int j = i - 1;
      while (j >= 0 && out[j].t > c.t) {
        out[j + 1] = out[j];
        --j;
      }
      out[j + 1] = c;
    }
    return n;
  }

 private:
  const MatrixTree& tree_;
  const CellSet& cells_;
  const uint8_t* boxes_;
  Vec3 o_, d_;
  const uint32_t* prims_ = nullptr;
  size_t numPrims_ = 0;
  int height_ = 0;
  double mag_ = 0;
  double inv_[3] = {0, 0, 0};
  bool enabled_ = false;
};

}  // namespace mtree

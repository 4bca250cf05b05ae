// Private to engine/src/trees: the binned / event plane candidates of the BSP builder and of the
// hybrid tree's per-leaf kd builder, and their triangle counts.
#pragma once

#include <algorithm>
#include <cstdint>
#include <numeric>
#include <vector>

#include "mtree/trees/split_tree.h"

namespace mtree {
namespace detail {

/// Candidate planes on one direction of a node and, per plane j, the triangles on each side:
///   nl[j] = #{lo <= w[j]} (not starting above the plane), nr[j] = #{hi >= w[j]}.
/// Positions are turned into encodable planes (SplitFrame::toFloat), kept when strictly inside
/// (cellLo, cellHi), sorted, without repeats.
struct PlaneSweep {
  std::vector<double> w;
  std::vector<float> s;
  std::vector<uint32_t> nl, nr;

  /// positions: where to put planes (any order). interval(i, lo, hi): triangle i's bounds.
  /// binsOver > 0: the positions are candidatePositions()' bins + 1 even ones over [a, b], which
  /// lets a triangle's bound find its place from a guess instead of a binary search.
  template <class Interval>
  void run(const SplitFrame& f, int k, const std::vector<double>& positions, double cellLo, double cellHi, size_t n,
           Interval&& interval, int binsOver = 0, double a = 0, double b = 0) {
    w.clear();
    s.clear();
    order_.clear();
    for (double x : positions) {
      const float sf = f.toFloat(k, x);
      const double wv = f.world(k, sf);
      if (wv > cellLo && wv < cellHi) {
        order_.push_back(static_cast<uint32_t>(w.size()));
        w.push_back(wv);
        s.push_back(sf);
      }
    }
    std::sort(order_.begin(), order_.end(), [&](uint32_t a, uint32_t b) { return w[a] < w[b]; });
    sw_.clear();
    ss_.clear();
    for (uint32_t i : order_)
      if (sw_.empty() || w[i] > sw_.back()) {
        sw_.push_back(w[i]);
        ss_.push_back(s[i]);
      }
    w.swap(sw_);
    s.swap(ss_);
    const size_t m = w.size();
    hLo_.assign(m + 1, 0);
    hHi_.assign(m + 1, 0);
    // lo <= w[j] iff fewer than j + 1 planes lie below lo; hi >= w[j] iff more than j lie at or
    // below hi. Counted by binary search, or from the even positions' guess corrected by steps.
    const double toBin = binsOver > 0 && b > a ? binsOver / (b - a) : 0;
    auto below = [&](double v, bool orEqual) -> size_t {
      if (toBin == 0)
        return orEqual ? std::upper_bound(w.begin(), w.end(), v) - w.begin()
                       : std::lower_bound(w.begin(), w.end(), v) - w.begin();
      const double g = (v - a) * toBin + 1;
      size_t j = g <= 0 ? 0 : (g >= double(m) ? m : static_cast<size_t>(g));
      auto under = [&](size_t i) { return orEqual ? w[i] <= v : w[i] < v; };
      while (j > 0 && !under(j - 1)) --j;
      while (j < m && under(j)) ++j;
      return j;
    };
    for (size_t i = 0; i < n; ++i) {
      double lo, hi;
      interval(i, lo, hi);
      ++hLo_[below(lo, false)];
      ++hHi_[below(hi, true)];
    }
    nl.resize(m);
    nr.resize(m);
    uint32_t left = 0, right = static_cast<uint32_t>(n);
    for (size_t j = 0; j < m; ++j) {
      left += hLo_[j];
      right -= hHi_[j];
      nl[j] = left;
      nr[j] = right;
    }
  }

 private:
  std::vector<uint32_t> order_, hLo_, hHi_;
  std::vector<double> sw_;
  std::vector<float> ss_;
};

/// The positions a node tries: every triangle bound when there are at most bins + 1 of them,
/// else bins + 1 planes evenly over [a, b] (its two ends included: they cut off empty space in one
/// plane).
/// Returns `bins` for the even positions, 0 for the triangle bounds (PlaneSweep::run's binsOver).
template <class Interval>
int candidatePositions(size_t n, int bins, double a, double b, Interval&& interval, std::vector<double>& out) {
  out.clear();
  if (2 * n <= size_t(bins) + 1) {
    for (size_t i = 0; i < n; ++i) {
      double lo, hi;
      interval(i, lo, hi);
      out.push_back(lo);
      out.push_back(hi);
    }
    return 0;
  }
  for (int j = 0; j <= bins; ++j) out.push_back(j == bins ? b : a + (b - a) * j / bins);
  return bins;
}

}  // namespace detail
}  // namespace mtree

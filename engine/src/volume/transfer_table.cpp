// TransferTable (the classification's lookup table with range-max opacity queries) and the
// step-corrected table the marchers read. See engine/include/mtree/volume/volume.h.
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <utility>
#include <vector>

#include "mtree/volume/volume.h"

namespace mtree {

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

}  // namespace mtree

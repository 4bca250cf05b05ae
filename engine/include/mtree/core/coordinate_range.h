// The coordinates the trees and their queries accept, checked once where a point set enters the
// engine (TriangleMesh, CellSet).
//
// Every coordinate must be finite with |x| <= kMaxCoordinate, and a point set that is not a
// single point must span at least kMinExtent (the longest side of its bounding box). The reasons:
//   - the cell locator keeps single-precision boxes per cell and per reference (FLT_MAX ~ 3.4e38);
//   - the ray tests (Moller-Trumbore, the watertight test) form determinants of three lengths and
//     the closest-point and cell tests squared distances and squared areas: at lengths of 1e102 a
//     cube overflows to inf, below 1e-103 it underflows to 0, squares of squared lengths below
//     ~1e-77. Within [1e-30, 1e30] the largest such product (a length to the fourth) stays within
//     [1e-120, 1e120], far from both ends of the double range.
// A point set outside the range is refused with the measured value and the range in the message,
// rather than answered wrongly (see docs/reliability.md for the measurements).
#pragma once

#include <cmath>
#include <cstddef>
#include <sstream>
#include <stdexcept>
#include <string>

namespace mtree {

inline constexpr double kMaxCoordinate = 1e30;
inline constexpr double kMinExtent = 1e-30;

/// Checks 3 x n coordinates (x y z per point, float or double). Throws std::invalid_argument
/// naming `who`, the first offending point and the valid range: a non-finite coordinate, one of
/// magnitude above kMaxCoordinate, or a bounding box whose longest side lies in (0, kMinExtent).
template <class T>
void checkCoordinateRange(const T* xyz, size_t n, const char* who) {
  double lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
  for (size_t i = 0; i < n; ++i) {
    for (int a = 0; a < 3; ++a) {
      const double v = static_cast<double>(xyz[3 * i + a]);
      if (!(std::fabs(v) <= kMaxCoordinate)) {
        std::ostringstream os;
        os.precision(17);
        os << who << ": point " << i << " has the coordinate " << v;
        if (std::isfinite(v))
          os << ", beyond the supported range [-1e30, 1e30] (the trees keep single-precision boxes, and "
                "the ray and distance tests multiply up to four lengths); scale the data into range";
        else
          os << " (non-finite: NaN or inf)";
        throw std::invalid_argument(os.str());
      }
      if (i == 0 || v < lo[a]) lo[a] = v;
      if (i == 0 || v > hi[a]) hi[a] = v;
    }
  }
  double extent = 0;  // the bounding box's longest side (a diagonal's square underflows first)
  for (int a = 0; a < 3; ++a) extent = std::fmax(extent, hi[a] - lo[a]);
  if (extent > 0 && extent < kMinExtent) {
    std::ostringstream os;
    os << who << ": the points span only " << extent
       << " (the bounding box's longest side); at least 1e-30 is supported (the ray and distance tests multiply up "
          "to four lengths, which underflow below it); scale the data into range";
    throw std::invalid_argument(os.str());
  }
}

}  // namespace mtree

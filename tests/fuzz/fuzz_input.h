// The byte stream a fuzz harness decodes its case from (libFuzzer's input, or the standalone
// driver's random bytes): integers in ranges, and coordinates drawn in the modes that break
// geometry code -- small integers (coincident points, collinear and zero-area triangles, points on
// node boundaries), uniform values, raw IEEE-754 doubles (NaN, inf, denormals, 1e300), and values
// at the ends of the supported range (mtree/core/coordinate_range.h). Past the end of the input
// every read returns zeros, so any input decodes to a case.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>

#include "mtree/core/builder.h"

namespace mfuzz {

class Input {
 public:
  Input(const uint8_t* data, size_t size) : p_(data), end_(data + size) {}

  uint8_t u8() { return p_ < end_ ? *p_++ : 0; }
  uint32_t u32() {
    uint32_t v = 0;
    for (int i = 0; i < 4; ++i) v |= uint32_t(u8()) << (8 * i);
    return v;
  }
  uint64_t u64() { return uint64_t(u32()) | (uint64_t(u32()) << 32); }
  /// An integer in [0, n) (0 when n is 0).
  uint32_t below(uint32_t n) { return n ? u32() % n : 0; }
  bool flag() { return u8() & 1; }
  /// A uniform double in [lo, hi].
  double uniform(double lo, double hi) { return lo + (hi - lo) * (u32() / 4294967295.0); }
  double rawDouble() {
    const uint64_t bits = u64();
    double d;
    std::memcpy(&d, &bits, sizeof d);
    return d;
  }

  /// How a case's coordinates are drawn (one mode per case, so a case is coherent).
  enum Mode : uint8_t { kSmallIntegers, kUniform, kRawDoubles, kRangeEnds, kPlane, kModes };
  Mode mode() { return static_cast<Mode>(below(kModes)); }
  double coordinate(Mode m) {
    switch (m) {
      case kSmallIntegers:
        return double(int(below(5)) - 2);
      case kUniform:
        return uniform(-1, 1);
      case kRawDoubles:
        return rawDouble();
      case kRangeEnds: {
        static const double kEnds[] = {1e30, -1e30, 1e29, 1e-30, -1e-30, 0.0, 1.0, 3e-31, 2e30};
        return kEnds[below(sizeof kEnds / sizeof kEnds[0])] * (flag() ? 1 : uniform(0.5, 1));
      }
      default:  // kPlane: z = 0, x and y uniform
        return flag() ? 0.0 : uniform(-1, 1);
    }
  }
  bool empty() const { return p_ >= end_; }

 private:
  const uint8_t* p_;
  const uint8_t* end_;
};

/// The build options both tree harnesses draw, in this order: kind, height (automatic, or small
/// enough that the dense leaf pointer matrix stays in megabytes), block edge, overlap test, sort,
/// leaf scale. A harness draws its other options after these.
inline mtree::BuildOptions treeOptions(Input& in) {
  mtree::BuildOptions opt;
  opt.kind = in.flag() ? mtree::TreeKind::RegularKd : mtree::TreeKind::Octree;
  opt.height = int(in.below(opt.kind == mtree::TreeKind::Octree ? 6 : 16));
  opt.blockEdge = 1 << in.below(6);
  opt.overlap = in.flag() ? mtree::OverlapMode::Exact : mtree::OverlapMode::BoundingBox;
  opt.sort = in.flag() ? mtree::BuildSort::Counting : mtree::BuildSort::Radix;
  opt.leafScale = 0.5 * (1 + in.below(8));
  return opt;
}

/// A harness's invariant broke: print what and abort (libFuzzer saves the input as a crash).
[[noreturn]] inline void fail(const char* what) {
  std::fprintf(stderr, "fuzz invariant broken: %s\n", what);
  std::fflush(stderr);
  std::abort();
}

}  // namespace mfuzz

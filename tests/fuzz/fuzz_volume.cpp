// Fuzz harness: the block-sparse volume build (BlockSparseVolume::build, paper §3) and the ray
// marcher over random volumes, transfer tables and cameras.
//
// A case is a grid of 2..24 points per axis of uint8, int16, uint16, float (NaN, inf and huge
// values included) or double scalars, a transfer table of 2..64 entries (opacities possibly
// out of [0, 1] or NaN: the table clamps them), build options (sparse or dense, compact
// storage, integral floats compacted, 1-2 threads), a geometry (negative and anisotropic
// spacing) and a camera (inside the grid, degenerate, parallel), rendered at 7 x 5 pixels.
// Invariants:
//   - build and render accept the case or throw std::invalid_argument (no finite value, a
//     degenerate camera or table); never crash or overflow;
//   - empty-space skipping changes nothing: the image with and without it is the same bit for
//     bit (volume.h: a skipped cell has opacity exactly 0 at every sample), and so is the image
//     of the dense storage (every block allocated: the sparse build only leaves out invisible ones).
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <type_traits>
#include <vector>

#include "fuzz_input.h"
#include "mtree/volume/volume.h"

using namespace mtree;

namespace {
template <class T>
std::vector<T> scalars(mfuzz::Input& in, size_t n) {
  std::vector<T> v(n);
  const uint32_t pattern = in.below(3);
  for (size_t i = 0; i < n; ++i) {
    double x;
    if (pattern == 0) {
      x = double(in.u8());  // raw bytes: noise
    } else if (pattern == 1) {
      x = double(i % 7) * 37.0;  // structured, mostly empty once classified
    } else {
      x = in.below(16) == 0 ? in.rawDouble() : double(in.below(1000));
    }
    if constexpr (std::is_integral_v<T>) {
      // Into [0, max of T] before the cast (a double past T's range has no T value).
      const double wrap = double(std::numeric_limits<T>::max()) + 1.0;
      v[i] = static_cast<T>(std::isfinite(x) ? std::fmod(std::fabs(x), wrap) : 0.0);
    } else {
      v[i] = static_cast<T>(x);
    }
  }
  return v;
}

template <class T>
void run(mfuzz::Input& in, const int dims[3]) {
  const std::vector<T> values = scalars<T>(in, size_t(dims[0]) * dims[1] * dims[2]);
  const int ne = 2 + int(in.below(63));
  std::vector<float> rgba(4 * size_t(ne));
  for (float& f : rgba) f = in.below(32) == 0 ? float(in.rawDouble()) : float(in.below(5)) / 4;
  const double lo = in.uniform(-10, 500), hi = lo + in.uniform(0.5, 1000);
  VolumeBuildOptions bo;
  bo.compact = in.flag();
  bo.compactIntegralFloat = in.flag();
  bo.threads = 1 + int(in.below(2));
  VolumeGeometry geo;
  for (int a = 0; a < 3; ++a) {
    geo.spacing[a] = (in.flag() ? -1 : 1) * 0.25 * (1 + in.below(8));
    geo.origin[a] = in.uniform(-5, 5);
  }
  VolumeCamera cam;
  cam.width = 7;
  cam.height = 5;
  for (int a = 0; a < 3; ++a) {
    const double extent = (dims[a] - 1) * geo.spacing[a];
    cam.focalPoint[a] = geo.origin[a] + extent * in.uniform(0, 1);
    cam.position[a] = geo.origin[a] + extent * in.uniform(-2, 3);  // outside or inside the grid
    cam.viewUp[a] = in.uniform(-1, 1);
  }
  cam.parallel = in.below(4) == 0;
  cam.viewAngle = in.uniform(1, 120);
  cam.parallelScale = in.uniform(0.5, 20);
  VolumeRenderOptions ro;
  ro.sampleDistance = 0.1 * (1 + in.below(10));
  ro.imageSampleDistance = 1 + in.below(3);
  ro.earlyTermination = in.flag() ? 0.99 : 1.0;
  ro.doublePrecision = in.flag();
  ro.shade = in.flag();
  ro.threads = bo.threads;

  std::vector<float> images[3];
  for (int variant = 0; variant < 3; ++variant) {
    // 0: sparse, skipping; 1: sparse, no skipping; 2: dense storage, skipping.
    try {
      const TransferTable tf(lo, hi, rgba, 1.0);
      VolumeBuildOptions o = bo;
      o.sparse = variant != 2;
      BlockSparseVolume vol;
      vol.build(values.data(), dims, tf, o);
      VolumeRenderOptions r = ro;
      r.emptySpaceSkipping = variant != 1;
      images[variant] = renderVolume(vol, geo, tf, cam, r).rgba;
    } catch (const std::invalid_argument&) {
      if (variant == 0) return;  // refused: then every variant refuses
      mfuzz::fail("a variant refused what the first accepted");
    }
  }
  auto sameBits = [](const std::vector<float>& a, const std::vector<float>& b) {
    return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(float)) == 0;
  };
  if (!sameBits(images[0], images[1])) mfuzz::fail("empty-space skipping changed the image");
  if (!sameBits(images[0], images[2])) mfuzz::fail("the dense storage renders another image than the sparse one");
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  mfuzz::Input in(data, size);
  const int dims[3] = {2 + int(in.below(23)), 2 + int(in.below(23)), 2 + int(in.below(23))};
  switch (in.below(5)) {
    case 0:
      run<uint8_t>(in, dims);
      break;
    case 1:
      run<int16_t>(in, dims);
      break;
    case 2:
      run<uint16_t>(in, dims);
      break;
    case 3:
      run<float>(in, dims);
      break;
    default:
      run<double>(in, dims);
  }
  return 0;
}

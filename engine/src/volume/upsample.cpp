// upsampleRGBA: the full-size image from one rendered at a coarser image sample distance.
#include <algorithm>
#include <vector>

#include "mtree/volume/volume.h"

namespace mtree {

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

}  // namespace mtree

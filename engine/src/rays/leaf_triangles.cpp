// The leaf payload's gather (see leaf_triangles.h).
#include "mtree/rays/leaf_triangles.h"

#include <algorithm>

#include "mtree/core/parallel.h"

namespace mtree {

void LeafTriangles::build(const uint32_t* ids, size_t n, const TriangleMesh& mesh, int threads) {
  n_ = n;
  stride_ = n + kPad;
  data_.resize(9 * stride_);
  double* out = data_.data();
  const size_t stride = stride_;
  const int64_t count = static_cast<int64_t>(n);
  // About a nanosecond a reference: serial below kSerialBelow (parallel.h).
#pragma omp parallel for num_threads(resolveThreads(threads)) schedule(static) if (count >= kSerialBelow)
  for (int64_t k = 0; k < count; ++k) {
    for (int c = 0; c < 3; ++c) {
      const Vec3 p = mesh.vertex(ids[k], c);
      out[size_t(3 * c + 0) * stride + size_t(k)] = p.x;
      out[size_t(3 * c + 1) * stride + size_t(k)] = p.y;
      out[size_t(3 * c + 2) * stride + size_t(k)] = p.z;
    }
  }
  for (int c = 0; c < 9; ++c) std::fill_n(out + size_t(c) * stride + n, kPad, 0.0);
}

}  // namespace mtree

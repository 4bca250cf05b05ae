// The leaf payload of the ray tests: every triangle a tree references, pre-gathered in the tree's
// reference order (its leaves' order), so that a leaf's triangles are read from consecutive
// entries instead of through three dependent loads each (reference id -> vertex ids -> vertices).
//
// Layout: structure of arrays, nine arrays of doubles (a.x, a.y, a.z, b.x, ..., c.z of reference
// k at index k of each), so that W consecutive references load as one W-lane vector per
// coordinate for any W (2 with SSE2, 4 with AVX2; leaf_test.h) with no per-leaf padding. The
// corners are the mesh's own doubles, copied: a leaf test on them computes what the test on the
// mesh computes, bit for bit. kPad entries after the last reference (zeros) let a window of up to
// kPad lanes start at any reference.
//
// The same payload serves every tree that lists its leaves' triangles as one array of ids
// (MatrixTree::primitiveIndices(), SahKdTree::primitiveIndices()): the trees are compared with the
// same leaf tests on the same kind of data (docs/bench_rays.md).
#pragma once

#include <cstddef>
#include <cstdint>

#include "mtree/core/memory.h"
#include "mtree/core/primitives.h"

namespace mtree {

class LeafTriangles {
 public:
  static constexpr size_t kPad = 8;

  /// Gathers the corners of triangles ids[0..n) of `mesh` (ids < mesh.size()), replacing any
  /// previous payload. OpenMP over the references.
  void build(const uint32_t* ids, size_t n, const TriangleMesh& mesh, int threads);
  void clear() {
    data_ = LargeVector<double>();
    n_ = stride_ = 0;
  }
  /// References held (the length of the id array it was built from).
  size_t size() const { return n_; }
  bool empty() const { return n_ == 0; }
  /// Bytes held (the nine arrays with their padding).
  size_t bytes() const { return data_.size() * sizeof(double); }
  /// Coordinate k of every reference's corners: k = 3 * corner + axis (corner 0, 1, 2 = a, b, c).
  const double* coord(int k) const { return data_.data() + size_t(k) * stride_; }

 private:
  LargeVector<double> data_;
  size_t n_ = 0, stride_ = 0;
};

}  // namespace mtree

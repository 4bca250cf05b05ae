// Primitive sets the builder is generic over. A primitive set answers three questions:
//   size()             how many primitives;
//   bounds(i)          the primitive's axis-aligned box (world coordinates);
//   overlaps(i, box)   whether it overlaps a closed box (exact, or conservative).
// For speed a set also offers local(i): the primitive with its data fetched once, answering
// bounds(), overlaps(box) and tester(halfSize), whose overlaps(centre) tests many equal boxes. The builder never sees anything else, so triangles and unstructured-grid cells share it.
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "mtree/core/coordinate_range.h"
#include "mtree/core/geometry.h"

namespace mtree {

/// An indexed triangle mesh. Owns copies of the coordinates (doubles) and indices.
class TriangleMesh {
 public:
  TriangleMesh() = default;
  /// points: 3 doubles per vertex; triangles: 3 vertex indices per triangle.
  /// Throws std::invalid_argument naming the first bad index or a coordinate out of
  /// checkCoordinateRange's range.
  TriangleMesh(std::vector<double> points, std::vector<uint32_t> triangles)
      : pts_(std::move(points)), tris_(std::move(triangles)) {
    if (pts_.size() % 3 || tris_.size() % 3)
      throw std::invalid_argument("TriangleMesh: points and triangles must come in triples");
    const size_t nv = pts_.size() / 3;
    checkCoordinateRange(pts_.data(), nv, "TriangleMesh");
    for (size_t i = 0; i < tris_.size(); ++i)
      if (tris_[i] >= nv)
        throw std::invalid_argument("TriangleMesh: triangle " + std::to_string(i / 3) +
                                    " refers to vertex " + std::to_string(tris_[i]) + " but there are " +
                                    std::to_string(nv) + " points");
  }

  size_t size() const { return tris_.size() / 3; }
  size_t numPoints() const { return pts_.size() / 3; }
  Vec3 vertex(size_t tri, int k) const { return Vec3(&pts_[3 * size_t(tris_[3 * tri + k])]); }
  Box bounds(size_t i) const {
    Box b;
    b.extend(vertex(i, 0));
    b.extend(vertex(i, 1));
    b.extend(vertex(i, 2));
    return b;
  }
  bool overlaps(size_t i, const Box& box) const {
    return triangleOverlapsBox(vertex(i, 0), vertex(i, 1), vertex(i, 2), box);
  }
  /// One primitive with its vertices fetched once, for the builder's per-candidate-node loop.
  struct Local {
    Vec3 a, b, c;
    Box bounds() const {
      Box bb;
      bb.extend(a);
      bb.extend(b);
      bb.extend(c);
      return bb;
    }
    bool overlaps(const Box& box) const { return triangleOverlapsBox(a, b, c, box); }
    /// Overlap tests against many boxes of half size `half`, given by their centres.
    TriangleBoxTester tester(Vec3 half) const { return TriangleBoxTester(a, b, c, half); }
  };
  Local local(size_t i) const { return Local{vertex(i, 0), vertex(i, 1), vertex(i, 2)}; }
  const std::vector<double>& points() const { return pts_; }
  const std::vector<uint32_t>& triangles() const { return tris_; }
  /// Replace the coordinates (same connectivity): the per-frame update of a deforming mesh.
  void setPoints(std::vector<double> points) {
    if (points.size() != pts_.size())
      throw std::invalid_argument("TriangleMesh::setPoints: point count differs from the mesh");
    checkCoordinateRange(points.data(), points.size() / 3, "TriangleMesh::setPoints");
    pts_ = std::move(points);
  }

 private:
  std::vector<double> pts_;
  std::vector<uint32_t> tris_;
};

}  // namespace mtree

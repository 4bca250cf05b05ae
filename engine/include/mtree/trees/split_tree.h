// Binary space partitions in pointer form: the common input of the implicit trees (implicit_tree.h).
//
// A node splits its cell by a plane {x : dot(normal[k], x) = w} of one of the tree's directions
// k; the left child holds dot(normal[k], x) <= w, the right child >= w. A kd-tree has the three
// axes as directions (paper §4.1), a restricted BSP tree a fixed larger set (§4.2; the 13
// directions of a 26-DOP here, see bsp_builder.h).
//
// ---- Planes as floats (SplitFrame) ------------------------------------------------------------
// A plane is stored as a float s: w = anchor[k] + double(s) * scale[k], computed with this one
// expression by every builder and every traversal, so they agree on every plane bit for bit
// (SahKdTree's frame, sah_kdtree.h, is the kd case). The implicit trees keep one 32-bit word per
// node: the float's bits with its `tagBits` low mantissa bits replaced by the direction (2 bits
// for a kd-tree, 4 for 13 directions). A float whose tag bits are zero is stored exactly; any
// other is rounded towards zero first (encodable()), which moves the plane by less than
// 2^(tagBits - 23) of |s|, relative: 2^-21 for a kd-tree, 2^-19 for the BSP tree.
// SahKdTree's planes lose nothing: they are multiples of 2^-24 below 0.25, where a float's last
// two mantissa bits are zero (an ulp there is at most 2^-26). The BSP builder (bsp_builder.h) and
// the binned kd builder (binned_kd.h) choose encodable floats to begin with.
//
// ---- Robustness --------------------------------------------------------------------------------
// Every builder here sends a triangle to a child only when it may reach that child: left only if
// its projection on the direction ends below w - pad, right only if it starts above w + pad,
// both otherwise (pad() below: a relative 2^-32 of the scene's coordinates, far above the
// round-off of a projection or of a ray's plane crossing). The traversals (implicit_tree.h) take
// SahKdTree's rules: strict interval tests, the ray's interval widened by a relative 2^-30, and
// the walk ends after a leaf only when the best hit lies before the leaf's exit by that margin.
#pragma once

#include <cstdint>
#include <cstring>
#include <vector>

#include "mtree/core/geometry.h"
#include "mtree/core/primitives.h"

namespace mtree {

class SahKdTree;

struct SplitFrame {
  static constexpr int kMaxDirs = 13;
  int count = 0;    // directions 0..count-1
  int tagBits = 2;  // low bits of a node word that hold the direction (all ones: a leaf)
  Vec3 normal[kMaxDirs];
  double anchor[kMaxDirs] = {}, scale[kMaxDirs] = {};
  /// Round-off allowance of the builders' classification (see Robustness), in units of the
  /// projection on a direction of unit 1-norm; multiplied by the 1-norm of normal[k].
  double padUnit = 0;

  /// The plane of float s on direction k.
  double world(int k, float s) const { return anchor[k] + static_cast<double>(s) * scale[k]; }
  /// The projection of p on direction k, as the builders and traversals compute it.
  double project(int k, Vec3 p) const { return dot(normal[k], p); }
  double pad(int k) const {
    return padUnit * (std::fabs(normal[k].x) + std::fabs(normal[k].y) + std::fabs(normal[k].z));
  }
  uint32_t tagMask() const { return (1u << tagBits) - 1u; }
  /// Whether float s is stored exactly in a node word (its tag bits are zero).
  bool encodable(float s) const {
    uint32_t b;
    std::memcpy(&b, &s, sizeof b);
    return (b & tagMask()) == 0;
  }
  /// s with its tag bits cleared: rounded towards zero to an encodable float.
  float encode(float s) const {
    uint32_t b;
    std::memcpy(&b, &s, sizeof b);
    b &= ~tagMask();
    float r;
    std::memcpy(&r, &b, sizeof r);
    return r;
  }
  /// The float whose plane on direction k lies at (or just below, towards the anchor) x.
  float toFloat(int k, double x) const { return encode(static_cast<float>((x - anchor[k]) / scale[k])); }

  /// The three axes, planes at anchor[a] + s * scale: SahKdTree's frame.
  static SplitFrame axes(const double anchor[3], double scale, double padUnit);
  /// The 13 directions of a 26-DOP (the axes, the 6 face diagonals, the 4 corner diagonals, with
  /// integer components), each with a frame that maps the projections of the triangles' vertices
  /// into s in [0, 0.25] as SahKdTree maps its axes.
  static SplitFrame kdop13(const TriangleMesh& mesh);
  /// The pad unit of a scene of box `scene` (see Robustness).
  static double padUnitOf(const Box& scene);
};

/// A tree in pointer form: SahKdTree's layout generalised to any direction count. Children are
/// adjacent (right = left + 1); pointerBytes() counts 8 bytes a node as SahKdNode (4 for the
/// plane's float, 4 for the direction and the child index, or a leaf's count and offset).
struct PointerSplitTree {
  struct Node {
    bool leaf = true;
    uint8_t dir = 0;
    float s = 0;
    uint32_t child = 0;   // inner: left child (the right child is child + 1)
    uint32_t offset = 0;  // leaf: its triangles are prims[offset, offset + count)
    uint32_t count = 0;
  };
  std::vector<Node> nodes;  // root = nodes[0]; empty: no tree
  std::vector<uint32_t> prims;
  SplitFrame frame;
  Box root;  // the root cell (rays are clipped to it)

  size_t pointerBytes() const { return nodes.size() * 8 + prims.size() * sizeof(uint32_t); }
  int depth() const;
  uint64_t leaves() const;
};

/// A node's split plane drawn within the node's cell (a convex polygon, counter-clockwise about
/// the direction's normal), for pictures of a tree (vtkMatrixTreeRepresentation, docs/trees.md).
struct SplitPolygon {
  int level = 0;
  int dir = 0;
  std::vector<Vec3> points;
};

/// SahKdTree's nodes, triangle lists and plane frame (the same planes, bit for bit).
PointerSplitTree pointerTreeOf(const SahKdTree& tree);

}  // namespace mtree

// A restricted BSP tree by the surface area heuristic (paper §4.2: "split planes with arbitrary
// orientation"): planes from the 13 directions of a 26-DOP (the axes, the 6 face diagonals, the 4
// corner diagonals; Kammaje & Mora 2007, Budge et al. 2008 restrict BSP trees the same way), so
// that a node's plane is a direction index and a distance, and fits the implicit trees' 4-byte
// node word (implicit_tree.h; tag bits 4, precision in split_tree.h). directions = 3 gives a
// binned kd-tree from the same builder, for comparing the planes alone.
//
// Cells are convex polytopes (the root's box clipped by the planes above). At each node, per
// direction, the candidate planes are every bound of the node's triangles when there are at most
// bins + 1 of them, else bins + 1 planes evenly over the triangles' range within the cell (its two
// ends included, which cut off empty space in one plane), each rounded to an encodable float and
// kept when strictly inside the cell. The cost of a plane is SahKdTree's
//     lambda (K_T + K_I (A(L) N_L + A(R) N_R) / A(cell)),
// with A the exact surface area of the two clipped polytopes and lambda = emptyBonus when a side
// holds no triangle. A triangle goes left unless its projection starts above the plane, right
// unless it ends below it (both when it straddles or touches it); a triangle on both sides is
// clipped to each child's cell ("perfect splits", Wald & Havran §4.3, with every plane of the path
// moved outwards by the frame's pad, split_tree.h) for its projections there, and left out of a
// child it does not reach. Leaves: at most one triangle, the depth limit (round(8 + 1.3 log2 N) by
// default, at most ImplicitSplitTree::kMaxLevel), or no plane cheaper than K_I N. Single threaded;
// the polytope areas make it slow (seconds per 10^4 triangles: docs/trees.md).
#pragma once

#include <cstdint>

#include "mtree/core/primitives.h"
#include "mtree/trees/split_tree.h"

namespace mtree {

struct BspBuildOptions {
  double costTraverse = 1.0;   // K_T
  double costIntersect = 1.5;  // K_I
  /// lambda for a plane with an empty side. 1 (none), not SahKdTree's 0.8: with 13 directions a
  /// bonus buys cuts of the polytope's corners that empty little space, and the tree renders
  /// slower (docs/trees.md, the BSP section).
  double emptyBonus = 1.0;
  int bins = 16;               // candidate planes per direction: bins - 1 (2..256)
  int directions = 13;         // 13 (26-DOP) or 3 (the axes: a binned kd-tree)
  int maxDepth = 0;            // 0 = round(8 + 1.3 log2 N); at most ImplicitSplitTree::kMaxLevel
};

struct BspBuildStats {
  uint64_t nodes = 0, leaves = 0, emptyLeaves = 0, references = 0;
  uint64_t axisSplits = 0, diagonalSplits = 0;  // inner nodes split by an axis / another direction
  int depth = 0, maxDepth = 0;
  double sahCost = 0;  // expected cost of a ray, as SahBuildStats::sahCost
  double buildMs = 0;
};

/// Builds the tree over `mesh` (an empty mesh gives an empty tree). Throws std::invalid_argument
/// for bad options.
PointerSplitTree buildBspTree(const TriangleMesh& mesh, const BspBuildOptions& opt = BspBuildOptions{},
                              BspBuildStats* stats = nullptr);

}  // namespace mtree

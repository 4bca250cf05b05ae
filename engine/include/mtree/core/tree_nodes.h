// The nodes of a matrix tree as a list: what a picture of the tree (the Python package's
// tree_mesh, vtkMatrixTreeLocator::GenerateNodes) shows for each node.
#pragma once

#include <algorithm>
#include <cstdint>
#include <vector>

#include "mtree/core/matrix_tree.h"
#include "mtree/core/tree_queries.h"  // forEachChild

namespace mtree {

struct TreeNodeInfo {
  int level = 0;
  int c[3] = {0, 0, 0};
  /// For an inner node, the fraction of its children that exist; 1 for a leaf.
  double occupancy = 1;
  /// Distinct primitives referenced by the leaves below the node (for a leaf, its candidates).
  uint64_t primitives = 0;
};

/// The existing nodes of levels lo..hi (clamped to 0..height; hi < 0 means the leaves), level by
/// level from lo, each level in the order of its nodes' linear index (x fastest). Empty for an
/// empty tree. The distinct primitives per node come from the (node, primitive) pairs of the
/// leaves, carried up one level at a time with each node replaced by its parent and repeats
/// removed: O(R log R) per level for R references.
std::vector<TreeNodeInfo> treeNodes(const MatrixTree& tree, int lo, int hi);

}  // namespace mtree

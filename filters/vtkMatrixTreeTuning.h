// Private to the MatrixTree::Filters module and its tests and benchmarks (C++ only: not wrapped,
// not installed): the developer settings of vtkMatrixTree, set through its SetTuning. Each is an
// alternative that the production path is checked or timed against, and each gives the same
// answers as the defaults (tests/cpp/test_tree_kinds.cpp holds them to it).
#ifndef vtkMatrixTreeTuning_h
#define vtkMatrixTreeTuning_h

struct vtkMatrixTreeTuning
{
  enum SplitTraversals
  {
    RESTART = 0,
    STACK = 1,
    BACKTRACK = 2
  };
  /// The CPU ray walk of the implicit split trees (IMPLICIT_KDTREE, BSP_TREE; mtree::SplitTraversal):
  /// STACK (default, the fastest on a CPU: docs/trees.md), RESTART (KD-Restart) or BACKTRACK (no
  /// stack, no parent pointers: ancestors derived from the node's position, §4.1). The same hits
  /// bit for bit. A query setting: no rebuild.
  int SplitTraversal = STACK;

  bool operator==(const vtkMatrixTreeTuning& o) const { return this->SplitTraversal == o.SplitTraversal; }
  bool operator!=(const vtkMatrixTreeTuning& o) const { return !(*this == o); }
};

#endif

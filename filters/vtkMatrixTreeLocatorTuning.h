/**
 * @struct   vtkMatrixTreeLocatorTuning
 * @brief    the alternative ways vtkMatrixTreeLocator can compute the same answers (C++ only)
 *
 * Each field picks one of two (three) implementations whose answers are the same; the defaults
 * are the production choices, and the others exist so that tests can compare the two and
 * benchmarks can time them (tests/cpp/test_locator_tuning.cpp, bench/cpp/locator_ab.cxx). Not
 * wrapped: set with vtkMatrixTreeLocator::SetTuning() from C++.
 *
 * - BuildSort: how the build groups the (leaf, cell) references by leaf. COUNTING (default):
 *   per-leaf counts, a scan and a scatter that also writes the quantized leaf boxes, then each
 *   leaf's ids sorted; RADIX: the paper's §5.1 (pairs at scanned offsets, a stable radix sort by
 *   leaf, ranges from neighbouring keys), then a pass over the leaves for the boxes. The same
 *   tree, boxes and GetMemorySize() for any NumberOfThreads. Build phases "leaf counts",
 *   "leaf scan", "scatter", "leaf order" (COUNTING) or "scan", "pairs", "sort", "offsets",
 *   "refdata" (RADIX).
 * - CellStorage: where the engine reads the cells' point ids and types, for unstructured grids
 *   and polygon-only polydata whose points are a float or double array (other data sets are
 *   always copied). CELLS_IN_PLACE: the data set's own vtkCellArray (32- or 64-bit offsets and
 *   connectivity) and types, held by reference; CELLS_COPIED: a 32-bit copy of the point ids
 *   (types not kept when all cells have one); CELLS_AUTOMATIC (default): in place when the
 *   arrays are 32-bit or the cells have more than 5 points on average, else copied (64-bit ids
 *   are twice the cache footprint of a 32-bit copy). The same tree and answers.
 * - EngineCellEvaluation: on (default), FindCell evaluates the linear volume cells with the
 *   engine's copy of VTK 9.1's EvaluatePosition (mtree/vtk91/cell_eval.h), asking VTK where a
 *   different rounding could change the answer, and fills the generic cell only for the cell
 *   found; off, every candidate is filled and handed to VTK's EvaluatePosition. The same cell
 *   ids, pcoords and weights bit for bit.
 * - RayStepTable: on (default), the ray queries walk a tree that has a step table
 *   (mtree::MatrixTree::hasStepTable(): surfaces) by it; off, by the occupancy masks. The same
 *   nodes and answers.
 *
 * BuildSort and CellStorage are build settings (a change rebuilds the tree on the next query);
 * EngineCellEvaluation and RayStepTable are query settings (no rebuild).
 */
#ifndef vtkMatrixTreeLocatorTuning_h
#define vtkMatrixTreeLocatorTuning_h

#include "MatrixTreeFiltersModule.h" // For export macro
#include "vtkType.h"                 // For vtkTypeUInt64

struct vtkMatrixTreeLocatorTuning
{
  enum BuildSorts
  {
    RADIX = 0,
    COUNTING = 1
  };
  enum CellStorages
  {
    CELLS_AUTOMATIC = 0,
    CELLS_IN_PLACE = 1,
    CELLS_COPIED = 2
  };

  int BuildSort = COUNTING;
  int CellStorage = CELLS_AUTOMATIC;
  bool EngineCellEvaluation = true;
  bool RayStepTable = true;
};

/**
 * Query statistics, for diagnosing what a query costs: counters summed over every
 * vtkMatrixTreeLocator and thread since the last Reset(). FindCell: "findcell_queries", and per
 * scan of a leaf "findcell_leaf_scans", "findcell_references" (the leaf's), "findcell_box_passes"
 * (references whose quantized box holds the point), "findcell_evaluations" (cells tested
 * exactly), "findcell_found". IntersectWithLine (first hit): "ray_queries", "ray_steps" and
 * "ray_node_visits" (the walk's, as MatrixTree::traverseRay counts them), "ray_leaves",
 * "ray_references", "ray_candidates" (after the leaf's box filter), "ray_cell_tests" (with
 * "ray_mailbox_repeats", cells met again in a later leaf and skipped), "ray_proved_misses",
 * "ray_certain_hits", "ray_vtk_calls", "ray_hits". Kept only in a build configured with
 * -DMATRIXTREE_QUERY_STATS=ON (one relaxed atomic add per event, too slow for timing);
 * otherwise Enabled() is false and GetNumber() 0.
 */
class MATRIXTREEFILTERS_EXPORT vtkMatrixTreeLocatorQueryStatistics
{
public:
  static bool Enabled();
  static int GetNumber();
  /** The i-th counter's name (nullptr outside 0..GetNumber()-1). */
  static const char* GetName(int i);
  /** The i-th counter (0 outside 0..GetNumber()-1). */
  static vtkTypeUInt64 Get(int i);
  static void Reset();
};

#endif

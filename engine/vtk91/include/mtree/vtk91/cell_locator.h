// CellLocator: the queries of a VTK cell locator (vtkAbstractCellLocator: FindCell,
// IntersectWithLine, FindClosestPoint, FindCellsWithinBounds, FindCellsAlongLine) over the cells of
// a CellSet, answered by the engine alone. It serves the Python package where VTK's C++ library
// is not available (pip's VTK wheels ship none); vtkMatrixTreeLocator (filters/) is the VTK
// class over the same tree, which asks VTK's own cells where cell_eval.h cannot be sure.
//
// The tree is the VTK locator's: a matrix tree over the cells (builder.h, the paper's §5.1
// build), each reference carrying its cell's bounds quantized to the leaf (quantizeLeafBox), with
// the same automatic height and the same options, so both locators see the same leaves, the same
// candidates in the same order (ascending cell ids) and, where the cell tests agree, return the
// same cells. The cell tests are cell_geometry.h's (VTK's rules, see there).
//
// Queries are const and thread-safe once built; the batched ones run OpenMP-parallel over their
// inputs. Bad input to build() throws std::invalid_argument (unsupported cell types name the first
// such cell); queries with non-finite coordinates answer "nothing" (-1, NaN, inf).
#pragma once

#include <cstdint>
#include <vector>

#include "mtree/vtk91/cell_geometry.h"
#include "mtree/cells/cells.h"
#include "mtree/core/matrix_tree.h"
#include "mtree/core/memory.h"

namespace mtree {

struct CellLocatorOptions {
  TreeKind kind = TreeKind::Octree;
  /// Levels below the root; 0 = chosen from the cells (chooseHeight).
  int height = 0;
  /// Block edge of the block-sparse levels (power of two, 1..32).
  int blockEdge = 8;
  /// Exact cell/leaf overlap (separating axes, faces only) or bounding boxes (default: the same
  /// answers, a faster build; see vtkMatrixTreeLocator::ExactOverlap).
  bool exactOverlap = false;
  /// Automatic height: leaf extent in median cell extents, and the mean candidate leaves per
  /// cell above which the height steps back up. 0 chooses from the cells as
  /// vtkMatrixTreeLocator does: 1 and 16 when any cell is 3-D, 4 and 3 for surfaces.
  double leafScale = 0;
  double maxCandidates = 0;
  /// OpenMP threads of the build; 0 = one per 1024 cells, up to all.
  int threads = 0;
};

/// A segment's meeting with a cell: t along the segment (0..1), the cell, the point.
struct SegmentHit {
  double t = 0;
  int64_t cell = -1;
  Vec3 x;
};

class CellLocator {
 public:
  CellLocator() = default;

  /// Builds the tree over `cells`. Throws std::invalid_argument if a cell's type is not one the
  /// engine evaluates (cellTypeSupported; the message names the cell and its type) or on bad
  /// options; the locator is then empty. An empty set gives a tree where every query misses.
  void build(CellSet cells, const CellLocatorOptions& opt);

  const CellSet& cells() const { return cells_; }
  const MatrixTree& tree() const { return tree_; }
  const BuildStats& stats() const { return stats_; }
  size_t numCells() const { return cells_.size(); }
  /// Points of the largest cell: the width of findCells' weights.
  int maxCellPoints() const { return maxCellPoints_; }
  /// The largest dimension among the cells (-1 when there are none).
  int maxCellDimension() const { return maxDim_; }
  double leafScaleUsed() const { return leafScale_; }
  double maxCandidatesUsed() const { return maxCandidates_; }
  /// Bytes held: the tree, the cell copy with its cached float bounds (24 bytes per cell) and the
  /// quantized leaf boxes (6 per reference).
  size_t bytes() const { return tree_.bytes() + cells_.bytes() + leafBoxes_.size(); }

  /// FindCell: the first cell of x's leaf, in ascending id order, that contains x (a 3-D cell:
  /// by its acceptance rule; a lower-dimensional one: x projects into it and lies within
  /// sqrt(tol2) of it), or -1. pcoords (3) and weights (maxCellPoints(); unused entries 0) are
  /// written for a found cell. tol2 is honoured within the cells' boxes, which are padded by
  /// 1e-3 of their extent.
  int64_t findCell(const double x[3], double tol2, double pcoords[3], double* weights) const;
  /// findCell for n points (x: 3n doubles): ids (n), pcoords (3n, may be null), weights
  /// (n * maxCellPoints(), may be null); zeros where no cell contains the point.
  void findCells(const double* x, size_t n, double tol2, int64_t* ids, double* pcoords, double* weights,
                 int threads) const;

  /// IntersectWithLine's first hit: the smallest t (ties: the smaller cell id) at which the
  /// segment p1 -> p2 meets a cell within tol. False if it meets none.
  bool firstHit(Vec3 p1, Vec3 p2, double tol, SegmentHit& hit) const;
  /// firstHit for n segments (3n doubles each): t (inf on a miss), ids (-1), x (NaN; may be null).
  void firstHits(const double* p1, const double* p2, size_t n, double tol, double* t, int64_t* ids, double* x,
                 int threads) const;
  /// Every cell the segment meets within tol, once each at its first meeting, sorted by t
  /// (ties by id).
  void allHits(Vec3 p1, Vec3 p2, double tol, std::vector<SegmentHit>& hits) const;

  /// FindClosestPoint(WithinRadius): the cell nearest x (ties: the smaller id) no farther than
  /// radius, its closest point and the squared distance; -1 (and dist2 inf) if there is none.
  int64_t closestPoint(const double x[3], double radius, Vec3& closest, double& dist2) const;
  /// closestPoint for n points: closest (3n), ids (n), dist2 (n; may be null).
  void closestPoints(const double* x, size_t n, double radius, double* closest, int64_t* ids, double* dist2,
                     int threads) const;

  /// FindCellsWithinBounds: every cell whose bounds meet the box, ascending ids.
  void cellsWithinBounds(const Box& box, std::vector<int64_t>& out) const;
  /// FindCellsAlongLine: every cell whose bounds, padded by tol, the segment crosses, ascending
  /// (with exactOverlap, among the cells of the leaves the segment crosses: a cell whose box
  /// meets the segment where the cell itself does not reach may be left out).
  void cellsAlongSegment(Vec3 p1, Vec3 p2, double tol, std::vector<int64_t>& out) const;

 private:
  /// Per-thread buffers for cells of more than CellSet::kMaxLocalPoints points.
  struct Scratch {
    std::vector<double> pts, weights;
  };
  template <class F>
  void forEachQuery(size_t n, int threads, int chunk, int64_t serial, F&& f) const;
  /// Cell c's points (3 doubles each) in scratch.pts; returns their number.
  int gather(size_t c, Scratch& s) const;
  int64_t findCellIn(const double x[3], double tol2, double pcoords[3], double* weights, Scratch& s) const;
  bool firstHitIn(Vec3 p1, Vec3 p2, double tol, SegmentHit& hit, Scratch& s) const;
  int64_t closestIn(const double x[3], double radius, Vec3& closest, double& dist2, Scratch& s) const;

  CellSet cells_;
  MatrixTree tree_;
  BuildStats stats_;
  LargeVector<uint8_t> leafBoxes_;
  int maxCellPoints_ = 0;
  int maxDim_ = -1;
  double leafScale_ = 0, maxCandidates_ = 0;
};

}  // namespace mtree

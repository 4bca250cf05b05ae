// CellLocator: the queries of a VTK cell locator (vtkAbstractCellLocator: FindCell,
// IntersectWithLine, FindClosestPoint, FindCellsWithinBounds, FindCellsAlongLine) over the cells of
// a CellSet, without VTK. It serves the Python package where VTK's C++ library is not available
// (pip's VTK wheels ship none).
//
// It is vtkMatrixTreeLocator's algorithm (locator_core.h: the same build, the same leaves, the
// same candidates in the same order, the same fast decisions), with VTK 9.1's cells transcribed
// (cell_mirror.h) where vtkMatrixTreeLocator asks VTK's own: so its answers are that locator's,
// VTK's cells, pcoords, weights, t and hit points. Cell types the transcription does not cover
// are refused at build time (see cell_mirror.h for the list and for the one approximation,
// vtkPolygon's random-ray point-in-polygon test).
//
// Queries are const and thread-safe once built; the batched ones run OpenMP-parallel over their
// inputs. Bad input to build() throws std::invalid_argument (unsupported cell types name the first
// such cell); queries with non-finite coordinates answer "nothing" (-1, NaN, inf).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "mtree/cells/cells.h"
#include "mtree/core/matrix_tree.h"
#include "mtree/vtk91/locator_core.h"

namespace mtree {

/// The build settings of vtkMatrixTreeLocator (vtk91::LocatorSettings: tree kind, height, block
/// edge, exact overlap, leaf scale and candidates, sort), with the engine's defaults: threads 0
/// is one per 1024 cells, up to all; the cells' float bounds are kept (every ray and
/// closest-point candidate reads them before its points).
struct CellLocatorOptions : vtk91::LocatorSettings {
  CellLocatorOptions() {
    threads = 0;
    keepBounds = true;
  }
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
  /// transcription covers (vtk91::mirrorCovers; the message names the cell and its type) or on
  /// bad options; the locator is then empty. An empty set gives a tree where every query misses.
  void build(CellSet cells, const CellLocatorOptions& opt);

  const CellSet& cells() const { return core_.cells; }
  const MatrixTree& tree() const { return core_.tree; }
  const BuildStats& stats() const { return core_.stats; }
  size_t numCells() const { return core_.cells.size(); }
  /// Points of the largest cell: the width of findCells' weights.
  int maxCellPoints() const { return core_.maxCellPoints; }
  /// The largest dimension among the cells (-1 when there are none).
  int maxCellDimension() const { return core_.maxDimension; }
  double leafScaleUsed() const { return core_.leafScaleUsed; }
  double maxCandidatesUsed() const { return core_.maxCandidatesUsed; }
  /// Bytes held: the tree, the cell copy with its cached float bounds (24 bytes per cell, kept:
  /// every ray and closest-point candidate reads them), the quantized leaf boxes (6 per
  /// reference) and the rays' shape byte per hexahedron, wedge or pyramid grid cell.
  size_t bytes() const { return core_.bytes(); }

  /// FindCell: the first cell of x's leaf, in ascending id order, that contains x as VTK 9.1's
  /// EvaluatePosition decides (for a 2-D cell: x projects into it; tol2 is not used, as by
  /// VTK 9.1's own locators), or -1. pcoords (3) and weights (maxCellPoints(); unused entries 0)
  /// are VTK's, written for a found cell.
  int64_t findCell(const double x[3], double tol2, double pcoords[3], double* weights) const;
  /// findCell for n points (x: 3n doubles): ids (n), pcoords (3n, may be null), weights
  /// (n * maxCellPoints(), may be null); zeros where no cell contains the point.
  void findCells(const double* x, size_t n, double tol2, int64_t* ids, double* pcoords, double* weights,
                 int threads) const;

  /// IntersectWithLine's first hit: the smallest t at which the segment p1 -> p2 meets a cell
  /// within tol (VTK's IntersectWithLine of each cell), the cell and VTK's hit point. False if
  /// it meets none.
  bool firstHit(Vec3 p1, Vec3 p2, double tol, SegmentHit& hit) const;
  /// firstHit for n segments (3n doubles each): t (inf on a miss), ids (-1), x (NaN; may be null).
  void firstHits(const double* p1, const double* p2, size_t n, double tol, double* t, int64_t* ids, double* x,
                 int threads) const;
  /// Every cell the segment meets within tol, once each, sorted by t (ties by id).
  void allHits(Vec3 p1, Vec3 p2, double tol, std::vector<SegmentHit>& hits) const;

  /// FindClosestPoint(WithinRadius): the cell nearest x (VTK's EvaluatePosition distance; ties:
  /// the smaller id) no farther than radius, its closest point and the squared distance; -1 (and
  /// dist2 inf) if there is none.
  int64_t closestPoint(const double x[3], double radius, Vec3& closest, double& dist2) const;
  /// closestPoint for n points: closest (3n), ids (n), dist2 (n; may be null).
  void closestPoints(const double* x, size_t n, double radius, double* closest, int64_t* ids, double* dist2,
                     int threads) const;

  /// FindCellsWithinBounds: every cell whose bounds meet the box, ascending ids.
  void cellsWithinBounds(const Box& box, std::vector<int64_t>& out) const;
  /// FindCellsAlongLine: every cell whose bounds, padded by tol, the segment crosses, ascending
  /// (among the cells of the leaves the segment crosses).
  void cellsAlongSegment(Vec3 p1, Vec3 p2, double tol, std::vector<int64_t>& out) const;

 private:
  vtk91::LocatorCore core_;
};

}  // namespace mtree

// Private to the MatrixTree::Filters module (not wrapped, not installed): between the engine's
// cells (mtree::CellSet, VTK's type codes and point order) and VTK's own cell classes, for
// vtkMatrixTreeLocator's queries: the Oracle of mtree::vtk91::LocatorCore (locator_core.h) that
// settles what the engine's fast decisions leave open with VTK's own vtkCell, so every answer a
// query returns is VTK's.
//
// The hot functions (FillCell and the Oracle's) are inline: they run per candidate cell inside
// the queries' loops.
#ifndef vtkMatrixTreeCellBridge_h
#define vtkMatrixTreeCellBridge_h

#include "mtree/cells/cells.h"
#include "mtree/cells/segment_filter.h"
#include "mtree/vtk91/cell_eval.h"
#include "mtree/vtk91/cell_faces.h"
#include "mtree/vtk91/face_hit.h"
#include "mtree/vtk91/locator_core.h"

#include "vtkMatrixTreeQueryStatistics.h"

#include "vtkCellType.h"
#include "vtkDataSet.h"
#include "vtkDoubleArray.h"
#include "vtkGenericCell.h"
#include "vtkIdList.h"
#include "vtkPoints.h"
#include "vtkVersionMacros.h"

#include <algorithm>
#include <cstdint>
#include <vector>

namespace vtkMatrixTreeCellBridge
{
/** How this VTK's vtkQuad::IntersectWithLine splits a quad (segment_filter.h's QuadSplit): with
 * it known, the ray queries decide hexahedra, wedges and pyramids with slightly warped faces
 * without VTK too (tests/cpp/test_segment_filter checks it against VTK). */
constexpr mtree::QuadSplit kVtkQuadSplit = mtree::vtk91::quadSplitOfVtk(VTK_MAJOR_VERSION, VTK_MINOR_VERSION);

/** Whether this VTK's face tests and cell evaluation are the ones mtree/vtk91 recomputes (9.1's). */
constexpr bool kVtk91 =
  VTK_VERSION_NUMBER >= VTK_VERSION_CHECK(9, 1, 0) && VTK_VERSION_NUMBER < VTK_VERSION_CHECK(9, 2, 0);

/** VTK's tolerance on a tetrahedron's barycentric coordinates in EvaluatePosition. */
constexpr double kTetraTolerance = 1e-3;

/**
 * Cell `id` into `cell` with the same type, point ids and coordinates as vtkDataSet::GetCell
 * gives (the engine's points are the data set's values exactly: its doubles, or floats where
 * every coordinate is one), read from the engine's copy: for a random query, VTK's own
 * connectivity and point arrays would be a second set of cache misses on data the scan has just
 * read. Linear types only (VTK_VERTEX ... VTK_PYRAMID need no initialisation and have no
 * explicit faces, so the generic cell's type is all there is to set); the others go through
 * GetCell. pts, when given, are the cell's coordinates already gathered (3 doubles per point).
 */
inline void FillCell(vtkDataSet* ds, const mtree::CellSet& cells, vtkIdType id, vtkGenericCell* cell,
  const double* pts = nullptr)
{
  const size_t c = static_cast<size_t>(id);
  const uint8_t type = cells.type(c);
  if (type < VTK_VERTEX || type > VTK_PYRAMID)
  {
    ds->GetCell(id, cell);
    return;
  }
  cell->SetCellType(type);
  const vtkIdType n = static_cast<vtkIdType>(cells.numCellPoints(c));
  const mtree::CellSet::PointIds pid = cells.cellPointIds(c);
  if (cell->PointIds->GetNumberOfIds() != n)
  {
    cell->PointIds->SetNumberOfIds(n);
  }
  vtkIdType* ids = cell->PointIds->GetPointer(0);
  for (vtkIdType k = 0; k < n; ++k)
  {
    ids[k] = static_cast<vtkIdType>(pid[k]);
  }
  // The coordinates straight into the cell's double array (n virtual SetTuple calls otherwise),
  // with Modified() as SetNumberOfPoints does, so the points' MTime moves as there.
  vtkDoubleArray* xyz = vtkDoubleArray::FastDownCast(cell->Points->GetData());
  if (!xyz || xyz->GetNumberOfComponents() != 3 || xyz->GetNumberOfTuples() != n)
  {
    cell->Points->SetNumberOfPoints(n);
    xyz = vtkDoubleArray::FastDownCast(cell->Points->GetData());
  }
  else
  {
    cell->Points->Modified();
  }
  if (!xyz)
  {
    for (vtkIdType k = 0; k < n; ++k)
    {
      const mtree::Vec3 p = cells.cellPoint(c, k);
      cell->Points->SetPoint(k, p.x, p.y, p.z);
    }
    return;
  }
  double* out = xyz->GetPointer(0);
  if (pts)
  {
    std::copy(pts, pts + 3 * n, out);
  }
  else
  {
    mtree::vtk91::gatherCellPoints(cells, c, n, out);
  }
}

/**
 * vtkHexahedron, vtkWedge or vtkTetra::IntersectWithLine (VTK 9.1) for a segment whose hit is
 * certain to lie on face `face` (mtree::convexFirstHitIfCertain's or tetraCertainHitFace's
 * face: every other face is far from the line, so VTK's loop over the faces finds only this
 * one, or this one first): that face's vtkQuad or vtkTriangle test, its points set as the cell
 * sets them, recomputed by mtree::vtk91 at tolerance 0 and asked of VTK's own face cell where
 * the recomputation leaves the answer to VTK, and the face's pcoords mapped as the cell maps
 * them (mtree::vtk91::faceHitPcoords). One face test instead of six (five, four). False if the
 * face reports no hit (the caller then asks the cell), the type has no mapping, or this VTK is
 * not 9.1 (whose mappings these are).
 */
bool CertainFaceHit(const mtree::CellSet& cells, vtkIdType id, int face, const double p1[3], const double p2[3],
  double tol, double& t, double x[3], double pcoords[3], int& subId);

/** The data set's cells made safe to fetch from many threads (polydata builds its cell links on
 * the first GetCell). */
void PrepareForThreads(vtkDataSet* ds);

/**
 * The LocatorCore Oracle of vtkMatrixTreeLocator: a cell the engine's fast decisions leave open
 * is filled into the query's vtkGenericCell (FillCell) and asked of VTK. One per query (or per
 * thread of a batch): it remembers which cell the generic cell holds, so that the answer's cell
 * is filled once. engineEval: the tuning's EngineCellEvaluation (off: every FindCell candidate
 * goes to VTK, a tetrahedron after a pre-test that only rejects what VTK would: outside
 * barycentric tolerance 1e-2, where VTK accepts 1e-3).
 */
class Oracle
{
public:
  static constexpr bool kCounting = vtkMatrixTreeQueryStatistics::kQueryStats;

  Oracle(vtkDataSet* ds, const mtree::CellSet& cells, vtkGenericCell* cell, bool engineEval)
    : DS(ds)
    , Cells(cells)
    , Cell(cell)
    , EngineEval(engineEval)
  {
  }

  bool fastEvaluation() const { return this->EngineEval; }
  bool mirrorIsVtk() const { return kVtk91; }
  mtree::QuadSplit quadSplit() const { return kVtkQuadSplit; }
  void count(mtree::vtk91::LocatorEvent e, uint64_t n) const
  {
    vtkMatrixTreeQueryStatistics::CountQuery(e, n);
  }

  bool contains(size_t c, const double x[3], const double* pts, double pcoords[3], double* weights)
  {
    if (!pts && !this->EngineEval && this->Cells.type(c) == mtree::kTetra &&
      !this->Cells.tetraMayContain(c, mtree::Vec3(x), 0.01))
    {
      return false;
    }
    this->Fill(c, pts);
    double closest[3], dist2;
    int subId = 0;
    return this->Cell->EvaluatePosition(x, closest, subId, pcoords, dist2, weights) == 1;
  }
  void found(size_t c, const double* pts) { this->Fill(c, pts); }
  int intersect(size_t c, const double p1[3], const double p2[3], double tol, double& t, double x[3],
    double pcoords[3], int& subId)
  {
    this->Fill(c, nullptr);
    return this->Cell->IntersectWithLine(p1, p2, tol, t, x, pcoords, subId);
  }
  int intersectFace(size_t c, int face, const double p1[3], const double p2[3], double tol, double& t, double x[3],
    double pcoords[3], int& subId)
  {
    return CertainFaceHit(this->Cells, static_cast<vtkIdType>(c), face, p1, p2, tol, t, x, pcoords, subId) ? 1 : 0;
  }
  void holding(size_t c)
  {
    if (this->Filled != static_cast<vtkIdType>(c))
    {
      this->Fill(c, nullptr);
    }
  }
  int closest(size_t c, const double x[3], double cp[3], int& subId, double& dist2)
  {
    this->DS->GetCell(static_cast<vtkIdType>(c), this->Cell);
    this->Filled = static_cast<vtkIdType>(c);
    const size_t n = static_cast<size_t>(this->Cell->GetNumberOfPoints());
    if (this->Weights.size() < n)
    {
      this->Weights.resize(n);
    }
    double pcoords[3];
    return this->Cell->EvaluatePosition(x, cp, subId, pcoords, dist2, this->Weights.data());
  }

private:
  void Fill(size_t c, const double* pts)
  {
    FillCell(this->DS, this->Cells, static_cast<vtkIdType>(c), this->Cell, pts);
    this->Filled = static_cast<vtkIdType>(c);
  }

  vtkDataSet* DS;
  const mtree::CellSet& Cells;
  vtkGenericCell* Cell;
  bool EngineEval;
  vtkIdType Filled = -1; // the cell the generic cell holds
  std::vector<double> Weights;
};
}

#endif

// Private to the MatrixTree::Filters module (not wrapped, not installed): between the engine's
// cells (mtree::CellSet, VTK's type codes and point order) and VTK's own cell classes, for
// vtkMatrixTreeLocator's queries. Every answer a query returns is VTK's: what the engine
// decides without VTK (mtree/vtk91: VTK 9.1's arithmetic recomputed in VTK's order) gives VTK's
// bits, and everything else goes to the vtkCell.
//
// The hot functions (GatherPoints, FillCell, CellContains, RecomputedTriangleHit) are inline:
// they run per candidate cell inside the queries' loops.
#ifndef vtkMatrixTreeCellBridge_h
#define vtkMatrixTreeCellBridge_h

#include "mtree/cells/cells.h"
#include "mtree/cells/segment_filter.h"
#include "mtree/vtk91/cell_eval.h"
#include "mtree/vtk91/cell_faces.h"
#include "mtree/vtk91/face_hit.h"

#include "vtkCellType.h"
#include "vtkDataSet.h"
#include "vtkDoubleArray.h"
#include "vtkGenericCell.h"
#include "vtkIdList.h"
#include "vtkPoints.h"
#include "vtkVersionMacros.h"

#include <algorithm>
#include <cstdint>

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

/** Cell `id`'s first n points as the engine reads them, into pts (3 doubles each). */
inline void GatherPoints(const mtree::CellSet& cells, size_t id, int64_t n, double* pts)
{
  const mtree::CellSet::PointIds pid = cells.cellPointIds(id);
  for (int64_t k = 0; k < n; ++k)
  {
    const mtree::Vec3 p = cells.point(pid[k]);
    pts[3 * k] = p.x;
    pts[3 * k + 1] = p.y;
    pts[3 * k + 2] = p.z;
  }
}

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
    GatherPoints(cells, c, n, out);
  }
}

/**
 * Does cell `id` contain x, as vtkCellLocator decides: EvaluatePosition says inside and, for a
 * cell of dimension < 3 (a vertex, a line or a polygon in a 3-D grid, where "inside" only means
 * that x projects into the cell), x also lies in the cell's bounds. If so the cell is filled into
 * `cell` and pcoords and weights are VTK's. engineEval: the linear volume cells are evaluated by
 * mtree::vtk91::evaluateLinearCell (VTK's arithmetic; VTK is asked where a different rounding
 * could change the answer) and only a containing cell is filled; otherwise every cell is filled
 * and handed to VTK (a tetrahedron after a pre-test that only rejects what VTK would: outside
 * barycentric tolerance 1e-2, where VTK accepts 1e-3).
 */
MT_ALWAYS_INLINE bool CellContains(vtkDataSet* ds, const mtree::CellSet& cells, const double x[3], vtkIdType id,
  vtkGenericCell* cell, double pcoords[3], double* weights, bool engineEval)
{
  const size_t c = static_cast<size_t>(id);
  const uint8_t type = cells.type(c);
  double closest[3], dist2;
  int subId = 0;
  if (engineEval)
  {
    const int64_t np = cells.numCellPoints(c);
    if (mtree::vtk91::cellEvaluable(type, np))
    {
      double pts[3 * mtree::CellSet::kMaxLocalPoints];
      GatherPoints(cells, c, np, pts);
      const mtree::vtk91::PointInCell v = mtree::vtk91::evaluateLinearCell(type, pts, x, pcoords, weights);
      if (v == mtree::vtk91::PointInCell::kOutside)
      {
        return false;
      }
      FillCell(ds, cells, id, cell, pts);
      return v == mtree::vtk91::PointInCell::kInside ||
        cell->EvaluatePosition(x, closest, subId, pcoords, dist2, weights) == 1;
    }
  }
  else if (type == mtree::kTetra && !cells.tetraMayContain(c, mtree::Vec3(x), 0.01))
  {
    return false;
  }
  FillCell(ds, cells, id, cell);
  return cell->EvaluatePosition(x, closest, subId, pcoords, dist2, weights) == 1 &&
    (cell->GetCellDimension() == 3 || cells.exactBounds(c).contains(mtree::Vec3(x)));
}

/**
 * Cell `id`'s vtkTriangle::IntersectWithLine at tolerance 0 recomputed by mtree::vtk91 (the same
 * verdict and bits) where the cell is a triangle and this is VTK 9.1; kAskVtk otherwise, and
 * where the recomputation leaves the answer to VTK.
 */
inline mtree::vtk91::FaceHit RecomputedTriangleHit(const mtree::CellSet& cells, vtkIdType id, const double p1[3],
  const double p2[3], mtree::vtk91::LineHit& h)
{
  const size_t c = static_cast<size_t>(id);
  if (!kVtk91 || cells.type(c) != mtree::kTriangle || cells.numCellPoints(c) != 3)
  {
    return mtree::vtk91::FaceHit::kAskVtk;
  }
  double q[3][3];
  GatherPoints(cells, c, 3, &q[0][0]);
  return mtree::vtk91::triangleLineHit(q[0], q[1], q[2], p1, p2, h);
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

/** Whether no cell is 3-D (a surface; lines and vertices too), by VTK's cell classes. */
bool NoVolumeCells(const mtree::CellSet& cells);

/** Whether any cell is a hexahedron, wedge or pyramid (the cells mtree::ConvexShapeMemo serves). */
bool HasConvexPolyhedra(const mtree::CellSet& cells);

/** The data set's cells made safe to fetch from many threads (polydata builds its cell links on
 * the first GetCell). */
void PrepareForThreads(vtkDataSet* ds);
}

#endif

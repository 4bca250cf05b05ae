#include "vtkMatrixTreeCellBridge.h"

#include "vtkCell.h"
#include "vtkQuad.h"
#include "vtkSmartPointer.h"
#include "vtkTriangle.h"

namespace vtkMatrixTreeCellBridge
{
bool CertainFaceHit(const mtree::CellSet& cells, vtkIdType id, int face, const double p1[3], const double p2[3],
  double tol, double& t, double x[3], double pcoords[3], int& subId)
{
  const uint8_t type = cells.type(static_cast<size_t>(id));
  if (!kVtk91 || !mtree::vtk91::faceHitMapped(type))
  {
    return false;
  }
  const mtree::CellTopology* topo = mtree::cellTopology(type);
  const int n = topo->faceSize[face];
  const auto pid = cells.cellPointIds(static_cast<size_t>(id));
  double q[4][3];
  for (int k = 0; k < n; ++k)
  {
    const mtree::Vec3 p = cells.point(pid[topo->face[face][k]]);
    q[k][0] = p.x, q[k][1] = p.y, q[k][2] = p.z;
  }
  double pc[3];
  mtree::vtk91::FaceHit fast = mtree::vtk91::FaceHit::kAskVtk;
  if (tol == 0.0)
  {
    mtree::vtk91::LineHit h;
    fast = n == 4 ? mtree::vtk91::quadLineHit(q, p1, p2, h) : mtree::vtk91::triangleLineHit(q[0], q[1], q[2], p1, p2, h);
    if (fast == mtree::vtk91::FaceHit::kMiss)
    {
      return false;
    }
    if (fast == mtree::vtk91::FaceHit::kHit)
    {
      t = h.t;
      std::copy(h.x, h.x + 3, x);
      std::copy(h.pcoords, h.pcoords + 3, pc);
      subId = 0;
    }
  }
  if (fast == mtree::vtk91::FaceHit::kAskVtk)
  {
    // The face as a vtkQuad or vtkTriangle of its own (the point ids its constructor gives: they
    // only break ties between equal quad diagonals, as in the cell's own faces).
    static thread_local vtkSmartPointer<vtkQuad> quad = vtkSmartPointer<vtkQuad>::New();
    static thread_local vtkSmartPointer<vtkTriangle> triangle = vtkSmartPointer<vtkTriangle>::New();
    vtkCell* f = n == 4 ? static_cast<vtkCell*>(quad) : static_cast<vtkCell*>(triangle);
    for (int k = 0; k < n; ++k)
    {
      f->GetPoints()->SetPoint(k, q[k]);
    }
    if (!f->IntersectWithLine(p1, p2, tol, t, x, pc, subId))
    {
      return false;
    }
  }
  mtree::vtk91::faceHitPcoords(type, face, pc, pcoords);
  return true;
}

void PrepareForThreads(vtkDataSet* ds)
{
  if (ds && ds->GetNumberOfCells() > 0)
  {
    vtkNew<vtkGenericCell> c;
    ds->GetCell(0, c);
  }
}
}

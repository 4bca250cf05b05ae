#include "vtkMatrixTreeInternals.h"

#include "vtkCellArray.h"
#include "vtkCellArrayIterator.h"
#include "vtkDataArray.h"
#include "vtkPoints.h"
#include "vtkPolyData.h"
#include "vtkSmartPointer.h"


namespace vtkMatrixTreeConvert
{
bool ToTriangleMesh(vtkPolyData* pd, mtree::TriangleMesh& mesh, std::vector<vtkIdType>& cellOfTriangle,
  std::string& error)
{
  cellOfTriangle.clear();
  std::vector<double> pts;
  std::vector<uint32_t> tris;
  vtkPoints* points = pd ? pd->GetPoints() : nullptr;
  const vtkIdType np = points ? points->GetNumberOfPoints() : 0;
  if (np >= static_cast<vtkIdType>(MT_NULL))
  {
    error = "too many points for 32-bit indices";
    return false;
  }
  pts.resize(static_cast<size_t>(np) * 3);
  for (vtkIdType i = 0; i < np; ++i)
  {
    points->GetPoint(i, &pts[3 * i]);
  }
  if (np > 0)
  {
    // Cell ids of polydata run verts, lines, polys, strips.
    const vtkIdType polyBase = pd->GetNumberOfVerts() + pd->GetNumberOfLines();
    auto addTri = [&](vtkIdType a, vtkIdType b, vtkIdType c, vtkIdType cell) {
      tris.push_back(static_cast<uint32_t>(a));
      tris.push_back(static_cast<uint32_t>(b));
      tris.push_back(static_cast<uint32_t>(c));
      cellOfTriangle.push_back(cell);
    };
    vtkIdType cell = polyBase;
    auto it = vtk::TakeSmartPointer(pd->GetPolys()->NewIterator());
    for (it->GoToFirstCell(); !it->IsDoneWithTraversal(); it->GoToNextCell(), ++cell)
    {
      vtkIdType n;
      const vtkIdType* ids;
      it->GetCurrentCell(n, ids);
      for (vtkIdType k = 1; k + 1 < n; ++k)
      {
        addTri(ids[0], ids[k], ids[k + 1], cell);
      }
    }
    auto st = vtk::TakeSmartPointer(pd->GetStrips()->NewIterator());
    for (st->GoToFirstCell(); !st->IsDoneWithTraversal(); st->GoToNextCell(), ++cell)
    {
      vtkIdType n;
      const vtkIdType* ids;
      st->GetCurrentCell(n, ids);
      for (vtkIdType k = 0; k + 2 < n; ++k)
      {
        if (k % 2 == 0)
        {
          addTri(ids[k], ids[k + 1], ids[k + 2], cell);
        }
        else
        {
          addTri(ids[k + 1], ids[k], ids[k + 2], cell);
        }
      }
    }
  }
  try
  {
    mesh = mtree::TriangleMesh(std::move(pts), std::move(tris));
  }
  catch (const std::exception& e)
  {
    error = e.what();
    return false;
  }
  return true;
}
}

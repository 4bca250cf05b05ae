// vtkMatrixTreeLocatorProcessor's views of the tree as VTK data (GenerateRepresentation,
// GenerateNodes): every existing node of a level as a box, with the engine's node queries
// (mtree/core/tree_queries.h) for the counts.
#include "vtkMatrixTreeLocatorProcessor.h"

#include "vtkCellArray.h"
#include "vtkCellData.h"
#include "vtkDoubleArray.h"
#include "vtkFieldData.h"
#include "vtkIdTypeArray.h"
#include "vtkIntArray.h"
#include "vtkNew.h"
#include "vtkPoints.h"
#include "vtkPolyData.h"
#include "vtkUnstructuredGrid.h"

#include "mtree/core/tree_queries.h"

#include <algorithm>

void vtkMatrixTreeLocatorProcessor::Representation(int level, vtkPolyData* pd) const
{
  const mtree::MatrixTree& tree = this->Core.tree;
  vtkNew<vtkPoints> pts;
  vtkNew<vtkCellArray> quads;
  vtkNew<vtkIntArray> levels;
  levels->SetName("Level");
  vtkNew<vtkIntArray> counts;
  counts->SetName("NumberOfCells");
  if (!tree.empty())
  {
    const int H = tree.height();
    const int l = (level < 0 || level > H) ? H : level;
    mtree::forEachNode(tree, l, [&](const int c[3], uint32_t references) {
      const mtree::Box b = tree.nodeBox(l, c);
      const vtkIdType base = pts->GetNumberOfPoints();
      for (int k = 0; k < 8; ++k)
      {
        pts->InsertNextPoint((k & 1) ? b.hi.x : b.lo.x, (k & 2) ? b.hi.y : b.lo.y, (k & 4) ? b.hi.z : b.lo.z);
      }
      static const int faces[6][4] = { { 0, 2, 6, 4 }, { 1, 5, 7, 3 }, { 0, 4, 5, 1 }, { 2, 3, 7, 6 },
        { 0, 1, 3, 2 }, { 4, 6, 7, 5 } };
      for (const auto& f : faces)
      {
        const vtkIdType q[4] = { base + f[0], base + f[1], base + f[2], base + f[3] };
        quads->InsertNextCell(4, q);
        levels->InsertNextValue(l);
        counts->InsertNextValue(static_cast<int>(references));
      }
    });
  }
  pd->Initialize();
  pd->SetPoints(pts);
  pd->SetPolys(quads);
  pd->GetCellData()->AddArray(levels);
  pd->GetCellData()->AddArray(counts);
}

vtkIdType vtkMatrixTreeLocatorProcessor::Nodes(int minLevel, int maxLevel, vtkUnstructuredGrid* output) const
{
  const mtree::MatrixTree& tree = this->Core.tree;
  vtkNew<vtkPoints> pts;
  pts->SetDataTypeToDouble();
  vtkNew<vtkCellArray> cells;
  vtkNew<vtkIntArray> levels;
  levels->SetName("level");
  vtkNew<vtkDoubleArray> occupancy;
  occupancy->SetName("occupancy");
  vtkNew<vtkIdTypeArray> counts;
  counts->SetName("cell_count");
  vtkNew<vtkIntArray> height;
  height->SetName("tree_height");
  height->InsertNextValue(tree.empty() ? 0 : tree.height());
  output->GetFieldData()->AddArray(height);
  if (tree.empty())
  {
    output->SetPoints(pts);
    output->SetCells(VTK_VOXEL, cells);
    return 0;
  }
  const int H = tree.height();
  const int hi = (maxLevel < 0 || maxLevel > H) ? H : maxLevel;
  const int lo = std::max(0, std::min(minLevel, hi));
  const auto perLevel = mtree::distinctPrimitivesPerNode(tree, lo, hi);
  for (int l = lo; l <= hi; ++l)
  {
    for (const mtree::NodePrimitiveCount& n : perLevel[static_cast<size_t>(l - lo)])
    {
      const mtree::Box b = tree.nodeBox(l, n.c);
      vtkIdType ids[8];
      for (int k = 0; k < 8; ++k)
      {
        ids[k] =
          pts->InsertNextPoint((k & 1) ? b.hi.x : b.lo.x, (k & 2) ? b.hi.y : b.lo.y, (k & 4) ? b.hi.z : b.lo.z);
      }
      cells->InsertNextCell(8, ids);
      levels->InsertNextValue(l);
      occupancy->InsertNextValue(n.occupancy);
      counts->InsertNextValue(static_cast<vtkIdType>(n.primitives));
    }
  }
  output->SetPoints(pts);
  output->SetCells(VTK_VOXEL, cells);
  output->GetCellData()->AddArray(levels);
  output->GetCellData()->AddArray(occupancy);
  output->GetCellData()->AddArray(counts);
  return cells->GetNumberOfCells();
}

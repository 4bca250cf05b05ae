// vtkMatrixTree's split-plane trees (paper §4.1, §4.2) and hybrid (§7): their builds, and their
// nodes as VTK cells for vtkMatrixTreeRepresentation.
#include "vtkMatrixTreeInternals.h"

#include "vtkCellData.h"
#include "vtkFieldData.h"
#include "vtkIntArray.h"
#include "vtkNew.h"
#include "vtkPoints.h"
#include "vtkUnstructuredGrid.h"

#include "mtree/core/tree_queries.h"
#include "mtree/rays/sah_kdtree.h"
#include "mtree/trees/bsp_builder.h"

#include <algorithm>
#include <chrono>

namespace
{
double MsSince(std::chrono::steady_clock::time_point t0)
{
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}
}

namespace vtkMatrixTreeSplitTrees
{
//------------------------------------------------------------------------------
void Build(vtkMatrixTreeInternals& in, int depth, const mtree::BuildOptions& matrix)
{
  in.Tree = mtree::MatrixTree();
  in.Split = mtree::ImplicitSplitTree();
  in.Hybrid = mtree::HybridTree();
  in.Stats = mtree::BuildStats();
  in.PointerBytes = 0;
  mtree::BuildStats& st = in.Stats;
  st.primitives = in.Mesh.size();
  if (in.IsHybrid())
  {
    mtree::HybridBuildOptions opt;
    opt.matrix = matrix;
    mtree::HybridBuildStats hs;
    in.Hybrid.build(in.Mesh, opt, &hs);
    st = hs.matrix;
    st.phasesMs.emplace_back("leaf kd-trees", hs.subtreeMs);
    st.totalMs = hs.totalMs;
    st.references += hs.kdReferences;
    st.leaves = hs.leavesTested + hs.kdLeaves;
    return;
  }
  // The pointer tree (SahKdTree's or the BSP builder's), then its implicit layout (§4).
  const auto t0 = std::chrono::steady_clock::now();
  mtree::PointerSplitTree pointer;
  if (in.Type == vtkMatrixTree::BSP_TREE)
  {
    mtree::BspBuildOptions opt;
    opt.maxDepth = depth;
    pointer = mtree::buildBspTree(in.Mesh, opt);
    st.phasesMs.emplace_back("BSP build", MsSince(t0));
  }
  else
  {
    mtree::SahBuildOptions opt;
    opt.maxDepth = depth;
    pointer = mtree::pointerTreeOf(mtree::SahKdTree(in.Mesh, opt));
    st.phasesMs.emplace_back("SAH build", MsSince(t0));
  }
  const auto t1 = std::chrono::steady_clock::now();
  in.Split.build(pointer, in.Mesh, 0);
  st.phasesMs.emplace_back("implicit layout", MsSince(t1));
  st.totalMs = MsSince(t0);
  st.references = in.Split.primitiveIndices().size();
  st.leaves = in.Split.leafStart().empty() ? 0 : in.Split.leafStart().size() - 1;
  st.height = in.Split.empty() ? 0 : in.Split.numLevels() - 1;
  in.PointerBytes = pointer.pointerBytes();
}

//------------------------------------------------------------------------------
uint64_t CountNodes(const mtree::MatrixTree& tree)
{
  uint64_t n = 0;
  for (int l = 0; !tree.empty() && l <= tree.height(); ++l)
  {
    mtree::forEachNode(tree, l, [&n](const int*, uint32_t) { ++n; });
  }
  return n;
}

//------------------------------------------------------------------------------
void Nodes(const vtkMatrixTreeInternals& in, int minLevel, int maxLevel, vtkUnstructuredGrid* output)
{
  vtkNew<vtkPoints> pts;
  pts->SetDataTypeToDouble();
  vtkNew<vtkIntArray> levels;
  levels->SetName("level");
  vtkNew<vtkIntArray> directions;
  directions->SetName("direction");
  vtkNew<vtkIntArray> height;
  height->SetName("tree_height");
  output->Initialize();
  output->Allocate();
  output->SetPoints(pts);
  const int lo = std::max(minLevel, 0);
  const int hi = maxLevel < 0 ? mtree::ImplicitSplitTree::kMaxLevel + mtree::HybridTree::kMaxDepth : maxLevel;
  std::vector<mtree::SplitPolygon> polys;
  if (in.IsSplit())
  {
    height->InsertNextValue(in.Split.empty() ? 0 : in.Split.numLevels() - 1);
    polys = in.Split.splitPolygons(hi);
  }
  else if (in.IsHybrid() && !in.Hybrid.empty())
  {
    const mtree::MatrixTree& m = in.Hybrid.matrix();
    const int H = m.height();
    height->InsertNextValue(H);
    for (int l = lo; l <= std::min(hi, H); ++l)
    {
      mtree::forEachNode(m, l, [&](const int c[3], uint32_t) {
        const mtree::Box b = m.nodeBox(l, c);
        vtkIdType ids[8];
        for (int k = 0; k < 8; ++k)
        {
          ids[k] =
            pts->InsertNextPoint((k & 1) ? b.hi.x : b.lo.x, (k & 2) ? b.hi.y : b.lo.y, (k & 4) ? b.hi.z : b.lo.z);
        }
        output->InsertNextCell(VTK_VOXEL, 8, ids);
        levels->InsertNextValue(l);
        directions->InsertNextValue(-1);
      });
    }
    if (hi >= H)
    {
      polys = in.Hybrid.splitPolygons(hi - H);
      for (mtree::SplitPolygon& p : polys)
      {
        p.level += H; // a kd root's plane splits its matrix leaf, a node of level H
      }
    }
  }
  else
  {
    height->InsertNextValue(0);
  }
  std::vector<vtkIdType> ids;
  for (const mtree::SplitPolygon& p : polys)
  {
    if (p.level < lo || p.level > hi)
    {
      continue;
    }
    ids.clear();
    for (const mtree::Vec3& q : p.points)
    {
      ids.push_back(pts->InsertNextPoint(q.x, q.y, q.z));
    }
    output->InsertNextCell(VTK_POLYGON, static_cast<vtkIdType>(ids.size()), ids.data());
    levels->InsertNextValue(p.level);
    directions->InsertNextValue(p.dir);
  }
  output->GetCellData()->AddArray(levels);
  output->GetCellData()->AddArray(directions);
  output->GetFieldData()->AddArray(height);
}
}

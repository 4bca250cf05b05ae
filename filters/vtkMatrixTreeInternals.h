// Private to the MatrixTree::Filters module (not wrapped, not installed): the engine objects
// behind vtkMatrixTree, and the conversion of VTK data to engine types.
#ifndef vtkMatrixTreeInternals_h
#define vtkMatrixTreeInternals_h

#include "mtree/core/builder.h"
#include "mtree/core/primitives.h"
#include "mtree/rays/leaf_triangles.h"
#include "mtree/rays/render.h"
#include "mtree/trees/hybrid_tree.h"
#include "mtree/trees/implicit_tree.h"

#include "vtkMatrixTree.h"
#include "vtkMatrixTreeTuning.h"

#include <string>
#include <utility>
#include <vector>

#include "vtkType.h"

class vtkPolyData;

struct vtkMatrixTreeInternals
{
  mtree::TriangleMesh Mesh;
  std::vector<vtkIdType> CellOfTriangle; // source polydata cell of every engine triangle
  /// The built tree: one of the three, by Type (vtkMatrixTree::TreeTypes); the others are empty.
  int Type = 0;
  mtree::MatrixTree Tree;          // OCTREE, KDTREE
  mtree::LeafTriangles Payload;    // Tree's leaf triangles for the ray queries (LeafTriangles)
  mtree::ImplicitSplitTree Split;  // IMPLICIT_KDTREE, BSP_TREE
  mtree::HybridTree Hybrid;        // HYBRID
  vtkMatrixTreeTuning Tuning; // the developer settings (vtkMatrixTree::SetTuning)
  mtree::BuildStats Stats; // matrix trees and the hybrid's matrix part; phases and total for all
  uint64_t PointerBytes = 0; // a split tree in SahKdNode's pointer layout (pointerBytes())
  bool Valid = false;

  bool IsSplit() const
  {
    return this->Type == vtkMatrixTree::IMPLICIT_KDTREE || this->Type == vtkMatrixTree::BSP_TREE;
  }
  bool IsHybrid() const { return this->Type == vtkMatrixTree::HYBRID; }
  /// The matrix tree of the matrix trees and of the hybrid (nullptr for the split trees).
  const mtree::MatrixTree* Matrix() const
  {
    return this->IsSplit() ? nullptr : (this->IsHybrid() ? &this->Hybrid.matrix() : &this->Tree);
  }

  /**
   * f(tracer) with the CPU tracer (render.h's interface) of the built tree over Mesh:
   * MatrixTreeTracer (with the leaf triangles where kept), ImplicitTreeTracer with Tuning.SplitTraversal, or HybridTracer; returns f's
   * result.
   */
  template <class F>
  decltype(auto) WithTracer(mtree::TriangleTest test, F&& f) const
  {
    if (this->IsSplit())
    {
      const auto walk = static_cast<mtree::SplitTraversal>(this->Tuning.SplitTraversal);
      return std::forward<F>(f)(mtree::ImplicitTreeTracer{ this->Split, this->Mesh, walk, test });
    }
    if (this->IsHybrid())
    {
      return std::forward<F>(f)(mtree::HybridTracer{ this->Hybrid, this->Mesh, test });
    }
    return std::forward<F>(f)(
      mtree::MatrixTreeTracer{ this->Tree, this->Mesh, test, this->Payload.empty() ? nullptr : &this->Payload });
  }
};

class vtkUnstructuredGrid;

/// The split-plane trees and the hybrid behind vtkMatrixTree (vtkMatrixTreeSplitTrees.cxx).
namespace vtkMatrixTreeSplitTrees
{
/**
 * Builds in.Type's tree over in.Mesh into in.Split or in.Hybrid and fills in.Stats (phases,
 * total, leaves, references, height) and in.PointerBytes. IMPLICIT_KDTREE: a SahKdTree with depth
 * limit `depth` (0 = its automatic limit) stored in the implicit layout; BSP_TREE: buildBspTree's
 * tree (26-DOP planes, the same depth limit) in the same layout; HYBRID: a HybridTree whose
 * matrix part is built with `matrix`. Both layouts take the block shape of least bytes per level.
 * Throws the engine's exceptions (bad options, trees past their limits).
 */
void Build(vtkMatrixTreeInternals& in, int depth, const mtree::BuildOptions& matrix);
/** Existing nodes of every level of a matrix tree. */
uint64_t CountNodes(const mtree::MatrixTree& tree);
/**
 * vtkMatrixTreeRepresentation's output for a split tree or the hybrid: each inner node's plane of
 * levels [minLevel, maxLevel] (maxLevel < 0: every level) as a VTK_POLYGON clipped to the node's
 * cell, and for the hybrid each existing matrix node of those levels as a VTK_VOXEL (its kd planes
 * start at the matrix leaves' level, the matrix height). Cell data "level" and "direction" (the
 * plane's direction index, SplitFrame; -1 for a voxel); field data "tree_height" (GetTreeHeight()).
 */
void Nodes(const vtkMatrixTreeInternals& in, int minLevel, int maxLevel, vtkUnstructuredGrid* output);
}

namespace vtkMatrixTreeConvert
{
/**
 * Triangulates the polygons and strips of `pd` (triangles as they are, quads and other polygons
 * as fans from their first point, strips alternating) into an engine mesh. Vertices and lines
 * are skipped. `cellOfTriangle` receives the source cell id of every triangle.
 * Returns false and fills `error` when the engine refuses the mesh (coordinates out of
 * mtree::checkCoordinateRange's range, more than 2^32 - 1 points).
 */
bool ToTriangleMesh(vtkPolyData* pd, mtree::TriangleMesh& mesh, std::vector<vtkIdType>& cellOfTriangle,
  std::string& error);
}

#endif

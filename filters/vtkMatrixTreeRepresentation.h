/**
 * @class   vtkMatrixTreeRepresentation
 * @brief   the matrix tree of a data set's cells as an unstructured grid of node boxes, or the
 *          split planes of an implicit kd-tree, BSP tree or hybrid tree
 *
 * vtkMatrixTreeRepresentation builds (or borrows) a vtkMatrixTreeLocator over the cells of its
 * input (any vtkDataSet) and outputs one VTK_VOXEL per existing node of the chosen levels, so
 * the tree can be viewed in any VTK viewer (ParaView, pyvista). Cell data:
 * - "level" (int): 0 = root, the tree height = leaves;
 * - "occupancy" (double): for an inner node, the fraction of its children that exist (an
 *   octree node has 8 children, a kd-tree node 2; fewer where an axis is not split); 1 for a
 *   leaf (leaves exist only when they hold cells);
 * - "cell_count" (vtkIdType): distinct input cells (triangles, for a surface) overlapping the
 *   node under the build's overlap test; for a leaf, the candidates a point query tests.
 * Field data "tree_height" holds the height.
 *
 * TreeType IMPLICIT_KDTREE, BSP_TREE or HYBRID (vtkMatrixTree's, over the triangles of a
 * vtkPolyData input; another input is an error) outputs instead each inner node's split plane of
 * the chosen levels as a VTK_POLYGON clipped to the node's cell (the root box cut by the planes
 * above it), and for the hybrid each existing node of its matrix part as a VTK_VOXEL, its
 * kd-trees' planes starting at the matrix leaves' level (MaxLevel -1: every level). Cell data
 * "level" and "direction" (the plane's direction: 0-2 the axes, 3-12 the BSP tree's diagonal
 * directions, -1 for a voxel); field data "tree_height" (vtkMatrixTree::GetTreeHeight()).
 *
 * Settings: MinLevel (default 0) and MaxLevel (default -1 = the leaf level) choose the levels;
 * TreeType, Height, BlockSize and ExactOverlap configure the internal locator (or, for the
 * three tree types above, the internal vtkMatrixTree). With SetLocator the given locator is used
 * instead (its settings apply, its tree is reused when it is already built on this input, and the
 * filter's tree settings are ignored).
 *
 * @sa
 * vtkMatrixTreeLocator vtkMatrixTree
 */
#ifndef vtkMatrixTreeRepresentation_h
#define vtkMatrixTreeRepresentation_h

#include "MatrixTreeFiltersModule.h" // For export macro
#include "vtkUnstructuredGridAlgorithm.h"

class vtkMatrixTree;
class vtkMatrixTreeLocator;

class MATRIXTREEFILTERS_EXPORT vtkMatrixTreeRepresentation : public vtkUnstructuredGridAlgorithm
{
public:
  static vtkMatrixTreeRepresentation* New();
  vtkTypeMacro(vtkMatrixTreeRepresentation, vtkUnstructuredGridAlgorithm);
  void PrintSelf(ostream& os, vtkIndent indent) override;

  ///@{
  /** First level written (0 = root, default). */
  vtkSetClampMacro(MinLevel, int, 0, 63);
  vtkGetMacro(MinLevel, int);
  ///@}

  ///@{
  /** Last level written; -1 (default) or anything past the height = the leaf level. */
  vtkSetClampMacro(MaxLevel, int, -1, 63);
  vtkGetMacro(MaxLevel, int);
  ///@}

  ///@{
  /**
   * Tree: vtkMatrixTree::TreeTypes: OCTREE (0, default) and KDTREE (1) of the internal locator,
   * IMPLICIT_KDTREE (2), BSP_TREE (3) and HYBRID (4) of the internal vtkMatrixTree.
   */
  vtkSetClampMacro(TreeType, int, 0, 4);
  vtkGetMacro(TreeType, int);
  ///@}

  ///@{
  /** Height of the internal locator's tree (0 = automatic, default). */
  vtkSetClampMacro(Height, int, 0, 63);
  vtkGetMacro(Height, int);
  ///@}

  ///@{
  /** Block edge of the internal locator (power of two 1..32, default 8). */
  vtkSetMacro(BlockSize, int);
  vtkGetMacro(BlockSize, int);
  ///@}

  ///@{
  /** Bounding-box (default, as vtkMatrixTreeLocator's) or exact cell/leaf overlap of the internal locator. */
  vtkSetMacro(ExactOverlap, bool);
  vtkGetMacro(ExactOverlap, bool);
  vtkBooleanMacro(ExactOverlap, bool);
  ///@}

  ///@{
  /** A locator to use instead of the internal one (nullptr, default: the internal one). */
  void SetLocator(vtkMatrixTreeLocator* locator);
  vtkGetObjectMacro(Locator, vtkMatrixTreeLocator);
  ///@}

  /** Includes the locator's modification time. */
  vtkMTimeType GetMTime() override;

protected:
  vtkMatrixTreeRepresentation();
  ~vtkMatrixTreeRepresentation() override;

  int FillInputPortInformation(int port, vtkInformation* info) override;
  int RequestData(vtkInformation* request, vtkInformationVector** inputVector,
    vtkInformationVector* outputVector) override;

  int MinLevel = 0;
  int MaxLevel = -1;
  int TreeType = 0;
  int Height = 0;
  int BlockSize = 8;
  bool ExactOverlap = false;
  vtkMatrixTreeLocator* Locator = nullptr;
  vtkMatrixTreeLocator* InternalLocator = nullptr;
  vtkMatrixTree* InternalTree = nullptr;

private:
  vtkMatrixTreeRepresentation(const vtkMatrixTreeRepresentation&) = delete;
  void operator=(const vtkMatrixTreeRepresentation&) = delete;
};

#endif

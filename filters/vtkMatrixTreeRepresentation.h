/**
 * @class   vtkMatrixTreeRepresentation
 * @brief   the matrix tree of a data set's cells as an unstructured grid of node boxes
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
 * Settings: MinLevel (default 0) and MaxLevel (default -1 = the leaf level) choose the levels;
 * TreeType, Height, BlockSize and ExactOverlap configure the internal locator. With SetLocator
 * the given locator is used instead (its settings apply, its tree is reused when it is already
 * built on this input, and the filter's tree settings are ignored).
 *
 * @sa
 * vtkMatrixTreeLocator vtkMatrixTree
 */
#ifndef vtkMatrixTreeRepresentation_h
#define vtkMatrixTreeRepresentation_h

#include "MatrixTreeFiltersModule.h" // For export macro
#include "vtkUnstructuredGridAlgorithm.h"

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
  /** Tree of the internal locator: 0 = octree (default), 1 = regular kd-tree. */
  vtkSetClampMacro(TreeType, int, 0, 1);
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

private:
  vtkMatrixTreeRepresentation(const vtkMatrixTreeRepresentation&) = delete;
  void operator=(const vtkMatrixTreeRepresentation&) = delete;
};

#endif

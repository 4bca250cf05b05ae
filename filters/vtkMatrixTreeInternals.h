// Private to the MatrixTree::Filters module (not wrapped, not installed): the engine objects
// behind vtkMatrixTree, and the conversion of VTK data to engine types.
#ifndef vtkMatrixTreeInternals_h
#define vtkMatrixTreeInternals_h

#include "mtree/core/builder.h"
#include "mtree/core/primitives.h"

#include <string>
#include <vector>

#include "vtkType.h"

class vtkPolyData;

struct vtkMatrixTreeInternals
{
  mtree::TriangleMesh Mesh;
  std::vector<vtkIdType> CellOfTriangle; // source polydata cell of every engine triangle
  mtree::MatrixTree Tree;
  mtree::BuildStats Stats;
  bool Valid = false;
};

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

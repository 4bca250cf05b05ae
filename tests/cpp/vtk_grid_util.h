// Shared by the C++ tests that need the real CFD grids as VTK datasets: SU2 (read here, the
// tests do not depend on meshio) and VTK XML unstructured grids.
#pragma once

#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <vtkIdList.h>
#include <vtkNew.h>
#include <vtkPoints.h>
#include <vtkSmartPointer.h>
#include <vtkUnstructuredGrid.h>
#include <vtkVersionMacros.h>
#include <vtkXMLUnstructuredGridReader.h>

#include "mtree/cells/cells.h"
#include "mtree/cells/segment_filter.h"
#include "mtree/vtk91/cell_faces.h"
#include "test_util.h"

namespace mtest {

/// How the VTK these tests link splits a quad for IntersectWithLine (segment_filter.h's
/// QuadSplit), as the locator tells its ray tests.
constexpr mtree::QuadSplit kVtkQuadSplit = mtree::vtk91::quadSplitOfVtk(VTK_MAJOR_VERSION, VTK_MINOR_VERSION);

/// The volume cells of an SU2 mesh (NDIME, NELEM lines "type ids... index", NPOIN lines
/// "x y z [index]"; markers skipped). SU2 element types are VTK's cell type codes.
inline vtkSmartPointer<vtkUnstructuredGrid> readSu2(const std::string& path) {
  std::ifstream in(path);
  if (!in) return nullptr;
  auto grid = vtkSmartPointer<vtkUnstructuredGrid>::New();
  vtkNew<vtkPoints> pts;
  pts->SetDataTypeToDouble();
  std::vector<int> types;
  std::vector<std::vector<vtkIdType>> cells;
  std::string line;
  int dim = 3;
  while (std::getline(in, line)) {
    if (line.rfind("NDIME=", 0) == 0) {
      dim = std::stoi(line.substr(6));
    } else if (line.rfind("NELEM=", 0) == 0) {
      const long n = std::stol(line.substr(6));
      for (long e = 0; e < n && std::getline(in, line); ++e) {
        std::istringstream ls(line);
        int type = 0;
        ls >> type;
        const int np = type == 10 ? 4 : type == 12 ? 8 : type == 13 ? 6 : type == 14 ? 5 : type == 5 ? 3 : 4;
        std::vector<vtkIdType> ids(np);
        for (auto& id : ids) ls >> id;
        types.push_back(type);
        cells.push_back(ids);
      }
    } else if (line.rfind("NPOIN=", 0) == 0) {
      const long n = std::stol(line.substr(6));
      for (long i = 0; i < n && std::getline(in, line); ++i) {
        std::istringstream ls(line);
        double x[3] = {0, 0, 0};
        for (int a = 0; a < dim; ++a) ls >> x[a];
        pts->InsertNextPoint(x);
      }
    } else if (line.rfind("NMARK=", 0) == 0) {
      break;
    }
  }
  grid->SetPoints(pts);
  grid->Allocate(static_cast<vtkIdType>(cells.size()));
  for (size_t c = 0; c < cells.size(); ++c)
    grid->InsertNextCell(types[c], static_cast<vtkIdType>(cells[c].size()), cells[c].data());
  return grid;
}

/// A grid by its path under the shared data folder (e.g. "cfd/brick_hex.su2"); nullptr if unreadable.
inline vtkSmartPointer<vtkUnstructuredGrid> readGrid(const std::string& rel) {
  const std::string path = dataPath(rel);
  if (rel.size() > 4 && rel.compare(rel.size() - 4, 4, ".su2") == 0) return readSu2(path);
  vtkNew<vtkXMLUnstructuredGridReader> r;
  r->SetFileName(path.c_str());
  r->Update();
  if (r->GetOutput()->GetNumberOfCells() == 0) return nullptr;
  return vtkSmartPointer<vtkUnstructuredGrid>(r->GetOutput());
}

/// A grid's cells as the engine's CellSet (points as doubles, the grid's cell order).
inline mtree::CellSet cellSet(vtkUnstructuredGrid* g) {
  const vtkIdType np = g->GetNumberOfPoints(), nc = g->GetNumberOfCells();
  std::vector<double> pts(static_cast<size_t>(np) * 3);
  for (vtkIdType i = 0; i < np; ++i) g->GetPoint(i, &pts[3 * i]);
  std::vector<uint32_t> off(static_cast<size_t>(nc) + 1, 0), conn;
  std::vector<uint8_t> types(static_cast<size_t>(nc));
  vtkNew<vtkIdList> ids;
  for (vtkIdType c = 0; c < nc; ++c) {
    types[c] = static_cast<uint8_t>(g->GetCellType(c));
    g->GetCellPoints(c, ids);
    for (vtkIdType k = 0; k < ids->GetNumberOfIds(); ++k) conn.push_back(static_cast<uint32_t>(ids->GetId(k)));
    off[c + 1] = static_cast<uint32_t>(conn.size());
  }
  return mtree::CellSet(std::move(pts), std::move(off), std::move(conn), std::move(types));
}

}  // namespace mtest

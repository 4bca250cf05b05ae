#include "vtkMatrixTreeCellSetSource.h"
#include "vtkMatrixTreeLocatorTuning.h"

#include "vtkCellArray.h"
#include "vtkCellType.h"
#include "vtkDataSet.h"
#include "vtkDoubleArray.h"
#include "vtkFloatArray.h"
#include "vtkIdList.h"
#include "vtkNew.h"
#include "vtkPointSet.h"
#include "vtkPoints.h"
#include "vtkPolyData.h"
#include "vtkUnsignedCharArray.h"
#include "vtkUnstructuredGrid.h"

#include "mtree/core/parallel.h"

#include <algorithm>
#include <utility>

namespace
{
// The cell types of a polygon-only vtkPolyData's nc cells from its offsets: 3 points a
// triangle, 4 a quad; other sizes are asked of the data set.
template <class I>
void PolygonTypes(vtkDataSet* ds, const I* offsets, vtkIdType nc, std::vector<uint8_t>& types)
{
  types.resize(static_cast<size_t>(nc));
  for (vtkIdType c = 0; c < nc; ++c)
  {
    const auto n = offsets[c + 1] - offsets[c];
    types[c] = static_cast<uint8_t>(n == 3 ? VTK_TRIANGLE : (n == 4 ? VTK_QUAD : ds->GetCellType(c)));
  }
}
}

bool vtkMatrixTreeCellSetSource::Read(vtkDataSet* ds, int storage, int threads, std::string& error)
{
  // Nothing of the last Read() is left; the held arrays stay until MakeCellSet() replaces them.
  this->NumberOfPoints = 0;
  this->ViewFloats = nullptr;
  this->ViewDoubles = nullptr;
  this->PointCopy.clear();
  this->ViewCells = false;
  this->CellView = mtree::CellArrays();
  this->ViewOffsets = this->ViewConnectivity = this->ViewTypes = nullptr;
  this->Offsets.clear();
  this->Connectivity.clear();
  this->Types.clear();
  const vtkIdType np = ds->GetNumberOfPoints();
  const vtkIdType nc = ds->GetNumberOfCells();
  vtkPointSet* ps = vtkPointSet::SafeDownCast(ds);
  vtkDataArray* pdata = ps && ps->GetPoints() ? ps->GetPoints()->GetData() : nullptr;
  if (pdata && pdata->GetNumberOfComponents() == 3 && pdata->GetNumberOfTuples() == np)
  {
    this->ViewFloats = vtkFloatArray::FastDownCast(pdata);
    this->ViewDoubles = vtkDoubleArray::FastDownCast(pdata);
  }
  if (!this->ViewFloats && !this->ViewDoubles)
  {
    this->PointCopy.resize(static_cast<size_t>(np) * 3);
    for (vtkIdType i = 0; i < np; ++i)
    {
      ds->GetPoint(i, &this->PointCopy[3 * i]);
    }
  }
  if (np >= 0xffffffffLL)
  {
    error = "more than 2^32 - 1 points are not supported.";
    return false;
  }
  this->NumberOfPoints = static_cast<size_t>(np);
  vtkUnstructuredGrid* ug = vtkUnstructuredGrid::SafeDownCast(ds);
  vtkCellArray* ca = ug && ug->GetCellTypesArray() ? ug->GetCells() : nullptr;
  // Polydata with polygons only (the surface meshes): cell c is polygon c, so its cell array is
  // read the same way; the types follow from the sizes.
  vtkPolyData* pd = ug ? nullptr : vtkPolyData::SafeDownCast(ds);
  const bool polysOnly = pd && pd->GetPolys() && pd->GetNumberOfVerts() == 0 && pd->GetNumberOfLines() == 0 &&
    pd->GetNumberOfStrips() == 0;
  if (!ca && polysOnly)
  {
    ca = pd->GetPolys();
  }
  const bool inPlace = storage == vtkMatrixTreeLocatorTuning::CELLS_IN_PLACE ||
    (storage == vtkMatrixTreeLocatorTuning::CELLS_AUTOMATIC && ca &&
      (!ca->IsStorage64Bit() || ca->GetNumberOfConnectivityIds() > 5 * ca->GetNumberOfCells()));
  this->ViewCells =
    inPlace && ca && nc > 0 && ca->GetNumberOfCells() == nc && (this->ViewFloats || this->ViewDoubles);
  if (this->ViewCells)
  {
    auto view = [&](auto* off, auto* cn) {
      this->ViewOffsets = off;
      this->ViewConnectivity = cn;
      mtree::CellArrays& v = this->CellView;
      v.offsets = off->GetPointer(0);
      v.connectivity = cn->GetPointer(0);
      v.connectivitySize = static_cast<size_t>(cn->GetNumberOfValues());
      v.indexBytes = static_cast<int>(sizeof(*off->GetPointer(0)));
      v.numCells = static_cast<size_t>(nc);
      if (ug)
      {
        this->ViewTypes = ug->GetCellTypesArray();
        v.types = ug->GetCellTypesArray()->GetPointer(0);
        return;
      }
      PolygonTypes(ds, off->GetPointer(0), nc, v.typeCopy);
    };
    if (ca->IsStorage64Bit())
    {
      view(ca->GetOffsetsArray64(), ca->GetConnectivityArray64());
    }
    else
    {
      view(ca->GetOffsetsArray32(), ca->GetConnectivityArray32());
    }
    return true;
  }
  std::vector<uint32_t>& offsets = this->Offsets;
  std::vector<uint32_t>& conn = this->Connectivity;
  std::vector<uint8_t>& types = this->Types;
  offsets.assign(static_cast<size_t>(nc) + 1, 0);
  types.resize(static_cast<size_t>(nc));
  if (ca && ca->GetNumberOfCells() == nc)
  {
    // Unstructured grids and polygon meshes: the cell arrays copied directly (a per-cell loop
    // through the data set costs more than the whole tree build).
    if (ug)
    {
      const unsigned char* t = ug->GetCellTypesArray()->GetPointer(0);
      std::copy(t, t + nc, types.begin());
    }
    bool fits = true;
    auto copyArrays = [&](auto* off, auto* cn) {
      const auto* o = off->GetPointer(0);
      const auto* cc = cn->GetPointer(0);
      const vtkIdType m = cn->GetNumberOfValues();
      if (m >= 0xffffffffLL)
      {
        fits = false;
        return;
      }
      conn.resize(static_cast<size_t>(m));
      // Negative or too large values become 2^32 - 1, which the CellSet's range check rejects.
#pragma omp parallel for num_threads(threads) schedule(static) if (m > mtree::kSerialBelow)
      for (vtkIdType k = 0; k < m; ++k)
      {
        conn[k] = (cc[k] < 0 || static_cast<long long>(cc[k]) >= np) ? 0xffffffffu : static_cast<uint32_t>(cc[k]);
      }
#pragma omp parallel for num_threads(threads) schedule(static) if (nc > mtree::kSerialBelow)
      for (vtkIdType c = 0; c <= nc; ++c)
      {
        offsets[c] = static_cast<uint32_t>(o[c]);
      }
    };
    if (ca->IsStorage64Bit())
    {
      copyArrays(ca->GetOffsetsArray64(), ca->GetConnectivityArray64());
    }
    else
    {
      copyArrays(ca->GetOffsetsArray32(), ca->GetConnectivityArray32());
    }
    if (!fits)
    {
      error = "more than 2^32 - 1 connectivity entries are not supported.";
      return false;
    }
    if (!ug)
    {
      PolygonTypes(ds, offsets.data(), nc, types);
    }
    return true;
  }
  conn.reserve(static_cast<size_t>(nc) * 4);
  vtkNew<vtkIdList> ids;
  for (vtkIdType c = 0; c < nc; ++c)
  {
    types[c] = static_cast<uint8_t>(ds->GetCellType(c));
    ds->GetCellPoints(c, ids);
    for (vtkIdType k = 0; k < ids->GetNumberOfIds(); ++k)
    {
      conn.push_back(static_cast<uint32_t>(ids->GetId(k)));
    }
    if (conn.size() >= 0xffffffffu)
    {
      error = "more than 2^32 - 1 connectivity entries are not supported.";
      return false;
    }
    offsets[c + 1] = static_cast<uint32_t>(conn.size());
  }
  return true;
}

void vtkMatrixTreeCellSetSource::MakeCellSet(int threads, mtree::CellSet& cells)
{
  this->PointArray = nullptr;
  this->OffsetsArray = nullptr;
  this->ConnectivityArray = nullptr;
  this->TypesArray = nullptr;
  auto viewPoints = [&](auto* array) {
    if (this->ViewCells)
    {
      cells = mtree::CellSet(array->GetPointer(0), this->NumberOfPoints, std::move(this->CellView), threads);
      this->OffsetsArray = this->ViewOffsets;
      this->ConnectivityArray = this->ViewConnectivity;
      this->TypesArray = this->ViewTypes;
    }
    else
    {
      cells = mtree::CellSet(array->GetPointer(0), this->NumberOfPoints, std::move(this->Offsets),
        std::move(this->Connectivity), std::move(this->Types), threads);
    }
    this->PointArray = array;
  };
  if (this->ViewFloats)
  {
    viewPoints(this->ViewFloats);
  }
  else if (this->ViewDoubles)
  {
    viewPoints(this->ViewDoubles);
  }
  else
  {
    cells = mtree::CellSet(std::move(this->PointCopy), std::move(this->Offsets), std::move(this->Connectivity),
      std::move(this->Types), threads);
  }
}

// Private to the MatrixTree::Filters module (not wrapped, not installed): the cells of a
// vtkDataSet as an mtree::CellSet, for vtkMatrixTreeLocator's build.
//
// Points: a float or double array of 3 components is read in place (as VTK's own locators read
// the data set); any other array, and a data set without a point array, is copied as doubles.
// Cells: with the points read in place, an unstructured grid's or a polygon-only polydata's
// vtkCellArray may be read in place too (32- or 64-bit offsets and connectivity, the grid's
// types; a polygon mesh's types from the polygon sizes), per vtkMatrixTreeLocatorTuning's
// CellStorage; otherwise the point ids are copied to 32 bits (a direct copy of those cell
// arrays, or GetCellPoints per cell for other data sets). Invariant: every array the CellSet
// reads in place is held here by reference, so it outlives a SetPoints() or SetCells() on the
// data set until the next Read() or the source's destruction.
#ifndef vtkMatrixTreeCellSetSource_h
#define vtkMatrixTreeCellSetSource_h

#include "mtree/cells/cells.h"

#include "vtkSmartPointer.h"
#include "vtkType.h"

#include <cstdint>
#include <string>
#include <vector>

class vtkDataArray;
class vtkDataSet;
class vtkDoubleArray;
class vtkFloatArray;

class vtkMatrixTreeCellSetSource
{
public:
  /**
   * Reads the points and cells of `ds` (the conversion: point and connectivity copies where
   * needed), with `threads` OpenMP threads for the copies. storage: a
   * vtkMatrixTreeLocatorTuning::CellStorages value. False, with `error` set and nothing read,
   * for more than 2^32 - 1 points or connectivity entries.
   */
  bool Read(vtkDataSet* ds, int storage, int threads, std::string& error);
  /**
   * Moves what Read() gathered into `cells` (the CellSet's constructor: bounds and extents on
   * `threads` threads) and holds the arrays it reads in place, releasing those of the previous
   * build first. Throws what the CellSet's constructor throws (bad indices, too many cells).
   */
  void MakeCellSet(int threads, mtree::CellSet& cells);

private:
  // Read()'s result, consumed by MakeCellSet().
  size_t NumberOfPoints = 0;
  vtkFloatArray* ViewFloats = nullptr;   // the point array read in place, float or double
  vtkDoubleArray* ViewDoubles = nullptr;
  std::vector<double> PointCopy;          // the points otherwise
  bool ViewCells = false;                 // whether the cell arrays are read in place
  mtree::CellArrays CellView;
  vtkDataArray* ViewOffsets = nullptr;
  vtkDataArray* ViewConnectivity = nullptr;
  vtkDataArray* ViewTypes = nullptr;
  std::vector<uint32_t> Offsets, Connectivity; // the 32-bit copy otherwise
  std::vector<uint8_t> Types;

  // The arrays the current CellSet reads in place.
  vtkSmartPointer<vtkDataArray> PointArray, OffsetsArray, ConnectivityArray, TypesArray;
};

#endif

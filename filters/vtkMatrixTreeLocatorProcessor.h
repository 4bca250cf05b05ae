// Private to the MatrixTree::Filters module (not wrapped, not installed): what
// vtkMatrixTreeLocator's public methods delegate to. It reads the data set's cells
// (vtkMatrixTreeCellSetSource), builds and queries them with the engine's one locator algorithm
// (mtree::vtk91::LocatorCore, the same as the VTK-free mtree::CellLocator's), with VTK's own
// cells as the oracle for what the engine's fast decisions leave open
// (vtkMatrixTreeCellBridge::Oracle), and converts the answers to VTK's types; the locator only
// decides when to build and checks its arguments.
//
// Invariants: Core describes the cells of the data set the build read (BuiltOn), whose arrays
// Source holds; Valid is false until a build completes. Queries only read the build, so they
// may run concurrently.
#ifndef vtkMatrixTreeLocatorProcessor_h
#define vtkMatrixTreeLocatorProcessor_h

#include "vtkMatrixTreeBackend.h"
#include "vtkMatrixTreeCellSetSource.h"
#include "vtkMatrixTreeLocatorTuning.h"
#include "vtkMatrixTreeQueryStatistics.h"

#include "mtree/device/opencl.h"
#include "mtree/vtk91/locator_core.h"

#include "vtkType.h"

#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

class vtkDataArray;
class vtkDataSet;
class vtkGenericCell;
class vtkIdList;
class vtkObject;
class vtkPoints;
class vtkPolyData;
class vtkUnstructuredGrid;

class vtkMatrixTreeLocatorProcessor
{
public:
  /** The locator's build settings (its public settings, the tuning's build fields). */
  struct BuildSettings
  {
    bool Kd = false; // TreeType KDTREE
    int Height = 0;
    int BlockSize = 8;
    bool ExactOverlap = false;
    double LeafScale = 0;
    double MaxCandidates = 0;
    int NumberOfThreads = 0;
    int BuildSort = vtkMatrixTreeLocatorTuning::COUNTING;
    int CellStorage = vtkMatrixTreeLocatorTuning::CELLS_AUTOMATIC;
    bool CacheCellBounds = false;
  };

  /**
   * Builds on `ds` (not null): false with `error` set (the message after "BuildLocator: ") when
   * the settings or the data set cannot be built. `progress` gets vtkCommand::ProgressEvent at
   * 0.2 (cells read) and 1.0 (done).
   */
  bool Build(vtkDataSet* ds, const BuildSettings& s, vtkObject* progress, std::string& error);

  // ---- queries on the build (Valid) ----
  /** FindCell: the leaf holding x, scanned from its first candidate (inline: most points of a
   * surface's box are in no leaf, answered here). */
  vtkIdType FindCell(
    vtkDataSet* ds, const double x[3], vtkGenericCell* cell, double pcoords[3], double* weights) const;
  /**
   * The point-location loop over the candidates [k, end) of leaf n, the leaf leafHolding gives
   * for x: FindCell runs it from the leaf's first candidate, the OpenCL backend from the
   * candidate where the device stopped. The first candidate in the leaf's order (ascending ids)
   * that contains x, or -1.
   */
  vtkIdType ScanLeaf(vtkDataSet* ds, const double x[3], const mtree::NodeRef& n, uint32_t k, vtkGenericCell* cell,
    double pcoords[3], double* weights) const;
  /** IntersectWithLine's first hit (LocatorCore::firstHit, VTK's cells the oracle). */
  int FirstHit(vtkDataSet* ds, const double p1[3], const double p2[3], double tol, double& t, double x[3],
    double pcoords[3], int& subId, vtkIdType& cellId, vtkGenericCell* cell) const;
  /** Every hit of the segment, sorted by t then cell id; the number of hits. */
  int AllHits(vtkDataSet* ds, const double p1[3], const double p2[3], vtkPoints* points, vtkIdList* cellIds) const;
  /** FindClosestPointWithinRadius (a non-empty tree, radius >= 0); 0 for a non-finite x. */
  vtkIdType ClosestPoint(vtkDataSet* ds, const double x[3], double radius, double closestPoint[3],
    vtkGenericCell* cell, vtkIdType& cellId, int& subId, double& dist2, int& inside) const;
  /** The cells whose bounds meet bbox (xmin xmax ymin ymax zmin zmax), ascending. */
  void CellsWithinBounds(const double bbox[6], vtkIdList* cells) const;
  /** The cells whose bounds, grown by tol, the segment crosses, ascending. */
  void CellsAlongLine(const double p1[3], const double p2[3], double tol, vtkIdList* cells) const;
  /** GenerateRepresentation's quads of level `level` into pd. */
  void Representation(int level, vtkPolyData* pd) const;
  /** GenerateNodes's voxels of levels minLevel..maxLevel into output; their number. */
  vtkIdType Nodes(int minLevel, int maxLevel, vtkUnstructuredGrid* output) const;

  // ---- the OpenCL backend of FindCells ----
  /**
   * Uploads the build to the device `selector` names where it is not there yet, and locates the
   * points there: answers gets 2 words per point (outcome, candidate; see
   * mtree::ocl::CellLocator). True when this call copied the build. FindPhases gets "upload ...;
   * points ...; kernel ...; download ...; device call ...", and FindCells with these answers
   * adds "host ...; total ...". Throws on device errors.
   */
  bool LocateOnDevice(const std::string& selector, vtkPoints* points, std::vector<uint32_t>& answers);

  /**
   * FindCells' loop over the points (mtree::vtk91::runBatch, `threads`): per point i, ids[i]
   * as FindCell gives it (-1: none), pcoords (3 per point, optional) and weights (nw per point,
   * optional) as FindCell writes them for the found cell and 0 elsewhere. With `answers` (the
   * device's, 2 per point) each point is finished from where the device stopped: a "found" is
   * confirmed by the cell's evaluation where pcoords or weights are asked for (an unconfirmed
   * one, and a "resume", rescan the leaf from that candidate). resumes / unconfirmed: how many
   * points the host finished, and how many device answers were not confirmed.
   */
  void FindCells(vtkDataSet* ds, vtkPoints* points, const uint32_t* answers, int threads, vtkIdType* ids,
    double* pcoords, double* weights, int nw, vtkIdType& resumes, vtkIdType& unconfirmed);

  /**
   * IntersectSegments' loop (`threads`): per segment i of p1 -> p2 (3-component arrays), the
   * first hit's t (+inf on a miss), cell (-1) and point (NaN; xp optional).
   */
  void IntersectSegments(vtkDataSet* ds, vtkDataArray* p1, vtkDataArray* p2, double tol, int threads, double* t,
    vtkIdType* ids, double* xp) const;
  /**
   * FindClosestPoints' loop (`threads`): per point, the closest point on the cells (NaN when
   * there is none), the cell (-1) and the squared distance (+inf; dist2 optional).
   */
  void ClosestPoints(vtkDataSet* ds, vtkPoints* points, int threads, double* closest, vtkIdType* ids,
    double* dist2) const;

  /** Bytes held (see vtkMatrixTreeLocator::GetMemorySize). */
  size_t MemorySize() const;

  /** Sets the tuning (BuildSort and CellStorage clamped to their ranges); true when a build
   * field changed (the next query rebuilds). */
  bool SetTuning(const vtkMatrixTreeLocatorTuning& tuning);
  vtkMatrixTreeLocatorTuning Tuning; // the query fields are read per query

  // The build.
  vtkMatrixTreeCellSetSource Source; // holds the arrays Core.cells reads in place
  mtree::vtk91::LocatorCore Core;
  vtkDataSet* BuiltOn = nullptr; // the data set of the last build (compared, never dereferenced)
  std::string Phases;            // "name ms; ..." of the last build
  double TotalMs = 0;            // the last build's time
  bool Valid = false;

  // The OpenCL backend: the device locator for the selector, and whether it holds the current
  // build (cleared by every build, so the device gets the build again only after one).
  std::unique_ptr<mtree::ocl::CellLocator> CL;
  vtkMatrixTreeDevice CLDevice; // the OpenCL device of the OPENCL backend
  bool CLUploaded = false;
  std::string FindPhases; // "name ms; ..." of the last OpenCL FindCells
  std::chrono::steady_clock::time_point DeviceStart; // when the last OpenCL FindCells began
};

#endif

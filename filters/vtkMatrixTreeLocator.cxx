#include "vtkMatrixTreeLocator.h"

#include "vtkMatrixTreeBackend.h"
#include "vtkMatrixTreeLocatorProcessor.h"
#include "vtkMatrixTreeLocatorTuning.h"

#include "vtkCommand.h"
#include "vtkDataSet.h"
#include "vtkDoubleArray.h"
#include "vtkIdList.h"
#include "vtkIdTypeArray.h"
#include "vtkObjectFactory.h"
#include "vtkPoints.h"
#include "vtkPolyData.h"
#include "vtkUnstructuredGrid.h"

#include "mtree/core/memory.h"

#include <algorithm>
#include <limits>
#include <string>
#include <vector>

vtkStandardNewMacro(vtkMatrixTreeLocator);

namespace
{
bool CheckTriples(vtkObject* self, vtkDataArray* a, const char* what)
{
  if (!a || a->GetNumberOfComponents() != 3)
  {
    vtkErrorWithObjectMacro(self, << what << " must be a 3-component array.");
    return false;
  }
  return true;
}
}

//------------------------------------------------------------------------------
vtkMatrixTreeLocator::vtkMatrixTreeLocator()
  : Processor(new vtkMatrixTreeLocatorProcessor)
{
  // Off: 24 bytes per cell not held; only the queries with a tolerance and the proximity
  // queries read cell bounds (see the class description).
  this->CacheCellBounds = 0;
}

vtkMatrixTreeLocator::~vtkMatrixTreeLocator()
{
  this->SetOpenCLDevice(nullptr);
  delete this->Processor;
}

void vtkMatrixTreeLocator::SetTuning(const vtkMatrixTreeLocatorTuning& tuning)
{
  if (this->Processor->SetTuning(tuning))
  {
    this->Modified();
  }
}

const vtkMatrixTreeLocatorTuning& vtkMatrixTreeLocator::GetTuning() const
{
  return this->Processor->Tuning;
}

static_assert(int(vtkMatrixTreeLocator::CPU) == vtkMatrixTreeBackend::CPU &&
    int(vtkMatrixTreeLocator::OPENCL) == vtkMatrixTreeBackend::OPENCL,
  "vtkMatrixTreeLocator's Backend values are vtkMatrixTreeBackend's");

//------------------------------------------------------------------------------
const char* vtkMatrixTreeLocator::GetBackendAsString() const
{
  return vtkMatrixTreeBackend::Name(this->Backend);
}

//------------------------------------------------------------------------------
const char* vtkMatrixTreeLocator::GetOpenCLDeviceName()
{
  return this->Processor->CLDevice.GetDeviceName();
}

const char* vtkMatrixTreeLocator::GetLastFindCellsPhases()
{
  return this->Processor->FindPhases.c_str();
}

//------------------------------------------------------------------------------
bool vtkMatrixTreeLocator::NeedsBuild()
{
  if (!this->Processor->Valid)
  {
    return true;
  }
  if (this->UseExistingSearchStructure)
  {
    return false;
  }
  return this->BuildTime < this->GetMTime() ||
    (this->DataSet && this->BuildTime < this->DataSet->GetMTime());
}

bool vtkMatrixTreeLocator::EnsureBuilt()
{
  // Queries build lazily and rebuild when the data set object or a setting changed, but do not
  // walk the data set's modification times (its arrays') on every query: as with VTK's own
  // locators, call BuildLocator() after changing the data set in place.
  const vtkMatrixTreeLocatorProcessor& p = *this->Processor;
  if (p.Valid && p.BuiltOn == this->DataSet && (this->UseExistingSearchStructure || this->BuildTime >= this->MTime))
  {
    return true;
  }
  if (!this->DataSet)
  {
    vtkErrorMacro("No data set: call SetDataSet() first.");
    return false;
  }
  if (this->NeedsBuild() || p.BuiltOn != this->DataSet)
  {
    this->ForceBuildLocator();
  }
  return p.Valid;
}

void vtkMatrixTreeLocator::BuildLocator()
{
  if (this->NeedsBuild())
  {
    this->ForceBuildLocator();
  }
}

void vtkMatrixTreeLocator::ForceBuildLocator()
{
  vtkMatrixTreeLocatorProcessor::BuildSettings s;
  s.Kd = this->TreeType == KDTREE;
  s.Height = this->Height;
  s.BlockSize = this->BlockSize;
  s.ExactOverlap = this->ExactOverlap;
  s.LeafScale = this->LeafScale;
  s.MaxCandidates = this->MaxCandidates;
  s.NumberOfThreads = this->NumberOfThreads;
  s.BuildSort = this->Processor->Tuning.BuildSort;
  s.CellStorage = this->Processor->Tuning.CellStorage;
  s.CacheCellBounds = this->CacheCellBounds != 0;
  std::string error;
  if (!this->Processor->Build(this->DataSet, s, this, error))
  {
    vtkErrorMacro(<< error);
    return;
  }
  this->BuildTime.Modified();
  double progress = 1.0;
  this->InvokeEvent(vtkCommand::ProgressEvent, &progress);
}

void vtkMatrixTreeLocator::FreeSearchStructure()
{
  const vtkMatrixTreeLocatorTuning tuning = this->Processor->Tuning;
  delete this->Processor;
  this->Processor = new vtkMatrixTreeLocatorProcessor;
  this->Processor->SetTuning(tuning);
}

//------------------------------------------------------------------------------
bool vtkMatrixTreeLocator::InsideCellBounds(double x[3], vtkIdType cellId)
{
  if (!this->EnsureBuilt() || cellId < 0 || cellId >= static_cast<vtkIdType>(this->Processor->Core.cells.size()))
  {
    return false;
  }
  return this->Processor->Core.cells.exactBounds(static_cast<size_t>(cellId)).contains(mtree::Vec3(x));
}

vtkIdType vtkMatrixTreeLocator::FindCell(
  double x[3], double vtkNotUsed(tol2), vtkGenericCell* cell, double pcoords[3], double* weights)
{
  return this->EnsureBuilt() ? this->Processor->FindCell(this->DataSet, x, cell, pcoords, weights) : -1;
}

#if VTK_VERSION_NUMBER >= VTK_VERSION_CHECK(9, 2, 0)
vtkIdType vtkMatrixTreeLocator::FindCell(
  double x[3], double tol2, vtkGenericCell* cell, int& subId, double pcoords[3], double* weights)
{
  subId = 0;
  return this->FindCell(x, tol2, cell, pcoords, weights);
}
#endif

int vtkMatrixTreeLocator::IntersectWithLine(const double p1[3], const double p2[3], double tol,
  double& t, double x[3], double pcoords[3], int& subId, vtkIdType& cellId, vtkGenericCell* cell)
{
  cellId = -1;
  t = VTK_DOUBLE_MAX;
  return this->EnsureBuilt()
    ? this->Processor->FirstHit(this->DataSet, p1, p2, tol, t, x, pcoords, subId, cellId, cell)
    : 0;
}

int vtkMatrixTreeLocator::IntersectWithLine(
  const double p1[3], const double p2[3], vtkPoints* points, vtkIdList* cellIds)
{
  if (points)
  {
    points->Reset();
  }
  if (cellIds)
  {
    cellIds->Reset();
  }
  return this->EnsureBuilt() ? this->Processor->AllHits(this->DataSet, p1, p2, points, cellIds) : 0;
}

vtkIdType vtkMatrixTreeLocator::FindClosestPointWithinRadius(double x[3], double radius,
  double closestPoint[3], vtkGenericCell* cell, vtkIdType& cellId, int& subId, double& dist2,
  int& inside)
{
  cellId = -1;
  subId = 0;
  inside = 0;
  dist2 = VTK_DOUBLE_MAX;
  if (!this->EnsureBuilt() || this->Processor->Core.tree.empty() || !(radius >= 0))
  {
    return 0;
  }
  return this->Processor->ClosestPoint(
    this->DataSet, x, radius, closestPoint, cell, cellId, subId, dist2, inside);
}

void vtkMatrixTreeLocator::FindClosestPoint(const double x[3], double closestPoint[3],
  vtkGenericCell* cell, vtkIdType& cellId, int& subId, double& dist2)
{
  int inside;
  double xx[3] = { x[0], x[1], x[2] };
  this->FindClosestPointWithinRadius(xx, std::numeric_limits<double>::infinity(), closestPoint,
    cell, cellId, subId, dist2, inside);
}

void vtkMatrixTreeLocator::FindCellsWithinBounds(double* bbox, vtkIdList* cells)
{
  cells->Reset();
  if (this->EnsureBuilt() && !this->Processor->Core.tree.empty())
  {
    this->Processor->CellsWithinBounds(bbox, cells);
  }
}

void vtkMatrixTreeLocator::FindCellsAlongLine(
  const double p1[3], const double p2[3], double tolerance, vtkIdList* cells)
{
  cells->Reset();
  if (this->EnsureBuilt())
  {
    this->Processor->CellsAlongLine(p1, p2, tolerance, cells);
  }
}

//------------------------------------------------------------------------------
void vtkMatrixTreeLocator::GenerateRepresentation(int level, vtkPolyData* pd)
{
  if (pd && this->EnsureBuilt())
  {
    this->Processor->Representation(level, pd);
  }
}

vtkIdType vtkMatrixTreeLocator::GenerateNodes(int minLevel, int maxLevel, vtkUnstructuredGrid* output)
{
  if (!output)
  {
    return 0;
  }
  output->Initialize();
  return this->EnsureBuilt() ? this->Processor->Nodes(minLevel, maxLevel, output) : 0;
}

//------------------------------------------------------------------------------
void vtkMatrixTreeLocator::FindCells(
  vtkPoints* points, vtkIdTypeArray* cellIds, vtkDoubleArray* pcoords, vtkDoubleArray* weights)
{
  if (!cellIds)
  {
    vtkErrorMacro("FindCells: cellIds must not be null.");
    return;
  }
  cellIds->SetNumberOfComponents(1);
  cellIds->SetNumberOfTuples(0);
  if (pcoords)
  {
    pcoords->SetNumberOfComponents(3);
    pcoords->SetNumberOfTuples(0);
  }
  if (weights)
  {
    weights->SetNumberOfTuples(0);
  }
  if (!points || !CheckTriples(this, points->GetData(), "FindCells: points") || !this->EnsureBuilt())
  {
    return;
  }
  vtkMatrixTreeLocatorProcessor& p = *this->Processor;
  const vtkIdType n = points->GetNumberOfPoints();
  // OpenCL: the device answers first (outcome and candidate per point, see
  // mtree::ocl::CellLocator); the host loop finishes each point from there.
  const bool device = this->Backend == OPENCL;
  std::vector<uint32_t> answers;
  if (device)
  {
    this->LastNumberOfHostResumes = 0;
    this->LastNumberOfUnconfirmedCells = 0;
    try
    {
      this->NumberOfOpenCLUploads +=
        p.LocateOnDevice(this->OpenCLDevice ? this->OpenCLDevice : "", points, answers) ? 1 : 0;
    }
    catch (const std::exception& e)
    {
      p.CLUploaded = false;
      vtkErrorMacro("FindCells failed (opencl backend): " << e.what() << " (or locate with SetBackendToCPU())");
      return;
    }
  }
  const int nw = std::max(1, this->DataSet->GetMaxCellSize());
  cellIds->SetNumberOfTuples(n);
  if (pcoords)
  {
    pcoords->SetNumberOfTuples(n);
  }
  if (weights)
  {
    weights->SetNumberOfComponents(nw);
    weights->SetNumberOfTuples(n);
  }
  vtkIdType resumes = 0, unconfirmed = 0;
  p.FindCells(this->DataSet, points, device ? answers.data() : nullptr, this->NumberOfThreads,
    cellIds->GetPointer(0), pcoords ? pcoords->GetPointer(0) : nullptr, weights ? weights->GetPointer(0) : nullptr,
    nw, resumes, unconfirmed);
  if (device)
  {
    this->LastNumberOfHostResumes = resumes;
    this->LastNumberOfUnconfirmedCells = unconfirmed;
  }
}

void vtkMatrixTreeLocator::IntersectSegments(vtkDataArray* p1, vtkDataArray* p2, double tol,
  vtkDoubleArray* t, vtkIdTypeArray* cellIds, vtkDoubleArray* points)
{
  if (!t || !cellIds)
  {
    vtkErrorMacro("IntersectSegments: t and cellIds must not be null.");
    return;
  }
  t->SetNumberOfComponents(1);
  t->SetNumberOfTuples(0);
  cellIds->SetNumberOfComponents(1);
  cellIds->SetNumberOfTuples(0);
  if (points)
  {
    points->SetNumberOfComponents(3);
    points->SetNumberOfTuples(0);
  }
  if (!CheckTriples(this, p1, "IntersectSegments: p1") || !CheckTriples(this, p2, "IntersectSegments: p2"))
  {
    return;
  }
  if (p1->GetNumberOfTuples() != p2->GetNumberOfTuples())
  {
    vtkErrorMacro("IntersectSegments: p1 has " << p1->GetNumberOfTuples() << " tuples, p2 "
                                               << p2->GetNumberOfTuples() << ".");
    return;
  }
  if (!this->EnsureBuilt())
  {
    return;
  }
  const vtkIdType n = p1->GetNumberOfTuples();
  t->SetNumberOfTuples(n);
  cellIds->SetNumberOfTuples(n);
  if (points)
  {
    points->SetNumberOfTuples(n);
  }
  this->Processor->IntersectSegments(this->DataSet, p1, p2, tol, this->NumberOfThreads, t->GetPointer(0),
    cellIds->GetPointer(0), points ? points->GetPointer(0) : nullptr);
}

void vtkMatrixTreeLocator::FindClosestPoints(
  vtkPoints* points, vtkDoubleArray* closestPoints, vtkIdTypeArray* cellIds, vtkDoubleArray* dist2)
{
  if (!closestPoints || !cellIds)
  {
    vtkErrorMacro("FindClosestPoints: closestPoints and cellIds must not be null.");
    return;
  }
  closestPoints->SetNumberOfComponents(3);
  closestPoints->SetNumberOfTuples(0);
  cellIds->SetNumberOfComponents(1);
  cellIds->SetNumberOfTuples(0);
  if (dist2)
  {
    dist2->SetNumberOfComponents(1);
    dist2->SetNumberOfTuples(0);
  }
  if (!points || !CheckTriples(this, points->GetData(), "FindClosestPoints: points") || !this->EnsureBuilt())
  {
    return;
  }
  const vtkIdType n = points->GetNumberOfPoints();
  closestPoints->SetNumberOfTuples(n);
  cellIds->SetNumberOfTuples(n);
  if (dist2)
  {
    dist2->SetNumberOfTuples(n);
  }
  this->Processor->ClosestPoints(this->DataSet, points, this->NumberOfThreads, closestPoints->GetPointer(0),
    cellIds->GetPointer(0), dist2 ? dist2->GetPointer(0) : nullptr);
}

//------------------------------------------------------------------------------
double vtkMatrixTreeLocator::GetLeafScaleUsed()
{
  return this->Processor->Valid ? this->Processor->Core.leafScaleUsed : 0.0;
}
double vtkMatrixTreeLocator::GetMaxCandidatesUsed()
{
  return this->Processor->Valid ? this->Processor->Core.maxCandidatesUsed : 0.0;
}
int vtkMatrixTreeLocator::GetTreeHeight()
{
  return this->Processor->Valid ? this->Processor->Core.tree.height() : 0;
}
vtkIdType vtkMatrixTreeLocator::GetNumberOfLeaves()
{
  return this->Processor->Valid ? static_cast<vtkIdType>(this->Processor->Core.stats.leaves) : 0;
}
vtkIdType vtkMatrixTreeLocator::GetNumberOfReferences()
{
  return this->Processor->Valid ? static_cast<vtkIdType>(this->Processor->Core.stats.references) : 0;
}
vtkIdType vtkMatrixTreeLocator::GetMemorySize()
{
  return static_cast<vtkIdType>(this->Processor->MemorySize());
}
const char* vtkMatrixTreeLocator::GetBuildPhases()
{
  return this->Processor->Phases.c_str();
}
double vtkMatrixTreeLocator::GetLastBuildTime()
{
  return this->Processor->Core.stats.totalMs;
}
vtkTypeInt64 vtkMatrixTreeLocator::GetCachedMemorySize()
{
  return static_cast<vtkTypeInt64>(mtree::cachedMemoryBytes());
}
vtkTypeInt64 vtkMatrixTreeLocator::ReleaseCachedMemory()
{
  return static_cast<vtkTypeInt64>(mtree::releaseCachedMemory());
}

void vtkMatrixTreeLocator::CopySettings(vtkMatrixTreeLocator* other)
{
  if (!other)
  {
    return;
  }
  this->SetTreeType(other->TreeType);
  this->SetHeight(other->Height);
  this->SetBlockSize(other->BlockSize);
  this->SetLeafScale(other->LeafScale);
  this->SetExactOverlap(other->ExactOverlap);
  this->SetMaxCandidates(other->MaxCandidates);
  this->SetNumberOfThreads(other->NumberOfThreads);
  this->SetCacheCellBounds(other->CacheCellBounds);
  this->SetUseExistingSearchStructure(other->UseExistingSearchStructure);
  this->SetBackend(other->Backend);
  this->SetOpenCLDevice(other->OpenCLDevice);
  this->SetTuning(other->GetTuning());
}

void vtkMatrixTreeLocator::PrintSelf(ostream& os, vtkIndent indent)
{
  this->Superclass::PrintSelf(os, indent);
  const vtkMatrixTreeLocatorProcessor& p = *this->Processor;
  const vtkMatrixTreeLocatorTuning& t = p.Tuning;
  os << indent << "TreeType: " << (this->TreeType == KDTREE ? "KDTREE" : "OCTREE") << "\n";
  os << indent << "Height: " << this->Height << (this->Height == 0 ? " (automatic)" : "") << "\n";
  os << indent << "BlockSize: " << this->BlockSize << "\n";
  os << indent << "ExactOverlap: " << (this->ExactOverlap ? "On" : "Off") << "\n";
  os << indent << "LeafScale: " << this->LeafScale << "\n";
  os << indent << "MaxCandidates: " << this->MaxCandidates << "\n";
  os << indent << "NumberOfThreads: " << this->NumberOfThreads << "\n";
  vtkMatrixTreeBackend::Print(os, indent, this->Backend, this->OpenCLDevice, p.CLDevice.GetDeviceName());
  os << indent << "NumberOfOpenCLUploads: " << this->NumberOfOpenCLUploads << "\n";
  os << indent << "LastNumberOfHostResumes: " << this->LastNumberOfHostResumes << "\n";
  os << indent << "LastNumberOfUnconfirmedCells: " << this->LastNumberOfUnconfirmedCells << "\n";
  os << indent << "LastFindCellsPhases: " << p.FindPhases << "\n";
  os << indent << "Tuning:\n";
  os << indent.GetNextIndent()
     << "BuildSort: " << (t.BuildSort == vtkMatrixTreeLocatorTuning::RADIX ? "radix" : "counting") << "\n";
  os << indent.GetNextIndent() << "CellStorage: "
     << (t.CellStorage == vtkMatrixTreeLocatorTuning::CELLS_IN_PLACE
            ? "in place"
            : (t.CellStorage == vtkMatrixTreeLocatorTuning::CELLS_COPIED ? "copied" : "automatic"))
     << "\n";
  os << indent.GetNextIndent() << "EngineCellEvaluation: " << (t.EngineCellEvaluation ? "On" : "Off") << "\n";
  os << indent.GetNextIndent() << "RayStepTable: " << (t.RayStepTable ? "On" : "Off") << "\n";
  os << indent << "Built: " << (p.Valid ? "yes" : "no") << "\n";
  if (p.Valid)
  {
    os << indent << "TreeHeight: " << this->GetTreeHeight() << "\n";
    os << indent << "NumberOfLeaves: " << this->GetNumberOfLeaves() << "\n";
    os << indent << "NumberOfReferences: " << this->GetNumberOfReferences() << "\n";
    os << indent << "MemorySize: " << this->GetMemorySize() << " bytes\n";
    os << indent << "LastBuildTime: " << this->GetLastBuildTime() << " ms\n";
  }
}

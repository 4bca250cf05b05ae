#include "vtkMatrixTreeLocatorProcessor.h"

#include "vtkMatrixTreeCellBridge.h"
#include "vtkMatrixTreeQueryStatistics.h"

#include "vtkCommand.h"
#include "vtkDataSet.h"
#include "vtkDoubleArray.h"
#include "vtkGenericCell.h"
#include "vtkIdList.h"
#include "vtkNew.h"
#include "vtkObject.h"
#include "vtkPoints.h"
#include "vtkSmartPointer.h"


#include <omp.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>
#include <unordered_set>

namespace
{
using Clock = std::chrono::steady_clock;
double MsSince(Clock::time_point t)
{
  return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
}

// The batched queries' loop (mtree::vtk91::runBatch) over a data set made safe to fetch cells
// from many threads; `threads` 0: all.
template <class MakeWorker>
void RunBatch(vtkDataSet* ds, vtkIdType n, int threads, int chunk, MakeWorker&& makeWorker)
{
  vtkMatrixTreeCellBridge::PrepareForThreads(ds);
  mtree::vtk91::runBatch(n, threads, chunk, 1, std::forward<MakeWorker>(makeWorker));
}
}

//------------------------------------------------------------------------------
bool vtkMatrixTreeLocatorProcessor::Build(
  vtkDataSet* ds, const BuildSettings& s, vtkObject* progress, std::string& error)
{
  this->Valid = false;
  this->CLUploaded = false;
  const Clock::time_point tStart = Clock::now();
  if (!ds)
  {
    error = "BuildLocator: no data set; call SetDataSet() first.";
    return false;
  }
  const int b = s.BlockSize;
  if (b < 1 || b > 32 || (b & (b - 1)))
  {
    error = "BuildLocator: BlockSize must be a power of two in [1, 32], got " + std::to_string(b) + ".";
    return false;
  }
  // Threads of the whole build, the copies included: as set, or (0) one per 1024 cells up to
  // all (a second thread pays for itself from about 1000 cells on; docs/bench_locators.md).
  const vtkIdType nc = ds->GetNumberOfCells();
  const int threads = s.NumberOfThreads > 0
    ? s.NumberOfThreads
    : static_cast<int>(std::min<vtkIdType>(omp_get_max_threads(), std::max<vtkIdType>(1, nc / 1024)));
  std::string readError;
  if (!this->Source.Read(ds, s.CellStorage, threads, readError))
  {
    error = "BuildLocator: " + readError;
    return false;
  }
  const double convertMs = MsSince(tStart);
  double fraction = 0.2; // a locator is no algorithm: progress goes out as an event
  progress->InvokeEvent(vtkCommand::ProgressEvent, &fraction);
  mtree::vtk91::LocatorSettings settings;
  settings.kind = s.Kd ? mtree::TreeKind::RegularKd : mtree::TreeKind::Octree;
  settings.height = s.Height;
  settings.blockEdge = s.BlockSize;
  settings.exactOverlap = s.ExactOverlap;
  settings.leafScale = s.LeafScale;
  settings.maxCandidates = s.MaxCandidates;
  settings.threads = threads;
  settings.sort =
    s.BuildSort == vtkMatrixTreeLocatorTuning::RADIX ? mtree::BuildSort::Radix : mtree::BuildSort::Counting;
  settings.keepBounds = s.CacheCellBounds;
  double cellsetMs = 0;
  try
  {
    this->Source.MakeCellSet(threads, this->Core.cells);
    cellsetMs = MsSince(tStart) - convertMs;
    this->Core.build(settings);
  }
  catch (const std::exception& e)
  {
    error = std::string("BuildLocator failed: ") + e.what();
    return false;
  }
  std::ostringstream os;
  os << "convert " << convertMs << "; cellset " << cellsetMs;
  for (const auto& ph : this->Core.stats.phasesMs)
  {
    os << "; " << ph.first << " " << ph.second;
  }
  this->TotalMs = MsSince(tStart);
  os << "; total " << this->TotalMs;
  this->Phases = os.str();
  this->BuiltOn = ds;
  this->Valid = true;
  return true;
}

//------------------------------------------------------------------------------
vtkIdType vtkMatrixTreeLocatorProcessor::FindCell(
  vtkDataSet* ds, const double x[3], vtkGenericCell* cell, double pcoords[3], double* weights) const
{
  vtkMatrixTreeCellBridge::Oracle o(ds, this->Core.cells, cell, this->Tuning.EngineCellEvaluation);
  return this->Core.findCell(x, o, pcoords, weights);
}

vtkIdType vtkMatrixTreeLocatorProcessor::ScanLeaf(vtkDataSet* ds, const double x[3], const mtree::NodeRef& n,
  uint32_t k, vtkGenericCell* cell, double pcoords[3], double* weights) const
{
  vtkMatrixTreeCellBridge::Oracle o(ds, this->Core.cells, cell, this->Tuning.EngineCellEvaluation);
  return this->Core.scanLeaf(x, n, k, o, pcoords, weights);
}

//------------------------------------------------------------------------------
int vtkMatrixTreeLocatorProcessor::FirstHit(vtkDataSet* ds, const double p1[3], const double p2[3], double tol,
  double& t, double x[3], double pcoords[3], int& subId, vtkIdType& cellId, vtkGenericCell* cell) const
{
  vtkMatrixTreeCellBridge::Oracle o(ds, this->Core.cells, cell, this->Tuning.EngineCellEvaluation);
  mtree::vtk91::FirstHitAnswer a;
  if (!this->Core.firstHit(p1, p2, tol, o, a))
  {
    return 0;
  }
  t = a.t;
  std::copy(a.x, a.x + 3, x);
  std::copy(a.pcoords, a.pcoords + 3, pcoords);
  subId = a.subId;
  cellId = a.cell;
  return 1;
}

int vtkMatrixTreeLocatorProcessor::AllHits(
  vtkDataSet* ds, const double p1[3], const double p2[3], vtkPoints* points, vtkIdList* cellIds) const
{
  vtkNew<vtkGenericCell> cell;
  vtkMatrixTreeCellBridge::Oracle o(ds, this->Core.cells, cell, this->Tuning.EngineCellEvaluation);
  std::vector<mtree::vtk91::SegmentCellHit> hits;
  this->Core.allHits(p1, p2, 0.0, o, hits);
  for (const mtree::vtk91::SegmentCellHit& h : hits)
  {
    if (points)
    {
      points->InsertNextPoint(h.x);
    }
    if (cellIds)
    {
      cellIds->InsertNextId(h.cell);
    }
  }
  return static_cast<int>(hits.size());
}

//------------------------------------------------------------------------------
vtkIdType vtkMatrixTreeLocatorProcessor::ClosestPoint(vtkDataSet* ds, const double x[3], double radius,
  double closestPoint[3], vtkGenericCell* cell, vtkIdType& cellId, int& subId, double& dist2, int& inside) const
{
  // A non-finite query point is no distance from anything: no closest point (the caller's -1).
  if (!(std::isfinite(x[0]) && std::isfinite(x[1]) && std::isfinite(x[2])))
  {
    return 0;
  }
  vtkMatrixTreeCellBridge::Oracle o(ds, this->Core.cells, cell, this->Tuning.EngineCellEvaluation);
  const double radius2 = std::isinf(radius) ? std::numeric_limits<double>::infinity() : radius * radius;
  mtree::vtk91::ClosestAnswer a;
  if (!this->Core.closestPoint(x, radius2, o, a))
  {
    return 0;
  }
  cellId = a.cell;
  subId = a.subId;
  inside = a.inside;
  dist2 = a.dist2;
  std::copy(a.point, a.point + 3, closestPoint);
  return 1;
}

//------------------------------------------------------------------------------
void vtkMatrixTreeLocatorProcessor::CellsWithinBounds(const double bbox[6], vtkIdList* cells) const
{
  std::vector<int64_t> found;
  this->Core.cellsWithinBounds(bbox, found);
  for (const int64_t id : found)
  {
    cells->InsertNextId(id);
  }
}

void vtkMatrixTreeLocatorProcessor::CellsAlongLine(
  const double p1[3], const double p2[3], double tol, vtkIdList* cells) const
{
  std::vector<int64_t> found;
  this->Core.cellsAlongLine(p1, p2, tol, found);
  for (const int64_t id : found)
  {
    cells->InsertNextId(id);
  }
}

//------------------------------------------------------------------------------
bool vtkMatrixTreeLocatorProcessor::LocateOnDevice(
  const std::string& selector, vtkPoints* points, std::vector<uint32_t>& answers)
{
  this->DeviceStart = Clock::now();
  bool uploaded = false;
  if (this->CLDevice.Acquire(selector.c_str()) || !this->CL)
  {
    this->CL.reset();
    this->CLUploaded = false;
    this->CL.reset(new mtree::ocl::CellLocator(this->CLDevice.GetContext()));
  }
  double uploadMs = 0;
  if (!this->CLUploaded)
  {
    const Clock::time_point t0 = Clock::now();
    this->CL->upload(this->Core.tree, this->Core.cells, this->Core.leafBoxes);
    this->CLUploaded = true;
    uploaded = true;
    uploadMs = MsSince(t0);
  }
  // The kernel reads doubles: the points' own array where it holds them.
  const size_t n = static_cast<size_t>(points->GetNumberOfPoints());
  std::vector<double> copy;
  const double* xyz = nullptr;
  vtkDoubleArray* dbl = vtkDoubleArray::FastDownCast(points->GetData());
  if (dbl && n > 0)
  {
    xyz = dbl->GetPointer(0);
  }
  else
  {
    copy.resize(3 * n);
    for (size_t i = 0; i < n; ++i)
    {
      points->GetPoint(static_cast<vtkIdType>(i), &copy[3 * i]);
    }
    xyz = copy.data();
  }
  answers.resize(2 * n);
  std::vector<mtree::ocl::KernelTiming> timing;
  const Clock::time_point t1 = Clock::now();
  this->CL->locate(xyz, n, vtkMatrixTreeCellBridge::kTetraTolerance, answers.data(), &timing);
  const double deviceMs = MsSince(t1);
  double pointsMs = 0, kernelMs = 0, downloadMs = 0;
  for (const auto& t : timing)
  {
    (t.kernel == "(upload)" ? pointsMs : (t.kernel == "(download)" ? downloadMs : kernelMs)) += t.ms;
  }
  std::ostringstream os;
  os << "upload " << uploadMs << "; points " << pointsMs << "; kernel " << kernelMs << "; download " << downloadMs
     << "; device call " << deviceMs;
  this->FindPhases = os.str();
  return uploaded;
}

void vtkMatrixTreeLocatorProcessor::FindCells(vtkDataSet* ds, vtkPoints* points, const uint32_t* answers,
  int threads, vtkIdType* ids, double* pcoords, double* weights, int nw, vtkIdType& resumes,
  vtkIdType& unconfirmed)
{
  const Clock::time_point tHost = Clock::now();
  const uint32_t* prims = this->Core.tree.primitiveIndices().data();
  const bool wantParams = pcoords || weights;
  std::atomic<vtkIdType> totalResumes{ 0 }, totalUnconfirmed{ 0 };
  // One per thread: its generic cell and weights, and its tallies, added up when it is done.
  struct Worker
  {
    const vtkMatrixTreeLocatorProcessor& P;
    vtkDataSet* DS;
    vtkPoints* Points;
    const uint32_t* Answers;
    const uint32_t* Prims;
    bool WantParams;
    vtkIdType* Ids;
    double* Pcoords;
    double* Weights;
    int Nw;
    std::atomic<vtkIdType>& TotalResumes;
    std::atomic<vtkIdType>& TotalUnconfirmed;
    vtkSmartPointer<vtkGenericCell> Cell = vtkSmartPointer<vtkGenericCell>::New();
    std::vector<double> Wk = std::vector<double>(static_cast<size_t>(Nw));
    vtkMatrixTreeCellBridge::Oracle Or{ DS, P.Core.cells, Cell, P.Tuning.EngineCellEvaluation };
    vtkIdType Resumes = 0, Unconfirmed = 0;

    ~Worker()
    {
      this->TotalResumes += this->Resumes;
      this->TotalUnconfirmed += this->Unconfirmed;
    }

    void operator()(vtkIdType i)
    {
      double x[3], p[3] = { 0.0, 0.0, 0.0 };
      this->Points->GetPoint(i, x);
      std::fill(this->Wk.begin(), this->Wk.end(), 0.0);
      vtkIdType id = -1;
      if (!this->Answers)
      {
        id = this->P.FindCell(this->DS, x, this->Cell, p, this->Wk.data());
      }
      else
      {
        const uint32_t outcome = this->Answers[2 * static_cast<size_t>(i)];
        const uint32_t k = this->Answers[2 * static_cast<size_t>(i) + 1];
        bool resume = outcome == mtree::ocl::CellLocator::kResume;
        if (outcome == mtree::ocl::CellLocator::kFound)
        {
          id = this->Prims[k];
          // pcoords and weights as the cell's evaluation gives them, which also confirms the
          // device's answer.
          if (this->WantParams &&
            !this->P.Core.cellContains(static_cast<size_t>(id), x, this->Or, p, this->Wk.data()))
          {
            ++this->Unconfirmed;
            resume = true;
          }
        }
        if (resume)
        {
          ++this->Resumes;
          const mtree::NodeRef leaf = this->P.Core.tree.leafHolding(mtree::Vec3(x));
          id = leaf.exists ? this->P.ScanLeaf(this->DS, x, leaf, k, this->Cell, p, this->Wk.data()) : -1;
        }
      }
      this->Ids[i] = id;
      if (id < 0)
      {
        // A miss leaves what the last rejected candidate wrote: not meaningful, zeroed.
        p[0] = p[1] = p[2] = 0.0;
      }
      if (this->Pcoords)
      {
        std::copy(p, p + 3, this->Pcoords + 3 * i);
      }
      if (this->Weights)
      {
        // Only the found cell's weights are meaningful; the rest are zeroed.
        const auto keep = id < 0 ? 0 : std::min<vtkIdType>(this->Nw, this->Cell->GetNumberOfPoints());
        std::fill(this->Wk.begin() + keep, this->Wk.end(), 0.0);
        std::copy(this->Wk.begin(), this->Wk.end(), this->Weights + static_cast<size_t>(this->Nw) * i);
      }
    }
  };
  RunBatch(ds, points->GetNumberOfPoints(), threads, 1024, [&]() {
    return Worker{ *this, ds, points, answers, prims, wantParams, ids, pcoords, weights, nw, totalResumes,
      totalUnconfirmed };
  });
  resumes = totalResumes;
  unconfirmed = totalUnconfirmed;
  if (answers)
  {
    std::ostringstream os;
    os << "; host " << MsSince(tHost) << "; total " << MsSince(this->DeviceStart);
    this->FindPhases += os.str();
  }
}

bool vtkMatrixTreeLocatorProcessor::SetTuning(const vtkMatrixTreeLocatorTuning& tuning)
{
  const int sort = std::min(std::max(tuning.BuildSort, static_cast<int>(vtkMatrixTreeLocatorTuning::RADIX)),
    static_cast<int>(vtkMatrixTreeLocatorTuning::COUNTING));
  const int storage = std::min(std::max(tuning.CellStorage, static_cast<int>(vtkMatrixTreeLocatorTuning::CELLS_AUTOMATIC)),
    static_cast<int>(vtkMatrixTreeLocatorTuning::CELLS_COPIED));
  const bool rebuild = sort != this->Tuning.BuildSort || storage != this->Tuning.CellStorage;
  this->Tuning = tuning;
  this->Tuning.BuildSort = sort;
  this->Tuning.CellStorage = storage;
  this->Core.tree.enableStepTable(tuning.RayStepTable); // the tree keeps it across builds
  return rebuild;
}

void vtkMatrixTreeLocatorProcessor::IntersectSegments(vtkDataSet* ds, vtkDataArray* p1, vtkDataArray* p2,
  double tol, int threads, double* t, vtkIdType* ids, double* xp) const
{
  RunBatch(ds, p1->GetNumberOfTuples(), threads, 256, [&]() {
    return [&, cell = vtkSmartPointer<vtkGenericCell>::New()](vtkIdType i) {
      double a[3], b[3], x[3], pc[3], ti = VTK_DOUBLE_MAX;
      int sub;
      vtkIdType id = -1;
      p1->GetTuple(i, a);
      p2->GetTuple(i, b);
      const int hit = this->FirstHit(ds, a, b, tol, ti, x, pc, sub, id, cell);
      ids[i] = hit ? id : -1;
      t[i] = hit ? ti : std::numeric_limits<double>::infinity();
      for (int k = 0; xp && k < 3; ++k)
      {
        xp[3 * i + k] = hit ? x[k] : std::numeric_limits<double>::quiet_NaN();
      }
    };
  });
}

void vtkMatrixTreeLocatorProcessor::ClosestPoints(vtkDataSet* ds, vtkPoints* points, int threads, double* closest,
  vtkIdType* ids, double* dist2) const
{
  RunBatch(ds, points->GetNumberOfPoints(), threads, 256, [&]() {
    return [&, cell = vtkSmartPointer<vtkGenericCell>::New()](vtkIdType i) {
      double x[3], c[3], d = VTK_DOUBLE_MAX;
      int sub = 0, inside = 0;
      vtkIdType id = -1;
      points->GetPoint(i, x);
      if (!this->Core.tree.empty())
      {
        this->ClosestPoint(ds, x, std::numeric_limits<double>::infinity(), c, cell, id, sub, d, inside);
      }
      ids[i] = id;
      for (int k = 0; k < 3; ++k)
      {
        closest[3 * i + k] = id >= 0 ? c[k] : std::numeric_limits<double>::quiet_NaN();
      }
      if (dist2)
      {
        dist2[i] = id >= 0 ? d : std::numeric_limits<double>::infinity();
      }
    };
  });
}

size_t vtkMatrixTreeLocatorProcessor::MemorySize() const
{
  return this->Valid
    ? this->Core.bytes()
    : 0;
}

#include "vtkMatrixTreeLocatorProcessor.h"

#include "vtkMatrixTreeBatchRunner.h"
#include "vtkMatrixTreeCellBridge.h"
#include "vtkMatrixTreeFirstHitQuery.h"
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

#include "mtree/cells/leaf_boxes.h"
#include "mtree/core/tree_queries.h"

#include <omp.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>
#include <unordered_set>

using namespace vtkMatrixTreeQueryStatistics;

namespace
{
using Clock = std::chrono::steady_clock;
double MsSince(Clock::time_point t)
{
  return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
}

// Distance squared from x to cell bounds given as 6 floats (xmin xmax ymin ymax zmin zmax).
inline double BoundsDistance2(const double x[3], const float* b)
{
  double d2 = 0;
  for (int a = 0; a < 3; ++a)
  {
    const double d = std::max({ b[2 * a] - x[a], 0.0, x[a] - b[2 * a + 1] });
    d2 += d * d;
  }
  return d2;
}
}

//------------------------------------------------------------------------------
bool vtkMatrixTreeLocatorProcessor::Build(
  vtkDataSet* ds, const BuildSettings& s, vtkObject* progress, std::string& error)
{
  this->Valid = false;
  this->CLUploaded = false;
  this->ShapeMemo.reset();
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
  mtree::BuildOptions opt;
  opt.kind = s.Kd ? mtree::TreeKind::RegularKd : mtree::TreeKind::Octree;
  opt.height = s.Height;
  opt.blockEdge = s.BlockSize;
  opt.overlap = s.ExactOverlap ? mtree::OverlapMode::Exact : mtree::OverlapMode::BoundingBox;
  opt.sort = s.BuildSort == vtkMatrixTreeLocatorTuning::RADIX ? mtree::BuildSort::Radix : mtree::BuildSort::Counting;
  opt.threads = threads;
  double cellsetMs = 0;
  try
  {
    this->Source.MakeCellSet(threads, this->Cells);
    cellsetMs = MsSince(tStart) - convertMs;
    // The automatic height: leaves about one median cell wide where any cell is 3-D (point
    // location tests every candidate of one leaf), about four on a surface (1.8-2.3 references
    // per triangle instead of 6-10; docs/bench_locators.md, "Surfaces").
    const bool surface =
      (s.LeafScale <= 0 || s.MaxCandidates <= 0) && vtkMatrixTreeCellBridge::NoVolumeCells(this->Cells);
    opt.leafScale = s.LeafScale > 0 ? std::max(s.LeafScale, 1e-3) : (surface ? 4.0 : 1.0);
    opt.maxCandidates = s.MaxCandidates > 0 ? std::max(s.MaxCandidates, 1.0) : (surface ? 3.0 : 16.0);
    this->LeafScaleUsed = opt.leafScale;
    this->MaxCandidatesUsed = opt.maxCandidates;
    // The quantized leaf boxes are the builder's per-reference data: written at the scatter
    // (COUNTING) or by a pass over the leaves (RADIX), the same bytes either way.
    mtree::MatrixTreeBuilder<mtree::CellSet>::build<6>(
      this->Cells, opt, this->Tree, &this->Stats, &this->LeafBoxes, mtree::LeafBoxQuantizer());
  }
  catch (const std::exception& e)
  {
    error = std::string("BuildLocator failed: ") + e.what();
    return false;
  }
  // The cell bounds serve the build (read several times per cell there); unless CacheCellBounds
  // is on, the queries that need a few compute them from the points: 24 bytes per cell not
  // held. The builder's work arrays, which the tree keeps for a next build, go too.
  const Clock::time_point tRelease = Clock::now();
  if (!s.CacheCellBounds)
  {
    this->Cells.releaseBounds();
  }
  this->Tree.releaseBuildScratch();
  const double releaseMs = MsSince(tRelease);
  if (vtkMatrixTreeCellBridge::HasConvexPolyhedra(this->Cells))
  {
    // calloc: zero pages from the system for a large grid, touched only where rays go.
    this->ShapeMemo.reset(static_cast<uint8_t*>(std::calloc(this->Cells.size(), 1)));
  }
  const mtree::Vec3 m = this->Cells.maxExtent();
  this->MaxCellExtent[0] = m.x;
  this->MaxCellExtent[1] = m.y;
  this->MaxCellExtent[2] = m.z;
  std::ostringstream os;
  os << "convert " << convertMs << "; cellset " << cellsetMs;
  for (const auto& ph : this->Stats.phasesMs)
  {
    os << "; " << ph.first << " " << ph.second;
  }
  os << "; release " << releaseMs << "; total " << MsSince(tStart);
  this->Phases = os.str();
  this->BuiltOn = ds;
  this->Valid = true;
  return true;
}

//------------------------------------------------------------------------------
vtkIdType vtkMatrixTreeLocatorProcessor::ScanLeaf(vtkDataSet* ds, const double x[3], const mtree::NodeRef& n,
  uint32_t k, vtkGenericCell* cell, double pcoords[3], double* weights) const
{
  const bool engineEval = this->Tuning.EngineCellEvaluation;
  const MtLeafRange r = n.range; // leafHolding's read of the leaf
  const uint32_t* ids = this->Tree.primitiveIndices().data();
  const uint8_t* boxes = this->LeafBoxes.data();
  // The leaf's boxes and its cell ids are two independent reads (usually cache misses): both
  // start now, so that they overlap each other and the set-up below.
  __builtin_prefetch(boxes + 6 * static_cast<size_t>(k));
  __builtin_prefetch(ids + k);
  uint8_t qmax[3], qmin[3];
  mtree::quantizePoint(x, this->Tree.nodeBox(n.level, n.c), qmax, qmin);
  const mtree::LeafBoxTest boxTest(qmax, qmin, r.end - k);
  CountQuery(kFcLeafScans);
  CountQuery(kFcReferences, r.end - k);
  // The candidates whose box holds the point are gathered first (in the leaf's order: ascending
  // ids, so the first that contains the point is the answer), up to kChunk references at once;
  // then the point ids of up to kIdsAhead of them are prefetched, then the points of up to
  // kAhead: each level of these random reads overlaps across the candidates.
  constexpr uint32_t kChunk = 128;
  constexpr int kAhead = 16, kIdsAhead = 24;
  uint32_t cand[kChunk];
  while (k < r.end)
  {
    const uint32_t stop = std::min<uint32_t>(r.end, k + kChunk);
    // Every line of the chunk's boxes and ids (the first of each is on its way already).
    mtree::prefetchLines(boxes + 6 * static_cast<size_t>(k) + 64, boxes + 6 * static_cast<size_t>(stop));
    mtree::prefetchLines(reinterpret_cast<const char*>(ids + k) + 64, ids + stop);
    const int nc = boxTest.gather(boxes, k, stop, cand);
    CountQuery(kFcBoxPasses, static_cast<uint64_t>(nc));
    for (int j = 0; j < nc; ++j)
    {
      cand[j] = ids[cand[j]];
    }
    k = stop;
    // With the engine's evaluation every candidate's test waits on its reads; with VTK's only
    // tetrahedra (judged by the first candidate) do: there the cheap pre-test waits, while a
    // larger cell's Newton steps in VTK hide the loads.
    const bool ahead = nc > 1 && (engineEval || this->Cells.type(cand[0]) == mtree::kTetra);
    for (int j = 0, e = ahead ? std::min(nc, kIdsAhead) : 0; j < e; ++j)
    {
      this->Cells.prefetchPointIds(cand[j]);
    }
    for (int j = 0, e = ahead ? std::min(nc, kAhead) : 0; j < e; ++j)
    {
      this->Cells.prefetchPoints(cand[j]);
    }
    for (int j = 0; j < nc; ++j)
    {
      if (ahead && j + kIdsAhead < nc)
      {
        this->Cells.prefetchPointIds(cand[j + kIdsAhead]);
      }
      if (ahead && j + kAhead < nc)
      {
        this->Cells.prefetchPoints(cand[j + kAhead]);
      }
      CountQuery(kFcEvaluations);
      if (vtkMatrixTreeCellBridge::CellContains(
            ds, this->Cells, x, cand[j], cell, pcoords, weights, engineEval))
      {
        CountQuery(kFcFound);
        return cand[j];
      }
    }
  }
  return -1;
}

//------------------------------------------------------------------------------
int vtkMatrixTreeLocatorProcessor::FirstHit(vtkDataSet* ds, const double p1[3], const double p2[3], double tol,
  double& t, double x[3], double pcoords[3], int& subId, vtkIdType& cellId, vtkGenericCell* cell) const
{
  vtkMatrixTreeFirstHitQuery query(*this, ds, p1, p2, tol, cell);
  return query.Run(t, x, pcoords, subId, cellId);
}

int vtkMatrixTreeLocatorProcessor::AllHits(
  vtkDataSet* ds, const double p1[3], const double p2[3], vtkPoints* points, vtkIdList* cellIds) const
{
  struct Hit
  {
    double t;
    vtkIdType id;
    double x[3];
  };
  std::vector<Hit> hits;
  std::unordered_set<vtkIdType> seen;
  vtkNew<vtkGenericCell> cell;
  const mtree::Vec3 o(p1), d = mtree::Vec3(p2) - mtree::Vec3(p1);
  const mtree::SegmentFrame frame(o, mtree::Vec3(p2), 0.0, vtkMatrixTreeCellBridge::kVtkQuadSplit);
  this->Tree.traverseRay(
    o, d, 0.0, 1.0,
    [&](const uint32_t* ids, uint32_t count, double, double) {
      for (uint32_t k = 0; k < count; ++k)
      {
        const vtkIdType id = ids[k];
        if (!seen.insert(id).second ||
          !mtree::segmentMayHitCell(frame, this->Cells, static_cast<size_t>(id), 1.0))
        {
          continue;
        }
        Hit h;
        h.id = id;
        // A triangle without VTK, as in the first-hit query; VTK's own cell otherwise.
        mtree::vtk91::LineHit lh;
        const mtree::vtk91::FaceHit v = vtkMatrixTreeCellBridge::RecomputedTriangleHit(this->Cells, id, p1, p2, lh);
        if (v == mtree::vtk91::FaceHit::kHit)
        {
          h.t = lh.t;
          std::copy(lh.x, lh.x + 3, h.x);
          hits.push_back(h);
        }
        if (v != mtree::vtk91::FaceHit::kAskVtk)
        {
          continue;
        }
        ds->GetCell(id, cell);
        double pc[3];
        int sid;
        if (cell->IntersectWithLine(p1, p2, 0.0, h.t, h.x, pc, sid))
        {
          hits.push_back(h);
        }
      }
      return false;
    },
    nullptr);
  std::sort(hits.begin(), hits.end(),
    [](const Hit& a, const Hit& b) { return a.t < b.t || (a.t == b.t && a.id < b.id); });
  for (const Hit& h : hits)
  {
    if (points)
    {
      points->InsertNextPoint(h.x);
    }
    if (cellIds)
    {
      cellIds->InsertNextId(h.id);
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
  std::vector<double> weights(static_cast<size_t>(std::max(ds->GetMaxCellSize(), 1)));
  double cp[3], pc[3], d2;
  int sid;
  vtkIdType bestId = -1;
  double bestPoint[3] = { 0, 0, 0 };
  int bestSub = 0, bestInside = 0;
  double bestD2 = 0;
  const double radius2 = std::isinf(radius) ? std::numeric_limits<double>::infinity() : radius * radius;
  mtree::closestPrimitiveSearch(
    this->Tree, x, radius2,
    [&](uint32_t id, double bound2) {
      return !(BoundsDistance2(x, this->Cells.cellBox(static_cast<size_t>(id)).data()) > bound2);
    },
    [&](uint32_t id32, double bound2) {
      const vtkIdType id = id32;
      ds->GetCell(id, cell);
      const int ret = cell->EvaluatePosition(x, cp, sid, pc, d2, weights.data());
      if (ret == -1)
      {
        return bound2; // a degenerate cell
      }
      // EvaluatePosition's dist2 and closest point are right for every cell dimension (for a
      // triangle "inside" means the projection falls inside, and dist2 is the plane distance).
      // Equal distances: the lowest cell id.
      if (d2 < bound2 || (d2 == bound2 && bestId >= 0 && id < bestId) || (bestId < 0 && d2 <= bound2))
      {
        bestId = id;
        bestD2 = d2;
        std::copy(cp, cp + 3, bestPoint);
        bestSub = sid;
        bestInside = ret == 1 ? 1 : 0;
        return d2;
      }
      return bound2;
    });
  if (bestId < 0)
  {
    return 0;
  }
  cellId = bestId;
  subId = bestSub;
  inside = bestInside;
  dist2 = bestD2;
  std::copy(bestPoint, bestPoint + 3, closestPoint);
  ds->GetCell(bestId, cell);
  return 1;
}

//------------------------------------------------------------------------------
void vtkMatrixTreeLocatorProcessor::CellsWithinBounds(const double bbox[6], vtkIdList* cells) const
{
  // VTK's semantics: every cell whose bounds meet the box. A cell is only in the leaves it
  // overlaps, so the candidates come from the leaves of the box widened by the largest cell
  // extent (a cell whose bounds meet the box overlaps that), then the cells' bounds decide.
  const double* e = this->MaxCellExtent;
  mtree::Box q;
  q.lo = mtree::Vec3(bbox[0] - e[0], bbox[2] - e[1], bbox[4] - e[2]);
  q.hi = mtree::Vec3(bbox[1] + e[0], bbox[3] + e[1], bbox[5] + e[2]);
  mtree::Box query;
  query.lo = mtree::Vec3(bbox[0], bbox[2], bbox[4]);
  query.hi = mtree::Vec3(bbox[1], bbox[3], bbox[5]);
  for (const uint32_t id : mtree::primitivesInLeavesOverlapping(this->Tree, q))
  {
    // The float bounds contain the exact ones: a miss is final, a hit is checked exactly.
    const std::array<float, 6> b = this->Cells.cellBox(id);
    if (b[0] <= bbox[1] && b[1] >= bbox[0] && b[2] <= bbox[3] && b[3] >= bbox[2] && b[4] <= bbox[5] &&
      b[5] >= bbox[4] && this->Cells.exactBounds(id).overlaps(query))
    {
      cells->InsertNextId(id);
    }
  }
}

void vtkMatrixTreeLocatorProcessor::CellsAlongLine(const double p1[3], const double p2[3], vtkIdList* cells) const
{
  std::vector<vtkIdType> found;
  const mtree::Vec3 o(p1), d = mtree::Vec3(p2) - mtree::Vec3(p1);
  this->Tree.traverseRay(
    o, d, 0.0, 1.0,
    [&](const uint32_t* ids, uint32_t count, double, double) {
      found.insert(found.end(), ids, ids + count);
      return false;
    },
    nullptr);
  std::sort(found.begin(), found.end());
  found.erase(std::unique(found.begin(), found.end()), found.end());
  for (vtkIdType id : found)
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
    this->CL->upload(this->Tree, this->Cells, this->LeafBoxes);
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
  const uint32_t* prims = this->Tree.primitiveIndices().data();
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
            !vtkMatrixTreeCellBridge::CellContains(this->DS, this->P.Cells, x, id, this->Cell, p, this->Wk.data(),
              this->P.Tuning.EngineCellEvaluation))
          {
            ++this->Unconfirmed;
            resume = true;
          }
        }
        if (resume)
        {
          ++this->Resumes;
          const mtree::NodeRef leaf = this->P.Tree.leafHolding(mtree::Vec3(x));
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
  vtkMatrixTreeBatchRunner::Run(ds, points->GetNumberOfPoints(), threads, 1024, [&]() {
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
  this->Tree.enableStepTable(tuning.RayStepTable); // the tree keeps it across builds
  return rebuild;
}

void vtkMatrixTreeLocatorProcessor::IntersectSegments(vtkDataSet* ds, vtkDataArray* p1, vtkDataArray* p2,
  double tol, int threads, double* t, vtkIdType* ids, double* xp) const
{
  vtkMatrixTreeBatchRunner::Run(ds, p1->GetNumberOfTuples(), threads, 256, [&]() {
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
  vtkMatrixTreeBatchRunner::Run(ds, points->GetNumberOfPoints(), threads, 256, [&]() {
    return [&, cell = vtkSmartPointer<vtkGenericCell>::New()](vtkIdType i) {
      double x[3], c[3], d = VTK_DOUBLE_MAX;
      int sub = 0, inside = 0;
      vtkIdType id = -1;
      points->GetPoint(i, x);
      if (!this->Tree.empty())
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
    ? this->Tree.bytes() + this->Cells.bytes() + this->LeafBoxes.size() + (this->ShapeMemo ? this->Cells.size() : 0)
    : 0;
}

// Locator benchmark driver: every locator on one grid, the same seeded points and segments, in
// one process. Prints one JSON object per locator on stdout (bench/locators.py collects them).
//
//   locators_bench GRID.vtu|.vtp NUM_POINTS NUM_RAYS THREADS [HEIGHT [ONLY,NAMES [BACKEND]]]
//
// FindCell runs single-threaded and on THREADS OpenMP threads (one vtkGenericCell per thread:
// FindCell with a generic cell is thread-safe in every locator measured). IntersectWithLine is
// timed single-threaded. The THREADS loop runs 3 times per locator and the best pass is
// reported. The one-thread loops (FindCell and rays) are interleaved across the locators, slice
// by slice (see "paired" below): findcell_pts_per_s_1thread, findcell_pts_per_cpu_s_1thread,
// rays_per_s and rays_per_cpu_s come from each slice's fastest of 3 passes, and
// findcell_paired_ratio_vs_static / rays_paired_ratio_vs_static (with _q1 and _q3, the
// quartiles) are the median over slices and passes of vtkStaticCellLocator's CPU time over this
// locator's on the same slice, taken back to back (-1 without a vtkStaticCellLocator row).
// Disagreements are counted against vtkCellLocator, VTK's reference.
// build_ms: median of 3 builds, each after FreeSearchStructure (nothing kept from the last one);
// build_first_ms: the first of those 3 (the locator's first build in this process);
// rebuild_ms: median of 3 BuildLocator calls after the points moved (see the loop: what a
// deforming mesh costs per frame, with whatever storage the locator keeps between builds).
//
// The matrix-tree rows also time the batched FindCells (ids only; best of 3 after one warm-up
// call): batch_pts_per_s. BACKEND cpu (default) | opencl | all: opencl adds the row
// "matrix-octree-opencl" (Backend OPENCL; "opencl" alone drops the CPU matrix rows), whose
// findcell_pts_per_s_* are the batched FindCells with 1 and THREADS host threads (the
// one-point FindCell stays on the CPU), with first_call_ms (upload, and kernel compile when
// PoCL's cache is cold) and its phases, the phases of the last call, and differs_from_cpu (ids that differ from
// matrix-octree's batch, expected 0; -1 without that row).
#include "locator_bench_common.h"
#include "vtkMatrixTreeLocator.h"
#include "vtkMatrixTreeLocatorTuning.h"

#include "vtkCellLocator.h"
#include "vtkCellTreeLocator.h"
#include "vtkDataSet.h"
#include "vtkGenericCell.h"
#include "vtkIdTypeArray.h"
#include "vtkModifiedBSPTree.h"
#include "vtkNew.h"
#include "vtkPointSet.h"
#include "vtkPoints.h"
#include "vtkPolyData.h"
#include "vtkUnstructuredGrid.h"
#include "vtkSmartPointer.h"
#include "vtkStaticCellLocator.h"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

namespace
{
using locbench::Now;
using locbench::ThreadCpuNow;

bool Contains(vtkDataSet* ds, vtkIdType id, const double x[3])
{
  vtkNew<vtkGenericCell> c;
  ds->GetCell(id, c);
  double cp[3], pc[3], d2, w[64];
  int sub;
  return c->EvaluatePosition(x, cp, sub, pc, d2, w) == 1;
}
}

int main(int argc, char* argv[])
{
  if (argc < 5)
  {
    std::fprintf(stderr, "usage: %s GRID.vtu|.vtp NUM_POINTS NUM_RAYS THREADS\n", argv[0]);
    return 2;
  }
  const std::string path = argv[1];
  const int nPts = std::atoi(argv[2]), nRays = std::atoi(argv[3]), threads = std::atoi(argv[4]);
  const int height = argc > 5 ? std::atoi(argv[5]) : 0; // matrix-tree height, 0 = automatic
  // Optional comma-separated list of locator names to run (for profiling one of them);
  // without vtkCellLocator in the list, disagreements are not counted (-1).
  const std::string only = argc > 6 ? argv[6] : "";
  const std::string backend = argc > 7 ? argv[7] : "cpu";
  if (backend != "cpu" && backend != "opencl" && backend != "all")
  {
    std::fprintf(stderr, "BACKEND must be cpu, opencl or all, got '%s'\n", backend.c_str());
    return 2;
  }
  vtkSmartPointer<vtkDataSet> ds = locbench::ReadGrid(path);
  if (!ds || ds->GetNumberOfCells() == 0)
  {
    std::fprintf(stderr, "could not read cells from %s\n", path.c_str());
    return 1;
  }
  double b[6];
  ds->GetBounds(b);
  std::vector<double> pts, seg;
  locbench::SeededQueries(b, nPts, nRays, 42, pts, seg);

  struct Entry
  {
    const char* name;
    vtkSmartPointer<vtkAbstractCellLocator> loc;
  };
  std::vector<Entry> locs;
  auto addMatrix = [&](const char* name, int type, bool exact, bool opencl = false) {
    auto l = vtkSmartPointer<vtkMatrixTreeLocator>::New();
    l->SetTreeType(type);
    l->SetExactOverlap(exact);
    l->SetHeight(height);
    l->SetBackend(opencl ? vtkMatrixTreeLocator::OPENCL : vtkMatrixTreeLocator::CPU);
    locs.push_back({ name, l });
  };
  if (backend != "opencl")
  {
    addMatrix("matrix-octree", 0, false);
    addMatrix("matrix-kdtree", 1, false);
    addMatrix("matrix-octree-exact", 0, true);
  }
  if (backend != "cpu")
  {
    addMatrix("matrix-octree-opencl", 0, false, true);
  }
  locs.push_back({ "vtkStaticCellLocator", vtkSmartPointer<vtkStaticCellLocator>::New() });
  locs.push_back({ "vtkCellLocator", vtkSmartPointer<vtkCellLocator>::New() });
  locs.push_back({ "vtkCellTreeLocator", vtkSmartPointer<vtkCellTreeLocator>::New() });
  locs.push_back({ "vtkModifiedBSPTree", vtkSmartPointer<vtkModifiedBSPTree>::New() });
  if (!only.empty())
  {
    const std::string list = "," + only + ",";
    locs.erase(std::remove_if(locs.begin(), locs.end(),
                 [&](const Entry& e) {
                   return list.find("," + std::string(e.name) + ",") == std::string::npos;
                 }),
      locs.end());
  }

  struct Result
  {
    double buildMs, firstBuildMs = -1, rebuildMs = -1, pps1, ppsAll, raysPerS, raysPerCpuS = 0, pps1Cpu = 0;
    long long bytes;
    long long height = -1, refs = -1, leaves = -1; // matrix trees only
    std::vector<vtkIdType> found;
    std::vector<double> rayT; // each segment's first-hit t, -1 on a miss
    double batchPps = -1, firstCallMs = -1;
    std::string device, phases, firstPhases;
    bool opencl = false, failed = false, matrix = false;
    // Paired one-thread ratios to vtkStaticCellLocator (its CPU time over this one's, per slice;
    // see below): first quartile, median, third quartile; -1 without a static row.
    double findPaired[3] = { -1, -1, -1 }, raysPaired[3] = { -1, -1, -1 };
    std::vector<unsigned long long> stats; // query statistics (stats builds of matrix rows)
  };
  vtkNew<vtkPoints> batchPoints;
  batchPoints->SetDataTypeToDouble();
  batchPoints->SetNumberOfPoints(nPts);
  for (int i = 0; i < nPts; ++i)
    batchPoints->SetPoint(i, &pts[3 * i]);
  constexpr int kRepeats = 3; // timed passes of each query loop, best kept
  // Query statistics (a -DMATRIXTREE_QUERY_STATS=ON build) are global counters: each matrix
  // row's share is summed from the counts taken around its own queries.
  auto addStats = [&](Result& res) {
    if (!res.matrix || !vtkMatrixTreeLocatorQueryStatistics::Enabled())
      return;
    const int ns = vtkMatrixTreeLocatorQueryStatistics::GetNumber();
    res.stats.resize(static_cast<size_t>(ns), 0);
    for (int i = 0; i < ns; ++i)
      res.stats[static_cast<size_t>(i)] += vtkMatrixTreeLocatorQueryStatistics::Get(i);
    vtkMatrixTreeLocatorQueryStatistics::Reset();
  };
  // The points the rebuilds move (point sets only) and a copy of the original ones.
  vtkPointSet* pset = vtkPointSet::SafeDownCast(ds);
  vtkPoints* moved = pset ? pset->GetPoints() : nullptr;
  vtkNew<vtkPoints> originalStore;
  vtkPoints* original = nullptr;
  double centre[3] = { 0.5 * (b[0] + b[1]), 0.5 * (b[2] + b[3]), 0.5 * (b[4] + b[5]) };
  if (moved)
  {
    originalStore->DeepCopy(moved);
    original = originalStore;
  }
  std::vector<Result> results;
  for (Entry& e : locs)
  {
    vtkAbstractCellLocator* loc = e.loc;
    loc->SetDataSet(ds);
    loc->LazyEvaluationOff();
    // The median of 3 BuildLocator() calls (ms), each after prepare(r) for r = 1, 2, 3 (untimed);
    // first (optional): the first call's ms.
    auto medianBuildMs = [loc](auto&& prepare, double* first = nullptr) {
      double ms[3];
      for (int r = 1; r <= 3; ++r)
      {
        prepare(r);
        const double t0 = Now();
        loc->BuildLocator();
        ms[r - 1] = (Now() - t0) * 1e3;
      }
      if (first)
        *first = ms[0];
      std::sort(ms, ms + 3);
      return ms[1];
    };
    Result res;
    // FreeSearchStructure + Modified force each build. The first of them is this locator's
    // first build in the process (build_first_ms).
    res.buildMs = medianBuildMs(
      [loc](int) {
        loc->FreeSearchStructure();
        loc->Modified();
      },
      &res.firstBuildMs);
    // Rebuilds after the points moved, the per-frame case of a deforming mesh: the points are
    // scaled about the bounds' centre by 1 + 1e-3 r (r = 1, 2, 3), the data set marked modified
    // and BuildLocator() called without FreeSearchStructure (a locator keeps whatever storage it
    // keeps); median of the 3. The original points are copied back and built on (untimed)
    // before the queries.
    if (original)
    {
      res.rebuildMs = medianBuildMs([&](int r) {
        const double s = 1.0 + 1e-3 * r;
        for (vtkIdType i = 0; i < moved->GetNumberOfPoints(); ++i)
        {
          double p[3];
          original->GetPoint(i, p);
          for (int a = 0; a < 3; ++a)
            p[a] = centre[a] + s * (p[a] - centre[a]);
          moved->SetPoint(i, p);
        }
        moved->Modified();
        ds->Modified();
      });
      moved->DeepCopy(original);
      moved->Modified();
      ds->Modified();
      loc->BuildLocator();
    }
    // Memory: the matrix tree reports its bytes; VTK 9.1's locators do not (-1).
    res.bytes = -1;
    if (auto* m = vtkMatrixTreeLocator::SafeDownCast(loc))
    {
      res.bytes = m->GetMemorySize();
      res.height = m->GetTreeHeight();
      res.refs = m->GetNumberOfReferences();
      res.leaves = m->GetNumberOfLeaves();
    }
    else if (auto* st = vtkStaticCellLocator::SafeDownCast(loc))
    {
      // VTK 9.1 reports no size: estimated from its layout (vtkStaticCellLocator.cxx): cell
      // bounds (6 doubles per cell), one (cell, bin) fragment of two ids per bin a cell's
      // bounds touch, and one offset per bin; ids are int unless LargeIds.
      int div[3];
      st->GetDivisions(div);
      const long long idBytes = st->GetLargeIds() ? 8 : 4;
      double sb[6], h[3];
      ds->GetBounds(sb);
      for (int a = 0; a < 3; ++a)
        h[a] = (sb[2 * a + 1] - sb[2 * a]) / div[a];
      long long frags = 0;
      for (vtkIdType c = 0; c < ds->GetNumberOfCells(); ++c)
      {
        double cb[6];
        ds->GetCellBounds(c, cb);
        long long k = 1;
        for (int a = 0; a < 3; ++a)
        {
          auto bin = [&](double v) {
            const int i = h[a] > 0 ? static_cast<int>((v - sb[2 * a]) / h[a]) : 0;
            return std::min(std::max(i, 0), div[a] - 1);
          };
          k *= bin(cb[2 * a + 1]) - bin(cb[2 * a]) + 1;
        }
        frags += k;
      }
      res.bytes = 48LL * ds->GetNumberOfCells() + 2 * idBytes * frags +
        idBytes * (static_cast<long long>(div[0]) * div[1] * div[2] + 1);
    }
    res.found.resize(static_cast<size_t>(nPts));
    res.rayT.assign(static_cast<size_t>(nRays), -1.0);
    auto* mloc = vtkMatrixTreeLocator::SafeDownCast(loc);
    res.opencl = mloc && mloc->GetBackend() == vtkMatrixTreeLocator::OPENCL;
    res.matrix = mloc != nullptr;
    vtkMatrixTreeLocatorQueryStatistics::Reset();
    // Batched FindCells (ids only) with nt host threads: one warm-up call, then best of 3.
    auto runBatch = [&](int nt) {
      mloc->SetNumberOfThreads(nt);
      vtkNew<vtkIdTypeArray> ids;
      double t0 = Now();
      mloc->FindCells(batchPoints, ids);
      const double first = (Now() - t0) * 1e3;
      if (res.firstCallMs < 0)
      {
        res.firstCallMs = first;
        res.firstPhases = mloc->GetLastFindCellsPhases();
      }
      double best = 1e300;
      for (int r = 0; r < 3; ++r)
      {
        t0 = Now();
        mloc->FindCells(batchPoints, ids);
        best = std::min(best, Now() - t0);
      }
      if (ids->GetNumberOfTuples() != nPts)
      {
        res.failed = true;
        return 0.0;
      }
      for (int i = 0; i < nPts; ++i)
        res.found[i] = ids->GetValue(i);
      return nPts / best;
    };
    // FindCell on nt threads: the best of kRepeats passes over the same points, by wall time
    // (this machine's speed drifts by tens of percent within a run). The one-thread loop is
    // timed by "paired" below.
    auto runFind = [&](int nt) {
      double bestWall = 0;
      for (int rep = 0; rep < kRepeats; ++rep)
      {
        const double t0 = Now();
#pragma omp parallel num_threads(nt)
        {
          vtkNew<vtkGenericCell> gc;
          double pc[3], w[64];
#pragma omp for schedule(static)
          for (int i = 0; i < nPts; ++i)
            res.found[i] = loc->FindCell(&pts[3 * i], 0.0, gc, pc, w);
        }
        bestWall = std::max(bestWall, nPts / (Now() - t0));
      }
      return bestWall;
    };
    if (res.opencl)
    {
      res.pps1 = runBatch(1);
      res.ppsAll = runBatch(threads);
      res.batchPps = res.ppsAll;
      res.device = mloc->GetOpenCLDeviceName();
      res.phases = mloc->GetLastFindCellsPhases();
    }
    else
    {
      if (mloc)
        res.batchPps = runBatch(threads);
      // The one-thread FindCell is timed below, interleaved with the other locators.
      res.ppsAll = runFind(threads);
    }
    addStats(res);
    results.push_back(std::move(res));
  }

  // One-thread FindCell and IntersectWithLine, paired: the queries are cut into kSlices slices,
  // and every locator runs the same slice back to back (the order rotating from slice to
  // slice), kPasses times over all slices. Each slice's time on a locator is thus taken
  // within milliseconds of vtkStaticCellLocator's on the same queries, and the paired ratio of
  // the two (the median over slices and passes) does not see this machine's drift, which
  // moved the best-of-3 ratios of separate loops by +-30% from run to run (brick_hex FindCell
  // 1.58-2.66 in three runs). Before each timed slice the locator answers queries of another
  // slice, untimed, for kWarmSeconds: the previous locator has just evicted its data from the
  // caches, and refilling them within the timed slice made a fast, latency-bound locator look
  // slower (brick_hex FindCell 1.95x with no warm-up, 2.10x after 2000 queries; lucy's 30 ns
  // FindCell needed more than that, hence a time). A locator's throughput: all queries over the
  // sum, per slice, of its fastest pass.
  constexpr int kPasses = 3, kSlices = 8;
  constexpr double kWarmSeconds = 2e-3;
  size_t staticIndex = 0;
  while (staticIndex < locs.size() && std::string(locs[staticIndex].name) != "vtkStaticCellLocator")
    ++staticIndex;
  auto paired = [&](int n, bool rays) {
    if (n <= 0)
      return;
    const size_t nl = locs.size();
    std::vector<std::vector<double>> cpu(nl, std::vector<double>(kPasses * kSlices, -1.0)), wall = cpu;
    vtkNew<vtkGenericCell> gc;
    double t, x[3], pc[3], w[64];
    int sub;
    vtkIdType cid;
    auto query = [&](vtkAbstractCellLocator* loc, int i, Result* res) {
      if (rays)
      {
        const int hit = loc->IntersectWithLine(&seg[6 * i], &seg[6 * i + 3], 0.0, t, x, pc, sub, cid, gc);
        if (res)
          res->rayT[i] = hit ? t : -1.0;
      }
      else
      {
        const vtkIdType c = loc->FindCell(&pts[3 * i], 0.0, gc, pc, w);
        if (res)
          res->found[i] = c;
      }
    };
    for (int pass = 0; pass < kPasses; ++pass)
      for (int sl = 0; sl < kSlices; ++sl)
      {
        const int lo = static_cast<int>(int64_t(n) * sl / kSlices);
        const int hi = static_cast<int>(int64_t(n) * (sl + 1) / kSlices);
        const int next = (sl + 1) % kSlices;
        const int wlo = static_cast<int>(int64_t(n) * next / kSlices);
        const int whi = static_cast<int>(int64_t(n) * (next + 1) / kSlices);
        const int k = pass * kSlices + sl;
        for (size_t j = 0; j < nl; ++j)
        {
          const size_t li = (j + static_cast<size_t>(k)) % nl;
          Result& res = results[li];
          // The OpenCL row's one-thread FindCell is its batched call (above); its rays are the
          // CPU's and are timed here.
          if (res.failed || (!rays && res.opencl))
            continue;
          vtkAbstractCellLocator* loc = locs[li].loc;
          // Warm-up: the next slice's queries (cycling) for at least kWarmSeconds of wall time.
          locbench::WarmUp(kWarmSeconds, whi - wlo, [&](int i) { query(loc, wlo + i, nullptr); });
          vtkMatrixTreeLocatorQueryStatistics::Reset();
          const double c0 = ThreadCpuNow(), t0 = Now();
          for (int i = lo; i < hi; ++i)
            query(loc, i, &res);
          cpu[li][k] = ThreadCpuNow() - c0;
          wall[li][k] = Now() - t0;
          addStats(res);
        }
      }
    for (size_t li = 0; li < nl; ++li)
    {
      Result& res = results[li];
      if (cpu[li][0] < 0)
        continue;
      double sumCpu = 0, sumWall = 0;
      for (int sl = 0; sl < kSlices; ++sl)
      {
        double bc = 1e300, bw = 1e300;
        for (int pass = 0; pass < kPasses; ++pass)
        {
          bc = std::min(bc, cpu[li][pass * kSlices + sl]);
          bw = std::min(bw, wall[li][pass * kSlices + sl]);
        }
        sumCpu += bc;
        sumWall += bw;
      }
      std::vector<double> ratios;
      if (staticIndex < nl && cpu[staticIndex][0] >= 0)
        for (int k = 0; k < kPasses * kSlices; ++k)
          ratios.push_back(cpu[staticIndex][k] / cpu[li][k]);
      double* q = rays ? res.raysPaired : res.findPaired;
      if (!ratios.empty())
      {
        q[0] = locbench::Quantile(ratios, 0.25);
        q[1] = locbench::Quantile(ratios, 0.5);
        q[2] = locbench::Quantile(ratios, 0.75);
      }
      if (rays)
      {
        res.raysPerS = n / sumWall;
        res.raysPerCpuS = n / sumCpu;
      }
      else
      {
        res.pps1 = n / sumWall;
        res.pps1Cpu = n / sumCpu;
      }
    }
  };
  paired(nPts, false);
  paired(nRays, true);
  for (size_t li = 0; li < locs.size(); ++li)
  {
    const Result& res = results[li];
    if (res.stats.empty())
      continue;
    // A build with -DMATRIXTREE_QUERY_STATS=ON: what this locator's queries did (batched and
    // all-thread FindCell, and the timed one-thread slices; not the warm-up queries), as
    // totals, to stderr (the JSON rows stay as they are).
    std::fprintf(stderr, "{\"query_stats\": \"%s\"", locs[li].name);
    for (int i = 0; i < vtkMatrixTreeLocatorQueryStatistics::GetNumber(); ++i)
      std::fprintf(stderr, ", \"%s\": %llu", vtkMatrixTreeLocatorQueryStatistics::GetName(i),
        static_cast<unsigned long long>(res.stats[static_cast<size_t>(i)]));
    std::fprintf(stderr, "}\n");
  }
  // Disagreements with vtkCellLocator: a cell that does not contain the point, or none where
  // vtkCellLocator found one. Where this locator finds a cell that contains the point and
  // vtkCellLocator finds none (it drops points outside its buckets' bounds, and a curved
  // quadratic cell can bulge past its nodes' bounds), the point counts as reference_misses.
  size_t refIndex = 0;
  while (refIndex < locs.size() && std::string(locs[refIndex].name) != "vtkCellLocator")
    ++refIndex;
  const bool haveRef = refIndex < locs.size();
  size_t cpuIndex = 0;
  while (cpuIndex < locs.size() && std::string(locs[cpuIndex].name) != "matrix-octree")
    ++cpuIndex;
  for (size_t li = 0; li < locs.size(); ++li)
  {
    const Result& r = results[li];
    long long dis = haveRef ? 0 : -1, refMisses = haveRef ? 0 : -1, found = 0;
    for (int i = 0; i < nPts; ++i)
    {
      found += r.found[i] >= 0;
      if (!haveRef)
        continue;
      const std::vector<vtkIdType>& ref = results[refIndex].found;
      if (r.found[i] < 0)
        dis += ref[i] >= 0;
      else if (r.found[i] != ref[i])
      {
        if (!Contains(ds, r.found[i], &pts[3 * i]))
          ++dis;
        else
          refMisses += ref[i] < 0;
      }
    }
    // Rays against vtkStaticCellLocator's: a hit against a miss, or first hits whose t differ
    // by more than 1e-9 (t runs over [0, 1] along the segment). A different cell at the same t
    // is a tie (a shared face), not counted.
    long long rayDis = -1;
    if (staticIndex < locs.size() && !r.failed && nRays > 0)
    {
      rayDis = 0;
      const std::vector<double>& st = results[staticIndex].rayT;
      for (int i = 0; i < nRays; ++i)
        rayDis += (r.rayT[i] < 0) != (st[i] < 0) || std::abs(r.rayT[i] - st[i]) > 1e-9;
    }
    long long differs = -1;
    if (r.opencl && cpuIndex < locs.size())
    {
      differs = 0;
      for (int i = 0; i < nPts; ++i)
        differs += r.found[i] != results[cpuIndex].found[i];
    }
    std::printf("{\"locator\": \"%s\", \"backend\": \"%s\", \"device\": \"%s\", \"cells\": %lld, "
                "\"build_ms\": %.3f, \"build_first_ms\": %.3f, \"rebuild_ms\": %.3f, \"bytes\": %lld, \"height\": %lld, \"refs\": %lld, \"leaves\": %lld, "
                "\"findcell_pts_per_s_1thread\": %.1f, \"findcell_pts_per_cpu_s_1thread\": %.1f, "
                "\"findcell_pts_per_s_all\": %.1f, \"threads\": %d, "
                "\"batch_pts_per_s\": %.1f, \"first_call_ms\": %.3f, \"first_call_phases\": \"%s\", \"phases\": \"%s\", "
                "\"differs_from_cpu\": %lld, \"failed\": %s, "
                "\"rays_per_s\": %.1f, \"rays_per_cpu_s\": %.1f, "
                "\"findcell_paired_ratio_vs_static\": %.4f, \"findcell_paired_ratio_q1\": %.4f, \"findcell_paired_ratio_q3\": %.4f, "
                "\"rays_paired_ratio_vs_static\": %.4f, \"rays_paired_ratio_q1\": %.4f, \"rays_paired_ratio_q3\": %.4f, "
                "\"points\": %d, \"found\": %lld, \"disagreements\": %lld, \"reference_misses\": %lld, "
                "\"ray_disagreements_vs_static\": %lld}\n",
      locs[li].name, r.opencl ? "opencl" : "cpu", r.device.c_str(), static_cast<long long>(ds->GetNumberOfCells()),
      r.buildMs, r.firstBuildMs, r.rebuildMs, r.bytes, r.height, r.refs, r.leaves, r.pps1, r.pps1Cpu, r.ppsAll, threads, r.batchPps, r.firstCallMs, r.firstPhases.c_str(), r.phases.c_str(), differs,
      r.failed ? "true" : "false", r.raysPerS, r.raysPerCpuS, r.findPaired[1], r.findPaired[0], r.findPaired[2],
      r.raysPaired[1], r.raysPaired[0], r.raysPaired[2], nPts, found, dis, refMisses, rayDis);
  }
  return 0;
}

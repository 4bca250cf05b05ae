// Paired comparison of two locator configurations on one grid, in one process.
//
//   locator_ab GRID.vtu|.vtp A B [POINTS [RAYS [ROUNDS [OUT.json]]]]
//
// A and B: "static" (vtkStaticCellLocator with VTK's defaults) or vtkMatrixTreeLocator settings,
// comma-separated, applied in order to a default locator ("default" or "" for none):
//   octree | kdtree, height=H, leaf_scale=S, max_candidates=C, exact=0|1, block=B, threads=T,
// and the fields of vtkMatrixTreeLocatorTuning: sort=radix|counting, cells=auto|in_place|copied,
//   engine_eval=0|1, step_table=0|1
// e.g. `locator_ab lucy.vtp default leaf_scale=6`.
//
// Why: on this kind of shared machine a locator's speed drifts by tens of percent within a
// minute, and the same code's fastest loop differed by up to 70% between processes (lucy rays,
// 735-1246 ns), so two configurations timed in separate loops or processes cannot be told
// apart at the 5% level. Here A and B alternate, ROUNDS times (default 20), on the same
// queries:
//   build: FreeSearchStructure + BuildLocator, wall time (the build's own threads);
//   findcell: POINTS (default 20000) seeded points in the bounds, one thread, thread CPU time;
//   rays: RAYS (default 20000) seeded segments of a quarter of the diagonal, first hit, one
//   thread, thread CPU time.
// Before each timed query loop the locator answers queries of a second seeded set for 2 ms,
// untimed (the other configuration has just evicted its data from the caches). Each
// round gives one ratio B/A per measure; the table shows A's and B's median times and the
// median ratio with its quartiles. An A against itself gave 0.99-1.02 here. The answers are
// compared too (FindCell: cells that differ where B's does not contain the point; rays: hits
// that differ in cell or in t by more than 1e-9 of the segment): a change of settings must not
// change them beyond what VTK's tolerances allow.
//
// Prints a table; OUT.json (optional) gets one object per measure.
#include "locator_bench_common.h"
#include "vtkMatrixTreeLocator.h"
#include "vtkMatrixTreeLocatorTuning.h"

#include "vtkAbstractCellLocator.h"
#include "vtkDataSet.h"
#include "vtkGenericCell.h"
#include "vtkNew.h"
#include "vtkSmartPointer.h"
#include "vtkStaticCellLocator.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace
{
using locbench::Now;
using locbench::ThreadCpuNow;

// A locator from a configuration string (see the header); throws std::invalid_argument.
vtkSmartPointer<vtkAbstractCellLocator> MakeLocator(const std::string& config)
{
  if (config == "static")
  {
    return vtkSmartPointer<vtkStaticCellLocator>::New();
  }
  auto loc = vtkSmartPointer<vtkMatrixTreeLocator>::New();
  vtkMatrixTreeLocatorTuning tuning;
  std::stringstream list(config == "default" ? std::string() : config);
  std::string item;
  while (std::getline(list, item, ','))
  {
    if (item.empty())
      continue;
    const size_t eq = item.find('=');
    const std::string key = item.substr(0, eq);
    const std::string val = eq == std::string::npos ? std::string() : item.substr(eq + 1);
    auto number = [&]() {
      char* end = nullptr;
      const double v = std::strtod(val.c_str(), &end);
      if (val.empty() || *end != '\0' || !std::isfinite(v))
        throw std::invalid_argument("'" + item + "': expected " + key + "=NUMBER");
      return v;
    };
    if (key == "octree" && val.empty())
      loc->SetTreeTypeToOctree();
    else if (key == "kdtree" && val.empty())
      loc->SetTreeTypeToKdTree();
    else if (key == "height")
      loc->SetHeight(static_cast<int>(number()));
    else if (key == "leaf_scale")
      loc->SetLeafScale(number());
    else if (key == "max_candidates")
      loc->SetMaxCandidates(number());
    else if (key == "exact")
      loc->SetExactOverlap(number() != 0);
    else if (key == "block")
      loc->SetBlockSize(static_cast<int>(number()));
    else if (key == "threads")
      loc->SetNumberOfThreads(static_cast<int>(number()));
    else if (key == "engine_eval")
      tuning.EngineCellEvaluation = number() != 0;
    else if (key == "step_table")
      tuning.RayStepTable = number() != 0;
    else if (key == "sort" && (val == "radix" || val == "counting"))
      tuning.BuildSort = val == "radix" ? vtkMatrixTreeLocatorTuning::RADIX : vtkMatrixTreeLocatorTuning::COUNTING;
    else if (key == "cells" && (val == "auto" || val == "in_place" || val == "copied"))
      tuning.CellStorage = val == "auto" ? vtkMatrixTreeLocatorTuning::CELLS_AUTOMATIC
        : val == "in_place"             ? vtkMatrixTreeLocatorTuning::CELLS_IN_PLACE
                                        : vtkMatrixTreeLocatorTuning::CELLS_COPIED;
    else
      throw std::invalid_argument("unknown setting '" + item + "'");
  }
  loc->SetTuning(tuning);
  return loc;
}

std::string Describe(vtkAbstractCellLocator* loc)
{
  auto* m = vtkMatrixTreeLocator::SafeDownCast(loc);
  if (!m)
    return "vtkStaticCellLocator";
  char s[160];
  std::snprintf(s, sizeof(s), "height %d, %lld references, %lld bytes", m->GetTreeHeight(),
    static_cast<long long>(m->GetNumberOfReferences()), static_cast<long long>(m->GetMemorySize()));
  return s;
}

struct Measure
{
  std::string name;
  std::vector<double> a, b; // per round: seconds (build) or seconds per query
};

} // namespace

int main(int argc, char** argv)
{
  if (argc < 4)
  {
    std::fprintf(stderr, "usage: %s GRID.vtu|.vtp A B [POINTS [RAYS [ROUNDS [OUT.json]]]]\n", argv[0]);
    return 2;
  }
  const std::string path = argv[1];
  const int nPts = argc > 4 ? std::atoi(argv[4]) : 20000;
  const int nRays = argc > 5 ? std::atoi(argv[5]) : 20000;
  const int rounds = argc > 6 ? std::max(1, std::atoi(argv[6])) : 20;
  const char* jsonPath = argc > 7 ? argv[7] : nullptr;
  vtkSmartPointer<vtkDataSet> ds = locbench::ReadGrid(path);
  if (!ds || ds->GetNumberOfCells() == 0)
  {
    std::fprintf(stderr, "could not read cells from %s\n", path.c_str());
    return 1;
  }
  vtkSmartPointer<vtkAbstractCellLocator> loc[2];
  try
  {
    loc[0] = MakeLocator(argv[2]);
    loc[1] = MakeLocator(argv[3]);
  }
  catch (const std::invalid_argument& e)
  {
    std::fprintf(stderr, "%s\n", e.what());
    return 2;
  }
  for (auto& l : loc)
  {
    l->SetDataSet(ds);
    l->LazyEvaluationOff();
    l->BuildLocator();
  }
  std::printf("%s: %lld cells\n  A = %s: %s\n  B = %s: %s\n", path.c_str(),
    static_cast<long long>(ds->GetNumberOfCells()), argv[2], Describe(loc[0]).c_str(), argv[3],
    Describe(loc[1]).c_str());

  // The queries: locators_bench's (seed 42), and a second set (seed 4242) for the warm-ups:
  // the same distribution, not the same queries.
  double b[6];
  ds->GetBounds(b);
  std::vector<double> pts, seg, warmPts, warmSeg;
  locbench::SeededQueries(b, nPts, nRays, 42, pts, seg);
  locbench::SeededQueries(b, nPts, nRays, 4242, warmPts, warmSeg);

  vtkNew<vtkGenericCell> gc;
  double pc[3], w[64], x[3];
  int sub;
  std::vector<vtkIdType> foundCell[2];
  std::vector<double> rayT[2];
  std::vector<vtkIdType> rayCell[2];
  for (int s = 0; s < 2; ++s)
  {
    foundCell[s].assign(static_cast<size_t>(nPts), -1);
    rayT[s].assign(static_cast<size_t>(nRays), 0.0);
    rayCell[s].assign(static_cast<size_t>(nRays), -1);
  }
  auto findLoop = [&](vtkAbstractCellLocator* l, const double* p, int n, vtkIdType* out) {
    for (int i = 0; i < n; ++i)
    {
      const vtkIdType c = l->FindCell(const_cast<double*>(p + 3 * static_cast<size_t>(i)), 0.0, gc, pc, w);
      if (out)
        out[i] = c;
    }
  };
  auto rayLoop = [&](vtkAbstractCellLocator* l, const double* sg, int n, double* ts, vtkIdType* cs) {
    for (int i = 0; i < n; ++i)
    {
      double t;
      vtkIdType cid;
      l->IntersectWithLine(sg + 6 * static_cast<size_t>(i), sg + 6 * static_cast<size_t>(i) + 3, 0.0, t, x, pc, sub, cid, gc);
      if (ts)
      {
        ts[i] = cid >= 0 ? t : -1.0;
        cs[i] = cid;
      }
    }
  };
  // Warm-up: the second set of queries, cycling, for 2 ms.
  auto warm = [&](vtkAbstractCellLocator* l, bool rays) {
    const int n = rays ? nRays : nPts;
    locbench::WarmUp(2e-3, n, [&](int i) {
      if (rays)
        rayLoop(l, warmSeg.data() + 6 * static_cast<size_t>(i), 1, nullptr, nullptr);
      else
        findLoop(l, warmPts.data() + 3 * static_cast<size_t>(i), 1, nullptr);
    });
  };
  Measure build{ "build", {}, {} }, find{ "findcell", {}, {} }, rays{ "rays", {}, {} };
  for (int r = 0; r < rounds; ++r)
  {
    // A first on even rounds, B first on odd ones.
    for (int j = 0; j < 2; ++j)
    {
      const int s = (j + r) % 2;
      vtkAbstractCellLocator* l = loc[s];
      const double t0 = Now();
      l->FreeSearchStructure();
      l->BuildLocator();
      (s ? build.b : build.a).push_back(Now() - t0);
      if (nPts > 0)
      {
        warm(l, false);
        const double c0 = ThreadCpuNow();
        findLoop(l, pts.data(), nPts, foundCell[s].data());
        (s ? find.b : find.a).push_back((ThreadCpuNow() - c0) / nPts);
      }
      if (nRays > 0)
      {
        warm(l, true);
        const double c0 = ThreadCpuNow();
        rayLoop(l, seg.data(), nRays, rayT[s].data(), rayCell[s].data());
        (s ? rays.b : rays.a).push_back((ThreadCpuNow() - c0) / nRays);
      }
    }
  }
  // The answers of the last round: B's against A's.
  long long findDiff = 0, rayDiff = 0;
  for (int i = 0; i < nPts; ++i)
  {
    const vtkIdType ca = foundCell[0][i], cb = foundCell[1][i];
    if (ca == cb)
      continue;
    bool contained = false;
    if (cb >= 0)
    {
      ds->GetCell(cb, gc);
      double cp[3], d2;
      int sid;
      contained = gc->EvaluatePosition(&pts[3 * static_cast<size_t>(i)], cp, sid, pc, d2, w) == 1;
    }
    findDiff += (ca < 0) != (cb < 0) || !contained;
  }
  for (int i = 0; i < nRays; ++i)
    rayDiff += rayCell[0][i] != rayCell[1][i] || std::fabs(rayT[0][i] - rayT[1][i]) > 1e-9;

  std::printf("\n%-9s %14s %14s %12s %12s %12s\n", "measure", "A (median)", "B (median)", "B/A q1", "B/A median",
    "B/A q3");
  std::string json = "[";
  for (const Measure* m : { &build, &find, &rays })
  {
    if (m->a.empty())
      continue;
    std::vector<double> ratio;
    for (size_t k = 0; k < m->a.size(); ++k)
      ratio.push_back(m->b[k] / m->a[k]);
    const bool perQuery = m != &build;
    const double scale = perQuery ? 1e9 : 1e3;
    const char* unit = perQuery ? "ns" : "ms";
    const double ma = locbench::Quantile(m->a, 0.5) * scale, mb = locbench::Quantile(m->b, 0.5) * scale;
    const double q1 = locbench::Quantile(ratio, 0.25), q2 = locbench::Quantile(ratio, 0.5), q3 = locbench::Quantile(ratio, 0.75);
    std::printf("%-9s %11.2f %s %11.2f %s %12.3f %12.3f %12.3f\n", m->name.c_str(), ma, unit, mb, unit, q1, q2, q3);
    char row[512];
    std::snprintf(row, sizeof(row),
      "%s{\"grid\": \"%s\", \"a\": \"%s\", \"b\": \"%s\", \"measure\": \"%s\", \"unit\": \"%s\", \"a_median\": %.6g, "
      "\"b_median\": %.6g, \"ratio_q1\": %.5f, \"ratio_median\": %.5f, \"ratio_q3\": %.5f, \"rounds\": %d}",
      json.size() > 1 ? ", " : "", path.substr(path.find_last_of('/') + 1).c_str(), argv[2], argv[3], m->name.c_str(),
      unit, ma, mb, q1, q2, q3, rounds);
    json += row;
  }
  json += "]\n";
  std::printf("\nanswers, B against A (last round): FindCell %lld of %d differ (a cell that does not contain "
              "the point, or found/not found), rays %lld of %d (cell, or t by more than 1e-9)\n",
    findDiff, nPts, rayDiff, nRays);
  if (jsonPath)
  {
    FILE* f = std::fopen(jsonPath, "w");
    if (!f)
    {
      std::fprintf(stderr, "cannot write %s\n", jsonPath);
      return 1;
    }
    std::fputs(json.c_str(), f);
    std::fclose(f);
    std::printf("wrote %s\n", jsonPath);
  }
  return 0;
}

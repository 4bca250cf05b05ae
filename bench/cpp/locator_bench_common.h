// What the locator benchmark drivers (locators_bench.cxx, locator_ab.cxx) share: the clocks,
// reading a grid file, and the seeded queries, so that both time the same points and segments.
#pragma once

#include "vtkDataSet.h"
#include "vtkNew.h"
#include "vtkPolyData.h"
#include "vtkSmartPointer.h"
#include "vtkUnstructuredGrid.h"
#include "vtkXMLPolyDataReader.h"
#include "vtkXMLUnstructuredGridReader.h"

#include <time.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

namespace locbench
{
inline double Now()
{
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// CPU time of the calling thread: a one-thread query loop's own time, leaving out the time it
// waited for a core on a shared machine.
inline double ThreadCpuNow()
{
  timespec ts;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

// Calls query(i) for i = 0, 1, ..., n - 1, cycling, until `seconds` of wall time have passed
// (checked every 32 calls); nothing when n <= 0. The drivers' untimed warm-up before a timed
// loop: the locator timed before has evicted this one's data from the caches.
template <class Query>
void WarmUp(double seconds, int n, Query&& query)
{
  if (n <= 0)
    return;
  const double t0 = Now();
  for (int i = 0, k = 0;; ++k)
  {
    query(i);
    i = i + 1 < n ? i + 1 : 0;
    if ((k & 31) == 31 && Now() - t0 >= seconds)
      break;
  }
}

// The q-quantile of v (0 <= q <= 1, v not empty), interpolated linearly between the sorted
// values: the median of an even count is the mean of the middle two.
inline double Quantile(std::vector<double> v, double q)
{
  std::sort(v.begin(), v.end());
  const double pos = q * (v.size() - 1);
  const size_t i = static_cast<size_t>(pos);
  const double f = pos - i;
  return i + 1 < v.size() ? v[i] * (1 - f) + v[i + 1] * f : v[i];
}

// A .vtp (vtkPolyData) or any other name as .vtu (vtkUnstructuredGrid); null or cell-less when
// the file could not be read.
inline vtkSmartPointer<vtkDataSet> ReadGrid(const std::string& path)
{
  vtkSmartPointer<vtkDataSet> ds;
  if (path.size() > 4 && path.compare(path.size() - 4, 4, ".vtp") == 0)
  {
    vtkNew<vtkXMLPolyDataReader> r;
    r->SetFileName(path.c_str());
    r->Update();
    ds = r->GetOutput();
  }
  else
  {
    vtkNew<vtkXMLUnstructuredGridReader> r;
    r->SetFileName(path.c_str());
    r->Update();
    ds = r->GetOutput();
  }
  return ds;
}

// nPts points uniform in the bounds b (3 doubles each), then nRays segments (6 doubles each)
// from uniform points, in uniform directions of the cube [-0.5, 0.5]^3 normalised, a quarter of
// the bounds' diagonal long; one generator seeded with `seed`, points first.
inline void SeededQueries(const double b[6], int nPts, int nRays, uint64_t seed, std::vector<double>& pts,
  std::vector<double>& seg)
{
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  pts.assign(3 * static_cast<size_t>(nPts), 0.0);
  seg.assign(6 * static_cast<size_t>(nRays), 0.0);
  for (int i = 0; i < nPts; ++i)
    for (int a = 0; a < 3; ++a)
      pts[3 * i + a] = b[2 * a] + U(rng) * (b[2 * a + 1] - b[2 * a]);
  const double diag = std::sqrt((b[1] - b[0]) * (b[1] - b[0]) + (b[3] - b[2]) * (b[3] - b[2]) +
    (b[5] - b[4]) * (b[5] - b[4]));
  for (int i = 0; i < nRays; ++i)
  {
    double d[3], n2 = 0;
    for (int a = 0; a < 3; ++a)
    {
      seg[6 * i + a] = b[2 * a] + U(rng) * (b[2 * a + 1] - b[2 * a]);
      d[a] = U(rng) - 0.5;
      n2 += d[a] * d[a];
    }
    for (int a = 0; a < 3; ++a)
      seg[6 * i + 3 + a] = seg[6 * i + a] + d[a] / std::sqrt(n2) * 0.25 * diag;
  }
}
} // namespace locbench

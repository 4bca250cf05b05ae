// Private to the MatrixTree::Filters module: the query counters behind
// vtkMatrixTreeLocatorQueryStatistics. CountQuery is a relaxed atomic add in a build configured
// with -DMATRIXTREE_QUERY_STATS=ON and nothing otherwise (kQueryStats false), so that the
// counting sites cost nothing in a normal build.
#ifndef vtkMatrixTreeQueryStatistics_h
#define vtkMatrixTreeQueryStatistics_h

#include <atomic>
#include <cstdint>

#include "mtree/vtk91/locator_events.h"

namespace vtkMatrixTreeQueryStatistics
{
// The counters are the engine locator's events (mtree::vtk91::LocatorEvent), in its order.
using QueryStat = mtree::vtk91::LocatorEvent;
constexpr int kNumQueryStats = static_cast<int>(QueryStat::kCount);

#if defined(MATRIXTREE_QUERY_STATS) && MATRIXTREE_QUERY_STATS
constexpr bool kQueryStats = true;
extern std::atomic<uint64_t> gQueryStats[kNumQueryStats];
inline void CountQuery(QueryStat s, uint64_t n = 1)
{
  gQueryStats[static_cast<int>(s)].fetch_add(n, std::memory_order_relaxed);
}
#else
constexpr bool kQueryStats = false;
inline void CountQuery(QueryStat, uint64_t = 1) {}
#endif
}

#endif

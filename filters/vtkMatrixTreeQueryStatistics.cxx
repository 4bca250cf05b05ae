#include "vtkMatrixTreeQueryStatistics.h"
#include "vtkMatrixTreeLocatorTuning.h"

namespace vtkMatrixTreeQueryStatistics
{
namespace
{
const char* const kQueryStatNames[kNumQueryStats] = { "findcell_queries", "findcell_leaf_scans",
  "findcell_references", "findcell_box_passes", "findcell_evaluations", "findcell_found", "ray_queries",
  "ray_steps", "ray_node_visits", "ray_leaves", "ray_references", "ray_candidates", "ray_cell_tests",
  "ray_mailbox_repeats", "ray_proved_misses", "ray_certain_hits", "ray_vtk_calls", "ray_hits" };
}
#if defined(MATRIXTREE_QUERY_STATS) && MATRIXTREE_QUERY_STATS
std::atomic<uint64_t> gQueryStats[kNumQueryStats];
#endif
}

using namespace vtkMatrixTreeQueryStatistics;

bool vtkMatrixTreeLocatorQueryStatistics::Enabled()
{
  return kQueryStats;
}

int vtkMatrixTreeLocatorQueryStatistics::GetNumber()
{
  return kQueryStats ? kNumQueryStats : 0;
}

const char* vtkMatrixTreeLocatorQueryStatistics::GetName(int i)
{
  return i >= 0 && i < GetNumber() ? kQueryStatNames[i] : nullptr;
}

vtkTypeUInt64 vtkMatrixTreeLocatorQueryStatistics::Get(int i)
{
#if defined(MATRIXTREE_QUERY_STATS) && MATRIXTREE_QUERY_STATS
  return i >= 0 && i < kNumQueryStats ? gQueryStats[i].load(std::memory_order_relaxed) : 0;
#else
  (void)i;
  return 0;
#endif
}

void vtkMatrixTreeLocatorQueryStatistics::Reset()
{
#if defined(MATRIXTREE_QUERY_STATS) && MATRIXTREE_QUERY_STATS
  for (auto& c : gQueryStats)
  {
    c.store(0, std::memory_order_relaxed);
  }
#endif
}

// What LocatorCore's queries count (locator_core.h, Oracle::count): a header of its own so that
// a counter table (vtkMatrixTreeQueryStatistics) can be indexed by these events without the
// locator's templates.
#pragma once

namespace mtree {
namespace vtk91 {

/// FindCell's queries, leaf scans, references scanned, quantized-box passes, cells evaluated,
/// cells found; the first-hit query's queries, walk steps, node visits, leaves, references,
/// candidates after the leaf filter, cell tests, mailbox repeats, misses proved without a cell
/// test, certain hits, oracle calls, hits. kCount: their number.
enum class LocatorEvent : int {
  kFcQueries,
  kFcLeafScans,
  kFcReferences,
  kFcBoxPasses,
  kFcEvaluations,
  kFcFound,
  kRayQueries,
  kRaySteps,
  kRayNodeVisits,
  kRayLeaves,
  kRayReferences,
  kRayCandidates,
  kRayCellTests,
  kRayMailboxRepeats,
  kRayProvedMisses,
  kRayCertainHits,
  kRayOracleCalls,
  kRayHits,
  kCount
};

}  // namespace vtk91
}  // namespace mtree

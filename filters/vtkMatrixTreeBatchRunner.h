// Private to the MatrixTree::Filters module (not wrapped, not installed): the loop behind
// vtkMatrixTreeLocator's batched queries (FindCells, IntersectSegments, FindClosestPoints).
//
// Each query index i in [0, n) is answered by one worker call, worker(i). Every thread makes
// its own worker with makeWorker() (its vtkGenericCell, its buffers), so the one-point queries
// it calls are the thread-safe overloads; the schedule is dynamic in chunks of `chunk` indices
// (the cost of a point or segment varies by orders of magnitude across a data set). A worker's
// destructor runs on its thread after its last index: where to fold per-thread tallies.
#ifndef vtkMatrixTreeBatchRunner_h
#define vtkMatrixTreeBatchRunner_h

#include "vtkMatrixTreeCellBridge.h"

#include "vtkType.h"

#include <omp.h>

namespace vtkMatrixTreeBatchRunner
{
/** OpenMP threads for a batch: as set, or all (0). */
inline int ThreadCount(int requested)
{
  return requested > 0 ? requested : omp_get_max_threads();
}

template <class MakeWorker>
void Run(vtkDataSet* ds, vtkIdType n, int threads, int chunk, MakeWorker&& makeWorker)
{
  vtkMatrixTreeCellBridge::PrepareForThreads(ds);
#pragma omp parallel num_threads(ThreadCount(threads))
  {
    auto worker = makeWorker();
#pragma omp for schedule(dynamic, chunk)
    for (vtkIdType i = 0; i < n; ++i)
    {
      worker(i);
    }
  }
}
}

#endif

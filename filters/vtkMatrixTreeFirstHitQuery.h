// Private to the MatrixTree::Filters module (not wrapped, not installed): one first-hit ray
// query of vtkMatrixTreeLocator (IntersectWithLine with a vtkGenericCell), VTK's answer found
// with as few VTK calls as the engine can prove enough.
//
// The walk: MatrixTree::traverseRay visits the leaves the segment crosses front to back (paper
// §4.2: neighbour finding from leaf to leaf) and stops after the first leaf whose exit lies
// beyond the best hit so far; a hit in a later leaf cannot be closer.
// Per leaf (tolerance 0): mtree::LeafSegmentFilter keeps the candidates whose quantized box the
// segment crosses, in the order it enters their boxes, and the leaf stops at the first whose
// entry lies beyond the best hit (with a tolerance every candidate is tested, its bounds first).
// Per cell: a direct-mapped mailbox skips cells already tested in an earlier leaf; then
// mtree::decideCell proves most misses from the cell's points (segment_filter.h) and, at
// tolerance 0, finds certain hits of tetrahedra and convex planar-faced cells; a triangle is
// decided by VTK 9.1's arithmetic recomputed (mtree/vtk91/face_hit.h); the rest goes to VTK.
// Certain hits are not handed to VTK one by one: the closest is kept and VTK (or the one face
// test that decides it, vtkMatrixTreeCellBridge::CertainFaceHit) answers for it at the end, for
// VTK's exact t, x and pcoords. Should VTK not confirm it, the query runs again with every cell
// going to VTK, so the answer is VTK's in every case.
#ifndef vtkMatrixTreeFirstHitQuery_h
#define vtkMatrixTreeFirstHitQuery_h

#include "mtree/cells/leaf_segment_filter.h"
#include "mtree/cells/segment_filter.h"

#include "vtkType.h"

#include <optional>
#include <vector>

class vtkDataSet;
class vtkGenericCell;
class vtkMatrixTreeLocatorProcessor;

class vtkMatrixTreeFirstHitQuery
{
public:
  /** The query of segment p1 -> p2 with tolerance tol on the processor's build (Valid). */
  vtkMatrixTreeFirstHitQuery(const vtkMatrixTreeLocatorProcessor& processor, vtkDataSet* ds, const double p1[3],
    const double p2[3], double tol, vtkGenericCell* cell);
  /**
   * 1 and the hit (t, x, pcoords, subId, cellId; the cell filled into the generic cell) as VTK's
   * IntersectWithLine of the hit cell gives it, or 0. x, pcoords and subId may be written on a
   * miss too; t and cellId only on a hit.
   */
  int Run(double& t, double x[3], double pcoords[3], int& subId, vtkIdType& cellId);

private:
  /** One walk of the tree; deferCertain: keep certain hits for the end (the first pass). */
  void Walk(bool deferCertain);
  /** The leaf's candidates (the walk's callback); true stops the walk. */
  bool VisitLeaf(const uint32_t* ids, uint32_t count, double tExit, const int* leaf);
  /** One candidate; boxTest: test the segment against the cell's bounds first. */
  void TestCell(vtkIdType id, bool boxTest);
  /** VTK's answer for the closest certain hit; false when VTK does not confirm it. */
  bool ResolveDeferred();
  /** The hit of cell `id` at tt, where closer than the best so far. */
  void Offer(vtkIdType id, double tt, const double xx[3], const double pc[3], int sid);
  /** The segment's frame, set up at the first cell test (many segments reach no candidate). */
  const mtree::SegmentFrame& Frame();
  /** No hit beyond this t can be the answer. */
  double Bound() const;

  const vtkMatrixTreeLocatorProcessor& P;
  vtkDataSet* DataSet;
  const double* P1;
  const double* P2;
  const double Tol;
  vtkGenericCell* Cell;
  const mtree::Vec3 O, D;
  std::optional<mtree::SegmentFrame> FrameStore;
  const mtree::LeafSegmentFilter LeafFilter;
  vtkIdType Filled = -1; // the cell Cell holds

  // The answer so far, written to the caller's arrays as found.
  double* X = nullptr;
  double* Pcoords = nullptr;
  int* SubId = nullptr;
  double Best = 0;
  vtkIdType BestId = -1;

  // The pass's state.
  bool DeferCertain = false;
  double DeferredT = 0;
  vtkIdType DeferredId = -1;
  int DeferredFace = -1; // the face holding its hit, where certain
  // Cells span several leaves: a small direct-mapped mailbox skips most repeated tests
  // (cleared at the pass's first test).
  vtkIdType Mailbox[64];
  bool MailboxClear = false;
  mtree::LeafSegmentFilter::Candidate StackCandidates[256];
  std::vector<mtree::LeafSegmentFilter::Candidate> HeapCandidates;
};

#endif

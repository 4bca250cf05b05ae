#include "vtkMatrixTreeFirstHitQuery.h"

#include "vtkMatrixTreeCellBridge.h"
#include "vtkMatrixTreeLocatorProcessor.h"
#include "vtkMatrixTreeQueryStatistics.h"

#include "vtkGenericCell.h"

#include <algorithm>
#include <array>

using namespace vtkMatrixTreeQueryStatistics;

vtkMatrixTreeFirstHitQuery::vtkMatrixTreeFirstHitQuery(const vtkMatrixTreeLocatorProcessor& processor,
  vtkDataSet* ds, const double p1[3], const double p2[3], double tol, vtkGenericCell* cell)
  : P(processor)
  , DataSet(ds)
  , P1(p1)
  , P2(p2)
  , Tol(tol)
  , Cell(cell)
  , O(p1)
  , D(mtree::Vec3(p2) - mtree::Vec3(p1))
  , LeafFilter(processor.Tree, processor.LeafBoxes.data(), processor.LeafBoxes.size(), processor.Cells, O, D, tol)
{
}

const mtree::SegmentFrame& vtkMatrixTreeFirstHitQuery::Frame()
{
  if (!this->FrameStore)
  {
    this->FrameStore.emplace(this->O, mtree::Vec3(this->P2), this->Tol, vtkMatrixTreeCellBridge::kVtkQuadSplit);
  }
  return *this->FrameStore;
}

inline double vtkMatrixTreeFirstHitQuery::Bound() const
{
  return std::min({ this->Best, this->DeferredT, 1.0 });
}

int vtkMatrixTreeFirstHitQuery::Run(double& t, double x[3], double pcoords[3], int& subId, vtkIdType& cellId)
{
  CountQuery(kRayQueries);
  this->X = x;
  this->Pcoords = pcoords;
  this->SubId = &subId;
  // The first pass defers certain hits (tolerance 0); the second, run only when VTK does not
  // confirm the deferred hit, hands every cell to VTK.
  for (int pass = 0; pass < 2; ++pass)
  {
    this->Walk(pass == 0 && this->Tol == 0.0);
    if (this->DeferredId < 0 || (this->BestId >= 0 && this->Best <= this->DeferredT) || this->ResolveDeferred())
    {
      break;
    }
  }
  if (this->BestId < 0)
  {
    return 0;
  }
  CountQuery(kRayHits);
  t = this->Best;
  cellId = this->BestId;
  if (this->Filled != this->BestId) // the winner is usually the last cell VTK evaluated: already there
  {
    vtkMatrixTreeCellBridge::FillCell(this->DataSet, this->P.Cells, this->BestId, this->Cell);
  }
  return 1;
}

void vtkMatrixTreeFirstHitQuery::Walk(bool deferCertain)
{
  this->DeferCertain = deferCertain;
  this->DeferredT = VTK_DOUBLE_MAX;
  this->DeferredId = -1;
  this->DeferredFace = -1;
  this->Best = VTK_DOUBLE_MAX;
  this->BestId = -1;
  this->MailboxClear = false;
  mtree::TraversalStats walk;
  this->P.Tree.traverseRay(
    this->O, this->D, 0.0, 1.0,
    [this](const uint32_t* ids, uint32_t count, double, double tExit, const int* leaf) {
      return this->VisitLeaf(ids, count, tExit, leaf);
    },
    kQueryStats ? &walk : nullptr);
  CountQuery(kRaySteps, walk.cells);
  CountQuery(kRayNodeVisits, walk.nodeVisits);
}

inline bool vtkMatrixTreeFirstHitQuery::VisitLeaf(
  const uint32_t* ids, uint32_t count, double tExit, const int* leaf)
{
  const vtkMatrixTreeLocatorProcessor& p = this->P;
  // The leaf's ids (read for the survivors only after its boxes are tested) and its boxes are
  // asked for as soon as the leaf is reached: their misses overlap each other and the box
  // test's set-up.
  mtree::prefetchLines(ids, ids + count);
  const size_t first = static_cast<size_t>(ids - p.Tree.primitiveIndices().data());
  if (6 * (first + count) <= p.LeafBoxes.size())
  {
    const uint8_t* lb = p.LeafBoxes.data() + 6 * first;
    mtree::prefetchLines(lb, lb + 6 * static_cast<size_t>(count));
  }
  CountQuery(kRayLeaves);
  CountQuery(kRayReferences, count);
  mtree::LeafSegmentFilter::Candidate* cand = this->StackCandidates;
  if (count > 256)
  {
    this->HeapCandidates.resize(count);
    cand = this->HeapCandidates.data();
  }
  const int nc = this->LeafFilter.candidates(ids, count, leaf, this->Bound(), cand);
  CountQuery(kRayCandidates, nc < 0 ? count : static_cast<uint64_t>(nc));
  if (nc < 0)
  {
    for (uint32_t k = 0; k < count; ++k)
    {
      this->TestCell(ids[k], true);
    }
  }
  else
  {
    // The survivors are known ahead: their point ids, then their points, are fetched a few
    // candidates early (random reads that otherwise stall each test in turn).
    for (int j = 0; j < std::min(nc, 16); ++j)
    {
      p.Cells.prefetchPointIds(ids[cand[j].k]);
    }
    for (int j = 0; j < nc; ++j)
    {
      if (cand[j].t > this->Bound())
      {
        break; // sorted: the rest enter their boxes in this leaf later still
      }
      if (j + 16 < nc)
      {
        p.Cells.prefetchPointIds(ids[cand[j + 16].k]);
      }
      if (j + 2 < nc)
      {
        p.Cells.prefetchPoints(ids[cand[j + 2].k]);
      }
      this->TestCell(ids[cand[j].k], false);
    }
  }
  return (this->BestId >= 0 || this->DeferredId >= 0) && std::min(this->Best, this->DeferredT) <= tExit;
}

inline void vtkMatrixTreeFirstHitQuery::Offer(
  vtkIdType id, double tt, const double xx[3], const double pc[3], int sid)
{
  if (tt < this->Best)
  {
    this->Best = tt;
    this->BestId = id;
    std::copy(xx, xx + 3, this->X);
    std::copy(pc, pc + 3, this->Pcoords);
    *this->SubId = sid;
  }
}

inline void vtkMatrixTreeFirstHitQuery::TestCell(vtkIdType id, bool boxTest)
{
  const vtkMatrixTreeLocatorProcessor& p = this->P;
  CountQuery(kRayCellTests);
  if (!this->MailboxClear)
  {
    std::fill(this->Mailbox, this->Mailbox + 64, -1);
    this->MailboxClear = true;
  }
  vtkIdType& slot = this->Mailbox[id & 63];
  if (slot == id)
  {
    CountQuery(kRayMailboxRepeats);
    return;
  }
  slot = id;
  const double bound = this->Bound();
  if (boxTest)
  {
    // The segment must meet the cell's bounds (padded by tol) before the cell is read.
    const std::array<float, 6> cb = p.Cells.cellBox(static_cast<size_t>(id));
    const double tol = this->Tol;
    mtree::Box box;
    box.lo = mtree::Vec3(cb[0] - tol, cb[2] - tol, cb[4] - tol);
    box.hi = mtree::Vec3(cb[1] + tol, cb[3] + tol, cb[5] + tol);
    double t0 = 0.0, t1 = bound;
    if (!mtree::rayBox(this->O, this->D, box, t0, t1))
    {
      return;
    }
  }
  // Then the cell's points: most cells whose box the segment crosses are proved missed (or hit
  // only beyond the bound) without VTK.
  double tc;
  int face = -1;
  const mtree::CellVerdict verdict = mtree::decideCell(
    this->Frame(), p.Cells, static_cast<size_t>(id), bound, this->DeferCertain, tc, &face, p.ShapeMemo.get());
  if (verdict == mtree::CellVerdict::kMiss)
  {
    CountQuery(kRayProvedMisses);
    return;
  }
  if (verdict == mtree::CellVerdict::kCertain)
  {
    CountQuery(kRayCertainHits);
    if (tc < this->DeferredT)
    {
      this->DeferredT = tc;
      this->DeferredId = id;
      this->DeferredFace = face;
    }
    return;
  }
  // A triangle at tolerance 0 without VTK, so that the cell is filled only if it wins.
  if (this->Tol == 0.0)
  {
    mtree::vtk91::LineHit h;
    const mtree::vtk91::FaceHit v =
      vtkMatrixTreeCellBridge::RecomputedTriangleHit(p.Cells, id, this->P1, this->P2, h);
    if (v == mtree::vtk91::FaceHit::kMiss)
    {
      return;
    }
    if (v == mtree::vtk91::FaceHit::kHit)
    {
      this->Offer(id, h.t, h.x, h.pcoords, 0);
      return;
    }
  }
  vtkMatrixTreeCellBridge::FillCell(this->DataSet, p.Cells, id, this->Cell);
  this->Filled = id;
  CountQuery(kRayVtkCalls);
  double tt, xx[3], pc[3];
  int sid;
  if (this->Cell->IntersectWithLine(this->P1, this->P2, this->Tol, tt, xx, pc, sid))
  {
    this->Offer(id, tt, xx, pc, sid);
  }
}

bool vtkMatrixTreeFirstHitQuery::ResolveDeferred()
{
  const vtkMatrixTreeLocatorProcessor& p = this->P;
  const vtkIdType id = this->DeferredId;
  vtkMatrixTreeCellBridge::FillCell(this->DataSet, p.Cells, id, this->Cell);
  this->Filled = id;
  CountQuery(kRayVtkCalls);
  // A hexahedron, wedge or tetrahedron whose hit face is known: VTK's test of that face alone
  // gives its answer (a tetrahedron's face is found here, for the winner only).
  if (this->DeferredFace < 0 && this->Tol == 0.0)
  {
    this->DeferredFace = mtree::tetraCertainHitFace(this->Frame(), p.Cells, static_cast<size_t>(id));
  }
  double tt, xx[3], pc[3];
  int sid;
  const bool faceHit = this->DeferredFace >= 0 &&
    vtkMatrixTreeCellBridge::CertainFaceHit(
      p.Cells, id, this->DeferredFace, this->P1, this->P2, this->Tol, tt, xx, pc, sid);
  if (!faceHit && !this->Cell->IntersectWithLine(this->P1, this->P2, this->Tol, tt, xx, pc, sid))
  {
    return false;
  }
  if (this->BestId < 0 || tt < this->Best)
  {
    this->Best = tt;
    this->BestId = id;
    std::copy(xx, xx + 3, this->X);
    std::copy(pc, pc + 3, this->Pcoords);
    *this->SubId = sid;
  }
  return true;
}

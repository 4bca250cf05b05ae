// LocatorCore: the one cell-locator algorithm behind both locators of the project,
// vtkMatrixTreeLocator (filters/, VTK's classes at hand) and mtree::CellLocator (cell_locator.h,
// the VTK-free one the pip extension wraps). It holds one build — the cells, the matrix tree
// (builder.h, paper §5.1), each reference's quantized leaf box (leaf_boxes.h) and the rays'
// per-cell shape memo — and answers every query on it: FindCell (the leaf scan), the first hit
// of a segment (the front-to-back walk of paper §4.2 with the leaf filter and the certain-hit
// proofs of segment_filter.h), all hits, the closest point (best-first search), the cells
// within a box or along a segment, and the batched loops over them.
//
// The two locators differ only in who settles a cell the fast decisions leave open. The fast
// decisions are VTK 9.1's arithmetic with round-off margins (cell_eval.h for points, face_hit.h
// for a triangle or one certain face), answered only where no rounding could change VTK's
// answer; the rest goes to the Oracle:
//   vtkMatrixTreeLocator: VTK's own vtkCell (EvaluatePosition, IntersectWithLine);
//   CellLocator: cell_mirror.h, VTK 9.1's code transcribed, which gives VTK's answer.
// So both return VTK's cells, pcoords, weights, t and hit points, and the same as each other.
//
// Oracle (a class the locator supplies; every member is called with a cell of `cells`):
//   bool fastEvaluation() const      use cell_eval.h's verdict before contains() (a tuning
//                                    switch of the VTK locator; true for the engine)
//   bool mirrorIsVtk() const         face_hit.h's recomputations are the oracle's answers (VTK 9.1)
//   QuadSplit quadSplit() const      how the oracle's vtkQuad splits a face (segment_filter.h)
//   bool contains(c, x, pts, pcoords, weights)
//                                    EvaluatePosition(x, nullptr, ...) == 1, with VTK's pcoords
//                                    and weights; pts: the cell's points when gathered, else null
//   void found(c, pts)               the fast verdict found x in c (the VTK oracle fills its cell)
//   int intersect(c, p1, p2, tol, t, x, pcoords, subId)        IntersectWithLine of cell c
//   int intersectFace(c, face, p1, p2, tol, t, x, pcoords, subId)
//                                    the cell's answer computed from face `face` alone, for a
//                                    segment whose first hit is certain to lie on it; 0 where
//                                    the oracle cannot (the cell is then asked whole)
//   void holding(c)                  c is the answer: the VTK oracle's cell must hold it
//   int closest(c, x, closest, subId, dist2)   EvaluatePosition with a closest point
//   void count(LocatorEvent, n)      query statistics (a no-op unless counted)
//
// Thread safety: queries only read the build (the shape memo's bytes are relaxed atomics), so
// they may run concurrently, each with its own Oracle.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <memory>
#include <optional>
#include <unordered_set>
#include <vector>

#include <omp.h>

#include "mtree/cells/cells.h"
#include "mtree/cells/leaf_boxes.h"
#include "mtree/cells/leaf_segment_filter.h"
#include "mtree/cells/segment_filter.h"
#include "mtree/core/builder.h"
#include "mtree/core/matrix_tree.h"
#include "mtree/core/memory.h"
#include "mtree/core/tree_queries.h"
#include "mtree/rays/raycast.h"
#include "mtree/vtk91/cell_eval.h"
#include "mtree/vtk91/face_hit.h"
#include "mtree/vtk91/locator_events.h"

namespace mtree {
namespace vtk91 {

/// The build's settings (the locators' public settings).
struct LocatorSettings {
  TreeKind kind = TreeKind::Octree;
  /// Levels below the root; 0: chosen from the cells.
  int height = 0;
  /// Block edge of the block-sparse levels (power of two, 1..32).
  int blockEdge = 8;
  /// Separating-axis cell/leaf overlap instead of bounding boxes (the same answers).
  bool exactOverlap = false;
  /// Automatic height: leaf extent in median cell extents and the mean candidate leaves per
  /// cell above which the height steps up; 0 chooses (1 and 16 with a 3-D cell, 4 and 3 for
  /// surfaces).
  double leafScale = 0;
  double maxCandidates = 0;
  /// OpenMP threads of the build (resolved: >= 1).
  int threads = 1;
  BuildSort sort = BuildSort::Counting;
  /// Keep the cells' float bounds after the build (24 bytes per cell; the queries that read
  /// them compute them from the points otherwise).
  bool keepBounds = false;
};

/// A segment's first hit as a query reports it.
struct FirstHitAnswer {
  double t = 0;
  double x[3] = {0, 0, 0};
  double pcoords[3] = {0, 0, 0};
  int subId = 0;
  int64_t cell = -1;
};

/// One hit of all hits.
struct SegmentCellHit {
  double t;
  int64_t cell;
  double x[3];
};

/// The closest point query's answer.
struct ClosestAnswer {
  int64_t cell = -1;
  double point[3] = {0, 0, 0};
  double dist2 = 0;
  int subId = 0;
  int inside = 0;
};

class LocatorCore {
 public:
  /// Builds over `cells` (set first; the core keeps them). Throws what the builder throws (bad
  /// settings, non-finite coordinates, too many references); the core is then not valid.
  void build(const LocatorSettings& s);

  bool valid() const { return valid_; }
  /// Bytes held: the tree, the cells' copy (CellSet::bytes), the quantized leaf boxes and the
  /// shape memo.
  size_t bytes() const {
    return valid_ ? tree.bytes() + cells.bytes() + leafBoxes.size() + (shapeMemo ? cells.size() : 0) : 0;
  }

  // ---- FindCell ----
  /// The first cell of x's leaf, in the leaf's order (ascending ids), that contains x, or -1.
  template <class O>
  int64_t findCell(const double x[3], O& o, double pcoords[3], double* weights) const {
    o.count(LocatorEvent::kFcQueries, 1);
    const NodeRef n = tree.leafHolding(Vec3(x));
    return n.exists ? scanLeaf(x, n, n.range.begin, o, pcoords, weights) : -1;
  }
  /// The point-location loop over the candidates [k, end) of leaf n (leafHolding's for x):
  /// FindCell runs it from the leaf's first candidate, the OpenCL backend from where the device
  /// stopped.
  template <class O>
  int64_t scanLeaf(const double x[3], const NodeRef& n, uint32_t k, O& o, double pcoords[3], double* weights) const;
  /// Whether cell c contains x (the fast verdict, else the oracle's), with VTK's pcoords and
  /// weights when it does.
  template <class O>
  bool cellContains(size_t c, const double x[3], O& o, double pcoords[3], double* weights) const;

  // ---- segments ----
  /// IntersectWithLine's first hit of p1 -> p2 within tol (the smallest t; ties: the first
  /// found in the walk's order, as VTK's locators). False on a miss.
  template <class O>
  bool firstHit(const double p1[3], const double p2[3], double tol, O& o, FirstHitAnswer& a) const;
  /// Every cell the segment hits within tol, once, sorted by t then cell id.
  template <class O>
  void allHits(const double p1[3], const double p2[3], double tol, O& o, std::vector<SegmentCellHit>& hits) const;

  // ---- closest point ----
  /// The cell nearest x within sqrt(radius2) (VTK's EvaluatePosition distance; ties: the
  /// smaller id; degenerate cells, -1, skipped). False if there is none.
  template <class O>
  bool closestPoint(const double x[3], double radius2, O& o, ClosestAnswer& a) const;

  // ---- boxes ----
  /// Every cell whose bounds meet bbox (xmin xmax ymin ymax zmin zmax), ascending.
  void cellsWithinBounds(const double bbox[6], std::vector<int64_t>& out) const;
  /// Every cell whose bounds, grown by tol, the segment crosses, ascending.
  void cellsAlongLine(const double p1[3], const double p2[3], double tol, std::vector<int64_t>& out) const;

  // The build.
  CellSet cells;
  MatrixTree tree;
  BuildStats stats;
  /// Per reference (the order of tree.primitiveIndices()), the cell's quantized box in the leaf.
  LargeVector<uint8_t> leafBoxes;
  struct FreeDeleter {
    void operator()(uint8_t* p) const { std::free(p); }
  };
  /// One ConvexShapeMemo byte per cell where the cells include hexahedra, wedges or pyramids
  /// (else null), written by concurrent ray queries (relaxed atomics).
  std::unique_ptr<uint8_t[], FreeDeleter> shapeMemo;
  Vec3 maxExtent;  // the largest cell bounding-box extent per axis
  double leafScaleUsed = 0, maxCandidatesUsed = 0;
  int maxCellPoints = 0;
  int maxDimension = -1;  // the largest cell dimension (-1: no cells)

 private:
  bool valid_ = false;
};

/// Runs worker(i) for i in [0, n) on `threads` OpenMP threads (dynamic, chunks of `chunk`);
/// every thread makes its own worker with makeWorker() (its oracle and buffers), destroyed on
/// that thread after its last index. One thread below `serialBelow` items.
template <class MakeWorker>
void runBatch(int64_t n, int threads, int chunk, int64_t serialBelow, MakeWorker&& makeWorker) {
  const int t = threads > 0 ? threads : omp_get_max_threads();
#pragma omp parallel num_threads(t) if (n >= serialBelow)
  {
    auto worker = makeWorker();
#pragma omp for schedule(dynamic, chunk)
    for (int64_t i = 0; i < n; ++i) worker(i);
  }
}

// ---- implementation -----------------------------------------------------------------------------

/// Cell c's first np points (3 doubles each) into pts.
inline void gatherCellPoints(const CellSet& cells, size_t c, int64_t np, double* pts) {
  const CellSet::PointIds pid = cells.cellPointIds(c);
  for (int64_t k = 0; k < np; ++k) {
    const Vec3 p = cells.point(pid[k]);
    pts[3 * k] = p.x;
    pts[3 * k + 1] = p.y;
    pts[3 * k + 2] = p.z;
  }
}

template <class O>
MT_ALWAYS_INLINE bool LocatorCore::cellContains(size_t c, const double x[3], O& o, double pcoords[3],
                                                double* weights) const {
  if (o.fastEvaluation()) {
    const uint8_t type = cells.type(c);
    const int64_t np = cells.numCellPoints(c);
    if (cellEvaluable(type, np)) {
      double pts[3 * CellSet::kMaxLocalPoints];
      gatherCellPoints(cells, c, np, pts);
      const PointInCell v = evaluateLinearCell(type, pts, x, pcoords, weights);
      if (v == PointInCell::kOutside) return false;
      if (v == PointInCell::kInside) {
        o.found(c, pts);
        return true;
      }
      return o.contains(c, x, pts, pcoords, weights);
    }
  }
  // A cell of dimension < 3 (a vertex, line or polygon in a 3-D grid, where EvaluatePosition's
  // "inside" only means that x projects into the cell) contains x only within its bounds, as
  // vtkCellLocator decides.
  return o.contains(c, x, nullptr, pcoords, weights) &&
         (cellTypeDimension(cells.type(c)) == 3 || cells.exactBounds(c).contains(Vec3(x)));
}

template <class O>
int64_t LocatorCore::scanLeaf(const double x[3], const NodeRef& n, uint32_t k, O& o, double pcoords[3],
                              double* weights) const {
  const MtLeafRange r = n.range;
  const uint32_t* ids = tree.primitiveIndices().data();
  const uint8_t* boxes = leafBoxes.data();
  // The leaf's boxes and its cell ids are two independent reads (usually cache misses): both
  // start now, so that they overlap each other and the set-up below.
  __builtin_prefetch(boxes + 6 * static_cast<size_t>(k));
  __builtin_prefetch(ids + k);
  uint8_t qmax[3], qmin[3];
  quantizePoint(x, tree.nodeBox(n.level, n.c), qmax, qmin);
  const LeafBoxTest boxTest(qmax, qmin, r.end - k);
  o.count(LocatorEvent::kFcLeafScans, 1);
  o.count(LocatorEvent::kFcReferences, r.end - k);
  // The candidates whose box holds the point are gathered first (in the leaf's order: ascending
  // ids, so the first that contains the point is the answer), up to kChunk references at once;
  // then the point ids of up to kIdsAhead of them are prefetched, then the points of up to
  // kAhead: each level of these random reads overlaps across the candidates.
  constexpr uint32_t kChunk = 128;
  constexpr int kAhead = 16, kIdsAhead = 24;
  uint32_t cand[kChunk];
  const bool fast = o.fastEvaluation();
  while (k < r.end) {
    const uint32_t stop = std::min<uint32_t>(r.end, k + kChunk);
    // Every line of the chunk's boxes and ids (the first of each is on its way already).
    prefetchLines(boxes + 6 * static_cast<size_t>(k) + 64, boxes + 6 * static_cast<size_t>(stop));
    prefetchLines(reinterpret_cast<const char*>(ids + k) + 64, ids + stop);
    const int nc = boxTest.gather(boxes, k, stop, cand);
    o.count(LocatorEvent::kFcBoxPasses, static_cast<uint64_t>(nc));
    for (int j = 0; j < nc; ++j) cand[j] = ids[cand[j]];
    k = stop;
    // With the fast evaluation every candidate's test waits on its reads; without it only
    // tetrahedra (judged by the first candidate) do: there the cheap pre-test waits, while a
    // larger cell's Newton steps in the oracle hide the loads.
    const bool ahead = nc > 1 && (fast || cells.type(cand[0]) == kTetra);
    for (int j = 0, e = ahead ? std::min(nc, kIdsAhead) : 0; j < e; ++j) cells.prefetchPointIds(cand[j]);
    for (int j = 0, e = ahead ? std::min(nc, kAhead) : 0; j < e; ++j) cells.prefetchPoints(cand[j]);
    for (int j = 0; j < nc; ++j) {
      if (ahead && j + kIdsAhead < nc) cells.prefetchPointIds(cand[j + kIdsAhead]);
      if (ahead && j + kAhead < nc) cells.prefetchPoints(cand[j + kAhead]);
      o.count(LocatorEvent::kFcEvaluations, 1);
      if (cellContains(cand[j], x, o, pcoords, weights)) {
        o.count(LocatorEvent::kFcFound, 1);
        return static_cast<int64_t>(cand[j]);
      }
    }
  }
  return -1;
}

/// One first-hit query (firstHit): the walk, VTK's answer found with as few oracle calls as the
/// engine can prove enough.
///
/// MatrixTree::traverseRay visits the leaves the segment crosses front to back (paper §4.2:
/// neighbour finding from leaf to leaf) and stops after the first leaf whose exit lies beyond
/// the best hit so far. Per leaf at tolerance 0: LeafSegmentFilter keeps the candidates whose
/// quantized box the segment crosses, in the order it enters their boxes, and the leaf stops at
/// the first whose entry lies beyond the best hit (with a tolerance every candidate is tested,
/// its bounds first). Per cell: a direct-mapped mailbox skips cells tested in an earlier leaf;
/// decideCell proves most misses from the points and, at tolerance 0, finds certain hits of
/// tetrahedra and convex planar-faced cells; a triangle is decided by face_hit.h where that is
/// the oracle's arithmetic; the rest goes to the oracle. Certain hits are not resolved one by
/// one: the closest is kept and resolved at the end (its certain face alone where known), for
/// the oracle's exact t, x and pcoords. Should the oracle not confirm it, the walk runs again
/// with every cell asked, so the answer is the oracle's in every case.
template <class O>
class FirstHitQuery {
 public:
  FirstHitQuery(const LocatorCore& core, const double p1[3], const double p2[3], double tol, O& oracle)
      : C(core), P1(p1), P2(p2), Tol(tol), Or(oracle), Orig(p1), Dir(Vec3(p2) - Vec3(p1)),
        LeafFilter(core.tree, core.leafBoxes.data(), core.leafBoxes.size(), core.cells, Orig, Dir, tol) {}

  bool run(FirstHitAnswer& a) {
    Or.count(LocatorEvent::kRayQueries, 1);
    Ans = &a;
    // The first pass defers certain hits (tolerance 0); the second, run only when the oracle
    // does not confirm the deferred hit, asks the oracle for every cell.
    for (int pass = 0; pass < 2; ++pass) {
      walk(pass == 0 && Tol == 0.0);
      if (DeferredId < 0 || (BestId >= 0 && Best <= DeferredT) || resolveDeferred()) break;
    }
    if (BestId < 0) return false;
    Or.count(LocatorEvent::kRayHits, 1);
    a.t = Best;
    a.cell = BestId;
    Or.holding(static_cast<size_t>(BestId));
    return true;
  }

 private:
  const SegmentFrame& frame() {
    if (!FrameStore) FrameStore.emplace(Orig, Vec3(P2), Tol, Or.quadSplit());
    return *FrameStore;
  }
  double bound() const { return std::min({Best, DeferredT, 1.0}); }

  void walk(bool deferCertain) {
    DeferCertain = deferCertain;
    DeferredT = kMax;
    DeferredId = -1;
    DeferredFace = -1;
    Best = kMax;
    BestId = -1;
    MailboxClear = false;
    TraversalStats walkStats;
    C.tree.traverseRay(
        Orig, Dir, 0.0, 1.0,
        [this](const uint32_t* ids, uint32_t count, double, double tExit, const int* leaf) {
          return visitLeaf(ids, count, tExit, leaf);
        },
        O::kCounting ? &walkStats : nullptr);
    Or.count(LocatorEvent::kRaySteps, walkStats.cells);
    Or.count(LocatorEvent::kRayNodeVisits, walkStats.nodeVisits);
  }

  bool visitLeaf(const uint32_t* ids, uint32_t count, double tExit, const int* leaf) {
    // The leaf's ids (read for the survivors only after its boxes are tested) and its boxes are
    // asked for as soon as the leaf is reached: their misses overlap each other and the box
    // test's set-up.
    prefetchLines(ids, ids + count);
    const size_t first = static_cast<size_t>(ids - C.tree.primitiveIndices().data());
    if (6 * (first + count) <= C.leafBoxes.size()) {
      const uint8_t* lb = C.leafBoxes.data() + 6 * first;
      prefetchLines(lb, lb + 6 * static_cast<size_t>(count));
    }
    Or.count(LocatorEvent::kRayLeaves, 1);
    Or.count(LocatorEvent::kRayReferences, count);
    LeafSegmentFilter::Candidate* cand = StackCandidates;
    if (count > 256) {
      HeapCandidates.resize(count);
      cand = HeapCandidates.data();
    }
    const int nc = LeafFilter.candidates(ids, count, leaf, bound(), cand);
    Or.count(LocatorEvent::kRayCandidates, nc < 0 ? count : static_cast<uint64_t>(nc));
    if (nc < 0) {
      for (uint32_t k = 0; k < count; ++k) testCell(ids[k], true);
    } else {
      // The survivors are known ahead: their point ids, then their points, are fetched a few
      // candidates early (random reads that otherwise stall each test in turn).
      for (int j = 0; j < std::min(nc, 16); ++j) C.cells.prefetchPointIds(ids[cand[j].k]);
      for (int j = 0; j < nc; ++j) {
        if (cand[j].t > bound()) break;  // sorted: the rest enter their boxes in this leaf later still
        if (j + 16 < nc) C.cells.prefetchPointIds(ids[cand[j + 16].k]);
        if (j + 2 < nc) C.cells.prefetchPoints(ids[cand[j + 2].k]);
        testCell(ids[cand[j].k], false);
      }
    }
    return (BestId >= 0 || DeferredId >= 0) && std::min(Best, DeferredT) <= tExit;
  }

  void offer(int64_t id, double tt, const double xx[3], const double pc[3], int sid) {
    if (tt < Best) {
      Best = tt;
      BestId = id;
      std::copy(xx, xx + 3, Ans->x);
      std::copy(pc, pc + 3, Ans->pcoords);
      Ans->subId = sid;
    }
  }

  void testCell(uint32_t id, bool boxTest) {
    Or.count(LocatorEvent::kRayCellTests, 1);
    if (!MailboxClear) {
      std::fill(Mailbox, Mailbox + 64, ~uint32_t{0});
      MailboxClear = true;
    }
    uint32_t& slot = Mailbox[id & 63];
    if (slot == id) {
      Or.count(LocatorEvent::kRayMailboxRepeats, 1);
      return;
    }
    slot = id;
    const double b = bound();
    if (boxTest) {
      // The segment must meet the cell's bounds (padded by tol) before the cell is read.
      const std::array<float, 6> cb = C.cells.cellBox(id);
      Box box;
      box.lo = Vec3(cb[0] - Tol, cb[2] - Tol, cb[4] - Tol);
      box.hi = Vec3(cb[1] + Tol, cb[3] + Tol, cb[5] + Tol);
      double t0 = 0.0, t1 = b;
      if (!rayBox(Orig, Dir, box, t0, t1)) return;
    }
    // Then the cell's points: most cells whose box the segment crosses are proved missed (or
    // hit only beyond the bound) without the oracle.
    double tc;
    int face = -1;
    const CellVerdict verdict = decideCell(frame(), C.cells, id, b, DeferCertain, tc, &face, C.shapeMemo.get());
    if (verdict == CellVerdict::kMiss) {
      Or.count(LocatorEvent::kRayProvedMisses, 1);
      return;
    }
    if (verdict == CellVerdict::kCertain) {
      Or.count(LocatorEvent::kRayCertainHits, 1);
      if (tc < DeferredT) {
        DeferredT = tc;
        DeferredId = id;
        DeferredFace = face;
      }
      return;
    }
    // A triangle at tolerance 0 by VTK 9.1's arithmetic, where that is the oracle's.
    if (Tol == 0.0 && Or.mirrorIsVtk() && C.cells.type(id) == kTriangle && C.cells.numCellPoints(id) == 3) {
      double q[9];
      gatherCellPoints(C.cells, id, 3, q);
      LineHit h;
      const FaceHit v = triangleLineHit(q, q + 3, q + 6, P1, P2, h);
      if (v == FaceHit::kMiss) return;
      if (v == FaceHit::kHit) {
        offer(id, h.t, h.x, h.pcoords, 0);
        return;
      }
    }
    Or.count(LocatorEvent::kRayOracleCalls, 1);
    double tt, xx[3], pc[3];
    int sid;
    if (Or.intersect(id, P1, P2, Tol, tt, xx, pc, sid)) offer(id, tt, xx, pc, sid);
  }

  bool resolveDeferred() {
    const int64_t id = DeferredId;
    Or.count(LocatorEvent::kRayOracleCalls, 1);
    // A cell whose hit face is known: that face alone gives the cell's answer (a tetrahedron's
    // face is found here, for the winner only).
    if (DeferredFace < 0 && Tol == 0.0) DeferredFace = tetraCertainHitFace(frame(), C.cells, static_cast<size_t>(id));
    double tt, xx[3], pc[3];
    int sid;
    const bool faceHit = DeferredFace >= 0 && Or.intersectFace(id, DeferredFace, P1, P2, Tol, tt, xx, pc, sid);
    if (!faceHit && !Or.intersect(id, P1, P2, Tol, tt, xx, pc, sid)) return false;
    if (BestId < 0 || tt < Best) {
      Best = tt;
      BestId = id;
      std::copy(xx, xx + 3, Ans->x);
      std::copy(pc, pc + 3, Ans->pcoords);
      Ans->subId = sid;
    }
    return true;
  }

  static constexpr double kMax = 1.0e+299;  // VTK_DOUBLE_MAX
  const LocatorCore& C;
  const double* P1;
  const double* P2;
  const double Tol;
  O& Or;
  const Vec3 Orig, Dir;
  std::optional<SegmentFrame> FrameStore;
  const LeafSegmentFilter LeafFilter;
  FirstHitAnswer* Ans = nullptr;
  double Best = 0;
  int64_t BestId = -1;
  bool DeferCertain = false;
  double DeferredT = 0;
  int64_t DeferredId = -1;
  int DeferredFace = -1;  // the face holding its hit, where certain
  // Cells span several leaves: a small direct-mapped mailbox skips most repeated tests
  // (cleared at the pass's first test).
  uint32_t Mailbox[64];
  bool MailboxClear = false;
  LeafSegmentFilter::Candidate StackCandidates[256];
  std::vector<LeafSegmentFilter::Candidate> HeapCandidates;
};

template <class O>
bool LocatorCore::firstHit(const double p1[3], const double p2[3], double tol, O& o, FirstHitAnswer& a) const {
  FirstHitQuery<O> q(*this, p1, p2, tol, o);
  return q.run(a);
}

template <class O>
void LocatorCore::allHits(const double p1[3], const double p2[3], double tol, O& o,
                          std::vector<SegmentCellHit>& hits) const {
  hits.clear();
  std::unordered_set<uint32_t> seen;
  const Vec3 orig(p1), d = Vec3(p2) - Vec3(p1);
  const SegmentFrame frame(orig, Vec3(p2), tol, o.quadSplit());
  tree.traverseRay(
      orig, d, 0.0, 1.0,
      [&](const uint32_t* ids, uint32_t count, double, double) {
        for (uint32_t k = 0; k < count; ++k) {
          const uint32_t id = ids[k];
          if (!seen.insert(id).second || !segmentMayHitCell(frame, cells, id, 1.0)) continue;
          SegmentCellHit h;
          h.cell = id;
          double pc[3];
          int sid;
          if (o.intersect(id, p1, p2, tol, h.t, h.x, pc, sid)) hits.push_back(h);
        }
        return false;
      },
      nullptr);
  std::sort(hits.begin(), hits.end(),
            [](const SegmentCellHit& a, const SegmentCellHit& b) { return a.t < b.t || (a.t == b.t && a.cell < b.cell); });
}

template <class O>
bool LocatorCore::closestPoint(const double x[3], double radius2, O& o, ClosestAnswer& a) const {
  // The distance from x to cell bounds given as 6 floats (xmin xmax ymin ymax zmin zmax).
  auto boundsDistance2 = [x](const std::array<float, 6>& b) {
    double d2 = 0;
    for (int k = 0; k < 3; ++k) {
      const double dk = std::max({b[2 * k] - x[k], 0.0, x[k] - b[2 * k + 1]});
      d2 += dk * dk;
    }
    return d2;
  };
  int64_t bestId = -1;
  closestPrimitiveSearch(
      tree, x, radius2, [&](uint32_t id, double bound2) { return !(boundsDistance2(cells.cellBox(id)) > bound2); },
      [&](uint32_t id32, double bound2) {
        const int64_t id = id32;
        double cp[3], d2;
        int sid;
        const int ret = o.closest(id32, x, cp, sid, d2);
        if (ret == -1) return bound2;  // a degenerate cell
        // EvaluatePosition's dist2 and closest point are VTK's for every cell dimension. Equal
        // distances: the lowest cell id.
        if (d2 < bound2 || (d2 == bound2 && bestId >= 0 && id < bestId) || (bestId < 0 && d2 <= bound2)) {
          bestId = id;
          a.dist2 = d2;
          std::copy(cp, cp + 3, a.point);
          a.subId = sid;
          a.inside = ret == 1 ? 1 : 0;
          return d2;
        }
        return bound2;
      });
  a.cell = bestId;
  if (bestId >= 0) o.holding(static_cast<size_t>(bestId));
  return bestId >= 0;
}

}  // namespace vtk91
}  // namespace mtree

#include "mtree/vtk91/cell_locator.h"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <queue>
#include <stdexcept>
#include <string>
#include <unordered_set>

#include "mtree/cells/leaf_boxes.h"
#include "mtree/cells/segment_filter.h"
#include "mtree/core/builder.h"
#include "mtree/core/parallel.h"
#include "mtree/core/tree_nodes.h"
#include "mtree/rays/raycast.h"

namespace mtree {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
const double kNaN = std::numeric_limits<double>::quiet_NaN();

/// The cell's conservative bounds (CellSet::bounds) grown by tol on every side.
Box paddedBounds(const CellSet& cells, size_t c, double tol) {
  Box b = cells.bounds(c);
  b.lo = b.lo - Vec3(tol, tol, tol);
  b.hi = b.hi + Vec3(tol, tol, tol);
  return b;
}

/// Whether the segment p1 + t d, t in [0, tMax], crosses the box.
bool segmentCrossesBox(Vec3 p1, Vec3 d, const Box& b, double tMax) {
  double t0 = 0, t1 = tMax;
  return rayBox(p1, d, b, t0, t1);
}

/// Cell c's points (3 doubles each) into pts (grown as needed); returns their number.
int gatherPoints(const CellSet& cells, size_t c, std::vector<double>& pts) {
  const int n = static_cast<int>(cells.numCellPoints(c));
  if (pts.size() < size_t(3 * n)) pts.resize(size_t(3 * n));
  const CellSet::PointIds id = cells.cellPointIds(c);
  for (int k = 0; k < n; ++k) {
    const Vec3 p = cells.point(id[k]);
    pts[3 * k] = p.x;
    pts[3 * k + 1] = p.y;
    pts[3 * k + 2] = p.z;
  }
  return n;
}

/// Where cell c first meets the segment p1 + t d (frame), if at t <= tMax: its padded bounds
/// must be crossed; then segment_filter.h's decideCell proves most misses from the points (the
/// hull of the points, grown by 2 tol and 1e-3 of the cell's extent, holds every point a hit of
/// cell_geometry.h can report, except on a warped polygon's plane: polygons skip it) and, at
/// tol 0, gives the crossing of tetrahedra and planar-faced convex cells where it is certain
/// (away from edges and vertices); the rest go to intersectCellSegment.
bool cellHit(const CellSet& cells, size_t c, const SegmentFrame& frame, Vec3 p2, double tol, double tMax,
             std::vector<double>& pts, double& t, Vec3& x) {
  if (!segmentCrossesBox(frame.p1, frame.d, paddedBounds(cells, c, tol), tMax)) return false;
  const uint8_t type = cells.type(c);
  if (type != kPolygon) {
    double tc;
    const CellVerdict v = decideCell(frame, cells, c, tMax, tol == 0, tc);
    if (v == CellVerdict::kMiss) return false;
    if (v == CellVerdict::kCertain) {
      t = tc;
      x = frame.p1 + frame.d * tc;
      return true;
    }
  }
  const int n = gatherPoints(cells, c, pts);
  return intersectCellSegment(type, pts.data(), n, frame.p1, p2, tol, t, x);
}

}  // namespace

/// Runs f(i, scratch) for i in [0, n) on OpenMP threads (one scratch each), in chunks of `chunk`,
/// on one thread below `serial` items.
template <class F>
void CellLocator::forEachQuery(size_t n, int threads, int chunk, int64_t serial, F&& f) const {
  const int64_t m = static_cast<int64_t>(n);
#pragma omp parallel num_threads(resolveThreads(threads)) if (m > serial)
  {
    Scratch s;
#pragma omp for schedule(dynamic, chunk)
    for (int64_t i = 0; i < m; ++i) f(i, s);
  }
}

void CellLocator::build(CellSet cells, const CellLocatorOptions& o) {
  *this = CellLocator{};
  const size_t nc = cells.size();
  int maxPts = 0, maxDim = -1;
  for (size_t c = 0; c < nc; ++c) {
    const uint8_t t = cells.type(c);
    const int64_t np = cells.numCellPoints(c);
    if (!cellTypeSupported(t, np))
      throw std::invalid_argument("cell " + std::to_string(c) + " is a " + cellTypeName(t) + " with " +
                                  std::to_string(np) +
                                  " points: the engine's cell locator takes VTK's linear cell types (vertex to "
                                  "pyramid, polygons and strips included), not quadratic, higher-order or "
                                  "polyhedral cells");
    maxPts = std::max<int>(maxPts, static_cast<int>(np));
    maxDim = std::max(maxDim, cellDimension(t));
  }
  BuildOptions opt;
  opt.kind = o.kind;
  opt.height = o.height;
  opt.blockEdge = o.blockEdge;
  opt.overlap = o.exactOverlap ? OverlapMode::Exact : OverlapMode::BoundingBox;
  opt.sort = BuildSort::Counting;
  opt.threads = o.threads > 0 ? o.threads
                              : static_cast<int>(std::min<size_t>(omp_get_max_threads(), std::max<size_t>(1, nc / 1024)));
  // The automatic height of vtkMatrixTreeLocator: surfaces (no 3-D cell) get leaves about four
  // median cell extents wide, volume meshes one (see its LeafScale).
  const bool surface = maxDim < 3;
  opt.leafScale = o.leafScale > 0 ? std::max(o.leafScale, 1e-3) : (surface ? 4.0 : 1.0);
  opt.maxCandidates = o.maxCandidates > 0 ? std::max(o.maxCandidates, 1.0) : (surface ? 3.0 : 16.0);
  cells.setAxes(CellAxes::Faces);
  MatrixTreeBuilder<CellSet>::build<6>(cells, opt, tree_, &stats_, &leafBoxes_, LeafBoxQuantizer());
  // The cells' float bounds stay cached (24 bytes per cell): every ray and closest-point
  // candidate reads them before its points.
  tree_.releaseBuildScratch();
  cells_ = std::move(cells);
  maxCellPoints_ = maxPts;
  maxDim_ = maxDim;
  leafScale_ = opt.leafScale;
  maxCandidates_ = opt.maxCandidates;
}

int CellLocator::gather(size_t c, Scratch& s) const {
  const int n = gatherPoints(cells_, c, s.pts);
  if (s.weights.size() < size_t(std::max(n, maxCellPoints_))) s.weights.resize(size_t(std::max(n, maxCellPoints_)));
  return n;
}

int64_t CellLocator::findCellIn(const double x[3], double tol2, double pcoords[3], double* weights,
                                Scratch& s) const {
  const NodeRef n = tree_.leafHolding(Vec3(x));
  if (!n.exists) return -1;
  // x in the leaf's quantized frame (quantizeLeafBox's arithmetic, monotone): a reference whose
  // box [lo, hi] does not hold it (lo > floor(q) or hi < ceil(q) on an axis) cannot contain x.
  const Box lb = tree_.nodeBox(n.level, n.c);
  int qf[3], qc[3];
  for (int a = 0; a < 3; ++a) {
    const double q = std::min(255.0, std::max(0.0, (x[a] - lb.lo[a]) * detail::leafBoxScale(lb.lo[a], lb.hi[a])));
    qf[a] = static_cast<int>(q);
    qc[a] = qf[a] + (qf[a] < q ? 1 : 0);
  }
  const uint32_t* ids = tree_.primitiveIndices().data();
  for (uint32_t k = n.range.begin; k < n.range.end; ++k) {
    const uint8_t* b = &leafBoxes_[6 * size_t(k)];
    if (b[0] > qf[0] || b[1] < qc[0] || b[2] > qf[1] || b[3] < qc[1] || b[4] > qf[2] || b[5] < qc[2]) continue;
    const size_t c = ids[k];
    const uint8_t type = cells_.type(c);
    const int np = gather(c, s);
    const CellPoint r = evaluateCellPoint(type, s.pts.data(), np, x, s.weights.data(), false);
    if (r.status != 1 || (cellDimension(type) < 3 && !(r.dist2 <= tol2))) continue;
    if (pcoords) std::copy(r.pcoords, r.pcoords + 3, pcoords);
    if (weights) {
      std::copy(s.weights.data(), s.weights.data() + np, weights);
      std::fill(weights + np, weights + maxCellPoints_, 0.0);
    }
    return static_cast<int64_t>(c);
  }
  return -1;
}

int64_t CellLocator::findCell(const double x[3], double tol2, double pcoords[3], double* weights) const {
  Scratch s;
  return findCellIn(x, tol2, pcoords, weights, s);
}

void CellLocator::findCells(const double* x, size_t n, double tol2, int64_t* ids, double* pcoords, double* weights,
                            int threads) const {
  const int64_t w = maxCellPoints_;
  forEachQuery(n, threads, 512, 256, [&](int64_t i, Scratch& s) {
    double pc[3];
    double* wi = weights ? weights + i * w : nullptr;
    ids[i] = findCellIn(x + 3 * i, tol2, pc, wi, s);
    if (ids[i] < 0) {
      pc[0] = pc[1] = pc[2] = 0;
      if (wi) std::fill(wi, wi + w, 0.0);
    }
    if (pcoords) std::copy(pc, pc + 3, pcoords + 3 * i);
  });
}

bool CellLocator::firstHitIn(Vec3 p1, Vec3 p2, double tol, SegmentHit& hit, Scratch& s) const {
  hit = SegmentHit{};
  hit.t = kInf;
  const Vec3 d = p2 - p1;
  if (!isFinite(p1) || !isFinite(p2) || !(tol >= 0) || (d.x == 0 && d.y == 0 && d.z == 0)) return false;
  RayMailbox tested;
  const SegmentFrame frame(p1, p2, tol);
  tree_.traverseRay(
      p1, d, 0.0, 1.0,
      [&](const uint32_t* prims, uint32_t count, double, double tExit) {
        for (uint32_t k = 0; k < count; ++k) {
          const uint32_t c = prims[k];
          double t;
          Vec3 x;
          if (tested.seen(c) || !cellHit(cells_, c, frame, p2, tol, std::min(hit.t, 1.0), s.pts, t, x)) continue;
          if (t < hit.t || (t == hit.t && int64_t(c) < hit.cell)) {
            hit.t = t;
            hit.cell = c;
            hit.x = x;
          }
        }
        // A hit inside this leaf (t <= its exit) cannot be beaten by a later leaf.
        return hit.cell >= 0 && hit.t <= tExit;
      },
      nullptr);
  return hit.cell >= 0;
}

bool CellLocator::firstHit(Vec3 p1, Vec3 p2, double tol, SegmentHit& hit) const {
  Scratch s;
  return firstHitIn(p1, p2, tol, hit, s);
}

void CellLocator::firstHits(const double* p1, const double* p2, size_t n, double tol, double* t, int64_t* ids,
                            double* x, int threads) const {
  forEachQuery(n, threads, 128, 64, [&](int64_t i, Scratch& s) {
    SegmentHit h;
    const bool found = firstHitIn(Vec3(p1 + 3 * i), Vec3(p2 + 3 * i), tol, h, s);
    t[i] = found ? h.t : kInf;
    ids[i] = found ? h.cell : -1;
    if (x)
      for (int a = 0; a < 3; ++a) x[3 * i + a] = found ? h.x[a] : kNaN;
  });
}

void CellLocator::allHits(Vec3 p1, Vec3 p2, double tol, std::vector<SegmentHit>& hits) const {
  hits.clear();
  const Vec3 d = p2 - p1;
  if (!isFinite(p1) || !isFinite(p2) || !(tol >= 0) || (d.x == 0 && d.y == 0 && d.z == 0)) return;
  Scratch s;
  std::unordered_set<uint32_t> seen;
  const SegmentFrame frame(p1, p2, tol);
  tree_.traverseRay(
      p1, d, 0.0, 1.0,
      [&](const uint32_t* prims, uint32_t count, double, double) {
        for (uint32_t k = 0; k < count; ++k) {
          const uint32_t c = prims[k];
          SegmentHit h;
          h.cell = c;
          if (seen.insert(c).second && cellHit(cells_, c, frame, p2, tol, 1.0, s.pts, h.t, h.x)) hits.push_back(h);
        }
        return false;
      },
      nullptr);
  std::sort(hits.begin(), hits.end(),
            [](const SegmentHit& a, const SegmentHit& b) { return a.t < b.t || (a.t == b.t && a.cell < b.cell); });
}

int64_t CellLocator::closestIn(const double x[3], double radius, Vec3& closest, double& dist2, Scratch& s) const {
  dist2 = kInf;
  closest = Vec3(kNaN, kNaN, kNaN);
  const Vec3 xv(x);
  if (tree_.empty() || !isFinite(xv) || !(radius >= 0)) return -1;
  // Best-first over the existing nodes, nearest box first: a node farther than the best
  // distance so far holds no nearer cell.
  struct Entry {
    double d2;
    int level;
    int c[3];
    bool operator<(const Entry& o) const { return d2 > o.d2; }
  };
  std::priority_queue<Entry> queue;
  double best = std::isinf(radius) ? kInf : radius * radius;
  int64_t bestId = -1;
  const int root[3] = {0, 0, 0};
  if (tree_.nodeExists(0, root)) queue.push(Entry{boxDistance2(xv, tree_.nodeBox(0, root)), 0, {0, 0, 0}});
  std::unordered_set<uint32_t> tested;
  const int H = tree_.height();
  while (!queue.empty()) {
    const Entry e = queue.top();
    queue.pop();
    if (e.d2 > best) break;
    if (e.level < H) {
      forEachChild(tree_, e.level, e.c, [&](const int cc[3]) {
        const double cd2 = boxDistance2(xv, tree_.nodeBox(e.level + 1, cc));
        if (cd2 <= best) queue.push(Entry{cd2, e.level + 1, {cc[0], cc[1], cc[2]}});
      });
      continue;
    }
    const MtLeafRange r = tree_.leafLevel().get(e.c[0], e.c[1], e.c[2]);
    for (uint32_t k = r.begin; k < r.end; ++k) {
      const uint32_t c = tree_.primitiveIndices()[k];
      if (boxDistance2(xv, cells_.bounds(c)) > best || !tested.insert(c).second) continue;
      const int np = gather(c, s);
      const CellPoint p = evaluateCellPoint(cells_.type(c), s.pts.data(), np, x, s.weights.data(), true);
      if (p.dist2 < best || (p.dist2 == best && (bestId < 0 || int64_t(c) < bestId))) {
        best = p.dist2;
        bestId = c;
        closest = p.closest;
      }
    }
  }
  if (bestId >= 0) dist2 = best;
  return bestId;
}

int64_t CellLocator::closestPoint(const double x[3], double radius, Vec3& closest, double& dist2) const {
  Scratch s;
  return closestIn(x, radius, closest, dist2, s);
}

void CellLocator::closestPoints(const double* x, size_t n, double radius, double* closest, int64_t* ids,
                                double* dist2, int threads) const {
  forEachQuery(n, threads, 128, 64, [&](int64_t i, Scratch& s) {
    Vec3 c;
    double d2;
    ids[i] = closestIn(x + 3 * i, radius, c, d2, s);
    for (int a = 0; a < 3; ++a) closest[3 * i + a] = c[a];
    if (dist2) dist2[i] = d2;
  });
}

void CellLocator::cellsWithinBounds(const Box& box, std::vector<int64_t>& out) const {
  out.clear();
  if (tree_.empty() || box.empty()) return;
  // A cell is referenced only by the leaves it overlaps, which may not meet the box even when
  // its bounds do: gather from the box grown by the largest cell extent, then test the bounds.
  const Vec3 grow = cells_.maxExtent();
  Box q;
  q.lo = box.lo - grow;
  q.hi = box.hi + grow;
  struct Node {
    int level;
    int c[3];
  };
  std::vector<Node> stack;
  const int root[3] = {0, 0, 0};
  if (tree_.nodeExists(0, root) && tree_.nodeBox(0, root).overlaps(q)) stack.push_back(Node{0, {0, 0, 0}});
  std::vector<uint32_t> found;
  while (!stack.empty()) {
    const Node nd = stack.back();
    stack.pop_back();
    if (nd.level == tree_.height()) {
      const MtLeafRange r = tree_.leafLevel().get(nd.c[0], nd.c[1], nd.c[2]);
      found.insert(found.end(), tree_.primitiveIndices().begin() + r.begin, tree_.primitiveIndices().begin() + r.end);
      continue;
    }
    forEachChild(tree_, nd.level, nd.c, [&](const int cc[3]) {
      if (tree_.nodeBox(nd.level + 1, cc).overlaps(q)) stack.push_back(Node{nd.level + 1, {cc[0], cc[1], cc[2]}});
    });
  }
  std::sort(found.begin(), found.end());
  found.erase(std::unique(found.begin(), found.end()), found.end());
  for (uint32_t c : found)
    if (cells_.exactBounds(c).overlaps(box)) out.push_back(c);
}

void CellLocator::cellsAlongSegment(Vec3 p1, Vec3 p2, double tol, std::vector<int64_t>& out) const {
  out.clear();
  const Vec3 d = p2 - p1;
  if (!isFinite(p1) || !isFinite(p2) || !(tol >= 0)) return;
  std::vector<uint32_t> found;
  tree_.traverseRay(
      p1, d, 0.0, 1.0,
      [&](const uint32_t* prims, uint32_t count, double, double) {
        found.insert(found.end(), prims, prims + count);
        return false;
      },
      nullptr);
  std::sort(found.begin(), found.end());
  found.erase(std::unique(found.begin(), found.end()), found.end());
  for (uint32_t c : found) {
    Box b = cells_.exactBounds(c);
    b.lo = b.lo - Vec3(tol, tol, tol);
    b.hi = b.hi + Vec3(tol, tol, tol);
    if (segmentCrossesBox(p1, d, b, 1.0)) out.push_back(c);
  }
}

}  // namespace mtree

#include "mtree/vtk91/locator_core.h"

#include <chrono>

namespace mtree {
namespace vtk91 {

void LocatorCore::build(const LocatorSettings& s) {
  valid_ = false;
  shapeMemo.reset();
  const size_t nc = cells.size();
  // One pass over the types (one when all cells share it): the largest dimension, and whether
  // the rays' shape memo serves any cell.
  int maxDim = -1;
  bool convex = false, anyEvaluable = false;
  int maxPts = 0;
  const size_t scan = cells.uniformType() ? std::min<size_t>(nc, 1) : nc;
  for (size_t c = 0; c < scan; ++c) {
    const uint8_t t = cells.type(c);
    maxDim = std::max(maxDim, cellTypeDimension(t));
    convex = convex || t == kHexahedron || t == kWedge || t == kPyramid;
    anyEvaluable = anyEvaluable || cellEvaluable(t, cells.numCellPoints(c));
  }
  if (cells.uniformCellSize()) {
    maxPts = nc > 0 ? static_cast<int>(cells.numCellPoints(0)) : 0;
  } else {
    for (size_t c = 0; c < nc; ++c) maxPts = std::max<int>(maxPts, static_cast<int>(cells.numCellPoints(c)));
  }
  BuildOptions opt;
  opt.kind = s.kind;
  opt.height = s.height;
  opt.blockEdge = s.blockEdge;
  opt.overlap = s.exactOverlap ? OverlapMode::Exact : OverlapMode::BoundingBox;
  opt.sort = s.sort;
  opt.threads = s.threads;
  // The automatic height: leaves about one median cell wide where any cell is 3-D (point
  // location tests every candidate of one leaf), about four on a surface (1.8-2.3 references
  // per triangle instead of 6-10; docs/bench_locators.md, "Surfaces"). Where no cell has
  // cell_eval.h's fast verdict (quadratic and higher-order cells: every candidate whose box
  // holds the point costs VTK's Newton iteration), at most 4 candidate leaves per cell: the
  // quantized leaf boxes keep the Newton calls per point as they are, while the shallower tree
  // holds a fraction of the references (docs/bench_locators.md, "Generated grids").
  const bool surface = maxDim < 3;
  opt.leafScale = s.leafScale > 0 ? std::max(s.leafScale, 1e-3) : (surface ? 4.0 : 1.0);
  opt.maxCandidates = s.maxCandidates > 0 ? std::max(s.maxCandidates, 1.0)
                                          : (surface ? 3.0 : anyEvaluable ? 16.0 : 4.0);
  leafScaleUsed = opt.leafScale;
  maxCandidatesUsed = opt.maxCandidates;
  // The quantized leaf boxes are the builder's per-reference data: written at the scatter
  // (Counting) or by a pass over the leaves (Radix), the same bytes either way.
  MatrixTreeBuilder<CellSet>::build<6>(cells, opt, tree, &stats, &leafBoxes, LeafBoxQuantizer());
  // The cell bounds serve the build (read several times per cell there); unless kept, the
  // queries that need a few compute them from the points: 24 bytes per cell not held. The
  // builder's work arrays, which the tree keeps for a next build, go too.
  const auto t0 = std::chrono::steady_clock::now();
  if (!s.keepBounds) cells.releaseBounds();
  tree.releaseBuildScratch();
  stats.phasesMs.emplace_back("release",
                              std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  // calloc: zero pages from the system for a large grid, touched only where rays go.
  if (convex) shapeMemo.reset(static_cast<uint8_t*>(std::calloc(nc, 1)));
  maxExtent = cells.maxExtent();
  maxCellPoints = maxPts;
  maxDimension = maxDim;
  valid_ = true;
}

void LocatorCore::cellsWithinBounds(const double bbox[6], std::vector<int64_t>& out) const {
  out.clear();
  if (!valid_ || tree.empty()) return;
  // Every cell whose bounds meet the box. A cell is only in the leaves it overlaps, so the
  // candidates come from the leaves of the box widened by the largest cell extent (a cell whose
  // bounds meet the box overlaps that), then the cells' bounds decide.
  Box q;
  q.lo = Vec3(bbox[0] - maxExtent.x, bbox[2] - maxExtent.y, bbox[4] - maxExtent.z);
  q.hi = Vec3(bbox[1] + maxExtent.x, bbox[3] + maxExtent.y, bbox[5] + maxExtent.z);
  Box query;
  query.lo = Vec3(bbox[0], bbox[2], bbox[4]);
  query.hi = Vec3(bbox[1], bbox[3], bbox[5]);
  for (const uint32_t id : primitivesInLeavesOverlapping(tree, q)) {
    // The float bounds contain the exact ones: a miss is final, a hit is checked exactly.
    const std::array<float, 6> b = cells.cellBox(id);
    if (b[0] <= bbox[1] && b[1] >= bbox[0] && b[2] <= bbox[3] && b[3] >= bbox[2] && b[4] <= bbox[5] &&
        b[5] >= bbox[4] && cells.exactBounds(id).overlaps(query))
      out.push_back(id);
  }
}

void LocatorCore::cellsAlongLine(const double p1[3], const double p2[3], double tol, std::vector<int64_t>& out) const {
  out.clear();
  const Vec3 a(p1), b(p2), d = b - a;
  if (!valid_ || tree.empty() || !isFinite(a) || !isFinite(b) || !(tol >= 0)) return;
  std::vector<uint32_t> found;
  tree.traverseRay(
      a, d, 0.0, 1.0,
      [&](const uint32_t* ids, uint32_t count, double, double) {
        found.insert(found.end(), ids, ids + count);
        return false;
      },
      nullptr);
  std::sort(found.begin(), found.end());
  found.erase(std::unique(found.begin(), found.end()), found.end());
  for (uint32_t c : found) {
    Box box = cells.exactBounds(c);
    box.lo = box.lo - Vec3(tol, tol, tol);
    box.hi = box.hi + Vec3(tol, tol, tol);
    double t0 = 0, t1 = 1.0;
    if (rayBox(a, d, box, t0, t1)) out.push_back(c);
  }
}

}  // namespace vtk91
}  // namespace mtree

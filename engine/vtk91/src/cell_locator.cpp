#include "mtree/vtk91/cell_locator.h"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "mtree/core/parallel.h"
#include "mtree/vtk91/cell_faces.h"
#include "mtree/vtk91/cell_mirror.h"

namespace mtree {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
const double kNaN = std::numeric_limits<double>::quiet_NaN();

/// The oracle of locator_core.h without VTK: every cell the fast decisions leave open is
/// settled by VTK 9.1's code transcribed (cell_mirror.h), which gives VTK's answer. One per
/// thread: it holds the gathered cell.
class MirrorOracle {
 public:
  static constexpr bool kCounting = false;
  explicit MirrorOracle(const CellSet& cells) : cells_(cells) {}

  bool fastEvaluation() const { return true; }
  bool mirrorIsVtk() const { return true; }
  QuadSplit quadSplit() const { return vtk91::quadSplitOfVtk(9, 1); }
  void count(vtk91::LocatorEvent, uint64_t) const {}
  void found(size_t, const double*) const {}
  void holding(size_t) const {}

  bool contains(size_t c, const double x[3], const double* pts, double pcoords[3], double* weights) {
    vtk91::MirrorCell mc = load(c, pts);
    int subId;
    double dist2;
    return vtk91::evaluatePosition(mc, x, nullptr, subId, pcoords, dist2, weights) == 1;
  }
  int intersect(size_t c, const double p1[3], const double p2[3], double tol, double& t, double x[3],
                double pcoords[3], int& subId) {
    return vtk91::intersectWithLine(load(c, nullptr), p1, p2, tol, t, x, pcoords, subId);
  }
  int intersectFace(size_t c, int face, const double p1[3], const double p2[3], double tol, double& t, double x[3],
                    double pcoords[3], int& subId) {
    const uint8_t type = cells_.type(c);
    if (type != kTetra && type != kHexahedron && type != kWedge && type != kPyramid) return 0;
    return vtk91::intersectFace(load(c, nullptr), face, p1, p2, tol, t, x, pcoords, subId);
  }
  int closest(size_t c, const double x[3], double cp[3], int& subId, double& dist2) {
    vtk91::MirrorCell mc = load(c, nullptr);
    if (weights_.size() < size_t(mc.n)) weights_.resize(size_t(mc.n));
    double pcoords[3];
    return vtk91::evaluatePosition(mc, x, cp, subId, pcoords, dist2, weights_.data());
  }

 private:
  /// Cell c as the transcription takes it: its points (pts when the caller has gathered them)
  /// and point ids.
  vtk91::MirrorCell load(size_t c, const double* pts) {
    const int n = static_cast<int>(cells_.numCellPoints(c));
    if (ids_.size() < size_t(n)) ids_.resize(size_t(n)), pts_.resize(3 * size_t(n));
    const CellSet::PointIds pid = cells_.cellPointIds(c);
    for (int k = 0; k < n; ++k) ids_[size_t(k)] = pid[k];
    if (!pts) {
      vtk91::gatherCellPoints(cells_, c, n, pts_.data());
      pts = pts_.data();
    }
    vtk91::MirrorCell mc;
    mc.type = cells_.type(c);
    mc.n = n;
    mc.pts = pts;
    mc.ids = ids_.data();
    return mc;
  }

  const CellSet& cells_;
  std::vector<double> pts_, weights_;
  std::vector<int64_t> ids_;
};

}  // namespace

void CellLocator::build(CellSet cells, const CellLocatorOptions& o) {
  core_ = vtk91::LocatorCore{};
  const size_t nc = cells.size();
  for (size_t c = 0; c < nc; ++c) {
    const uint8_t t = cells.type(c);
    const int64_t np = cells.numCellPoints(c);
    if (!vtk91::mirrorCovers(t, np))
      throw std::invalid_argument("cell " + std::to_string(c) + " is a " + cellTypeName(t) + " with " +
                                  std::to_string(np) +
                                  " points: the engine's cell locator takes the cell types whose VTK 9.1 "
                                  "evaluation it repeats (every linear type, vertex to pyramid, polygons and "
                                  "strips included; the quadratic tetrahedron, hexahedron, wedge and pyramid and "
                                  "the triquadratic hexahedron), not the other quadratic, Lagrange, Bezier or "
                                  "polyhedral cells");
  }
  vtk91::LocatorSettings s = o;
  if (s.threads <= 0)
    s.threads = static_cast<int>(std::min<size_t>(omp_get_max_threads(), std::max<size_t>(1, nc / 1024)));
  core_.cells = std::move(cells);
  core_.build(s);
}

int64_t CellLocator::findCell(const double x[3], double, double pcoords[3], double* weights) const {
  MirrorOracle o(core_.cells);
  std::vector<double> w(std::max(core_.maxCellPoints, 1));
  double pc[3];
  const int64_t id = core_.valid() ? core_.findCell(x, o, pc, w.data()) : -1;
  if (id >= 0) {
    if (pcoords) std::copy(pc, pc + 3, pcoords);
    if (weights) {
      const int np = static_cast<int>(core_.cells.numCellPoints(static_cast<size_t>(id)));
      std::copy(w.data(), w.data() + np, weights);
      std::fill(weights + np, weights + core_.maxCellPoints, 0.0);
    }
  }
  return id;
}

void CellLocator::findCells(const double* x, size_t n, double, int64_t* ids, double* pcoords, double* weights,
                            int threads) const {
  const int64_t wn = core_.maxCellPoints;
  vtk91::runBatch(static_cast<int64_t>(n), threads, 512, 256, [&]() {
    return [&, o = MirrorOracle(core_.cells), w = std::vector<double>(std::max<int64_t>(wn, 1))](int64_t i) mutable {
      double pc[3] = {0, 0, 0};
      const double* xi = x + 3 * i;
      const int64_t id = core_.valid() ? core_.findCell(xi, o, pc, w.data()) : -1;
      ids[i] = id;
      if (id < 0) pc[0] = pc[1] = pc[2] = 0;
      if (pcoords) std::copy(pc, pc + 3, pcoords + 3 * i);
      if (weights) {
        double* wi = weights + i * wn;
        const int64_t keep = id < 0 ? 0 : core_.cells.numCellPoints(static_cast<size_t>(id));
        std::copy(w.data(), w.data() + keep, wi);
        std::fill(wi + keep, wi + wn, 0.0);
      }
    };
  });
}

bool CellLocator::firstHit(Vec3 p1, Vec3 p2, double tol, SegmentHit& hit) const {
  hit = SegmentHit{};
  hit.t = kInf;
  if (!core_.valid() || !isFinite(p1) || !isFinite(p2)) return false;
  MirrorOracle o(core_.cells);
  const double a[3] = {p1.x, p1.y, p1.z}, b[3] = {p2.x, p2.y, p2.z};
  vtk91::FirstHitAnswer ans;
  if (!core_.firstHit(a, b, tol, o, ans)) return false;
  hit.t = ans.t;
  hit.cell = ans.cell;
  hit.x = Vec3(ans.x);
  return true;
}

void CellLocator::firstHits(const double* p1, const double* p2, size_t n, double tol, double* t, int64_t* ids,
                            double* x, int threads) const {
  vtk91::runBatch(static_cast<int64_t>(n), threads, 128, 64, [&]() {
    return [&](int64_t i) {
      SegmentHit h;
      const bool found = firstHit(Vec3(p1 + 3 * i), Vec3(p2 + 3 * i), tol, h);
      t[i] = found ? h.t : kInf;
      ids[i] = found ? h.cell : -1;
      if (x)
        for (int a = 0; a < 3; ++a) x[3 * i + a] = found ? h.x[a] : kNaN;
    };
  });
}

void CellLocator::allHits(Vec3 p1, Vec3 p2, double tol, std::vector<SegmentHit>& hits) const {
  hits.clear();
  if (!core_.valid() || !isFinite(p1) || !isFinite(p2)) return;
  MirrorOracle o(core_.cells);
  const double a[3] = {p1.x, p1.y, p1.z}, b[3] = {p2.x, p2.y, p2.z};
  std::vector<vtk91::SegmentCellHit> all;
  core_.allHits(a, b, tol, o, all);
  for (const vtk91::SegmentCellHit& h : all) {
    SegmentHit s;
    s.t = h.t;
    s.cell = h.cell;
    s.x = Vec3(h.x);
    hits.push_back(s);
  }
}

int64_t CellLocator::closestPoint(const double x[3], double radius, Vec3& closest, double& dist2) const {
  dist2 = kInf;
  closest = Vec3(kNaN, kNaN, kNaN);
  if (!core_.valid() || core_.tree.empty() || !isFinite(Vec3(x)) || !(radius >= 0)) return -1;
  MirrorOracle o(core_.cells);
  vtk91::ClosestAnswer a;
  if (!core_.closestPoint(x, std::isinf(radius) ? kInf : radius * radius, o, a)) return -1;
  closest = Vec3(a.point);
  dist2 = a.dist2;
  return a.cell;
}

void CellLocator::closestPoints(const double* x, size_t n, double radius, double* closest, int64_t* ids,
                                double* dist2, int threads) const {
  vtk91::runBatch(static_cast<int64_t>(n), threads, 128, 64, [&]() {
    return [&](int64_t i) {
      Vec3 c;
      double d2;
      ids[i] = closestPoint(x + 3 * i, radius, c, d2);
      for (int a = 0; a < 3; ++a) closest[3 * i + a] = c[a];
      if (dist2) dist2[i] = d2;
    };
  });
}

void CellLocator::cellsWithinBounds(const Box& box, std::vector<int64_t>& out) const {
  out.clear();
  if (box.empty()) return;
  const double b[6] = {box.lo.x, box.hi.x, box.lo.y, box.hi.y, box.lo.z, box.hi.z};
  core_.cellsWithinBounds(b, out);
}

void CellLocator::cellsAlongSegment(Vec3 p1, Vec3 p2, double tol, std::vector<int64_t>& out) const {
  const double a[3] = {p1.x, p1.y, p1.z}, b[3] = {p2.x, p2.y, p2.z};
  core_.cellsAlongLine(a, b, tol, out);
}

}  // namespace mtree

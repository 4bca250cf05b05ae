// SAH build of a restricted BSP tree over convex polytope cells. See bsp_builder.h.
#include "mtree/trees/bsp_builder.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "mtree/trees/implicit_tree.h"
#include "plane_sweep.h"
#include "polytope.h"

namespace mtree {

using detail::boxPoly;
using detail::clipPoly;
using detail::clipPolygon;
using detail::kMaxPolyVerts;
using detail::Poly;
using detail::surfaceArea;
using detail::vectorArea2;

namespace {

/// A cell's faces prepared for many areaBelow() calls: each face's area, and the axis of its
/// normal's largest component with 1 / that component of the unit normal (the face's area is its
/// shadow on the other two axes' plane times that factor).
struct FaceData {
  std::vector<double> area, scale;
  std::vector<int> axis;
  double total = 0;
};

FaceData faceData(const Poly& p) {
  FaceData fd;
  for (size_t f = 0; f < p.faces(); ++f) {
    const Vec3 n = vectorArea2(&p.v[p.start[f]], static_cast<int>(p.start[f + 1] - p.start[f]));
    const double len = norm(n);
    int a = 0;
    for (int k = 1; k < 3; ++k)
      if (std::fabs(n[k]) > std::fabs(n[a])) a = k;
    fd.area.push_back(0.5 * len);
    fd.axis.push_back(a);
    fd.scale.push_back(n[a] != 0 ? len / std::fabs(n[a]) : 0.0);
    fd.total += 0.5 * len;
  }
  return fd;
}

/// One direction's view of a cell: every vertex's projection, each face's projection range.
struct Projections {
  std::vector<double> x, lo, hi;
};

void projectCell(const Poly& p, const SplitFrame& f, int k, Projections& pr) {
  pr.x.resize(p.v.size());
  pr.lo.resize(p.faces());
  pr.hi.resize(p.faces());
  for (size_t i = 0; i < p.v.size(); ++i) pr.x[i] = f.project(k, p.v[i]);
  for (size_t fc = 0; fc < p.faces(); ++fc) {
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (uint32_t i = p.start[fc]; i < p.start[fc + 1]; ++i) {
      lo = std::min(lo, pr.x[i]);
      hi = std::max(hi, pr.x[i]);
    }
    pr.lo[fc] = lo;
    pr.hi[fc] = hi;
  }
}

/// Area of the part of p with projection <= w (faces only) and of the cut (the cap). Faces
/// wholly on one side count whole or not at all; a face the plane cuts is clipped, its area the
/// shoelace of its shadow on its FaceData plane.
double areaBelow(const Poly& p, const FaceData& fd, const Projections& pr, double w, double& cap) {
  Vec3 capSum(0, 0, 0), ref(0, 0, 0);
  bool haveRef = false;
  double below = 0;
  for (size_t f = 0; f < p.faces(); ++f) {
    if (pr.hi[f] <= w) {
      below += fd.area[f];
      continue;
    }
    if (pr.lo[f] > w) continue;
    const int ax = fd.axis[f], u = ax == 0 ? 1 : 0, v = ax == 2 ? 1 : 2;
    const uint32_t b = p.start[f], n = p.start[f + 1] - b;
    double shoe = 0, fu = 0, fv = 0, pu = 0, pv = 0;
    int m = 0;
    auto emit = [&](const Vec3& q) {
      if (m == 0) {
        fu = q[u];
        fv = q[v];
      } else {
        shoe += pu * q[v] - q[u] * pv;
      }
      pu = q[u];
      pv = q[v];
      ++m;
    };
    Vec3 leave, enter;
    for (uint32_t i = 0; i < n; ++i) {
      const uint32_t j = i + 1 == n ? 0 : i + 1;
      const double dp = pr.x[b + i] - w, dq = pr.x[b + j] - w;
      const bool pin = dp <= 0, qin = dq <= 0;
      if (pin) emit(p.v[b + i]);
      if (pin != qin) {
        const double t = std::min(1.0, std::max(0.0, dp / (dp - dq)));
        const Vec3 X = p.v[b + i] + (p.v[b + j] - p.v[b + i]) * t;
        emit(X);
        (pin ? leave : enter) = X;
      }
    }
    if (m >= 3) below += 0.5 * std::fabs(shoe + pu * fv - fu * pv) * fd.scale[f];
    if (!haveRef) {
      ref = leave;
      haveRef = true;
    }
    capSum = capSum + cross(enter - ref, leave - ref);  // the cap's edge enter -> leave
  }
  cap = 0.5 * norm(capSum);
  return below;
}

struct Candidate {
  int dir = -1;
  float s = 0;
  double w = 0;
  uint32_t nl = 0, nr = 0;
  double cost = std::numeric_limits<double>::infinity();
};

/// A node's triangles and, per triangle and direction, the padded projection interval of the
/// triangle's part in the cell (lo then hi, 2 D doubles a triangle).
struct TriList {
  std::vector<uint32_t> ids;
  std::vector<double> bounds;
  size_t size() const { return ids.size(); }
  void clear() {
    ids.clear();
    ids.shrink_to_fit();
    bounds.clear();
    bounds.shrink_to_fit();
  }
};

/// A plane on the path from the root: the cell lies where side (dot(normal[dir], x) - w) <= 0.
struct PathPlane {
  int dir;
  double w, side;
};

class BspBuilder {
 public:
  BspBuilder(const TriangleMesh& mesh, const BspBuildOptions& opt, PointerSplitTree& out, BspBuildStats& st)
      : mesh_(mesh), opt_(opt), out_(out), st_(st), f_(out.frame), D_(out.frame.count) {}

  TriList rootList() const {
    TriList l;
    l.ids.resize(mesh_.size());
    l.bounds.resize(mesh_.size() * 2 * D_);
    for (size_t t = 0; t < mesh_.size(); ++t) {
      l.ids[t] = static_cast<uint32_t>(t);
      const Vec3 v[3] = {mesh_.vertex(t, 0), mesh_.vertex(t, 1), mesh_.vertex(t, 2)};
      setBounds(v, 3, &l.bounds[t * 2 * D_]);
    }
    return l;
  }

  void build(uint32_t idx, const Poly& cell, TriList& tris, int depth) {
    const double area = surfaceArea(cell);
    const uint32_t n = static_cast<uint32_t>(tris.size());
    Candidate best;
    if (n > 1 && depth < st_.maxDepth && area > 0) best = findSplit(cell, tris, area);
    if (best.dir < 0 || !(best.cost < opt_.costIntersect * n)) {
      makeLeaf(idx, tris, depth, area);
      return;
    }
    const uint32_t c = static_cast<uint32_t>(out_.nodes.size());
    out_.nodes.resize(c + 2);
    PointerSplitTree::Node& nd = out_.nodes[idx];
    nd.leaf = false;
    nd.dir = static_cast<uint8_t>(best.dir);
    nd.s = best.s;
    nd.child = c;
    (best.dir < 3 ? st_.axisSplits : st_.diagonalSplits) += 1;
    sahSum_ += opt_.costTraverse * area;
    const Vec3 nrm = f_.normal[best.dir];
    for (int side = 0; side < 2; ++side) {
      path_.push_back(PathPlane{best.dir, best.w, side == 0 ? 1.0 : -1.0});
      TriList child = split(tris, best, side);
      if (side == 1) tris.clear();
      const Poly sub = clipPoly(cell, nrm, best.w, side == 0 ? 1.0 : -1.0);
      build(c + side, sub, child, depth + 1);
      path_.pop_back();
    }
  }

  double sahSum() const { return sahSum_; }

 private:
  /// The padded projection intervals of polygon v[0..n) on every direction.
  void setBounds(const Vec3* v, int n, double* b) const {
    for (int k = 0; k < D_; ++k) {
      double lo = std::numeric_limits<double>::infinity(), hi = -lo;
      for (int i = 0; i < n; ++i) {
        const double x = f_.project(k, v[i]);
        lo = std::min(lo, x);
        hi = std::max(hi, x);
      }
      b[2 * k] = lo - f_.pad(k);
      b[2 * k + 1] = hi + f_.pad(k);
    }
  }

  /// The triangles of one side of the split (left: those not starting above w; right: those not
  /// ending below it). A triangle on both sides is clipped to the child's cell (every plane of
  /// the path, each moved outwards by the pad) for its new intervals, and left out of the child
  /// when nothing of it remains ("perfect splits", Wald & Havran §4.3, for polytope cells).
  TriList split(const TriList& tris, const Candidate& best, int side) const {
    TriList out;
    const int k = best.dir;
    Vec3 a[kMaxPolyVerts], b[kMaxPolyVerts];
    for (size_t i = 0; i < tris.size(); ++i) {
      const double* bd = &tris.bounds[i * 2 * D_];
      const bool left = !(bd[2 * k] > best.w), right = !(bd[2 * k + 1] < best.w);
      if (!(side == 0 ? left : right)) continue;
      const uint32_t t = tris.ids[i];
      if (left && right) {
        int n = 3;
        a[0] = mesh_.vertex(t, 0);
        a[1] = mesh_.vertex(t, 1);
        a[2] = mesh_.vertex(t, 2);
        for (const PathPlane& pl : path_) {
          Vec3 leave, enter;
          bool crossed;
          n = clipPolygon(a, n, f_.normal[pl.dir], pl.w + pl.side * f_.pad(pl.dir), pl.side, b, leave, enter,
                          crossed);
          std::copy(b, b + n, a);
          if (n == 0) break;
        }
        if (n == 0) continue;
        out.ids.push_back(t);
        const size_t at = out.bounds.size();
        out.bounds.resize(at + 2 * D_);
        setBounds(a, n, &out.bounds[at]);
        // Never wider than before: the clipped part lies in the triangle.
        for (int j = 0; j < D_; ++j) {
          out.bounds[at + 2 * j] = std::max(out.bounds[at + 2 * j], bd[2 * j]);
          out.bounds[at + 2 * j + 1] = std::min(out.bounds[at + 2 * j + 1], bd[2 * j + 1]);
        }
      } else {
        out.ids.push_back(t);
        out.bounds.insert(out.bounds.end(), bd, bd + 2 * D_);
      }
    }
    return out;
  }

  Candidate findSplit(const Poly& cell, const TriList& tris, double area) {
    Candidate best;
    const double invArea = 1.0 / area;
    const int B = opt_.bins;
    const size_t n = tris.size();
    std::vector<double> xs;
    const FaceData fd = faceData(cell);
    Projections pr;
    for (int k = 0; k < D_; ++k) {
      projectCell(cell, f_, k, pr);
      double clo = std::numeric_limits<double>::infinity(), chi = -clo;
      for (size_t fc = 0; fc < cell.faces(); ++fc) {
        clo = std::min(clo, pr.lo[fc]);
        chi = std::max(chi, pr.hi[fc]);
      }
      double tlo = std::numeric_limits<double>::infinity(), thi = -tlo;
      for (size_t i = 0; i < n; ++i) {
        tlo = std::min(tlo, tris.bounds[i * 2 * D_ + 2 * k]);
        thi = std::max(thi, tris.bounds[i * 2 * D_ + 2 * k + 1]);
      }
      const double a = std::max(clo, tlo), b = std::min(chi, thi);
      if (!(a < b)) continue;
      auto interval = [&](size_t i, double& lo, double& hi) {
        lo = tris.bounds[i * 2 * D_ + 2 * k];
        hi = tris.bounds[i * 2 * D_ + 2 * k + 1];
      };
      const int even = detail::candidatePositions(n, B, a, b, interval, xs);
      sweep_.run(f_, k, xs, clo, chi, n, interval, even, a, b);
      for (size_t j = 0; j < sweep_.w.size(); ++j) {
        const uint32_t nl = sweep_.nl[j], nr = sweep_.nr[j];
        double cap;
        const double below = areaBelow(cell, fd, pr, sweep_.w[j], cap);
        const double al = below + cap, ar = area - below + cap;
        double cst = opt_.costTraverse + opt_.costIntersect * (al * nl + ar * nr) * invArea;
        if (nl == 0 || nr == 0) cst *= opt_.emptyBonus;
        if (cst < best.cost) {
          best.cost = cst;
          best.dir = k;
          best.s = sweep_.s[j];
          best.w = sweep_.w[j];
          best.nl = nl;
          best.nr = nr;
        }
      }
    }
    return best;
  }

  void makeLeaf(uint32_t idx, TriList& tris, int depth, double area) {
    std::vector<uint32_t>& ids = tris.ids;
    std::sort(ids.begin(), ids.end());
    PointerSplitTree::Node& nd = out_.nodes[idx];
    nd.leaf = true;
    nd.offset = static_cast<uint32_t>(out_.prims.size());
    nd.count = static_cast<uint32_t>(ids.size());
    out_.prims.insert(out_.prims.end(), ids.begin(), ids.end());
    ++st_.leaves;
    st_.emptyLeaves += ids.empty();
    st_.references += ids.size();
    st_.depth = std::max(st_.depth, depth);
    sahSum_ += opt_.costIntersect * double(ids.size()) * area;
  }

  const TriangleMesh& mesh_;
  const BspBuildOptions& opt_;
  PointerSplitTree& out_;
  BspBuildStats& st_;
  const SplitFrame& f_;
  const int D_;
  std::vector<PathPlane> path_;
  detail::PlaneSweep sweep_;
  double sahSum_ = 0;
};

}  // namespace

PointerSplitTree buildBspTree(const TriangleMesh& mesh, const BspBuildOptions& opt, BspBuildStats* stats) {
  const auto t0 = std::chrono::steady_clock::now();
  if (opt.directions != 3 && opt.directions != 13)
    throw std::invalid_argument("buildBspTree: directions must be 3 or 13");
  if (opt.bins < 2 || opt.bins > 256) throw std::invalid_argument("buildBspTree: bins must be in [2, 256]");
  if (!(opt.costTraverse >= 0) || !(opt.costIntersect > 0) || !(opt.emptyBonus > 0))
    throw std::invalid_argument("buildBspTree: costs must be positive");
  BspBuildStats st;
  PointerSplitTree out;
  if (mesh.size() > 0) {
    out.frame = SplitFrame::kdop13(mesh);
    if (opt.directions == 3) {
      out.frame.count = 3;
      out.frame.tagBits = 2;
    }
    for (size_t t = 0; t < mesh.size(); ++t) out.root.extend(mesh.bounds(t));
    const double logN = std::log2(static_cast<double>(mesh.size()));
    const int cap = ImplicitSplitTree::kMaxLevel;
    st.maxDepth = opt.maxDepth > 0 ? std::min(opt.maxDepth, cap)
                                   : std::min(cap, static_cast<int>(std::lround(8 + 1.3 * logN)));
    out.nodes.resize(1);
    BspBuilder b(mesh, opt, out, st);
    TriList all = b.rootList();
    const Poly root = boxPoly(out.root);
    const double rootArea = surfaceArea(root);
    b.build(0, root, all, 0);
    st.sahCost = rootArea > 0 ? b.sahSum() / rootArea : opt.costIntersect * double(mesh.size());
    st.nodes = out.nodes.size();
  }
  st.buildMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  if (stats) *stats = st;
  return out;
}

}  // namespace mtree

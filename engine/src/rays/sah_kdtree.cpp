// SAH kd-tree build (Wald & Havran 2006, O(N log N) with perfect splits). See sah_kdtree.h.
#include "mtree/rays/sah_kdtree.h"

#include <algorithm>
#include <array>
#include <cfloat>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>

namespace mtree {

const char* sahTraversalName(SahTraversal t) {
  switch (t) {
    case SahTraversal::Restart:
      return "restart";
    case SahTraversal::Stack:
      return "stack";
    case SahTraversal::ShortStack:
      return "shortstack";
  }
  return "?";
}

namespace {

constexpr float kFloatInf = std::numeric_limits<float>::infinity();

// ---- events ---------------------------------------------------------------------------------
// Types ordered as the sweep needs them at one position: end < planar < start.
constexpr uint32_t kEnd = 0, kPlanar = 1, kStart = 2;

struct Event {
  float pos;
  uint32_t key;  // type << 30 | triangle: sorting by (pos, key) sorts by (pos, type, triangle)
  uint32_t tri() const { return key & SahKdTree::kMaxIndex; }
  uint32_t type() const { return key >> 30; }
};
static_assert(sizeof(Event) == 8, "events are 8 bytes");
inline bool operator<(const Event& a, const Event& b) {
  return a.pos < b.pos || (a.pos == b.pos && a.key < b.key);
}
inline Event makeEvent(float pos, uint32_t type, uint32_t tri) { return Event{pos, (type << 30) | tri}; }

using EventLists = std::array<std::vector<Event>, 3>;

/// A box in the tree's float plane coordinates.
struct FBox {
  float lo[3], hi[3];
};

inline double halfArea(const FBox& b) {
  const double ex = double(b.hi[0]) - b.lo[0], ey = double(b.hi[1]) - b.lo[1], ez = double(b.hi[2]) - b.lo[2];
  return ex * ey + ey * ez + ez * ex;
}

// ---- the float frame of the planes ------------------------------------------------------------
// Plane coordinates are floats on a grid of kGrid = 2^-24 in [-0.5, 1): world(a, s) = anchor[a] +
// s * scale, with scale a power of two >= 4 x the scene's extent (scene coordinates map into
// [0, 0.25]) and anchor a multiple of kGrid * scale. Every grid float is a float, and world() of it
// is exact (an integer multiple of kGrid * scale, below 2^53 of them: scale is also kept >= 2^-28 of
// the largest coordinate), so world() is strictly increasing on the grid and the build can compare
// grid positions in place of world coordinates. Resolution: kGrid * scale, 2^-22 to 2^-21 of the
// scene's extent.
constexpr float kGrid = 0x1p-24f;

struct Frame {
  double anchor[3] = {0, 0, 0};
  double scale = 1, step = kGrid;  // step = kGrid * scale: one grid step in world units
  double world(int a, float s) const { return anchor[a] + static_cast<double>(s) * scale; }
  float grid(double k) const {  // k * kGrid, k clamped to the grid's range
    return static_cast<float>(std::min(std::max(k, -0x1p23), 0x1p24 - 1) * double(kGrid));
  }
  /// The largest grid float s with world(a, s) <= x (x within the scene, give or take a little).
  float down(int a, double x) const {
    float f = grid(std::floor((x - anchor[a]) / step));
    while (world(a, f) > x && f > -0.5f) f -= kGrid;
    for (int i = 0; i < 4 && world(a, f + kGrid) <= x; ++i) f += kGrid;
    return f;
  }
  /// The smallest grid float s with world(a, s) >= x.
  float up(int a, double x) const {
    float f = grid(std::ceil((x - anchor[a]) / step));
    while (world(a, f) < x && f < 1.0f - kGrid) f += kGrid;
    for (int i = 0; i < 4 && world(a, f - kGrid) >= x; ++i) f -= kGrid;
    return f;
  }
};

enum Side : uint8_t { kBoth = 0, kLeftOnly = 1, kRightOnly = 2 };

struct Split {
  int axis = -1;
  float pos = 0;
  uint32_t nl = 0, nr = 0;  // triangles of the children (straddling ones in both)
  double cost = std::numeric_limits<double>::infinity();
};

class Builder {
 public:
  Builder(const TriangleMesh& mesh, const SahBuildOptions& opt, const Frame& frame, double pad,
          std::vector<SahKdNode>& nodes, std::vector<uint32_t>& prims, SahBuildStats& stats)
      : mesh_(mesh), opt_(opt), frame_(frame), pad_(pad), nodes_(nodes), prims_(prims), stats_(stats),
        side_(mesh.size(), kBoth), triBox_(mesh.size()) {}

  /// Float bounds of every triangle (rounded outward); returns their union.
  FBox triangleBoxes() {
    FBox root;
    for (int a = 0; a < 3; ++a) {
      root.lo[a] = kFloatInf;
      root.hi[a] = -kFloatInf;
    }
    for (size_t t = 0; t < mesh_.size(); ++t) {
      const Box b = mesh_.bounds(t);
      FBox& fb = triBox_[t];
      for (int a = 0; a < 3; ++a) {
        fb.lo[a] = frame_.down(a, b.lo[a]);
        fb.hi[a] = frame_.up(a, b.hi[a]);
        root.lo[a] = std::min(root.lo[a], fb.lo[a]);
        root.hi[a] = std::max(root.hi[a], fb.hi[a]);
      }
    }
    return root;
  }

  void rootEvents(EventLists& ev) const {
    for (int a = 0; a < 3; ++a) {
      ev[a].clear();
      ev[a].reserve(2 * mesh_.size());
    }
    for (size_t t = 0; t < mesh_.size(); ++t) addEvents(triBox_[t], static_cast<uint32_t>(t), ev);
    for (int a = 0; a < 3; ++a) std::sort(ev[a].begin(), ev[a].end());
  }

  /// Builds node `idx` over box `box` holding `n` triangles whose events are `ev` (consumed).
  void build(uint32_t idx, const FBox& box, EventLists& ev, uint32_t n, int depth) {
    const double area = halfArea(box);
    Split best;
    if (n > 1 && depth < stats_.maxDepth && area > 0) best = findSplit(box, ev, n, area);
    if (best.axis < 0 || !(best.cost < opt_.costIntersect * n)) {
      makeLeaf(idx, ev, n, depth, area);
      return;
    }
    const int k = best.axis;
    const float p = best.pos;
    FBox lbox = box, rbox = box;
    lbox.hi[k] = p;
    rbox.lo[k] = p;

    // Classify (Wald & Havran §4.4, but closed): left only if the triangle ends before p, right
    // only if it starts after p, both otherwise, including triangles that touch the plane or lie
    // in it. So every leaf whose closed box holds a point of a triangle references the triangle
    // (the planes one grid step off the events give the paper's one-sided touching triangles).
    for (const Event& e : ev[k])
      if (e.type() != kEnd) side_[e.tri()] = kBoth;
    for (const Event& e : ev[k]) {
      const uint32_t type = e.type();
      if (type != kStart && e.pos < p) side_[e.tri()] = kLeftOnly;  // hi < p
      if (type != kEnd && e.pos > p) side_[e.tri()] = kRightOnly;   // lo > p
    }
    both_.clear();
    for (const Event& e : ev[k])
      if (e.type() != kEnd && side_[e.tri()] == kBoth) both_.push_back(e.tri());

    // Split the sorted lists in order; straddling triangles are clipped to each child box
    // ("perfect splits"), and only their new events are sorted and merged in.
    EventLists left, right;
    for (int a = 0; a < 3; ++a) {
      // At most 2 events per triangle of the child.
      left[a].reserve(2 * size_t(best.nl));
      right[a].reserve(2 * size_t(best.nr));
      for (const Event& e : ev[a]) {
        const uint8_t s = side_[e.tri()];
        if (s == kLeftOnly)
          left[a].push_back(e);
        else if (s == kRightOnly)
          right[a].push_back(e);
      }
    }
    for (int a = 0; a < 3; ++a) {
      ev[a].clear();
      ev[a].shrink_to_fit();
    }
    if (!both_.empty()) {
      std::array<size_t, 3> lmid, rmid;
      for (int a = 0; a < 3; ++a) {
        lmid[a] = left[a].size();
        rmid[a] = right[a].size();
      }
      for (uint32_t t : both_) {
        addEvents(clipped(t, lbox), t, left);
        addEvents(clipped(t, rbox), t, right);
      }
      for (int a = 0; a < 3; ++a) {
        mergeTail(left[a], lmid[a]);
        mergeTail(right[a], rmid[a]);
      }
    }

    const size_t c = nodes_.size();
    if (c + 2 > SahKdTree::kMaxIndex)
      throw std::length_error("SahKdTree: more than 2^30 nodes");
    nodes_.resize(c + 2);
    nodes_[idx] = SahKdNode::inner(k, p, static_cast<uint32_t>(c));
    sahSum_ += opt_.costTraverse * area;
    const uint32_t nl = best.nl, nr = best.nr;
    build(static_cast<uint32_t>(c), lbox, left, nl, depth + 1);
    build(static_cast<uint32_t>(c + 1), rbox, right, nr, depth + 1);
  }

  double sahSum() const { return sahSum_; }

 private:
  /// Sorts v[mid..] and merges it with the sorted v[..mid] (through a reused buffer).
  void mergeTail(std::vector<Event>& v, size_t mid) {
    std::sort(v.begin() + mid, v.end());
    if (mid == 0 || mid == v.size() || !(v[mid] < v[mid - 1])) return;
    merged_.resize(v.size());
    std::merge(v.begin(), v.begin() + mid, v.begin() + mid, v.end(), merged_.begin());
    std::copy(merged_.begin(), merged_.end(), v.begin());
  }

  static void addEvents(const FBox& b, uint32_t t, EventLists& ev) {
    for (int a = 0; a < 3; ++a) {
      if (b.lo[a] == b.hi[a]) {
        ev[a].push_back(makeEvent(b.lo[a], kPlanar, t));
      } else {
        ev[a].push_back(makeEvent(b.lo[a], kStart, t));
        ev[a].push_back(makeEvent(b.hi[a], kEnd, t));
      }
    }
  }

  /// SAH sweep over the three sorted lists (Wald & Havran Algorithm 4, closed classification).
  /// Candidates on each axis: every event position x (triangles touching x go to both sides), and
  /// one grid step off each side of it, between two event positions: there the triangles that end
  /// at x are left only and those that start at the next position right only, as the paper's
  /// touching triangles, and an empty side can cut off empty space.
  Split findSplit(const FBox& box, const EventLists& ev, uint32_t n, double area) const {
    Split best;
    const double invArea = 1.0 / area;
    const double KT = opt_.costTraverse, KI = opt_.costIntersect, bonus = opt_.emptyBonus;
    for (int k = 0; k < 3; ++k) {
      if (!(box.lo[k] < box.hi[k])) continue;  // flat: no plane strictly inside
      const int k1 = (k + 1) % 3, k2 = (k + 2) % 3;
      const double e1 = double(box.hi[k1]) - box.lo[k1], e2 = double(box.hi[k2]) - box.lo[k2];
      const double lo = box.lo[k], hi = box.hi[k];
      auto consider = [&](float p, uint32_t nl, uint32_t nr) {
        if (!(p > box.lo[k] && p < box.hi[k])) return;
        const double wl = double(p) - lo, wr = hi - double(p);
        const double pl = (wl * (e1 + e2) + e1 * e2) * invArea;
        const double pr = (wr * (e1 + e2) + e1 * e2) * invArea;
        double c = KT + KI * (pl * nl + pr * nr);
        if (nl == 0 || nr == 0) c *= bonus;
        if (c < best.cost) {
          best.cost = c;
          best.axis = k;
          best.pos = p;
          best.nl = nl;
          best.nr = nr;
        }
      };
      // nl: triangles with lo < x (x the next event position), nr: those with hi >= x.
      uint32_t nl = 0, nr = n;
      const std::vector<Event>& E = ev[k];
      const size_t m = E.size();
      size_t i = 0;
      float a = box.lo[k];
      bool aIsEvent = false;
      for (;;) {
        const bool bIsEvent = i < m;
        const float b = bIsEvent ? E[i].pos : box.hi[k];
        // The gap between positions a and b: left nl (lo <= a), right nr (hi >= b).
        if (aIsEvent && a + kGrid < b) consider(a + kGrid, nl, nr);
        if (bIsEvent && b - kGrid > a && (!aIsEvent || b - kGrid != a + kGrid)) consider(b - kGrid, nl, nr);
        if (!bIsEvent) break;
        uint32_t pe = 0, pp = 0, ps = 0;
        while (i < m && E[i].pos == b && E[i].type() == kEnd) ++pe, ++i;
        while (i < m && E[i].pos == b && E[i].type() == kPlanar) ++pp, ++i;
        while (i < m && E[i].pos == b && E[i].type() == kStart) ++ps, ++i;
        consider(b, nl + ps + pp, nr);  // the plane at b: touching and planar triangles on both sides
        nl += ps + pp;
        nr -= pe + pp;
        a = b;
        aIsEvent = true;
      }
    }
    return best;
  }

  /// Bounds of triangle t clipped to `box` (Sutherland–Hodgman in world coordinates), rounded
  /// outward to the grid, within `box`. A polygon vertex keeps, per axis, whether its coordinate is
  /// exact (a triangle vertex, the clipping plane itself, or interpolated between two equal exact
  /// values); inexact coordinates are padded by the clip's round-off first. So a triangle lying in a
  /// plane stays flat there. Falls back to the triangle's own bounds within `box` if the clip comes
  /// out empty (it only grazes the box, to round-off).
  FBox clipped(uint32_t t, const FBox& box) const {
    struct V {
      Vec3 p;
      unsigned exact;  // bit a: coordinate a is exact
    };
    V buf[2][16];
    int n = 3;
    for (int k = 0; k < 3; ++k) buf[0][k] = V{mesh_.vertex(t, k), 7u};
    int cur = 0;
    for (int a = 0; a < 3 && n > 0; ++a) {
      for (int s = 0; s < 2 && n > 0; ++s) {
        const double plane = frame_.world(a, s == 0 ? box.lo[a] : box.hi[a]);
        const V* in = buf[cur];
        bool allIn = true;
        for (int i = 0; i < n && allIn; ++i) allIn = s == 0 ? in[i].p[a] >= plane : in[i].p[a] <= plane;
        if (allIn) continue;  // this plane cuts nothing off
        V* out = buf[1 - cur];
        int m = 0;
        for (int i = 0; i < n; ++i) {
          const V& P = in[i];
          const V& Q = in[i + 1 == n ? 0 : i + 1];
          const bool pin = s == 0 ? P.p[a] >= plane : P.p[a] <= plane;
          const bool qin = s == 0 ? Q.p[a] >= plane : Q.p[a] <= plane;
          if (pin) out[m++] = P;
          if (pin != qin) {
            double f = (plane - P.p[a]) / (Q.p[a] - P.p[a]);
            f = std::min(1.0, std::max(0.0, f));
            V X{P.p + (Q.p - P.p) * f, 1u << a};
            X.p[a] = plane;
            for (int j = 0; j < 3; ++j)
              if (j != a && (P.exact & Q.exact & (1u << j)) && P.p[j] == Q.p[j]) X.exact |= 1u << j;
            out[m++] = X;
          }
        }
        n = m;
        cur = 1 - cur;
      }
    }
    FBox r;
    if (n > 0) {
      for (int a = 0; a < 3; ++a) {
        double lo = std::numeric_limits<double>::infinity(), hi = -lo;
        for (int i = 0; i < n; ++i) {
          const V& v = buf[cur][i];
          const double pad = (v.exact >> a) & 1u ? 0.0 : pad_;
          lo = std::min(lo, v.p[a] - pad);
          hi = std::max(hi, v.p[a] + pad);
        }
        r.lo[a] = std::max(box.lo[a], frame_.down(a, lo));
        r.hi[a] = std::min(box.hi[a], frame_.up(a, hi));
        if (!(r.lo[a] <= r.hi[a])) n = 0;
      }
    }
    if (n == 0) {
      const FBox& tb = triBox_[t];
      for (int a = 0; a < 3; ++a) {
        r.lo[a] = std::max(box.lo[a], tb.lo[a]);
        r.hi[a] = std::min(box.hi[a], tb.hi[a]);
        if (!(r.lo[a] <= r.hi[a])) {  // cannot happen for a triangle of this node; stay conservative
          r.lo[a] = box.lo[a];
          r.hi[a] = box.hi[a];
        }
      }
    }
    return r;
  }

  void makeLeaf(uint32_t idx, const EventLists& ev, uint32_t n, int depth, double area) {
    const size_t offset = prims_.size();
    if (offset + n > SahKdTree::kMaxIndex)
      throw std::length_error("SahKdTree: more than 2^30 triangle references");
    for (const Event& e : ev[0])
      if (e.type() != kEnd) prims_.push_back(e.tri());
    std::sort(prims_.begin() + offset, prims_.end());
    if (prims_.size() - offset != n) throw std::logic_error("SahKdTree: triangle count out of step with events");
    nodes_[idx] = SahKdNode::leaf(n, static_cast<uint32_t>(offset));
    ++stats_.leaves;
    stats_.emptyLeaves += n == 0;
    stats_.references += n;
    stats_.maxLeafSize = std::max(stats_.maxLeafSize, n);
    stats_.depth = std::max(stats_.depth, depth);
    sahSum_ += opt_.costIntersect * n * area;
  }

  const TriangleMesh& mesh_;
  const SahBuildOptions& opt_;
  const Frame& frame_;
  double pad_;
  std::vector<SahKdNode>& nodes_;
  std::vector<uint32_t>& prims_;
  SahBuildStats& stats_;
  std::vector<uint8_t> side_;
  std::vector<FBox> triBox_;
  std::vector<uint32_t> both_;
  std::vector<Event> merged_;
  double sahSum_ = 0;
};

}  // namespace

void SahKdTree::build(const TriangleMesh& mesh, const SahBuildOptions& opt) {
  const auto t0 = std::chrono::steady_clock::now();
  nodes_.clear();
  prims_.clear();
  root_ = Box{};
  anchor_[0] = anchor_[1] = anchor_[2] = 0;
  scale_ = 1;
  stats_ = SahBuildStats{};
  const size_t N = mesh.size();
  stats_.primitives = N;
  if (N == 0) return;
  if (N > kMaxIndex) throw std::length_error("SahKdTree: more than 2^30 triangles");

  // The plane frame (see Frame). Only points used by triangles count: an unused far-away point
  // must not coarsen the planes.
  Box scene;
  for (size_t t = 0; t < N; ++t) scene.extend(mesh.bounds(t));
  Frame frame;
  double half = 0, maxAbs = 0;
  for (int a = 0; a < 3; ++a) {
    half = std::max(half, scene.hi[a] * 0.5 - scene.lo[a] * 0.5);  // no overflow
    maxAbs = std::max(maxAbs, std::max(std::fabs(scene.lo[a]), std::fabs(scene.hi[a])));
  }
  {
    int eExt = -1074, eAbs = -1074;
    if (half > 0) std::frexp(half, &eExt);   // 2^eExt >= half
    if (maxAbs > 0) std::frexp(maxAbs, &eAbs);  // 2^eAbs >= maxAbs
    int e = std::max(eExt + 3, eAbs - 28);     // scale >= 8 half = 4 extent, >= 2^-28 maxAbs
    if (half == 0 && maxAbs == 0) e = 0;
    e = std::min(1000, std::max(-1000, e));
    frame.scale = std::ldexp(1.0, e);
    frame.step = std::ldexp(1.0, e - 24);
    for (int a = 0; a < 3; ++a) frame.anchor[a] = std::floor(scene.lo[a] / frame.step) * frame.step;
  }
  for (int a = 0; a < 3; ++a) anchor_[a] = frame.anchor[a];
  scale_ = frame.scale;
  // Round-off of a clipped vertex: a few ulps of the largest coordinate per clipping stage.
  const double pad = 64 * DBL_EPSILON * maxAbs;

  const double logN = std::log2(static_cast<double>(N));
  stats_.maxDepth = opt.maxDepth > 0 ? std::min(opt.maxDepth, kMaxDepth)
                                     : std::min(kMaxDepth, static_cast<int>(std::lround(8 + 1.3 * logN)));
  if (opt.maxDepth < 0) stats_.maxDepth = 0;

  try {
    Builder b(mesh, opt, frame, pad, nodes_, prims_, stats_);
    const FBox rootBox = b.triangleBoxes();
    for (int a = 0; a < 3; ++a) {
      root_.lo[a] = frame.world(a, rootBox.lo[a]);
      root_.hi[a] = frame.world(a, rootBox.hi[a]);
    }
    EventLists ev;
    b.rootEvents(ev);
    nodes_.resize(1);
    b.build(0, rootBox, ev, static_cast<uint32_t>(N), 0);
    const double rootArea = halfArea(rootBox);
    stats_.sahCost = rootArea > 0 ? b.sahSum() / rootArea : opt.costIntersect * N;
  } catch (...) {
    nodes_.clear();
    nodes_.shrink_to_fit();
    prims_.clear();
    prims_.shrink_to_fit();
    root_ = Box{};
    stats_ = SahBuildStats{};
    stats_.primitives = N;
    throw;
  }
  nodes_.shrink_to_fit();
  prims_.shrink_to_fit();
  stats_.nodes = nodes_.size();
  stats_.bytes = bytes();
  stats_.buildMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace mtree

// The ray-tracing baseline: a surface-area-heuristic kd-tree over a triangle mesh, built as in
// Wald & Havran 2006, "On building fast kd-trees for ray tracing, and on doing that in
// O(N log N)", and traversed three ways:
//   Restart     KD-Restart (Foley & Sugerman 2005): no stack; after each leaf the ray restarts at
//               the root with its interval advanced to the leaf's exit.
//   Stack       the classic front-to-back traversal with a full stack of (node, tMin, tMax).
//   ShortStack  Horn, Sugerman, Houston & Hanrahan 2007: a ring buffer of the K most recent far
//               children (K = 3 by default; older entries are dropped when it overflows); when it
//               runs empty the ray restarts, not at the root but at the push-down node (the
//               deepest node that contains the rest of the ray, found on the way down).
// All three visit the same leaves in the same order, apply the same termination test and return
// bit-identical first hits; Stack visits each node at most once, the others revisit ancestors.
// Every query takes the traversal and the ray/triangle test (intersect.h) as arguments.
//
// ---- SAH (Wald & Havran §3-4) -------------------------------------------------------------------
// Cost of a split of node V at plane p into V_L, V_R with N_L, N_R triangles:
//     C(p) = lambda(p) * (K_T + K_I * (SA(V_L) N_L + SA(V_R) N_R) / SA(V)),
//     lambda(p) = emptyBonus (0.8) if N_L == 0 or N_R == 0, else 1;
// a leaf costs K_I * N. Defaults K_T = 1 (one traversal step), K_I = 1.5 (one triangle test).
// A node becomes a leaf when no plane costs less than the leaf, when it holds at most one triangle,
// or at the depth limit (default round(8 + 1.3 log2 N), never more than kMaxDepth). Candidate
// planes lie strictly inside the node (a plane on the node's face would make a zero-volume cell).
// Unlike the paper, a triangle that touches the plane or lies in it ("planar") goes to both
// children, not to one side (see Robustness): N_L counts the triangles with lo <= p, N_R those with
// hi >= p. The sweep tries, per axis, every event position x (touching triangles on both sides) and
// the planes one grid step (see below) off x towards the neighbouring positions: there a triangle
// ending at x is left only and one starting at the next position right only, which is the paper's
// one-sided choice in effect, and how a split cuts off empty space with an empty child.
//
// ---- Build (Wald & Havran §4.3-4.4, O(N log N)) --------------------------------------------------
// Every triangle contributes per axis one "planar" event (flat in that axis) or a "start" and an
// "end" event at its bounds, sorted once at the root by (position, type end < planar < start,
// triangle). Each node sweeps its three sorted lists once to find the best plane, classifies its
// triangles left / right / both, splits the lists in order (no re-sorting) and clips each triangle
// that goes to both sides to both child boxes ("perfect splits": Sutherland–Hodgman against the box,
// bounds of the polygon); only those few new events are sorted and merged in. Single threaded.
//
// ---- Planes as floats ------------------------------------------------------------------------------
// Split positions are stored as floats (4 bytes of the 8-byte node) in a per-tree frame: the plane
// of float s on axis a lies at world(a, s) = anchor[a] + double(s) * scale, where scale is a power of
// two >= 4x the scene's extent, the scene maps into s in [0, 0.25], and the build only uses floats
// on a grid of 2^-24 (every one a float; resolution 2^-22 to 2^-21 of the scene's extent, wherever
// the scene lies: a bunny at 1e8 from the origin keeps its planes). anchor is a multiple of
// 2^-24 scale, so world() is exact on the grid and strictly increasing: comparing two grid floats
// is comparing the world planes. Every triangle bound is rounded outward to the grid (a float whose
// world value is <= the lower bound, >= the upper; clipped bounds are padded by the clip's round-off
// first), so classification is conservative; the traversal computes each plane with the same
// world() expression, so build and traversal agree on where every plane is, bit for bit.
//
// ---- Node layout (8 bytes, like PBRT's and Wald's) -------------------------------------------------
//   word0: inner: the split position (float bits)      leaf: the number of triangles
//   word1: low 2 bits: the split axis (0, 1, 2), or 3 for a leaf;
//          high 30 bits: inner: index of the left child (the right child is the next node);
//                        leaf: offset of the leaf's triangles in primitiveIndices().
// A union of two layouts in spirit; written as two uint32 with memcpy for the float, which is
// defined behaviour and compiles to a plain load. Limits: 2^30 nodes and 2^30 references.
//
// ---- Robustness ----------------------------------------------------------------------------------
// Build: a triangle goes to every child whose closed box its (conservative) bounds touch: left only
// if it ends before the plane, right only if it starts after it, both otherwise, also when it only
// touches the plane or lies in it. So every leaf whose closed box holds a point of a triangle
// references that triangle. (The paper sends touching and planar triangles to one side; then a ray
// through a vertex where three planes meet, or starting on a planar triangle, can miss it: the
// leaves the ray passes through only touch the triangle's leaf at a point.)
// Traversal: at a node the ray's interval [tMin, tMax] is compared with the plane's tSplit strictly:
// first child only if tSplit >= tMax, second only if tSplit <= tMin, both otherwise; a ray lying in
// the plane takes the left child. Every leaf visited holds a piece of the ray of positive length,
// leaves come strictly front to back, and the leaves' closed boxes cover the ray's whole interval:
// with the build's rule, a triangle the ray meets at any point (an edge, a vertex on three planes,
// the ray's first or last point) is referenced by one of the leaves visited. No special cases, so
// the three traversals visit the same leaves.
// After a leaf the ray stops if its best hit t < the leaf's exit t minus a relative 2^-30 (so a hit
// on or next to the exit plane, whose t may differ from the plane's by round-off, still meets the
// next leaf's triangles: ties go to the smaller id as in the brute force). The ray's interval
// clipped to the root box is widened by the same relative 2^-30 at both ends, for the same
// round-off at its ends (a ray aimed at a vertex on the root box, a shadow ray whose tmax is a
// hit's t).
//
// Bad input: an empty mesh gives an empty tree (every ray misses); a ray with a NaN or infinite
// component, a zero direction or tmin > tmax (or NaN) misses at once.
#pragma once

#include <cstdint>
#include <cstring>
#include <limits>
#include <vector>

#include "mtree/core/geometry.h"
#include "mtree/rays/intersect.h"
#include "mtree/rays/triangle_batch.h"
#include "mtree/core/matrix_tree.h"
#include "mtree/core/primitives.h"
#include "mtree/rays/raycast.h"

namespace mtree {

enum class SahTraversal : int { Restart = 0, Stack = 1, ShortStack = 2 };
const char* sahTraversalName(SahTraversal t);

struct SahBuildOptions {
  double costTraverse = 1.0;   // K_T
  double costIntersect = 1.5;  // K_I
  double emptyBonus = 0.8;     // lambda for a split with an empty child
  /// Depth limit; 0 = round(8 + 1.3 log2 N); negative = the root is a leaf. At most
  /// SahKdTree::kMaxDepth.
  int maxDepth = 0;
};

struct SahBuildStats {
  uint64_t primitives = 0;
  uint64_t nodes = 0;        // inner + leaves
  uint64_t leaves = 0;
  uint64_t emptyLeaves = 0;
  uint64_t references = 0;   // (leaf, triangle) pairs
  uint64_t bytes = 0;        // nodes + primitive index array
  uint32_t maxLeafSize = 0;
  int depth = 0;             // deepest leaf (root = 0)
  int maxDepth = 0;          // the limit used
  double sahCost = 0;        // expected cost of a ray: sum over nodes of SA(node)/SA(root) x cost
  double buildMs = 0;
};

/// 8-byte kd-tree node (see the layout above).
class SahKdNode {
 public:
  static constexpr uint32_t kLeafTag = 3u;
  static SahKdNode inner(int axis, float split, uint32_t leftChild) {
    SahKdNode n;
    std::memcpy(&n.w0_, &split, sizeof(float));
    n.w1_ = (leftChild << 2) | static_cast<uint32_t>(axis);
    return n;
  }
  static SahKdNode leaf(uint32_t count, uint32_t offset) {
    SahKdNode n;
    n.w0_ = count;
    n.w1_ = (offset << 2) | kLeafTag;
    return n;
  }
  bool isLeaf() const { return (w1_ & 3u) == kLeafTag; }
  int axis() const { return static_cast<int>(w1_ & 3u); }
  float split() const {
    float f;
    std::memcpy(&f, &w0_, sizeof(float));
    return f;
  }
  uint32_t leftChild() const { return w1_ >> 2; }
  uint32_t primCount() const { return w0_; }
  uint32_t primOffset() const { return w1_ >> 2; }
  bool operator==(const SahKdNode& o) const { return w0_ == o.w0_ && w1_ == o.w1_; }

 private:
  uint32_t w0_ = 0;
  uint32_t w1_ = kLeafTag;
};
static_assert(sizeof(SahKdNode) == 8, "SahKdNode must stay 8 bytes");

class SahKdTree {
 public:
  static constexpr int kMaxDepth = 60;        // the Stack traversal's stack is kMaxDepth + 4
  static constexpr int kMaxShortStack = 64;   // ShortStack sizes are clamped to [0, this]
  static constexpr uint32_t kMaxIndex = (1u << 30) - 1;
  /// Relative widening of the ray's interval and of the termination test (see Robustness).
  static constexpr double kTPad = 0x1p-30;
  /// The termination / culling bound: a hit at t < before(tExit) ends the walk.
  static double before(double t) { return t - kTPad * std::fabs(t); }

  SahKdTree() = default;
  /// Builds over `mesh` (see the header comment). Throws std::length_error past the 2^30 limits
  /// (the tree is then empty). Replaces any previous tree.
  void build(const TriangleMesh& mesh, const SahBuildOptions& opt = SahBuildOptions{});
  explicit SahKdTree(const TriangleMesh& mesh, const SahBuildOptions& opt = SahBuildOptions{}) {
    build(mesh, opt);
  }

  bool empty() const { return nodes_.empty(); }
  const std::vector<SahKdNode>& nodes() const { return nodes_; }
  const std::vector<uint32_t>& primitiveIndices() const { return prims_; }
  const SahBuildStats& stats() const { return stats_; }
  size_t bytes() const { return nodes_.size() * sizeof(SahKdNode) + prims_.size() * sizeof(uint32_t); }
  /// World box of the root (the scene's bounds rounded outward to the float grid of the planes).
  const Box& rootBox() const { return root_; }
  /// World coordinate of the plane stored as float `s` on `axis`.
  double planeWorld(int axis, float s) const { return anchor_[axis] + static_cast<double>(s) * scale_; }
  /// The frame of planeWorld(): anchor per axis and the common scale (for copies of the tree that
  /// must place every plane where this one does, bit for bit).
  double planeAnchor(int axis) const { return anchor_[axis]; }
  double planeScale() const { return scale_; }

  /// Closest hit with t in [tmin, tmax]; ties (equal t) go to the smaller triangle id, as in
  /// intersectFirstBruteForce. `shortStack` is ShortStack's K (0..kMaxShortStack; 0 = push-down
  /// restarts only). Stats: nodeVisits = inner and leaf nodes visited (each restart's descent
  /// counts again), primTests = triangle tests, cells = leaves visited.
  bool intersectFirst(const TriangleMesh& mesh, Vec3 o, Vec3 d, double tmin, double tmax, RayHit& hit,
                      SahTraversal traversal = SahTraversal::Stack,
                      TriangleTest test = TriangleTest::MollerTrumbore, TraversalStats* st = nullptr,
                      int shortStack = 3) const;
  /// Any hit with t in [tmin, tmax] (shadow rays): stops at the first one found.
  bool intersectAny(const TriangleMesh& mesh, Vec3 o, Vec3 d, double tmin, double tmax,
                    SahTraversal traversal = SahTraversal::Stack,
                    TriangleTest test = TriangleTest::MollerTrumbore, TraversalStats* st = nullptr,
                    int shortStack = 3) const;

  /// The traversals, generic over a visitor with
  ///   bool leaf(const uint32_t* prims, uint32_t count)  // true: stop the walk (e.g. any hit found)
  ///   double cutoff() const                            // best hit t so far, +inf if none
  /// over the ray o + t d, t in [tmin, tmax]. Leaves come front to back; the walk ends after a leaf
  /// whose exit t is beyond cutoff() (see before()).
  template <class Visitor>
  void walk(SahTraversal traversal, Vec3 o, Vec3 d, double tmin, double tmax, Visitor& vis,
            TraversalStats* st, int shortStack = 3) const;

 private:
  struct RayCtx {
    double o[3], inv[3];
    bool par[3];     // the ray does not move along this axis (d == 0, or 1/d overflows)
    uint32_t neg[3]; // 1 if d < 0: the right child comes first
    double t0, t1;   // the interval clipped to the root box
  };
  struct Entry {
    uint32_t node;
    double tMin, tMax;
  };
  bool setup(Vec3 o, Vec3 d, double tmin, double tmax, RayCtx& r) const;
  int decide(const SahKdNode& nd, const RayCtx& r, double tMin, double tMax, uint32_t& first, uint32_t& second,
             double& ts) const;
  /// From node n down to the leaf the interval [tMin, tMax] meets first (front to back): a single
  /// child the ray enters is passed to onOne(child); where it crosses the split, onFar(far child,
  /// ts, tMax) receives the far part and tMax becomes ts. Returns the leaf (n its index), counts
  /// the nodes seen in visits.
  template <class OnOne, class OnFar>
  const SahKdNode* descend(const RayCtx& r, uint32_t& n, double tMin, double& tMax, uint64_t& visits, OnOne&& onOne,
                           OnFar&& onFar) const;
  template <class Visitor>
  void walkStack(const RayCtx& r, Visitor& vis, TraversalStats* st) const;
  template <class Visitor>
  void walkRestart(const RayCtx& r, Visitor& vis, TraversalStats* st) const;
  template <class Visitor>
  void walkShortStack(const RayCtx& r, Visitor& vis, int K, TraversalStats* st) const;

  std::vector<SahKdNode> nodes_;
  std::vector<uint32_t> prims_;
  Box root_;
  double anchor_[3] = {0, 0, 0};
  double scale_ = 1;
  SahBuildStats stats_;
};

/// The ray o + t d, t in [tmin, tmax], clipped to the closed box `root` by its slabs and widened
/// by a relative SahKdTree::kTPad at both ends (see Robustness): [t0, t1]. False, with nothing
/// to walk, for a ray that misses the box, a NaN or infinite component, a zero direction or
/// tmin > tmax (or NaN). An axis along which the ray does not move (1 / d overflows) keeps the
/// interval when o lies within the box's slab. The set-up of every tree clipped to its root box
/// by SahKdTree's rules (SahKdTree, ImplicitSplitTree).
inline bool clipRayToRoot(const Box& root, Vec3 o, Vec3 d, double tmin, double tmax, double& t0, double& t1);

// ---------------------------------------------------------------------------------------------
// Implementation of the traversals (templates: the visitor's leaf loop inlines).
// ---------------------------------------------------------------------------------------------

MT_ALWAYS_INLINE bool clipRayToRoot(const Box& root, Vec3 o, Vec3 d, double tmin, double tmax, double& t0, double& t1) {
  if (!isFinite(o) || !isFinite(d) || !(tmin <= tmax)) return false;
  if (d.x == 0 && d.y == 0 && d.z == 0) return false;
  double lo = tmin, hi = tmax;
  for (int a = 0; a < 3; ++a) {
    const double inv = 1.0 / d[a];
    if (!(std::fabs(inv) < std::numeric_limits<double>::infinity())) {  // no motion along a
      if (o[a] < root.lo[a] || o[a] > root.hi[a]) return false;
      continue;
    }
    double tn = (root.lo[a] - o[a]) * inv, tf = (root.hi[a] - o[a]) * inv;
    if (tn > tf) std::swap(tn, tf);
    if (tn > lo) lo = tn;
    if (tf < hi) hi = tf;
  }
  // Widened by kTPad (relative) so that round-off between a plane's t and a hit's t (a ray aimed at
  // a vertex on a plane, a shadow ray ending exactly at a hit) cannot hide a leaf the ray touches.
  t0 = lo - SahKdTree::kTPad * std::fabs(lo);
  t1 = hi + SahKdTree::kTPad * std::fabs(hi);
  return t0 <= t1;
}

MT_ALWAYS_INLINE bool SahKdTree::setup(Vec3 o, Vec3 d, double tmin, double tmax, RayCtx& r) const {
  if (nodes_.empty() || !clipRayToRoot(root_, o, d, tmin, tmax, r.t0, r.t1)) return false;
  for (int a = 0; a < 3; ++a) {
    r.o[a] = o[a];
    const double inv = 1.0 / d[a];
    r.par[a] = !(std::fabs(inv) < std::numeric_limits<double>::infinity());
    r.inv[a] = r.par[a] ? 0.0 : inv;
    r.neg[a] = d[a] < 0 ? 1u : 0u;
  }
  return true;
}

// The descent decision shared by the three walks, at inner node `nd` with the ray's interval
// [tMin, tMax]; `first` is the child the ray meets first. Returns kFirst (first child only),
// kSecond (second only) or kBoth (first over [tMin, ts], second over [ts, tMax], tMin < ts < tMax).
// Strict: a child the ray only touches (ts == tMin or ts == tMax, or a ray lying in the plane, which
// goes to the left) is skipped; it holds nothing the ray can meet that the other child lacks.
enum : int { kFirst = 1, kSecond = 2, kBoth = 3 };

inline int SahKdTree::decide(const SahKdNode& nd, const RayCtx& r, double tMin, double tMax, uint32_t& first,
                             uint32_t& second, double& ts) const {
  const int a = nd.axis();
  const uint32_t c = nd.leftChild();
  const double w = planeWorld(a, nd.split());
  if (r.par[a]) {
    first = r.o[a] <= w ? c : c + 1;
    return kFirst;
  }
  ts = (w - r.o[a]) * r.inv[a];
  first = c + r.neg[a];
  second = c + 1 - r.neg[a];
  if (ts >= tMax) return kFirst;
  if (ts <= tMin) return kSecond;
  return kBoth;
}

template <class OnOne, class OnFar>
inline const SahKdNode* SahKdTree::descend(const RayCtx& r, uint32_t& n, double tMin, double& tMax, uint64_t& visits,
                                           OnOne&& onOne, OnFar&& onFar) const {
  const SahKdNode* nd = &nodes_[n];
  ++visits;
  while (!nd->isLeaf()) {
    uint32_t first, second;
    double ts = 0;
    const int what = decide(*nd, r, tMin, tMax, first, second, ts);
    if (what != kBoth) {
      n = what == kFirst ? first : second;
      onOne(n);
    } else {
      onFar(second, ts, tMax);
      n = first;
      tMax = ts;
    }
    nd = &nodes_[n];
    ++visits;
  }
  return nd;
}

template <class Visitor>
void SahKdTree::walkStack(const RayCtx& r, Visitor& vis, TraversalStats* st) const {
  Entry stack[kMaxDepth + 4];
  int sp = 0;
  uint64_t visits = 0, leaves = 0;
  uint32_t n = 0;
  double tMin = r.t0, tMax = r.t1;
  for (;;) {
    const SahKdNode* nd = descend(r, n, tMin, tMax, visits, [](uint32_t) {},
                                  [&](uint32_t far, double ts, double t1) { stack[sp++] = Entry{far, ts, t1}; });
    ++leaves;
    if (nd->primCount() && vis.leaf(prims_.data() + nd->primOffset(), nd->primCount())) break;
    // The next entry starts where this leaf ends (leaves come front to back); a hit before that
    // (see before()) ends the walk.
    if (sp == 0 || vis.cutoff() < before(tMax)) break;
    const Entry& e = stack[--sp];
    n = e.node;
    tMin = e.tMin;
    tMax = e.tMax;
  }
  if (st) {
    st->nodeVisits += visits;
    st->cells += leaves;
  }
}

template <class Visitor>
void SahKdTree::walkRestart(const RayCtx& r, Visitor& vis, TraversalStats* st) const {
  uint64_t visits = 0, leaves = 0;
  double tMin = r.t0;
  for (;;) {
    uint32_t n = 0;
    double tMax = r.t1;
    const SahKdNode* nd = descend(r, n, tMin, tMax, visits, [](uint32_t) {}, [](uint32_t, double, double) {});
    ++leaves;
    if (nd->primCount() && vis.leaf(prims_.data() + nd->primOffset(), nd->primCount())) break;
    // The ray ends in this leaf, or a hit precedes its exit. Otherwise tMin strictly grows (every
    // leaf reached has tMin < tMax), so the walk ends.
    if (tMax >= r.t1 || vis.cutoff() < before(tMax)) break;
    tMin = tMax;
  }
  if (st) {
    st->nodeVisits += visits;
    st->cells += leaves;
  }
}

template <class Visitor>
void SahKdTree::walkShortStack(const RayCtx& r, Visitor& vis, int K, TraversalStats* st) const {
  Entry ring[kMaxShortStack > 0 ? kMaxShortStack : 1];
  int top = 0, count = 0;  // next free slot, number of entries held
  uint64_t visits = 0, leaves = 0;
  uint32_t restartNode = 0;  // push-down: the deepest node known to hold the rest of the ray
  bool pushdown = true;
  uint32_t n = 0;
  double tMin = r.t0, tMax = r.t1;
  for (;;) {
    const SahKdNode* nd = descend(
        r, n, tMin, tMax, visits,
        [&](uint32_t child) {
          if (pushdown) restartNode = child;
        },
        [&](uint32_t far, double ts, double t1) {
          if (K > 0) {
            ring[top] = Entry{far, ts, t1};
            top = top + 1 == K ? 0 : top + 1;
            if (count < K) ++count;  // else the oldest entry was overwritten
          }
          pushdown = false;
        });
    ++leaves;
    if (nd->primCount() && vis.leaf(prims_.data() + nd->primOffset(), nd->primCount())) break;
    if (tMax >= r.t1 || vis.cutoff() < before(tMax)) break;
    if (count > 0) {
      top = top == 0 ? K - 1 : top - 1;
      --count;
      n = ring[top].node;
      tMin = ring[top].tMin;  // == tMax: leaves come front to back
      tMax = ring[top].tMax;
    } else {  // restart below the push-down node with the interval advanced past this leaf
      n = restartNode;
      tMin = tMax;
      tMax = r.t1;
      pushdown = true;
    }
  }
  if (st) {
    st->nodeVisits += visits;
    st->cells += leaves;
  }
}

template <class Visitor>
void SahKdTree::walk(SahTraversal traversal, Vec3 o, Vec3 d, double tmin, double tmax, Visitor& vis,
                     TraversalStats* st, int shortStack) const {
  RayCtx r;
  if (!setup(o, d, tmin, tmax, r)) return;
  if (traversal == SahTraversal::Restart) {
    walkRestart(r, vis, st);
  } else if (traversal == SahTraversal::ShortStack) {
    const int K = shortStack < 0 ? 0 : (shortStack > kMaxShortStack ? kMaxShortStack : shortStack);
    walkShortStack(r, vis, K, st);
  } else {
    walkStack(r, vis, st);
  }
}

namespace detail {

template <TriangleTest Test>
struct SahFirstVisitor {
  const TriangleMesh& mesh;
  Vec3 o, d;
  double tmin, tmax;
  RayHit hit;
  uint64_t tests = 0;
  SahFirstVisitor(const TriangleMesh& m, Vec3 oo, Vec3 dd, double t0, double t1)
      : mesh(m), o(oo), d(dd), tmin(t0), tmax(t1) {
    hit.t = tmax;
  }
  double cutoff() const { return hit.prim != MT_NULL ? hit.t : std::numeric_limits<double>::infinity(); }
  bool leaf(const uint32_t* prims, uint32_t count) {
    firstInList<Test>(mesh, o, d, prims, count, tmin, hit, tests);
    return false;
  }
};

template <TriangleTest Test>
struct SahAnyVisitor {
  const TriangleMesh& mesh;
  Vec3 o, d;
  double tmin, tmax;
  bool found = false;
  uint64_t tests = 0;
  double cutoff() const { return std::numeric_limits<double>::infinity(); }
  bool leaf(const uint32_t* prims, uint32_t count) {
    return found = anyInList<Test>(mesh, o, d, prims, count, tmin, tmax, tests);
  }
};

template <TriangleTest Test>
inline bool sahFirst(const SahKdTree& tree, const TriangleMesh& mesh, Vec3 o, Vec3 d, double tmin, double tmax,
                     RayHit& hit, SahTraversal trav, TraversalStats* st, int K) {
  SahFirstVisitor<Test> vis(mesh, o, d, tmin, tmax);
  tree.walk(trav, o, d, tmin, tmax, vis, st, K);
  if (st) st->primTests += vis.tests;
  hit = vis.hit;
  if (!hit.hit()) hit.t = std::numeric_limits<double>::infinity();
  return hit.hit();
}

template <TriangleTest Test>
inline bool sahAny(const SahKdTree& tree, const TriangleMesh& mesh, Vec3 o, Vec3 d, double tmin, double tmax,
                   SahTraversal trav, TraversalStats* st, int K) {
  SahAnyVisitor<Test> vis{mesh, o, d, tmin, tmax};
  tree.walk(trav, o, d, tmin, tmax, vis, st, K);
  if (st) st->primTests += vis.tests;
  return vis.found;
}

}  // namespace detail

inline bool SahKdTree::intersectFirst(const TriangleMesh& mesh, Vec3 o, Vec3 d, double tmin, double tmax,
                                      RayHit& hit, SahTraversal traversal, TriangleTest test, TraversalStats* st,
                                      int shortStack) const {
  return test == TriangleTest::Watertight
             ? detail::sahFirst<TriangleTest::Watertight>(*this, mesh, o, d, tmin, tmax, hit, traversal, st,
                                                          shortStack)
             : detail::sahFirst<TriangleTest::MollerTrumbore>(*this, mesh, o, d, tmin, tmax, hit, traversal, st,
                                                              shortStack);
}

inline bool SahKdTree::intersectAny(const TriangleMesh& mesh, Vec3 o, Vec3 d, double tmin, double tmax,
                                    SahTraversal traversal, TriangleTest test, TraversalStats* st,
                                    int shortStack) const {
  return test == TriangleTest::Watertight
             ? detail::sahAny<TriangleTest::Watertight>(*this, mesh, o, d, tmin, tmax, traversal, st, shortStack)
             : detail::sahAny<TriangleTest::MollerTrumbore>(*this, mesh, o, d, tmin, tmax, traversal, st,
                                                            shortStack);
}

}  // namespace mtree

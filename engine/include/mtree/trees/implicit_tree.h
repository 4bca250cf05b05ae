// Implicit general kd-trees and BSP trees (paper §4.1, §4.2): every level of a binary tree is one
// block-sparse matrix (§3), and a node keeps only its split plane, or a leaf mark and its
// triangle range. No child or parent pointers: they are computed from the node's position.
//
// ---- Shape ------------------------------------------------------------------------------------
// Level l is a 2^lx x 2^ly x 2^lz matrix; level l + 1 doubles it along axis l mod 3 (x, y, z, x,
// ...), so the matrix stays within a factor 2 of a cube (§4.1: "alternating split directions
// between levels"). The children of node c at level l are c with c[a] -> 2 c[a] (left) and
// 2 c[a] + 1 (right), a = l mod 3; its parent is c[a'] -> c[a'] >> 1, a' = (l - 1) mod 3; its
// ancestor at any level p is one shift per axis. The matrix axis a node doubles along has nothing
// to do with its split direction (any direction, any position: the node stores them).
//
// ---- Node word (4 bytes) -------------------------------------------------------------------------
//   inner       the split's float (split_tree.h) with its tagBits low mantissa bits replaced by the
//               direction k (< count <= 2^tagBits - 1);
//   leaf        tag bits all ones, the leaf's index in the upper bits: its triangles are
//               primitiveIndices()[leafStart[i], leafStart[i + 1]);
//   empty leaf  0xFFFFFFFF, which is also the matrices' empty value: an empty leaf, or a block
//               of them, costs nothing where its block is not allocated.
// Node storage: 4 bytes per entry of every allocated block, 4 per pointer-matrix cell, and 4 per
// non-empty leaf (leafStart). A pointer kd-tree (SahKdTree) takes 8 bytes per node.
//
// ---- Block shape per level ---------------------------------------------------------------------
// A block of 2^k entries shaped as the level-l descendants of one level-(l - k) node (2^kx x 2^ky x
// 2^kz, kx + ky + kz = k, the doublings of the last k levels) needs a pointer matrix of 2^(l - k)
// cells. Level l then costs 4 (2^(l-k) + 2^k blocks_k) bytes, blocks_k = the distinct level-(l - k)
// ancestors of its stored nodes. build() with blockEdge 0 takes, per level, the k in [0, min(l, 15)]
// of least bytes (ties: the smaller k); blockEdge B > 0 puts B^3 blocks (shrunk to the level's
// dims) on every level, as the matrix trees do. layoutCost() gives any layout's bytes without
// building it: the pointer matrix grows as 2^l whatever the tree, so deep, sparse levels cost far
// more than their nodes (docs/trees.md).
//
// ---- Traversals (same leaves, same order, same hits as SahKdTree's) ------------------------------
//   Stack      SahKdTree's stack traversal, nodes read from the matrices.
//   Restart    KD-Restart (Foley & Sugerman 2005): after each leaf, down again from the root.
//   Backtrack  KD-Backtrack with derived parents and no stack: one bit per level says which nodes
//              on the current path the ray split (its far child still to visit); at a dead end the
//              walk jumps to the deepest such ancestor (its position is the current node's shifted
//              right, §4.1) and re-reads its plane for the far child's entry t, and the plane of the
//              next such ancestor up for its exit t (what the stack would have held): the
//              path-preserving jump of KD-Jump (Hughes & Lim 2009) without a complete tree.
// Node visits count every node word read, the two re-reads of a Backtrack jump included.
// The ray's interval is clipped to the root box and the decisions are SahKdTree's expressions
// (for the axes, dot(normal, o) is o's component exactly), so a tree built from a SahKdTree visits
// its leaves with the same t intervals, bit for bit.
#pragma once

#include <cstdint>
#include <limits>
#include <vector>

#include "mtree/core/block_sparse.h"
#include "mtree/core/matrix_tree.h"
#include "mtree/rays/intersect.h"
#include "mtree/rays/raycast.h"
#include "mtree/rays/sah_kdtree.h"
#include "mtree/trees/split_tree.h"

namespace mtree {

enum class SplitTraversal : int { Restart = 0, Stack = 1, Backtrack = 2 };
const char* splitTraversalName(SplitTraversal t);

/// Bytes of one level of a layout (layoutCost()).
struct ImplicitLevelCost {
  uint64_t nodes = 0;        // stored nodes (inner and non-empty leaves)
  uint64_t emptyLeaves = 0;  // empty leaves (stored only where their block exists)
  int logBlock[3] = {0, 0, 0};
  uint64_t pointers = 0;     // pointer-matrix cells
  uint64_t blocks = 0;       // allocated blocks
  uint64_t bytes = 0;        // 4 (pointers + blocks x block volume)
  double fill() const {
    const double v = double(blocks) * double(uint64_t(1) << (logBlock[0] + logBlock[1] + logBlock[2]));
    return v > 0 ? double(nodes) / v : 0;
  }
};
struct ImplicitLayoutCost {
  std::vector<ImplicitLevelCost> levels;
  uint64_t leafTableBytes = 0;  // leafStart
  uint64_t nodeBytes() const {
    uint64_t b = leafTableBytes;
    for (const auto& l : levels) b += l.bytes;
    return b;
  }
};

class ImplicitSplitTree {
 public:
  static constexpr uint32_t kEmpty = 0xFFFFFFFFu;
  /// Deepest level stored: a level's pointer matrix has at least 2^(l - 15) cells, which must
  /// stay below 2^32.
  static constexpr int kMaxLevel = 46;
  /// Relative widening of the ray's interval and of the termination test (SahKdTree::kTPad).
  static constexpr double kTPad = SahKdTree::kTPad;
  static double before(double t) { return t - kTPad * std::fabs(t); }

  /// log2 of the level's matrix size along `axis` (level l has doubled axis a at levels a, a+3, ...).
  static int logDim(int level, int axis) { return (level + 2 - axis) / 3; }
  /// The axis along which level l + 1 doubles level l.
  static int doublingAxis(int level) { return level % 3; }

  ImplicitSplitTree() = default;
  /// Stores `src` (a tree over `mesh`). blockEdge 0: per level, the block shape of least bytes;
  /// 1..32 (a power of two): B^3 blocks on every level. Planes that are not encodable are rounded
  /// (SplitFrame::encode) and the triangles redistributed down the rounded planes (see
  /// split_tree.h, Robustness); redistributed() then says so. Throws std::invalid_argument for a
  /// bad blockEdge, a frame with too many directions for its tag bits, a child, direction or
  /// triangle range that does not exist, or a triangle the mesh does not have;
  /// std::length_error for a tree deeper than kMaxLevel or a layout past 4 GiB (the tree is then
  /// empty). Replaces any previous tree.
  void build(const PointerSplitTree& src, const TriangleMesh& mesh, int blockEdge = 0);
  /// The bytes build(src, mesh, blockEdge) would take, level by level, without allocating them
  /// (for block edges whose pointer matrices would not fit in memory). Same exceptions.
  static ImplicitLayoutCost layoutCost(const PointerSplitTree& src, int blockEdge);

  bool empty() const { return levels_.empty(); }
  int numLevels() const { return static_cast<int>(levels_.size()); }
  const SplitFrame& frame() const { return frame_; }
  const Box& rootBox() const { return root_; }
  const BlockSparseMatrix<uint32_t>& level(int l) const { return levels_[l]; }
  const std::vector<uint32_t>& leafStart() const { return leafStart_; }
  const std::vector<uint32_t>& primitiveIndices() const { return prims_; }
  bool redistributed() const { return redistributed_; }
  uint64_t numNodes() const { return nodes_; }        // inner + leaves, empty ones included
  uint64_t numStoredNodes() const { return stored_; } // inner + non-empty leaves
  /// Level matrices (pointer matrices and blocks) and the leaf table.
  size_t nodeBytes() const;
  /// nodeBytes() plus the triangle index array.
  size_t bytes() const { return nodeBytes() + prims_.size() * sizeof(uint32_t); }
  /// Per level: nodes, block shape, pointer cells, blocks, bytes (the layout built).
  ImplicitLayoutCost levelCosts() const { return cost_; }

  /// The leaf holding point p: down from the root to the child on p's side of each plane (the
  /// left child for p on the plane, the side SahKdTree's walk takes for a ray lying in it). Returns
  /// the leaf's word (kEmpty for an empty leaf), its level and position; level -1 and kEmpty for a
  /// point outside the root box (or with a NaN coordinate) and for an empty tree.
  uint32_t leafFind(Vec3 p, int& level, int c[3]) const;

  /// The split planes of the inner nodes of levels [0, maxLevel] within their cells (the root
  /// box cut by the planes above), found by descending from the root through derived children.
  std::vector<SplitPolygon> splitPolygons(int maxLevel) const;

  /// The word of node c at level l (kEmpty where its block is absent). One pointer-matrix read and
  /// one block read.
  uint32_t word(int l, int x, int y, int z) const {
    const LevelView& v = views_[l];
    const uint32_t b = v.ptr[(size_t(uint32_t(z) >> v.lb[2]) * v.py + (uint32_t(y) >> v.lb[1])) * v.px +
                             (uint32_t(x) >> v.lb[0])];
    if (b == MT_NULL) return kEmpty;
    return v.data[size_t(b) * v.vol + ((uint32_t(z) & v.m[2]) << v.sz) + ((uint32_t(y) & v.m[1]) << v.lb[0]) +
                  (uint32_t(x) & v.m[0])];
  }
  bool isLeaf(uint32_t w) const { return (w & tagMask_) == tagMask_; }
  int direction(uint32_t w) const { return static_cast<int>(w & tagMask_); }
  float split(uint32_t w) const {
    const uint32_t b = w & ~tagMask_;
    float f;
    std::memcpy(&f, &b, sizeof f);
    return f;
  }
  /// A leaf word's triangles (count 0 for an empty leaf).
  const uint32_t* leafPrims(uint32_t w, uint32_t& count) const {
    if (w == kEmpty) {
      count = 0;
      return prims_.data();
    }
    const uint32_t i = w >> frame_.tagBits;
    count = leafStart_[i + 1] - leafStart_[i];
    return prims_.data() + leafStart_[i];
  }

  /// Closest hit in [tmin, tmax] (ties to the smaller triangle id, as the brute force). Stats:
  /// nodeVisits = node words read, primTests, cells = leaves visited.
  bool intersectFirst(const TriangleMesh& mesh, Vec3 o, Vec3 d, double tmin, double tmax, RayHit& hit,
                      SplitTraversal traversal = SplitTraversal::Stack,
                      TriangleTest test = TriangleTest::MollerTrumbore, TraversalStats* st = nullptr) const;
  /// Any hit in [tmin, tmax] (shadow rays).
  bool intersectAny(const TriangleMesh& mesh, Vec3 o, Vec3 d, double tmin, double tmax,
                    SplitTraversal traversal = SplitTraversal::Stack,
                    TriangleTest test = TriangleTest::MollerTrumbore, TraversalStats* st = nullptr) const;

  /// The traversals over a visitor with SahKdTree::walk's interface (leaf(prims, count) -> stop,
  /// cutoff() -> best hit t).
  template <class Visitor>
  void walk(SplitTraversal traversal, Vec3 o, Vec3 d, double tmin, double tmax, Visitor& vis,
            TraversalStats* st) const;

  /// The ray as the traversals see it (public for the OpenCL upload's tests and for
  /// vtkMatrixTreeRepresentation-style views that replay a walk).
  struct Ray {
    double o[SplitFrame::kMaxDirs], inv[SplitFrame::kMaxDirs];
    bool par[SplitFrame::kMaxDirs];
    uint32_t neg[SplitFrame::kMaxDirs];
    double t0, t1;
  };
  bool setup(Vec3 o, Vec3 d, double tmin, double tmax, Ray& r) const;

 private:
  struct LevelView {
    const uint32_t* ptr = nullptr;
    const uint32_t* data = nullptr;
    uint32_t px = 1, py = 1, vol = 1, sz = 0;
    uint32_t lb[3] = {0, 0, 0}, m[3] = {0, 0, 0};
  };
  enum : int { kFirst = 1, kSecond = 2, kBoth = 3 };
  // The decision of SahKdTree::decide at an inner node of word w: the side (0 left, 1 right)
  // the ray meets first, and which children it visits over [tMin, tMax] (kBoth: split at ts).
  int decide(uint32_t w, const Ray& r, double tMin, double tMax, int& firstSide, double& ts) const {
    const int k = direction(w);
    const double p = frame_.world(k, split(w));
    if (r.par[k]) {
      firstSide = r.o[k] <= p ? 0 : 1;
      return kFirst;
    }
    ts = (p - r.o[k]) * r.inv[k];
    firstSide = static_cast<int>(r.neg[k]);
    if (ts >= tMax) return kFirst;
    if (ts <= tMin) return kSecond;
    return kBoth;
  }
  /// ts of an inner node the ray crossed (kBoth), recomputed as decide() computed it.
  double crossing(uint32_t w, const Ray& r) const {
    const int k = direction(w);
    return (frame_.world(k, split(w)) - r.o[k]) * r.inv[k];
  }
  static void child(int level, int c[3], int side) {
    const int a = doublingAxis(level);
    c[a] = 2 * c[a] + side;
  }
  // Down from node (level, c) over [tMin, tMax] to a leaf (its word returned, level and c moved
  // to it, tMax to its exit); onSplit(firstSide, ts) at every node the ray crosses, before the
  // descent takes its first child.
  template <class OnSplit>
  uint32_t descend(const Ray& r, int& level, int c[3], double tMin, double& tMax, uint64_t& visits,
                   OnSplit&& onSplit) const;
  template <class Visitor>
  void walkStack(const Ray& r, Visitor& vis, TraversalStats* st) const;
  template <class Visitor>
  void walkRestart(const Ray& r, Visitor& vis, TraversalStats* st) const;
  template <class Visitor>
  void walkBacktrack(const Ray& r, Visitor& vis, TraversalStats* st) const;
  void makeViews();

  std::vector<BlockSparseMatrix<uint32_t>> levels_;
  std::vector<LevelView> views_;
  std::vector<uint32_t> leafStart_;
  std::vector<uint32_t> prims_;
  SplitFrame frame_;
  Box root_;
  uint32_t tagMask_ = 3;
  uint64_t nodes_ = 0, stored_ = 0;
  bool redistributed_ = false;
  ImplicitLayoutCost cost_;
};

/// The implicit tree as a tracer of render.h.
struct ImplicitTreeTracer {
  const ImplicitSplitTree& tree;
  const TriangleMesh& mesh;
  SplitTraversal traversal = SplitTraversal::Stack;
  TriangleTest test = TriangleTest::MollerTrumbore;
  bool first(Vec3 o, Vec3 d, double tmin, double tmax, RayHit& h, TraversalStats* st) const {
    return tree.intersectFirst(mesh, o, d, tmin, tmax, h, traversal, test, st);
  }
  bool any(Vec3 o, Vec3 d, double tmin, double tmax, TraversalStats* st) const {
    return tree.intersectAny(mesh, o, d, tmin, tmax, traversal, test, st);
  }
};

// ---------------------------------------------------------------------------------------------
// Traversals (templates: the visitor's leaf loop inlines)
// ---------------------------------------------------------------------------------------------

inline bool ImplicitSplitTree::setup(Vec3 o, Vec3 d, double tmin, double tmax, Ray& r) const {
  // The root box's slabs as SahKdTree::setup clips them (kTPad is SahKdTree's).
  if (levels_.empty() || !clipRayToRoot(root_, o, d, tmin, tmax, r.t0, r.t1)) return false;
  for (int k = 0; k < frame_.count; ++k) {
    r.o[k] = frame_.project(k, o);
    const double inv = 1.0 / frame_.project(k, d);
    r.par[k] = !(std::fabs(inv) < std::numeric_limits<double>::infinity());
    r.inv[k] = r.par[k] ? 0.0 : inv;
    r.neg[k] = inv < 0 ? 1u : 0u;
  }
  return true;
}

template <class OnSplit>
uint32_t ImplicitSplitTree::descend(const Ray& r, int& level, int c[3], double tMin, double& tMax, uint64_t& visits,
                                    OnSplit&& onSplit) const {
  uint32_t w = word(level, c[0], c[1], c[2]);
  ++visits;
  while (!isLeaf(w)) {
    int firstSide;
    double ts = 0;
    const int what = decide(w, r, tMin, tMax, firstSide, ts);
    if (what == kBoth) {
      onSplit(firstSide, ts);
      tMax = ts;
    }
    child(level, c, what == kSecond ? 1 - firstSide : firstSide);
    ++level;
    w = word(level, c[0], c[1], c[2]);
    ++visits;
  }
  return w;
}

template <class Visitor>
void ImplicitSplitTree::walkStack(const Ray& r, Visitor& vis, TraversalStats* st) const {
  struct Entry {
    int level, c[3];
    double tMin, tMax;
  };
  Entry stack[kMaxLevel + 4];
  int sp = 0;
  uint64_t visits = 0, leaves = 0;
  int level = 0, c[3] = {0, 0, 0};
  double tMin = r.t0, tMax = r.t1;
  for (;;) {
    const uint32_t w = descend(r, level, c, tMin, tMax, visits, [&](int firstSide, double ts) {
      Entry& e = stack[sp++];
      e.level = level + 1;
      e.c[0] = c[0];
      e.c[1] = c[1];
      e.c[2] = c[2];
      child(level, e.c, 1 - firstSide);
      e.tMin = ts;
      e.tMax = tMax;
    });
    ++leaves;
    uint32_t count;
    const uint32_t* ids = leafPrims(w, count);
    if (count && vis.leaf(ids, count)) break;
    if (sp == 0 || vis.cutoff() < before(tMax)) break;
    const Entry& e = stack[--sp];
    level = e.level;
    c[0] = e.c[0];
    c[1] = e.c[1];
    c[2] = e.c[2];
    tMin = e.tMin;
    tMax = e.tMax;
  }
  if (st) {
    st->nodeVisits += visits;
    st->cells += leaves;
  }
}

template <class Visitor>
void ImplicitSplitTree::walkRestart(const Ray& r, Visitor& vis, TraversalStats* st) const {
  uint64_t visits = 0, leaves = 0;
  double tMin = r.t0;
  for (;;) {
    int level = 0, c[3] = {0, 0, 0};
    double tMax = r.t1;
    const uint32_t w = descend(r, level, c, tMin, tMax, visits, [](int, double) {});
    ++leaves;
    uint32_t count;
    const uint32_t* ids = leafPrims(w, count);
    if (count && vis.leaf(ids, count)) break;
    if (tMax >= r.t1 || vis.cutoff() < before(tMax)) break;
    tMin = tMax;
  }
  if (st) {
    st->nodeVisits += visits;
    st->cells += leaves;
  }
}

template <class Visitor>
void ImplicitSplitTree::walkBacktrack(const Ray& r, Visitor& vis, TraversalStats* st) const {
  uint64_t visits = 0, leaves = 0;
  uint64_t pending = 0;  // bit l: the path's node at level l was split by the ray, far child unvisited
  int level = 0, c[3] = {0, 0, 0};
  double tMin = r.t0, tMax = r.t1;
  // The position of the current node's ancestor at level p: one shift per axis.
  auto ancestor = [&](int p, int a[3]) {
    for (int k = 0; k < 3; ++k) a[k] = c[k] >> (logDim(level, k) - logDim(p, k));
  };
  for (;;) {
    const uint32_t w =
        descend(r, level, c, tMin, tMax, visits, [&](int, double) { pending |= uint64_t(1) << level; });
    ++leaves;
    uint32_t count;
    const uint32_t* ids = leafPrims(w, count);
    if (count && vis.leaf(ids, count)) break;
    if (pending == 0 || vis.cutoff() < before(tMax)) break;
    // Jump to the deepest split ancestor p: its far child spans [ts_p, ts_q] with q the next split
    // ancestor up (t1 if none), the entry the stack would have popped.
    const int p = 63 - __builtin_clzll(pending);
    pending &= ~(uint64_t(1) << p);
    int a[3];
    ancestor(p, a);
    const uint32_t wp = word(p, a[0], a[1], a[2]);
    ++visits;
    tMin = crossing(wp, r);
    if (pending) {
      const int q = 63 - __builtin_clzll(pending);
      int b[3];
      ancestor(q, b);
      tMax = crossing(word(q, b[0], b[1], b[2]), r);
      ++visits;
    } else {
      tMax = r.t1;
    }
    child(p, a, 1 - static_cast<int>(r.neg[direction(wp)]));
    level = p + 1;
    c[0] = a[0];
    c[1] = a[1];
    c[2] = a[2];
  }
  if (st) {
    st->nodeVisits += visits;
    st->cells += leaves;
  }
}

template <class Visitor>
void ImplicitSplitTree::walk(SplitTraversal traversal, Vec3 o, Vec3 d, double tmin, double tmax, Visitor& vis,
                             TraversalStats* st) const {
  Ray r;
  if (!setup(o, d, tmin, tmax, r)) return;
  if (traversal == SplitTraversal::Restart)
    walkRestart(r, vis, st);
  else if (traversal == SplitTraversal::Backtrack)
    walkBacktrack(r, vis, st);
  else
    walkStack(r, vis, st);
}

namespace detail {

/// First hit through any tree with walk(traversal, o, d, tmin, tmax, visitor, stats).
template <TriangleTest Test, class Tree, class Traversal>
bool splitFirst(const Tree& tree, const TriangleMesh& mesh, Vec3 o, Vec3 d, double tmin, double tmax, RayHit& hit,
                Traversal trav, TraversalStats* st) {
  SahFirstVisitor<Test> vis(mesh, o, d, tmin, tmax);  // SahKdTree's leaf visitors (sah_kdtree.h)
  tree.walk(trav, o, d, tmin, tmax, vis, st);
  if (st) st->primTests += vis.tests;
  hit = vis.hit;
  if (!hit.hit()) hit.t = std::numeric_limits<double>::infinity();
  return hit.hit();
}
template <TriangleTest Test, class Tree, class Traversal>
bool splitAny(const Tree& tree, const TriangleMesh& mesh, Vec3 o, Vec3 d, double tmin, double tmax, Traversal trav,
              TraversalStats* st) {
  SahAnyVisitor<Test> vis{mesh, o, d, tmin, tmax};
  tree.walk(trav, o, d, tmin, tmax, vis, st);
  if (st) st->primTests += vis.tests;
  return vis.found;
}

}  // namespace detail

inline bool ImplicitSplitTree::intersectFirst(const TriangleMesh& mesh, Vec3 o, Vec3 d, double tmin, double tmax,
                                              RayHit& hit, SplitTraversal traversal, TriangleTest test,
                                              TraversalStats* st) const {
  return test == TriangleTest::Watertight
             ? detail::splitFirst<TriangleTest::Watertight>(*this, mesh, o, d, tmin, tmax, hit, traversal, st)
             : detail::splitFirst<TriangleTest::MollerTrumbore>(*this, mesh, o, d, tmin, tmax, hit, traversal, st);
}

inline bool ImplicitSplitTree::intersectAny(const TriangleMesh& mesh, Vec3 o, Vec3 d, double tmin, double tmax,
                                            SplitTraversal traversal, TriangleTest test, TraversalStats* st) const {
  return test == TriangleTest::Watertight
             ? detail::splitAny<TriangleTest::Watertight>(*this, mesh, o, d, tmin, tmax, traversal, st)
             : detail::splitAny<TriangleTest::MollerTrumbore>(*this, mesh, o, d, tmin, tmax, traversal, st);
}

}  // namespace mtree

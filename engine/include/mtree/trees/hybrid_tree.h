// The hybrid matrix/SAH tree of the paper's §7: "the matrix build at nodes near the root and SAH
// near the leaves". A matrix tree (matrix_tree.h, built by the §5.1 builder) with larger leaves
// than the matrix trees' own default, and inside every occupied matrix leaf that holds more than
// `leafTriangles` triangles a small general kd-tree over them, built by binned SAH so that the
// per-frame build stays close to the matrix build (a full SAH build per leaf costs about what the
// whole SAH build costs).
//
// ---- Per-leaf build ------------------------------------------------------------------------------
// Each triangle's box is clipped to the matrix leaf's box (triangles the builder's padded overlap
// test kept but that only graze the box are flattened onto the nearest face). A node with n
// triangles tries, on each axis, `bins` - 1 planes splitting the node's box evenly, or every
// triangle bound when 2n is fewer; the cost is SahKdTree's (K_T + K_I (SA(L) N_L + SA(R) N_R) /
// SA(V), empty bonus), a triangle goes left unless its box starts above the plane, right unless
// it ends below it (touching ones both), and the children's boxes clip its box. Every comparison
// is between doubles the triangle's vertices and the planes' world() values give exactly, so no
// pad is needed: a leaf's closed box holds every point of the triangles it lists. Planes are floats
// in one frame for the whole tree (SplitFrame over the root box); nodes are SahKdNode's 8 bytes.
//
// ---- Traversal -----------------------------------------------------------------------------------
// MatrixTree::traverseRay walks the matrix leaves; a leaf without a kd-tree is tested as the
// matrix trees test theirs (raycast.h: the per-ray mailbox, firstInList / anyInList); a leaf with
// one walks it over the ray's interval in the leaf, [tEnter, tExit] widened by a relative 2^-30, with
// SahKdTree's stack traversal and its strict decisions, testing each kd leaf the same way. A
// first-hit walk stops in the kd-tree after a kd leaf whose exit lies beyond the best hit (see
// SahKdTree::before), and in the matrix walk after a matrix leaf that holds the best hit.
// Node visits: the matrix walk's, plus every kd node visited.
#pragma once

#include <cstdint>
#include <limits>
#include <vector>

#include "mtree/core/block_sparse.h"
#include "mtree/core/builder.h"
#include "mtree/core/matrix_tree.h"
#include "mtree/rays/intersect.h"
#include "mtree/rays/raycast.h"
#include "mtree/rays/sah_kdtree.h"
#include "mtree/trees/split_tree.h"

namespace mtree {

struct HybridBuildOptions {
  /// The matrix part: kind, height (0 = automatic), block edge, overlap, threads. Its leafScale
  /// sets how large the matrix leaves are (in median triangle extents; the matrix trees' own
  /// default is 2, here 4: one level up for an octree): larger leaves leave more to the kd-trees.
  BuildOptions matrix = [] {
    BuildOptions o;
    o.leafScale = 4.0;
    return o;
  }();
  int leafTriangles = 8;  // matrix leaves with more triangles than this get a kd-tree
  int bins = 8;           // candidate planes per axis: bins - 1 (2..64)
  int maxDepth = 8;       // of each kd-tree (1..kMaxDepth): shallow, so the build stays fast
  double costTraverse = 1.0, costIntersect = 1.5, emptyBonus = 0.8;
};

struct HybridBuildStats {
  BuildStats matrix;
  double matrixMs = 0, subtreeMs = 0, totalMs = 0;
  uint64_t subtrees = 0;       // matrix leaves with a kd-tree
  uint64_t leavesTested = 0;   // matrix leaves without one
  uint64_t kdNodes = 0, kdLeaves = 0, kdReferences = 0;
  int kdDepth = 0;
};

class HybridTree {
 public:
  static constexpr int kMaxDepth = 30;
  static constexpr double kTPad = 0x1p-30;
  static double before(double t) { return t - kTPad * std::fabs(t); }

  /// Builds over `mesh`: the matrix tree, then a kd-tree per large occupied leaf (the leaves in
  /// parallel over matrix.threads). Options out of range throw std::invalid_argument (the
  /// matrix builder's own errors pass through). Replaces any previous tree.
  void build(const TriangleMesh& mesh, const HybridBuildOptions& opt = HybridBuildOptions{},
             HybridBuildStats* stats = nullptr);

  bool empty() const { return matrix_.empty(); }
  const MatrixTree& matrix() const { return matrix_; }
  const std::vector<SahKdNode>& kdNodes() const { return nodes_; }
  const std::vector<uint32_t>& kdPrimitives() const { return prims_; }
  /// The kd-tree root of matrix leaf L (bottom-level coordinates), MT_NULL where it has none.
  uint32_t subtreeOf(const int L[3]) const { return roots_.get(L[0], L[1], L[2]); }
  const SplitFrame& frame() const { return frame_; }
  /// The matrix tree, the leaf table of kd roots, the kd nodes and their triangle lists.
  size_t bytes() const {
    return matrix_.bytes() + roots_.bytes() + nodes_.size() * sizeof(SahKdNode) + prims_.size() * sizeof(uint32_t);
  }

  /// The kd-trees' split planes within their cells (rectangles in the matrix leaves' boxes),
  /// kd levels [0, maxLevel] (level 0: a kd root); dir is the axis.
  std::vector<SplitPolygon> splitPolygons(int maxLevel) const;

  bool intersectFirst(const TriangleMesh& mesh, Vec3 o, Vec3 d, double tmin, double tmax, RayHit& hit,
                      TriangleTest test = TriangleTest::MollerTrumbore, TraversalStats* st = nullptr) const;
  bool intersectAny(const TriangleMesh& mesh, Vec3 o, Vec3 d, double tmin, double tmax,
                    TriangleTest test = TriangleTest::MollerTrumbore, TraversalStats* st = nullptr) const;

  /// The kd-tree below `root` over the ray's part [tEnter, tExit] (SahKdTree's stack traversal):
  /// leaf(ids, count) for each kd leaf front to back (true: stop), cutoff() the best hit t.
  template <class Visitor>
  bool walkSubtree(uint32_t root, Vec3 o, const double inv[3], const bool par[3], double tEnter, double tExit,
                   Visitor& vis, uint64_t& visits) const;

 private:
  MatrixTree matrix_;
  BlockSparseMatrix<uint32_t> roots_;
  std::vector<SahKdNode> nodes_;
  std::vector<uint32_t> prims_;
  SplitFrame frame_;
};

/// The hybrid tree as a tracer of render.h.
struct HybridTracer {
  const HybridTree& tree;
  const TriangleMesh& mesh;
  TriangleTest test = TriangleTest::MollerTrumbore;
  bool first(Vec3 o, Vec3 d, double tmin, double tmax, RayHit& h, TraversalStats* st) const {
    return tree.intersectFirst(mesh, o, d, tmin, tmax, h, test, st);
  }
  bool any(Vec3 o, Vec3 d, double tmin, double tmax, TraversalStats* st) const {
    return tree.intersectAny(mesh, o, d, tmin, tmax, test, st);
  }
};

// ---------------------------------------------------------------------------------------------

template <class Visitor>
bool HybridTree::walkSubtree(uint32_t root, Vec3 o, const double inv[3], const bool par[3], double tEnter,
                             double tExit, Visitor& vis, uint64_t& visits) const {
  struct Entry {
    uint32_t node;
    double tMin, tMax;
  };
  Entry stack[kMaxDepth + 2];
  int sp = 0;
  uint32_t n = root;
  double tMin = tEnter - kTPad * std::fabs(tEnter), tMax = tExit + kTPad * std::fabs(tExit);
  for (;;) {
    const SahKdNode* nd = &nodes_[n];
    ++visits;
    while (!nd->isLeaf()) {
      const int a = nd->axis();
      const uint32_t c = nd->leftChild();
      const double w = frame_.world(a, nd->split());
      if (par[a]) {
        n = o[a] <= w ? c : c + 1;
      } else {
        const double ts = (w - o[a]) * inv[a];
        const uint32_t neg = inv[a] < 0 ? 1u : 0u;
        const uint32_t first = c + neg, second = c + 1 - neg;
        if (ts >= tMax) {
          n = first;
        } else if (ts <= tMin) {
          n = second;
        } else {
          stack[sp++] = Entry{second, ts, tMax};
          n = first;
          tMax = ts;
        }
      }
      nd = &nodes_[n];
      ++visits;
    }
    if (nd->primCount() && vis.leaf(prims_.data() + nd->primOffset(), nd->primCount())) return true;
    if (sp == 0 || vis.cutoff() < before(tMax)) return false;
    --sp;
    n = stack[sp].node;
    tMin = stack[sp].tMin;
    tMax = stack[sp].tMax;
  }
}

namespace detail {

/// The matrix trees' leaf test (raycast.h's intersectFirst / intersectAny), also applied to the
/// hybrid's kd leaves.
template <TriangleTest Test>
struct HybridFirst {
  const TriangleMesh& mesh;
  Vec3 o, d;
  double tmin;
  RayHit hit;
  RayMailbox mb;
  uint64_t tests = 0;
  HybridFirst(const TriangleMesh& m, Vec3 oo, Vec3 dd, double t0, double t1) : mesh(m), o(oo), d(dd), tmin(t0) {
    hit.t = t1;
  }
  double cutoff() const { return hit.prim != MT_NULL ? hit.t : std::numeric_limits<double>::infinity(); }
  bool leaf(const uint32_t* prims, uint32_t count) {
    forUntested(mb, prims, count, [&](const uint32_t* ids, uint32_t m) {
      firstInList<Test>(mesh, o, d, ids, m, tmin, hit, tests);
      return false;
    });
    return false;
  }
};
template <TriangleTest Test>
struct HybridAny {
  const TriangleMesh& mesh;
  Vec3 o, d;
  double tmin, tmax;
  RayMailbox mb;
  bool found = false;
  uint64_t tests = 0;
  HybridAny(const TriangleMesh& m, Vec3 oo, Vec3 dd, double t0, double t1) : mesh(m), o(oo), d(dd), tmin(t0), tmax(t1) {}
  double cutoff() const { return std::numeric_limits<double>::infinity(); }
  bool leaf(const uint32_t* prims, uint32_t count) {
    return forUntested(mb, prims, count, [&](const uint32_t* ids, uint32_t m) {
      return found = anyInList<Test>(mesh, o, d, ids, m, tmin, tmax, tests);
    });
  }
};

/// The hybrid walk with visitor `vis` (HybridFirst or HybridAny): the matrix walk, each matrix
/// leaf through its kd-tree or directly.
template <class Visitor>
void hybridWalk(const HybridTree& tree, Vec3 o, Vec3 d, double tmin, double tmax, Visitor& vis, TraversalStats* st) {
  double inv[3];
  bool par[3];
  for (int a = 0; a < 3; ++a) {
    const double i = 1.0 / d[a];
    par[a] = !(std::fabs(i) < std::numeric_limits<double>::infinity());
    inv[a] = par[a] ? 0.0 : i;
  }
  uint64_t kdVisits = 0;
  tree.matrix().traverseRay(
      o, d, tmin, tmax,
      [&](const uint32_t* prims, uint32_t count, double tEnter, double tExit, const int* L) {
        const uint32_t root = tree.subtreeOf(L);
        const bool stop = root == MT_NULL ? vis.leaf(prims, count)
                                          : tree.walkSubtree(root, o, inv, par, tEnter, tExit, vis, kdVisits);
        // A hit inside this matrix leaf (t <= tExit) cannot be beaten by a later one.
        return stop || vis.cutoff() <= tExit;
      },
      st);
  if (st) st->nodeVisits += kdVisits;
}

}  // namespace detail

inline bool HybridTree::intersectFirst(const TriangleMesh& mesh, Vec3 o, Vec3 d, double tmin, double tmax,
                                       RayHit& hit, TriangleTest test, TraversalStats* st) const {
  auto run = [&](auto vis) {
    detail::hybridWalk(*this, o, d, tmin, tmax, vis, st);
    if (st) st->primTests += vis.tests;
    hit = vis.hit;
    if (!hit.hit()) hit.t = std::numeric_limits<double>::infinity();
    return hit.hit();
  };
  if (test == TriangleTest::Watertight) return run(detail::HybridFirst<TriangleTest::Watertight>(mesh, o, d, tmin, tmax));
  return run(detail::HybridFirst<TriangleTest::MollerTrumbore>(mesh, o, d, tmin, tmax));
}

inline bool HybridTree::intersectAny(const TriangleMesh& mesh, Vec3 o, Vec3 d, double tmin, double tmax,
                                     TriangleTest test, TraversalStats* st) const {
  auto run = [&](auto vis) {
    detail::hybridWalk(*this, o, d, tmin, tmax, vis, st);
    if (st) st->primTests += vis.tests;
    return vis.found;
  };
  if (test == TriangleTest::Watertight) return run(detail::HybridAny<TriangleTest::Watertight>(mesh, o, d, tmin, tmax));
  return run(detail::HybridAny<TriangleTest::MollerTrumbore>(mesh, o, d, tmin, tmax));
}

}  // namespace mtree

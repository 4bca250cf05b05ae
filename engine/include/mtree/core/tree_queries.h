// Queries over the nodes of a MatrixTree that need no ray walk: the children of a node, the
// nodes of a level, the best-first search for the closest primitive, the primitives of the
// leaves that overlap a box, and per node the number of distinct primitives below it.
//
// A node c of level l exists when the level's block-sparse matrix holds it (paper §2: an inner
// node exists when some child exists, a leaf when it references primitives), and its children
// are the nodes of level l + 1 whose coordinates shifted right by the level's split bits are c
// (level l + 1 splits axis a by 2^(logDim(l + 1, a) - logDim(l, a))).
#pragma once

#include <algorithm>
#include <cstdint>
#include <queue>
#include <unordered_set>
#include <vector>

#include "mtree/core/geometry.h"
#include "mtree/core/matrix_tree.h"

namespace mtree {

/// Calls f(cc) for every existing child cc of node c of level l < height(), x fastest.
template <class F>
void forEachChild(const MatrixTree& t, int l, const int c[3], F&& f) {
  int s[3];
  for (int a = 0; a < 3; ++a) s[a] = t.logDim(l + 1, a) - t.logDim(l, a);
  for (int dz = 0; dz < (1 << s[2]); ++dz)
    for (int dy = 0; dy < (1 << s[1]); ++dy)
      for (int dx = 0; dx < (1 << s[0]); ++dx) {
        const int cc[3] = {(c[0] << s[0]) + dx, (c[1] << s[1]) + dy, (c[2] << s[2]) + dz};
        if (t.nodeExists(l + 1, cc)) f(cc);
      }
}

/// Calls f(c, references) for every existing node of level l (0..height()), in the order of the
/// level's block-sparse storage; references: a leaf's number of primitive references, 0 for an
/// inner node.
template <class F>
void forEachNode(const MatrixTree& t, int l, F&& f) {
  if (l == t.height()) {
    const auto& m = t.leafLevel();
    for (size_t e = 0; e < m.data().size(); ++e) {
      const MtLeafRange r = m.data()[e];
      if (r.begin == MT_NULL) continue;
      int c[3];
      m.entryCoords(static_cast<uint32_t>(e), c);
      f(static_cast<const int*>(c), r.end - r.begin);
    }
    return;
  }
  const auto& m = t.innerLevel(l);
  for (size_t e = 0; e < m.data().size(); ++e) {
    if (!m.data()[e]) continue;
    int c[3];
    m.entryCoords(static_cast<uint32_t>(e), c);
    f(static_cast<const int*>(c), uint32_t{0});
  }
}

/// Squared distance from x to the box b (0 inside it).
inline double boxDistance2(const double x[3], const Box& b) {
  double d2 = 0;
  for (int a = 0; a < 3; ++a) {
    const double d = std::max({b.lo[a] - x[a], 0.0, x[a] - b.hi[a]});
    d2 += d * d;
  }
  return d2;
}

/// Best-first search for the primitive closest to x within sqrt(bound2) (Hjaltason & Samet's
/// incremental nearest-neighbour order over the tree's node boxes): nodes are taken nearest box
/// first, and the search ends when the nearest remaining node is farther than the bound, which
/// no primitive inside it can then beat. Per primitive index of a reached leaf:
///   near(id, bound2) -> bool: whether the primitive may lie within the bound (a cheap test, e.g.
///     of its bounding box); false skips it here;
///   visit(id, bound2) -> double: the exact test, called once per distinct primitive that passes
///     near(); returns the new bound (<= bound2: the primitive's squared distance where closer).
/// The caller keeps the answer (which primitive, where); bound2 only shrinks.
template <class Near, class Visit>
void closestPrimitiveSearch(const MatrixTree& t, const double x[3], double bound2, Near&& near, Visit&& visit) {
  if (t.empty()) return;
  struct Entry {
    double d2;
    int level;
    int c[3];
    bool operator<(const Entry& o) const { return d2 > o.d2; }  // the nearest on top
  };
  std::priority_queue<Entry> queue;
  const int root[3] = {0, 0, 0};
  if (t.nodeExists(0, root)) queue.push(Entry{boxDistance2(x, t.nodeBox(0, root)), 0, {0, 0, 0}});
  std::unordered_set<uint32_t> visited;
  const int H = t.height();
  while (!queue.empty()) {
    const Entry e = queue.top();
    queue.pop();
    if (e.d2 > bound2) break;
    if (e.level == H) {
      const MtLeafRange r = t.leafLevel().get(e.c[0], e.c[1], e.c[2]);
      for (uint32_t k = r.begin; k < r.end; ++k) {
        const uint32_t id = t.primitiveIndices()[k];
        if (!near(id, bound2) || !visited.insert(id).second) continue;
        bound2 = visit(id, bound2);
      }
      continue;
    }
    forEachChild(t, e.level, e.c, [&](const int cc[3]) {
      const double cd2 = boxDistance2(x, t.nodeBox(e.level + 1, cc));
      if (cd2 <= bound2) queue.push(Entry{cd2, e.level + 1, {cc[0], cc[1], cc[2]}});
    });
  }
}

/// The distinct primitives referenced by the leaves whose (closed) box overlaps q, ascending.
/// A primitive is referenced by every leaf it overlaps, so every primitive that overlaps q is
/// among them (with those that overlap only the leaves).
std::vector<uint32_t> primitivesInLeavesOverlapping(const MatrixTree& t, const Box& q);

/// A node and the number of distinct primitives referenced by the leaves below it (for a leaf:
/// its references), with the fraction of its child slots that exist (1 for a leaf).
struct NodePrimitiveCount {
  int c[3];
  uint64_t primitives;
  double occupancy;
};

/// Per level lo..hi (0 <= lo <= hi <= height()), every existing node with its count, each
/// level's nodes in linear order of their coordinates (x fastest). Computed bottom-up: the
/// (node, primitive) pairs of level l are those of level l + 1 with each node replaced by its
/// parent, deduplicated. Empty for an empty tree.
std::vector<std::vector<NodePrimitiveCount>> distinctPrimitivesPerNode(const MatrixTree& t, int lo, int hi);

}  // namespace mtree

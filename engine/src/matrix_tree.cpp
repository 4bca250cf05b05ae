#include "mtree/matrix_tree.h"

namespace mtree {

const char* treeKindName(TreeKind k) { return k == TreeKind::Octree ? "octree" : "kdtree"; }

namespace {
// One level down: which axes split (the tree kind's rule, see matrix_tree.h). Updates the node
// extent `cell` and the per-axis log2 node counts `s`. The one place the rule is written, so the
// level shapes and the automatic height can never disagree.
void splitLevel(TreeKind kind, Vec3& cell, std::array<int, 3>& s) {
  const double m = std::max(cell.x, std::max(cell.y, cell.z));
  if (kind == TreeKind::Octree) {
    for (int a = 0; a < 3; ++a)
      if (cell[a] * 2.0 > m) { ++s[a]; cell[a] *= 0.5; }
  } else {
    const int a = (cell.x >= cell.y && cell.x >= cell.z) ? 0 : (cell.y >= cell.z ? 1 : 2);
    ++s[a];
    cell[a] *= 0.5;
  }
}
}  // namespace

std::vector<std::array<int, 3>> levelShapes(TreeKind kind, Vec3 e, int height) {
  std::vector<std::array<int, 3>> shapes(static_cast<size_t>(height) + 1, std::array<int, 3>{0, 0, 0});
  Vec3 cell = e;
  for (int l = 1; l <= height; ++l) {
    shapes[l] = shapes[l - 1];
    splitLevel(kind, cell, shapes[l]);
  }
  return shapes;
}

int chooseHeight(TreeKind kind, Vec3 rootExtent, double medianExtent, double leafScale, int blockEdge) {
  const double target = leafScale * medianExtent;
  // Deep enough for the target leaf size, but the leaf level's dense pointer matrix stays at most
  // 2^24 cells (64 MiB), and no axis gets more than 2^30 nodes.
  const int lb = ceilLog2(static_cast<uint64_t>(std::max(blockEdge, 1)));
  constexpr int kMaxLogPointers = 24, kMaxLogAxis = 30;
  const int maxH = kind == TreeKind::Octree ? 24 : MT_MAX_LEVELS - 1;
  Vec3 cell = rootExtent;
  int h = 0;
  std::array<int, 3> s{0, 0, 0};
  while (h < maxH) {
    const double m = std::max(cell.x, std::max(cell.y, cell.z));
    if (!(target > 0) || m <= target) break;
    std::array<int, 3> ns = s;
    Vec3 nc = cell;
    splitLevel(kind, nc, ns);
    int logPtr = 0;
    for (int a = 0; a < 3; ++a) logPtr += std::max(0, ns[a] - lb);
    if (logPtr > kMaxLogPointers || std::max(ns[0], std::max(ns[1], ns[2])) > kMaxLogAxis) break;
    s = ns;
    cell = nc;
    ++h;
  }
  return h;
}

size_t MatrixTree::bytes() const {
  size_t b = prims_.size() * sizeof(uint32_t) + leaves_.bytes();
  for (const auto& m : inner_) b += m.bytes();
  return b;
}

uint64_t MatrixTree::numLeaves() const {
  uint64_t n = 0;
  for (const MtLeafRange& r : leaves_.data()) n += (r.begin != MT_NULL);
  return n;
}

bool MatrixTree::leafCoords(Vec3 p, int L[3]) const {
  if (empty_ || !isFinite(p) || !root_.contains(p)) return false;
  for (int a = 0; a < 3; ++a) L[a] = cellIndex((p[a] - root_.lo[a]) * invLeaf_[a], 0, dim(height_, a) - 1);
  return true;
}

NodeRef MatrixTree::leafFind(Vec3 p, TraversalStats* st) const {
  int L[3];
  if (!leafCoords(p, L)) return NodeRef{};
  return locate(L, 0, height_ + 1, st);
}

NodeRef MatrixTree::leafFindTopDown(Vec3 p) const {
  int L[3];
  if (!leafCoords(p, L)) return NodeRef{};
  NodeRef r;
  for (int l = 1; l <= height_; ++l) {
    ancestor(L, l, r.c);
    if (!nodeExists(l, r.c)) {
      r.level = l;
      return r;
    }
  }
  r.level = height_;
  ancestor(L, height_, r.c);
  r.exists = true;
  return r;
}

}  // namespace mtree

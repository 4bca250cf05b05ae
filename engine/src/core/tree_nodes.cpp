#include "mtree/core/tree_nodes.h"

#include <algorithm>
#include <utility>

namespace mtree {

std::vector<TreeNodeInfo> treeNodes(const MatrixTree& tree, int lo, int hi) {
  std::vector<TreeNodeInfo> out;
  if (tree.empty()) return out;
  const int H = tree.height();
  hi = (hi < 0 || hi > H) ? H : hi;
  lo = std::max(0, std::min(lo, hi));

  // A node's key: its linear index in its level's full grid (x fastest). The leaf pointer
  // matrix is capped at 2^24 cells of at most 32^3 leaves, so keys fit 64 bits.
  auto key = [&](int l, const int c[3]) {
    return uint64_t(c[0]) | (uint64_t(c[1]) << tree.logDim(l, 0)) |
           (uint64_t(c[2]) << (tree.logDim(l, 0) + tree.logDim(l, 1)));
  };
  auto coords = [&](int l, uint64_t k, int c[3]) {
    const int bx = tree.logDim(l, 0), by = tree.logDim(l, 1);
    c[0] = int(k & ((uint64_t(1) << bx) - 1));
    c[1] = int((k >> bx) & ((uint64_t(1) << by) - 1));
    c[2] = int(k >> (bx + by));
  };

  using Pair = std::pair<uint64_t, uint32_t>;  // (node key, primitive)
  std::vector<Pair> pairs;
  pairs.reserve(tree.primitiveIndices().size());
  const auto& leaves = tree.leafLevel();
  for (size_t e = 0; e < leaves.data().size(); ++e) {
    const MtLeafRange r = leaves.data()[e];
    if (r.begin == MT_NULL) continue;
    int c[3];
    leaves.entryCoords(static_cast<uint32_t>(e), c);
    const uint64_t k = key(H, c);
    for (uint32_t i = r.begin; i < r.end; ++i) pairs.emplace_back(k, tree.primitiveIndices()[i]);
  }
  std::sort(pairs.begin(), pairs.end());

  std::vector<std::vector<TreeNodeInfo>> levels(size_t(hi - lo + 1));
  for (int l = H; l >= lo; --l) {
    if (l < H) {
      // Up one level: each node becomes its parent; repeats of (parent, primitive) go.
      int s[3];
      for (int a = 0; a < 3; ++a) s[a] = tree.logDim(l + 1, a) - tree.logDim(l, a);
      for (Pair& p : pairs) {
        int c[3];
        coords(l + 1, p.first, c);
        const int parent[3] = {c[0] >> s[0], c[1] >> s[1], c[2] >> s[2]};
        p.first = key(l, parent);
      }
      std::sort(pairs.begin(), pairs.end());
      pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
    }
    if (l > hi) continue;
    std::vector<TreeNodeInfo>& level = levels[size_t(l - lo)];
    int s[3] = {0, 0, 0};
    if (l < H)
      for (int a = 0; a < 3; ++a) s[a] = tree.logDim(l + 1, a) - tree.logDim(l, a);
    const double children = double(1 << (s[0] + s[1] + s[2]));
    for (size_t i = 0; i < pairs.size();) {
      size_t j = i;
      while (j < pairs.size() && pairs[j].first == pairs[i].first) ++j;
      TreeNodeInfo n;
      n.level = l;
      coords(l, pairs[i].first, n.c);
      n.primitives = j - i;
      if (l < H) {
        int present = 0;
        forEachChild(tree, l, n.c, [&](const int*) { ++present; });
        n.occupancy = present / children;
      }
      level.push_back(n);
      i = j;
    }
  }
  for (auto& level : levels) out.insert(out.end(), level.begin(), level.end());
  return out;
}

}  // namespace mtree

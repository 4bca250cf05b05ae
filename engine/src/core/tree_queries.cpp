#include "mtree/core/tree_queries.h"

#include <utility>

namespace mtree {

std::vector<uint32_t> primitivesInLeavesOverlapping(const MatrixTree& t, const Box& q) {
  std::vector<uint32_t> found;
  if (t.empty()) return found;
  struct Node {
    int level;
    int c[3];
  };
  std::vector<Node> stack;
  const int root[3] = {0, 0, 0};
  if (t.nodeExists(0, root) && t.nodeBox(0, root).overlaps(q)) stack.push_back(Node{0, {0, 0, 0}});
  while (!stack.empty()) {
    const Node nd = stack.back();
    stack.pop_back();
    if (nd.level == t.height()) {
      const MtLeafRange r = t.leafLevel().get(nd.c[0], nd.c[1], nd.c[2]);
      for (uint32_t k = r.begin; k < r.end; ++k) found.push_back(t.primitiveIndices()[k]);
      continue;
    }
    forEachChild(t, nd.level, nd.c, [&](const int cc[3]) {
      if (t.nodeBox(nd.level + 1, cc).overlaps(q)) stack.push_back(Node{nd.level + 1, {cc[0], cc[1], cc[2]}});
    });
  }
  std::sort(found.begin(), found.end());
  found.erase(std::unique(found.begin(), found.end()), found.end());
  return found;
}

std::vector<std::vector<NodePrimitiveCount>> distinctPrimitivesPerNode(const MatrixTree& t, int lo, int hi) {
  std::vector<std::vector<NodePrimitiveCount>> out;
  if (t.empty() || lo < 0 || hi < lo || hi > t.height()) return out;
  const int H = t.height();
  // Node keys are linear indices in the level's full grid: at most 2^43 nodes (the leaf pointer
  // matrix is capped), so 64 bits hold them.
  auto linear = [&](int l, const int c[3]) {
    return static_cast<uint64_t>(c[0]) +
           (uint64_t{1} << t.logDim(l, 0)) *
               (static_cast<uint64_t>(c[1]) + (uint64_t{1} << t.logDim(l, 1)) * static_cast<uint64_t>(c[2]));
  };
  auto unlinear = [&](int l, uint64_t k, int c[3]) {
    c[0] = static_cast<int>(k & ((uint64_t{1} << t.logDim(l, 0)) - 1));
    k >>= t.logDim(l, 0);
    c[1] = static_cast<int>(k & ((uint64_t{1} << t.logDim(l, 1)) - 1));
    c[2] = static_cast<int>(k >> t.logDim(l, 1));
  };
  using Pair = std::pair<uint64_t, uint32_t>;  // (node key, primitive)
  std::vector<Pair> pairs;
  pairs.reserve(t.primitiveIndices().size());
  forEachNode(t, H, [&](const int c[3], uint32_t) {
    const MtLeafRange r = t.leafLevel().get(c[0], c[1], c[2]);
    const uint64_t key = linear(H, c);
    for (uint32_t k = r.begin; k < r.end; ++k) pairs.emplace_back(key, t.primitiveIndices()[k]);
  });
  std::sort(pairs.begin(), pairs.end());
  out.resize(static_cast<size_t>(hi - lo + 1));
  for (int l = H; l >= lo; --l) {
    if (l < H) {
      int s[3];
      for (int a = 0; a < 3; ++a) s[a] = t.logDim(l + 1, a) - t.logDim(l, a);
      for (Pair& p : pairs) {
        int c[3];
        unlinear(l + 1, p.first, c);
        const int pc[3] = {c[0] >> s[0], c[1] >> s[1], c[2] >> s[2]};
        p.first = linear(l, pc);
      }
      std::sort(pairs.begin(), pairs.end());
      pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
    }
    if (l > hi) continue;
    double slots = 1.0;
    if (l < H) {
      int s = 0;
      for (int a = 0; a < 3; ++a) s += t.logDim(l + 1, a) - t.logDim(l, a);
      slots = static_cast<double>(1 << s);
    }
    std::vector<NodePrimitiveCount>& level = out[static_cast<size_t>(l - lo)];
    for (size_t i = 0; i < pairs.size();) {
      size_t j = i;
      while (j < pairs.size() && pairs[j].first == pairs[i].first) ++j;
      NodePrimitiveCount n;
      unlinear(l, pairs[i].first, n.c);
      n.primitives = j - i;
      n.occupancy = 1.0;
      if (l < H) {
        int present = 0;
        forEachChild(t, l, n.c, [&](const int*) { ++present; });
        n.occupancy = present / slots;
      }
      level.push_back(n);
      i = j;
    }
  }
  return out;
}

}  // namespace mtree

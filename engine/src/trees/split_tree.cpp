// Split frames and the pointer form of the split-plane trees. See split_tree.h.
#include "mtree/trees/split_tree.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

#include "mtree/rays/sah_kdtree.h"

namespace mtree {

double SplitFrame::padUnitOf(const Box& scene) {
  if (scene.empty()) return 0;
  double maxAbs = 0, ext = 0;
  for (int a = 0; a < 3; ++a) {
    maxAbs = std::max(maxAbs, std::max(std::fabs(scene.lo[a]), std::fabs(scene.hi[a])));
    ext = std::max(ext, scene.hi[a] - scene.lo[a]);
  }
  return 0x1p-32 * (maxAbs + 8 * ext);
}

SplitFrame SplitFrame::axes(const double anchor[3], double scale, double padUnit) {
  SplitFrame f;
  f.count = 3;
  f.tagBits = 2;
  for (int a = 0; a < 3; ++a) {
    f.normal[a] = Vec3(a == 0, a == 1, a == 2);
    f.anchor[a] = anchor[a];
    f.scale[a] = scale;
  }
  f.padUnit = padUnit;
  return f;
}

SplitFrame SplitFrame::kdop13(const TriangleMesh& mesh) {
  static const int kDirs[13][3] = {{1, 0, 0},  {0, 1, 0},  {0, 0, 1}, {1, 1, 0},  {1, -1, 0},
                                   {1, 0, 1},  {1, 0, -1}, {0, 1, 1}, {0, 1, -1}, {1, 1, 1},
                                   {1, 1, -1}, {1, -1, 1}, {-1, 1, 1}};
  SplitFrame f;
  f.count = 13;
  f.tagBits = 4;
  double lo[13], hi[13];
  for (int k = 0; k < 13; ++k) {
    f.normal[k] = Vec3(kDirs[k][0], kDirs[k][1], kDirs[k][2]);
    lo[k] = std::numeric_limits<double>::infinity();
    hi[k] = -lo[k];
  }
  Box scene;
  for (size_t t = 0; t < mesh.size(); ++t)
    for (int v = 0; v < 3; ++v) {
      const Vec3 p = mesh.vertex(t, v);
      scene.extend(p);
      for (int k = 0; k < 13; ++k) {
        const double x = f.project(k, p);
        lo[k] = std::min(lo[k], x);
        hi[k] = std::max(hi[k], x);
      }
    }
  // Per direction, SahKdTree's frame: scale a power of two >= 4 x the extent of the projections
  // (and >= 2^-28 of their magnitude), anchor a multiple of 2^-24 scale at or below the lowest.
  for (int k = 0; k < 13; ++k) {
    if (!(lo[k] <= hi[k])) {
      f.anchor[k] = 0;
      f.scale[k] = 1;
      continue;
    }
    const double half = hi[k] * 0.5 - lo[k] * 0.5, maxAbs = std::max(std::fabs(lo[k]), std::fabs(hi[k]));
    int eExt = -1074, eAbs = -1074;
    if (half > 0) std::frexp(half, &eExt);
    if (maxAbs > 0) std::frexp(maxAbs, &eAbs);
    int e = std::max(eExt + 3, eAbs - 28);
    if (half == 0 && maxAbs == 0) e = 0;
    e = std::min(1000, std::max(-1000, e));
    f.scale[k] = std::ldexp(1.0, e);
    const double step = std::ldexp(1.0, e - 24);
    f.anchor[k] = std::floor(lo[k] / step) * step;
  }
  f.padUnit = padUnitOf(scene);
  return f;
}

int PointerSplitTree::depth() const {
  if (nodes.empty()) return 0;
  int deepest = 0;
  std::vector<std::pair<uint32_t, int>> stack{{0u, 0}};
  while (!stack.empty()) {
    const auto [n, d] = stack.back();
    stack.pop_back();
    deepest = std::max(deepest, d);
    if (!nodes[n].leaf) {
      stack.push_back({nodes[n].child, d + 1});
      stack.push_back({nodes[n].child + 1, d + 1});
    }
  }
  return deepest;
}

uint64_t PointerSplitTree::leaves() const {
  uint64_t n = 0;
  for (const Node& nd : nodes) n += nd.leaf;
  return n;
}

PointerSplitTree pointerTreeOf(const SahKdTree& tree) {
  PointerSplitTree p;
  if (tree.empty()) return p;
  const double anchor[3] = {tree.planeAnchor(0), tree.planeAnchor(1), tree.planeAnchor(2)};
  p.root = tree.rootBox();
  p.frame = SplitFrame::axes(anchor, tree.planeScale(), SplitFrame::padUnitOf(p.root));
  p.prims = tree.primitiveIndices();
  p.nodes.resize(tree.nodes().size());
  for (size_t i = 0; i < p.nodes.size(); ++i) {
    const SahKdNode& s = tree.nodes()[i];
    PointerSplitTree::Node& n = p.nodes[i];
    n.leaf = s.isLeaf();
    if (n.leaf) {
      n.offset = s.primOffset();
      n.count = s.primCount();
    } else {
      n.dir = static_cast<uint8_t>(s.axis());
      n.s = s.split();
      n.child = s.leftChild();
    }
  }
  return p;
}

}  // namespace mtree

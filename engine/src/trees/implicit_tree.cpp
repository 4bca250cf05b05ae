// Implicit split-plane trees: conversion of a pointer tree into per-level block-sparse matrices
// and the choice of each level's block shape. See implicit_tree.h.
#include "mtree/trees/implicit_tree.h"

#include <algorithm>
#include <stdexcept>
#include <string>
#include <utility>

#include "polytope.h"

namespace mtree {

const char* splitTraversalName(SplitTraversal t) {
  switch (t) {
    case SplitTraversal::Restart:
      return "restart";
    case SplitTraversal::Stack:
      return "stack";
    case SplitTraversal::Backtrack:
      return "backtrack";
  }
  return "?";
}

namespace {

// A node position packed into 64 bits: 21 bits per axis (a level holds at most 2^14 per axis).
inline uint64_t packKey(uint64_t x, uint64_t y, uint64_t z) { return x | (y << 21) | (z << 42); }
inline uint32_t keyAxis(uint64_t key, int a) { return static_cast<uint32_t>((key >> (21 * a)) & ((1u << 21) - 1)); }

// The stored nodes of a tree, level by level (key, word), sorted by key; the leaf table and
// the triangle lists in leaf order.
struct Collected {
  std::vector<std::vector<std::pair<uint64_t, uint32_t>>> levels;
  std::vector<uint64_t> emptyLeaves;  // per level
  std::vector<uint32_t> leafStart{0};
  std::vector<uint32_t> prims;
  uint64_t nodes = 0, stored = 0;
};

void validate(const PointerSplitTree& src, int blockEdge) {
  if (blockEdge < 0 || blockEdge > 32 || (blockEdge & (blockEdge - 1)))
    throw std::invalid_argument("ImplicitSplitTree: block edge must be 0 (per level) or a power of two in [1, 32]");
  if (src.nodes.empty()) return;
  const SplitFrame& f = src.frame;
  if (f.tagBits < 1 || f.tagBits > 8 || f.count < 1 || f.count > SplitFrame::kMaxDirs ||
      uint32_t(f.count) > f.tagMask())
    throw std::invalid_argument("ImplicitSplitTree: the frame's " + std::to_string(f.count) +
                                " directions do not fit its " + std::to_string(f.tagBits) + " tag bits");
  for (const PointerSplitTree::Node& n : src.nodes) {
    if (!n.leaf && (n.dir >= f.count || n.child + 1 >= src.nodes.size()))
      throw std::invalid_argument("ImplicitSplitTree: a node refers to a direction or child that does not exist");
    if (n.leaf && (n.offset > src.prims.size() || n.count > src.prims.size() - n.offset))
      throw std::invalid_argument("ImplicitSplitTree: a leaf's triangle range lies outside the index array");
  }
}

class Collector {
 public:
  Collector(const PointerSplitTree& src, const TriangleMesh& mesh, bool redistribute)
      : src_(src), mesh_(mesh), f_(src.frame), redistribute_(redistribute) {
    maxLeaf_ = (uint32_t(0xFFFFFFFFu) >> f_.tagBits) - 1;  // the all-ones index is the empty leaf
    if (redistribute_) {
      const size_t n = mesh.size();
      lo_.resize(n * f_.count);
      hi_.resize(n * f_.count);
      for (size_t t = 0; t < n; ++t)
        for (int k = 0; k < f_.count; ++k) {
          const double p0 = f_.project(k, mesh.vertex(t, 0)), p1 = f_.project(k, mesh.vertex(t, 1)),
                       p2 = f_.project(k, mesh.vertex(t, 2));
          lo_[t * f_.count + k] = std::min(p0, std::min(p1, p2));
          hi_[t * f_.count + k] = std::max(p0, std::max(p1, p2));
        }
    }
  }

  Collected run() {
    std::vector<uint32_t> all;
    if (redistribute_) {
      all.resize(mesh_.size());
      for (size_t t = 0; t < all.size(); ++t) all[t] = static_cast<uint32_t>(t);
    }
    visit(0, 0, 0, 0, 0, all);
    for (auto& l : out_.levels) std::sort(l.begin(), l.end());
    return std::move(out_);
  }

 private:
  void visit(uint32_t n, int level, uint32_t x, uint32_t y, uint32_t z, std::vector<uint32_t>& tris) {
    if (level > ImplicitSplitTree::kMaxLevel)
      throw std::length_error("ImplicitSplitTree: the tree is " + std::to_string(src_.depth()) +
                              " levels deep; at most " + std::to_string(ImplicitSplitTree::kMaxLevel) +
                              " are stored (a level's pointer matrix has at least 2^(level - 15) cells)");
    if (size_t(level) >= out_.levels.size()) {
      out_.levels.resize(level + 1);
      out_.emptyLeaves.resize(level + 1, 0);
    }
    ++out_.nodes;
    const PointerSplitTree::Node& nd = src_.nodes[n];
    const uint64_t key = packKey(x, y, z);
    if (nd.leaf) {
      const uint32_t* ids = redistribute_ ? tris.data() : src_.prims.data() + nd.offset;
      const size_t count = redistribute_ ? tris.size() : nd.count;
      if (count == 0) {
        ++out_.emptyLeaves[level];
        return;
      }
      const uint32_t index = static_cast<uint32_t>(out_.leafStart.size() - 1);
      if (index >= maxLeaf_) throw std::length_error("ImplicitSplitTree: too many leaves for the node word");
      out_.prims.insert(out_.prims.end(), ids, ids + count);
      if (out_.prims.size() >= MT_NULL) throw std::length_error("ImplicitSplitTree: more than 2^32 triangle references");
      out_.leafStart.push_back(static_cast<uint32_t>(out_.prims.size()));
      out_.levels[level].push_back({key, f_.tagMask() | (index << f_.tagBits)});
      ++out_.stored;
      return;
    }
    const float s = f_.encode(nd.s);
    uint32_t bits;
    std::memcpy(&bits, &s, sizeof bits);
    out_.levels[level].push_back({key, bits | nd.dir});
    ++out_.stored;
    uint32_t c[3] = {x, y, z};
    const int a = ImplicitSplitTree::doublingAxis(level);
    std::vector<uint32_t> left, right;
    if (redistribute_) {
      // Left only if the projection ends below the plane by the pad, right only if it starts above.
      const int k = nd.dir;
      const double w = f_.world(k, s), pad = f_.pad(k);
      for (uint32_t t : tris) {
        const double lo = lo_[size_t(t) * f_.count + k], hi = hi_[size_t(t) * f_.count + k];
        if (!(hi + pad < w)) right.push_back(t);
        if (!(lo - pad > w)) left.push_back(t);
      }
      tris.clear();
      tris.shrink_to_fit();
    }
    c[a] = 2 * c[a];
    visit(nd.child, level + 1, c[0], c[1], c[2], left);
    c[a] += 1;
    visit(nd.child + 1, level + 1, c[0], c[1], c[2], right);
  }

  const PointerSplitTree& src_;
  const TriangleMesh& mesh_;
  const SplitFrame& f_;
  bool redistribute_;
  uint32_t maxLeaf_ = 0;
  std::vector<double> lo_, hi_;  // per triangle and direction: the projection interval
  Collected out_;
};

// The block shape of a level of `keys` (sorted) that takes the least bytes (blockEdge 0), or B^3
// blocks (blockEdge B).
ImplicitLevelCost levelCost(int l, const std::vector<std::pair<uint64_t, uint32_t>>& nodes, uint64_t emptyLeaves,
                            int blockEdge) {
  int dimLog[3];
  for (int a = 0; a < 3; ++a) dimLog[a] = ImplicitSplitTree::logDim(l, a);
  std::vector<uint64_t> blockKeys(nodes.size());
  auto costOf = [&](const int lb[3]) {
    ImplicitLevelCost c;
    c.nodes = nodes.size();
    c.emptyLeaves = emptyLeaves;
    for (int a = 0; a < 3; ++a) c.logBlock[a] = lb[a];
    c.pointers = uint64_t(1) << ((dimLog[0] - lb[0]) + (dimLog[1] - lb[1]) + (dimLog[2] - lb[2]));
    for (size_t i = 0; i < nodes.size(); ++i) {
      const uint64_t k = nodes[i].first;
      blockKeys[i] = packKey(keyAxis(k, 0) >> lb[0], keyAxis(k, 1) >> lb[1], keyAxis(k, 2) >> lb[2]);
    }
    std::sort(blockKeys.begin(), blockKeys.end());
    c.blocks = static_cast<uint64_t>(std::unique(blockKeys.begin(), blockKeys.end()) - blockKeys.begin());
    c.bytes = 4 * (c.pointers + (c.blocks << (lb[0] + lb[1] + lb[2])));
    return c;
  };
  if (blockEdge > 0) {
    const int e = ceilLog2(static_cast<uint64_t>(blockEdge));
    const int lb[3] = {std::min(e, dimLog[0]), std::min(e, dimLog[1]), std::min(e, dimLog[2])};
    return costOf(lb);
  }
  ImplicitLevelCost best;
  for (int k = 0; k <= std::min(l, 3 * MT_MAX_LOG_BLOCK); ++k) {
    int lb[3];
    for (int a = 0; a < 3; ++a) lb[a] = dimLog[a] - ImplicitSplitTree::logDim(l - k, a);
    const ImplicitLevelCost c = costOf(lb);
    if (k == 0 || c.bytes < best.bytes) best = c;
  }
  return best;
}

bool allEncodable(const PointerSplitTree& src) {
  for (const PointerSplitTree::Node& n : src.nodes)
    if (!n.leaf && !src.frame.encodable(n.s)) return false;
  return true;
}

ImplicitLayoutCost costOfCollected(const Collected& col, int blockEdge) {
  ImplicitLayoutCost cost;
  for (size_t l = 0; l < col.levels.size(); ++l)
    cost.levels.push_back(levelCost(static_cast<int>(l), col.levels[l], col.emptyLeaves[l], blockEdge));
  cost.leafTableBytes = col.leafStart.size() * sizeof(uint32_t);
  return cost;
}

}  // namespace

ImplicitLayoutCost ImplicitSplitTree::layoutCost(const PointerSplitTree& src, int blockEdge) {
  validate(src, blockEdge);
  if (src.nodes.empty()) return ImplicitLayoutCost{};
  // The layout depends only on where nodes are, not on the triangle lists: no redistribution.
  TriangleMesh none;
  PointerSplitTree shape = src;
  for (PointerSplitTree::Node& n : shape.nodes)
    if (!n.leaf) n.s = src.frame.encode(n.s);
  return costOfCollected(Collector(shape, none, false).run(), blockEdge);
}

void ImplicitSplitTree::build(const PointerSplitTree& src, const TriangleMesh& mesh, int blockEdge) {
  levels_.clear();
  views_.clear();
  leafStart_.clear();
  prims_.clear();
  cost_ = ImplicitLayoutCost{};
  nodes_ = stored_ = 0;
  redistributed_ = false;
  validate(src, blockEdge);
  frame_ = src.frame;
  root_ = src.root;
  tagMask_ = frame_.tagMask();
  if (src.nodes.empty()) return;
  for (uint32_t id : src.prims)
    if (id >= mesh.size())
      throw std::invalid_argument("ImplicitSplitTree: the tree lists triangle " + std::to_string(id) + " but the mesh has " +
                                  std::to_string(mesh.size()));
  redistributed_ = !allEncodable(src);
  Collected col = Collector(src, mesh, redistributed_).run();
  cost_ = costOfCollected(col, blockEdge);
  // A layout past 4 GiB is refused before anything is allocated (see layoutCost for its bytes).
  if (cost_.nodeBytes() > (uint64_t(1) << 32)) {
    const uint64_t need = cost_.nodeBytes();
    cost_ = ImplicitLayoutCost{};
    throw std::length_error("ImplicitSplitTree: block edge " + std::to_string(blockEdge) + " needs " +
                            std::to_string(need >> 20) + " MiB of node storage; use block edge 0 (per level)");
  }
  try {
    levels_.resize(col.levels.size());
    for (size_t l = 0; l < col.levels.size(); ++l) {
      const int L = static_cast<int>(l);
      levels_[l].resetShape(1 << logDim(L, 0), 1 << logDim(L, 1), 1 << logDim(L, 2), cost_.levels[l].logBlock,
                            kEmpty);
      for (const auto& [key, w] : col.levels[l])
        levels_[l].insert(static_cast<int>(keyAxis(key, 0)), static_cast<int>(keyAxis(key, 1)),
                          static_cast<int>(keyAxis(key, 2))) = w;
    }
  } catch (...) {
    levels_.clear();
    cost_ = ImplicitLayoutCost{};
    throw;
  }
  leafStart_ = std::move(col.leafStart);
  prims_ = std::move(col.prims);
  nodes_ = col.nodes;
  stored_ = col.stored;
  makeViews();
}

void ImplicitSplitTree::makeViews() {
  views_.resize(levels_.size());
  for (size_t l = 0; l < levels_.size(); ++l) {
    const MtSparseDesc& d = levels_[l].desc();
    LevelView& v = views_[l];
    v.ptr = levels_[l].pointers().data();
    v.data = levels_[l].data().data();
    v.px = static_cast<uint32_t>(d.ptrDims[0]);
    v.py = static_cast<uint32_t>(d.ptrDims[1]);
    v.vol = d.blockVolume;
    for (int a = 0; a < 3; ++a) {
      v.lb[a] = static_cast<uint32_t>(d.logBlock[a]);
      v.m[a] = (1u << d.logBlock[a]) - 1u;
    }
    v.sz = v.lb[0] + v.lb[1];
  }
}

std::vector<SplitPolygon> ImplicitSplitTree::splitPolygons(int maxLevel) const {
  std::vector<SplitPolygon> out;
  if (levels_.empty()) return out;
  struct Item {
    int level, c[3];
    detail::Poly cell;
  };
  std::vector<Item> stack;
  stack.push_back(Item{0, {0, 0, 0}, detail::boxPoly(root_)});
  while (!stack.empty()) {
    Item it = std::move(stack.back());
    stack.pop_back();
    const uint32_t w = word(it.level, it.c[0], it.c[1], it.c[2]);
    if (isLeaf(w) || it.level > maxLevel) continue;
    const int k = direction(w);
    const double p = frame_.world(k, split(w));
    const Vec3 n = frame_.normal[k];
    SplitPolygon poly;
    poly.level = it.level;
    poly.dir = k;
    poly.points = detail::cutPolygon(it.cell, n, p);
    if (!poly.points.empty()) out.push_back(std::move(poly));
    for (int side = 0; side < 2; ++side) {
      Item ch{it.level + 1, {it.c[0], it.c[1], it.c[2]}, detail::clipPoly(it.cell, n, p, side == 0 ? 1.0 : -1.0)};
      child(it.level, ch.c, side);
      stack.push_back(std::move(ch));
    }
  }
  return out;
}

uint32_t ImplicitSplitTree::leafFind(Vec3 p, int& level, int c[3]) const {
  level = -1;
  c[0] = c[1] = c[2] = 0;
  if (levels_.empty() || !root_.contains(p)) return kEmpty;
  level = 0;
  uint32_t w = word(0, 0, 0, 0);
  while (!isLeaf(w)) {
    const int k = direction(w);
    child(level, c, frame_.project(k, p) <= frame_.world(k, split(w)) ? 0 : 1);
    ++level;
    w = word(level, c[0], c[1], c[2]);
  }
  return w;
}

size_t ImplicitSplitTree::nodeBytes() const {
  size_t b = leafStart_.size() * sizeof(uint32_t);
  for (const auto& l : levels_) b += l.bytes();
  return b;
}

}  // namespace mtree

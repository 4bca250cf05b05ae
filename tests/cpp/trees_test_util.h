// Helpers of the split-plane tree tests (test_implicit_kd, test_bsp_tree, test_hybrid_tree,
// test_opencl_trees): seeded rays that probe a tree's planes, bitwise hit comparison, and a
// general kd-tree with planes anywhere.
#pragma once

#include <cstring>
#include <vector>

#include "mtree/trees/implicit_tree.h"
#include "mtree/trees/split_tree.h"
#include "test_util.h"

namespace mtest {

/// The three traversals of a split-plane tree, every test runs each.
inline const mtree::SplitTraversal kTraversals[3] = {mtree::SplitTraversal::Stack, mtree::SplitTraversal::Restart,
                                                     mtree::SplitTraversal::Backtrack};

/// Same triangle, t, u, v to the bit.
inline bool sameHitBits(const mtree::RayHit& a, const mtree::RayHit& b) {
  return a.prim == b.prim && std::memcmp(&a.t, &b.t, sizeof(double)) == 0 && a.u == b.u && a.v == b.v;
}

/// n seeded rays against a mesh and a split-plane tree over it: half aimedRays() (from outside at
/// triangle points, from inside, axis-parallel through triangle points), a fifth aimed exactly at
/// vertices and edge midpoints, a fifth lying in a random inner node's plane (a third of those in
/// a second plane as well, along the line where they meet; exact for the axes, to round-off for
/// other directions), the rest from inside along random directions; every 10th with a clipped
/// interval [tmin, tmax].
inline std::vector<Ray> splitTreeRays(const mtree::TriangleMesh& mesh, const mtree::PointerSplitTree& tree, int n,
                                      uint64_t seed) {
  std::vector<Ray> rays = aimedRays(mesh, n / 2, seed);
  Rng rng(seed ^ 0x5157ull);
  const Box mb = meshBounds(mesh);
  const Vec3 c = mb.center();
  const double diag = std::max(mtree::norm(mb.extent()), 1e-300);
  std::vector<uint32_t> inner;
  for (uint32_t i = 0; i < tree.nodes.size(); ++i)
    if (!tree.nodes[i].leaf) inner.push_back(i);
  // Moves o into the plane of inner node `n` and turns d parallel to it.
  auto intoPlane = [&](Ray& r, uint32_t node) {
    const mtree::PointerSplitTree::Node& nd = tree.nodes[node];
    const Vec3 nrm = tree.frame.normal[nd.dir];
    const double w = tree.frame.world(nd.dir, nd.s), nn = mtree::dot(nrm, nrm);
    int axis = -1;
    for (int a = 0; a < 3; ++a)
      if (nrm[a] != 0 && nn == 1) axis = a;
    if (axis >= 0) {
      r.o[axis] = w;
      r.d[axis] = 0;
    } else {
      r.o = r.o + nrm * ((w - tree.frame.project(nd.dir, r.o)) / nn);
      r.d = r.d - nrm * (mtree::dot(nrm, r.d) / nn);
    }
  };
  while (static_cast<int>(rays.size()) < n) {
    Ray r;
    const int kind = static_cast<int>(rays.size() % 5);
    if (kind < 2) {  // at a vertex or an edge midpoint, from outside
      const size_t t = rng.below(static_cast<uint32_t>(mesh.size()));
      const int k = static_cast<int>(rng.below(3));
      const Vec3 a = mesh.vertex(t, k), b = mesh.vertex(t, (k + 1) % 3);
      const Vec3 target = rng.below(2) ? a : a + (b - a) * 0.5;
      r.o = c + rng.direction() * (diag * rng.uniform(0.6, 1.5));
      r.d = target - r.o;
    } else if (kind < 4 && !inner.empty()) {  // in one or two planes
      r.o = rng.inBox(mb);
      r.d = rng.direction();
      intoPlane(r, inner[rng.below(static_cast<uint32_t>(inner.size()))]);
      if (rng.below(3) == 0) intoPlane(r, inner[rng.below(static_cast<uint32_t>(inner.size()))]);
      if (r.d.x == 0 && r.d.y == 0 && r.d.z == 0) r.d = Vec3(0, 0, 1);
    } else {
      r.o = rng.inBox(mb);
      r.d = rng.direction();
    }
    rays.push_back(r);
  }
  for (size_t i = 9; i < rays.size(); i += 10) {
    const double scale = diag / std::max(mtree::norm(rays[i].d), 1e-300);
    rays[i].tmin = rng.uniform(0, 0.5) * scale;
    rays[i].tmax = rays[i].tmin + rng.uniform(0, 1.5) * scale;
  }
  return rays;
}

/// A general kd-tree over `mesh` of the given depth in pointer form: random axis and a random
/// float plane inside each cell (so most planes are not encodable), every leaf holding every
/// triangle (redistribution decides where they belong). Frame: the axes over the mesh's box.
inline mtree::PointerSplitTree randomKdTree(const mtree::TriangleMesh& mesh, int depth, uint64_t seed) {
  Rng rng(seed);
  mtree::PointerSplitTree t;
  const Box mb = meshBounds(mesh);
  const double anchor[3] = {mb.lo.x, mb.lo.y, mb.lo.z};
  const double scale = std::max(mb.extent().x, std::max(mb.extent().y, mb.extent().z));
  t.frame = mtree::SplitFrame::axes(anchor, scale, mtree::SplitFrame::padUnitOf(mb));
  t.root = mb;
  for (uint32_t i = 0; i < mesh.size(); ++i) t.prims.push_back(i);
  struct Item {
    uint32_t node;
    Box cell;
    int depth;
  };
  t.nodes.resize(1);
  std::vector<Item> stack{{0, mb, 0}};
  while (!stack.empty()) {
    const Item it = stack.back();
    stack.pop_back();
    mtree::PointerSplitTree::Node& nd = t.nodes[it.node];
    const int a = static_cast<int>(rng.below(3));
    const float s = static_cast<float>((rng.uniform(it.cell.lo[a], it.cell.hi[a]) - anchor[a]) / scale);
    const double w = t.frame.world(a, t.frame.encode(s));
    if (it.depth >= depth || rng.below(8) == 0 || !(w > it.cell.lo[a] && w < it.cell.hi[a])) {
      nd.leaf = true;
      nd.offset = 0;
      nd.count = static_cast<uint32_t>(t.prims.size());
      continue;
    }
    const uint32_t child = static_cast<uint32_t>(t.nodes.size());
    nd.leaf = false;
    nd.dir = static_cast<uint8_t>(a);
    nd.s = s;
    nd.child = child;
    t.nodes.resize(t.nodes.size() + 2);  // nd is not used past this point
    Box l = it.cell, r = it.cell;
    l.hi[a] = w;
    r.lo[a] = w;
    stack.push_back({child, l, it.depth + 1});
    stack.push_back({child + 1, r, it.depth + 1});
  }
  return t;
}

}  // namespace mtest

// Ray queries over a triangle mesh indexed by a matrix tree, and the brute-force references the
// tests compare them with. Ties (two triangles at the same t, e.g. a hit on a shared edge) are
// broken by the smaller triangle id, in both, so answers are comparable exactly.
#pragma once

#include "mtree/rays/intersect.h"
#include "mtree/core/matrix_tree.h"
#include "mtree/core/primitives.h"
#include "mtree/rays/triangle_batch.h"

namespace mtree {

/// A per-ray mailbox (Amanatides & Woo 1987; Havran's thesis): a triangle referenced by several
/// leaves along the ray is tested once. Direct mapped, 16 slots: a slot holds the last id tested
/// that maps to it. Exact: a second test of the same triangle by the same ray gives the same
/// answer (first hit: the interval [tmin, best t] only shrinks; any hit: it already failed).
struct RayMailbox {
  uint32_t slot[16];
  RayMailbox() {
    for (uint32_t& s : slot) s = MT_NULL;
  }
  /// True if `id` was tested already; otherwise records it.
  bool seen(uint32_t id) {
    uint32_t& s = slot[id & 15u];
    if (s == id) return true;
    s = id;
    return false;
  }
};

/// Calls f(ids, m) for the triangles among prims[0..count) that this ray has not tested yet
/// (the mailbox records them now), in leaf order, at most 64 at a time; a true return stops and
/// is returned.
template <class F>
inline bool forUntested(RayMailbox& mb, const uint32_t* prims, uint32_t count, F&& f) {
  uint32_t fresh[64];
  for (uint32_t k = 0; k < count;) {
    uint32_t m = 0;
    for (; k < count && m < 64; ++k)
      if (!mb.seen(prims[k])) fresh[m++] = prims[k];
    if (f(static_cast<const uint32_t*>(fresh), m)) return true;
  }
  return false;
}

struct RayHit {
  double t = std::numeric_limits<double>::infinity();
  uint32_t prim = MT_NULL;
  double u = 0, v = 0;
  bool hit() const { return prim != MT_NULL; }
  /// Keeps triangle `id` hit at t (weights u, v) if it is nearer than the hit held, or as near
  /// with a smaller id: the first-hit rule of every tree and of the brute force.
  void offer(uint32_t id, double tt, double uu, double vv) {
    if (tt < t || (tt == t && id < prim)) {
      t = tt;
      prim = id;
      u = uu;
      v = vv;
    }
  }
};

/// The leaf loops every tree's traversal shares. firstInList: the triangles ids[0..m) offered to
/// `hit` (t in [tmin, hit.t]); anyInList: whether one is hit with t in [tmin, tmax]. Both add the
/// triangles tested to `tests`, the any-hit count stopping at the one that hits, as a one-by-one
/// loop would.
template <TriangleTest Test>
inline void firstInList(const TriangleMesh& mesh, Vec3 o, Vec3 d, const uint32_t* ids, uint32_t m, double tmin,
                        RayHit& hit, uint64_t& tests) {
  tests += m;
  testTriangles<Test>(mesh, o, d, ids, m, tmin, hit.t, [&](uint32_t k, double t, double u, double v) {
    hit.offer(ids[k], t, u, v);
    return false;
  });
}
template <TriangleTest Test>
inline bool anyInList(const TriangleMesh& mesh, Vec3 o, Vec3 d, const uint32_t* ids, uint32_t m, double tmin,
                      double tmax, uint64_t& tests) {
  uint32_t at = 0;
  const bool found = testTriangles<Test>(mesh, o, d, ids, m, tmin, tmax, [&](uint32_t k, double, double, double) {
    at = k;
    return true;
  });
  tests += found ? at + 1 : m;
  return found;
}

/// Closest hit with t in [tmin, tmax]. Returns whether anything was hit. `Test` picks the
/// ray/triangle test (intersect.h); the default is the engine's Moller-Trumbore.
template <TriangleTest Test = TriangleTest::MollerTrumbore>
inline bool intersectFirst(const MatrixTree& tree, const TriangleMesh& mesh, Vec3 o, Vec3 d, double tmin,
                           double tmax, RayHit& hit, TraversalStats* st = nullptr) {
  hit = RayHit{};
  hit.t = tmax;
  uint64_t tests = 0;
  RayMailbox mb;
  tree.traverseRay(
      o, d, tmin, tmax,
      [&](const uint32_t* prims, uint32_t count, double /*tEnter*/, double tExit) {
        forUntested(mb, prims, count, [&](const uint32_t* ids, uint32_t m) {
          firstInList<Test>(mesh, o, d, ids, m, tmin, hit, tests);
          return false;
        });
        // A hit inside this node (t <= tExit) cannot be beaten by a later node.
        return hit.prim != MT_NULL && hit.t <= tExit;
      },
      st);
  if (st) st->primTests += tests;
  if (!hit.hit()) hit.t = std::numeric_limits<double>::infinity();
  return hit.hit();
}

/// Any hit with t in [tmin, tmax] (shadow rays): stops at the first one found.
template <TriangleTest Test = TriangleTest::MollerTrumbore>
inline bool intersectAny(const MatrixTree& tree, const TriangleMesh& mesh, Vec3 o, Vec3 d, double tmin,
                         double tmax, TraversalStats* st = nullptr) {
  bool found = false;
  uint64_t tests = 0;
  RayMailbox mb;
  tree.traverseRay(
      o, d, tmin, tmax,
      [&](const uint32_t* prims, uint32_t count, double, double) {
        return forUntested(mb, prims, count, [&](const uint32_t* ids, uint32_t m) {
          return found = anyInList<Test>(mesh, o, d, ids, m, tmin, tmax, tests);
        });
      },
      st);
  if (st) st->primTests += tests;
  return found;
}

/// Reference: test every triangle.
inline bool intersectFirstBruteForce(const TriangleMesh& mesh, Vec3 o, Vec3 d, double tmin, double tmax,
                                     RayHit& hit) {
  hit = RayHit{};
  hit.t = tmax;
  for (size_t id = 0; id < mesh.size(); ++id) {
    double t, u, v;
    if (rayTriangleMT(o, d, mesh.vertex(id, 0), mesh.vertex(id, 1), mesh.vertex(id, 2), tmin, hit.t, t, u, v))
      hit.offer(static_cast<uint32_t>(id), t, u, v);
  }
  if (!hit.hit()) hit.t = std::numeric_limits<double>::infinity();
  return hit.hit();
}

}  // namespace mtree

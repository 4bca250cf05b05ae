// Rays traced in batches: the production path of render() (render.h), the VTK ray caster and the
// batched ray queries. A batch hands the tracer many independent rays at once, so that
//   - the matrix tree's walk keeps several rays in flight on one core (TraceTuning::inFlight):
//     each ray is walked exactly as alone (MatrixTree::TableWalk, one step at a time: the same
//     nodes, the same leaves, the same hits; test_rays BatchWalkIsTheSingleRayWalk), but the
//     steps of different rays are independent, so the core overlaps one ray's dependent loads
//     and plane tests with another's instead of waiting on each;
//   - the leaf tests run W triangles per SIMD step on the pre-gathered payload (leaf_test.h,
//     leaf_triangles.h), with the width chosen at run time (TraceTuning::simd, clamped to
//     simdSupported());
//   - counting is a compile-time choice made once per batch: without counter arrays the walks
//     compile without counters, with them the same walks count (render()'s per-pixel counts).
// Without a payload (null) the leaf tests read the mesh through the ids with a per-ray mailbox
// (raycast.h's intersectFirst / intersectAny): the memory-saving setting, same answers.
//
// Answers: first hits are intersectFirst's (nearest t in [tmin, tmax], ties to the smaller id;
// t = +inf and prim = MT_NULL where nothing is hit); any-hit answers are intersectAny's.
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>

#include "mtree/core/matrix_tree.h"
#include "mtree/rays/intersect.h"
#include "mtree/rays/leaf_test.h"
#include "mtree/rays/leaf_triangles.h"
#include "mtree/rays/raycast.h"
#include "mtree/rays/sah_kdtree.h"

namespace mtree {

/// n rays o[i] + t d[i], t in [tmin[i], tmax[i]] (tmin null: 0 for every ray; tmax null: +inf).
struct RayBatch {
  const Vec3* o = nullptr;
  const Vec3* d = nullptr;
  const double* tmin = nullptr;
  const double* tmax = nullptr;
  size_t n = 0;
  double tMin(size_t i) const { return tmin ? tmin[i] : 0.0; }
  double tMax(size_t i) const { return tmax ? tmax[i] : std::numeric_limits<double>::infinity(); }
};

/// Per-ray counters, added to (null: not counted, and not compiled into the walk).
struct RayCounters {
  uint32_t* visits = nullptr;  // node visits: matrix walk steps (one step-table byte each), SAH nodes
  uint32_t* tests = nullptr;   // ray/triangle tests
  bool on() const { return visits != nullptr; }
};

/// How the batch tracers run. An unwrapped tuning struct for benchmarks and tests; the defaults
/// are the production path.
struct TraceTuning {
  /// The widest leaf test allowed (clamped to simdSupported()).
  Simd simd = Simd::Avx2;
  /// Rays walked at once per core by the matrix tree's table walk: 1, 2, 4 or 8 (others round
  /// down to one of these).
  int inFlight = 4;
};

/// First hits of a batch through a matrix tree over `mesh`. `payload`: the tree's
/// LeafTriangles (built from tree.primitiveIndices() over this mesh), or null.
void traceFirst(const MatrixTree& tree, const TriangleMesh& mesh, const LeafTriangles* payload, TriangleTest test,
                const RayBatch& rays, RayHit* hits, RayCounters counters = {}, const TraceTuning& tuning = {});
/// Any hit (shadow rays): blocked[i] = 1 if ray i hits a triangle with t in [tmin, tmax[i]].
void traceAny(const MatrixTree& tree, const TriangleMesh& mesh, const LeafTriangles* payload, TriangleTest test,
              const RayBatch& rays, uint8_t* blocked, RayCounters counters = {}, const TraceTuning& tuning = {});
/// The same through the SAH kd-tree and one of its traversals (payload: built from
/// tree.primitiveIndices(), or null). The SAH walks take one ray at a time.
void traceFirst(const SahKdTree& tree, SahTraversal traversal, int shortStack, const TriangleMesh& mesh,
                const LeafTriangles* payload, TriangleTest test, const RayBatch& rays, RayHit* hits,
                RayCounters counters = {}, const TraceTuning& tuning = {});
void traceAny(const SahKdTree& tree, SahTraversal traversal, int shortStack, const TriangleMesh& mesh,
              const LeafTriangles* payload, TriangleTest test, const RayBatch& rays, uint8_t* blocked,
              RayCounters counters = {}, const TraceTuning& tuning = {});

}  // namespace mtree

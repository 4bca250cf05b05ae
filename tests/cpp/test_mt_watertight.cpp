// The matrix trees with the watertight ray/triangle test (Woop, Benthin & Wald 2013): the same
// first hits as a watertight brute force on the real meshes, and no ray through a shared edge or
// vertex of a closed sphere slips through (the tree's leaves hold every triangle touching their
// closed box, so the walk must not lose what the test keeps).
#include "test_util.h"

#include <string>

#include "mtree/rays/intersect.h"
#include "mtree/rays/render.h"

namespace {

using mtest::Ray;
using mtree::RayHit;
using mtree::TriangleMesh;
using mtree::TriangleTest;
using mtree::Vec3;
constexpr double kInf = std::numeric_limits<double>::infinity();

RayHit bruteWatertight(const TriangleMesh& mesh, const Ray& r) {
  RayHit best;
  best.t = r.tmax;
  for (size_t id = 0; id < mesh.size(); ++id) {
    double t, u, v;
    if (mtree::rayTriangleWatertight(r.o, r.d, mesh.vertex(id, 0), mesh.vertex(id, 1), mesh.vertex(id, 2), r.tmin,
                                     best.t, t, u, v) &&
        (t < best.t || (t == best.t && id < best.prim))) {
      best.t = t;
      best.prim = static_cast<uint32_t>(id);
    }
  }
  if (!best.hit()) best.t = kInf;
  return best;
}

mtree::MatrixTree buildTree(const TriangleMesh& mesh, mtree::TreeKind kind) {
  mtree::BuildOptions bo;
  bo.kind = kind;
  mtree::MatrixTree tree;
  mtree::MatrixTreeBuilder<TriangleMesh>::build(mesh, bo, tree, nullptr);
  return tree;
}

// The rays traced as one batch (the renderer's path), first hits or any hits up to tmax[i].
struct BatchRays {
  std::vector<Vec3> o, d;
  std::vector<double> tmin, tmax;
  explicit BatchRays(const std::vector<Ray>& rays) {
    for (const Ray& r : rays) {
      o.push_back(r.o);
      d.push_back(r.d);
      tmin.push_back(r.tmin);
      tmax.push_back(r.tmax);
    }
  }
  mtree::RayBatch batch() const {
    mtree::RayBatch b;
    b.o = o.data();
    b.d = d.data();
    b.tmin = tmin.data();
    b.tmax = tmax.data();
    b.n = o.size();
    return b;
  }
};

class RealMeshWatertight : public ::testing::TestWithParam<std::string> {};

TEST_P(RealMeshWatertight, FirstHitsEqualWatertightBruteForce) {
  const TriangleMesh mesh = mtest::loadRealMesh(GetParam());
  const std::vector<Ray> rays = mtest::aimedRays(mesh, 1500, mtest::seedFor("mt-watertight", mesh.size()));
  std::vector<RayHit> ref(rays.size());
#pragma omp parallel for schedule(dynamic, 16)
  for (int64_t i = 0; i < static_cast<int64_t>(rays.size()); ++i) ref[i] = bruteWatertight(mesh, rays[i]);
  // The shadow rays: up to just past the hit, which must find something.
  std::vector<Ray> shadow;
  for (size_t i = 0; i < rays.size(); ++i)
    if (ref[i].hit()) {
      Ray r = rays[i];
      r.tmax = ref[i].t * (1 + 1e-9) + 1e-300;
      shadow.push_back(r);
    }
  const BatchRays primary(rays), shadows(shadow);
  for (auto kind : {mtree::TreeKind::Octree, mtree::TreeKind::RegularKd}) {
    const mtree::MatrixTree tree = buildTree(mesh, kind);
    mtree::LeafTriangles payload;
    payload.build(tree.primitiveIndices().data(), tree.primitiveIndices().size(), mesh, 0);
    // With the pre-gathered leaf triangles (SIMD) and without them (the mesh through the ids).
    for (const mtree::LeafTriangles* p : {static_cast<const mtree::LeafTriangles*>(&payload), static_cast<const mtree::LeafTriangles*>(nullptr)}) {
      SCOPED_TRACE(std::string(mtree::treeKindName(kind)) + (p ? ", payload" : ", mesh"));
      const mtree::MatrixTreeTracer tracer{tree, mesh, TriangleTest::Watertight, p};
      std::vector<RayHit> got(rays.size());
      tracer.first(primary.batch(), got.data(), {});
      std::vector<uint8_t> blocked(shadow.size());
      tracer.any(shadows.batch(), blocked.data(), {});
      int wrong = 0, anyWrong = 0;
      for (size_t i = 0; i < rays.size(); ++i) {
        const RayHit& h = got[i];
        // same triangle, or the same t (a tie on a shared edge goes to the smaller id in both)
        if (h.prim != ref[i].prim && !(h.hit() && ref[i].hit() && h.t == ref[i].t)) ++wrong;
      }
      for (uint8_t b : blocked) anyWrong += !b;
      EXPECT_EQ(wrong, 0) << GetParam();
      EXPECT_EQ(anyWrong, 0) << GetParam();
    }
  }
}

INSTANTIATE_TEST_SUITE_P(RealMeshes, RealMeshWatertight, ::testing::ValuesIn(mtest::realMeshes()),
                         [](const ::testing::TestParamInfo<std::string>& info) { return mtest::meshTag(info.param); });

TEST(MatrixTreeWatertight, NoRayFallsThroughEdgesOrVerticesOfClosedSpheres) {
  struct Sphere {
    int subdiv;
    double radius;
    Vec3 center;
  };
  const Sphere spheres[] = {{4, 1.0, Vec3(0, 0, 0)}, {3, 0.37, Vec3(3.1, -7.3, 11.9)}, {5, 2.5, Vec3(1e3, -2e3, 5e2)}};
  for (const Sphere& sp : spheres) {
    const TriangleMesh mesh = mtest::makeIcosphere(sp.subdiv, sp.radius, sp.center);
    mtest::Rng rng(mtest::seedFor("mt-leaks", sp.subdiv));
    const int n = 4000;
    const std::vector<Ray> rays = mtest::edgeAndVertexRays(mesh, sp.center, sp.radius, n, rng);
    for (auto kind : {mtree::TreeKind::Octree, mtree::TreeKind::RegularKd}) {
      const mtree::MatrixTree tree = buildTree(mesh, kind);
      mtree::LeafTriangles payload;
      payload.build(tree.primitiveIndices().data(), tree.primitiveIndices().size(), mesh, 0);
      std::vector<Ray> open = rays;
      for (Ray& r : open) {
        r.tmin = 0;
        r.tmax = kInf;
      }
      const BatchRays batch(open);
      for (const mtree::LeafTriangles* p : {static_cast<const mtree::LeafTriangles*>(&payload), static_cast<const mtree::LeafTriangles*>(nullptr)}) {
        const mtree::MatrixTreeTracer wt{tree, mesh, TriangleTest::Watertight, p};
        const mtree::MatrixTreeTracer mt{tree, mesh, TriangleTest::MollerTrumbore, p};
        std::vector<RayHit> hw(open.size()), hm(open.size());
        wt.first(batch.batch(), hw.data(), {});
        mt.first(batch.batch(), hm.data(), {});
        int wtLeaks = 0, mtLeaks = 0;
        for (size_t i = 0; i < open.size(); ++i) {
          wtLeaks += !hw[i].hit();
          mtLeaks += !hm[i].hit();
        }
        EXPECT_EQ(wtLeaks, 0) << mtree::treeKindName(kind) << ", sphere subdiv " << sp.subdiv << (p ? ", payload" : ", mesh");
        std::printf("[ info ] %s, icosphere %d, %s: Moller-Trumbore lets %d of %d rays through, watertight %d\n",
                    mtree::treeKindName(kind), sp.subdiv, p ? "payload" : "mesh", mtLeaks, n, wtLeaks);
      }
    }
  }
}

}  // namespace

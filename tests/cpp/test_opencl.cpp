// The OpenCL back end against the CPU engine (the reference), on the first OpenCL device
// ($MATRIXTREE_OPENCL_DEVICE picks another; PoCL on the CI machine):
//   build   every §5.1 kernel through a whole build: identical trees (height, level shapes, root
//           box, every level's pointer matrix as the device computed it and as the host copy
//           holds it, every block, every leaf range, the triangle order), real meshes, both
//           tree kinds, exact and bounding-box overlap, explicit heights and block edges;
//   rays    first hits (same triangle, t within 1e-6 relative) and shadow rays (same answer);
//   points  batched leaf finding (same level, node and existence);
//   errors  an empty mesh, a bad device selector, a query before upload.
// Every test is skipped, with the reason printed, when the machine has no OpenCL device.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "mtree/device/opencl.h"
#include "opencl_test_util.h"
#include "test_util.h"

namespace {

using mtree::BuildOptions;
using mtree::MatrixTree;
using mtree::TreeKind;
using mtree::Vec3;
namespace ocl = mtree::ocl;


/// Asserts that the CPU and the device trees are the same, array for array, and that the
/// pointer matrices the device computed are the host copy's.
void expectSameTree(const MatrixTree& cpu, const MatrixTree& gpu, const ocl::Builder* b, const std::string& what) {
  mtest::expectSameTree(cpu, gpu, what, b && !b->devicePointers().empty() ? &b->devicePointers() : nullptr);
}

class OpenCLMesh : public ::testing::TestWithParam<std::string> {};

// One build per kind and mode, then the queries on the tree the device built.
TEST_P(OpenCLMesh, BuildRaysAndPointsMatchTheCpuEngine) {
  REQUIRE_DEVICE(ctx);
  const std::string rel = GetParam();
  const mtree::TriangleMesh mesh = mtest::loadRealMesh(rel);
  ocl::Builder builder(ctx);
  builder.keepDevicePointers(true);
  ocl::Tracer tracer(ctx);
  const auto rays = mtest::aimedRays(mesh, 4000, mtest::seedFor(rel, 7));
  for (TreeKind kind : {TreeKind::Octree, TreeKind::RegularKd}) {
    for (mtree::OverlapMode mode : {mtree::OverlapMode::Exact, mtree::OverlapMode::BoundingBox}) {
      if (kind == TreeKind::RegularKd && mode == mtree::OverlapMode::BoundingBox) continue;
      BuildOptions opt = mtest::options(kind);
      opt.overlap = mode;
      mtree::BuildStats cs, gs;
      const MatrixTree cpu = mtest::buildTree(mesh, opt, &cs);
      MatrixTree gpu;
      builder.build(mesh, opt, gpu, &gs);
      const std::string what = mtest::meshTag(rel) + " " + mtree::treeKindName(kind) +
                               (mode == mtree::OverlapMode::Exact ? " exact" : " bbox");
      expectSameTree(cpu, gpu, &builder, what);
      EXPECT_EQ(cs.references, gs.references);
      EXPECT_EQ(cs.leaves, gs.leaves);
      if (mode != mtree::OverlapMode::Exact) continue;

      // Rays: the aimed set plus rays starting on leaf planes and running inside them.
      std::vector<double> o, d;
      for (const auto& r : rays)
        for (int a = 0; a < 3; ++a) o.push_back(r.o[a]), d.push_back(r.d[a]);
      mtest::Rng rng(mtest::seedFor(rel, 11));
      const int H = gpu.height();
      for (int i = 0; i < 1000; ++i) {
        Vec3 p = rng.inBox(gpu.rootBox()), dir = rng.direction();
        const int a = static_cast<int>(rng.below(3));
        const int cells = gpu.dim(H, a);
        p[a] = gpu.rootBox().lo[a] + rng.below(static_cast<uint32_t>(cells)) * gpu.cellSize(H)[a];
        dir[a] = 0;
        for (int k = 0; k < 3; ++k) o.push_back(p[k]), d.push_back(dir[k]);
      }
      const size_t n = o.size() / 3;
      tracer.upload(gpu, mesh);
      for (double tmax : {std::numeric_limits<double>::infinity(), 0.5}) {
        std::vector<double> t(n);
        std::vector<uint32_t> prim(n);
        std::vector<uint8_t> any(n);
        uint64_t visits = 0, tests = 0;
        tracer.intersectFirst(o.data(), d.data(), n, 0.0, tmax, t.data(), prim.data(), &visits, &tests);
        tracer.intersectAny(o.data(), d.data(), n, 0.0, tmax, any.data());
        size_t badPrim = 0, badT = 0, badAny = 0, hits = 0;
        mtree::TraversalStats st;
        for (size_t i = 0; i < n; ++i) {
          const Vec3 ro(&o[3 * i]), rd(&d[3 * i]);
          mtree::RayHit h;
          const bool hit = mtree::intersectFirst(cpu, mesh, ro, rd, 0.0, tmax, h, &st);
          hits += hit;
          if (h.prim != prim[i]) ++badPrim;
          else if (hit && !(std::fabs(t[i] - h.t) <= 1e-6 * std::fabs(h.t))) ++badT;
          if (mtree::intersectAny(cpu, mesh, ro, rd, 0.0, tmax) != (any[i] != 0)) ++badAny;
        }
        EXPECT_EQ(badPrim, 0u) << what << ": first-hit triangles differ (tmax " << tmax << ")";
        EXPECT_EQ(badT, 0u) << what << ": hit distances differ";
        EXPECT_EQ(badAny, 0u) << what << ": shadow rays differ";
        // Counters are not compared one for one: the CPU walker's bookkeeping (mailboxes, how
        // it brackets the neighbour search) may change without changing any answer.
        EXPECT_GE(visits, n / 2) << what;
        EXPECT_GT(tests, 0u) << what;
        if (tmax > 1) {
          EXPECT_GT(hits, n / 4) << what << ": the aimed rays should mostly hit";
        }
      }

      // Points: inside, on leaf corners, and outside the root box.
      std::vector<double> pts;
      const mtree::Box wide = mtest::enlarged(gpu.rootBox(), 0.1);
      for (int i = 0; i < 6000; ++i) {
        Vec3 p = rng.inBox(i % 3 ? gpu.rootBox() : wide);
        if (i % 5 == 0) p = mtest::pointOn(mesh, rng.below(static_cast<uint32_t>(mesh.size())), rng);
        for (int k = 0; k < 3; ++k) pts.push_back(p[k]);
      }
      const size_t np = pts.size() / 3;
      std::vector<int32_t> loc(5 * np);
      tracer.findLeaves(pts.data(), np, loc.data());
      size_t badLoc = 0;
      for (size_t i = 0; i < np; ++i) {
        const mtree::NodeRef r = cpu.leafFind(Vec3(&pts[3 * i]));
        const int32_t* g = &loc[5 * i];
        if (r.level != g[0] || (r.level >= 0 && (r.c[0] != g[1] || r.c[1] != g[2] || r.c[2] != g[3] ||
                                                 int(r.exists) != g[4])))
          ++badLoc;
      }
      EXPECT_EQ(badLoc, 0u) << what << ": located leaves differ";
    }
  }
}

INSTANTIATE_TEST_SUITE_P(opencl, OpenCLMesh, ::testing::ValuesIn(mtest::realMeshes()),
                         [](const auto& info) { return mtest::meshTag(info.param); });

// Explicit heights (deep and shallow), every block edge from 1 to 32, a flat mesh: each build
// exercises the scans over many tiles, several radix passes and the one-entry blocks.
TEST(opencl, ExplicitHeightsAndBlockEdgesGiveIdenticalTrees) {
  REQUIRE_DEVICE(ctx);
  const mtree::TriangleMesh sphere = mtest::makeIcosphere(4);
  ocl::Builder builder(ctx);
  builder.keepDevicePointers(true);
  for (TreeKind kind : {TreeKind::Octree, TreeKind::RegularKd})
    for (int height : {1, 3, 7})
      for (int edge : {1, 4, 32}) {
        const BuildOptions opt = mtest::options(kind, kind == TreeKind::RegularKd ? 3 * height : height, edge);
        MatrixTree gpu;
        builder.build(sphere, opt, gpu);
        expectSameTree(mtest::buildTree(sphere, opt), gpu, &builder,
                       std::string(mtree::treeKindName(kind)) + " H=" + std::to_string(opt.height) +
                           " B=" + std::to_string(edge));
      }
  // A flat square of two triangles, and a single triangle.
  const mtree::TriangleMesh flat({0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0}, {0, 1, 2, 0, 2, 3});
  const mtree::TriangleMesh one({0, 0, 0, 1, 0, 0, 0, 1, 0.5}, {0, 1, 2});
  for (const auto* m : {&flat, &one}) {
    MatrixTree gpu;
    builder.build(*m, BuildOptions{}, gpu);
    expectSameTree(mtest::buildTree(*m, BuildOptions{}), gpu, &builder, "tiny mesh");
  }
}

TEST(opencl, RebuildAfterMovingPointsReusesBuffersAndMatches) {
  REQUIRE_DEVICE(ctx);
  mtree::TriangleMesh mesh = mtest::makeIcosphere(5);
  ocl::Builder builder(ctx);
  MatrixTree gpu;
  for (int frame = 0; frame < 3; ++frame) {
    std::vector<double> p = mesh.points();
    for (size_t i = 0; i < p.size(); i += 3) p[i] *= 1.0 + 0.3 * frame;  // stretch along x
    mesh.setPoints(p);
    builder.build(mesh, BuildOptions{}, gpu);
    expectSameTree(mtest::buildTree(mesh, BuildOptions{}), gpu, nullptr, "frame " + std::to_string(frame));
  }
}

TEST(opencl, EmptyMeshGivesAnEmptyTreeAndMisses) {
  REQUIRE_DEVICE(ctx);
  const mtree::TriangleMesh empty;
  ocl::Builder builder(ctx);
  MatrixTree gpu;
  builder.build(empty, BuildOptions{}, gpu);
  EXPECT_TRUE(gpu.empty());
  ocl::Tracer tracer(ctx);
  tracer.upload(gpu, empty);
  const double o[3] = {0, 0, 0}, d[3] = {1, 0, 0};
  double t = 0;
  uint32_t prim = 0;
  tracer.intersectFirst(o, d, 1, 0, 1e30, &t, &prim);
  EXPECT_EQ(prim, MT_NULL);
  EXPECT_TRUE(std::isinf(t));
  int32_t loc[5];
  tracer.findLeaves(o, 1, loc);
  EXPECT_EQ(loc[0], -1);
}

TEST(opencl, ErrorsAreClearNotCrashes) {
  REQUIRE_DEVICE(ctx);
  try {
    ocl::Context::create("no such device anywhere");
    ADD_FAILURE() << "a bad selector must throw";
  } catch (const ocl::Error& e) {
    EXPECT_NE(std::string(e.what()).find("no device matches"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find(ctx->device().name), std::string::npos) << "should list the devices";
  }
  ocl::Tracer tracer(ctx);
  const double o[3] = {0, 0, 0};
  int32_t loc[5];
  EXPECT_THROW(tracer.findLeaves(o, 1, loc), ocl::Error);
  ocl::Builder builder(ctx);
  MatrixTree gpu;
  BuildOptions bad;
  bad.blockEdge = 3;
  EXPECT_THROW(builder.build(mtest::makeIcosphere(1), bad, gpu), std::invalid_argument);
  EXPECT_TRUE(gpu.empty());
}

}  // namespace

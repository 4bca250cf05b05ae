// The stackless derived-parent traversal of the implicit split-plane trees as an OpenCL kernel
// (opencl/trees.cl, engine/include/mtree/device/opencl_trees.h), against the CPU's Backtrack
// traversal: for the implicit kd-tree built from the SAH tree and for the implicit BSP tree, on
// seeded rays (test_implicit_kd's) and on a render's primary and shadow rays, every first hit must
// be the CPU's to the bit (triangle and t), every any-hit answer the CPU's, and the summed node
// visits and triangle tests the CPU's. Empty trees, bad calls (no upload), and rays that miss the
// root box. Skipped, with the reason, without an OpenCL device.
#include <gtest/gtest.h>

#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include "mtree/device/opencl_render.h"
#include "mtree/device/opencl_trees.h"
#include "mtree/rays/render.h"
#include "mtree/rays/sah_kdtree.h"
#include "mtree/trees/bsp_builder.h"
#include "mtree/trees/implicit_tree.h"
#include "opencl_test_util.h"
#include "test_util.h"
#include "trees_test_util.h"

namespace {

using mtest::Ray;
using mtree::ImplicitSplitTree;
using mtree::PointerSplitTree;
using mtree::RayHit;
using mtree::SplitTraversal;
using mtree::TraversalStats;
using mtree::TriangleMesh;
using mtree::Vec3;

// The device's answers for rays (tmin, tmax common to the batch: each ray is run alone when they
// differ) against the CPU Backtrack traversal's.
void expectDeviceEqualsCpu(mtree::ocl::SplitTreeTracer& dev, const ImplicitSplitTree& tree, const TriangleMesh& mesh,
                           const std::vector<Ray>& rays) {
  const size_t n = rays.size();
  std::vector<double> o(3 * n), d(3 * n), t(n);
  std::vector<uint32_t> prim(n);
  std::vector<uint8_t> any(n);
  for (size_t i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k) {
      o[3 * i + k] = rays[i].o[k];
      d[3 * i + k] = rays[i].d[k];
    }
  const double inf = std::numeric_limits<double>::infinity();
  uint64_t visits = 0, tests = 0, aVisits = 0, aTests = 0;
  dev.intersectFirst(o.data(), d.data(), n, 0.0, inf, t.data(), prim.data(), &visits, &tests);
  dev.intersectAny(o.data(), d.data(), n, 0.0, inf, any.data(), &aVisits, &aTests);
  TraversalStats cpu, cpuAny;
  uint64_t primDiffer = 0, tDiffer = 0, anyDiffer = 0, hits = 0;
  for (size_t i = 0; i < n; ++i) {
    RayHit h;
    tree.intersectFirst(mesh, rays[i].o, rays[i].d, 0.0, inf, h, SplitTraversal::Backtrack,
                        mtree::TriangleTest::MollerTrumbore, &cpu);
    hits += h.hit();
    primDiffer += h.prim != prim[i];
    tDiffer += std::memcmp(&h.t, &t[i], sizeof(double)) != 0;
    anyDiffer += tree.intersectAny(mesh, rays[i].o, rays[i].d, 0.0, inf, SplitTraversal::Backtrack,
                                   mtree::TriangleTest::MollerTrumbore, &cpuAny) != (any[i] != 0);
  }
  EXPECT_EQ(primDiffer, 0u);
  EXPECT_EQ(tDiffer, 0u);
  EXPECT_EQ(anyDiffer, 0u);
  EXPECT_EQ(visits, cpu.nodeVisits);
  EXPECT_EQ(tests, cpu.primTests);
  EXPECT_EQ(aVisits, cpuAny.nodeVisits);
  EXPECT_EQ(aTests, cpuAny.primTests);
  EXPECT_GT(hits, n / 4);
}

class OpenCLSplitTrees : public ::testing::TestWithParam<std::string> {};

TEST_P(OpenCLSplitTrees, KdAndBspEqualTheCpu) {
  REQUIRE_DEVICE(ctx);
  const std::string rel = GetParam();
  const TriangleMesh mesh = mtest::loadRealMesh(rel);
  mtree::ocl::SplitTreeTracer dev(ctx);
  {
    SCOPED_TRACE("implicit kd-tree");
    const PointerSplitTree p = mtree::pointerTreeOf(mtree::SahKdTree(mesh));
    ImplicitSplitTree tree;
    tree.build(p, mesh);
    dev.upload(tree, mesh);
    EXPECT_GT(dev.deviceTreeBytes(), tree.nodeBytes());
    expectDeviceEqualsCpu(dev, tree, mesh, mtest::splitTreeRays(mesh, p, 6000, mtest::seedFor(rel, 13)));
    // A render's rays: primary and shadow rays, pixel by pixel.
    const mtree::Box box = mtest::meshBounds(mesh);
    mtree::Camera cam;
    cam.width = cam.height = 96;
    cam.target = box.center();
    cam.eye = box.center() + Vec3(0.3, 0.4, 1.0) * (2 * mtree::norm(box.extent()));
    mtree::RenderOptions ro;
    const mtree::RenderResult c =
        mtree::render(mtree::ImplicitTreeTracer{tree, mesh, SplitTraversal::Backtrack}, mesh, box, cam, ro);
    const mtree::RenderResult g = mtree::renderOpenCL(dev, mesh, box, cam, ro);
    EXPECT_EQ(c.hitPrim, g.hitPrim);
    EXPECT_EQ(c.depth, g.depth);
    EXPECT_EQ(c.rgb, g.rgb) << "the shadow rays differ";
    EXPECT_GT(c.hits, 0u);
  }
  {
    SCOPED_TRACE("implicit BSP tree");
    mtree::BspBuildOptions bo;
    bo.maxDepth = 14;  // a quick build: the traversal is what is compared
    const PointerSplitTree p = mtree::buildBspTree(mesh, bo);
    ImplicitSplitTree tree;
    tree.build(p, mesh);
    dev.upload(tree, mesh);
    expectDeviceEqualsCpu(dev, tree, mesh, mtest::splitTreeRays(mesh, p, 4000, mtest::seedFor(rel, 19)));
  }
}

INSTANTIATE_TEST_SUITE_P(Meshes, OpenCLSplitTrees,
                         ::testing::Values("scenes/utah_hand/hand_00.obj", "meshes/bunny.ply"),
                         [](const ::testing::TestParamInfo<std::string>& info) {
                           return mtest::meshTag(info.param);
                         });

TEST(OpenCLSplitTree, EmptyTreesAndMissingUploads) {
  REQUIRE_DEVICE(ctx);
  mtree::ocl::SplitTreeTracer dev(ctx);
  const double o[3] = {0, 0, -1}, d[3] = {0, 0, 1};
  double t = 0;
  uint32_t prim = 0;
  EXPECT_THROW(dev.intersectFirst(o, d, 1, 0, 10, &t, &prim), mtree::ocl::Error);
  const TriangleMesh none;
  ImplicitSplitTree empty;
  empty.build(mtree::pointerTreeOf(mtree::SahKdTree(none)), none);
  dev.upload(empty, none);
  dev.intersectFirst(o, d, 1, 0, 10, &t, &prim);
  EXPECT_EQ(prim, MT_NULL);
  EXPECT_EQ(t, std::numeric_limits<double>::infinity());
  uint8_t hit = 1;
  dev.intersectAny(o, d, 1, 0, 10, &hit);
  EXPECT_EQ(hit, 0);
  // One triangle: a hit, a miss beside it, a ray pointing away, a NaN origin.
  const TriangleMesh one({0, 0, 0, 1, 0, 0, 0, 1, 0}, {0, 1, 2});
  ImplicitSplitTree tree;
  tree.build(mtree::pointerTreeOf(mtree::SahKdTree(one)), one);
  dev.upload(tree, one);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double os[12] = {0.2, 0.2, -1, 0.8, 0.8, -1, 0.2, 0.2, -1, nan, 0, 0};
  const double ds[12] = {0, 0, 1, 0, 0, 1, 0, 0, -1, 0, 0, 1};
  double ts[4];
  uint32_t ps[4];
  dev.intersectFirst(os, ds, 4, 0, 10, ts, ps);
  EXPECT_EQ(ps[0], 0u);
  EXPECT_EQ(ts[0], 1.0);
  EXPECT_EQ(ps[1], MT_NULL);
  EXPECT_EQ(ps[2], MT_NULL);
  EXPECT_EQ(ps[3], MT_NULL);
}

}  // namespace

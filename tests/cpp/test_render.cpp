// render() through MatrixTreeTracer, against analytic answers for a sphere (the projected disc,
// the depth at the centre), against the same renderer driven by a brute-force tracer (every
// pixel, shadows included), and the per-pixel counters against the rays that enter the root box.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "mtree/rays/render.h"
#include "test_util.h"

namespace {

using mtree::Box;
using mtree::Camera;
using mtree::MatrixTree;
using mtree::RayHit;
using mtree::RenderOptions;
using mtree::RenderResult;
using mtree::TreeKind;
using mtree::TriangleMesh;
using mtree::Vec3;

const TreeKind kKinds[2] = {TreeKind::Octree, TreeKind::RegularKd};

// The tracer interface of render(), answered by testing every triangle.
struct BruteForceTracer {
  const mtest::BruteForce& bf;
  bool first(Vec3 o, Vec3 d, double tmin, double tmax, RayHit& h, mtree::TraversalStats*) const {
    mtest::Ray r;
    r.o = o, r.d = d, r.tmin = tmin, r.tmax = tmax;
    h = bf.first(r);
    return h.hit();
  }
  bool any(Vec3 o, Vec3 d, double tmin, double tmax, mtree::TraversalStats* st) const {
    RayHit h;
    return first(o, d, tmin, tmax, h, st);
  }
};

// Primary ray direction of pixel (x, y), written exactly as render() computes it.
Vec3 primaryDirection(const Camera& cam, int x, int y) {
  const Vec3 fwd = mtree::normalized(cam.target - cam.eye);
  Vec3 right = mtree::cross(fwd, cam.up);
  if (mtree::norm(right) == 0)
    right = mtree::cross(fwd, std::fabs(fwd.y) < 0.9 ? Vec3(0, 1, 0) : Vec3(1, 0, 0));
  right = mtree::normalized(right);
  const Vec3 up = mtree::cross(right, fwd);
  const double th = std::tan(0.5 * cam.fovyDegrees * M_PI / 180.0);
  const double aspect = double(cam.width) / cam.height;
  const double sx = (2.0 * (x + 0.5) / cam.width - 1.0) * th * aspect;
  const double sy = (2.0 * (y + 0.5) / cam.height - 1.0) * th;
  return mtree::normalized(fwd + right * sx + up * sy);
}

Camera sphereCamera(double distance) {
  Camera cam;
  cam.eye = Vec3(0, 0, distance);
  cam.target = Vec3(0, 0, 0);
  cam.up = Vec3(0, 1, 0);
  cam.fovyDegrees = 30;
  cam.width = cam.height = 201;  // odd: the centre pixel's ray is the optical axis
  return cam;
}

TEST(Render, SphereCoverageDepthAndCounters) {
  const double R = 1.0, D = 5.0;
  const TriangleMesh sphere = mtest::makeIcosphere(5, R);  // 20480 triangles
  const Camera cam = sphereCamera(D);
  const int W = cam.width, Hh = cam.height;
  // The silhouette of a sphere seen from distance D is a cone of half-angle asin(R / D); on the
  // image plane at distance 1 a disc of radius tan(alpha). Image plane half-height: tan(fovy/2).
  const double tanA = R / std::sqrt(D * D - R * R);
  const double th = std::tan(0.5 * cam.fovyDegrees * M_PI / 180.0);
  const double aspect = double(W) / Hh;
  const double discFraction = M_PI * tanA * tanA / (4 * th * th * aspect);
  for (TreeKind kind : kKinds) {
    SCOPED_TRACE(mtree::treeKindName(kind));
    const MatrixTree tree = mtest::buildTree(sphere, mtest::options(kind));
    mtree::LeafTriangles payload;
    payload.build(tree.primitiveIndices().data(), tree.primitiveIndices().size(), sphere, 0);
    const mtree::MatrixTreeTracer tracer{tree, sphere, mtree::TriangleTest::MollerTrumbore, &payload};
    RenderOptions opt;
    opt.counters = true;
    const RenderResult img = mtree::render(tracer, sphere, mtest::meshBounds(sphere), cam, opt);
    // Without counters (the walks compiled without them): the same image, and no counts.
    RenderOptions uncounted = opt;
    uncounted.counters = false;
    const RenderResult plain = mtree::render(tracer, sphere, mtest::meshBounds(sphere), cam, uncounted);
    EXPECT_TRUE(plain.rgb == img.rgb && plain.hitPrim == img.hitPrim && plain.depth == img.depth);
    EXPECT_EQ(plain.stats.nodeVisits + plain.stats.primTests, 0u);
    uint64_t plainCounts = 0;
    for (size_t p = 0; p < plain.nodeVisits.size(); ++p) plainCounts += plain.nodeVisits[p] + plain.primTests[p];
    EXPECT_EQ(plainCounts, 0u);
    ASSERT_EQ(img.width, W);
    ASSERT_EQ(img.height, Hh);
    ASSERT_EQ(img.rgb.size(), size_t(W) * Hh * 3);
    EXPECT_EQ(img.primaryRays, uint64_t(W) * Hh);

    // Coverage: the fraction of hit pixels is the disc's share of the image.
    const double fraction = double(img.hits) / (double(W) * Hh);
    EXPECT_NEAR(fraction / discFraction, 1.0, 0.01)
        << "hit fraction " << fraction << ", disc " << discFraction;
    std::printf("[render] %s: hit fraction %.5f, analytic disc %.5f (ratio %.5f)\n",
                mtree::treeKindName(kind), fraction, discFraction, fraction / discFraction);
    // Pixel by pixel: no hit outside the disc; a hit everywhere inside it, except within the
    // icosphere's silhouette deficit (< 1e-3 of the radius) of the rim.
    int outsideHits = 0, insideMisses = 0;
    for (int y = 0; y < Hh; ++y)
      for (int x = 0; x < W; ++x) {
        const double sx = (2.0 * (x + 0.5) / W - 1.0) * th * aspect, sy = (2.0 * (y + 0.5) / Hh - 1.0) * th;
        const double rho = std::sqrt(sx * sx + sy * sy);
        const bool hit = img.hitPrim[size_t(y) * W + x] != MT_NULL;
        outsideHits += hit && rho > tanA * (1 + 1e-9);
        insideMisses += !hit && rho < tanA * (1 - 2e-3);
        EXPECT_EQ(hit, std::isfinite(img.depth[size_t(y) * W + x]));
      }
    EXPECT_EQ(outsideHits, 0);
    EXPECT_EQ(insideMisses, 0);

    // The centre pixel looks along the axis and meets the sphere at t = D - R.
    const size_t centre = size_t(Hh / 2) * W + W / 2;
    ASSERT_NE(img.hitPrim[centre], MT_NULL);
    EXPECT_NEAR(img.depth[centre], D - R, 1e-3 * (D - R));

    // Background where missed, shaded (not background) where hit.
    const Vec3 bg = opt.background;
    uint64_t wrongColour = 0;
    for (size_t p = 0; p < size_t(W) * Hh; ++p) {
      bool isBg = true;
      for (int k = 0; k < 3; ++k)
        isBg = isBg && img.rgb[3 * p + k] ==
                           static_cast<uint8_t>(std::min(255.0, std::max(0.0, bg[k] * 255.0 + 0.5)));
      wrongColour += (img.hitPrim[p] == MT_NULL) != isBg;
    }
    EXPECT_EQ(wrongColour, 0u);

    // Counters: node lookups happen exactly for the primary rays that enter the root box;
    // primitive tests only there; every hit tested a primitive. Totals add up.
    uint64_t counterErrors = 0, visits = 0, tests = 0, entering = 0;
    for (int y = 0; y < Hh; ++y)
      for (int x = 0; x < W; ++x) {
        const size_t p = size_t(y) * W + x;
        double t0 = 0, t1 = std::numeric_limits<double>::infinity();
        const bool enters = mtree::rayBox(cam.eye, primaryDirection(cam, x, y), tree.rootBox(), t0, t1);
        entering += enters;
        counterErrors += (img.nodeVisits[p] > 0) != enters;
        counterErrors += img.primTests[p] > 0 && img.nodeVisits[p] == 0;
        counterErrors += img.hitPrim[p] != MT_NULL && img.primTests[p] == 0;
        visits += img.nodeVisits[p];
        tests += img.primTests[p];
      }
    EXPECT_EQ(counterErrors, 0u);
    EXPECT_GT(entering, img.hits) << "the root box is larger than the sphere's disc";
    EXPECT_LT(entering, uint64_t(W) * Hh);
    EXPECT_EQ(visits, img.stats.nodeVisits);
    EXPECT_EQ(tests, img.stats.primTests);

    // A convex object does not shadow itself: shadow rays are cast but change nothing.
    EXPECT_GT(img.shadowRays, 0u);
    RenderOptions noShadows = opt;
    noShadows.shadows = false;
    const RenderResult flat = mtree::render(tracer, sphere, mtest::meshBounds(sphere), cam, noShadows);
    EXPECT_EQ(flat.shadowRays, 0u);
    EXPECT_TRUE(flat.rgb == img.rgb) << "shadow rays found an occluder on a convex sphere";
    EXPECT_TRUE(flat.hitPrim == img.hitPrim);
  }
}

// A sphere with a small sphere between it and the light: the matrix-tree image equals the
// brute-force image pixel by pixel, shadows included.
TEST(Render, MatchesBruteForceTracerWithShadows) {
  const TriangleMesh big = mtest::makeIcosphere(4, 1.0);
  const Camera cam = sphereCamera(5.0);
  // render() puts the light at eye + up * 0.5 diag + right * 0.3 diag, diag = scene box diagonal.
  // Place the occluder on the way from the front of the sphere to that light (the scene box,
  // hence the light, depends on the occluder only weakly; iterate twice).
  Vec3 occ(0.3, 0.5, 2.0);
  TriangleMesh scene;
  for (int it = 0; it < 3; ++it) {
    const TriangleMesh small = mtest::makeIcosphere(3, 0.25, occ);
    std::vector<double> p = big.points();
    std::vector<uint32_t> t = big.triangles();
    const uint32_t base = static_cast<uint32_t>(big.numPoints());
    p.insert(p.end(), small.points().begin(), small.points().end());
    for (uint32_t v : small.triangles()) t.push_back(v + base);
    scene = TriangleMesh(std::move(p), std::move(t));
    const double diag = mtree::norm(mtest::meshBounds(scene).extent());
    const Vec3 light = cam.eye + Vec3(0, 1, 0) * (0.5 * diag) + Vec3(1, 0, 0) * (0.3 * diag);
    const Vec3 front(0, 0, 1);
    occ = front + (light - front) * 0.35;
  }
  const Box sceneBox = mtest::meshBounds(scene);
  const mtest::BruteForce bf(scene);
  const BruteForceTracer brute{bf};
  RenderOptions opt;
  const RenderResult ref = mtree::render(brute, scene, sceneBox, cam, opt);
  RenderOptions noShadows = opt;
  noShadows.shadows = false;
  const RenderResult refFlat = mtree::render(brute, scene, sceneBox, cam, noShadows);
  uint64_t shadowed = 0;
  for (size_t i = 0; i < ref.rgb.size(); ++i) shadowed += ref.rgb[i] != refFlat.rgb[i];
  ASSERT_GT(shadowed, 300u) << "the occluder should cast a visible shadow";
  ASSERT_GT(ref.hits, 10000u);

  for (TreeKind kind : kKinds) {
    SCOPED_TRACE(mtree::treeKindName(kind));
    const MatrixTree tree = mtest::buildTree(scene, mtest::options(kind));
    mtree::LeafTriangles payload;
    payload.build(tree.primitiveIndices().data(), tree.primitiveIndices().size(), scene, 0);
    // The pre-gathered leaf triangles (the default path) and the mesh through the ids.
    for (const mtree::LeafTriangles* pl : {static_cast<const mtree::LeafTriangles*>(&payload),
                                           static_cast<const mtree::LeafTriangles*>(nullptr)}) {
    SCOPED_TRACE(pl ? "payload" : "mesh");
    const RenderResult img = mtree::render(
        mtree::MatrixTreeTracer{tree, scene, mtree::TriangleTest::MollerTrumbore, pl}, scene, sceneBox, cam, opt);
    EXPECT_EQ(img.hits, ref.hits);
    EXPECT_EQ(img.shadowRays, ref.shadowRays);
    uint64_t primDiffers = 0, depthDiffers = 0, colourDiffers = 0;
    for (size_t p = 0; p < img.hitPrim.size(); ++p) {
      if (img.hitPrim[p] != ref.hitPrim[p]) {
        ++primDiffers;  // a tie on a shared edge: same depth, maybe another normal
        depthDiffers += !(std::fabs(img.depth[p] - ref.depth[p]) <= 1e-6f * std::max(1.0f, ref.depth[p]));
        continue;
      }
      depthDiffers +=
          !(img.depth[p] == ref.depth[p] || (std::isinf(img.depth[p]) && std::isinf(ref.depth[p])));
      for (int k = 0; k < 3; ++k) colourDiffers += img.rgb[3 * p + k] != ref.rgb[3 * p + k];
    }
    EXPECT_EQ(depthDiffers, 0u);
    EXPECT_EQ(colourDiffers, 0u) << "same hit, different shading: the shadow rays disagree";
    EXPECT_LE(primDiffers, 10u);
    std::printf("[render] %s: hits %llu, shadow rays %llu, pixels whose triangle differs (same depth) %llu\n",
                mtree::treeKindName(kind), (unsigned long long)img.hits, (unsigned long long)img.shadowRays,
                (unsigned long long)primDiffers);
    }
  }
}

TEST(Render, EmptyImageAndEmptyScene) {
  const TriangleMesh sphere = mtest::makeIcosphere(2);
  const MatrixTree tree = mtest::buildTree(sphere, mtest::options(TreeKind::Octree));
  Camera cam = sphereCamera(5);
  cam.width = 0;
  const RenderResult none =
      mtree::render(mtree::MatrixTreeTracer{tree, sphere}, sphere, tree.rootBox(), cam, {});
  EXPECT_TRUE(none.rgb.empty());
  EXPECT_EQ(none.primaryRays, 0u);

  const TriangleMesh empty;
  const MatrixTree emptyTree = mtest::buildTree(empty, mtest::options(TreeKind::Octree));
  cam = sphereCamera(5);
  cam.width = cam.height = 31;
  const RenderResult img = mtree::render(mtree::MatrixTreeTracer{emptyTree, empty}, empty, Box{}, cam, {});
  EXPECT_EQ(img.hits, 0u);
  for (size_t p = 0; p < img.nodeVisits.size(); ++p) {
    EXPECT_EQ(img.nodeVisits[p], 0u);
    EXPECT_EQ(img.primTests[p], 0u);
    EXPECT_EQ(img.hitPrim[p], MT_NULL);
  }
}

}  // namespace

// A small ray-casting renderer: pinhole camera, primary rays, one shadow ray per hit towards a
// point light, Lambert shading, OpenMP over image rows, and per-pixel counters (node visits and
// primitive tests, the paper's Figure 1). It is generic over a *tracer* so that every
// tree/traversal pair renders through the same code (the paper's §6 framework):
//   bool first(Vec3 o, Vec3 d, double tmin, double tmax, RayHit&, TraversalStats*) const;
//   bool any  (Vec3 o, Vec3 d, double tmin, double tmax, TraversalStats*) const;
#pragma once

#include <chrono>
#include <vector>

#include <omp.h>

#include "mtree/core/parallel.h"
#include "mtree/rays/raycast.h"

namespace mtree {

struct Camera {
  Vec3 eye{0, 0, 5}, target{0, 0, 0}, up{0, 1, 0};
  double fovyDegrees = 30;
  int width = 800, height = 800;
};

struct RenderOptions {
  bool shadows = true;
  /// Point light position; if lightAtEyeOffset, the light sits at eye + offset * (scene size).
  Vec3 light{0, 0, 0};
  bool lightFromCamera = true;
  Vec3 albedo{0.85, 0.8, 0.7};
  Vec3 background{0.08, 0.09, 0.12};
  double ambient = 0.15;
  int threads = 0;
};

struct RenderResult {
  int width = 0, height = 0;
  std::vector<uint8_t> rgb;           // width*height*3, row 0 at the bottom (VTK's image order)
  std::vector<uint32_t> nodeVisits;   // per pixel, primary + shadow ray
  std::vector<uint32_t> primTests;    // per pixel, primary + shadow ray
  std::vector<float> depth;           // per pixel t of the primary hit, +inf where missed
  std::vector<uint32_t> hitPrim;      // per pixel primitive id, MT_NULL where missed
  uint64_t primaryRays = 0, shadowRays = 0, hits = 0;
  TraversalStats stats;
  double ms = 0;
};

/// The primary rays of a pinhole camera: pixel (x, y) (y = 0 at the bottom) looks along
/// direction(x, y) from cam.eye, through the pixel's centre. Shared by render() and by anything
/// that must reproduce its rays (the benchmark's brute-force check, other ray tracers).
struct PinholeRays {
  Vec3 eye, fwd, right, up;
  double th = 0, aspect = 1;
  int width = 0, height = 0;
  explicit PinholeRays(const Camera& cam) : eye(cam.eye), width(cam.width), height(cam.height) {
    fwd = normalized(cam.target - cam.eye);
    right = cross(fwd, cam.up);
    if (norm(right) == 0) right = cross(fwd, std::fabs(fwd.y) < 0.9 ? Vec3(0, 1, 0) : Vec3(1, 0, 0));
    right = normalized(right);
    up = cross(right, fwd);
    th = std::tan(0.5 * cam.fovyDegrees * M_PI / 180.0);
    aspect = height > 0 ? double(width) / height : 1.0;
  }
  Vec3 direction(int x, int y) const {
    const double sx = (2.0 * (x + 0.5) / width - 1.0) * th * aspect;
    const double sy = (2.0 * (y + 0.5) / height - 1.0) * th;
    return normalized(fwd + right * sx + up * sy);
  }
};

/// The per-pixel arrays of a cam.width x cam.height render, before any ray: black, no hits, zero
/// counters (empty for a non-positive size). Shared by render() and renderOpenCL().
inline RenderResult blankRenderResult(const Camera& cam) {
  RenderResult r;
  r.width = cam.width;
  r.height = cam.height;
  if (cam.width <= 0 || cam.height <= 0) return r;
  const size_t npix = size_t(cam.width) * cam.height;
  r.rgb.assign(npix * 3, 0);
  r.nodeVisits.assign(npix, 0);
  r.primTests.assign(npix, 0);
  r.depth.assign(npix, std::numeric_limits<float>::infinity());
  r.hitPrim.assign(npix, MT_NULL);
  return r;
}

/// The shading every renderer shares: the point light (above and right of the eye, scaled by the
/// scene's diagonal, unless opt gives it), the shadow-ray offset along the normal, the normal
/// turned towards the viewer, Lambert plus ambient, and the colour's 8-bit quantisation.
struct Shading {
  Vec3 light;
  double eps = 0;
  Shading(const Box& sceneBox, const Camera& cam, const PinholeRays& rays, const RenderOptions& opt) {
    const double diag = sceneBox.empty() ? 1.0 : std::max(norm(sceneBox.extent()), 1e-300);
    eps = 1e-7 * diag + 1e-9 * norm(sceneBox.center());
    light = opt.lightFromCamera ? cam.eye + rays.up * (0.5 * diag) + rays.right * (0.3 * diag) : opt.light;
  }
  static Vec3 facingNormal(const TriangleMesh& mesh, uint32_t prim, Vec3 dir) {
    const Vec3 a = mesh.vertex(prim, 0), b = mesh.vertex(prim, 1), c = mesh.vertex(prim, 2);
    const Vec3 n = normalized(cross(b - a, c - a));
    return dot(n, dir) > 0 ? n * -1.0 : n;
  }
  static Vec3 colour(const RenderOptions& opt, double diffuse) {
    const double s = opt.ambient + (1 - opt.ambient) * diffuse;
    return Vec3(opt.albedo.x * s, opt.albedo.y * s, opt.albedo.z * s);
  }
  static void store(RenderResult& r, size_t pix, Vec3 c) {
    for (int k = 0; k < 3; ++k)
      r.rgb[pix * 3 + k] = static_cast<uint8_t>(std::min(255.0, std::max(0.0, c[k] * 255.0 + 0.5)));
  }
};

/// The matrix-tree tracer over a triangle mesh, with a choice of ray/triangle test.
struct MatrixTreeTracer {
  const MatrixTree& tree;
  const TriangleMesh& mesh;
  TriangleTest test = TriangleTest::MollerTrumbore;
  bool first(Vec3 o, Vec3 d, double tmin, double tmax, RayHit& h, TraversalStats* st) const {
    return test == TriangleTest::Watertight
               ? intersectFirst<TriangleTest::Watertight>(tree, mesh, o, d, tmin, tmax, h, st)
               : intersectFirst<TriangleTest::MollerTrumbore>(tree, mesh, o, d, tmin, tmax, h, st);
  }
  bool any(Vec3 o, Vec3 d, double tmin, double tmax, TraversalStats* st) const {
    return test == TriangleTest::Watertight
               ? intersectAny<TriangleTest::Watertight>(tree, mesh, o, d, tmin, tmax, st)
               : intersectAny<TriangleTest::MollerTrumbore>(tree, mesh, o, d, tmin, tmax, st);
  }
};

/// Renders `mesh` through `tracer`. `sceneBox` sets the shadow-ray offset and the light distance.
template <class Tracer>
RenderResult render(const Tracer& tracer, const TriangleMesh& mesh, const Box& sceneBox, const Camera& cam,
                    const RenderOptions& opt) {
  RenderResult r = blankRenderResult(cam);
  const int W = cam.width, Hh = cam.height;
  if (W <= 0 || Hh <= 0) return r;
  const size_t npix = size_t(W) * Hh;
  const PinholeRays rays(cam);
  const Shading sh(sceneBox, cam, rays, opt);
  const int threads = resolveThreads(opt.threads);

  uint64_t hits = 0, shadowRays = 0;
  TraversalStats total;
  const auto t0 = std::chrono::steady_clock::now();
#pragma omp parallel num_threads(threads) reduction(+ : hits, shadowRays)
  {
    TraversalStats local;
#pragma omp for schedule(dynamic, 1)
    for (int y = 0; y < Hh; ++y) {
      for (int x = 0; x < W; ++x) {
        const size_t pix = size_t(y) * W + x;
        const Vec3 d = rays.direction(x, y);
        TraversalStats ps;
        RayHit h;
        Vec3 c = opt.background;
        if (tracer.first(cam.eye, d, 0.0, std::numeric_limits<double>::infinity(), h, &ps)) {
          ++hits;
          const Vec3 n = Shading::facingNormal(mesh, h.prim, d);
          const Vec3 p = cam.eye + d * h.t;
          const Vec3 toL = sh.light - p;
          const double distL = norm(toL);
          const Vec3 l = toL * (1.0 / distL);
          double diffuse = std::max(0.0, dot(n, l));
          if (opt.shadows && diffuse > 0) {
            ++shadowRays;
            if (tracer.any(p + n * sh.eps, l, 0.0, distL, &ps)) diffuse = 0;
          }
          c = Shading::colour(opt, diffuse);
          r.depth[pix] = static_cast<float>(h.t);
          r.hitPrim[pix] = h.prim;
        }
        Shading::store(r, pix, c);
        r.nodeVisits[pix] = static_cast<uint32_t>(ps.nodeVisits);
        r.primTests[pix] = static_cast<uint32_t>(ps.primTests);
        local.add(ps);
      }
    }
#pragma omp critical
    total.add(local);
  }
  r.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  r.primaryRays = npix;
  r.shadowRays = shadowRays;
  r.hits = hits;
  r.stats = total;
  return r;
}

}  // namespace mtree

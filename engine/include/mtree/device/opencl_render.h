// render() (render.h) with the rays traced on an OpenCL device (ocl::Tracer) instead of a CPU
// tracer: the same camera rays, light, offset and shading, so the images and first hits can be
// compared pixel for pixel. Used by vtkMatrixTreeRayCaster's opencl backend and by
// bench/cpp/rays_bench.cxx (one copy for both).
#pragma once

#include <algorithm>
#include <chrono>
#include <limits>
#include <vector>

#include "mtree/device/opencl.h"
#include "mtree/rays/render.h"

namespace mtree {

// render() (mtree/rays/render.h) with the rays traced on the OpenCL device in two batches: the same
// camera rays, light, eps offset and shading. A shadow ray is the segment render() traces, from
// q = p + n*eps to q + (light - p): direction (light - p), t in [0, 1] (the batch kernel takes one
// t range for all rays). nodeVisits/primTests per pixel stay 0 (the kernels give sums only); the
// sums only with RenderOptions::counters (without, the kernels are given no counter buffer).
/// DeviceTracer: ocl::Tracer, or any device tracer with its intersectFirst / intersectAny
/// (ocl::SplitTreeTracer, opencl_trees.h).
template <class DeviceTracer>
inline RenderResult renderOpenCL(DeviceTracer& tracer, const TriangleMesh& mesh, const Box& sceneBox, const Camera& cam,
                          const RenderOptions& opt, double* traceMs = nullptr) {
  RenderResult r = blankRenderResult(cam);
  const int W = cam.width, Hh = cam.height;
  if (W <= 0 || Hh <= 0) return r;
  const size_t npix = size_t(W) * Hh;
  const auto t0 = std::chrono::steady_clock::now();
  const PinholeRays rays(cam);
  const Shading sh(sceneBox, cam, rays, opt);
  std::vector<double> o(3 * npix), d(3 * npix), t(npix);
  std::vector<uint32_t> prim(npix);
  for (int y = 0; y < Hh; ++y)
    for (int x = 0; x < W; ++x) {
      const size_t pix = size_t(y) * W + x;
      const Vec3 dir = rays.direction(x, y);
      for (int k = 0; k < 3; ++k) {
        o[3 * pix + k] = cam.eye[k];
        d[3 * pix + k] = dir[k];
      }
    }
  uint64_t v1 = 0, c1 = 0, v2 = 0, c2 = 0;
  auto tb = std::chrono::steady_clock::now();
  tracer.intersectFirst(o.data(), d.data(), npix, 0.0, std::numeric_limits<double>::infinity(), t.data(),
                        prim.data(), opt.counters ? &v1 : nullptr, opt.counters ? &c1 : nullptr);
  if (traceMs) *traceMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - tb).count();
  std::vector<double> diffuse(npix, 0.0), so, sd;
  std::vector<size_t> shadowPix;
  for (size_t pix = 0; pix < npix; ++pix) {
    if (prim[pix] == MT_NULL) continue;
    const Vec3 dir(d[3 * pix], d[3 * pix + 1], d[3 * pix + 2]);
    const Vec3 n = Shading::facingNormal(mesh, prim[pix], dir);
    const Vec3 p = cam.eye + dir * t[pix];
    const Vec3 toL = sh.light - p;
    const double distL = norm(toL);
    diffuse[pix] = std::max(0.0, dot(n, toL * (1.0 / distL)));
    if (opt.shadows && diffuse[pix] > 0) {
      const Vec3 q = p + n * sh.eps;
      for (int k = 0; k < 3; ++k) {
        so.push_back(q[k]);
        sd.push_back(toL[k]);
      }
      shadowPix.push_back(pix);
    }
  }
  std::vector<uint8_t> blocked(shadowPix.size(), 0);
  tb = std::chrono::steady_clock::now();
  if (!shadowPix.empty())
    tracer.intersectAny(so.data(), sd.data(), shadowPix.size(), 0.0, 1.0, blocked.data(), opt.counters ? &v2 : nullptr,
                        opt.counters ? &c2 : nullptr);
  if (traceMs) *traceMs += std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - tb).count();
  for (size_t k = 0; k < shadowPix.size(); ++k)
    if (blocked[k]) diffuse[shadowPix[k]] = 0;
  for (size_t pix = 0; pix < npix; ++pix) {
    Vec3 c = opt.background;
    if (prim[pix] != MT_NULL) {
      ++r.hits;
      c = Shading::colour(opt, diffuse[pix]);
      r.depth[pix] = static_cast<float>(t[pix]);
      r.hitPrim[pix] = prim[pix];
    }
    Shading::store(r, pix, c);
  }
  r.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  r.primaryRays = npix;
  r.shadowRays = shadowPix.size();
  r.stats.nodeVisits = v1 + v2;
  r.stats.primTests = c1 + c2;
  return r;
}

}  // namespace mtree

// A small ray-casting renderer: pinhole camera, primary rays, one shadow ray per hit towards a
// point light, Lambert shading, OpenMP over image rows, and optional per-pixel counters (node
// visits and primitive tests, the paper's Figure 1). It is generic over a *tracer* so that every
// tree/traversal pair renders through the same code (the paper's §6 framework). A tracer traces
// a row's rays as one batch (batch_trace.h):
//   void first(const RayBatch&, RayHit* hits, RayCounters) const;
//   void any  (const RayBatch&, uint8_t* blocked, RayCounters) const;
// or one ray at a time (render() then loops over the batch):
//   bool first(Vec3 o, Vec3 d, double tmin, double tmax, RayHit&, TraversalStats*) const;
//   bool any  (Vec3 o, Vec3 d, double tmin, double tmax, TraversalStats*) const;
// The counters are off by default (RenderOptions::counters): then the tracers run walks compiled
// without them, which is the render users time.
#pragma once

#include <algorithm>
#include <chrono>
#include <type_traits>
#include <utility>
#include <vector>

#include <omp.h>

#include "mtree/core/parallel.h"
#include "mtree/rays/batch_trace.h"
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
  /// Per-pixel node visits and triangle tests (RenderResult::nodeVisits, primTests, stats). Off:
  /// those stay zero and the walks run without counters.
  bool counters = false;
};

struct RenderResult {
  int width = 0, height = 0;
  std::vector<uint8_t> rgb;           // width*height*3, row 0 at the bottom (VTK's image order)
  std::vector<uint32_t> nodeVisits;   // per pixel, primary + shadow ray (RenderOptions::counters)
  std::vector<uint32_t> primTests;    // per pixel, primary + shadow ray (RenderOptions::counters)
  std::vector<float> depth;           // per pixel t of the primary hit, +inf where missed
  std::vector<uint32_t> hitPrim;      // per pixel primitive id, MT_NULL where missed
  uint64_t primaryRays = 0, shadowRays = 0, hits = 0;
  TraversalStats stats;               // nodeVisits and primTests summed (RenderOptions::counters)
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

/// The matrix-tree tracer over a triangle mesh, with a choice of ray/triangle test. With a
/// payload (the tree's LeafTriangles over this mesh) its batches take the interleaved walk and
/// the SIMD leaf tests; without one they test the mesh's triangles through the ids.
struct MatrixTreeTracer {
  const MatrixTree& tree;
  const TriangleMesh& mesh;
  TriangleTest test = TriangleTest::MollerTrumbore;
  const LeafTriangles* payload = nullptr;
  TraceTuning tuning{};
  void first(const RayBatch& b, RayHit* hits, RayCounters c) const {
    traceFirst(tree, mesh, payload, test, b, hits, c, tuning);
  }
  void any(const RayBatch& b, uint8_t* blocked, RayCounters c) const {
    traceAny(tree, mesh, payload, test, b, blocked, c, tuning);
  }
};

/// The SAH kd-tree as a tracer, with one of its traversals; with a payload (LeafTriangles built
/// from tree.primitiveIndices() over this mesh) its leaves take the same SIMD leaf tests as the
/// matrix tree's.
struct SahTracer {
  const SahKdTree& tree;
  const TriangleMesh& mesh;
  SahTraversal traversal = SahTraversal::Stack;
  TriangleTest test = TriangleTest::MollerTrumbore;
  int shortStack = 3;
  const LeafTriangles* payload = nullptr;
  TraceTuning tuning{};
  void first(const RayBatch& b, RayHit* hits, RayCounters c) const {
    traceFirst(tree, traversal, shortStack, mesh, payload, test, b, hits, c, tuning);
  }
  void any(const RayBatch& b, uint8_t* blocked, RayCounters c) const {
    traceAny(tree, traversal, shortStack, mesh, payload, test, b, blocked, c, tuning);
  }
};

namespace detail {
template <class Tracer, class = void>
struct TracesBatches : std::false_type {};
template <class Tracer>
struct TracesBatches<Tracer, std::void_t<decltype(std::declval<const Tracer&>().first(
                                 std::declval<const RayBatch&>(), std::declval<RayHit*>(), RayCounters{}))>>
    : std::true_type {};

/// The tracer's first hits of a batch: its batch method, or its single-ray one in a loop.
template <class Tracer>
void firstHits(const Tracer& tracer, const RayBatch& b, RayHit* hits, RayCounters c) {
  if constexpr (TracesBatches<Tracer>::value) {
    tracer.first(b, hits, c);
  } else {
    for (size_t i = 0; i < b.n; ++i) {
      TraversalStats st;
      const double tmax = b.tMax(i);
      tracer.first(b.o[i], b.d[i], b.tMin(i), tmax, hits[i], c.on() ? &st : nullptr);
      if (c.on()) {
        c.visits[i] += static_cast<uint32_t>(st.nodeVisits);
        c.tests[i] += static_cast<uint32_t>(st.primTests);
      }
    }
  }
}
template <class Tracer>
void anyHits(const Tracer& tracer, const RayBatch& b, uint8_t* blocked, RayCounters c) {
  if constexpr (TracesBatches<Tracer>::value) {
    tracer.any(b, blocked, c);
  } else {
    for (size_t i = 0; i < b.n; ++i) {
      TraversalStats st;
      blocked[i] = tracer.any(b.o[i], b.d[i], b.tMin(i), b.tMax(i), c.on() ? &st : nullptr);
      if (c.on()) {
        c.visits[i] += static_cast<uint32_t>(st.nodeVisits);
        c.tests[i] += static_cast<uint32_t>(st.primTests);
      }
    }
  }
}
}  // namespace detail

/// Renders `mesh` through `tracer`. `sceneBox` sets the shadow-ray offset and the light distance.
/// Row by row: the row's primary rays as one batch, then the shadow rays of its lit hits as one.
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
  const auto t0 = std::chrono::steady_clock::now();
#pragma omp parallel num_threads(threads) reduction(+ : hits, shadowRays)
  {
    const size_t w = static_cast<size_t>(W);
    std::vector<Vec3> po(w, cam.eye), pd(w), so(w), sd(w);
    std::vector<double> stmax(w), diffuse(w);
    std::vector<RayHit> ph(w);
    std::vector<uint8_t> blocked(w);
    std::vector<int> shadowPix(w);
    std::vector<uint32_t> sVisits(w), sTests(w);
#pragma omp for schedule(dynamic, 1)
    for (int y = 0; y < Hh; ++y) {
      const size_t row = size_t(y) * W;
      for (int x = 0; x < W; ++x) pd[size_t(x)] = rays.direction(x, y);
      RayCounters c;
      if (opt.counters) c = RayCounters{r.nodeVisits.data() + row, r.primTests.data() + row};
      RayBatch primary;
      primary.o = po.data();
      primary.d = pd.data();
      primary.n = size_t(W);
      detail::firstHits(tracer, primary, ph.data(), c);
      size_t ns = 0;
      for (int x = 0; x < W; ++x) {
        const RayHit& h = ph[size_t(x)];
        diffuse[size_t(x)] = -1;  // missed: the background
        if (!h.hit()) continue;
        ++hits;
        const Vec3 d = pd[size_t(x)];
        const Vec3 n = Shading::facingNormal(mesh, h.prim, d);
        const Vec3 p = cam.eye + d * h.t;
        const Vec3 toL = sh.light - p;
        const double distL = norm(toL);
        const Vec3 l = toL * (1.0 / distL);
        diffuse[size_t(x)] = std::max(0.0, dot(n, l));
        if (opt.shadows && diffuse[size_t(x)] > 0) {
          so[ns] = p + n * sh.eps;
          sd[ns] = l;
          stmax[ns] = distL;
          shadowPix[ns] = x;
          ++ns;
        }
        r.depth[row + size_t(x)] = static_cast<float>(h.t);
        r.hitPrim[row + size_t(x)] = h.prim;
      }
      shadowRays += ns;
      if (ns > 0) {
        RayBatch shadow;
        shadow.o = so.data();
        shadow.d = sd.data();
        shadow.tmax = stmax.data();
        shadow.n = ns;
        RayCounters sc;
        if (opt.counters) {  // the shadow rays' counts, added to their pixels' below
          std::fill_n(sVisits.begin(), ns, 0u);
          std::fill_n(sTests.begin(), ns, 0u);
          sc = RayCounters{sVisits.data(), sTests.data()};
        }
        detail::anyHits(tracer, shadow, blocked.data(), sc);
        for (size_t k = 0; k < ns; ++k) {
          const size_t pix = row + size_t(shadowPix[k]);
          if (blocked[k]) diffuse[size_t(shadowPix[k])] = 0;
          if (opt.counters) {
            r.nodeVisits[pix] += sVisits[k];
            r.primTests[pix] += sTests[k];
          }
        }
      }
      for (int x = 0; x < W; ++x) {
        const double df = diffuse[size_t(x)];
        Shading::store(r, row + size_t(x), df < 0 ? opt.background : Shading::colour(opt, df));
      }
    }
  }
  r.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  r.primaryRays = npix;
  r.shadowRays = shadowRays;
  r.hits = hits;
  if (opt.counters) {
    for (size_t p = 0; p < npix; ++p) {
      r.stats.nodeVisits += r.nodeVisits[p];
      r.stats.primTests += r.primTests[p];
    }
  }
  return r;
}

}  // namespace mtree

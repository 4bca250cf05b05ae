// rays_bench: the paper's ray-tracing experiment (§6, Table 1) on one scene, every tree and
// traversal through the same renderer (engine/include/mtree/rays/render.h): pinhole camera, primary
// rays, one shadow ray per hit towards a point light, Lambert shading, OpenMP over image rows.
// bench/rays.py writes the scene file, runs this program, adds Embree and writes the tables.
//
//   rays_bench SCENE.bin OUT.json [--threads T] [--repeat R] [--tests mt,watertight]
//              [--methods octree,kdtree,sah-restart,sah-stack,sah-shortstack] [--short-stack K]
//              [--samples S] [--heatmaps DIR] [--backend cpu|opencl|all] [--device SEL]
//
// SCENE.bin (little endian, written by bench/rays.py):
//   char[8] "MTSCENE1"; uint32 nverts, ntris, nframes, width, height;
//   double eye[3], target[3], up[3], fovy;
//   uint32 triangles[ntris][3]; then per frame double points[nverts][3].
// Per frame and method: the tree is rebuilt (timed), then the frame is rendered once per
// triangle test (timed); with --repeat R both are repeated R times and the median is kept.
// The SAH tree is built once per frame and rendered with each of its three traversals.
// Correctness: on S seeded pixels of the first and the last frame every method's primary hit is
// compared with the brute force (same triangle, or the same t within 1e-9 relative: a tie on a
// shared edge); the reference hits of the first frame go into the JSON so that bench/rays.py can
// check Embree on the same rays.
// With --heatmaps DIR the first frame's per-pixel node visits and triangle tests (uint32) and its
// RGB image (uint8, row 0 at the bottom) are written as raw files DIR/<row name>.{visits,tests,rgb}.
// --backend opencl (or all) adds rows with backend "opencl" for the matrix octree / kd-tree: per
// frame the tree is built on the OpenCL device (mtree::ocl::Builder; --device picks it, see
// ocl::Context::create), uploaded, and the frame is rendered with render()'s rays and shading but
// traced as two device batches (all primary rays, then the shadow rays of the lit hits: the same
// segment from p + n*eps to p + (light - p) that render() traces). build_ms counts the device
// build and the upload; render_ms the rays, both batches and the shading (trace_ms: the batches).
// Its first hits are compared with the CPU engine's render of the same frame, pixel by pixel
// (same triangle, or t within 1e-6 relative; every frame with --backend all, the first and last
// frame otherwise), and its shading (the shadow rays) by the RGB values; the device's kernels test
// triangles with Moller-Trumbore only, so its rows are "mt". Without an OpenCL device (or an
// engine built without OpenCL) --backend opencl|all stops with the back end's error.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <fstream>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "bench_scene.h"
#include "mtree/core/builder.h"
#include "mtree/rays/batch_trace.h"
#include "mtree/rays/intersect.h"
#include "mtree/device/opencl.h"
#include "mtree/device/opencl_render.h"
#include "mtree/rays/render.h"
#include "mtree/rays/sah_kdtree.h"

#ifdef MT_HAVE_EMBREE
#include <embree3/rtcore.h>
#endif

namespace {

using namespace mtree;
using mtbench::cpuMs;
using mtbench::readScene;
using mtbench::Scene;
using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

Box pointBox(const std::vector<double>& p) {
  Box b;
  for (size_t i = 0; i + 2 < p.size(); i += 3) b.extend(Vec3(p[i], p[i + 1], p[i + 2]));
  return b;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

struct Row {
  std::string method, traversal, test;
  bool payload = true;  // leaf tests on the pre-gathered triangles (else through the ids to the mesh)
  std::vector<double> buildMs, renderMs, renderCpuMs, buildCpuMs, payloadMs;
  double rays = 0, primary = 0, nodeVisits = 0, triTests = 0;  // summed over frames (counted renders)
  uint64_t mismatches = 0, checked = 0;
  size_t bytes = 0, payloadBytes = 0;
  int height = 0;
  uint64_t nodes = 0, references = 0;
  double missRays = 0, missCpuMs = 0, missVisits = 0;  // the first frame's in-box misses, traced alone
  std::string backend = "cpu", device;
  std::vector<double> uploadMs, traceMs;                      // opencl rows
  uint64_t cpuMismatches = 0, cpuChecked = 0, shadeMismatches = 0;  // opencl rows vs the CPU render
  std::string name() const {
    return method + "-" + traversal + "-" + test + (payload || method == "embree3" ? "" : "-mesh") +
           (backend == "cpu" ? "" : "-" + backend);
  }
};

struct Sample {
  int pixel;
  RayHit ref;
};

// The brute force's first hits on the sampled pixels of a frame.
std::vector<Sample> referenceHits(const TriangleMesh& mesh, const Camera& cam, int samples, uint64_t seed,
                                  int threads) {
  const PinholeRays rays(cam);
  const int npix = cam.width * cam.height;
  std::vector<Sample> out(std::min(samples, npix));
  uint64_t s = seed;
  for (auto& smp : out) {  // splitmix64
    uint64_t z = (s += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    z ^= z >> 31;
    smp.pixel = static_cast<int>(z % uint64_t(npix));
  }
#pragma omp parallel for num_threads(threads) schedule(dynamic, 16)
  for (long i = 0; i < long(out.size()); ++i) {
    const int x = out[i].pixel % cam.width, y = out[i].pixel / cam.width;
    intersectFirstBruteForce(mesh, cam.eye, rays.direction(x, y), 0.0, std::numeric_limits<double>::infinity(),
                             out[i].ref);
  }
  return out;
}

// relTol: 1e-6 for the double-precision tracers (the depth is stored as a float), 1e-5 for Embree's
// float rays.
uint64_t countMismatches(const RenderResult& r, const std::vector<Sample>& samples, double relTol) {
  uint64_t bad = 0;
  for (const auto& s : samples) {
    const uint32_t got = r.hitPrim[size_t(s.pixel)];
    if (got == s.ref.prim) continue;
    const bool gotHit = got != MT_NULL;
    if (gotHit != s.ref.hit()) {
      ++bad;
      continue;
    }
    const double t = r.depth[size_t(s.pixel)];  // float: compare at float precision
    if (std::fabs(t - s.ref.t) > relTol * std::max(1.0, std::fabs(s.ref.t))) ++bad;
  }
  return bad;
}

// Pixels whose first hit differs between two renders of the same frame (same triangle, or both
// hit with t within 1e-6 relative), and pixels whose colour differs (the shadow rays).
void compareRenders(const RenderResult& a, const RenderResult& ref, uint64_t* hitBad, uint64_t* rgbBad) {
  for (size_t p = 0; p < ref.hitPrim.size(); ++p) {
    if (a.hitPrim[p] != ref.hitPrim[p]) {
      const bool both = a.hitPrim[p] != MT_NULL && ref.hitPrim[p] != MT_NULL;
      if (!both || std::fabs(double(a.depth[p]) - double(ref.depth[p])) > 1e-6 * std::max(1.0, std::fabs(double(ref.depth[p]))))
        ++*hitBad;
    }
    if (a.rgb[3 * p] != ref.rgb[3 * p] || a.rgb[3 * p + 1] != ref.rgb[3 * p + 1] || a.rgb[3 * p + 2] != ref.rgb[3 * p + 2])
      ++*rgbBad;
  }
}

void writeRaw(const std::string& path, const void* data, size_t bytes) {
  std::ofstream f(path, std::ios::binary);
  f.write(static_cast<const char*>(data), std::streamsize(bytes));
  if (!f) throw std::runtime_error("cannot write " + path);
}

std::string jsonNumbers(const std::vector<double>& v) {
  std::ostringstream o;
  o.precision(6);
  o << "[";
  for (size_t i = 0; i < v.size(); ++i) o << (i ? ", " : "") << v[i];
  o << "]";
  return o.str();
}

#ifdef MT_HAVE_EMBREE
// Embree 3 (float BVH) as render()'s tracer: the outside reference on the same rays, with the same
// shading and shadow rays. Three builds per frame:
//   default  a new static scene per frame, RTC_BUILD_QUALITY_MEDIUM (Embree's default);
//   low      one scene with RTC_SCENE_FLAG_DYNAMIC and RTC_BUILD_QUALITY_LOW, its vertex buffer
//            rewritten and recommitted each frame (Embree's fastest full rebuild);
//   refit    the same dynamic scene with the geometry's RTC_BUILD_QUALITY_REFIT: each frame after
//            the first refits the first frame's BVH to the moved vertices (same triangles).
struct EmbreeScene {
  enum Mode { Default = 0, Low = 1, Refit = 2 };
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  RTCGeometry geom = nullptr;
  float* verts = nullptr;
  Mode mode = Default;
  EmbreeScene(int threads, Mode m) : mode(m) {
    const std::string cfg = "threads=" + std::to_string(threads) + ",set_affinity=0";
    device = rtcNewDevice(cfg.c_str());
    if (!device) throw std::runtime_error("rtcNewDevice failed");
  }
  ~EmbreeScene() {
    if (scene) rtcReleaseScene(scene);
    if (device) rtcReleaseDevice(device);
  }
  static const char* name(Mode m) { return m == Default ? "bvh-default" : (m == Low ? "bvh-low" : "bvh-refit"); }
  // The frame's BVH (timed by the caller): the vertices converted to float and the scene committed.
  void build(const Scene& sc, const std::vector<double>& pts) {
    const bool fresh = !scene || mode == Default;
    if (fresh) {
      if (scene) rtcReleaseScene(scene);
      scene = rtcNewScene(device);
      if (mode != Default) {
        rtcSetSceneFlags(scene, RTC_SCENE_FLAG_DYNAMIC);
        rtcSetSceneBuildQuality(scene, RTC_BUILD_QUALITY_LOW);
      }
      geom = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
      if (mode == Refit) rtcSetGeometryBuildQuality(geom, RTC_BUILD_QUALITY_REFIT);
      else if (mode == Low) rtcSetGeometryBuildQuality(geom, RTC_BUILD_QUALITY_LOW);
      verts = static_cast<float*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                          3 * sizeof(float), sc.nv));
      unsigned* idx = static_cast<unsigned*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                                     3 * sizeof(unsigned), sc.nt));
      std::copy(sc.tris.begin(), sc.tris.end(), idx);
    }
    for (size_t i = 0; i < pts.size(); ++i) verts[i] = static_cast<float>(pts[i]);
    if (!fresh) rtcUpdateGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0);
    rtcCommitGeometry(geom);
    if (fresh) {
      rtcAttachGeometry(scene, geom);
      rtcReleaseGeometry(geom);
    }
    rtcCommitScene(scene);
  }
};

struct EmbreeTracer {
  RTCScene scene;
  static float toFloat(double t) { return std::isinf(t) ? std::numeric_limits<float>::infinity() : static_cast<float>(t); }
  bool first(Vec3 o, Vec3 d, double tmin, double tmax, RayHit& h, TraversalStats*) const {
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    RTCRayHit rh;
    rh.ray.org_x = float(o.x);
    rh.ray.org_y = float(o.y);
    rh.ray.org_z = float(o.z);
    rh.ray.dir_x = float(d.x);
    rh.ray.dir_y = float(d.y);
    rh.ray.dir_z = float(d.z);
    rh.ray.tnear = toFloat(tmin);
    rh.ray.tfar = toFloat(tmax);
    rh.ray.time = 0;
    rh.ray.mask = ~0u;
    rh.ray.id = 0;
    rh.ray.flags = 0;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(scene, &ctx, &rh);
    h = RayHit{};
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return false;
    h.t = rh.ray.tfar;
    h.prim = rh.hit.primID;
    h.u = rh.hit.u;
    h.v = rh.hit.v;
    return true;
  }
  bool any(Vec3 o, Vec3 d, double tmin, double tmax, TraversalStats*) const {
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    RTCRay ray;
    ray.org_x = float(o.x);
    ray.org_y = float(o.y);
    ray.org_z = float(o.z);
    ray.dir_x = float(d.x);
    ray.dir_y = float(d.y);
    ray.dir_z = float(d.z);
    ray.tnear = toFloat(tmin);
    ray.tfar = toFloat(tmax);
    ray.time = 0;
    ray.mask = ~0u;
    ray.id = 0;
    ray.flags = 0;
    rtcOccluded1(scene, &ctx, &ray);
    return ray.tfar < 0;  // Embree marks an occluded ray with tfar = -inf
  }
};
#endif

// The primary rays of `cam` that enter `box` and hit nothing in `r` (a render of the frame): the
// in-box misses, which every tree must walk to the end.
void inBoxMisses(const Camera& cam, const Box& box, const RenderResult& r, std::vector<Vec3>& dirs) {
  const PinholeRays rays(cam);
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x) {
      if (r.hitPrim[size_t(y) * cam.width + x] != MT_NULL) continue;
      const Vec3 d = rays.direction(x, y);
      double t0 = 0, t1 = std::numeric_limits<double>::infinity();
      if (rayBox(cam.eye, d, box, t0, t1)) dirs.push_back(d);
    }
}

int run(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr,
                 "usage: rays_bench SCENE.bin OUT.json [--threads T] [--repeat R] [--tests mt,watertight]\n"
                 "       [--methods octree,kdtree,sah-restart,sah-stack,sah-shortstack,embree-default,embree-low,\n"
                 "        embree-refit] [--short-stack K] [--samples S] [--heatmaps DIR] [--backend cpu|opencl|all]\n"
                 "       [--device SEL] [--leaves payload|mesh|both] [--in-flight K] [--simd scalar|sse2|avx2]\n");
    return 2;
  }
  const std::string scenePath = argv[1], outPath = argv[2];
  int threads = 0, repeat = 1, samples = 2000, shortStack = 3, octHeight = 0, kdHeight = 0;
  double leafScale = BuildOptions{}.leafScale, maxCandidates = BuildOptions{}.maxCandidates;
  std::string testsArg = "mt,watertight",
              methodsArg = "octree,kdtree,sah-restart,sah-stack,sah-shortstack,embree-default,embree-low,embree-refit";
  std::string heatDir, backend = "cpu", deviceSel, leavesArg = "payload";
  TraceTuning tuning;
  tuning.simd = simdSupported();
  for (int i = 3; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) throw std::runtime_error(a + " needs a value");
      return argv[++i];
    };
    if (a == "--threads") threads = std::stoi(next());
    else if (a == "--repeat") repeat = std::max(1, std::stoi(next()));
    else if (a == "--tests") testsArg = next();
    else if (a == "--methods") methodsArg = next();
    else if (a == "--short-stack") shortStack = std::stoi(next());
    else if (a == "--samples") samples = std::max(0, std::stoi(next()));
    else if (a == "--heatmaps") heatDir = next();
    else if (a == "--backend") backend = next();
    else if (a == "--device") deviceSel = next();
    else if (a == "--octree-height") octHeight = std::stoi(next());
    else if (a == "--kdtree-height") kdHeight = std::stoi(next());
    else if (a == "--leaf-scale") leafScale = std::stod(next());
    else if (a == "--max-candidates") maxCandidates = std::stod(next());
    else if (a == "--leaves") leavesArg = next();
    else if (a == "--in-flight") tuning.inFlight = std::stoi(next());
    else if (a == "--simd") {
      const std::string v = next();
      if (v == "scalar") tuning.simd = Simd::Scalar;
      else if (v == "sse2") tuning.simd = Simd::Sse2;
      else if (v == "avx2") tuning.simd = Simd::Avx2;
      else throw std::runtime_error("--simd must be scalar, sse2 or avx2");
      tuning.simd = std::min(tuning.simd, simdSupported());
    } else throw std::runtime_error("unknown option " + a);
  }
  auto has = [](const std::string& list, const std::string& item) {
    return ("," + list + ",").find("," + item + ",") != std::string::npos;
  };
  std::vector<TriangleTest> tests;
  if (has(testsArg, "mt")) tests.push_back(TriangleTest::MollerTrumbore);
  if (has(testsArg, "watertight")) tests.push_back(TriangleTest::Watertight);
  if (tests.empty()) throw std::runtime_error("--tests must name mt and/or watertight");
  if (leavesArg != "payload" && leavesArg != "mesh" && leavesArg != "both")
    throw std::runtime_error("--leaves must be payload, mesh or both");
  std::vector<bool> leafModes;
  if (leavesArg != "mesh") leafModes.push_back(true);
  if (leavesArg != "payload") leafModes.push_back(false);
  threads = resolveThreads(threads);
  if (backend != "cpu" && backend != "opencl" && backend != "all")
    throw std::runtime_error("--backend must be cpu, opencl or all");
  const bool useCpu = backend != "opencl", useCl = backend != "cpu";
  const std::string cpuDevice = "host, " + std::to_string(threads) + " OpenMP threads";
  std::shared_ptr<ocl::Context> clCtx;
  std::unique_ptr<ocl::Builder> clBuilder;
  std::unique_ptr<ocl::Tracer> clTracer;
  std::string clDevice;
  bool clWarm = false;
  if (useCl) {  // the back end's own error (no SDK at build time, no device, bad selector)
    clCtx = ocl::Context::shared(deviceSel);
    clDevice = clCtx->deviceLabel();
    clBuilder = std::make_unique<ocl::Builder>(clCtx);
    clTracer = std::make_unique<ocl::Tracer>(clCtx);
    std::fprintf(stderr, "rays_bench: OpenCL device %s\n", clDevice.c_str());
  }

  Scene sc = readScene(scenePath);
  std::fprintf(stderr, "rays_bench: %u triangles, %u frames, %dx%d, %d threads, leaf tests %s, %d rays in flight\n",
               sc.nt, sc.nf, sc.cam.width, sc.cam.height, threads, simdName(tuning.simd), tuning.inFlight);

  const char* testName[2] = {"mt", "watertight"};
  struct MtMethod {
    std::string name;
    TreeKind kind;
  };
  std::vector<MtMethod> mtMethods;
  if (has(methodsArg, "octree")) mtMethods.push_back({"matrix-octree", TreeKind::Octree});
  if (has(methodsArg, "kdtree")) mtMethods.push_back({"matrix-kdtree", TreeKind::RegularKd});
  std::vector<SahTraversal> sahTravs;
  if (has(methodsArg, "sah-restart")) sahTravs.push_back(SahTraversal::Restart);
  if (has(methodsArg, "sah-stack")) sahTravs.push_back(SahTraversal::Stack);
  if (has(methodsArg, "sah-shortstack")) sahTravs.push_back(SahTraversal::ShortStack);
#ifdef MT_HAVE_EMBREE
  std::vector<std::unique_ptr<EmbreeScene>> embree;
  if (useCpu)
    for (auto m : {EmbreeScene::Default, EmbreeScene::Low, EmbreeScene::Refit})
      if (has(methodsArg, std::string("embree-") + (m == EmbreeScene::Default ? "default" : m == EmbreeScene::Low ? "low" : "refit")))
        embree.push_back(std::make_unique<EmbreeScene>(threads, m));
#endif

  // Rows in output order.
  std::vector<Row> rows;
  auto rowFor = [&](const std::string& m, const std::string& t, TriangleTest test, bool payload,
                    const std::string& be = "cpu") -> Row& {
    for (auto& r : rows)
      if (r.method == m && r.traversal == t && r.test == testName[int(test)] && r.payload == payload && r.backend == be)
        return r;
    Row row;
    row.method = m;
    row.traversal = t;
    row.test = testName[int(test)];
    row.payload = payload;
    row.backend = be;
    row.device = be == "cpu" ? cpuDevice : clDevice;
    rows.push_back(row);
    return rows.back();
  };
  if (useCpu) {
    for (const auto& m : mtMethods)
      for (auto t : tests)
        for (bool pl : leafModes) rowFor(m.name, "matrix", t, pl);
    for (auto tr : sahTravs)
      for (auto t : tests)
        for (bool pl : leafModes) rowFor("sah", sahTraversalName(tr), t, pl);
#ifdef MT_HAVE_EMBREE
    for (const auto& e : embree) rowFor("embree3", EmbreeScene::name(e->mode), TriangleTest::MollerTrumbore, false).test = "embree-float";
#endif
  }
  if (useCl)
    for (const auto& m : mtMethods) rowFor(m.name, "matrix", TriangleTest::MollerTrumbore, false, "opencl");
  if (!useCpu) sahTravs.clear();
  const bool wantPayload = leavesArg != "mesh";

  std::vector<MatrixTree> mtTrees(mtMethods.size());
  std::vector<LeafTriangles> mtPayloads(mtMethods.size());
  SahKdTree sah;
  LeafTriangles sahPayload;
  std::vector<Sample> firstRef, lastRef;
  RenderOptions ropt;
  ropt.threads = threads;
  RenderOptions countOpt = ropt;
  countOpt.counters = true;
  std::vector<Vec3> missDirs;  // the first frame's in-box misses (from the first counted render)

  for (uint32_t fi = 0; fi < sc.nf; ++fi) {
    const TriangleMesh mesh(sc.frames[fi], sc.tris);
    const Box box = pointBox(sc.frames[fi]);
    const bool check = samples > 0 && (fi == 0 || fi + 1 == sc.nf);
    std::vector<Sample> ref;
    if (check) {
      ref = referenceHits(mesh, sc.cam, samples, 0x5EEDull + fi, threads);
      if (fi == 0) firstRef = ref;
      if (fi + 1 == sc.nf) lastRef = ref;
    }
    // The row's frame: times (medians of `repeat`), the work counted in an untimed render with
    // counters, and the timed render's first hits against the brute force.
    auto account = [&](Row& row, const RenderResult& timed, const RenderResult& counted, double bms, double rms,
                       double rcpu, double bcpu) {
      row.buildMs.push_back(bms);
      row.buildCpuMs.push_back(bcpu);
      row.renderMs.push_back(rms);
      row.renderCpuMs.push_back(rcpu);
      row.rays += double(counted.primaryRays + counted.shadowRays);
      row.primary += double(counted.primaryRays);
      row.nodeVisits += double(counted.stats.nodeVisits);
      row.triTests += double(counted.stats.primTests);
      if (check) {
        row.mismatches += countMismatches(timed, ref, row.method == "embree3" ? 1e-5 : 1e-6);
        row.checked += ref.size();
      }
      if (fi == 0 && !heatDir.empty() && row.backend == "cpu") {
        const std::string base = heatDir + "/" + row.name();
        writeRaw(base + ".visits", counted.nodeVisits.data(), counted.nodeVisits.size() * 4);
        writeRaw(base + ".tests", counted.primTests.data(), counted.primTests.size() * 4);
        writeRaw(base + ".rgb", timed.rgb.data(), timed.rgb.size());
      }
    };

    // `repeat` renders of this frame through `tracer` without counters (wall and CPU times, the
    // last result), then one with counters, untimed; on the first frame, the in-box misses.
    auto measure = [&](Row& row, const auto& tracer, double bms, double bcpu) {
      std::vector<double> wall, cpu;
      RenderResult timed;
      for (int k = 0; k < repeat; ++k) {
        const double c0 = cpuMs();
        timed = render(tracer, mesh, box, sc.cam, ropt);
        cpu.push_back(cpuMs() - c0);
        wall.push_back(timed.ms);
      }
      const RenderResult counted = render(tracer, mesh, box, sc.cam, countOpt);
      account(row, timed, counted, bms, median(wall), median(cpu), bcpu);
      if (fi != 0) return;
      if (missDirs.empty()) inBoxMisses(sc.cam, box, counted, missDirs);
      if (missDirs.empty()) return;
      // The misses alone, in batches of a row's length, without counters (median of `repeat`).
      const std::vector<Vec3> eyes(missDirs.size(), sc.cam.eye);
      std::vector<RayHit> hits(missDirs.size());
      const size_t chunk = size_t(std::max(1, sc.cam.width));
      std::vector<double> mt;
      for (int k = 0; k < repeat; ++k) {
        const double c0 = cpuMs();
        for (size_t at = 0; at < missDirs.size(); at += chunk) {
          RayBatch b;
          b.o = eyes.data() + at;
          b.d = missDirs.data() + at;
          b.n = std::min(chunk, missDirs.size() - at);
          detail::firstHits(tracer, b, hits.data() + at, RayCounters{});
        }
        mt.push_back(cpuMs() - c0);
      }
      std::vector<uint32_t> v(missDirs.size(), 0), t(missDirs.size(), 0);
      for (size_t at = 0; at < missDirs.size(); at += chunk) {
        RayBatch b;
        b.o = eyes.data() + at;
        b.d = missDirs.data() + at;
        b.n = std::min(chunk, missDirs.size() - at);
        detail::firstHits(tracer, b, hits.data() + at, RayCounters{v.data() + at, t.data() + at});
      }
      row.missRays = double(missDirs.size());
      row.missCpuMs = median(mt);
      double vs = 0;
      for (uint32_t x : v) vs += x;
      row.missVisits = vs;
    };

    for (size_t mi = 0; mi < mtMethods.size(); ++mi) {
      BuildOptions bo;
      bo.kind = mtMethods[mi].kind;
      bo.threads = threads;
      bo.height = bo.kind == TreeKind::Octree ? octHeight : kdHeight;
      bo.leafScale = leafScale;
      bo.maxCandidates = maxCandidates;
      std::vector<double> bt, bc, pt, pc;
      BuildStats bs;
      RenderResult cpuMt;  // the CPU engine's Moller-Trumbore render of this frame, for the device rows
      bool haveCpuMt = false;
      for (int k = 0; useCpu && k < repeat; ++k) {
        bs = BuildStats{};
        const double c0 = cpuMs();
        const auto t0 = Clock::now();
        MatrixTreeBuilder<TriangleMesh>::build(mesh, bo, mtTrees[mi], &bs);
        bt.push_back(msSince(t0));
        bc.push_back(cpuMs() - c0);
        // The payload is part of the build of a frame that renders with it.
        const double p0 = cpuMs();
        const auto tp = Clock::now();
        if (wantPayload)
          mtPayloads[mi].build(mtTrees[mi].primitiveIndices().data(), mtTrees[mi].primitiveIndices().size(), mesh,
                               threads);
        pt.push_back(msSince(tp));
        pc.push_back(cpuMs() - p0);
      }
      for (auto test : tests) {
        if (!useCpu) break;
        for (bool pl : leafModes) {
          Row& row = rowFor(mtMethods[mi].name, "matrix", test, pl);
          MatrixTreeTracer tracer{mtTrees[mi], mesh, test, pl ? &mtPayloads[mi] : nullptr, tuning};
          measure(row, tracer, median(bt) + (pl ? median(pt) : 0), median(bc) + (pl ? median(pc) : 0));
          row.payloadMs.push_back(pl ? median(pc) : 0);
          row.bytes = mtTrees[mi].bytes();
          row.payloadBytes = pl ? mtPayloads[mi].bytes() : 0;
          row.height = mtTrees[mi].height();
          row.references = bs.references;
          row.nodes = bs.leaves;
        }
        if (test == TriangleTest::MollerTrumbore && useCl) {
          cpuMt = render(MatrixTreeTracer{mtTrees[mi], mesh, test, wantPayload ? &mtPayloads[mi] : nullptr, tuning},
                         mesh, box, sc.cam, ropt);
          haveCpuMt = true;
        }
      }
      if (useCl) {
        Row& row = rowFor(mtMethods[mi].name, "matrix", TriangleTest::MollerTrumbore, false, "opencl");
        MatrixTree clTree;
        BuildStats cbs;
        std::vector<double> cbt, cbc, cut, crt, ctt, cct;
        if (!clWarm) {  // untimed: the first use compiles the kernels (seconds on PoCL)
          double tms = 0;
          clBuilder->build(mesh, bo, clTree);
          clTracer->upload(clTree, mesh);
          renderOpenCL(*clTracer, mesh, box, sc.cam, ropt, &tms);
          clWarm = true;
        }
        for (int k = 0; k < repeat; ++k) {
          cbs = BuildStats{};
          const double bc0 = cpuMs();
          auto t0 = Clock::now();
          clBuilder->build(mesh, bo, clTree, &cbs);
          const double b = msSince(t0);
          t0 = Clock::now();
          clTracer->upload(clTree, mesh);
          cut.push_back(msSince(t0));
          cbt.push_back(b + cut.back());
          cbc.push_back(cpuMs() - bc0);  // PoCL's threads belong to this process: its CPU time counts
        }
        RenderResult r;
        for (int k = 0; k < repeat; ++k) {
          double tms = 0;
          const double c0 = cpuMs();
          r = renderOpenCL(*clTracer, mesh, box, sc.cam, ropt, &tms);
          cct.push_back(cpuMs() - c0);
          crt.push_back(r.ms);
          ctt.push_back(tms);
        }
        double untimed = 0;
        const RenderResult counted = renderOpenCL(*clTracer, mesh, box, sc.cam, countOpt, &untimed);
        account(row, r, counted, median(cbt), median(crt), median(cct), median(cbc));
        row.uploadMs.push_back(median(cut));
        row.traceMs.push_back(median(ctt));
        row.bytes = clTree.bytes();
        row.height = clTree.height();
        row.references = cbs.references;
        row.nodes = cbs.leaves;
        if (!haveCpuMt && check) {  // --backend opencl: the CPU engine's render, untimed
          MatrixTreeBuilder<TriangleMesh>::build(mesh, bo, mtTrees[mi], nullptr);
          cpuMt = render(MatrixTreeTracer{mtTrees[mi], mesh, TriangleTest::MollerTrumbore}, mesh, box, sc.cam, ropt);
          haveCpuMt = true;
        }
        if (haveCpuMt) {
          compareRenders(r, cpuMt, &row.cpuMismatches, &row.shadeMismatches);
          row.cpuChecked += cpuMt.hitPrim.size();
        }
      }
    }
    if (!sahTravs.empty()) {
      std::vector<double> bt, bc, pt, pc;
      for (int k = 0; k < repeat; ++k) {
        const double c0 = cpuMs();
        const auto t0 = Clock::now();
        sah.build(mesh);
        bt.push_back(msSince(t0));
        bc.push_back(cpuMs() - c0);
        const double p0 = cpuMs();
        const auto tp = Clock::now();
        if (wantPayload) sah.primitiveIndices().empty() ? sahPayload.clear()
                                                        : sahPayload.build(sah.primitiveIndices().data(),
                                                                           sah.primitiveIndices().size(), mesh, threads);
        pt.push_back(msSince(tp));
        pc.push_back(cpuMs() - p0);
      }
      for (auto tr : sahTravs) {
        for (auto test : tests) {
          for (bool pl : leafModes) {
            Row& row = rowFor("sah", sahTraversalName(tr), test, pl);
            SahTracer tracer{sah, mesh, tr, test, shortStack, pl ? &sahPayload : nullptr, tuning};
            measure(row, tracer, median(bt) + (pl ? median(pt) : 0), median(bc) + (pl ? median(pc) : 0));
            row.payloadMs.push_back(pl ? median(pc) : 0);
            row.bytes = sah.bytes();
            row.payloadBytes = pl ? sahPayload.bytes() : 0;
            row.height = sah.stats().depth;
            row.references = sah.stats().references;
            row.nodes = sah.stats().nodes;
          }
        }
      }
    }
#ifdef MT_HAVE_EMBREE
    for (const auto& e : embree) {
      Row* row = nullptr;
      for (auto& r : rows)
        if (r.method == "embree3" && r.traversal == EmbreeScene::name(e->mode)) row = &r;
      // The refit build needs the first frame's BVH: `repeat` builds refit it to the same points.
      std::vector<double> bt, bc;
      for (int k = 0; k < repeat; ++k) {
        const double c0 = cpuMs();
        const auto t0 = Clock::now();
        e->build(sc, sc.frames[fi]);
        bt.push_back(msSince(t0));
        bc.push_back(cpuMs() - c0);
      }
      measure(*row, EmbreeTracer{e->scene}, median(bt), median(bc));
      row->payloadMs.push_back(0);
    }
#endif
    std::fprintf(stderr, "\rrays_bench: frame %u/%u", fi + 1, sc.nf);
  }
  std::fprintf(stderr, "\n");

  std::ofstream out(outPath);
  out.precision(9);
  out << "{\n  \"threads\": " << threads << ",\n  \"triangles\": " << sc.nt << ",\n  \"frames\": " << sc.nf
      << ",\n  \"width\": " << sc.cam.width << ",\n  \"height\": " << sc.cam.height << ",\n  \"simd\": \""
      << simdName(tuning.simd) << "\",\n  \"in_flight\": " << tuning.inFlight << ",\n  \"rows\": [\n";
  for (size_t i = 0; i < rows.size(); ++i) {
    const Row& r = rows[i];
    double b = 0, m = 0, mc = 0, bcpu = 0, pms = 0;
    for (double x : r.renderCpuMs) mc += x;
    for (double x : r.buildCpuMs) bcpu += x;
    for (double x : r.buildMs) b += x;
    for (double x : r.renderMs) m += x;
    for (double x : r.payloadMs) pms += x;
    const double nf = double(std::max<size_t>(1, r.renderMs.size()));
    out << "    {\"method\": \"" << r.method << "\", \"traversal\": \"" << r.traversal << "\", \"test\": \""
        << r.test << "\", \"leaves\": \"" << (r.method == "embree3" ? "embree" : r.payload ? "payload" : "mesh")
        << "\", \"build_ms\": " << b / nf
        << ", \"build_cpu_ms\": " << bcpu / nf << ", \"payload_cpu_ms\": " << pms / nf
        << ", \"render_ms\": " << m / nf << ", \"render_cpu_ms\": " << mc / nf
        << ", \"rays\": " << r.rays / nf << ", \"primary_rays\": " << r.primary / nf
        << ", \"node_visits_per_ray\": " << (r.rays > 0 ? r.nodeVisits / r.rays : 0)
        << ", \"tri_tests_per_ray\": " << (r.rays > 0 ? r.triTests / r.rays : 0)
        << ", \"ns_per_visit\": " << (r.nodeVisits > 0 ? 1e6 * mc / r.nodeVisits : 0)
        << ", \"miss_rays\": " << r.missRays
        << ", \"miss_ns_per_ray\": " << (r.missRays > 0 ? 1e6 * r.missCpuMs / r.missRays : 0)
        << ", \"miss_visits_per_ray\": " << (r.missRays > 0 ? r.missVisits / r.missRays : 0)
        << ", \"mismatches_vs_brute_force\": " << r.mismatches << ", \"rays_checked\": " << r.checked
        << ", \"bytes\": " << r.bytes << ", \"payload_bytes\": " << r.payloadBytes << ", \"height\": " << r.height
        << ", \"references\": " << r.references
        << ", \"nodes\": " << r.nodes << ", \"build_ms_frames\": " << jsonNumbers(r.buildMs)
        << ", \"render_ms_frames\": " << jsonNumbers(r.renderMs) << ", \"backend\": \"" << r.backend
        << "\", \"device\": \"" << r.device << "\"";
    if (r.backend != "cpu") {
      double u = 0, tr = 0;
      for (double x : r.uploadMs) u += x;
      for (double x : r.traceMs) tr += x;
      out << ", \"upload_ms\": " << u / nf << ", \"trace_ms\": " << tr / nf
          << ", \"mismatches_vs_cpu\": " << r.cpuMismatches << ", \"pixels_vs_cpu\": " << r.cpuChecked
          << ", \"shading_mismatches_vs_cpu\": " << r.shadeMismatches;
    }
    out << "}" << (i + 1 < rows.size() ? "," : "") << "\n";
  }
  out << "  ],\n  \"reference\": {\"pixels\": [";
  for (size_t i = 0; i < firstRef.size(); ++i) out << (i ? "," : "") << firstRef[i].pixel;
  out << "], \"prim\": [";
  for (size_t i = 0; i < firstRef.size(); ++i)
    out << (i ? "," : "") << (firstRef[i].ref.hit() ? int64_t(firstRef[i].ref.prim) : -1);
  out << "], \"t\": [";
  for (size_t i = 0; i < firstRef.size(); ++i)
    out << (i ? "," : "") << (firstRef[i].ref.hit() ? firstRef[i].ref.t : -1.0);
  out << "]}\n}\n";
  if (!out) throw std::runtime_error("cannot write " + outPath);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "rays_bench: error: %s\n", e.what());
    return 1;
  }
}

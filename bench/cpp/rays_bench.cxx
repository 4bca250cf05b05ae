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

#include "mtree/core/builder.h"
#include "mtree/rays/intersect.h"
#include "mtree/device/opencl.h"
#include "mtree/device/opencl_render.h"
#include "mtree/rays/render.h"
#include "mtree/rays/sah_kdtree.h"

namespace {

using namespace mtree;
using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

struct Scene {
  uint32_t nv = 0, nt = 0, nf = 0;
  Camera cam;
  std::vector<uint32_t> tris;
  std::vector<std::vector<double>> frames;
};

Scene readScene(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw std::runtime_error("cannot open scene file " + path);
  char magic[8];
  f.read(magic, 8);
  if (!f || std::memcmp(magic, "MTSCENE1", 8) != 0) throw std::runtime_error(path + ": not an MTSCENE1 file");
  Scene s;
  uint32_t hdr[5];
  f.read(reinterpret_cast<char*>(hdr), sizeof hdr);
  double cam[10];
  f.read(reinterpret_cast<char*>(cam), sizeof cam);
  if (!f) throw std::runtime_error(path + ": truncated header");
  s.nv = hdr[0];
  s.nt = hdr[1];
  s.nf = hdr[2];
  s.cam.width = static_cast<int>(hdr[3]);
  s.cam.height = static_cast<int>(hdr[4]);
  s.cam.eye = Vec3(cam[0], cam[1], cam[2]);
  s.cam.target = Vec3(cam[3], cam[4], cam[5]);
  s.cam.up = Vec3(cam[6], cam[7], cam[8]);
  s.cam.fovyDegrees = cam[9];
  if (s.nf == 0 || s.cam.width <= 0 || s.cam.height <= 0) throw std::runtime_error(path + ": no frames or empty image");
  s.tris.resize(size_t(s.nt) * 3);
  f.read(reinterpret_cast<char*>(s.tris.data()), std::streamsize(s.tris.size() * sizeof(uint32_t)));
  s.frames.resize(s.nf);
  for (auto& fr : s.frames) {
    fr.resize(size_t(s.nv) * 3);
    f.read(reinterpret_cast<char*>(fr.data()), std::streamsize(fr.size() * sizeof(double)));
  }
  if (!f) throw std::runtime_error(path + ": truncated triangles or frames");
  return s;
}

Box pointBox(const std::vector<double>& p) {
  Box b;
  for (size_t i = 0; i + 2 < p.size(); i += 3) b.extend(Vec3(p[i], p[i + 1], p[i + 2]));
  return b;
}

// CPU time of the whole process (all threads): with one thread, a timing that other processes
// sharing the machine disturb much less than the wall clock.
double cpuMs() {
  timespec ts;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return 1e3 * double(ts.tv_sec) + 1e-6 * double(ts.tv_nsec);
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

struct Row {
  std::string method, traversal, test;
  std::vector<double> buildMs, renderMs, renderCpuMs, buildCpuMs;
  double rays = 0, primary = 0, nodeVisits = 0, triTests = 0, leaves = 0;  // summed over frames
  uint64_t mismatches = 0, checked = 0;
  size_t bytes = 0;
  int height = 0;
  uint64_t nodes = 0, references = 0;
  std::string backend = "cpu", device;
  std::vector<double> uploadMs, traceMs;                      // opencl rows
  uint64_t cpuMismatches = 0, cpuChecked = 0, shadeMismatches = 0;  // opencl rows vs the CPU render
  std::string name() const { return method + "-" + traversal + "-" + test + (backend == "cpu" ? "" : "-" + backend); }
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

uint64_t countMismatches(const RenderResult& r, const std::vector<Sample>& samples) {
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
    if (std::fabs(t - s.ref.t) > 1e-6 * std::max(1.0, std::fabs(s.ref.t))) ++bad;
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

int run(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr,
                 "usage: rays_bench SCENE.bin OUT.json [--threads T] [--repeat R] [--tests mt,watertight]\n"
                 "       [--methods octree,kdtree,sah-restart,sah-stack,sah-shortstack] [--short-stack K]\n"
                 "       [--samples S] [--heatmaps DIR] [--backend cpu|opencl|all] [--device SEL]\n");
    return 2;
  }
  const std::string scenePath = argv[1], outPath = argv[2];
  int threads = 0, repeat = 1, samples = 2000, shortStack = 3, octHeight = 0, kdHeight = 0;
  double leafScale = BuildOptions{}.leafScale, maxCandidates = BuildOptions{}.maxCandidates;
  std::string testsArg = "mt,watertight", methodsArg = "octree,kdtree,sah-restart,sah-stack,sah-shortstack";
  std::string heatDir, backend = "cpu", deviceSel;
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
    else throw std::runtime_error("unknown option " + a);
  }
  auto has = [](const std::string& list, const std::string& item) {
    return ("," + list + ",").find("," + item + ",") != std::string::npos;
  };
  std::vector<TriangleTest> tests;
  if (has(testsArg, "mt")) tests.push_back(TriangleTest::MollerTrumbore);
  if (has(testsArg, "watertight")) tests.push_back(TriangleTest::Watertight);
  if (tests.empty()) throw std::runtime_error("--tests must name mt and/or watertight");
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
  std::fprintf(stderr, "rays_bench: %u triangles, %u frames, %dx%d, %d threads\n", sc.nt, sc.nf, sc.cam.width,
               sc.cam.height, threads);

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

  // Rows in output order.
  std::vector<Row> rows;
  auto rowFor = [&](const std::string& m, const std::string& t, TriangleTest test,
                    const std::string& be = "cpu") -> Row& {
    for (auto& r : rows)
      if (r.method == m && r.traversal == t && r.test == testName[int(test)] && r.backend == be) return r;
    Row row;
    row.method = m;
    row.traversal = t;
    row.test = testName[int(test)];
    row.backend = be;
    row.device = be == "cpu" ? cpuDevice : clDevice;
    rows.push_back(row);
    return rows.back();
  };
  if (useCpu) {
    for (const auto& m : mtMethods)
      for (auto t : tests) rowFor(m.name, "matrix", t);
    for (auto tr : sahTravs)
      for (auto t : tests) rowFor("sah", sahTraversalName(tr), t);
  }
  if (useCl)
    for (const auto& m : mtMethods) rowFor(m.name, "matrix", TriangleTest::MollerTrumbore, "opencl");
  if (!useCpu) sahTravs.clear();

  std::vector<MatrixTree> mtTrees(mtMethods.size());
  SahKdTree sah;
  std::vector<Sample> firstRef, lastRef;
  RenderOptions ropt;
  ropt.threads = threads;

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
    auto account = [&](Row& row, const RenderResult& r, double bms, double rms, double rcpu, double bcpu = 0) {
      row.buildMs.push_back(bms);
      row.buildCpuMs.push_back(bcpu);
      row.renderMs.push_back(rms);
      row.renderCpuMs.push_back(rcpu);
      row.rays += double(r.primaryRays + r.shadowRays);
      row.primary += double(r.primaryRays);
      row.nodeVisits += double(r.stats.nodeVisits);
      row.triTests += double(r.stats.primTests);
      row.leaves += double(r.stats.cells);
      if (check) {
        row.mismatches += countMismatches(r, ref);
        row.checked += ref.size();
      }
      if (fi == 0 && !heatDir.empty() && row.backend == "cpu") {
        const std::string base = heatDir + "/" + row.name();
        writeRaw(base + ".visits", r.nodeVisits.data(), r.nodeVisits.size() * 4);
        writeRaw(base + ".tests", r.primTests.data(), r.primTests.size() * 4);
        writeRaw(base + ".rgb", r.rgb.data(), r.rgb.size());
      }
    };

    // `repeat` renders of this frame through `tracer`: wall and CPU times, the last result.
    auto timedRenders = [&](const auto& tracer, std::vector<double>& wall, std::vector<double>& cpu) {
      RenderResult r;
      for (int k = 0; k < repeat; ++k) {
        const double c0 = cpuMs();
        r = render(tracer, mesh, box, sc.cam, ropt);
        cpu.push_back(cpuMs() - c0);
        wall.push_back(r.ms);
      }
      return r;
    };

    for (size_t mi = 0; mi < mtMethods.size(); ++mi) {
      BuildOptions bo;
      bo.kind = mtMethods[mi].kind;
      bo.threads = threads;
      bo.height = bo.kind == TreeKind::Octree ? octHeight : kdHeight;
      bo.leafScale = leafScale;
      bo.maxCandidates = maxCandidates;
      std::vector<double> bt, bc;
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
      }
      for (auto test : tests) {
        if (!useCpu) break;
        Row& row = rowFor(mtMethods[mi].name, "matrix", test);
        MatrixTreeTracer tracer{mtTrees[mi], mesh, test};
        std::vector<double> rt, ct;
        const RenderResult r = timedRenders(tracer, rt, ct);
        account(row, r, median(bt), median(rt), median(ct), median(bc));
        row.bytes = mtTrees[mi].bytes();
        row.height = mtTrees[mi].height();
        row.references = bs.references;
        row.nodes = bs.leaves;
        if (test == TriangleTest::MollerTrumbore) {
          cpuMt = std::move(r);
          haveCpuMt = true;
        }
      }
      if (useCl) {
        Row& row = rowFor(mtMethods[mi].name, "matrix", TriangleTest::MollerTrumbore, "opencl");
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
        account(row, r, median(cbt), median(crt), median(cct), median(cbc));
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
      std::vector<double> bt, bc;
      for (int k = 0; k < repeat; ++k) {
        const double c0 = cpuMs();
        const auto t0 = Clock::now();
        sah.build(mesh);
        bt.push_back(msSince(t0));
        bc.push_back(cpuMs() - c0);
      }
      for (auto tr : sahTravs) {
        for (auto test : tests) {
          Row& row = rowFor("sah", sahTraversalName(tr), test);
          SahTracer tracer{sah, mesh, tr, test, shortStack};
          std::vector<double> rt, ct;
          const RenderResult r = timedRenders(tracer, rt, ct);
          account(row, r, median(bt), median(rt), median(ct), median(bc));
          row.bytes = sah.bytes();
          row.height = sah.stats().depth;
          row.references = sah.stats().references;
          row.nodes = sah.stats().nodes;
        }
      }
    }
    std::fprintf(stderr, "\rrays_bench: frame %u/%u", fi + 1, sc.nf);
  }
  std::fprintf(stderr, "\n");

  std::ofstream out(outPath);
  out.precision(9);
  out << "{\n  \"threads\": " << threads << ",\n  \"triangles\": " << sc.nt << ",\n  \"frames\": " << sc.nf
      << ",\n  \"width\": " << sc.cam.width << ",\n  \"height\": " << sc.cam.height << ",\n  \"rows\": [\n";
  for (size_t i = 0; i < rows.size(); ++i) {
    const Row& r = rows[i];
    double b = 0, m = 0, mc = 0, bcpu = 0;
    for (double x : r.renderCpuMs) mc += x;
    for (double x : r.buildCpuMs) bcpu += x;
    for (double x : r.buildMs) b += x;
    for (double x : r.renderMs) m += x;
    const double nf = double(std::max<size_t>(1, r.renderMs.size()));
    out << "    {\"method\": \"" << r.method << "\", \"traversal\": \"" << r.traversal << "\", \"test\": \""
        << r.test << "\", \"build_ms\": " << b / nf << ", \"build_cpu_ms\": " << bcpu / nf << ", \"render_ms\": " << m / nf << ", \"render_cpu_ms\": " << mc / nf
        << ", \"rays\": " << r.rays / nf << ", \"primary_rays\": " << r.primary / nf
        << ", \"node_visits_per_ray\": " << (r.rays > 0 ? r.nodeVisits / r.rays : 0)
        << ", \"tri_tests_per_ray\": " << (r.rays > 0 ? r.triTests / r.rays : 0)
        << ", \"leaves_per_ray\": " << (r.rays > 0 ? r.leaves / r.rays : 0)
        << ", \"mismatches_vs_brute_force\": " << r.mismatches << ", \"rays_checked\": " << r.checked
        << ", \"bytes\": " << r.bytes << ", \"height\": " << r.height << ", \"references\": " << r.references
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

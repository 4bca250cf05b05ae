// The scene file of the ray benchmarks (written by bench/rays.py's write_scene_file), the
// brute-force check on sampled pixels, and CPU-clock timing: for bench/cpp/trees_bench.cxx.
//
// SCENE.bin (little endian): char[8] "MTSCENE1"; uint32 nverts, ntris, nframes, width, height;
// double eye[3], target[3], up[3], fovy; uint32 triangles[ntris][3]; then per frame double
// points[nverts][3].
#pragma once

#include <time.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "mtree/rays/raycast.h"
#include "mtree/rays/render.h"

namespace mtbench {

struct Scene {
  uint32_t nv = 0, nt = 0, nf = 0;
  mtree::Camera cam;
  std::vector<uint32_t> tris;
  std::vector<std::vector<double>> frames;
};

inline Scene readScene(const std::string& path) {
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
  s.cam.eye = mtree::Vec3(cam[0], cam[1], cam[2]);
  s.cam.target = mtree::Vec3(cam[3], cam[4], cam[5]);
  s.cam.up = mtree::Vec3(cam[6], cam[7], cam[8]);
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

/// CPU time of the process (all threads): with one thread, a timing that other processes on the
/// machine disturb much less than the wall clock.
inline double cpuMs() {
  timespec ts;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return 1e3 * double(ts.tv_sec) + 1e-6 * double(ts.tv_nsec);
}

struct Sample {
  int pixel;
  mtree::RayHit ref;
};

/// The brute force's first hits on `samples` seeded pixels (splitmix64) of the camera's rays.
inline std::vector<Sample> referenceHits(const mtree::TriangleMesh& mesh, const mtree::Camera& cam, int samples,
                                         uint64_t seed) {
  const mtree::PinholeRays rays(cam);
  const int npix = cam.width * cam.height;
  std::vector<Sample> out(std::min(samples, npix));
  uint64_t s = seed;
  for (auto& smp : out) {
    uint64_t z = (s += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    z ^= z >> 31;
    smp.pixel = static_cast<int>(z % uint64_t(npix));
    const int x = smp.pixel % cam.width, y = smp.pixel / cam.width;
    mtree::intersectFirstBruteForce(mesh, cam.eye, rays.direction(x, y), 0.0,
                                    std::numeric_limits<double>::infinity(), smp.ref);
  }
  return out;
}

/// Sampled pixels whose primary hit differs from the brute force's (another triangle is accepted
/// at the same t within 1e-6 relative: a tie on a shared edge).
inline uint64_t countMismatches(const mtree::RenderResult& r, const std::vector<Sample>& samples) {
  uint64_t bad = 0;
  for (const auto& s : samples) {
    const uint32_t got = r.hitPrim[size_t(s.pixel)];
    if (got == s.ref.prim) continue;
    if ((got != MT_NULL) != s.ref.hit()) {
      ++bad;
      continue;
    }
    const double t = r.depth[size_t(s.pixel)];
    if (std::fabs(t - s.ref.t) > 1e-6 * std::max(1.0, std::fabs(s.ref.t))) ++bad;
  }
  return bad;
}

}  // namespace mtbench

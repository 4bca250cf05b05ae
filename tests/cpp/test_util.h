// Shared helpers of the C++ tests (header-only): mesh loading through VTK's readers, the shared
// data directory, the list of real meshes, seeded random numbers, synthetic meshes, and a fast
// brute-force ray reference that uses exactly the arithmetic of mtree::rayTriangleMT.
#pragma once

#include <gtest/gtest.h>
#include <vtkAlgorithm.h>
#include <vtkCellArray.h>
#include <vtkIdList.h>
#include <vtkNew.h>
#include <vtkOBJReader.h>
#include <vtkPLYReader.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkPolyDataReader.h>
#include <vtkSTLReader.h>
#include <vtkSmartPointer.h>
#include <vtkTriangleFilter.h>
#include <vtkXMLPolyDataReader.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <limits>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <vector>

#include "mtree/core/builder.h"
#include "mtree/core/geometry.h"
#include "mtree/core/matrix_tree.h"
#include "mtree/core/primitives.h"
#include "mtree/rays/raycast.h"

namespace mtest {

using mtree::Box;
using mtree::Vec3;

// ---------------------------------------------------------------------------------------------
// Data
// ---------------------------------------------------------------------------------------------

/// Absolute path of a file of the shared data directory ($MATRIXTREE_DATA, set by ctest).
inline std::string dataPath(const std::string& rel) {
  const char* env = std::getenv("MATRIXTREE_DATA");
  std::filesystem::path dir;
  if (env && *env) {
    dir = env;
  } else {
#ifdef MATRIXTREE_SOURCE_DIR
    dir = std::filesystem::path(MATRIXTREE_SOURCE_DIR) / ".." / "shared" / "data";
#else
    dir = std::filesystem::path("..") / "shared" / "data";
#endif
  }
  return (dir / rel).lexically_normal().string();
}

/// The 7 real meshes (paths relative to the data directory).
inline const std::vector<std::string>& realMeshes() {
  static const std::vector<std::string> list = {"meshes/bunny.ply",          "meshes/lucy.ply",
                                                "meshes/horse.ply",          "meshes/turbineblade.ply",
                                                "meshes/nefertiti.obj",      "scenes/utah_hand/hand_00.obj",
                                                "scenes/utah_ben/ben_00.obj"};
  return list;
}

/// A name usable in a GoogleTest parameter name: "scenes/utah_hand/hand_00.obj" -> "hand_00".
inline std::string meshTag(const std::string& rel) {
  std::string stem = std::filesystem::path(rel).stem().string();
  std::string out;
  for (char c : stem) out += std::isalnum(static_cast<unsigned char>(c)) ? c : '_';
  return out;
}

/// Reads a surface mesh with VTK (.ply, .obj, .stl, .vtp, .vtk), triangulates polygons and strips,
/// drops vertices and lines, and merges points with bit-identical coordinates (vtkOBJReader
/// duplicates a vertex for every face corner). Triangle order is the reader's cell order.
/// A missing or unreadable file fails the current test and throws (so the test stops there).
inline mtree::TriangleMesh loadMesh(const std::string& path) {
  auto fail = [&](const std::string& why) -> mtree::TriangleMesh {
    const std::string msg = "loadMesh(" + path + "): " + why;
    ADD_FAILURE() << msg;
    throw std::runtime_error(msg);
  };
  if (!std::filesystem::is_regular_file(path))
    return fail("file not found (is MATRIXTREE_DATA set to the shared data directory?)");
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });

  vtkSmartPointer<vtkAlgorithm> reader;
  if (ext == ".ply") {
    auto r = vtkSmartPointer<vtkPLYReader>::New();
    r->SetFileName(path.c_str());
    reader = r;
  } else if (ext == ".obj") {
    auto r = vtkSmartPointer<vtkOBJReader>::New();
    r->SetFileName(path.c_str());
    reader = r;
  } else if (ext == ".stl") {
    auto r = vtkSmartPointer<vtkSTLReader>::New();
    r->SetFileName(path.c_str());
    reader = r;
  } else if (ext == ".vtp") {
    auto r = vtkSmartPointer<vtkXMLPolyDataReader>::New();
    r->SetFileName(path.c_str());
    reader = r;
  } else if (ext == ".vtk") {
    auto r = vtkSmartPointer<vtkPolyDataReader>::New();
    r->SetFileName(path.c_str());
    reader = r;
  } else {
    return fail("unsupported extension '" + ext + "'");
  }
  vtkNew<vtkTriangleFilter> tri;
  tri->SetInputConnection(reader->GetOutputPort());
  tri->PassVertsOff();
  tri->PassLinesOff();
  tri->Update();
  vtkPolyData* pd = tri->GetOutput();
  if (!pd || !pd->GetPoints() || pd->GetNumberOfPolys() == 0) return fail("no triangles read");

  // Merge bit-identical points, in first-use order.
  struct Key {
    uint64_t b[3];
    bool operator==(const Key& o) const { return b[0] == o.b[0] && b[1] == o.b[1] && b[2] == o.b[2]; }
  };
  struct KeyHash {
    size_t operator()(const Key& k) const {
      uint64_t h = 1469598103934665603ull;
      for (uint64_t v : k.b) h = (h ^ v) * 1099511628211ull + (v >> 29);
      return static_cast<size_t>(h);
    }
  };
  std::unordered_map<Key, uint32_t, KeyHash> index;
  std::vector<double> pts;
  std::vector<uint32_t> tris;
  std::vector<int64_t> remap(static_cast<size_t>(pd->GetNumberOfPoints()), -1);
  vtkPoints* p = pd->GetPoints();
  vtkCellArray* polys = pd->GetPolys();
  vtkNew<vtkIdList> ids;
  polys->InitTraversal();
  while (polys->GetNextCell(ids)) {
    if (ids->GetNumberOfIds() != 3) return fail("vtkTriangleFilter left a non-triangle");
    for (int k = 0; k < 3; ++k) {
      const vtkIdType id = ids->GetId(k);
      if (remap[id] < 0) {
        double x[3];
        p->GetPoint(id, x);
        Key key;
        for (int a = 0; a < 3; ++a) {
          const double v = x[a] == 0.0 ? 0.0 : x[a];  // -0 and +0 are one point
          std::memcpy(&key.b[a], &v, sizeof(double));
        }
        auto it = index.find(key);
        if (it == index.end()) {
          it = index.emplace(key, static_cast<uint32_t>(pts.size() / 3)).first;
          pts.insert(pts.end(), x, x + 3);
        }
        remap[id] = it->second;
      }
      tris.push_back(static_cast<uint32_t>(remap[id]));
    }
  }
  return mtree::TriangleMesh(std::move(pts), std::move(tris));
}

inline mtree::TriangleMesh loadRealMesh(const std::string& rel) { return loadMesh(dataPath(rel)); }

// ---------------------------------------------------------------------------------------------
// Random numbers: a fixed generator (splitmix64) so every run and every platform draws the same.
// ---------------------------------------------------------------------------------------------
struct Rng {
  uint64_t s;
  explicit Rng(uint64_t seed) : s(seed) {}
  uint64_t next() {
    uint64_t z = (s += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  double uniform() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }  // [0, 1)
  double uniform(double a, double b) { return a + (b - a) * uniform(); }
  uint32_t below(uint32_t n) { return static_cast<uint32_t>((next() >> 32) * n >> 32); }
  Vec3 inBox(const Box& b) {
    return {uniform(b.lo.x, b.hi.x), uniform(b.lo.y, b.hi.y), uniform(b.lo.z, b.hi.z)};
  }
  Vec3 direction() {  // uniform on the unit sphere
    for (;;) {
      const Vec3 v(uniform(-1, 1), uniform(-1, 1), uniform(-1, 1));
      const double n2 = mtree::dot(v, v);
      if (n2 > 1e-6 && n2 <= 1) return v * (1.0 / std::sqrt(n2));
    }
  }
};

inline uint64_t seedFor(const std::string& s, uint64_t salt = 0) {
  uint64_t h = 1469598103934665603ull ^ salt;
  for (unsigned char c : s) h = (h ^ c) * 1099511628211ull;
  return h;
}

// ---------------------------------------------------------------------------------------------
// Geometry helpers
// ---------------------------------------------------------------------------------------------
inline Box meshBounds(const mtree::TriangleMesh& m) {
  Box b;
  for (size_t i = 0; i < m.numPoints(); ++i) b.extend(Vec3(&m.points()[3 * i]));
  return b;
}

inline Box enlarged(const Box& b, double frac) {
  const Vec3 e = b.extent() * frac;
  Box r;
  r.lo = b.lo - e;
  r.hi = b.hi + e;
  return r;
}

inline mtree::MatrixTree buildTree(const mtree::TriangleMesh& mesh, mtree::BuildOptions opt,
                                   mtree::BuildStats* stats = nullptr) {
  mtree::MatrixTree tree;
  mtree::MatrixTreeBuilder<mtree::TriangleMesh>::build(mesh, opt, tree, stats);
  return tree;
}

/// Asserts that two trees are the same, array for array: height, kind, block edge, root box,
/// every level's shape, pointer matrix and blocks (existence bytes; leaf ranges at the bottom)
/// and the primitive order. `pointers`, if given, must equal the pointer matrix of every level
/// of `a` as well (the OpenCL builder's own pointer matrices).
inline void expectSameTree(const mtree::MatrixTree& a, const mtree::MatrixTree& b, const std::string& what,
                           const std::vector<std::vector<uint32_t>>* pointers = nullptr) {
  SCOPED_TRACE(what);
  ASSERT_EQ(a.empty(), b.empty());
  ASSERT_EQ(a.height(), b.height());
  ASSERT_EQ(a.kind(), b.kind());
  ASSERT_EQ(a.blockEdge(), b.blockEdge());
  if (a.empty()) return;
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(a.rootBox().lo[k], b.rootBox().lo[k]);
    EXPECT_EQ(a.rootBox().hi[k], b.rootBox().hi[k]);
  }
  const int H = a.height();
  for (int l = 0; l <= H; ++l) {
    SCOPED_TRACE("level " + std::to_string(l));
    for (int k = 0; k < 3; ++k) ASSERT_EQ(a.logDim(l, k), b.logDim(l, k));
    const auto& ap = l == H ? a.leafLevel().pointers() : a.innerLevel(l).pointers();
    const auto& bp = l == H ? b.leafLevel().pointers() : b.innerLevel(l).pointers();
    ASSERT_EQ(a.levelBlocks(l), b.levelBlocks(l));
    ASSERT_TRUE(ap == bp) << "pointer matrices differ";
    if (pointers) {
      ASSERT_TRUE((*pointers)[l] == ap) << "device pointer matrix differs";
    }
    if (l < H) {
      ASSERT_TRUE(a.innerLevel(l).data() == b.innerLevel(l).data()) << "existence bytes differ";
    } else {
      const auto& ad = a.leafLevel().data();
      const auto& bd = b.leafLevel().data();
      ASSERT_EQ(ad.size(), bd.size());
      size_t bad = 0;
      for (size_t i = 0; i < ad.size(); ++i) bad += ad[i].begin != bd[i].begin || ad[i].end != bd[i].end;
      ASSERT_EQ(bad, 0u) << "leaf ranges differ";
    }
  }
  ASSERT_TRUE(a.primitiveIndices() == b.primitiveIndices()) << "primitive lists differ";
}

inline mtree::BuildOptions options(mtree::TreeKind kind, int height = 0, int blockEdge = 8, int threads = 0) {
  mtree::BuildOptions o;
  o.kind = kind;
  o.height = height;
  o.blockEdge = blockEdge;
  o.threads = threads;
  return o;
}

/// Icosphere: the icosahedron subdivided `subdiv` times, vertices pushed onto the sphere.
/// 20 * 4^subdiv triangles, shared vertices.
inline mtree::TriangleMesh makeIcosphere(int subdiv, double radius = 1.0, Vec3 center = Vec3(0, 0, 0)) {
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  std::vector<Vec3> v = {{-1, t, 0},  {1, t, 0},  {-1, -t, 0}, {1, -t, 0}, {0, -1, t},  {0, 1, t},
                         {0, -1, -t}, {0, 1, -t}, {t, 0, -1},  {t, 0, 1},  {-t, 0, -1}, {-t, 0, 1}};
  for (Vec3& p : v) p = mtree::normalized(p);
  std::vector<std::array<uint32_t, 3>> f = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                                            {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                                            {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                                            {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  for (int s = 0; s < subdiv; ++s) {
    std::unordered_map<uint64_t, uint32_t> mid;
    auto midpoint = [&](uint32_t a, uint32_t b) {
      const uint64_t key = (uint64_t(std::min(a, b)) << 32) | std::max(a, b);
      auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      v.push_back(mtree::normalized((v[a] + v[b]) * 0.5));
      const uint32_t id = static_cast<uint32_t>(v.size() - 1);
      mid.emplace(key, id);
      return id;
    };
    std::vector<std::array<uint32_t, 3>> nf;
    nf.reserve(f.size() * 4);
    for (const auto& tri : f) {
      const uint32_t a = midpoint(tri[0], tri[1]), b = midpoint(tri[1], tri[2]), c = midpoint(tri[2], tri[0]);
      nf.push_back({tri[0], a, c});
      nf.push_back({tri[1], b, a});
      nf.push_back({tri[2], c, b});
      nf.push_back({a, b, c});
    }
    f.swap(nf);
  }
  std::vector<double> pts;
  for (const Vec3& p : v) {
    pts.push_back(center.x + radius * p.x);
    pts.push_back(center.y + radius * p.y);
    pts.push_back(center.z + radius * p.z);
  }
  std::vector<uint32_t> tris;
  for (const auto& tri : f) tris.insert(tris.end(), tri.begin(), tri.end());
  return mtree::TriangleMesh(std::move(pts), std::move(tris));
}

// ---------------------------------------------------------------------------------------------
// Fast brute-force reference
// ---------------------------------------------------------------------------------------------
struct Ray {
  Vec3 o, d;
  double tmin = 0, tmax = std::numeric_limits<double>::infinity();
};

/// Rays aimed exactly at shared vertices and points of shared edges of a closed sphere mesh
/// (centre, radius), from inside (every 8th from the centre) and from outside on the target's
/// side, so each must hit: the watertightness probe of the SAH and matrix-tree tests.
inline std::vector<Ray> edgeAndVertexRays(const mtree::TriangleMesh& mesh, Vec3 center, double radius, int n,
                                          Rng& rng) {
  std::vector<Ray> rays(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) {
    const size_t tri = rng.below(static_cast<uint32_t>(mesh.size()));
    const int k = static_cast<int>(rng.below(3));
    const Vec3 a = mesh.vertex(tri, k), b = mesh.vertex(tri, (k + 1) % 3);
    const Vec3 target = i % 3 == 0 ? a : a + (b - a) * (i % 3 == 1 ? 0.5 : rng.uniform());
    Ray& r = rays[static_cast<size_t>(i)];
    if (i % 2 == 0) {
      r.o = center + rng.direction() * (radius * rng.uniform(0.0, 0.9));
      if (i % 8 == 0) r.o = center;
    } else {  // outside, on the target's side (the ray meets the sphere at the target or before)
      const Vec3 w = mtree::normalized(target - center) + rng.direction() * 0.5;
      r.o = target + w * (radius * rng.uniform(0.5, 3.0));
    }
    r.d = target - r.o;
  }
  return rays;
}

// A random point of triangle i (barycentric, uniform).
inline Vec3 pointOn(const mtree::TriangleMesh& m, size_t i, Rng& rng) {
  double u = rng.uniform(), v = rng.uniform();
  if (u + v > 1) u = 1 - u, v = 1 - v;
  const Vec3 a = m.vertex(i, 0), b = m.vertex(i, 1), c = m.vertex(i, 2);
  return a + (b - a) * u + (c - a) * v;
}

// Rays that meet the scene: half from outside its box aimed at points of random triangles, a
// quarter from inside with random directions, a quarter axis-parallel through triangle points.
inline std::vector<Ray> aimedRays(const mtree::TriangleMesh& m, int n, uint64_t seed) {
  Rng rng(seed);
  const Box b = meshBounds(m);
  const double diag = std::max(mtree::norm(b.extent()), 1e-300);
  std::vector<Ray> rays(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) {
    Ray& r = rays[i];
    const Vec3 target = pointOn(m, rng.below(static_cast<uint32_t>(m.size())), rng);
    switch (i % 4) {
      case 0:
      case 1:
        r.o = b.center() + rng.direction() * (diag * rng.uniform(0.6, 2.0));
        r.d = target - r.o;
        break;
      case 2:
        r.o = rng.inBox(b);
        r.d = rng.direction();
        break;
      default: {
        const int a = static_cast<int>(rng.below(3));
        r.d = Vec3(0, 0, 0);
        r.d[a] = rng.below(2) ? 1.0 : -1.0;
        r.o = target;
        r.o[a] -= r.d[a] * diag;
        break;
      }
    }
  }
  return rays;
}

// Pieces of the mixed ray sets of the traversal tests. Each draws from rng in a fixed order, so
// a seed names one ray set.

/// From outside box b (diagonal diag) at 0.55..1.5 diagonals from its centre, aimed at a random
/// point inside; the direction normalized on every other draw.
inline void aimFromOutside(Ray& r, const Box& b, double diag, Rng& rng) {
  r.o = b.center() + rng.direction() * (diag * rng.uniform(0.55, 1.5));
  r.d = rng.inBox(b) - r.o;
  if (rng.below(2)) r.d = mtree::normalized(r.d);
}

/// From a random point of `from` with one zero direction component, two on every other draw.
inline void axisParallel(Ray& r, const Box& from, Rng& rng) {
  r.o = rng.inBox(from);
  r.d = rng.direction();
  const int a = static_cast<int>(rng.below(3));
  r.d[a] = 0;
  if (rng.below(2)) r.d[(a + 1 + rng.below(2)) % 3] = 0;
}

/// Moves r.o along the first axis r.d moves on to margin[axis] outside box b, heading in.
inline void startOutside(Ray& r, const Box& b, const Vec3& margin) {
  for (int k = 0; k < 3; ++k)
    if (r.d[k] != 0) {
      r.o[k] = r.d[k] > 0 ? b.lo[k] - margin[k] : b.hi[k] + margin[k];
      return;
    }
}

/// Clips [tmin, tmax] to a random stretch of at most 0.5 + 1.5 lengths diag along the ray.
inline void clipInterval(Ray& r, double diag, Rng& rng) {
  const double scale = diag / mtree::norm(r.d);
  r.tmin = rng.uniform(0, 0.5) * scale;
  r.tmax = r.tmin + rng.uniform(0, 1.5) * scale;
}

/// An origin at or near the edge a-b for direction d: 0 the vertex a, 1 a random point of the
/// edge, 2 behind a, 3 behind the edge's midpoint (behind: up to `reach` along -d).
inline Vec3 atVertexOrEdge(int which, Vec3 a, Vec3 b, Vec3 d, double reach, Rng& rng) {
  switch (which) {
    case 0:
      return a;
    case 1:
      return a + (b - a) * rng.uniform();
    case 2:
      return a - d * (reach * rng.uniform(0.01, 1.0));
    default:
      return a + (b - a) * 0.5 - d * (reach * rng.uniform(0.01, 1.0));
  }
}

/// Appends n rays aimed exactly at the vertices of the mesh (triangle i % size, corner i % 3),
/// each from 2 units away in a random direction.
inline void addVertexRays(std::vector<Ray>& rays, const mtree::TriangleMesh& mesh, size_t n, Rng& rng) {
  for (size_t i = 0; i < n; ++i) {
    Ray r;
    const Vec3 target = mesh.vertex(i % mesh.size(), static_cast<int>(i % 3));
    r.o = target + rng.direction() * 2.0;
    r.d = target - r.o;
    rays.push_back(r);
  }
}

/// Two meshes of 400 degenerate triangles in the box [0,1]x[0,2]x[0,3]: (points, pointTris) with
/// every triangle a point, (segs, segTris) with every triangle three collinear points a, a + v,
/// a + 2v (exactly collinear where the coordinates allow it).
inline void degenerateTriangles(Rng& rng, std::vector<double>& points, std::vector<uint32_t>& pointTris,
                                std::vector<double>& segs, std::vector<uint32_t>& segTris) {
  for (uint32_t i = 0; i < 400; ++i) {
    const Vec3 a = rng.inBox(Box{Vec3(0, 0, 0), Vec3(1, 2, 3)});
    for (int k = 0; k < 3; ++k) points.insert(points.end(), {a.x, a.y, a.z});
    pointTris.insert(pointTris.end(), {3 * i, 3 * i + 1, 3 * i + 2});
    const Vec3 v = rng.direction() * 0.05;
    for (int k = 0; k < 3; ++k) segs.insert(segs.end(), {a.x + k * v.x, a.y + k * v.y, a.z + k * v.z});
    segTris.insert(segTris.end(), {3 * i, 3 * i + 2, 3 * i + 1});
  }
}

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__)) && !defined(__INTEL_COMPILER)
#define MTEST_PRETEST_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define MTEST_PRETEST_CLONES
#endif

/// The brute-force pre-test over one block of triangles (see BruteForce). Compiled for AVX2 and
/// for the baseline, picked at run time: AVX2 without FMA, so every lane does the same IEEE
/// double operations as the scalar code, only more of them at once.
MTEST_PRETEST_CLONES static void bruteForcePretest(const double* __restrict ax, const double* __restrict ay,
                                                   const double* __restrict az, const double* __restrict e1x,
                                                   const double* __restrict e1y, const double* __restrict e1z,
                                                   const double* __restrict e2x, const double* __restrict e2y,
                                                   const double* __restrict e2z, size_t m, double ox,
                                                   double oy, double oz, double dx, double dy, double dz,
                                                   double* __restrict keep) {
  for (size_t i = 0; i < m; ++i) {
    // p = cross(d, e2)
    const double px = dy * e2z[i] - dz * e2y[i];
    const double py = dz * e2x[i] - dx * e2z[i];
    const double pz = dx * e2y[i] - dy * e2x[i];
    // det = dot(e1, p)
    const double det = e1x[i] * px + e1y[i] * py + e1z[i] * pz;
    // s = o - a
    const double sx = ox - ax[i], sy = oy - ay[i], sz = oz - az[i];
    // dot(s, p)
    const double sp = sx * px + sy * py + sz * pz;
    // q = cross(s, e1), dot(d, q)
    const double qx = sy * e1z[i] - sz * e1y[i];
    const double qy = sz * e1x[i] - sx * e1z[i];
    const double qz = sx * e1y[i] - sy * e1x[i];
    const double dq = dx * qx + dy * qy + dz * qz;
    const double lim = 2.0 * std::fabs(det);
    // NaN anywhere keeps the triangle (comparisons with NaN are false): conservative.
    keep[i] = (det == 0.0) | (std::fabs(sp) > lim) | (std::fabs(dq) > lim) ? 0.0 : 1.0;
  }
}

/// The brute-force reference, fast enough for 10^5 rays x 2*10^5 triangles on two cores, yet
/// with answers bit-identical to mtree::intersectFirstBruteForce:
///  * triangles are stored as structure-of-arrays (corner a, edges e1 = b - a, e2 = c - a;
///    a subtraction gives the same double whether done here or inside rayTriangleMT);
///  * rays are processed in packets against blocks of triangles that stay in cache;
///  * a branch-free, vectorisable pre-test computes det, dot(s, p) and dot(d, q) with the very
///    operations of rayTriangleMT, and drops a triangle only when |dot(s, p)| > 2 |det| or
///    |dot(d, q)| > 2 |det| (then |u| > 1 or |v| > 1 after rounding, so rayTriangleMT rejects it
///    too) or det == 0 (rejected by rayTriangleMT). No division, no rounding changed;
///  * every surviving triangle goes through mtree::rayTriangleMT itself, in id order, with the
///    same shrinking tmax and the same tie rule (smaller t, then smaller id).
/// test_rays.cpp checks it against mtree::intersectFirstBruteForce on a sample of every mesh.
class BruteForce {
 public:
  explicit BruteForce(const mtree::TriangleMesh& mesh) : n_(mesh.size()), corners_(9 * mesh.size()) {
    for (auto* v : {&ax_, &ay_, &az_, &e1x_, &e1y_, &e1z_, &e2x_, &e2y_, &e2z_}) v->resize(n_);
    for (size_t i = 0; i < n_; ++i) {
      const Vec3 a = mesh.vertex(i, 0), b = mesh.vertex(i, 1), c = mesh.vertex(i, 2);
      const Vec3 corner[3] = {a, b, c};
      for (int k = 0; k < 3; ++k)
        for (int j = 0; j < 3; ++j) corners_[9 * i + 3 * k + j] = corner[k][j];
      const Vec3 e1 = b - a, e2 = c - a;  // exactly as rayTriangleMT computes them
      ax_[i] = a.x, ay_[i] = a.y, az_[i] = a.z;
      e1x_[i] = e1.x, e1y_[i] = e1.y, e1z_[i] = e1.z;
      e2x_[i] = e2.x, e2y_[i] = e2.y, e2z_[i] = e2.z;
    }
  }
  size_t size() const { return n_; }

  /// Same contract and tie rule as mtree::intersectFirstBruteForce.
  mtree::RayHit first(const Ray& r) const {
    mtree::RayHit hit;
    firstPacket(&r, &hit, 1);
    return hit;
  }

  /// first() for every ray; OpenMP over packets of rays.
  std::vector<mtree::RayHit> firstAll(const std::vector<Ray>& rays) const {
    std::vector<mtree::RayHit> out(rays.size());
    const int64_t n = static_cast<int64_t>(rays.size());
    const int64_t packets = (n + kPacket - 1) / kPacket;
#pragma omp parallel for schedule(dynamic, 1)
    for (int64_t p = 0; p < packets; ++p) {
      const int64_t b = p * kPacket, e = std::min(n, b + kPacket);
      firstPacket(&rays[b], &out[b], static_cast<int>(e - b));
    }
    return out;
  }

 private:
  static constexpr int kPacket = 32;
  static constexpr size_t kBlock = 512;

  void firstPacket(const Ray* rays, mtree::RayHit* hits, int count) const {
    alignas(64) double keep[kBlock];  // 1.0 = goes to rayTriangleMT (a double: vectorises on SSE2)
    for (int r = 0; r < count; ++r) {
      hits[r] = mtree::RayHit{};
      hits[r].t = rays[r].tmax;
    }
    for (size_t b0 = 0; b0 < n_; b0 += kBlock) {
      const size_t m = std::min(kBlock, n_ - b0);
      const double* __restrict ax = ax_.data() + b0;
      const double* __restrict ay = ay_.data() + b0;
      const double* __restrict az = az_.data() + b0;
      const double* __restrict e1x = e1x_.data() + b0;
      const double* __restrict e1y = e1y_.data() + b0;
      const double* __restrict e1z = e1z_.data() + b0;
      const double* __restrict e2x = e2x_.data() + b0;
      const double* __restrict e2y = e2y_.data() + b0;
      const double* __restrict e2z = e2z_.data() + b0;
      for (int r = 0; r < count; ++r) {
        const Ray& ray = rays[r];
        const double ox = ray.o.x, oy = ray.o.y, oz = ray.o.z;
        const double dx = ray.d.x, dy = ray.d.y, dz = ray.d.z;
        bruteForcePretest(ax, ay, az, e1x, e1y, e1z, e2x, e2y, e2z, m, ox, oy, oz, dx, dy, dz, keep);
        mtree::RayHit& hit = hits[r];
        for (size_t i = 0; i < m; ++i) {
          if (keep[i] == 0.0) continue;
          const size_t id = b0 + i;
          const double* c = &corners_[9 * id];
          double t, u, v;
          if (mtree::rayTriangleMT(ray.o, ray.d, Vec3(c), Vec3(c + 3), Vec3(c + 6), ray.tmin, hit.t, t, u,
                                   v)) {
            if (t < hit.t || (t == hit.t && id < hit.prim)) {
              hit.t = t;
              hit.prim = static_cast<uint32_t>(id);
              hit.u = u;
              hit.v = v;
            }
          }
        }
      }
    }
    for (int r = 0; r < count; ++r)
      if (!hits[r].hit()) hits[r].t = std::numeric_limits<double>::infinity();
  }

  size_t n_;
  std::vector<double> ax_, ay_, az_, e1x_, e1y_, e1z_, e2x_, e2y_, e2z_;
  std::vector<double> corners_;  // a, b, c of every triangle: the confirming test's input
};

/// Seconds on the steady clock, for the timings the tests print (never assert).
inline double seconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

/// The brute force over a mesh with the first hits of one ray set, and the seconds both took.
struct TimedFirstHits {
  TimedFirstHits(const mtree::TriangleMesh& mesh, const std::vector<Ray>& rays)
      : start(seconds()), bf(mesh), hits(bf.firstAll(rays)), elapsed(seconds() - start) {}
  double start;
  BruteForce bf;
  std::vector<mtree::RayHit> hits;
  double elapsed;
};

/// The mesh with every point scaled by `scale` about the origin, then moved by `offset`.
inline mtree::TriangleMesh transformed(const mtree::TriangleMesh& m, double scale, Vec3 offset) {
  std::vector<double> p = m.points();
  for (size_t i = 0; i < p.size(); i += 3)
    for (int a = 0; a < 3; ++a) p[i + a] = p[i + a] * scale + offset[a];
  return mtree::TriangleMesh(std::move(p), m.triangles());
}

/// An n x n grid of quads (two triangles each) over [0,1] x [0,0.7] in the plane z = 0.25: a
/// scene whose box has no z extent of its own.
inline mtree::TriangleMesh flatGrid(int n) {
  std::vector<double> p;
  std::vector<uint32_t> t;
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) p.insert(p.end(), {i / double(n), j * 0.7 / n, 0.25});
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const uint32_t a = j * (n + 1) + i, b = a + 1, c = a + n + 1, d = c + 1;
      t.insert(t.end(), {a, b, d, a, d, c});
    }
  return mtree::TriangleMesh(p, t);
}

/// Compares a tree answer with the reference. Equal if same primitive (and same t), or if both
/// hit with |t1 - t2| <= 1e-6 max(1, |t|) (two triangles met at the same place: a shared edge or
/// vertex, where round-off of the walk may pick the other one). `idDiffers` counts the latter.
struct HitComparison {
  uint64_t rays = 0, hits = 0, idDiffers = 0, mismatches = 0;
  std::string firstMismatch;
  void add(const mtree::RayHit& tree, const mtree::RayHit& ref, const Ray& r, size_t index) {
    ++rays;
    hits += ref.hit();
    if (tree.prim == ref.prim) {
      if (!tree.hit() || tree.t == ref.t) return;
    } else if (tree.hit() && ref.hit() &&
               std::fabs(tree.t - ref.t) <= 1e-6 * std::max(1.0, std::fabs(ref.t))) {
      ++idDiffers;
      return;
    }
    if (mismatches++ == 0) {
      char buf[512];
      std::snprintf(
          buf, sizeof buf,
          "ray %zu o=(%.17g, %.17g, %.17g) d=(%.17g, %.17g, %.17g) [%.17g, %.17g]: tree prim %d t %.17g,"
          " brute force prim %d t %.17g",
          index, r.o.x, r.o.y, r.o.z, r.d.x, r.d.y, r.d.z, r.tmin, r.tmax, tree.hit() ? int(tree.prim) : -1,
          tree.t, ref.hit() ? int(ref.prim) : -1, ref.t);
      firstMismatch = buf;
    }
  }
};

}  // namespace mtest

#include "mtree/cells.h"

#include <omp.h>

#include <cstring>

#include "mtree/parallel.h"

namespace mtree {

namespace {
CellTopology makeTopology(int numPoints, std::initializer_list<std::initializer_list<int>> faces,
                          std::initializer_list<std::pair<int, int>> edges) {
  CellTopology t;
  t.numPoints = numPoints;
  for (const auto& f : faces) {
    int k = 0;
    for (int v : f) t.face[t.numFaces][k++] = v;
    t.faceSize[t.numFaces++] = k;
  }
  for (const auto& e : edges) {
    t.edge[t.numEdges][0] = e.first;
    t.edge[t.numEdges][1] = e.second;
    ++t.numEdges;
  }
  return t;
}
}  // namespace

const CellTopology* cellTopology(uint8_t type) {
  // Point orderings are VTK's (vtkTetra, vtkHexahedron, vtkWedge, vtkPyramid, vtkTriangle, vtkQuad).
  static const CellTopology tri = makeTopology(3, {{0, 1, 2}}, {{0, 1}, {1, 2}, {2, 0}});
  static const CellTopology quad = makeTopology(4, {{0, 1, 2, 3}}, {{0, 1}, {1, 2}, {2, 3}, {3, 0}});
  static const CellTopology tet =
      makeTopology(4, {{0, 1, 3}, {1, 2, 3}, {2, 0, 3}, {0, 2, 1}}, {{0, 1}, {1, 2}, {2, 0}, {0, 3}, {1, 3}, {2, 3}});
  static const CellTopology hex = makeTopology(
      8, {{0, 4, 7, 3}, {1, 2, 6, 5}, {0, 1, 5, 4}, {3, 7, 6, 2}, {0, 3, 2, 1}, {4, 5, 6, 7}},
      {{0, 1}, {1, 2}, {2, 3}, {3, 0}, {4, 5}, {5, 6}, {6, 7}, {7, 4}, {0, 4}, {1, 5}, {2, 6}, {3, 7}});
  static const CellTopology wedge =
      makeTopology(6, {{0, 1, 2}, {3, 5, 4}, {0, 3, 4, 1}, {1, 4, 5, 2}, {2, 5, 3, 0}},
                   {{0, 1}, {1, 2}, {2, 0}, {3, 4}, {4, 5}, {5, 3}, {0, 3}, {1, 4}, {2, 5}});
  static const CellTopology pyramid =
      makeTopology(5, {{0, 3, 2, 1}, {0, 1, 4}, {1, 2, 4}, {2, 3, 4}, {3, 0, 4}},
                   {{0, 1}, {1, 2}, {2, 3}, {3, 0}, {0, 4}, {1, 4}, {2, 4}, {3, 4}});
  switch (type) {
    case kTriangle: return &tri;
    case kQuad: return &quad;
    case kTetra: return &tet;
    case kHexahedron: return &hex;
    case kWedge: return &wedge;
    case kPyramid: return &pyramid;
    default: return nullptr;  // voxels and pixels are their bounding box; others are padded
  }
}

std::vector<uint32_t> CellSet::narrow(const std::vector<int64_t>& v, const char* what) {
  std::vector<uint32_t> out(v.size());
  for (size_t i = 0; i < v.size(); ++i) {
    if (v[i] < 0) throw std::invalid_argument(std::string("CellSet: negative ") + what + " " + std::to_string(v[i]));
    if (v[i] >= 0xffffffffLL) throw std::length_error(std::string("CellSet: ") + what + " past 2^32 - 1");
    out[i] = static_cast<uint32_t>(v[i]);
  }
  return out;
}

void CellSet::validate() const {
  const size_t nc = 3 * pts_.n;
  for (size_t i = 0; i < nc; ++i)
    if (!std::isfinite(floatPoints_ ? double(pts_.fp[i]) : pts_.dp[i]))
      throw std::invalid_argument("CellSet: point " + std::to_string(i / 3) + " has a non-finite coordinate");
  const uint64_t np = pts_.n;
  for (size_t c = 0; c + 1 < off_.size(); ++c)
    if (off_[c + 1] < off_[c]) throw std::invalid_argument("CellSet: offsets must not decrease");
  for (size_t k = 0; k < conn_.size(); ++k)
    if (conn_[k] >= np) {
      const size_t c = static_cast<size_t>(std::upper_bound(off_.begin(), off_.end(), uint32_t(k)) - off_.begin()) - 1;
      throw std::invalid_argument("CellSet: cell " + std::to_string(c) + " refers to point " +
                                  std::to_string(conn_[k]) + " of " + std::to_string(np));
    }
}

void CellSet::dropUniformOffsets() {
  // Single-type grids (all tetrahedra, all hexahedra, triangle meshes): cell c starts at c x k
  // in the connectivity, so 4 bytes per cell need not be stored (nor read per query).
  const size_t n = size();
  if (n == 0) return;
  const uint32_t k = off_[1] - off_[0];
  for (size_t c = 1; c < n; ++c)
    if (off_[c + 1] - off_[c] != k) return;
  uniform_ = k;
  std::vector<uint32_t>().swap(off_);
}

void CellSet::keepFloatPointsIfExact() {
  // Grids read from float arrays (most VTK files) arrive here widened to doubles: kept as
  // floats they take half the memory and give back the very same doubles.
  if (pts_.view) return;  // nothing held to save
  for (double x : pts_.d)
    if (static_cast<double>(static_cast<float>(x)) != x) return;
  pts_.f.assign(pts_.d.begin(), pts_.d.end());
  std::vector<double>().swap(pts_.d);
  pts_.rebind();
  floatPoints_ = true;
}

namespace {
// std::nextafter(f, -inf) for a finite f, without the libm call (one per bound of every cell
// whose coordinates are not floats: most of the cached bounds' cost on double grids): the
// float below a positive one has the bit pattern one lower, below a negative one one higher,
// and below either zero is the negative smallest subnormal.
inline float nextFloatDown(float f) {
  uint32_t u;
  std::memcpy(&u, &f, sizeof u);
  if (f == 0) u = 0x80000001u;
  else if (f > 0) --u;
  else ++u;
  std::memcpy(&f, &u, sizeof f);
  return f;
}

// The float nearest x on the side of `dir` (-1: not above x, +1: not below x).
inline float roundOut(double x, int dir) {
  const double big = std::numeric_limits<float>::max();
  const float inf = std::numeric_limits<float>::infinity();
  if (x > big) return dir < 0 ? std::numeric_limits<float>::max() : inf;
  if (x < -big) return dir < 0 ? -inf : -std::numeric_limits<float>::max();
  float f = static_cast<float>(x);
  if (dir < 0 && static_cast<double>(f) > x) f = nextFloatDown(f);
  if (dir > 0 && static_cast<double>(f) < x) f = -nextFloatDown(-f);
  return f;
}
}  // namespace

void CellSet::computeBounds(int threads) {
  const int64_t n = static_cast<int64_t>(size());
  box_.resize(static_cast<size_t>(n) * 6);
  const int nt = resolveThreads(threads);
  std::vector<Vec3> ext(static_cast<size_t>(nt), Vec3(0, 0, 0));
#pragma omp parallel num_threads(nt)
  {
    Vec3 m(0, 0, 0);
#pragma omp for schedule(static)
    for (int64_t c = 0; c < n; ++c) {
      Box b = exactBounds(static_cast<size_t>(c));
      const uint8_t t = types_[c];
      if (!b.empty() && !cellTopology(t) && t != kVoxel && t != kPixel) {
        const Vec3 e = b.extent();
        const double pad = 0.05 * std::max(e.x, std::max(e.y, e.z));
        b.lo = b.lo - Vec3(pad, pad, pad);
        b.hi = b.hi + Vec3(pad, pad, pad);
      }
      float* f = &box_[6 * static_cast<size_t>(c)];
      for (int a = 0; a < 3; ++a) {
        f[2 * a] = roundOut(b.lo[a], -1);
        f[2 * a + 1] = roundOut(b.hi[a], +1);
        if (!b.empty()) m[a] = std::max(m[a], double(f[2 * a + 1]) - double(f[2 * a]));
      }
    }
    ext[static_cast<size_t>(omp_get_thread_num())] = m;
  }
  maxExt_ = Vec3(0, 0, 0);
  for (const Vec3& e : ext) maxExt_ = vmax(maxExt_, e);
}

}  // namespace mtree

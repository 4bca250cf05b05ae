#include "mtree/cells/cells.h"

#include <omp.h>

#include <cstring>
#include <string>

#include "mtree/core/coordinate_range.h"
#include "mtree/core/parallel.h"

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

int cellTypeDimension(uint8_t type) {
  switch (type) {
    case 1:   // VTK_VERTEX
    case 2:   // VTK_POLY_VERTEX
      return 0;
    case 3:   // VTK_LINE
    case 4:   // VTK_POLY_LINE
    case 21:  // VTK_QUADRATIC_EDGE
    case 35:  // VTK_CUBIC_LINE
    case 68:  // VTK_LAGRANGE_CURVE
    case 75:  // VTK_BEZIER_CURVE
      return 1;
    case 5: case 6: case 7: case 8: case 9:  // triangle, strip, polygon, pixel, quad
    case 22: case 23: case 28: case 30: case 34: case 36:  // the quadratic 2-D cells
    case 69: case 70: case 76: case 77:  // Lagrange and Bézier triangles and quadrilaterals
      return 2;
    case 10: case 11: case 12: case 13: case 14: case 15: case 16:  // linear volumes and prisms
    case 24: case 25: case 26: case 27: case 29: case 31: case 32: case 33: case 37:  // quadratic
    case 41: case 42:  // convex point set, polyhedron
    case 71: case 72: case 73: case 78: case 79: case 80:  // Lagrange, Bezier (no pyramids in 9.1)
      return 3;
    default: return -1;
  }
}

const char* cellTypeName(uint8_t type) {
  static const char* const names[] = {"VTK_EMPTY_CELL", "VTK_VERTEX", "VTK_POLY_VERTEX", "VTK_LINE",
                                      "VTK_POLY_LINE", "VTK_TRIANGLE", "VTK_TRIANGLE_STRIP", "VTK_POLYGON",
                                      "VTK_PIXEL", "VTK_QUAD", "VTK_TETRA", "VTK_VOXEL",
                                      "VTK_HEXAHEDRON", "VTK_WEDGE", "VTK_PYRAMID"};
  if (type <= kPyramid) return names[type];
  static thread_local std::string other;
  other = "cell type " + std::to_string(type);
  return other.c_str();
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

void CellSet::own(std::vector<uint32_t> offsets, std::vector<uint32_t> connectivity, std::vector<uint8_t> types) {
  if (offsets.empty() || offsets.size() != types.size() + 1)
    throw std::invalid_argument("CellSet: offsets must have numCells + 1 entries from 0 to the connectivity size");
  cells_ = Cells{};
  cells_.n = types.size();
  cells_.connSize = connectivity.size();
  cells_.off = std::move(offsets);
  cells_.conn32 = std::move(connectivity);
  cells_.own = std::move(types);
  cells_.rebind();
  validateViewed(cells_.off.data(), cells_.conn32.data(), cells_.connSize);
}

void CellSet::viewCells(CellArrays a) {
  if (!a.offsets || (a.connectivitySize && !a.connectivity) || (a.indexBytes != 4 && a.indexBytes != 8))
    throw std::invalid_argument("CellSet: cell arrays need offsets, connectivity and 4- or 8-byte indices");
  if (!a.types && !a.typeCopy.empty() && a.typeCopy.size() != a.numCells)
    throw std::invalid_argument("CellSet: one type per cell expected");
  if (a.connectivitySize >= 0xffffffffu) throw std::length_error("CellSet: connectivity past 2^32 - 1 entries");
  cells_ = Cells{};
  cells_.n = a.numCells;
  cells_.connSize = a.connectivitySize;
  cells_.view = true;
  if (a.indexBytes == 8) {
    validateViewed(static_cast<const int64_t*>(a.offsets), static_cast<const int64_t*>(a.connectivity),
                   a.connectivitySize);
    static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__, "the low word of a 64-bit index is read first");
    cells_.shift = 1;
  } else {
    validateViewed(static_cast<const int32_t*>(a.offsets), static_cast<const int32_t*>(a.connectivity),
                   a.connectivitySize);
  }
  cells_.off32 = static_cast<const Word*>(a.offsets);
  cells_.conn = static_cast<const Word*>(a.connectivity);
  if (a.types) {
    cells_.types = a.types;
  } else if (!a.typeCopy.empty()) {
    cells_.own = std::move(a.typeCopy);
  } else {
    cells_.types = typeCode(a.type);
    cells_.typeMask = 0;
  }
  cells_.rebind();
}

template <class I>
void CellSet::validateViewed(const I* off, const I* conn, size_t connSize) const {
  const size_t n = cells_.n;
  if (off[0] != 0 || static_cast<uint64_t>(off[n]) != connSize)
    throw std::invalid_argument("CellSet: offsets must have numCells + 1 entries from 0 to the connectivity size");
  if (connSize >= 0xffffffffu) throw std::length_error("CellSet: connectivity past 2^32 - 1 entries");
  for (size_t c = 0; c < n; ++c)
    if (off[c + 1] < off[c]) throw std::invalid_argument("CellSet: offsets must not decrease");
  const int64_t np = static_cast<int64_t>(pts_.n);
  for (size_t k = 0; k < connSize; ++k)
    if (static_cast<int64_t>(conn[k]) < 0 || static_cast<int64_t>(conn[k]) >= np) {
      const size_t c = static_cast<size_t>(std::upper_bound(off, off + n + 1, static_cast<I>(k)) - off) - 1;
      throw std::invalid_argument("CellSet: cell " + std::to_string(c) + " refers to point " +
                                  std::to_string(static_cast<int64_t>(conn[k])) + " of " + std::to_string(np));
    }
}

void CellSet::validate() const {
  if (floatPoints_)
    checkCoordinateRange(pts_.fp, pts_.n, "CellSet");
  else
    checkCoordinateRange(pts_.dp, pts_.n, "CellSet");
}

void CellSet::dropUniformOffsets() {
  // Single-type grids (all tetrahedra, all hexahedra, triangle meshes): cell c starts at c x k
  // in the connectivity, so 4 bytes per cell need not be stored (nor read per query).
  const size_t n = size();
  if (n == 0) return;
  const uint32_t k = offset(1) - offset(0);
  for (size_t c = 1; c < n; ++c)
    if (offset(c + 1) - offset(c) != k) return;
  uniform_ = k;
  if (!cells_.view) {
    std::vector<uint32_t>().swap(cells_.off);
    cells_.off32 = nullptr;
  }
}

const uint8_t* CellSet::typeCode(uint8_t t) {
  static const std::array<uint8_t, 256> kCodes = [] {
    std::array<uint8_t, 256> codes{};
    for (int i = 0; i < 256; ++i) codes[i] = static_cast<uint8_t>(i);
    return codes;
  }();
  return &kCodes[t];
}

void CellSet::dropUniformTypes() {
  // One type for all cells (most grids and surfaces): kept once, as a pointer into a table of
  // every type code, instead of a byte per cell (and a read per query).
  const size_t n = size();
  if (n == 0 || cells_.typeMask == 0) return;
  const uint8_t t = cells_.types[0];
  for (size_t c = 1; c < n; ++c)
    if (cells_.types[c] != t) return;
  cells_.types = typeCode(t);
  cells_.typeMask = 0;
  std::vector<uint8_t>().swap(cells_.own);
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
// Cell types whose bounds are their points' (a table, voxels, pixels); other types' boxes are
// padded (boxOf), their points not being their extent. One rule for boxOf and computeBounds'
// direct loop.
inline bool boundsArePoints(uint8_t t) { return cellTopology(t) || t == kVoxel || t == kPixel; }

// The float nearest x on the side of `dir` (-1: not above x, +1: not below x): the nearest
// float, moved one step outwards (std::nextafter towards -inf or +inf) when it lies on the wrong
// side of x, with bit arithmetic and no branch on whether the step is needed (about every other
// bound of a grid with double coordinates: as a branch, a coin flip). One step down is the bit
// pattern minus one for a positive float, plus one for a negative one (up: the opposite); from
// either zero it is the smallest subnormal of x's sign (the only case with a branch: rare).
inline float roundOut(double x, int dir) {
  const double big = std::numeric_limits<float>::max();
  const float inf = std::numeric_limits<float>::infinity();
  if (x > big) return dir < 0 ? std::numeric_limits<float>::max() : inf;
  if (x < -big) return dir < 0 ? -inf : -std::numeric_limits<float>::max();
  float f = static_cast<float>(x);
  const double d = static_cast<double>(f);
  const uint32_t step = dir < 0 ? uint32_t(d > x) : uint32_t(d < x);
  uint32_t u;
  std::memcpy(&u, &f, sizeof u);
  const uint32_t neg = u >> 31, zero = uint32_t((u << 1) == 0);
  u += step * (dir < 0 ? 2 * neg - 1 : 1 - 2 * neg);
  if (__builtin_expect((step & zero) != 0, 0)) u = dir < 0 ? 0x80000001u : 0x00000001u;
  std::memcpy(&f, &u, sizeof f);
  return f;
}
}  // namespace

void CellSet::boxOf(size_t c, float f[6]) const {
  Box b = exactBounds(c);
  const uint8_t t = type(c);
  if (!b.empty() && !boundsArePoints(t)) {
    const Vec3 e = b.extent();
    const double pad = 0.05 * std::max(e.x, std::max(e.y, e.z));
    b.lo = b.lo - Vec3(pad, pad, pad);
    b.hi = b.hi + Vec3(pad, pad, pad);
  }
  for (int a = 0; a < 3; ++a) {
    f[2 * a] = roundOut(b.lo[a], -1);
    f[2 * a + 1] = roundOut(b.hi[a], +1);
  }
}

void CellSet::computeBounds(int threads) {
  const int64_t n = static_cast<int64_t>(size());
  box_.resize(static_cast<size_t>(n) * 6);
  const int nt = resolveThreads(threads);
  std::vector<Vec3> ext(static_cast<size_t>(nt), Vec3(0, 0, 0));
  std::vector<Box> total(static_cast<size_t>(nt));
  // boundsArePoints per type, looked up once per cell.
  bool plain[256];
  for (int t = 0; t < 256; ++t) plain[t] = boundsArePoints(uint8_t(t));
  // Cells [b, e) with points of type T: the points' min and max read straight from the arrays
  // (boxOf's per-point checks hoisted), rounded outwards as boxOf rounds them: float points need
  // no rounding (their min and max are floats). Empty and padded cells go through boxOf.
  auto run = [&](auto* pts, int64_t b, int64_t e, Vec3& m, Box& tot) {
    constexpr bool isFloat = std::is_same_v<std::remove_const_t<std::remove_pointer_t<decltype(pts)>>, float>;
    const int shift = cells_.shift;
    for (int64_t c = b; c < e; ++c) {
      float* f = &box_[6 * static_cast<size_t>(c)];
      const int64_t np = numCellPoints(size_t(c));
      if (np > 0 && plain[type(size_t(c))]) {
        const Word* id = cells_.conn + (firstPoint(size_t(c)) << shift);
        const auto* p0 = pts + 3 * size_t(id[0]);
        double lo[3] = {double(p0[0]), double(p0[1]), double(p0[2])}, hi[3] = {lo[0], lo[1], lo[2]};
        for (int64_t k = 1; k < np; ++k) {
          const auto* p = pts + 3 * size_t(id[size_t(k) << shift]);
          for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], double(p[a]));
            hi[a] = std::max(hi[a], double(p[a]));
          }
        }
        for (int a = 0; a < 3; ++a) {
          if constexpr (isFloat) {
            f[2 * a] = static_cast<float>(lo[a]);
            f[2 * a + 1] = static_cast<float>(hi[a]);
          } else {
            f[2 * a] = roundOut(lo[a], -1);
            f[2 * a + 1] = roundOut(hi[a], +1);
          }
        }
      } else {
        boxOf(static_cast<size_t>(c), f);
      }
      // Empty cells (no points) are inf/-inf: no extent, and nothing added to the total.
      for (int a = 0; a < 3; ++a)
        if (f[2 * a] <= f[2 * a + 1]) m[a] = std::max(m[a], double(f[2 * a + 1]) - double(f[2 * a]));
      Box cb;
      cb.lo = Vec3(f[0], f[2], f[4]);
      cb.hi = Vec3(f[1], f[3], f[5]);
      tot.extend(cb);
    }
  };
#pragma omp parallel num_threads(nt)
  {
    Vec3 m(0, 0, 0);
    Box tot;
    const int th = omp_get_thread_num(), team = omp_get_num_threads();
    const int64_t b = n * th / team, e = n * (th + 1) / team;
    if (floatPoints_) run(pts_.fp, b, e, m, tot);
    else run(pts_.dp, b, e, m, tot);
    ext[static_cast<size_t>(th)] = m;
    total[static_cast<size_t>(th)] = tot;
  }
  maxExt_ = Vec3(0, 0, 0);
  for (const Vec3& e : ext) maxExt_ = vmax(maxExt_, e);
  total_ = Box{};
  for (const Box& b : total) total_.extend(b);
}

}  // namespace mtree

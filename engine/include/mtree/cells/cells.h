// CellSet: the cells of an unstructured grid (or the polygons of a surface) as a primitive set of
// the matrix-tree builder (see primitives.h for the contract).
//
// Overlap with a leaf box is a separating-axis test over the cell's vertices with the axes of its
// type: the box normals, the normals of its (triangulated) faces and the cross products of its
// edges with the box axes. Projections of a convex hull are projections of its vertices, so a
// separating axis found proves separation; testing only some axes can only answer "overlap".
// The test is therefore exact for convex linear cells and conservative for warped ones (a hex
// with non-planar faces lies inside its vertices' convex hull). Types without a table (quadratic
// and higher-order cells, polyhedra) use their nodes' bounding box padded by 5% of its largest
// extent, because curved edges can bulge past the nodes.
//
// Cell type codes are VTK's (VTK_TETRA = 10, ...), so VTK data converts without a table; the
// engine itself does not depend on VTK.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

#include "mtree/core/geometry.h"
#include "mtree/core/memory.h"

namespace mtree {

enum CellType : uint8_t {
  kEmptyCell = 0,
  kVertex = 1,
  kPolyVertex = 2,
  kLine = 3,
  kPolyLine = 4,
  kTriangle = 5,
  kTriangleStrip = 6,
  kPolygon = 7,
  kPixel = 8,
  kQuad = 9,
  kTetra = 10,
  kVoxel = 11,
  kHexahedron = 12,
  kWedge = 13,
  kPyramid = 14,
};

/// Faces and edges of the linear cell types, in VTK's point ordering.
struct CellTopology {
  int numPoints = 0;
  int numFaces = 0;
  int faceSize[6] = {0, 0, 0, 0, 0, 0};
  int face[6][4] = {};
  int numEdges = 0;
  int edge[12][2] = {};
};
const CellTopology* cellTopology(uint8_t type);  // nullptr: no table (bounding box is used)

/// The dimension of a VTK cell type: 0 (vertices) to 3 (volumes), for every type a VTK 9.1 data
/// set can hold (vtkGenericCell instantiates it: linear, quadratic, Lagrange, Bezier, convex
/// point sets, polyhedra); -1 for the empty cell and other codes.
int cellTypeDimension(uint8_t type);
/// VTK's name of a linear cell type ("VTK_TETRA"), else "cell type N".
const char* cellTypeName(uint8_t type);

/// Which separating axes the exact overlap test uses. Faces: the box normals (implicit in the
/// candidate range) and the cell's face normals — conservative (it may keep a leaf that only
/// an edge-cross axis would separate), about 5x cheaper for tetrahedra. All: also the cross
/// products of the cell's edges with the box axes — exact for convex cells.
enum class CellAxes : int { Faces = 0, All = 1 };

/// The caller's cell arrays, read in place instead of copied (VTK's vtkCellArray storage and a
/// vtkUnstructuredGrid's types): offsets (numCells + 1 entries, from 0 to connectivitySize)
/// and connectivity as signed integers of indexBytes (4 or 8) bytes. They must stay alive and
/// unchanged while the set is used. Types: the caller's array (types), else an owned copy
/// (typeCopy), else every cell is `type`.
struct CellArrays {
  const void* offsets = nullptr;
  const void* connectivity = nullptr;
  size_t numCells = 0;
  size_t connectivitySize = 0;
  int indexBytes = 8;
  const uint8_t* types = nullptr;
  std::vector<uint8_t> typeCopy;
  uint8_t type = kEmptyCell;
};

class CellSet {
 public:
  static constexpr int kMaxLocalPoints = 8;
  /// A 32-bit word of the caller's 32- or 64-bit index arrays (read through this type only).
  typedef uint32_t __attribute__((may_alias)) Word;

  CellSet() = default;
  /// points: 3 doubles per point; offsets: numCells + 1 entries into connectivity; types: one
  /// VTK cell type per cell. Throws std::invalid_argument on inconsistent arrays, an index out of
  /// range, or a coordinate out of checkCoordinateRange's range, and std::length_error past 2^32 - 1 connectivity
  /// entries or points (indices are stored in 32 bits). threads: OpenMP threads for the cached
  /// bounds (0 = OpenMP's default).
  CellSet(std::vector<double> points, std::vector<uint32_t> offsets, std::vector<uint32_t> connectivity,
          std::vector<uint8_t> types, int threads = 0) {
    pts_.d = std::move(points);
    if (pts_.d.size() % 3) throw std::invalid_argument("CellSet: points must come in triples");
    pts_.n = pts_.d.size() / 3;
    pts_.rebind();
    own(std::move(offsets), std::move(connectivity), std::move(types));
    init(threads);
  }
  /// The same over the caller's points, not copied: 3 floats (or doubles) per point, which must
  /// stay alive and unchanged while the set is used (the locator keeps a reference to the data
  /// set's point array). bytes() does not count them. Float points are read as floats; double
  /// points as doubles (not narrowed, as there is no copy to save).
  template <class T, class = std::enable_if_t<std::is_same_v<T, float> || std::is_same_v<T, double>>>
  CellSet(const T* points, size_t numPoints, std::vector<uint32_t> offsets, std::vector<uint32_t> connectivity,
          std::vector<uint8_t> types, int threads = 0) {
    viewPoints(points, numPoints);
    own(std::move(offsets), std::move(connectivity), std::move(types));
    init(threads);
  }
  /// The same over the caller's points and cell arrays (see CellArrays), neither copied: bytes()
  /// counts neither. The 64-bit arrays are read through the low word of each entry, so every
  /// offset and point index must lie below 2^32 (checked, as the other limits).
  template <class T, class = std::enable_if_t<std::is_same_v<T, float> || std::is_same_v<T, double>>>
  CellSet(const T* points, size_t numPoints, CellArrays cells, int threads = 0) {
    viewPoints(points, numPoints);
    viewCells(std::move(cells));
    init(threads);
  }
  /// The same from 64-bit offsets and connectivity (converted; see above for the limits).
  CellSet(std::vector<double> points, const std::vector<int64_t>& offsets, const std::vector<int64_t>& connectivity,
          std::vector<uint8_t> types, int threads = 0)
      : CellSet(std::move(points), narrow(offsets, "offset"), narrow(connectivity, "point index"), std::move(types),
                threads) {}

  size_t size() const { return cells_.n; }
  /// Cell c's type (one type for all cells is kept as that type, not per cell).
  uint8_t type(size_t c) const { return cells_.types[c & cells_.typeMask]; }
  int64_t numCellPoints(size_t c) const {
    return uniform_ >= 0 ? uniform_ : int64_t(offset(c + 1)) - int64_t(offset(c));
  }
  /// Cell c's point indices: ids[k], k < numCellPoints(c) (32-bit words of the owned copy, or
  /// the low words of the caller's 64-bit entries).
  struct PointIds {
    const Word* p;
    int shift;
    uint32_t operator[](int64_t k) const { return p[size_t(k) << shift]; }
  };
  PointIds cellPointIds(size_t c) const { return PointIds{cells_.conn + (firstPoint(c) << cells_.shift), cells_.shift}; }
  Vec3 cellPoint(size_t c, int64_t k) const { return point(cells_.conn[(firstPoint(c) + size_t(k)) << cells_.shift]); }
  size_t numPoints() const { return pts_.n; }
  /// Point i, as given (points that are all exact floats are kept as floats, read back exactly).
  Vec3 point(size_t i) const {
    if (floatPoints_) return Vec3(pts_.fp[3 * i], pts_.fp[3 * i + 1], pts_.fp[3 * i + 2]);
    return Vec3(&pts_.dp[3 * i]);
  }
  /// Whether the points are kept as floats (every coordinate given was exactly a float).
  bool floatPoints() const { return floatPoints_; }
  /// Whether the offsets are not read because every cell has the same number of points (and,
  /// when they were copied, not kept).
  bool uniformCellSize() const { return uniform_ >= 0; }
  /// Whether every cell has the same type (kept once, not per cell).
  bool uniformType() const { return cells_.typeMask == 0; }
  /// Whether the cell arrays are the caller's (the CellArrays constructor), not a copy.
  bool cellsViewed() const { return cells_.view; }

  /// Cell bounds as 6 floats (xmin xmax ymin ymax zmin zmax, VTK's order), rounded outwards
  /// so they contain the exact bounds; higher-order and polyhedral cells are padded by 5% of
  /// their largest extent, because curved edges can bulge past the nodes. Empty cells: inf/-inf.
  /// Cached from the constructor until releaseBounds(), then computed from the points (the
  /// same floats).
  std::array<float, 6> cellBox(size_t c) const {
    std::array<float, 6> f;
    if (box_.empty()) boxOf(c, f.data());
    else std::copy(&box_[6 * c], &box_[6 * c] + 6, f.begin());
    return f;
  }
  /// Frees the cached bounds (24 bytes per cell; the tree build is what reads them often):
  /// cellBox() and bounds() compute them from then on.
  void releaseBounds() { LargeVector<float>().swap(box_); }
  /// Whether the bounds are cached (see releaseBounds).
  bool boundsCached() const { return !box_.empty() || size() == 0; }
  /// A hint that cell c's bounds are read soon (the builder's gather over the leaves).
  void prefetch(size_t c) const {
    if (!box_.empty()) __builtin_prefetch(&box_[6 * c]);
  }
  /// A hint that cell c's point ids are read soon (the ray queries' candidates, known ahead).
  void prefetchPointIds(size_t c) const { __builtin_prefetch(cells_.conn + (firstPoint(c) << cells_.shift)); }
  /// A hint that cell c's points are read soon: reads its point ids (prefetch them first).
  void prefetchPoints(size_t c) const {
    const PointIds id = cellPointIds(c);
    const int64_t n = std::min<int64_t>(numCellPoints(c), kMaxLocalPoints);
    for (int64_t k = 0; k < n; ++k) {
      if (floatPoints_) __builtin_prefetch(&pts_.fp[3 * size_t(id[k])]);
      else __builtin_prefetch(&pts_.dp[3 * size_t(id[k])]);
    }
  }
  /// The (conservative) bounds of cellBox() as a Box: what the tree build uses (read straight
  /// from the cache while there is one: the build's setup measured 10-30% slower through a copy).
  Box bounds(size_t c) const {
    float g[6];
    const float* f = g;
    if (__builtin_expect(!box_.empty(), 1)) f = &box_[6 * c];
    else boxOf(c, g);
    Box b;
    b.lo = Vec3(f[0], f[2], f[4]);
    b.hi = Vec3(f[1], f[3], f[5]);
    return b;
  }
  /// Exact bounds of the cell's points (VTK's GetCellBounds), computed on demand.
  Box exactBounds(size_t c) const {
    Box b;
    for (int64_t k = 0; k < numCellPoints(c); ++k) b.extend(cellPoint(c, k));
    return b;
  }
  /// Largest extent along each axis of the cached bounds.
  Vec3 maxExtent() const { return maxExt_; }
  /// The union of every cell's bounds() (computed with them): the builder's root box without a
  /// pass of its own.
  Box totalBounds() const { return total_; }

  void setAxes(CellAxes a) { axes_ = a; }
  CellAxes axes() const { return axes_; }

  /// One cell as the builder sees it: bounds at once, points fetched only for the exact test.
  struct Local {
    const CellSet* set = nullptr;
    size_t cell = 0;
    Box box;
    Box bounds() const { return box; }
    /// Points and topology; false for types without a table or a malformed point count.
    bool fetch(Vec3* p, int& n, const CellTopology*& topo) const {
      topo = cellTopology(set->type(cell));
      const int64_t np = set->numCellPoints(cell);
      if (!topo || np != topo->numPoints) return false;
      n = static_cast<int>(np);
      for (int k = 0; k < n; ++k) p[k] = set->cellPoint(cell, k);
      return true;
    }
    bool overlaps(const Box& b) const {
      Vec3 p[kMaxLocalPoints];
      int n = 0;
      const CellTopology* topo = nullptr;
      if (!box.overlaps(b)) return false;
      if (!fetch(p, n, topo)) return true;  // the bounding box decides
      Vec3 normals[12], edges[12];
      int nf = 0;
      for (int f = 0; f < topo->numFaces; ++f) {
        const int* v = topo->face[f];
        normals[nf++] = cross(p[v[1]] - p[v[0]], p[v[2]] - p[v[0]]);
        if (topo->faceSize[f] == 4) normals[nf++] = cross(p[v[2]] - p[v[0]], p[v[3]] - p[v[0]]);
      }
      const int ne = set->axes() == CellAxes::All ? topo->numEdges : 0;
      for (int e = 0; e < ne; ++e) edges[e] = p[topo->edge[e][1]] - p[topo->edge[e][0]];
      return convexOverlapsBox(p, n, normals, nf, edges, ne, b);
    }
    /// The separating-axis test against many boxes of one size (the builder's candidate
    /// leaves): axes, the cell's projection intervals and the box radii computed once, then one
    /// dot product per axis and box. Box-normal axes are skipped: candidates come from the
    /// cell's bounding-box range, so they never separate (skipping stays conservative).
    struct Tester {
      static constexpr int kMaxAxes = 12 + 3 * 12;
      // Structure of arrays, left uninitialized: only the first n entries are ever written or
      // read (a tetrahedron's tester uses 4 of the 48 slots; zeroing all of them cost a quarter
      // of the tester's time). The arithmetic per axis is dot(c, axis), as before.
      double ax[kMaxAxes], ay[kMaxAxes], az[kMaxAxes];
      double lo[kMaxAxes], hi[kMaxAxes], r[kMaxAxes];
      int n = 0;
      bool overlaps(Vec3 c) const {
        for (int k = 0; k < n; ++k) {
          const double pc = c.x * ax[k] + c.y * ay[k] + c.z * az[k];
          if (lo[k] - pc > r[k] || hi[k] - pc < -r[k]) return false;
        }
        return true;
      }
    };
    Tester tester(Vec3 half) const {
      Vec3 p[kMaxLocalPoints];
      return tester(half, p, vertices(p));
    }
    /// The cell's points (at most kMaxLocalPoints), for the types with a table; 0 for the others
    /// (their bounding box decides) and for a malformed point count.
    int vertices(Vec3* p) const {
      const CellTopology* topo = cellTopology(set->type(cell));
      const int64_t np = set->numCellPoints(cell);
      if (!topo || np != topo->numPoints) return 0;
      for (int k = 0; k < topo->numPoints; ++k) p[k] = set->cellPoint(cell, k);
      return topo->numPoints;
    }
    /// The tester from the points vertices() gave (n of them; 0: no axes, every candidate of
    /// the bounding-box range overlaps).
    Tester tester(Vec3 half, const Vec3* p, int n) const {
      Tester t;
      if (n == 0) return t;
      const CellTopology* topo = cellTopology(set->type(cell));
      auto add = [&](Vec3 a) {
        if ((a.x == 0 && a.y == 0 && a.z == 0) || t.n == Tester::kMaxAxes) return;
        double mn = std::numeric_limits<double>::infinity(), mx = -mn;
        for (int i = 0; i < n; ++i) {
          const double q = dot(p[i], a);
          mn = std::min(mn, q);
          mx = std::max(mx, q);
        }
        t.ax[t.n] = a.x;
        t.ay[t.n] = a.y;
        t.az[t.n] = a.z;
        t.lo[t.n] = mn;
        t.hi[t.n] = mx;
        t.r[t.n] = half.x * std::fabs(a.x) + half.y * std::fabs(a.y) + half.z * std::fabs(a.z);
        ++t.n;
      };
      // A planar quad's two triangles have parallel normals, and parallel axes give the same
      // verdict (the projections are the same up to scale): its second normal is added only when
      // the face is warped. Leaving out an axis can only answer "overlap" more often, so the
      // cut-off (the sine of the angle below 1e-9) only decides when a nearly flat face counts
      // as flat, never whether the test stays conservative.
      for (int f = 0; f < topo->numFaces; ++f) {
        const int* v = topo->face[f];
        const Vec3 n0 = cross(p[v[1]] - p[v[0]], p[v[2]] - p[v[0]]);
        add(n0);
        if (topo->faceSize[f] == 4) {
          const Vec3 n1 = cross(p[v[2]] - p[v[0]], p[v[3]] - p[v[0]]), c = cross(n0, n1);
          if (dot(c, c) > 1e-18 * dot(n0, n0) * dot(n1, n1)) add(n1);
        }
      }
      if (set->axes() == CellAxes::All) {
        for (int e = 0; e < topo->numEdges; ++e) {
          const Vec3 d = p[topo->edge[e][1]] - p[topo->edge[e][0]];
          add(Vec3(0, -d.z, d.y));
          add(Vec3(d.z, 0, -d.x));
          add(Vec3(-d.y, d.x, 0));
        }
      }
      return t;
    }
  };
  Local local(size_t c) const {
    Local l;
    l.set = this;
    l.cell = c;
    l.box = bounds(c);
    return l;
  }
  bool overlaps(size_t c, const Box& b) const { return local(c).overlaps(b); }

  /// Cheap pre-test of point location in a tetrahedron: false only if some barycentric
  /// coordinate of p lies outside [-tol, 1 + tol]. Degenerate or non-finite cases answer true
  /// (let the exact test decide).
  bool tetraMayContain(size_t c, Vec3 p, double tol) const {
    const PointIds id = cellPointIds(c);
    const Vec3 p0 = point(id[0]), p1 = point(id[1]), p2 = point(id[2]), p3 = point(id[3]);
    const Vec3 a = p1 - p0, b = p2 - p0, d = p3 - p0, r = p - p0;
    const Vec3 bd = cross(b, d);
    const double det = dot(a, bd);
    if (!(std::fabs(det) > 0) || !std::isfinite(det)) return true;
    const double inv = 1.0 / det;
    const double u = dot(r, bd) * inv, v = dot(a, cross(r, d)) * inv, w = dot(a, cross(b, r)) * inv;
    const double s = 1.0 - u - v - w;
    const double lo = -tol, hi = 1.0 + tol;
    return u >= lo && u <= hi && v >= lo && v <= hi && w >= lo && w <= hi && s >= lo && s <= hi;
  }

  /// Bytes held: points (12 bytes each when they are all exact floats, else 24; none when they
  /// are the caller's), offsets (none when every cell has the same number of points: the
  /// offsets are then c x that number), connectivity and types (none when they are the
  /// caller's; no types when all cells have one type), and the cached bounds (until released).
  size_t bytes() const {
    return pts_.d.size() * sizeof(double) + pts_.f.size() * sizeof(float) +
           (cells_.off.size() + cells_.conn32.size()) * sizeof(uint32_t) + cells_.own.size() +
           box_.size() * sizeof(float);
  }
  /// Whether the points are the caller's (the view constructors), not a copy.
  bool pointsViewed() const { return pts_.view; }

 private:
  static std::vector<uint32_t> narrow(const std::vector<int64_t>& v, const char* what);
  template <class T>
  void viewPoints(const T* points, size_t numPoints) {
    if constexpr (std::is_same_v<T, float>) {
      pts_.fp = points;
      floatPoints_ = true;
    } else {
      pts_.dp = points;
    }
    pts_.n = numPoints;
    pts_.view = true;
  }
  void own(std::vector<uint32_t> offsets, std::vector<uint32_t> connectivity, std::vector<uint8_t> types);
  void viewCells(CellArrays cells);
  void validate() const;
  template <class I>
  void validateViewed(const I* off, const I* conn, size_t connSize) const;
  void dropUniformOffsets();
  void dropUniformTypes();
  /// The address of code t in a static table of all 256 codes (one type for all cells).
  static const uint8_t* typeCode(uint8_t t);
  void keepFloatPointsIfExact();
  uint32_t offset(size_t c) const { return cells_.off32[c << cells_.shift]; }
  size_t firstPoint(size_t c) const { return uniform_ >= 0 ? size_t(uniform_) * c : size_t(offset(c)); }
  /// Cell c's bounds as cellBox() gives them, computed from its points.
  void boxOf(size_t c, float f[6]) const;
  void computeBounds(int threads);
  /// The constructors' common checks and set-up, once the points and cells are in place.
  void init(int threads) {
    if (pts_.n >= 0xffffffffu) throw std::length_error("CellSet: more than 2^32 - 1 points");
    validate();
    dropUniformOffsets();
    dropUniformTypes();
    keepFloatPointsIfExact();
    computeBounds(threads);
  }

  /// T with T's member-wise copies followed by T::rebind(): T's pointers into its own vectors
  /// follow a copy (a moved vector keeps its buffer, so moves need no rebind).
  template <class T>
  struct Rebinding : T {
    Rebinding() = default;
    Rebinding(const Rebinding& o) : T(o) { T::rebind(); }
    Rebinding& operator=(const Rebinding& o) {
      T::operator=(o);
      T::rebind();
      return *this;
    }
    Rebinding(Rebinding&&) noexcept = default;
    Rebinding& operator=(Rebinding&&) noexcept = default;
  };
  /// The points: owned doubles (d), owned floats (f, when every given double was exactly a
  /// float), or the caller's (view); point() reads through dp or fp, which follow the owned
  /// arrays through copies and moves.
  struct PointArrays {
    std::vector<double> d;
    std::vector<float> f;
    const double* dp = nullptr;
    const float* fp = nullptr;
    size_t n = 0;
    bool view = false;
    void rebind() {
      if (view) return;
      dp = d.empty() ? nullptr : d.data();
      fp = f.empty() ? nullptr : f.data();
    }
  };
  using Points = Rebinding<PointArrays>;
  Points pts_;
  bool floatPoints_ = false;
  /// The cells: owned 32-bit offsets, connectivity and types, or the caller's arrays (view),
  /// read through off32, conn and types (which follow the owned arrays through copies and
  /// moves). Entry i of the offsets and connectivity is the word at i << shift (shift 1: the
  /// low word of a 64-bit entry). One type for all cells: types points at that type in a
  /// static table and typeMask is 0.
  struct CellData {
    std::vector<uint32_t> off, conn32;
    std::vector<uint8_t> own;
    const Word* off32 = nullptr;
    const Word* conn = nullptr;
    const uint8_t* types = nullptr;
    size_t typeMask = ~size_t{0};
    size_t n = 0;
    size_t connSize = 0;
    int shift = 0;
    bool view = false;
    /// Points the readers at the owned arrays that are in use.
    void rebind() {
      if (!view) {
        off32 = off.empty() ? nullptr : off.data();
        conn = conn32.empty() ? nullptr : conn32.data();
      }
      if (typeMask != 0 && !own.empty()) types = own.data();
    }
  };
  using Cells = Rebinding<CellData>;
  Cells cells_;
  int64_t uniform_ = -1;  // >= 0: every cell has this many points (owned offsets are released)
  LargeVector<float> box_;  // 6 per cell, until releaseBounds()
  Vec3 maxExt_;
  Box total_;
  CellAxes axes_ = CellAxes::Faces;
};

}  // namespace mtree

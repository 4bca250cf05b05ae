// matrixtree_engine: the VTK-free engine (engine/) as a Python extension module, built by
// `pip install .` (scikit-build-core + nanobind) where no VTK C++ library is at hand. It converts
// numpy arrays to the engine's inputs and its results back to numpy arrays, and delegates every
// query to the engine: mtree::CellLocator (cell location, weights, segments, closest points),
// the matrix tree and the SAH kd-tree over triangles (rays, renders with their counters),
// mtree::BlockSparseVolume (volume rendering) and mtree::treeNodes (the tree as boxes). The
// Python package (python/matrixtree) builds its pyvista-facing API on top.
//
// Conventions: points and directions are (n, 3) float64 arrays (other dtypes and layouts are
// converted); cell ids are int64, -1 for none; images have row 0 at the bottom, as the engine
// and VTK store them. Long calls release the GIL. Bad input raises ValueError with the engine's
// message.
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "mtree/vtk91/cell_locator.h"
#include "mtree/core/builder.h"
#include "mtree/core/memory.h"
#include "mtree/core/parallel.h"
#include "mtree/core/tree_nodes.h"
#include "mtree/rays/polygon_mesh.h"
#include "mtree/rays/raycast.h"
#include "mtree/rays/render.h"
#include "mtree/rays/sah_kdtree.h"
#include "mtree/volume/volume.h"

namespace nb = nanobind;
using namespace nb::literals;

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

template <class T>
using Array1 = nb::ndarray<const T, nb::ndim<1>, nb::c_contig, nb::device::cpu>;
using Points = nb::ndarray<const double, nb::shape<-1, 3>, nb::c_contig, nb::device::cpu>;
using Table = nb::ndarray<const float, nb::shape<-1, 4>, nb::c_contig, nb::device::cpu>;
template <class T>
using NumpyArray = nb::ndarray<nb::numpy, T>;

/// A numpy array that owns `v` (moved to the heap, freed with the array).
template <class T>
NumpyArray<T> toNumpy(std::vector<T> v, std::initializer_list<size_t> shape) {
  auto* held = new std::vector<T>(std::move(v));
  nb::capsule owner(held, [](void* p) noexcept { delete static_cast<std::vector<T>*>(p); });
  return NumpyArray<T>(held->data(), shape, owner);
}

template <class T>
std::vector<T> copyOf(const T* p, size_t n) {
  return std::vector<T>(p, p + n);
}

mtree::TreeKind treeKind(const std::string& s) {
  if (s == "octree") return mtree::TreeKind::Octree;
  if (s == "kdtree") return mtree::TreeKind::RegularKd;
  throw nb::value_error(("tree must be 'octree' or 'kdtree', got '" + s + "'").c_str());
}

mtree::TriangleTest triangleTest(const std::string& s) {
  if (s == "moller-trumbore" || s == "mt") return mtree::TriangleTest::MollerTrumbore;
  if (s == "watertight") return mtree::TriangleTest::Watertight;
  throw nb::value_error(("triangle test must be 'moller-trumbore' or 'watertight', got '" + s + "'").c_str());
}

mtree::SahTraversal sahTraversal(const std::string& s) {
  if (s == "stack") return mtree::SahTraversal::Stack;
  if (s == "shortstack") return mtree::SahTraversal::ShortStack;
  if (s == "restart") return mtree::SahTraversal::Restart;
  throw nb::value_error(("traversal must be 'stack', 'shortstack' or 'restart', got '" + s + "'").c_str());
}

void checkBlockEdge(int b) {
  if (b < 1 || b > 32 || (b & (b - 1)))
    throw nb::value_error(("block_size must be a power of two in [1, 32], got " + std::to_string(b)).c_str());
}

mtree::Vec3 vec3(const std::vector<double>& v, const char* what) {
  if (v.size() != 3) throw nb::value_error((std::string(what) + " must have 3 coordinates").c_str());
  return mtree::Vec3(v[0], v[1], v[2]);
}

void checkSameLength(size_t a, size_t b, const char* what) {
  if (a != b) throw nb::value_error((std::string(what) + ": the two arrays differ in length").c_str());
}

/// The nodes of levels lo..hi as numpy arrays: level, box corners, occupancy, primitives below.
nb::dict nodesDict(const mtree::MatrixTree& tree, int lo, int hi) {
  std::vector<mtree::TreeNodeInfo> nodes;
  {
    nb::gil_scoped_release unlocked;
    nodes = mtree::treeNodes(tree, lo, hi);
  }
  const size_t n = nodes.size();
  std::vector<int32_t> level(n);
  std::vector<double> boxLo(3 * n), boxHi(3 * n), occupancy(n);
  std::vector<int64_t> count(n);
  for (size_t i = 0; i < n; ++i) {
    const mtree::Box b = tree.nodeBox(nodes[i].level, nodes[i].c);
    level[i] = nodes[i].level;
    for (int a = 0; a < 3; ++a) {
      boxLo[3 * i + a] = b.lo[a];
      boxHi[3 * i + a] = b.hi[a];
    }
    occupancy[i] = nodes[i].occupancy;
    count[i] = static_cast<int64_t>(nodes[i].primitives);
  }
  nb::dict d;
  d["level"] = toNumpy(std::move(level), {n});
  d["lo"] = toNumpy(std::move(boxLo), {n, 3});
  d["hi"] = toNumpy(std::move(boxHi), {n, 3});
  d["occupancy"] = toNumpy(std::move(occupancy), {n});
  d["count"] = toNumpy(std::move(count), {n});
  d["height"] = tree.empty() ? 0 : tree.height();
  return d;
}

/// The shape and build figures of a matrix tree.
void addTreeStats(nb::dict& d, const mtree::MatrixTree& t, const mtree::BuildStats& s) {
  const int h = t.empty() ? 0 : t.height();
  nb::list levelBytes, levelBlocks, levelDims, phases;
  for (int l = 0; l <= h && !t.empty(); ++l) {
    levelBytes.append(t.levelBytes(l));
    levelBlocks.append(t.levelBlocks(l));
    levelDims.append(nb::make_tuple(t.dim(l, 0), t.dim(l, 1), t.dim(l, 2)));
  }
  nb::dict ph;
  for (const auto& p : s.phasesMs) ph[p.first.c_str()] = p.second;
  const mtree::Box& r = t.rootBox();
  d["tree"] = mtree::treeKindName(t.kind());
  d["height"] = h;
  d["leaves"] = s.leaves;
  d["references"] = s.references;
  d["bytes"] = t.bytes();
  d["level_bytes"] = levelBytes;
  d["level_blocks"] = levelBlocks;
  d["level_dims"] = levelDims;
  d["root_bounds"] = t.empty() ? nb::make_tuple(0.0, -1.0, 0.0, -1.0, 0.0, -1.0)
                               : nb::make_tuple(r.lo.x, r.hi.x, r.lo.y, r.hi.y, r.lo.z, r.hi.z);
  d["median_extent"] = s.medianPrimitiveExtent;
  d["phases_ms"] = ph;
  d["build_ms"] = s.totalMs;
}

// ---- cell locator -----------------------------------------------------------------------------

class CellLocator {
 public:
  CellLocator(Points points, Array1<int64_t> offsets, Array1<int64_t> connectivity, Array1<uint8_t> types,
              const std::string& tree, int height, int blockSize, bool exactOverlap, double leafScale,
              double maxCandidates, int threads)
      : threads_(threads) {
    if (offsets.shape(0) != types.shape(0) + 1)
      throw nb::value_error("offsets must have one entry more than types (numCells + 1)");
    if (height < 0 || height > 63) throw nb::value_error("height must be in [0, 63] (0 = automatic)");
    checkBlockEdge(blockSize);
    mtree::CellLocatorOptions opt;
    opt.kind = treeKind(tree);
    opt.height = height;
    opt.blockEdge = blockSize;
    opt.exactOverlap = exactOverlap;
    opt.leafScale = leafScale;
    opt.maxCandidates = maxCandidates;
    opt.threads = threads;
    std::vector<double> pts = copyOf(points.data(), 3 * points.shape(0));
    std::vector<int64_t> off = copyOf(offsets.data(), offsets.shape(0));
    std::vector<int64_t> conn = copyOf(connectivity.data(), connectivity.shape(0));
    std::vector<uint8_t> ty = copyOf(types.data(), types.shape(0));
    nb::gil_scoped_release unlocked;
    loc_.build(mtree::CellSet(std::move(pts), off, conn, std::move(ty), threads), opt);
  }

  nb::tuple findCells(Points x, double tol2, bool wantPcoords, bool wantWeights) const {
    const size_t n = x.shape(0), w = static_cast<size_t>(loc_.maxCellPoints());
    std::vector<int64_t> ids(n);
    std::vector<double> pc(wantPcoords ? 3 * n : 0), wt(wantWeights ? w * n : 0);
    {
      nb::gil_scoped_release unlocked;
      loc_.findCells(x.data(), n, tol2, ids.data(), wantPcoords ? pc.data() : nullptr,
                     wantWeights ? wt.data() : nullptr, threads_);
    }
    return nb::make_tuple(toNumpy(std::move(ids), {n}),
                          wantPcoords ? nb::cast(toNumpy(std::move(pc), {n, 3})) : nb::none(),
                          wantWeights ? nb::cast(toNumpy(std::move(wt), {n, w})) : nb::none());
  }

  nb::tuple firstHits(Points p1, Points p2, double tol) const {
    checkSameLength(p1.shape(0), p2.shape(0), "first_hits");
    const size_t n = p1.shape(0);
    std::vector<double> t(n), x(3 * n);
    std::vector<int64_t> ids(n);
    {
      nb::gil_scoped_release unlocked;
      loc_.firstHits(p1.data(), p2.data(), n, tol, t.data(), ids.data(), x.data(), threads_);
    }
    return nb::make_tuple(toNumpy(std::move(t), {n}), toNumpy(std::move(ids), {n}), toNumpy(std::move(x), {n, 3}));
  }

  /// Every hit of every segment: offsets (n + 1) into t, ids and x (segment i's hits are
  /// offsets[i]:offsets[i + 1], sorted by t).
  nb::tuple allHits(Points p1, Points p2, double tol) const {
    checkSameLength(p1.shape(0), p2.shape(0), "all_hits");
    const size_t n = p1.shape(0);
    std::vector<std::vector<mtree::SegmentHit>> per(n);
    {
      nb::gil_scoped_release unlocked;
      const int64_t m = static_cast<int64_t>(n);
#pragma omp parallel for num_threads(mtree::resolveThreads(threads_)) schedule(dynamic, 16) if (m > 16)
      for (int64_t i = 0; i < m; ++i)
        loc_.allHits(mtree::Vec3(p1.data() + 3 * i), mtree::Vec3(p2.data() + 3 * i), tol, per[size_t(i)]);
    }
    std::vector<int64_t> offsets(n + 1, 0), ids;
    std::vector<double> t, x;
    for (size_t i = 0; i < n; ++i) {
      for (const mtree::SegmentHit& h : per[i]) {
        t.push_back(h.t);
        ids.push_back(h.cell);
        x.insert(x.end(), {h.x.x, h.x.y, h.x.z});
      }
      offsets[i + 1] = static_cast<int64_t>(t.size());
    }
    const size_t k = t.size();
    return nb::make_tuple(toNumpy(std::move(offsets), {n + 1}), toNumpy(std::move(t), {k}),
                          toNumpy(std::move(ids), {k}), toNumpy(std::move(x), {k, 3}));
  }

  nb::tuple closestPoints(Points x, double radius) const {
    const size_t n = x.shape(0);
    std::vector<double> cp(3 * n), d2(n);
    std::vector<int64_t> ids(n);
    {
      nb::gil_scoped_release unlocked;
      loc_.closestPoints(x.data(), n, radius, cp.data(), ids.data(), d2.data(), threads_);
    }
    return nb::make_tuple(toNumpy(std::move(cp), {n, 3}), toNumpy(std::move(ids), {n}), toNumpy(std::move(d2), {n}));
  }

  NumpyArray<int64_t> cellsWithinBounds(const std::vector<double>& bounds) const {
    if (bounds.size() != 6) throw nb::value_error("bounds must be (xmin, xmax, ymin, ymax, zmin, zmax)");
    mtree::Box b;
    b.lo = mtree::Vec3(bounds[0], bounds[2], bounds[4]);
    b.hi = mtree::Vec3(bounds[1], bounds[3], bounds[5]);
    std::vector<int64_t> ids;
    {
      nb::gil_scoped_release unlocked;
      loc_.cellsWithinBounds(b, ids);
    }
    const size_t n = ids.size();
    return toNumpy(std::move(ids), {n});
  }

  NumpyArray<int64_t> cellsAlongSegment(const std::vector<double>& p1, const std::vector<double>& p2,
                                        double tol) const {
    const mtree::Vec3 a = vec3(p1, "p1"), b = vec3(p2, "p2");
    std::vector<int64_t> ids;
    {
      nb::gil_scoped_release unlocked;
      loc_.cellsAlongSegment(a, b, tol, ids);
    }
    const size_t n = ids.size();
    return toNumpy(std::move(ids), {n});
  }

  nb::dict nodes(int lo, int hi) const { return nodesDict(loc_.tree(), lo, hi); }

  nb::dict stats() const {
    nb::dict d;
    addTreeStats(d, loc_.tree(), loc_.stats());
    d["cells"] = loc_.numCells();
    d["max_cell_points"] = loc_.maxCellPoints();
    d["max_cell_dimension"] = loc_.maxCellDimension();
    d["leaf_scale"] = loc_.leafScaleUsed();
    d["max_candidates"] = loc_.maxCandidatesUsed();
    d["bytes"] = loc_.bytes();
    return d;
  }

  int maxCellPoints() const { return loc_.maxCellPoints(); }
  size_t numCells() const { return loc_.numCells(); }

 private:
  mtree::CellLocator loc_;
  int threads_ = 0;
};

// ---- surfaces: triangles for rays and renders ---------------------------------------------------

/// A render's per-pixel arrays (row 0 at the bottom) and totals.
nb::dict renderDict(mtree::RenderResult r, const std::vector<int64_t>& cellOfTriangle) {
  const size_t w = size_t(r.width), h = size_t(r.height), npix = w * h;
  std::vector<int64_t> cells(npix);
  for (size_t i = 0; i < npix; ++i) cells[i] = r.hitPrim[i] == MT_NULL ? -1 : cellOfTriangle[r.hitPrim[i]];
  nb::dict d;
  d["rgb"] = toNumpy(std::move(r.rgb), {h, w, 3});
  d["node_visits"] = toNumpy(std::move(r.nodeVisits), {h, w});
  d["triangle_tests"] = toNumpy(std::move(r.primTests), {h, w});
  d["depth"] = toNumpy(std::move(r.depth), {h, w});
  d["cell"] = toNumpy(std::move(cells), {h, w});
  d["render_ms"] = r.ms;
  d["primary_rays"] = r.primaryRays;
  d["shadow_rays"] = r.shadowRays;
  d["hits"] = r.hits;
  d["total_node_visits"] = r.stats.nodeVisits;
  d["total_triangle_tests"] = r.stats.primTests;
  return d;
}

/// Renders the surface through `tracer` (mtree::render: primary rays, one shadow ray per hit).
template <class Tracer>
nb::dict renderSurface(const Tracer& tracer, const mtree::TriangulatedSurface& surface, int width, int height,
                       const std::vector<double>& eye, const std::vector<double>& target,
                       const std::vector<double>& up, double viewAngle, bool shadows, bool counters, int threads) {
  if (width < 1 || height < 1 || width > 16384 || height > 16384)
    throw nb::value_error("the image size must be 1..16384 pixels per side");
  mtree::Camera cam;
  cam.eye = vec3(eye, "eye");
  cam.target = vec3(target, "target");
  cam.up = vec3(up, "up");
  cam.fovyDegrees = viewAngle;
  cam.width = width;
  cam.height = height;
  mtree::RenderOptions opt;
  opt.shadows = shadows;
  opt.threads = threads;
  opt.counters = counters;
  mtree::RenderResult r;
  {
    nb::gil_scoped_release unlocked;
    mtree::Box scene;
    for (size_t i = 0; i < surface.mesh.numPoints(); ++i) scene.extend(mtree::Vec3(&surface.mesh.points()[3 * i]));
    r = mtree::render(tracer, surface.mesh, scene, cam, opt);
  }
  return renderDict(std::move(r), surface.cellOfTriangle);
}

/// First hits of n rays through `tracer` (its batches, counted): t (inf on a miss), the polydata
/// cell (-1), and the summed node visits and triangle tests.
template <class Tracer>
nb::tuple traceRays(const Tracer& tracer, const std::vector<int64_t>& cellOfTriangle, Points o, Points d, double tMax,
                    int threads) {
  checkSameLength(o.shape(0), d.shape(0), "intersect");
  const size_t n = o.shape(0);
  std::vector<double> t(n);
  std::vector<int64_t> cells(n);
  uint64_t visits = 0, tests = 0;
  {
    nb::gil_scoped_release unlocked;
    constexpr int64_t chunk = 1024;
    const int64_t chunks = (static_cast<int64_t>(n) + chunk - 1) / chunk;
#pragma omp parallel for num_threads(mtree::resolveThreads(threads)) schedule(dynamic, 1) reduction(+ : visits, tests)
    for (int64_t c = 0; c < chunks; ++c) {
      const size_t first = size_t(c * chunk), m = std::min(size_t(chunk), n - first);
      std::vector<mtree::Vec3> ro(m), rd(m);
      for (size_t i = 0; i < m; ++i) {
        ro[i] = mtree::Vec3(o.data() + 3 * (first + i));
        rd[i] = mtree::Vec3(d.data() + 3 * (first + i));
      }
      const std::vector<double> tmax(m, tMax);
      mtree::RayBatch b;
      b.o = ro.data();
      b.d = rd.data();
      b.tmax = tmax.data();
      b.n = m;
      std::vector<mtree::RayHit> h(m);
      std::vector<uint32_t> v(m, 0), k(m, 0);
      tracer.first(b, h.data(), mtree::RayCounters{v.data(), k.data()});
      for (size_t i = 0; i < m; ++i) {
        t[first + i] = h[i].hit() ? h[i].t : kInf;
        cells[first + i] = h[i].hit() ? cellOfTriangle[h[i].prim] : -1;
        visits += v[i];
        tests += k[i];
      }
    }
  }
  return nb::make_tuple(toNumpy(std::move(t), {n}), toNumpy(std::move(cells), {n}), visits, tests);
}

/// A surface's polygons and strips (offsets/connectivity as vtkCellArray stores them) as
/// triangles, each knowing its polydata cell.
mtree::TriangulatedSurface surfaceOf(Points points, Array1<int64_t> polyOffsets, Array1<int64_t> polyConn,
                                     Array1<int64_t> stripOffsets, Array1<int64_t> stripConn, int64_t firstCell) {
  auto cells = [](const Array1<int64_t>& off) { return off.shape(0) > 0 ? off.shape(0) - 1 : 0; };
  return mtree::triangulateSurface(copyOf(points.data(), 3 * points.shape(0)), polyOffsets.data(), cells(polyOffsets),
                                   polyConn.data(), polyConn.shape(0), stripOffsets.data(), cells(stripOffsets),
                                   stripConn.data(), stripConn.shape(0), firstCell);
}

/// A matrix octree or kd-tree over the triangles of a surface (vtkMatrixTree's engine part).
class SurfaceTree {
 public:
  SurfaceTree(Points points, Array1<int64_t> polyOffsets, Array1<int64_t> polyConn, Array1<int64_t> stripOffsets,
              Array1<int64_t> stripConn, int64_t firstCell, const std::string& tree, int height, int blockSize,
              bool exact, double leafScale, int threads)
      : threads_(threads) {
    if (height < 0 || height > 63) throw nb::value_error("height must be in [0, 63] (0 = automatic)");
    checkBlockEdge(blockSize);
    if (!(leafScale > 0)) throw nb::value_error("leaf_scale must be > 0");
    mtree::BuildOptions opt;
    opt.kind = treeKind(tree);
    opt.height = height;
    opt.blockEdge = blockSize;
    opt.overlap = exact ? mtree::OverlapMode::Exact : mtree::OverlapMode::BoundingBox;
    opt.leafScale = leafScale;
    opt.threads = threads;
    surface_ = surfaceOf(points, polyOffsets, polyConn, stripOffsets, stripConn, firstCell);
    nb::gil_scoped_release unlocked;
    mtree::MatrixTreeBuilder<mtree::TriangleMesh>::build(surface_.mesh, opt, tree_, &stats_);
    // The leaf triangles the ray queries test (as vtkMatrixTree keeps them by default).
    payload_.build(tree_.primitiveIndices().data(), tree_.primitiveIndices().size(), surface_.mesh, threads);
  }

  nb::tuple intersect(Points o, Points d, double tMax, const std::string& test) const {
    const mtree::MatrixTreeTracer tracer{tree_, surface_.mesh, triangleTest(test), &payload_};
    return traceRays(tracer, surface_.cellOfTriangle, o, d, tMax, threads_);
  }

  NumpyArray<int32_t> findLeaves(Points x) const {
    const size_t n = x.shape(0);
    std::vector<int32_t> out(5 * n);
    {
      nb::gil_scoped_release unlocked;
      const int64_t m = static_cast<int64_t>(n);
#pragma omp parallel for num_threads(mtree::resolveThreads(threads_)) schedule(static) if (m > 4096)
      for (int64_t i = 0; i < m; ++i) {
        const mtree::NodeRef r = tree_.leafFind(mtree::Vec3(x.data() + 3 * i));
        int32_t* o = out.data() + 5 * i;
        o[0] = r.level;
        o[1] = r.c[0];
        o[2] = r.c[1];
        o[3] = r.c[2];
        o[4] = r.exists ? 1 : 0;
      }
    }
    return toNumpy(std::move(out), {n, 5});
  }

  nb::dict render(int width, int height, const std::vector<double>& eye, const std::vector<double>& target,
                  const std::vector<double>& up, double viewAngle, bool shadows, const std::string& test,
                  bool counters) const {
    const mtree::MatrixTreeTracer tracer{tree_, surface_.mesh, triangleTest(test), &payload_};
    return renderSurface(tracer, surface_, width, height, eye, target, up, viewAngle, shadows, counters, threads_);
  }

  nb::dict nodes(int lo, int hi) const { return nodesDict(tree_, lo, hi); }

  nb::dict stats() const {
    nb::dict d;
    addTreeStats(d, tree_, stats_);
    d["triangles"] = surface_.mesh.size();
    d["leaf_triangles_bytes"] = payload_.bytes();
    return d;
  }

  NumpyArray<int64_t> cellOfTriangle() const { return toNumpy(surface_.cellOfTriangle, {surface_.cellOfTriangle.size()}); }

 private:
  mtree::TriangulatedSurface surface_;
  mtree::MatrixTree tree_;
  mtree::LeafTriangles payload_;
  mtree::BuildStats stats_;
  int threads_ = 0;
};

/// The SAH kd-tree baseline over the same triangles (Wald & Havran build; the paper's comparison).
class SahTree {
 public:
  SahTree(Points points, Array1<int64_t> polyOffsets, Array1<int64_t> polyConn, Array1<int64_t> stripOffsets,
          Array1<int64_t> stripConn, int64_t firstCell, int threads)
      : threads_(threads) {
    surface_ = surfaceOf(points, polyOffsets, polyConn, stripOffsets, stripConn, firstCell);
    nb::gil_scoped_release unlocked;
    tree_.build(surface_.mesh);
    if (!tree_.primitiveIndices().empty())
      payload_.build(tree_.primitiveIndices().data(), tree_.primitiveIndices().size(), surface_.mesh, threads);
  }

  nb::tuple intersect(Points o, Points d, double tMax, const std::string& traversal, int shortStack,
                      const std::string& test) const {
    const mtree::SahTracer tracer{tree_, surface_.mesh, sahTraversal(traversal), triangleTest(test), shortStack, leaves()};
    return traceRays(tracer, surface_.cellOfTriangle, o, d, tMax, threads_);
  }

  nb::dict render(int width, int height, const std::vector<double>& eye, const std::vector<double>& target,
                  const std::vector<double>& up, double viewAngle, bool shadows, const std::string& traversal,
                  int shortStack, const std::string& test, bool counters) const {
    const mtree::SahTracer tracer{tree_, surface_.mesh, sahTraversal(traversal), triangleTest(test), shortStack, leaves()};
    return renderSurface(tracer, surface_, width, height, eye, target, up, viewAngle, shadows, counters, threads_);
  }

  nb::dict stats() const {
    const mtree::SahBuildStats& s = tree_.stats();
    nb::dict d;
    d["tree"] = "sah";
    d["triangles"] = surface_.mesh.size();
    d["nodes"] = s.nodes;
    d["leaves"] = s.leaves;
    d["references"] = s.references;
    d["bytes"] = s.bytes;
    d["depth"] = s.depth;
    d["sah_cost"] = s.sahCost;
    d["build_ms"] = s.buildMs;
    return d;
  }

 private:
  const mtree::LeafTriangles* leaves() const { return payload_.empty() ? nullptr : &payload_; }
  mtree::TriangulatedSurface surface_;
  mtree::SahKdTree tree_;
  mtree::LeafTriangles payload_;
  int threads_ = 0;
};

// ---- volumes ----------------------------------------------------------------------------------

/// A scalar volume classified through a transfer table into the block-sparse encoding
/// (mtree::BlockSparseVolume), rendered by ray marching with empty-space skipping.
class Volume {
 public:
  Volume(nb::ndarray<nb::ro, nb::c_contig, nb::device::cpu> scalars, const std::vector<int>& dims, Table table,
         double lo, double hi, double unitDistance, bool sparse, int threads)
      : table_(lo, hi, copyOf(table.data(), 4 * table.shape(0)), unitDistance) {
    if (dims.size() != 3) throw nb::value_error("dims must be three point counts (nx, ny, nz)");
    for (int a = 0; a < 3; ++a) dims_[a] = dims[a];
    if (int64_t(dims_[0]) * dims_[1] * dims_[2] != int64_t(scalars.size()))
      throw nb::value_error("scalars must hold nx * ny * nz values (x fastest)");
    mtree::VolumeBuildOptions bo;
    bo.sparse = sparse;
    bo.compactIntegralFloat = true;
    bo.threads = threads;
    const nb::dlpack::dtype t = scalars.dtype();
    const void* p = scalars.data();
    bool built;
    {
      nb::gil_scoped_release unlocked;
      built = build<uint8_t>(t, p, bo) || build<int8_t>(t, p, bo) || build<uint16_t>(t, p, bo) ||
              build<int16_t>(t, p, bo) || build<uint32_t>(t, p, bo) || build<int32_t>(t, p, bo) ||
              build<uint64_t>(t, p, bo) || build<int64_t>(t, p, bo) || build<float>(t, p, bo) ||
              build<double>(t, p, bo);
    }
    if (!built) throw nb::value_error("volume scalars must be a numeric array of (u)int8..64, float32 or float64");
  }

  nb::tuple render(int width, int height, const std::vector<double>& position, const std::vector<double>& focalPoint,
                   const std::vector<double>& viewUp, double viewAngle, bool parallel, double parallelScale,
                   const std::vector<double>& origin, const std::vector<double>& spacing, double sampleDistance,
                   double imageSampleDistance, double earlyTermination, bool doublePrecision, bool emptySpaceSkipping,
                   bool shade, double ambient, double diffuse, double specular, double specularPower,
                   int threads) const {
    mtree::VolumeCamera cam;
    cam.position = vec3(position, "position");
    cam.focalPoint = vec3(focalPoint, "focal_point");
    cam.viewUp = vec3(viewUp, "view_up");
    cam.viewAngle = viewAngle;
    cam.parallel = parallel;
    cam.parallelScale = parallelScale;
    cam.width = width;
    cam.height = height;
    mtree::VolumeGeometry geo;
    const mtree::Vec3 o = vec3(origin, "origin"), sp = vec3(spacing, "spacing");
    for (int a = 0; a < 3; ++a) {
      geo.origin[a] = o[a];
      geo.spacing[a] = sp[a];
    }
    mtree::VolumeRenderOptions ro;
    ro.sampleDistance = sampleDistance;
    ro.imageSampleDistance = imageSampleDistance;
    ro.earlyTermination = earlyTermination;
    ro.doublePrecision = doublePrecision;
    ro.emptySpaceSkipping = emptySpaceSkipping;
    ro.shade = shade;
    ro.ambient = ambient;
    ro.diffuse = diffuse;
    ro.specular = specular;
    ro.specularPower = specularPower;
    ro.threads = threads;
    mtree::checkVolumeRenderArguments(geo, table_, cam, ro, "render");
    mtree::VolumeImage img;
    {
      nb::gil_scoped_release unlocked;
      img = mtree::renderVolume(vol_, geo, table_, cam, ro);
    }
    nb::dict st;
    st["render_ms"] = img.ms;
    st["rays"] = img.rays;
    st["samples"] = img.samples;
    st["skips"] = img.skips;
    st["lanes"] = img.lanes;
    const size_t w = size_t(img.width), h = size_t(img.height);
    return nb::make_tuple(toNumpy(std::move(img.rgba), {h, w, 4}), st);
  }

  nb::dict stats() const {
    const mtree::VolumeStats& s = vol_.stats();
    static const char* const storage[] = {"float32", "uint8", "uint16"};
    nb::dict d;
    d["build_ms"] = s.buildMs;
    d["voxels"] = s.voxels;
    d["cells"] = s.cells;
    d["visible_cells"] = s.visibleCells;
    d["blocks_allocated"] = s.blocksAllocated;
    d["blocks_dense"] = s.blocksDense;
    d["bricks_visible"] = s.bricksVisible;
    d["bricks"] = s.bricks;
    d["levels"] = s.levels;
    d["block_bytes"] = s.blockBytes;
    d["bytes"] = s.bytes;
    d["dense_bytes"] = s.denseBytes;
    d["non_finite"] = s.nonFinite;
    d["storage"] = storage[static_cast<int>(s.storage)];
    d["quantization_step"] = double(vol_.quantizationStep());
    return d;
  }

 private:
  template <class T>
  bool build(nb::dlpack::dtype t, const void* p, const mtree::VolumeBuildOptions& bo) {
    if (t != nb::dtype<T>()) return false;
    vol_.build(static_cast<const T*>(p), dims_, table_, bo);
    return true;
  }

  mtree::TransferTable table_;
  mtree::BlockSparseVolume vol_;
  int dims_[3] = {0, 0, 0};
};

}  // namespace

NB_MODULE(matrixtree_engine, m) {
  m.doc() = "MatrixTree's VTK-free engine: cell location, rays, renders and volume rendering on matrix trees";
  m.attr("__version__") = MATRIXTREE_VERSION;

  m.def("cached_memory", []() { return mtree::cachedMemoryBytes(); },
        "Bytes of freed tree arrays the process keeps for the next build.");
  m.def("release_cached_memory", []() { return mtree::releaseCachedMemory(); },
        "Hands every kept mapping back to the system; returns its bytes.");

  nb::class_<CellLocator>(m, "CellLocator",
                          "Cell location, segments and closest points over linear cells (mtree::CellLocator).")
      .def(nb::init<Points, Array1<int64_t>, Array1<int64_t>, Array1<uint8_t>, const std::string&, int, int, bool,
                    double, double, int>(),
           "points"_a, "offsets"_a, "connectivity"_a, "types"_a, "tree"_a = "octree", "height"_a = 0,
           "block_size"_a = 8, "exact_overlap"_a = false, "leaf_scale"_a = 0.0, "max_candidates"_a = 0.0,
           "threads"_a = 0)
      .def("find_cells", &CellLocator::findCells, "points"_a, "tol2"_a = 0.0, "pcoords"_a = false,
           "weights"_a = false, "(ids, pcoords or None, weights or None) of the cell containing each point")
      .def("first_hits", &CellLocator::firstHits, "p1"_a, "p2"_a, "tol"_a = 0.0,
           "(t, ids, points) of each segment's first hit")
      .def("all_hits", &CellLocator::allHits, "p1"_a, "p2"_a, "tol"_a = 0.0,
           "(offsets, t, ids, points) of every hit of every segment")
      .def("closest_points", &CellLocator::closestPoints, "points"_a, "radius"_a = kInf,
           "(closest, ids, dist2) of each point")
      .def("cells_within_bounds", &CellLocator::cellsWithinBounds, "bounds"_a)
      .def("cells_along_segment", &CellLocator::cellsAlongSegment, "p1"_a, "p2"_a, "tol"_a = 0.0)
      .def("nodes", &CellLocator::nodes, "lo"_a = 0, "hi"_a = -1)
      .def("stats", &CellLocator::stats)
      .def_prop_ro("max_cell_points", &CellLocator::maxCellPoints)
      .def_prop_ro("n_cells", &CellLocator::numCells);

  nb::class_<SurfaceTree>(m, "SurfaceTree", "A matrix octree or kd-tree over a surface's triangles.")
      .def(nb::init<Points, Array1<int64_t>, Array1<int64_t>, Array1<int64_t>, Array1<int64_t>, int64_t,
                    const std::string&, int, int, bool, double, int>(),
           "points"_a, "poly_offsets"_a, "poly_connectivity"_a, "strip_offsets"_a, "strip_connectivity"_a,
           "first_cell"_a = 0, "tree"_a = "octree", "height"_a = 0, "block_size"_a = 8, "exact"_a = true,
           "leaf_scale"_a = 2.0, "threads"_a = 0)
      .def("intersect", &SurfaceTree::intersect, "origins"_a, "directions"_a, "t_max"_a = kInf,
           "test"_a = "moller-trumbore", "(t, cells, node_visits, triangle_tests) of each ray's first hit")
      .def("find_leaves", &SurfaceTree::findLeaves, "points"_a)
      .def("render", &SurfaceTree::render, "width"_a, "height"_a, "eye"_a, "target"_a, "up"_a,
           "view_angle"_a = 30.0, "shadows"_a = true, "test"_a = "moller-trumbore", "counters"_a = false,
           "per-pixel node visits and triangle tests only with counters (the walks run without them otherwise)")
      .def("nodes", &SurfaceTree::nodes, "lo"_a = 0, "hi"_a = -1)
      .def("stats", &SurfaceTree::stats)
      .def_prop_ro("cell_of_triangle", &SurfaceTree::cellOfTriangle, nb::rv_policy::move);

  nb::class_<SahTree>(m, "SahTree", "The SAH kd-tree baseline over a surface's triangles.")
      .def(nb::init<Points, Array1<int64_t>, Array1<int64_t>, Array1<int64_t>, Array1<int64_t>, int64_t, int>(),
           "points"_a, "poly_offsets"_a, "poly_connectivity"_a, "strip_offsets"_a, "strip_connectivity"_a,
           "first_cell"_a = 0, "threads"_a = 0)
      .def("intersect", &SahTree::intersect, "origins"_a, "directions"_a, "t_max"_a = kInf, "traversal"_a = "stack",
           "short_stack"_a = 3, "test"_a = "moller-trumbore")
      .def("render", &SahTree::render, "width"_a, "height"_a, "eye"_a, "target"_a, "up"_a, "view_angle"_a = 30.0,
           "shadows"_a = true, "traversal"_a = "stack", "short_stack"_a = 3, "test"_a = "moller-trumbore",
           "counters"_a = false)
      .def("stats", &SahTree::stats);

  nb::class_<Volume>(m, "Volume", "A scalar volume in the block-sparse encoding, classified by a transfer table.")
      .def(nb::init<nb::ndarray<nb::ro, nb::c_contig, nb::device::cpu>, const std::vector<int>&, Table, double, double,
                    double, bool, int>(),
           "scalars"_a, "dims"_a, "table"_a, "lo"_a, "hi"_a, "unit_distance"_a = 1.0, "sparse"_a = true,
           "threads"_a = 0)
      .def("render", &Volume::render, "width"_a, "height"_a, "position"_a, "focal_point"_a, "view_up"_a,
           "view_angle"_a = 30.0, "parallel"_a = false, "parallel_scale"_a = 1.0, "origin"_a, "spacing"_a,
           "sample_distance"_a, "image_sample_distance"_a = 1.0, "early_termination"_a = 0.99,
           "double_precision"_a = false, "empty_space_skipping"_a = true, "shade"_a = false, "ambient"_a = 0.2,
           "diffuse"_a = 0.7, "specular"_a = 0.2, "specular_power"_a = 10.0, "threads"_a = 0,
           "(rgba (h, w, 4) float32, row 0 at the bottom; stats)")
      .def("stats", &Volume::stats);
}

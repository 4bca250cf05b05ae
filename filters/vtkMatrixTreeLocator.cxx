#include "vtkMatrixTreeLocator.h"

#include "vtkCellData.h"
#include "vtkCommand.h"
#include "vtkCellArray.h"
#include "vtkDataSet.h"
#include "vtkDoubleArray.h"
#include "vtkFloatArray.h"
#include "vtkPointSet.h"
#include "vtkUnsignedCharArray.h"
#include "vtkUnstructuredGrid.h"
#include "vtkGenericCell.h"
#include "vtkIdList.h"
#include "vtkIdTypeArray.h"
#include "vtkFieldData.h"
#include "vtkIntArray.h"
#include "vtkObjectFactory.h"
#include "vtkPoints.h"
#include "vtkPolyData.h"
#include "vtkQuad.h"
#include "vtkTriangle.h"
#include "vtkSmartPointer.h"

#include "mtree/core/builder.h"
#include "mtree/cells/cell_eval.h"
#include "mtree/cells/cells.h"
#include "mtree/cells/leaf_boxes.h"
#include "mtree/cells/segment_filter.h"
#include "mtree/vtk91/face_hit.h"
#include "mtree/device/opencl.h"

#include <omp.h>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <sstream>
#include <string>
#include <limits>
#include <memory>
#include <optional>
#include <queue>
#include <unordered_set>
#include <vector>

struct vtkMatrixTreeLocatorInternals
{
  // The data set's point array when Cells reads the points from it instead of a copy (float or
  // double arrays of 3 components): held so that it outlives a SetPoints() on the data set.
  vtkSmartPointer<vtkDataArray> PointArray;
  // The same for the cell arrays Cells reads in place (a vtkCellArray's offsets and
  // connectivity, an unstructured grid's types), so that they outlive a SetCells() on the data set.
  vtkSmartPointer<vtkDataArray> OffsetsArray, ConnectivityArray, TypesArray;
  mtree::CellSet Cells;
  mtree::MatrixTree Tree;
  mtree::BuildStats Stats;
  double MaxCellExtent[3] = { 0, 0, 0 }; // largest cell bounding-box extent per axis
  double LeafScaleUsed = 0;               // the last build's leaf scale (LeafScale or automatic)
  double MaxCandidatesUsed = 0;           // and candidate cap (MaxCandidates or automatic)
  // Per reference (same order as the tree's primitive indices): the cell's bounds, padded by
  // 1e-3 of its largest extent, clipped to the leaf and quantized outwards to 1/255 of the
  // leaf (xlo xhi ylo yhi zlo zhi). Point location scans these sequentially instead of
  // fetching every candidate's bounds from a random place: 6 bytes per reference.
  mtree::LargeVector<uint8_t> LeafBoxes;
  // One mtree::ConvexShapeMemo byte per cell where the cells include hexahedra, wedges or
  // pyramids (else empty): the ray queries' planarity and convexity checks of a cell, done once
  // per build instead of once per segment. Written by concurrent queries (relaxed atomics).
  struct FreeDeleter
  {
    void operator()(uint8_t* p) const { std::free(p); }
  };
  std::unique_ptr<uint8_t[], FreeDeleter> ShapeMemo; // Cells.size() bytes when allocated
  vtkDataSet* BuiltOn = nullptr; // the data set of the last build (compared, never dereferenced)
  std::string Phases; // "name ms; ..." of the last build, conversion and tree phases
  bool Valid = false;

  // The OpenCL backend: the device locator for the selector, and whether it holds the current
  // build (cleared by every build, so FindCells uploads again only after one).
  std::unique_ptr<mtree::ocl::CellLocator> CL;
  std::string CLSelector;
  std::string CLDeviceName;
  bool CLUploaded = false;
  std::string FindPhases; // "name ms; ..." of the last OpenCL FindCells
};

vtkStandardNewMacro(vtkMatrixTreeLocator);

namespace
{
// Whether some cell's type satisfies pred: one type is asked once when all cells share it,
// else the cells are scanned in order until pred holds.
template <class Pred>
bool AnyCellType(const mtree::CellSet& cells, Pred pred)
{
  const size_t scan = cells.uniformType() ? std::min<size_t>(cells.size(), 1) : cells.size();
  for (size_t c = 0; c < scan; ++c)
  {
    if (pred(cells.type(c)))
    {
      return true;
    }
  }
  return false;
}

// Whether no cell is 3-D (a surface; lines and vertices too): the automatic LeafScale and
// MaxCandidates are then 4 and 3 instead of 1 and 16, about two levels up from the volume rule
// (leaves of about four median triangle extents, not one). On the five surface meshes that cut
// references per triangle from 6-10 to 1.8-2.3, memory from 2.2-3.7x vtkStaticCellLocator's to
// 0.56-0.68x and the build from 3.5-7.8x to 1.0-2.4x, and rays went from 4.8-8.4x to 6.4-9.6x
// faster than VTK's, FindCell within the noise (docs/bench_locators.md); on the volume grids
// one level up costs FindCell 20%, so they keep the volume rule. A first 3-D cell ends the scan.
bool NoVolumeCells(const mtree::CellSet& cells)
{
  // Each type's dimension from VTK's own cell class, once per type met.
  signed char dim[256];
  std::fill(dim, dim + 256, static_cast<signed char>(-1));
  return !AnyCellType(cells, [&dim](uint8_t t) {
    if (dim[t] < 0)
    {
      vtkSmartPointer<vtkCell> cell = vtkSmartPointer<vtkCell>::Take(vtkGenericCell::InstantiateCell(t));
      dim[t] = static_cast<signed char>(cell ? cell->GetCellDimension() : 0);
    }
    return dim[t] == 3;
  });
}

// Whether any cell is a hexahedron, wedge or pyramid (the cells ConvexShapeMemo serves).
bool HasConvexPolyhedra(const mtree::CellSet& cells)
{
  return AnyCellType(cells,
    [](uint8_t t) { return t == mtree::kHexahedron || t == mtree::kWedge || t == mtree::kPyramid; });
}

// Distance squared from x to a box given as (lo, hi).
inline double BoxDistance2(const double x[3], const mtree::Box& b)
{
  double d2 = 0;
  for (int a = 0; a < 3; ++a)
  {
    const double d = std::max({ b.lo[a] - x[a], 0.0, x[a] - b.hi[a] });
    d2 += d * d;
  }
  return d2;
}

inline double BoundsDistance2(const double x[3], const float* b)
{
  double d2 = 0;
  for (int a = 0; a < 3; ++a)
  {
    const double d = std::max({ b[2 * a] - x[a], 0.0, x[a] - b[2 * a + 1] });
    d2 += d * d;
  }
  return d2;
}

// Children of node c at level l (the next level splits each axis a by 2^s[a]).
template <class F>
void ForEachChild(const mtree::MatrixTree& t, int l, const int c[3], F&& f)
{
  int s[3];
  for (int a = 0; a < 3; ++a)
  {
    s[a] = t.logDim(l + 1, a) - t.logDim(l, a);
  }
  for (int dz = 0; dz < (1 << s[2]); ++dz)
    for (int dy = 0; dy < (1 << s[1]); ++dy)
      for (int dx = 0; dx < (1 << s[0]); ++dx)
      {
        const int cc[3] = { (c[0] << s[0]) + dx, (c[1] << s[1]) + dy, (c[2] << s[2]) + dz };
        if (t.nodeExists(l + 1, cc))
        {
          f(cc);
        }
      }
}

// Cell `id`'s points as the engine reads them into pts (3 doubles each); at most n points.
inline void GatherPoints(const mtree::CellSet& cells, size_t id, int64_t n, double* pts)
{
  const mtree::CellSet::PointIds pid = cells.cellPointIds(id);
  for (int64_t k = 0; k < n; ++k)
  {
    const mtree::Vec3 p = cells.point(pid[k]);
    pts[3 * k] = p.x;
    pts[3 * k + 1] = p.y;
    pts[3 * k + 2] = p.z;
  }
}

// Cell `id` into `cell` from the engine's copy: the same type, point ids and coordinates as
// vtkDataSet::GetCell (the copy holds the dataset's values exactly: doubles, or floats where every
// coordinate is one), without touching VTK's own connectivity and point arrays — for a random
// query those are a second set of cache misses on data the scan has just read. Linear types
// only; the others (and a cell needing VTK's initialisation) go through GetCell. `pts`, when
// given, are the cell's coordinates already read from the copy (3 doubles per point).
void FillCell(vtkDataSet* ds, const vtkMatrixTreeLocatorInternals& in, vtkIdType id, vtkGenericCell* cell,
  const double* pts = nullptr)
{
  const uint8_t type = in.Cells.type(static_cast<size_t>(id));
  if (type < VTK_VERTEX || type > VTK_PYRAMID)
  {
    ds->GetCell(id, cell);
    return;
  }
  // VTK_VERTEX ... VTK_PYRAMID need no initialisation and have no explicit faces (only
  // polyhedra and the higher-order types do), so the generic cell's type is all there is to set.
  cell->SetCellType(type);
  const vtkIdType n = static_cast<vtkIdType>(in.Cells.numCellPoints(static_cast<size_t>(id)));
  const mtree::CellSet::PointIds pid = in.Cells.cellPointIds(static_cast<size_t>(id));
  if (cell->PointIds->GetNumberOfIds() != n)
  {
    cell->PointIds->SetNumberOfIds(n);
  }
  vtkIdType* ids = cell->PointIds->GetPointer(0);
  for (vtkIdType k = 0; k < n; ++k)
  {
    ids[k] = static_cast<vtkIdType>(pid[k]);
  }
  // The coordinates straight into the cell's double array (n virtual SetTuple calls otherwise);
  // Modified() as SetNumberOfPoints does, so the points' MTime moves as before.
  vtkDoubleArray* xyz = vtkDoubleArray::FastDownCast(cell->Points->GetData());
  if (!xyz || xyz->GetNumberOfComponents() != 3 || xyz->GetNumberOfTuples() != n)
  {
    cell->Points->SetNumberOfPoints(n);
    xyz = vtkDoubleArray::FastDownCast(cell->Points->GetData());
  }
  else
  {
    cell->Points->Modified();
  }
  if (!xyz)
  {
    for (vtkIdType k = 0; k < n; ++k)
    {
      const mtree::Vec3 p = in.Cells.cellPoint(static_cast<size_t>(id), k);
      cell->Points->SetPoint(k, p.x, p.y, p.z);
    }
    return;
  }
  double* out = xyz->GetPointer(0);
  if (pts)
  {
    std::copy(pts, pts + 3 * n, out);
  }
  else
  {
    GatherPoints(in.Cells, static_cast<size_t>(id), n, out);
  }
}

// Does cell `id` contain x, as VTK's EvaluatePosition decides? If so the cell is filled into
// `cell` and pcoords and weights are VTK's. engineEval: the linear volume cells are evaluated by
// the engine (mtree/cells/cell_eval.h: VTK's arithmetic, VTK asked where a different rounding could
// change the answer), and only a containing cell is filled; otherwise every cell is filled and
// handed to VTK (tetrahedra after a cheap pre-test that only rejects what VTK would).
MT_ALWAYS_INLINE bool CellContains(vtkDataSet* ds, const vtkMatrixTreeLocatorInternals& in, const double x[3], vtkIdType id,
  vtkGenericCell* cell, double pcoords[3], double* weights, bool engineEval)
{
  const uint8_t type = in.Cells.type(static_cast<size_t>(id));
  double closest[3], dist2;
  int subId = 0;
  if (engineEval)
  {
    const int64_t np = in.Cells.numCellPoints(static_cast<size_t>(id));
    if (mtree::cellEvaluable(type, np))
    {
      double pts[3 * mtree::CellSet::kMaxLocalPoints];
      GatherPoints(in.Cells, static_cast<size_t>(id), np, pts);
      const mtree::PointInCell v = mtree::evaluateLinearCell(type, pts, x, pcoords, weights);
      if (v == mtree::PointInCell::kOutside)
      {
        return false;
      }
      FillCell(ds, in, id, cell, pts);
      return v == mtree::PointInCell::kInside ||
        cell->EvaluatePosition(x, closest, subId, pcoords, dist2, weights) == 1;
    }
  }
  else if (type == mtree::kTetra && !in.Cells.tetraMayContain(static_cast<size_t>(id), mtree::Vec3(x), 0.01))
  {
    return false; // VTK accepts barycentrics within 1e-3: outside 1e-2 it surely says no
  }
  FillCell(ds, in, id, cell);
  return cell->EvaluatePosition(x, closest, subId, pcoords, dist2, weights) == 1;
}

// The leaf's quantized boxes (6 bytes per reference: xlo xhi ylo yhi zlo zhi) against a
// quantized range [qmin, qmax] per axis: a box passes when lo <= qmax and hi >= qmin on every
// axis. FindCell asks with qmax = floor(q), qmin = ceil(q) (the box holds q); the ray queries
// with the bounds of the segment's part in the leaf.
class ByteBoxTest
{
public:
  // n: how many boxes will be tested; the eight-at-a-time path is set up only when it runs.
  ByteBoxTest(const uint8_t qmax[3], const uint8_t qmin[3], uint32_t n)
  {
    for (int a = 0; a < 3; ++a)
    {
      this->Max[a] = qmax[a];
      this->Min[a] = qmin[a];
    }
#if defined(__SSE2__)
    this->Simd = n >= 8;
    if (!this->Simd)
    {
      // Never read on this path; set so the compiler need not prove it (-Wmaybe-uninitialized).
      for (int v = 0; v < 3; ++v)
      {
        this->Thr[v] = this->Flip[v] = _mm_setzero_si128();
      }
      return;
    }
    // Eight boxes are 48 bytes, three 16-byte loads. A byte at offset p is field p % 6 of box
    // p / 6: a lower bound (even field) passes when it is <= qmax, an upper bound (odd) when it
    // is >= qmin, i.e. when its complement is <= 255 - qmin. So the upper bounds are
    // complemented (xor) and every byte compared with one threshold: max(y, T) == T.
    alignas(16) static const uint8_t kFlip[48] = { 0, 0xff, 0, 0xff, 0, 0xff, 0, 0xff, 0, 0xff, 0,
      0xff, 0, 0xff, 0, 0xff, 0, 0xff, 0, 0xff, 0, 0xff, 0, 0xff, 0, 0xff, 0, 0xff, 0, 0xff, 0, 0xff,
      0, 0xff, 0, 0xff, 0, 0xff, 0, 0xff, 0, 0xff, 0, 0xff, 0, 0xff, 0, 0xff };
    // The thresholds repeat the 6-byte pattern; the 8-byte words of the 48 start at bytes 0, 8,
    // ... 40, i.e. at pattern offsets 0, 2, 4, 0, 2, 4. They are formed in registers: written
    // to memory byte by byte and read back as vectors, they stalled on store forwarding.
    const uint64_t p = uint64_t{ qmax[0] } | uint64_t{ static_cast<uint8_t>(255 - qmin[0]) } << 8 |
      uint64_t{ qmax[1] } << 16 | uint64_t{ static_cast<uint8_t>(255 - qmin[1]) } << 24 |
      uint64_t{ qmax[2] } << 32 | uint64_t{ static_cast<uint8_t>(255 - qmin[2]) } << 40;
    const long long w0 = static_cast<long long>(p | p << 48);
    const long long w2 = static_cast<long long>(p >> 16 | p << 32);
    const long long w4 = static_cast<long long>(p >> 32 | p << 16);
    this->Thr[0] = _mm_set_epi64x(w2, w0);
    this->Thr[1] = _mm_set_epi64x(w0, w4);
    this->Thr[2] = _mm_set_epi64x(w4, w2);
    for (int v = 0; v < 3; ++v)
    {
      this->Flip[v] = _mm_load_si128(reinterpret_cast<const __m128i*>(kFlip + 16 * v));
    }
#endif
  }

  // The k in [k, stop) whose box passes, ascending, into out; their number.
  int gather(const uint8_t* boxes, uint32_t k, uint32_t stop, uint32_t* out) const
  {
    int n = 0;
#if defined(__SSE2__)
    for (; this->Simd && k + 8 <= stop; k += 8)
    {
      const uint8_t* qb = boxes + 6 * static_cast<size_t>(k);
      uint64_t m = 0;
      for (int v = 0; v < 3; ++v)
      {
        const __m128i y =
          _mm_xor_si128(_mm_loadu_si128(reinterpret_cast<const __m128i*>(qb + 16 * v)), this->Flip[v]);
        const __m128i ok = _mm_cmpeq_epi8(_mm_max_epu8(y, this->Thr[v]), this->Thr[v]);
        m |= static_cast<uint64_t>(static_cast<uint32_t>(_mm_movemask_epi8(ok))) << (16 * v);
      }
      for (int i = 0; i < 8; ++i)
      {
        out[n] = k + i;
        n += ((m >> (6 * i)) & 63) == 63 ? 1 : 0;
      }
    }
#endif
    for (; k < stop; ++k)
    {
      const uint8_t* qb = boxes + 6 * static_cast<size_t>(k);
      const bool pass = (qb[0] <= this->Max[0]) & (qb[1] >= this->Min[0]) & (qb[2] <= this->Max[1]) &
        (qb[3] >= this->Min[1]) & (qb[4] <= this->Max[2]) & (qb[5] >= this->Min[2]);
      out[n] = k;
      n += pass ? 1 : 0;
    }
    return n;
  }

private:
  uint8_t Max[3], Min[3];
#if defined(__SSE2__)
  bool Simd = false;
  __m128i Flip[3], Thr[3];
#endif
};

// Query statistics (GetQueryStatistic): compiled in with -DMATRIXTREE_QUERY_STATS=ON only.
enum QueryStat
{
  kFcQueries,
  kFcLeafScans,
  kFcReferences,
  kFcBoxPasses,
  kFcEvaluations,
  kFcFound,
  kRayQueries,
  kRaySteps,
  kRayNodeVisits,
  kRayLeaves,
  kRayReferences,
  kRayCandidates,
  kRayCellTests,
  kRayMailboxRepeats,
  kRayProvedMisses,
  kRayCertainHits,
  kRayVtkCalls,
  kRayHits,
  kNumQueryStats
};
const char* const kQueryStatNames[kNumQueryStats] = { "findcell_queries", "findcell_leaf_scans",
  "findcell_references", "findcell_box_passes", "findcell_evaluations", "findcell_found", "ray_queries",
  "ray_steps", "ray_node_visits", "ray_leaves", "ray_references", "ray_candidates", "ray_cell_tests",
  "ray_mailbox_repeats", "ray_proved_misses", "ray_certain_hits", "ray_vtk_calls", "ray_hits" };
#if defined(MATRIXTREE_QUERY_STATS) && MATRIXTREE_QUERY_STATS
constexpr bool kQueryStats = true;
std::atomic<uint64_t> gQueryStats[kNumQueryStats];
inline void CountQuery(QueryStat s, uint64_t n = 1)
{
  gQueryStats[s].fetch_add(n, std::memory_order_relaxed);
}
#else
constexpr bool kQueryStats = false;
inline void CountQuery(QueryStat, uint64_t = 1) {}
#endif

// vtkTetra::EvaluatePosition accepts barycentric coordinates within this of [0, 1].
constexpr double kTetraTolerance = 1e-3;

// The point-location loop over the candidates [k, end) of leaf n, the leaf that
// MatrixTree::leafHolding gives for x (with the range it read): FindCell runs it from the leaf's
// first candidate, the OpenCL backend from the candidate where the device stopped.
// Asks for the cache lines of [begin, end), in 64-byte steps from begin: a leaf's references
// (ids, quantized boxes) are read at random, so their lines are requested together and their
// misses overlap.
inline void PrefetchLines(const void* begin, const void* end)
{
  for (const char *b = static_cast<const char*>(begin), *e = static_cast<const char*>(end); b < e; b += 64)
  {
    __builtin_prefetch(b);
  }
}

vtkIdType ScanCandidates(vtkDataSet* ds, const vtkMatrixTreeLocatorInternals& in, const double x[3],
  const mtree::NodeRef& n, uint32_t k, vtkGenericCell* cell, double pcoords[3], double* weights,
  bool engineEval)
{
  const MtLeafRange r = n.range; // leafHolding's read of the leaf
  const uint32_t* ids = in.Tree.primitiveIndices().data();
  const uint8_t* boxes = in.LeafBoxes.data();
  // The leaf's boxes and its cell ids are two independent reads (usually cache misses): start
  // both now, so that they overlap each other and the set-up below instead of coming one after
  // the other (boxes, then the ids of the boxes that pass).
  __builtin_prefetch(boxes + 6 * static_cast<size_t>(k));
  __builtin_prefetch(ids + k);
  // The point in the leaf's quantized frame (the same arithmetic as the boxes': monotone, so
  // a point inside the padded bounds is never rejected). Clamped into the leaf: round-off of
  // the leaf search may put a point a hair outside it, where only clipped boxes reach.
  const mtree::Box lb = in.Tree.nodeBox(n.level, n.c);
  double q[3];
  for (int a = 0; a < 3; ++a)
  {
    q[a] = std::min(255.0, std::max(0.0, (x[a] - lb.lo[a]) * mtree::detail::leafBoxScale(lb.lo[a], lb.hi[a])));
  }
  // q inside [lo, hi] (integers) is floor(q) >= lo and ceil(q) <= hi: the test in bytes.
  uint8_t qf[3], qc[3];
  for (int a = 0; a < 3; ++a)
  {
    qf[a] = static_cast<uint8_t>(static_cast<int>(q[a]));
    qc[a] = static_cast<uint8_t>(static_cast<int>(q[a]) + (static_cast<int>(q[a]) < q[a] ? 1 : 0));
  }
  const ByteBoxTest boxTest(qf, qc, r.end - k);
  CountQuery(kFcLeafScans);
  CountQuery(kFcReferences, r.end - k);
  // The candidates whose box holds the point are gathered first (in the leaf's order: ascending
  // ids, so the first that contains the point is still the answer), a whole leaf of up to kChunk
  // references at once, then the point ids of up to kIdsAhead of them are prefetched, then the
  // points of up to kAhead: each level of these random reads overlaps across the candidates,
  // where one candidate at a time they stall one after another (the containing cell is as often
  // the last candidate as the first).
  constexpr uint32_t kChunk = 128;
  constexpr int kAhead = 16, kIdsAhead = 24;
  uint32_t cand[kChunk];
  while (k < r.end)
  {
    const uint32_t stop = std::min<uint32_t>(r.end, k + kChunk);
    // Every line of the chunk's boxes and ids (the first of each is on its way already).
    PrefetchLines(boxes + 6 * static_cast<size_t>(k) + 64, boxes + 6 * static_cast<size_t>(stop));
    PrefetchLines(reinterpret_cast<const char*>(ids + k) + 64, ids + stop);
    const int nc = boxTest.gather(boxes, k, stop, cand);
    CountQuery(kFcBoxPasses, static_cast<uint64_t>(nc));
    for (int j = 0; j < nc; ++j)
    {
      cand[j] = ids[cand[j]];
    }
    k = stop;
    // With the engine's evaluation every candidate's test would wait on its reads; with VTK's
    // only tetrahedra (judged by the first candidate) benefit: the cheap pre-test waits, while a
    // larger cell's Newton steps in VTK hide the loads, and there the hints measured slower.
    const bool ahead = nc > 1 && (engineEval || in.Cells.type(cand[0]) == mtree::kTetra);
    for (int j = 0, e = ahead ? std::min(nc, kIdsAhead) : 0; j < e; ++j)
    {
      in.Cells.prefetchPointIds(cand[j]);
    }
    for (int j = 0, e = ahead ? std::min(nc, kAhead) : 0; j < e; ++j)
    {
      in.Cells.prefetchPoints(cand[j]);
    }
    for (int j = 0; j < nc; ++j)
    {
      if (ahead && j + kIdsAhead < nc)
      {
        in.Cells.prefetchPointIds(cand[j + kIdsAhead]);
      }
      if (ahead && j + kAhead < nc)
      {
        in.Cells.prefetchPoints(cand[j + kAhead]);
      }
      CountQuery(kFcEvaluations);
      if (CellContains(ds, in, x, cand[j], cell, pcoords, weights, engineEval))
      {
        CountQuery(kFcFound);
        return cand[j];
      }
    }
  }
  return -1;
}

// The cell types of a polygon-only vtkPolyData's nc cells from its offsets: 3 points a
// triangle, 4 a quad; other sizes are asked of the data set.
template <class I>
void PolygonTypes(vtkDataSet* ds, const I* offsets, vtkIdType nc, std::vector<uint8_t>& types)
{
  types.resize(static_cast<size_t>(nc));
  for (vtkIdType c = 0; c < nc; ++c)
  {
    const auto n = offsets[c + 1] - offsets[c];
    types[c] = static_cast<uint8_t>(n == 3 ? VTK_TRIANGLE : (n == 4 ? VTK_QUAD : ds->GetCellType(c)));
  }
}

// How this VTK's vtkQuad::IntersectWithLine splits a quad (segment_filter.h's QuadSplit): with it
// known, the ray queries decide hexahedra, wedges and pyramids with slightly warped faces
// without VTK too (tests/cpp/test_segment_filter checks it against VTK).
constexpr mtree::QuadSplit kVtkQuadSplit = mtree::quadSplitOfVtk(VTK_MAJOR_VERSION, VTK_MINOR_VERSION);

// Whether this VTK's face tests are the ones mtree/vtk91/face_hit.h recomputes (9.1's).
constexpr bool kVtkFaceTestRecomputed =
  VTK_VERSION_NUMBER >= VTK_VERSION_CHECK(9, 1, 0) && VTK_VERSION_NUMBER < VTK_VERSION_CHECK(9, 2, 0);

// vtkHexahedron, vtkWedge and vtkTetra::IntersectWithLine (VTK 9.1) for a segment whose hit is
// certain to lie on face `face` (convexFirstHitIfCertain's or tetraCertainHit's face: every other
// face of the cell is far from the line, so VTK's loop over the faces finds only this one, or
// this one first): VTK's vtkQuad or vtkTriangle IntersectWithLine on that face, its points
// set as the cell sets them (the quad keeps the point ids vtkQuad's constructor gives it, as the
// cells' own quads do: they only break ties between equal diagonals), recomputed without VTK by
// mtree::vtk91 (the same bits; test_segment_filter's Vtk91FaceTestIsVtks) and asked of VTK's
// own cell only where that leaves the answer to VTK (a point at round-off from an edge or the
// quad's diagonal, a degenerate face, a line in its plane), and the face's pcoords
// (r, s, and the triangle's third) mapped as the cell maps them in 9.1 (checked against the
// library by tests/python/test_locator.py::test_ray_hit_values_are_vtks_own):
//   hexahedron  face 0 (0, r, 0), 1 (1, r, 0), 2 (r, 0, s), 3 (r, 1, s), 4 (r, s, 0), 5 (r, s, 1);
//   wedge       face 0 (r, s, 0), 1 (r, s, 1), 2 (s, 0, r), 3 (1 - s, s, r), 4 (0, s, r);
//   tetrahedron face 0 (r, s, 0), 1 (0, s, 0), 2 (r, 0, 0), 3 (r, s, third).
// One face test instead of six (five, four). False if the face reports no hit (the caller asks
// the cell), the type has no mapping here, or the VTK is not 9.1 (whose mappings these are).
bool CertainFaceHit(const mtree::CellSet& cells, vtkIdType id, int face, const double p1[3], const double p2[3],
  double tol, double& t, double x[3], double pcoords[3], int& subId)
{
  const uint8_t type = cells.type(static_cast<size_t>(id));
  const bool mapped = VTK_VERSION_NUMBER >= VTK_VERSION_CHECK(9, 1, 0) &&
    VTK_VERSION_NUMBER < VTK_VERSION_CHECK(9, 2, 0) &&
    (type == mtree::kHexahedron || type == mtree::kWedge || type == mtree::kTetra);
  if (!mapped)
  {
    return false;
  }
  const mtree::CellTopology* topo = mtree::cellTopology(type);
  const int n = topo->faceSize[face];
  const auto pid = cells.cellPointIds(static_cast<size_t>(id));
  double q[4][3];
  for (int k = 0; k < n; ++k)
  {
    const mtree::Vec3 p = cells.point(pid[topo->face[face][k]]);
    q[k][0] = p.x, q[k][1] = p.y, q[k][2] = p.z;
  }
  double pc[3];
  // VTK's face test recomputed (mtree/vtk91/face_hit.h: the same bits, without the vtkCell and its
  // virtual calls); VTK's own where that leaves the answer to it.
  mtree::vtk91::FaceHit fast = mtree::vtk91::FaceHit::kAskVtk;
  if (kVtkFaceTestRecomputed && tol == 0.0)
  {
    mtree::vtk91::LineHit h;
    fast = n == 4 ? mtree::vtk91::quadLineHit(q, p1, p2, h) : mtree::vtk91::triangleLineHit(q[0], q[1], q[2], p1, p2, h);
    if (fast == mtree::vtk91::FaceHit::kMiss)
    {
      return false;
    }
    if (fast == mtree::vtk91::FaceHit::kHit)
    {
      t = h.t;
      std::copy(h.x, h.x + 3, x);
      std::copy(h.pcoords, h.pcoords + 3, pc);
      subId = 0;
    }
  }
  if (fast == mtree::vtk91::FaceHit::kAskVtk)
  {
    static thread_local vtkSmartPointer<vtkQuad> quad = vtkSmartPointer<vtkQuad>::New();
    static thread_local vtkSmartPointer<vtkTriangle> triangle = vtkSmartPointer<vtkTriangle>::New();
    vtkCell* f = n == 4 ? static_cast<vtkCell*>(quad) : static_cast<vtkCell*>(triangle);
    for (int k = 0; k < n; ++k)
    {
      f->GetPoints()->SetPoint(k, q[k]);
    }
    if (!f->IntersectWithLine(p1, p2, tol, t, x, pc, subId))
    {
      return false;
    }
  }
  const double r = pc[0], s = pc[1];
  double out[3];
  if (type == mtree::kHexahedron)
  {
    switch (face)
    {
      case 0: out[0] = 0.0, out[1] = r, out[2] = 0.0; break;
      case 1: out[0] = 1.0, out[1] = r, out[2] = 0.0; break;
      case 2: out[0] = r, out[1] = 0.0, out[2] = s; break;
      case 3: out[0] = r, out[1] = 1.0, out[2] = s; break;
      case 4: out[0] = r, out[1] = s, out[2] = 0.0; break;
      default: out[0] = r, out[1] = s, out[2] = 1.0; break;
    }
  }
  else if (type == mtree::kTetra)
  {
    switch (face)
    {
      case 0: out[0] = r, out[1] = s, out[2] = 0.0; break;
      case 1: out[0] = 0.0, out[1] = s, out[2] = 0.0; break;
      case 2: out[0] = r, out[1] = 0.0, out[2] = 0.0; break;
      default: out[0] = r, out[1] = s, out[2] = pc[2]; break;
    }
  }
  else
  {
    switch (face)
    {
      case 0: out[0] = r, out[1] = s, out[2] = 0.0; break;
      case 1: out[0] = r, out[1] = s, out[2] = 1.0; break;
      case 2: out[0] = s, out[1] = 0.0, out[2] = r; break;
      case 3: out[0] = 1.0 - s, out[1] = s, out[2] = r; break;
      default: out[0] = 0.0, out[1] = s, out[2] = r; break;
    }
  }
  std::copy(out, out + 3, pcoords);
  return true;
}

// Cell `id`'s vtkTriangle::IntersectWithLine at tol 0, recomputed in VTK 9.1's arithmetic
// (mtree/vtk91/face_hit.h: the same verdict and bits) where the cell is a triangle and this is
// VTK 9.1; kAskVtk otherwise, and where the recomputation leaves the answer to VTK.
mtree::vtk91::FaceHit RecomputedTriangleHit(const mtree::CellSet& cells, vtkIdType id, const double p1[3],
  const double p2[3], mtree::vtk91::LineHit& h)
{
  const size_t c = static_cast<size_t>(id);
  if (!kVtkFaceTestRecomputed || cells.type(c) != mtree::kTriangle || cells.numCellPoints(c) != 3)
  {
    return mtree::vtk91::FaceHit::kAskVtk;
  }
  double q[3][3];
  GatherPoints(cells, c, 3, &q[0][0]);
  return mtree::vtk91::triangleLineHit(q[0], q[1], q[2], p1, p2, h);
}

// The ray queries' first test of a leaf's candidates (tol = 0): the segment o + t d, t in
// [0, bound], against each candidate's quantized box in this leaf (LeafBoxes, read in order),
// in double precision and grown by a margin (below). The quantized box contains the part of
// the cell's bounds (padded by 1e-3 of their extent) inside the leaf, so a VTK hit of the
// cell at a point of this leaf lies in it. A candidate that fails is only not tested in this
// leaf (it is not put in the mailbox): a hit elsewhere lies in another leaf that references
// the cell (a cell is referenced in every leaf it overlaps), which the walk visits before it
// can stop past that t. The margin (1e-7 of the leaf plus round-off in the coordinates'
// magnitude) keeps a hit that round-off puts on the other side of a leaf face in both leaves.
// With tol > 0 a hit may lie up to tol outside the cell, in a leaf that does not reference it:
// those queries test every candidate as before.
class LeafSegmentFilter
{
public:
  struct Candidate
  {
    double t; // where the segment enters the candidate's (grown) box, >= 0
    uint32_t k; // index into the leaf's candidates
  };

  LeafSegmentFilter(const vtkMatrixTreeLocatorInternals& in, mtree::Vec3 o, mtree::Vec3 d, double tol)
    : In(in), O(o), D(d)
  {
    const auto& prims = in.Tree.primitiveIndices();
    this->Enabled = tol == 0.0 && !in.Tree.empty() && mtree::isFinite(o) && mtree::isFinite(d) &&
      !(d.x == 0 && d.y == 0 && d.z == 0) && in.LeafBoxes.size() == 6 * prims.size();
    this->Prims = prims.data();
    this->NumPrims = prims.size();
    this->H = in.Tree.height();
    const mtree::Vec3 e = o + d;
    this->Mag = std::max({ std::fabs(o.x), std::fabs(o.y), std::fabs(o.z), std::fabs(e.x), std::fabs(e.y),
      std::fabs(e.z) });
    // Per ray, not per leaf: the direction's reciprocals (0 on an axis the segment does not
    // move along).
    for (int a = 0; a < 3; ++a)
    {
      this->Inv[a] = d[a] != 0 ? 1.0 / d[a] : 0.0;
    }
  }

  // The candidates of the leaf at bottom-level coordinates `leaf` (as the walk gives them),
  // whose references start at `ids`, that the segment may hit in this leaf at t <= bound, in
  // `out` sorted by entry t; -1 where the filter cannot decide (then every candidate must be
  // tested).
  int candidates(const uint32_t* ids, uint32_t count, const int leaf[3], double bound, Candidate* out) const
  {
    if (!this->Enabled || count == 0 || ids < this->Prims || ids + count > this->Prims + this->NumPrims)
    {
      return -1;
    }
    const mtree::MatrixTree& tree = this->In.Tree;
    const uint32_t begin = static_cast<uint32_t>(ids - this->Prims);
    const int L[3] = { leaf[0], leaf[1], leaf[2] };
    const mtree::Box lb = tree.nodeBox(this->H, L);
    constexpr double eps = std::numeric_limits<double>::epsilon();
    const double mag = std::max({ this->Mag, std::fabs(lb.lo.x), std::fabs(lb.lo.y), std::fabs(lb.lo.z),
      std::fabs(lb.hi.x), std::fabs(lb.hi.y), std::fabs(lb.hi.z) });
    // Per axis: t of quantized coordinate q is A + q B (moving axes), within +-M; a static
    // axis needs its coordinate's q within [qlo, qhi] grown by the margin. One division per
    // axis (the quantum's reciprocal): the products that replace quotients differ from them by
    // an ulp or two, a relative 1e-15 against margins of 1e-7 of the leaf and 1e-3 of a quantum.
    double A[3], B[3], M[3], SLo[3], SHi[3], Margin[3], PerUnit[3];
    bool moving[3];
    bool anyStatic = false;
    for (int a = 0; a < 3; ++a)
    {
      const double w = lb.hi[a] - lb.lo[a];
      if (!(w > 0) || !std::isfinite(w))
      {
        return -1;
      }
      const double unit = w * (1.0 / 255.0);
      PerUnit[a] = 255.0 / w;
      const double margin = 1e-7 * w + 16 * eps * mag; // world units
      Margin[a] = margin;
      moving[a] = this->D[a] != 0;
      if (moving[a])
      {
        const double inv = this->Inv[a];
        A[a] = (lb.lo[a] - this->O[a]) * inv;
        B[a] = unit * inv;
        M[a] = margin * std::fabs(inv) + 8 * eps * (std::fabs(A[a]) + 255 * std::fabs(B[a]));
        if (!std::isfinite(A[a]) || !std::isfinite(B[a]) || !std::isfinite(M[a]))
        {
          return -1;
        }
      }
      else
      {
        anyStatic = true;
        const double q = (this->O[a] - lb.lo[a]) * PerUnit[a], mq = margin * PerUnit[a] + 1e-9;
        SLo[a] = q - mq; // passes when qhi >= SLo and qlo <= SHi
        SHi[a] = q + mq;
      }
    }
    const uint8_t* boxes = this->In.LeafBoxes.data() + 6 * static_cast<size_t>(begin);
    // First the boxes against the bounds of the segment's part in the leaf (a byte test, eight
    // boxes at a time): t in [0, bound] clipped to the leaf grown by the margin (every grown
    // box lies in it), then that part's quantized range per axis, grown by the margin (and
    // 1e-3 of a quantum for round-off), rounded outwards. NaN gives the full range.
    double ta = 0.0, tb = bound;
    for (int a = 0; a < 3; ++a)
    {
      if (moving[a])
      {
        const double t1 = A[a], t2 = A[a] + 255 * B[a];
        ta = std::max(ta, std::min(t1, t2) - M[a]);
        tb = std::min(tb, std::max(t1, t2) + M[a]);
      }
      else if (SHi[a] < 0 || SLo[a] > 255)
      {
        return 0;
      }
    }
    if (!(ta <= tb))
    {
      return 0;
    }
    uint8_t qmin[3], qmax[3];
    for (int a = 0; a < 3; ++a)
    {
      const double q0 = (this->O[a] + this->D[a] * ta - lb.lo[a]) * PerUnit[a];
      const double q1 = (this->O[a] + this->D[a] * tb - lb.lo[a]) * PerUnit[a];
      const double mq = Margin[a] * PerUnit[a] + 1e-3;
      const double lo = std::min(q0, q1) - mq, hi = std::max(q0, q1) + mq;
      // floor(lo) and ceil(hi), clamped to [0, 255], by truncation of the clamped values (floor
      // for non-negatives; std::floor and std::ceil are libm calls in a build without SSE4.1),
      // without branches on where the segment lies (coin flips). A NaN gives the full range:
      // max(0, NaN) is 0 and min(255, NaN) is 255 in this argument order.
      const double l = std::min(255.0, std::max(0.0, lo)), h = std::max(0.0, std::min(255.0, hi));
      const int th = static_cast<int>(h);
      qmin[a] = static_cast<uint8_t>(static_cast<int>(l));
      qmax[a] = static_cast<uint8_t>(th + (th < h ? 1 : 0));
    }
    const ByteBoxTest boxTest(qmax, qmin, count);
    constexpr uint32_t kChunk = 64;
    uint32_t idx[kChunk];
    int n = 0;
    for (uint32_t k0 = 0; k0 < count; k0 += kChunk)
    {
      const int ng = boxTest.gather(boxes, k0, std::min(count, k0 + kChunk), idx);
      // The first survivors' point ids are asked for now, while their entry t are computed and
      // sorted: the first test waits on them, then on the points (in-process A/B, old/new:
      // 1.005-1.028 on the surfaces' rays, 0.996-1.051 on the volume grids').
      for (int g = 0, e = std::min(ng, 8); g < e; ++g)
      {
        this->In.Cells.prefetchPointIds(ids[idx[g]]);
      }
      for (int g = 0; g < ng; ++g)
      {
      const uint32_t k = idx[g];
      const uint8_t* qb = boxes + 6 * static_cast<size_t>(k);
      double te = 0.0, tx = bound;
      for (int a = 0; a < 3; ++a)
      {
        if (moving[a])
        {
          const double t1 = A[a] + qb[2 * a] * B[a], t2 = A[a] + qb[2 * a + 1] * B[a];
          te = std::max(te, std::min(t1, t2) - M[a]);
          tx = std::min(tx, std::max(t1, t2) + M[a]);
        }
        else if (anyStatic && (qb[2 * a + 1] < SLo[a] || qb[2 * a] > SHi[a]))
        {
          tx = -1.0;
        }
      }
      if (te <= tx)
      {
        out[n].t = te;
        out[n].k = k;
        ++n;
      }
      }
    }
    // Insertion sort by entry t (a handful of survivors).
    for (int i = 1; i < n; ++i)
    {
      const Candidate c = out[i];
      int j = i - 1;
      while (j >= 0 && out[j].t > c.t)
      {
        out[j + 1] = out[j];
        --j;
      }
      out[j + 1] = c;
    }
    return n;
  }

private:
  const vtkMatrixTreeLocatorInternals& In;
  mtree::Vec3 O, D;
  const uint32_t* Prims = nullptr;
  size_t NumPrims = 0;
  int H = 0;
  double Mag = 0;
  double Inv[3] = { 0, 0, 0 };
  bool Enabled = false;
};

}

//------------------------------------------------------------------------------
vtkMatrixTreeLocator::vtkMatrixTreeLocator()
  : Internals(new vtkMatrixTreeLocatorInternals)
{
  // Off: 24 bytes per cell not held; only the queries with a tolerance and the proximity
  // queries read cell bounds (see the class description).
  this->CacheCellBounds = 0;
}

vtkMatrixTreeLocator::~vtkMatrixTreeLocator()
{
  this->SetOpenCLDevice(nullptr);
  delete this->Internals;
}

const char* vtkMatrixTreeLocator::GetOpenCLDeviceName()
{
  return this->Internals->CLDeviceName.c_str();
}

const char* vtkMatrixTreeLocator::GetLastFindCellsPhases()
{
  return this->Internals->FindPhases.c_str();
}

//------------------------------------------------------------------------------
bool vtkMatrixTreeLocator::NeedsBuild()
{
  if (!this->Internals->Valid)
  {
    return true;
  }
  if (this->UseExistingSearchStructure)
  {
    return false;
  }
  return this->BuildTime < this->GetMTime() ||
    (this->DataSet && this->BuildTime < this->DataSet->GetMTime());
}

bool vtkMatrixTreeLocator::EnsureBuilt()
{
  // Queries build lazily and rebuild when the data set object or a setting changed, but do not
  // walk the data set's modification times (its arrays') on every query: as with VTK's own
  // locators, call BuildLocator() after changing the data set in place.
  if (this->Internals->Valid && this->Internals->BuiltOn == this->DataSet &&
    (this->UseExistingSearchStructure || this->BuildTime >= this->MTime))
  {
    return true;
  }
  if (!this->DataSet)
  {
    vtkErrorMacro("No data set: call SetDataSet() first.");
    return false;
  }
  if (this->NeedsBuild() || this->Internals->BuiltOn != this->DataSet)
  {
    this->ForceBuildLocator();
  }
  return this->Internals->Valid;
}

void vtkMatrixTreeLocator::BuildLocator()
{
  if (this->NeedsBuild())
  {
    this->ForceBuildLocator();
  }
}

//------------------------------------------------------------------------------
void vtkMatrixTreeLocator::ForceBuildLocator()
{
  vtkMatrixTreeLocatorInternals& in = *this->Internals;
  in.Valid = false;
  in.CLUploaded = false;
  in.ShapeMemo.reset();
  using Clock = std::chrono::steady_clock;
  const Clock::time_point tStart = Clock::now();
  auto msSince = [](Clock::time_point t) {
    return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
  };
  vtkDataSet* ds = this->DataSet;
  if (!ds)
  {
    vtkErrorMacro("BuildLocator: no data set; call SetDataSet() first.");
    return;
  }
  const int b = this->BlockSize;
  if (b < 1 || b > 32 || (b & (b - 1)))
  {
    vtkErrorMacro("BuildLocator: BlockSize must be a power of two in [1, 32], got " << b << ".");
    return;
  }
  const vtkIdType np = ds->GetNumberOfPoints();
  const vtkIdType nc = ds->GetNumberOfCells();
  // Float and double point arrays are read in place (as VTK's own locators read the data set),
  // not copied: no copy to make per build and none to hold. Other arrays (and data sets without
  // a point array) are copied as doubles.
  vtkPointSet* ps = vtkPointSet::SafeDownCast(ds);
  vtkDataArray* pdata = ps && ps->GetPoints() ? ps->GetPoints()->GetData() : nullptr;
  vtkFloatArray* viewFloats = nullptr;
  vtkDoubleArray* viewDoubles = nullptr;
  if (pdata && pdata->GetNumberOfComponents() == 3 && pdata->GetNumberOfTuples() == np)
  {
    viewFloats = vtkFloatArray::FastDownCast(pdata);
    viewDoubles = vtkDoubleArray::FastDownCast(pdata);
  }
  std::vector<double> pts;
  if (!viewFloats && !viewDoubles)
  {
    pts.resize(static_cast<size_t>(np) * 3);
    for (vtkIdType i = 0; i < np; ++i)
    {
      ds->GetPoint(i, &pts[3 * i]);
    }
  }
  if (np >= 0xffffffffLL)
  {
    vtkErrorMacro("BuildLocator: more than 2^32 - 1 points are not supported.");
    return;
  }
  // Threads of the whole build, the copies below included: as set, or (0) one per 1024 cells up
  // to all. On the quiet 2-core machine two threads built faster than one from 1000 cells up
  // (brick_tets 22.4 -> 15.9 ms, disk_out_ref 2.9 -> 1.7 ms, a 1000-tet grid 0.60 -> 0.39-0.53
  // ms; bench/locator_phases.py --threads 1 and 2); the old rule (one per 32768 cells) was
  // measured on a loaded machine, where a second thread mostly waits.
  const int buildThreads = this->NumberOfThreads > 0
    ? this->NumberOfThreads
    : static_cast<int>(std::min<vtkIdType>(omp_get_max_threads(), std::max<vtkIdType>(1, nc / 1024)));
  std::vector<uint32_t> offsets, conn; // the copy paths' arrays
  std::vector<uint8_t> types;
  vtkUnstructuredGrid* ug = vtkUnstructuredGrid::SafeDownCast(ds);
  vtkCellArray* ca = ug && ug->GetCellTypesArray() ? ug->GetCells() : nullptr;
  // Polydata with polygons only (the surface meshes): cell c is polygon c, so its cell array is
  // copied the same way; the types follow from the sizes below.
  vtkPolyData* pd = ug ? nullptr : vtkPolyData::SafeDownCast(ds);
  const bool polysOnly = pd && pd->GetPolys() && pd->GetNumberOfVerts() == 0 && pd->GetNumberOfLines() == 0 &&
    pd->GetNumberOfStrips() == 0;
  if (!ca && polysOnly)
  {
    ca = pd->GetPolys();
  }
  // With the points read in place, the cell arrays may be too (offsets and connectivity as VTK
  // stores them, 32- or 64-bit; an unstructured grid's types): nothing copied per build, no
  // bytes held (see CellStorage for the choice). Polygon meshes get their types from the sizes,
  // as below.
  mtree::CellArrays cellView;
  vtkDataArray* viewOffsets = nullptr;
  vtkDataArray* viewConn = nullptr;
  const bool inPlace = this->CellStorage == CELLS_IN_PLACE ||
    (this->CellStorage == CELLS_AUTOMATIC && ca &&
      (!ca->IsStorage64Bit() || ca->GetNumberOfConnectivityIds() > 5 * ca->GetNumberOfCells()));
  const bool viewCells = inPlace && ca && nc > 0 && ca->GetNumberOfCells() == nc && (viewFloats || viewDoubles);
  if (viewCells)
  {
    auto view = [&](auto* off, auto* cn) {
      viewOffsets = off;
      viewConn = cn;
      cellView.offsets = off->GetPointer(0);
      cellView.connectivity = cn->GetPointer(0);
      cellView.connectivitySize = static_cast<size_t>(cn->GetNumberOfValues());
      cellView.indexBytes = static_cast<int>(sizeof(*off->GetPointer(0)));
      cellView.numCells = static_cast<size_t>(nc);
      if (ug)
      {
        cellView.types = ug->GetCellTypesArray()->GetPointer(0);
        return;
      }
      PolygonTypes(ds, off->GetPointer(0), nc, cellView.typeCopy);
    };
    if (ca->IsStorage64Bit())
    {
      view(ca->GetOffsetsArray64(), ca->GetConnectivityArray64());
    }
    else
    {
      view(ca->GetOffsetsArray32(), ca->GetConnectivityArray32());
    }
  }
  else if (ca && ca->GetNumberOfCells() == nc)
  {
    offsets.assign(static_cast<size_t>(nc) + 1, 0);
    types.resize(static_cast<size_t>(nc));
    // Unstructured grids and polygon meshes: copy the cell arrays directly (the generic
    // per-cell loop below costs more than the whole tree build).
    if (ug)
    {
      const unsigned char* t = ug->GetCellTypesArray()->GetPointer(0);
      std::copy(t, t + nc, types.begin());
    }
    bool fits = true;
    auto copyArrays = [&](auto* off, auto* cn) {
      const auto* o = off->GetPointer(0);
      const auto* cc = cn->GetPointer(0);
      const vtkIdType m = cn->GetNumberOfValues();
      if (m >= 0xffffffffLL)
      {
        fits = false;
        return;
      }
      conn.resize(static_cast<size_t>(m));
      // Negative or too large values are caught by the CellSet's range check (as 2^32 - 1).
#pragma omp parallel for num_threads(buildThreads) schedule(static) if (m > mtree::kSerialBelow)
      for (vtkIdType k = 0; k < m; ++k)
      {
        conn[k] = (cc[k] < 0 || static_cast<long long>(cc[k]) >= np) ? 0xffffffffu : static_cast<uint32_t>(cc[k]);
      }
#pragma omp parallel for num_threads(buildThreads) schedule(static) if (nc > mtree::kSerialBelow)
      for (vtkIdType c = 0; c <= nc; ++c)
      {
        offsets[c] = static_cast<uint32_t>(o[c]);
      }
    };
    if (ca->IsStorage64Bit())
    {
      copyArrays(ca->GetOffsetsArray64(), ca->GetConnectivityArray64());
    }
    else
    {
      copyArrays(ca->GetOffsetsArray32(), ca->GetConnectivityArray32());
    }
    if (!fits)
    {
      vtkErrorMacro("BuildLocator: more than 2^32 - 1 connectivity entries are not supported.");
      return;
    }
    if (!ug)
    {
      PolygonTypes(ds, offsets.data(), nc, types);
    }
  }
  else
  {
    offsets.assign(static_cast<size_t>(nc) + 1, 0);
    types.resize(static_cast<size_t>(nc));
    conn.reserve(static_cast<size_t>(nc) * 4);
    vtkNew<vtkIdList> ids;
    for (vtkIdType c = 0; c < nc; ++c)
    {
      types[c] = static_cast<uint8_t>(ds->GetCellType(c));
      ds->GetCellPoints(c, ids);
      for (vtkIdType k = 0; k < ids->GetNumberOfIds(); ++k)
      {
        conn.push_back(static_cast<uint32_t>(ids->GetId(k)));
      }
      if (conn.size() >= 0xffffffffu)
      {
        vtkErrorMacro("BuildLocator: more than 2^32 - 1 connectivity entries are not supported.");
        return;
      }
      offsets[c + 1] = static_cast<uint32_t>(conn.size());
    }
  }
  const double convertMs = msSince(tStart);
  double progress = 0.2; // a locator is no algorithm: progress goes out as an event
  this->InvokeEvent(vtkCommand::ProgressEvent, &progress);
  mtree::BuildOptions opt;
  opt.kind = this->TreeType == KDTREE ? mtree::TreeKind::RegularKd : mtree::TreeKind::Octree;
  opt.height = this->Height;
  opt.blockEdge = this->BlockSize;
  opt.overlap = this->ExactOverlap ? mtree::OverlapMode::Exact : mtree::OverlapMode::BoundingBox;
  opt.sort = this->BuildSort == RADIX ? mtree::BuildSort::Radix : mtree::BuildSort::Counting;
  opt.threads = buildThreads;
  double convertMs2 = 0;
  try
  {
    in.PointArray = nullptr;
    in.OffsetsArray = nullptr;
    in.ConnectivityArray = nullptr;
    in.TypesArray = nullptr;
    auto viewPoints = [&](auto* array) {
      if (viewCells)
      {
        in.Cells = mtree::CellSet(array->GetPointer(0), static_cast<size_t>(np), std::move(cellView), buildThreads);
        in.OffsetsArray = viewOffsets;
        in.ConnectivityArray = viewConn;
        if (ug)
        {
          in.TypesArray = ug->GetCellTypesArray();
        }
      }
      else
      {
        in.Cells = mtree::CellSet(array->GetPointer(0), static_cast<size_t>(np), std::move(offsets),
          std::move(conn), std::move(types), buildThreads);
      }
      in.PointArray = array;
    };
    if (viewFloats)
    {
      viewPoints(viewFloats);
    }
    else if (viewDoubles)
    {
      viewPoints(viewDoubles);
    }
    else
    {
      in.Cells = mtree::CellSet(
        std::move(pts), std::move(offsets), std::move(conn), std::move(types), buildThreads);
    }
    in.Cells.setAxes(this->FullSeparatingAxes ? mtree::CellAxes::All : mtree::CellAxes::Faces);
    convertMs2 = msSince(tStart) - convertMs;
    const bool surface = (this->LeafScale <= 0 || this->MaxCandidates <= 0) && NoVolumeCells(in.Cells);
    opt.leafScale = this->LeafScale > 0 ? std::max(this->LeafScale, 1e-3) : (surface ? 4.0 : 1.0);
    opt.maxCandidates = this->MaxCandidates > 0 ? std::max(this->MaxCandidates, 1.0) : (surface ? 3.0 : 16.0);
    in.LeafScaleUsed = opt.leafScale;
    in.MaxCandidatesUsed = opt.maxCandidates;
    // The quantized leaf boxes are the builder's per-reference data: written at the scatter
    // (COUNTING) or by a pass over the leaves (RADIX), the same bytes either way.
    mtree::MatrixTreeBuilder<mtree::CellSet>::build<6>(
      in.Cells, opt, in.Tree, &in.Stats, &in.LeafBoxes, mtree::LeafBoxQuantizer());
  }
  catch (const std::exception& e)
  {
    vtkErrorMacro("BuildLocator failed: " << e.what());
    return;
  }
  // The cached cell bounds serve the build (read several times per cell there); unless
  // CacheCellBounds is on, queries compute the few they need from the points: 24 bytes per cell
  // not held.
  const Clock::time_point tRelease = Clock::now();
  if (!this->CacheCellBounds)
  {
    in.Cells.releaseBounds();
  }
  // So are the build's work arrays the tree keeps for a next build (counts and masks per cell,
  // counts and cursors per leaf: as much as the tree itself on surfaces), which GetMemorySize
  // does not count: a rebuild allocates them again.
  in.Tree.releaseBuildScratch();
  const double releaseMs = msSince(tRelease);
  if (HasConvexPolyhedra(in.Cells))
  {
    // calloc: zero pages from the system for a large grid, touched only where rays go.
    in.ShapeMemo.reset(static_cast<uint8_t*>(std::calloc(in.Cells.size(), 1)));
  }
  {
    const mtree::Vec3 m = in.Cells.maxExtent();
    in.MaxCellExtent[0] = m.x;
    in.MaxCellExtent[1] = m.y;
    in.MaxCellExtent[2] = m.z;
  }
  {
    std::ostringstream os;
    os << "convert " << convertMs << "; cellset " << convertMs2;
    for (const auto& ph : in.Stats.phasesMs)
    {
      os << "; " << ph.first << " " << ph.second;
    }
    os << "; release " << releaseMs;
    os << "; total " << msSince(tStart);
    in.Phases = os.str();
  }
  in.BuiltOn = ds;
  in.Valid = true;
  this->BuildTime.Modified();
  progress = 1.0;
  this->InvokeEvent(vtkCommand::ProgressEvent, &progress);
}

void vtkMatrixTreeLocator::FreeSearchStructure()
{
  delete this->Internals;
  this->Internals = new vtkMatrixTreeLocatorInternals;
  this->Internals->Tree.enableStepTable(this->RayStepTable);
}

void vtkMatrixTreeLocator::SetRayStepTable(bool on)
{
  this->RayStepTable = on;
  this->Internals->Tree.enableStepTable(on);
}

//------------------------------------------------------------------------------
bool vtkMatrixTreeLocator::InsideCellBounds(double x[3], vtkIdType cellId)
{
  if (!this->EnsureBuilt() || cellId < 0 || cellId >= static_cast<vtkIdType>(this->Internals->Cells.size()))
  {
    return false;
  }
  return this->Internals->Cells.exactBounds(static_cast<size_t>(cellId)).contains(mtree::Vec3(x));
}

//------------------------------------------------------------------------------
vtkIdType vtkMatrixTreeLocator::FindCell(
  double x[3], double vtkNotUsed(tol2), vtkGenericCell* cell, double pcoords[3], double* weights)
{
  if (!this->EnsureBuilt())
  {
    return -1;
  }
  const vtkMatrixTreeLocatorInternals& in = *this->Internals;
  CountQuery(kFcQueries);
  const mtree::NodeRef n = in.Tree.leafHolding(mtree::Vec3(x));
  if (!n.exists)
  {
    return -1;
  }
  return ScanCandidates(this->DataSet, in, x, n, n.range.begin, cell, pcoords, weights, this->EngineCellEvaluation);
}

#if VTK_VERSION_NUMBER >= VTK_VERSION_CHECK(9, 2, 0)
vtkIdType vtkMatrixTreeLocator::FindCell(
  double x[3], double tol2, vtkGenericCell* cell, int& subId, double pcoords[3], double* weights)
{
  subId = 0;
  return this->FindCell(x, tol2, cell, pcoords, weights);
}
#endif

//------------------------------------------------------------------------------
int vtkMatrixTreeLocator::IntersectWithLine(const double p1[3], const double p2[3], double tol,
  double& t, double x[3], double pcoords[3], int& subId, vtkIdType& cellId, vtkGenericCell* cell)
{
  cellId = -1;
  t = VTK_DOUBLE_MAX;
  if (!this->EnsureBuilt())
  {
    return 0;
  }
  const vtkMatrixTreeLocatorInternals& in = *this->Internals;
  CountQuery(kRayQueries);
  const mtree::Vec3 o(p1), d = mtree::Vec3(p2) - mtree::Vec3(p1);
  // The segment's frame (two normalisations) is set up when the first cell is tested: many
  // segments of a surface scene reach no candidate at all.
  std::optional<mtree::SegmentFrame> frameStore;
  auto frame = [&]() -> const mtree::SegmentFrame& {
    if (!frameStore)
    {
      frameStore.emplace(o, mtree::Vec3(p2), tol, kVtkQuadSplit);
    }
    return *frameStore;
  };
  double best = VTK_DOUBLE_MAX, tt, xx[3], pc[3];
  int sid;
  vtkIdType bestId = -1;
  // With tol = 0 each leaf's candidates are first tested against their quantized boxes in this
  // leaf (LeafBoxes: sequential bytes, where the cells' own bounds are a random read each); see
  // LeafSegmentFilter. Those that pass are taken in the order the segment enters their boxes,
  // and the leaf stops at the first whose entry lies beyond the best hit so far.
  const LeafSegmentFilter leafFilter(in, o, d, tol);
  vtkIdType filled = -1; // the cell `cell` holds
  // Cells whose hit is certain from the engine's copy (firstHitIfCertain, tol 0: tetrahedra, and
  // hexahedra, wedges and pyramids with planar faces) are not handed to VTK one by one: the
  // first of them is kept, and VTK evaluates only that one at the end, for the exact t, x and
  // pcoords. Should VTK not confirm it (it never did in the tests), the query is run again with
  // every cell going to VTK.
  for (int pass = 0; pass < 2; ++pass)
  {
    const bool deferCertain = pass == 0 && tol == 0.0;
    double deferredT = VTK_DOUBLE_MAX;
    vtkIdType deferredId = -1;
    int deferredFace = -1; // the face holding its hit, where certain (CertainFaceHit)
    best = VTK_DOUBLE_MAX;
    bestId = -1;
    // Cells span several leaves: a small direct-mapped mailbox skips most repeated tests (cleared
    // for the first test).
    vtkIdType mailbox[64];
    bool mailboxClear = false;
    LeafSegmentFilter::Candidate stackBuf[256];
    std::vector<LeafSegmentFilter::Candidate> heapBuf;
    // boxTest: whether the cell's own bounds are tested first (not needed after the leaf's
    // quantized boxes, which reject as much: a random read saved per candidate).
    auto test = [&](vtkIdType id, bool boxTest) {
      CountQuery(kRayCellTests);
      if (!mailboxClear)
      {
        std::fill(mailbox, mailbox + 64, -1);
        mailboxClear = true;
      }
      vtkIdType& slot = mailbox[id & 63];
      if (slot == id)
      {
        CountQuery(kRayMailboxRepeats);
        return;
      }
      slot = id;
      const double bound = std::min({ best, deferredT, 1.0 });
      if (boxTest)
      {
        // The segment must meet the cell's bounds (padded by tol) before a cell is fetched.
        const std::array<float, 6> cb = in.Cells.cellBox(static_cast<size_t>(id));
        mtree::Box box;
        box.lo = mtree::Vec3(cb[0] - tol, cb[2] - tol, cb[4] - tol);
        box.hi = mtree::Vec3(cb[1] + tol, cb[3] + tol, cb[5] + tol);
        double t0 = 0.0, t1 = bound;
        if (!mtree::rayBox(o, d, box, t0, t1))
        {
          return;
        }
      }
      // Then the cell's points: most cells whose box the segment crosses are proved missed
      // (or hit only beyond the best t so far) without VTK (segment_filter.h).
      double tc;
      int face = -1;
      const mtree::CellVerdict verdict =
        mtree::decideCell(frame(), in.Cells, static_cast<size_t>(id), bound, deferCertain, tc, &face, in.ShapeMemo.get());
      if (verdict == mtree::CellVerdict::kMiss)
      {
        CountQuery(kRayProvedMisses);
        return;
      }
      if (verdict == mtree::CellVerdict::kCertain)
      {
        CountQuery(kRayCertainHits);
        if (tc < deferredT)
        {
          deferredT = tc;
          deferredId = id;
          deferredFace = face;
        }
        return;
      }
      // A triangle at tol 0 without VTK (RecomputedTriangleHit), so the cell is filled only if it
      // wins.
      if (tol == 0.0)
      {
        mtree::vtk91::LineHit h;
        const mtree::vtk91::FaceHit v = RecomputedTriangleHit(in.Cells, id, p1, p2, h);
        if (v == mtree::vtk91::FaceHit::kMiss)
        {
          return;
        }
        if (v == mtree::vtk91::FaceHit::kHit)
        {
          if (h.t < best)
          {
            best = h.t;
            bestId = id;
            std::copy(h.x, h.x + 3, x);
            std::copy(h.pcoords, h.pcoords + 3, pcoords);
            subId = 0;
          }
          return;
        }
      }
      FillCell(this->DataSet, in, id, cell);
      filled = id;
      CountQuery(kRayVtkCalls);
      if (cell->IntersectWithLine(p1, p2, tol, tt, xx, pc, sid) && tt < best)
      {
        best = tt;
        bestId = id;
        std::copy(xx, xx + 3, x);
        std::copy(pc, pc + 3, pcoords);
        subId = sid;
      }
    };
    const uint32_t* prims = in.Tree.primitiveIndices().data();
    mtree::TraversalStats walk;
    in.Tree.traverseRay(
      o, d, 0.0, 1.0,
      [&](const uint32_t* ids, uint32_t count, double, double tExit, const int* leaf) {
        // The leaf's ids (read for the survivors only after its boxes are tested) and its boxes
        // are asked for as soon as the leaf is reached: their cache misses overlap each other
        // and the box test's set-up.
        PrefetchLines(ids, ids + count);
        const size_t first = static_cast<size_t>(ids - prims);
        if (6 * (first + count) <= in.LeafBoxes.size())
        {
          const uint8_t* lb = in.LeafBoxes.data() + 6 * first;
          PrefetchLines(lb, lb + 6 * static_cast<size_t>(count));
        }
        CountQuery(kRayLeaves);
        CountQuery(kRayReferences, count);
        LeafSegmentFilter::Candidate* cand = stackBuf;
        if (count > 256)
        {
          heapBuf.resize(count);
          cand = heapBuf.data();
        }
        const int nc =
          leafFilter.candidates(ids, count, leaf, std::min({ best, deferredT, 1.0 }), cand);
        CountQuery(kRayCandidates, nc < 0 ? count : static_cast<uint64_t>(nc));
        if (nc < 0)
        {
          for (uint32_t k = 0; k < count; ++k)
          {
            test(ids[k], true);
          }
        }
        else
        {
          // The survivors are known ahead: their point ids, then their points, are fetched
          // a few candidates early (random reads that otherwise stall each test in turn).
          for (int j = 0; j < std::min(nc, 16); ++j)
          {
            in.Cells.prefetchPointIds(ids[cand[j].k]);
          }
          for (int j = 0; j < nc; ++j)
          {
            if (cand[j].t > std::min({ best, deferredT, 1.0 }))
            {
              break; // sorted: the rest enter their boxes in this leaf later still
            }
            if (j + 16 < nc)
            {
              in.Cells.prefetchPointIds(ids[cand[j + 16].k]);
            }
            if (j + 2 < nc)
            {
              in.Cells.prefetchPoints(ids[cand[j + 2].k]);
            }
            test(ids[cand[j].k], false);
          }
        }
        return (bestId >= 0 || deferredId >= 0) && std::min(best, deferredT) <= tExit;
      },
      kQueryStats ? &walk : nullptr);
    CountQuery(kRaySteps, walk.cells);
    CountQuery(kRayNodeVisits, walk.nodeVisits);
    if (deferredId < 0 || (bestId >= 0 && best <= deferredT))
    {
      break;
    }
    FillCell(this->DataSet, in, deferredId, cell);
    filled = deferredId;
    CountQuery(kRayVtkCalls);
    // A hexahedron, wedge or tetrahedron whose hit face is known: VTK's test of that face alone
    // gives its answer. (A tetrahedron's face is found here, for the winner only.)
    if (deferredFace < 0 && tol == 0.0)
    {
      deferredFace = mtree::tetraCertainHitFace(frame(), in.Cells, static_cast<size_t>(deferredId));
    }
    const bool faceHit =
      deferredFace >= 0 && CertainFaceHit(in.Cells, deferredId, deferredFace, p1, p2, tol, tt, xx, pc, sid);
    if (faceHit || cell->IntersectWithLine(p1, p2, tol, tt, xx, pc, sid))
    {
      if (bestId < 0 || tt < best)
      {
        best = tt;
        bestId = deferredId;
        std::copy(xx, xx + 3, x);
        std::copy(pc, pc + 3, pcoords);
        subId = sid;
      }
      break;
    }
  }
  if (bestId < 0)
  {
    return 0;
  }
  CountQuery(kRayHits);
  t = best;
  cellId = bestId;
  if (filled != bestId) // the winner is usually the last cell VTK evaluated: already there
  {
    FillCell(this->DataSet, in, bestId, cell);
  }
  return 1;
}

//------------------------------------------------------------------------------
int vtkMatrixTreeLocator::IntersectWithLine(
  const double p1[3], const double p2[3], vtkPoints* points, vtkIdList* cellIds)
{
  if (points)
  {
    points->Reset();
  }
  if (cellIds)
  {
    cellIds->Reset();
  }
  if (!this->EnsureBuilt())
  {
    return 0;
  }
  const vtkMatrixTreeLocatorInternals& in = *this->Internals;
  struct Hit
  {
    double t;
    vtkIdType id;
    double x[3];
  };
  std::vector<Hit> hits;
  std::unordered_set<vtkIdType> seen;
  vtkNew<vtkGenericCell> cell;
  const mtree::Vec3 o(p1), d = mtree::Vec3(p2) - mtree::Vec3(p1);
  const mtree::SegmentFrame frame(o, mtree::Vec3(p2), 0.0, kVtkQuadSplit);
  in.Tree.traverseRay(
    o, d, 0.0, 1.0,
    [&](const uint32_t* ids, uint32_t count, double, double) {
      for (uint32_t k = 0; k < count; ++k)
      {
        const vtkIdType id = ids[k];
        if (!seen.insert(id).second ||
          !mtree::segmentMayHitCell(frame, in.Cells, static_cast<size_t>(id), 1.0))
        {
          continue;
        }
        Hit h;
        h.id = id;
        // A triangle without VTK, as in the first-hit query; VTK's own cell otherwise.
        mtree::vtk91::LineHit lh;
        const mtree::vtk91::FaceHit v = RecomputedTriangleHit(in.Cells, id, p1, p2, lh);
        if (v == mtree::vtk91::FaceHit::kHit)
        {
          h.t = lh.t;
          std::copy(lh.x, lh.x + 3, h.x);
          hits.push_back(h);
        }
        if (v != mtree::vtk91::FaceHit::kAskVtk)
        {
          continue;
        }
        this->DataSet->GetCell(id, cell);
        double pc[3];
        int sid;
        if (cell->IntersectWithLine(p1, p2, 0.0, h.t, h.x, pc, sid))
        {
          hits.push_back(h);
        }
      }
      return false;
    },
    nullptr);
  std::sort(hits.begin(), hits.end(),
    [](const Hit& a, const Hit& b) { return a.t < b.t || (a.t == b.t && a.id < b.id); });
  for (const Hit& h : hits)
  {
    if (points)
    {
      points->InsertNextPoint(h.x);
    }
    if (cellIds)
    {
      cellIds->InsertNextId(h.id);
    }
  }
  return static_cast<int>(hits.size());
}

//------------------------------------------------------------------------------
vtkIdType vtkMatrixTreeLocator::FindClosestPointWithinRadius(double x[3], double radius,
  double closestPoint[3], vtkGenericCell* cell, vtkIdType& cellId, int& subId, double& dist2,
  int& inside)
{
  cellId = -1;
  subId = 0;
  inside = 0;
  dist2 = VTK_DOUBLE_MAX;
  if (!this->EnsureBuilt() || this->Internals->Tree.empty() || !(radius >= 0))
  {
    return 0;
  }
  const vtkMatrixTreeLocatorInternals& in = *this->Internals;
  const mtree::MatrixTree& tree = in.Tree;
  const int H = tree.height();
  // Best-first search over existing nodes, nearest box first: a node farther than the best
  // distance found so far cannot hold a closer cell.
  struct Entry
  {
    double d2;
    int level;
    int c[3];
    bool operator<(const Entry& o) const { return d2 > o.d2; }
  };
  std::priority_queue<Entry> queue;
  double best = std::isinf(radius) ? std::numeric_limits<double>::infinity() : radius * radius;
  const int root[3] = { 0, 0, 0 };
  if (tree.nodeExists(0, root))
  {
    queue.push(Entry{ BoxDistance2(x, tree.nodeBox(0, root)), 0, { 0, 0, 0 } });
  }
  std::unordered_set<vtkIdType> tested;
  std::vector<double> weights(static_cast<size_t>(std::max(this->DataSet->GetMaxCellSize(), 1)));
  double cp[3], pc[3], d2;
  int sid;
  vtkIdType bestId = -1;
  double bestPoint[3] = { 0, 0, 0 };
  int bestSub = 0, bestInside = 0;
  while (!queue.empty())
  {
    const Entry e = queue.top();
    queue.pop();
    if (e.d2 > best)
    {
      break;
    }
    if (e.level == H)
    {
      const MtLeafRange r = tree.leafLevel().get(e.c[0], e.c[1], e.c[2]);
      for (uint32_t k = r.begin; k < r.end; ++k)
      {
        const vtkIdType id = tree.primitiveIndices()[k];
        if (BoundsDistance2(x, in.Cells.cellBox(static_cast<size_t>(id)).data()) > best || !tested.insert(id).second)
        {
          continue;
        }
        this->DataSet->GetCell(id, cell);
        const int ret = cell->EvaluatePosition(x, cp, sid, pc, d2, weights.data());
        if (ret == -1)
        {
          continue; // degenerate cell
        }
        // EvaluatePosition's dist2 and closest point are right for every cell dimension (for a
        // triangle "inside" means the projection falls inside, and dist2 is the plane distance).
        if (d2 < best || (d2 == best && bestId >= 0 && id < bestId) || (bestId < 0 && d2 <= best))
        {
          best = d2;
          bestId = id;
          std::copy(cp, cp + 3, bestPoint);
          bestSub = sid;
          bestInside = ret == 1 ? 1 : 0;
        }
      }
      continue;
    }
    ForEachChild(tree, e.level, e.c, [&](const int cc[3]) {
      const double cd2 = BoxDistance2(x, tree.nodeBox(e.level + 1, cc));
      if (cd2 <= best)
      {
        queue.push(Entry{ cd2, e.level + 1, { cc[0], cc[1], cc[2] } });
      }
    });
  }
  if (bestId < 0)
  {
    return 0;
  }
  cellId = bestId;
  subId = bestSub;
  inside = bestInside;
  dist2 = best;
  std::copy(bestPoint, bestPoint + 3, closestPoint);
  this->DataSet->GetCell(bestId, cell);
  return 1;
}

void vtkMatrixTreeLocator::FindClosestPoint(const double x[3], double closestPoint[3],
  vtkGenericCell* cell, vtkIdType& cellId, int& subId, double& dist2)
{
  int inside;
  double xx[3] = { x[0], x[1], x[2] };
  this->FindClosestPointWithinRadius(xx, std::numeric_limits<double>::infinity(), closestPoint,
    cell, cellId, subId, dist2, inside);
}

//------------------------------------------------------------------------------
void vtkMatrixTreeLocator::FindCellsWithinBounds(double* bbox, vtkIdList* cells)
{
  cells->Reset();
  if (!this->EnsureBuilt() || this->Internals->Tree.empty())
  {
    return;
  }
  const vtkMatrixTreeLocatorInternals& in = *this->Internals;
  const mtree::MatrixTree& tree = in.Tree;
  // VTK's semantics: every cell whose bounds meet the box. A cell is only in the leaves it
  // really overlaps, so gather from leaves of the box widened by the largest cell extent, then
  // filter by the cached cell bounds.
  mtree::Box q;
  q.lo = mtree::Vec3(bbox[0] - in.MaxCellExtent[0], bbox[2] - in.MaxCellExtent[1], bbox[4] - in.MaxCellExtent[2]);
  q.hi = mtree::Vec3(bbox[1] + in.MaxCellExtent[0], bbox[3] + in.MaxCellExtent[1], bbox[5] + in.MaxCellExtent[2]);
  std::vector<vtkIdType> found;
  struct Node
  {
    int level;
    int c[3];
  };
  std::vector<Node> stack;
  const int root[3] = { 0, 0, 0 };
  if (tree.nodeExists(0, root) && tree.nodeBox(0, root).overlaps(q))
  {
    stack.push_back(Node{ 0, { 0, 0, 0 } });
  }
  while (!stack.empty())
  {
    const Node nd = stack.back();
    stack.pop_back();
    if (nd.level == tree.height())
    {
      const MtLeafRange r = tree.leafLevel().get(nd.c[0], nd.c[1], nd.c[2]);
      for (uint32_t k = r.begin; k < r.end; ++k)
      {
        found.push_back(tree.primitiveIndices()[k]);
      }
      continue;
    }
    ForEachChild(tree, nd.level, nd.c, [&](const int cc[3]) {
      if (tree.nodeBox(nd.level + 1, cc).overlaps(q))
      {
        stack.push_back(Node{ nd.level + 1, { cc[0], cc[1], cc[2] } });
      }
    });
  }
  std::sort(found.begin(), found.end());
  found.erase(std::unique(found.begin(), found.end()), found.end());
  mtree::Box query;
  query.lo = mtree::Vec3(bbox[0], bbox[2], bbox[4]);
  query.hi = mtree::Vec3(bbox[1], bbox[3], bbox[5]);
  for (vtkIdType id : found)
  {
    // The float bounds contain the exact ones: a miss is final, a hit is checked exactly.
    const std::array<float, 6> b = in.Cells.cellBox(static_cast<size_t>(id));
    if (b[0] <= bbox[1] && b[1] >= bbox[0] && b[2] <= bbox[3] && b[3] >= bbox[2] && b[4] <= bbox[5] &&
      b[5] >= bbox[4] && in.Cells.exactBounds(static_cast<size_t>(id)).overlaps(query))
    {
      cells->InsertNextId(id);
    }
  }
}

//------------------------------------------------------------------------------
void vtkMatrixTreeLocator::FindCellsAlongLine(
  const double p1[3], const double p2[3], double vtkNotUsed(tolerance), vtkIdList* cells)
{
  cells->Reset();
  if (!this->EnsureBuilt())
  {
    return;
  }
  std::vector<vtkIdType> found;
  const mtree::Vec3 o(p1), d = mtree::Vec3(p2) - mtree::Vec3(p1);
  this->Internals->Tree.traverseRay(
    o, d, 0.0, 1.0,
    [&](const uint32_t* ids, uint32_t count, double, double) {
      found.insert(found.end(), ids, ids + count);
      return false;
    },
    nullptr);
  std::sort(found.begin(), found.end());
  found.erase(std::unique(found.begin(), found.end()), found.end());
  for (vtkIdType id : found)
  {
    cells->InsertNextId(id);
  }
}

//------------------------------------------------------------------------------
void vtkMatrixTreeLocator::GenerateRepresentation(int level, vtkPolyData* pd)
{
  if (!pd || !this->EnsureBuilt())
  {
    return;
  }
  const mtree::MatrixTree& tree = this->Internals->Tree;
  vtkNew<vtkPoints> pts;
  vtkNew<vtkCellArray> quads;
  vtkNew<vtkIntArray> levels;
  levels->SetName("Level");
  vtkNew<vtkIntArray> counts;
  counts->SetName("NumberOfCells");
  if (!tree.empty())
  {
    const int H = tree.height();
    const int l = (level < 0 || level > H) ? H : level;
    auto addBox = [&](const int c[3], int n) {
      const mtree::Box b = tree.nodeBox(l, c);
      const vtkIdType base = pts->GetNumberOfPoints();
      for (int k = 0; k < 8; ++k)
      {
        pts->InsertNextPoint((k & 1) ? b.hi.x : b.lo.x, (k & 2) ? b.hi.y : b.lo.y, (k & 4) ? b.hi.z : b.lo.z);
      }
      static const int faces[6][4] = { { 0, 2, 6, 4 }, { 1, 5, 7, 3 }, { 0, 4, 5, 1 }, { 2, 3, 7, 6 },
        { 0, 1, 3, 2 }, { 4, 6, 7, 5 } };
      for (const auto& f : faces)
      {
        const vtkIdType q[4] = { base + f[0], base + f[1], base + f[2], base + f[3] };
        quads->InsertNextCell(4, q);
        levels->InsertNextValue(l);
        counts->InsertNextValue(n);
      }
    };
    if (l == H)
    {
      const auto& m = tree.leafLevel();
      for (size_t e = 0; e < m.data().size(); ++e)
      {
        const MtLeafRange r = m.data()[e];
        if (r.begin == MT_NULL)
        {
          continue;
        }
        int c[3];
        m.entryCoords(static_cast<uint32_t>(e), c);
        addBox(c, static_cast<int>(r.end - r.begin));
      }
    }
    else
    {
      const auto& m = tree.innerLevel(l);
      for (size_t e = 0; e < m.data().size(); ++e)
      {
        if (!m.data()[e])
        {
          continue;
        }
        int c[3];
        m.entryCoords(static_cast<uint32_t>(e), c);
        addBox(c, 0);
      }
    }
  }
  pd->Initialize();
  pd->SetPoints(pts);
  pd->SetPolys(quads);
  pd->GetCellData()->AddArray(levels);
  pd->GetCellData()->AddArray(counts);
}

//------------------------------------------------------------------------------
vtkIdType vtkMatrixTreeLocator::GenerateNodes(int minLevel, int maxLevel, vtkUnstructuredGrid* output)
{
  if (!output)
  {
    return 0;
  }
  output->Initialize();
  if (!this->EnsureBuilt())
  {
    return 0;
  }
  const mtree::MatrixTree& tree = this->Internals->Tree;
  vtkNew<vtkPoints> pts;
  pts->SetDataTypeToDouble();
  vtkNew<vtkCellArray> cells;
  vtkNew<vtkIntArray> levels;
  levels->SetName("level");
  vtkNew<vtkDoubleArray> occupancy;
  occupancy->SetName("occupancy");
  vtkNew<vtkIdTypeArray> counts;
  counts->SetName("cell_count");
  vtkNew<vtkIntArray> height;
  height->SetName("tree_height");
  height->InsertNextValue(tree.empty() ? 0 : tree.height());
  output->GetFieldData()->AddArray(height);
  if (tree.empty())
  {
    output->SetPoints(pts);
    output->SetCells(VTK_VOXEL, cells);
    return 0;
  }
  const int H = tree.height();
  const int hi = (maxLevel < 0 || maxLevel > H) ? H : maxLevel;
  const int lo = std::max(0, std::min(minLevel, hi));

  // Distinct (node, cell) pairs level by level, bottom-up: the pairs of level l are those of
  // level l + 1 with each node replaced by its parent, deduplicated. Node keys are linear
  // indices in the level's full grid (at most 2^43 nodes: the leaf pointer matrix is capped).
  using Pair = std::pair<uint64_t, uint32_t>;
  auto linear = [&](int l, const int c[3]) {
    return static_cast<uint64_t>(c[0]) +
      (static_cast<uint64_t>(1) << tree.logDim(l, 0)) *
      (static_cast<uint64_t>(c[1]) + (static_cast<uint64_t>(1) << tree.logDim(l, 1)) * static_cast<uint64_t>(c[2]));
  };
  auto unlinear = [&](int l, uint64_t k, int c[3]) {
    c[0] = static_cast<int>(k & ((uint64_t(1) << tree.logDim(l, 0)) - 1));
    k >>= tree.logDim(l, 0);
    c[1] = static_cast<int>(k & ((uint64_t(1) << tree.logDim(l, 1)) - 1));
    c[2] = static_cast<int>(k >> tree.logDim(l, 1));
  };
  std::vector<Pair> pairs;
  pairs.reserve(tree.primitiveIndices().size());
  {
    const auto& m = tree.leafLevel();
    for (size_t e = 0; e < m.data().size(); ++e)
    {
      const MtLeafRange r = m.data()[e];
      if (r.begin == MT_NULL)
      {
        continue;
      }
      int c[3];
      m.entryCoords(static_cast<uint32_t>(e), c);
      const uint64_t key = linear(H, c);
      for (uint32_t k = r.begin; k < r.end; ++k)
      {
        pairs.emplace_back(key, tree.primitiveIndices()[k]);
      }
    }
    std::sort(pairs.begin(), pairs.end());
  }
  auto addBox = [&](int l, const int c[3], double occ, vtkIdType n) {
    const mtree::Box b = tree.nodeBox(l, c);
    vtkIdType ids[8];
    for (int k = 0; k < 8; ++k)
    {
      ids[k] = pts->InsertNextPoint(
        (k & 1) ? b.hi.x : b.lo.x, (k & 2) ? b.hi.y : b.lo.y, (k & 4) ? b.hi.z : b.lo.z);
    }
    cells->InsertNextCell(8, ids);
    levels->InsertNextValue(l);
    occupancy->InsertNextValue(occ);
    counts->InsertNextValue(n);
  };
  // Emits the nodes of level l (pairs sorted by node) in node-key order.
  auto emitLevel = [&](int l) {
    int s[3] = { 0, 0, 0 };
    if (l < H)
    {
      for (int a = 0; a < 3; ++a)
      {
        s[a] = tree.logDim(l + 1, a) - tree.logDim(l, a);
      }
    }
    const double children = static_cast<double>(1 << (s[0] + s[1] + s[2]));
    for (size_t i = 0; i < pairs.size();)
    {
      size_t j = i;
      while (j < pairs.size() && pairs[j].first == pairs[i].first)
      {
        ++j;
      }
      int c[3];
      unlinear(l, pairs[i].first, c);
      double occ = 1.0;
      if (l < H)
      {
        int present = 0;
        ForEachChild(tree, l, c, [&](const int*) { ++present; });
        occ = present / children;
      }
      addBox(l, c, occ, static_cast<vtkIdType>(j - i));
      i = j;
    }
  };
  // Output order: levels from lo to hi. Collect per level bottom-up, then append in order.
  std::vector<std::vector<Pair>> perLevel(static_cast<size_t>(hi - lo + 1));
  for (int l = H; l >= lo; --l)
  {
    if (l < H)
    {
      int s[3];
      for (int a = 0; a < 3; ++a)
      {
        s[a] = tree.logDim(l + 1, a) - tree.logDim(l, a);
      }
      for (Pair& p : pairs)
      {
        int c[3];
        unlinear(l + 1, p.first, c);
        const int pc[3] = { c[0] >> s[0], c[1] >> s[1], c[2] >> s[2] };
        p.first = linear(l, pc);
      }
      std::sort(pairs.begin(), pairs.end());
      pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
    }
    if (l <= hi)
    {
      perLevel[static_cast<size_t>(l - lo)] = pairs;
    }
  }
  for (int l = lo; l <= hi; ++l)
  {
    pairs.swap(perLevel[static_cast<size_t>(l - lo)]);
    emitLevel(l);
  }
  output->SetPoints(pts);
  output->SetCells(VTK_VOXEL, cells);
  output->GetCellData()->AddArray(levels);
  output->GetCellData()->AddArray(occupancy);
  output->GetCellData()->AddArray(counts);
  return cells->GetNumberOfCells();
}

//------------------------------------------------------------------------------
namespace
{
// The data set's cells made safe to fetch from many threads (polydata builds its cell links
// on the first GetCell).
void PrepareForThreads(vtkDataSet* ds)
{
  if (ds && ds->GetNumberOfCells() > 0)
  {
    vtkNew<vtkGenericCell> c;
    ds->GetCell(0, c);
  }
}

bool CheckTriples(vtkObject* self, vtkDataArray* a, const char* what)
{
  if (!a || a->GetNumberOfComponents() != 3)
  {
    vtkErrorWithObjectMacro(self, << what << " must be a 3-component array.");
    return false;
  }
  return true;
}

int ThreadCount(int requested)
{
  return requested > 0 ? requested : omp_get_max_threads();
}
}

void vtkMatrixTreeLocator::FindCells(
  vtkPoints* points, vtkIdTypeArray* cellIds, vtkDoubleArray* pcoords, vtkDoubleArray* weights)
{
  if (!cellIds)
  {
    vtkErrorMacro("FindCells: cellIds must not be null.");
    return;
  }
  cellIds->SetNumberOfComponents(1);
  cellIds->SetNumberOfTuples(0);
  if (pcoords)
  {
    pcoords->SetNumberOfComponents(3);
    pcoords->SetNumberOfTuples(0);
  }
  if (weights)
  {
    weights->SetNumberOfTuples(0);
  }
  if (!points || !CheckTriples(this, points->GetData(), "FindCells: points") || !this->EnsureBuilt())
  {
    return;
  }
  vtkMatrixTreeLocatorInternals& in = *this->Internals;
  const vtkIdType n = points->GetNumberOfPoints();
  using Clock = std::chrono::steady_clock;
  const Clock::time_point tStart = Clock::now();
  auto msSince = [](Clock::time_point t) {
    return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
  };

  // OpenCL: the device answers first (outcome and candidate position per point, see
  // mtree::ocl::CellLocator); the host loop below finishes each point from there.
  std::vector<uint32_t> answers;
  std::ostringstream phases;
  if (this->Backend == OPENCL)
  {
    this->LastNumberOfHostResumes = 0;
    this->LastNumberOfUnconfirmedCells = 0;
    try
    {
      const std::string selector = this->OpenCLDevice ? this->OpenCLDevice : "";
      if (!in.CL || selector != in.CLSelector)
      {
        in.CL.reset();
        in.CLUploaded = false;
        in.CLDeviceName.clear();
        in.CL.reset(new mtree::ocl::CellLocator(mtree::ocl::Context::shared(selector)));
        in.CLSelector = selector;
        in.CLDeviceName = in.CL->context().device().name;
      }
      double uploadMs = 0;
      if (!in.CLUploaded)
      {
        const Clock::time_point t0 = Clock::now();
        in.CL->upload(in.Tree, in.Cells, in.LeafBoxes);
        in.CLUploaded = true;
        ++this->NumberOfOpenCLUploads;
        uploadMs = msSince(t0);
      }
      // The kernel reads doubles: use the points' own array when it holds them.
      std::vector<double> copy;
      const double* xyz = nullptr;
      vtkDoubleArray* dbl = vtkDoubleArray::FastDownCast(points->GetData());
      if (dbl && n > 0)
      {
        xyz = dbl->GetPointer(0);
      }
      else
      {
        copy.resize(3 * static_cast<size_t>(n));
        for (vtkIdType i = 0; i < n; ++i)
        {
          points->GetPoint(i, &copy[3 * static_cast<size_t>(i)]);
        }
        xyz = copy.data();
      }
      answers.resize(2 * static_cast<size_t>(n));
      std::vector<mtree::ocl::KernelTiming> timing;
      const Clock::time_point t1 = Clock::now();
      in.CL->locate(xyz, static_cast<size_t>(n), kTetraTolerance, answers.data(), &timing);
      const double deviceMs = msSince(t1);
      double pointsMs = 0, kernelMs = 0, downloadMs = 0;
      for (const auto& t : timing)
      {
        (t.kernel == "(upload)" ? pointsMs : (t.kernel == "(download)" ? downloadMs : kernelMs)) += t.ms;
      }
      phases << "upload " << uploadMs << "; points " << pointsMs << "; kernel " << kernelMs << "; download "
             << downloadMs << "; device call " << deviceMs;
    }
    catch (const std::exception& e)
    {
      in.CLUploaded = false;
      vtkErrorMacro("FindCells failed (opencl backend): " << e.what()
                                                          << " (or locate with SetBackendToCPU())");
      return;
    }
  }
  const bool device = this->Backend == OPENCL;

  const int nw = std::max(1, this->DataSet->GetMaxCellSize());
  cellIds->SetNumberOfTuples(n);
  if (pcoords)
  {
    pcoords->SetNumberOfTuples(n);
  }
  if (weights)
  {
    weights->SetNumberOfComponents(nw);
    weights->SetNumberOfTuples(n);
  }
  PrepareForThreads(this->DataSet);
  vtkIdType* ids = cellIds->GetPointer(0);
  double* pc = pcoords ? pcoords->GetPointer(0) : nullptr;
  double* w = weights ? weights->GetPointer(0) : nullptr;
  const uint32_t* prims = in.Tree.primitiveIndices().data();
  const bool wantParams = pc || w;
  vtkIdType resumes = 0, unconfirmed = 0;
  const Clock::time_point tHost = Clock::now();
#pragma omp parallel num_threads(ThreadCount(this->NumberOfThreads)) reduction(+ : resumes, unconfirmed)
  {
    vtkNew<vtkGenericCell> cell;
    std::vector<double> wk(static_cast<size_t>(nw));
    double x[3], p[3];
#pragma omp for schedule(dynamic, 1024)
    for (vtkIdType i = 0; i < n; ++i)
    {
      points->GetPoint(i, x);
      std::fill(wk.begin(), wk.end(), 0.0);
      p[0] = p[1] = p[2] = 0.0;
      if (!device)
      {
        ids[i] = this->FindCell(x, 0.0, cell, p, wk.data());
      }
      else
      {
        const uint32_t outcome = answers[2 * static_cast<size_t>(i)];
        uint32_t k = answers[2 * static_cast<size_t>(i) + 1];
        ids[i] = -1;
        bool resume = outcome == mtree::ocl::CellLocator::kResume;
        if (outcome == mtree::ocl::CellLocator::kFound)
        {
          ids[i] = prims[k];
          if (wantParams)
          {
            // pcoords and weights as VTK's EvaluatePosition gives them, which also confirms the
            // device's answer.
            if (!CellContains(this->DataSet, in, x, ids[i], cell, p, wk.data(), this->EngineCellEvaluation))
            {
              ++unconfirmed;
              resume = true;
            }
          }
        }
        if (resume)
        {
          ++resumes;
          const mtree::NodeRef leaf = in.Tree.leafHolding(mtree::Vec3(x));
          ids[i] = leaf.exists
            ? ScanCandidates(this->DataSet, in, x, leaf, k, cell, p, wk.data(), this->EngineCellEvaluation)
            : -1;
        }
      }
      if (ids[i] < 0)
      {
        // A miss leaves what the last rejected candidate wrote: not meaningful, zeroed.
        p[0] = p[1] = p[2] = 0.0;
      }
      if (pc)
      {
        std::copy(p, p + 3, pc + 3 * i);
      }
      if (w)
      {
        if (ids[i] < 0)
        {
          std::fill(wk.begin(), wk.end(), 0.0);
        }
        else
        {
          // Only the found cell's weights are meaningful; zero the rest.
          std::fill(wk.begin() + std::min<vtkIdType>(nw, cell->GetNumberOfPoints()), wk.end(), 0.0);
        }
        std::copy(wk.begin(), wk.end(), w + static_cast<size_t>(nw) * i);
      }
    }
  }
  if (device)
  {
    this->LastNumberOfHostResumes = resumes;
    this->LastNumberOfUnconfirmedCells = unconfirmed;
    phases << "; host " << msSince(tHost) << "; total " << msSince(tStart);
    in.FindPhases = phases.str();
  }
}

void vtkMatrixTreeLocator::IntersectSegments(vtkDataArray* p1, vtkDataArray* p2, double tol,
  vtkDoubleArray* t, vtkIdTypeArray* cellIds, vtkDoubleArray* points)
{
  if (!t || !cellIds)
  {
    vtkErrorMacro("IntersectSegments: t and cellIds must not be null.");
    return;
  }
  t->SetNumberOfComponents(1);
  t->SetNumberOfTuples(0);
  cellIds->SetNumberOfComponents(1);
  cellIds->SetNumberOfTuples(0);
  if (points)
  {
    points->SetNumberOfComponents(3);
    points->SetNumberOfTuples(0);
  }
  if (!CheckTriples(this, p1, "IntersectSegments: p1") || !CheckTriples(this, p2, "IntersectSegments: p2"))
  {
    return;
  }
  if (p1->GetNumberOfTuples() != p2->GetNumberOfTuples())
  {
    vtkErrorMacro("IntersectSegments: p1 has " << p1->GetNumberOfTuples() << " tuples, p2 "
                                               << p2->GetNumberOfTuples() << ".");
    return;
  }
  if (!this->EnsureBuilt())
  {
    return;
  }
  const vtkIdType n = p1->GetNumberOfTuples();
  t->SetNumberOfTuples(n);
  cellIds->SetNumberOfTuples(n);
  if (points)
  {
    points->SetNumberOfTuples(n);
  }
  PrepareForThreads(this->DataSet);
  double* tt = t->GetPointer(0);
  vtkIdType* ids = cellIds->GetPointer(0);
  double* xp = points ? points->GetPointer(0) : nullptr;
  const double inf = std::numeric_limits<double>::infinity();
  const double nan = std::numeric_limits<double>::quiet_NaN();
#pragma omp parallel num_threads(ThreadCount(this->NumberOfThreads))
  {
    vtkNew<vtkGenericCell> cell;
    double a[3], b[3], x[3], pc[3], ti;
    int sub;
    vtkIdType id;
#pragma omp for schedule(dynamic, 256)
    for (vtkIdType i = 0; i < n; ++i)
    {
      p1->GetTuple(i, a);
      p2->GetTuple(i, b);
      const int hit = this->IntersectWithLine(a, b, tol, ti, x, pc, sub, id, cell);
      ids[i] = hit ? id : -1;
      tt[i] = hit ? ti : inf;
      if (xp)
      {
        for (int k = 0; k < 3; ++k)
        {
          xp[3 * i + k] = hit ? x[k] : nan;
        }
      }
    }
  }
}

void vtkMatrixTreeLocator::FindClosestPoints(
  vtkPoints* points, vtkDoubleArray* closestPoints, vtkIdTypeArray* cellIds, vtkDoubleArray* dist2)
{
  if (!closestPoints || !cellIds)
  {
    vtkErrorMacro("FindClosestPoints: closestPoints and cellIds must not be null.");
    return;
  }
  closestPoints->SetNumberOfComponents(3);
  closestPoints->SetNumberOfTuples(0);
  cellIds->SetNumberOfComponents(1);
  cellIds->SetNumberOfTuples(0);
  if (dist2)
  {
    dist2->SetNumberOfComponents(1);
    dist2->SetNumberOfTuples(0);
  }
  if (!points || !CheckTriples(this, points->GetData(), "FindClosestPoints: points") ||
    !this->EnsureBuilt())
  {
    return;
  }
  const vtkIdType n = points->GetNumberOfPoints();
  closestPoints->SetNumberOfTuples(n);
  cellIds->SetNumberOfTuples(n);
  if (dist2)
  {
    dist2->SetNumberOfTuples(n);
  }
  PrepareForThreads(this->DataSet);
  double* cp = closestPoints->GetPointer(0);
  vtkIdType* ids = cellIds->GetPointer(0);
  double* d2 = dist2 ? dist2->GetPointer(0) : nullptr;
  const double inf = std::numeric_limits<double>::infinity();
  const double nan = std::numeric_limits<double>::quiet_NaN();
#pragma omp parallel num_threads(ThreadCount(this->NumberOfThreads))
  {
    vtkNew<vtkGenericCell> cell;
    double x[3], c[3], d;
    int sub;
    vtkIdType id;
#pragma omp for schedule(dynamic, 256)
    for (vtkIdType i = 0; i < n; ++i)
    {
      points->GetPoint(i, x);
      this->FindClosestPoint(x, c, cell, id, sub, d);
      ids[i] = id;
      for (int k = 0; k < 3; ++k)
      {
        cp[3 * i + k] = id >= 0 ? c[k] : nan;
      }
      if (d2)
      {
        d2[i] = id >= 0 ? d : inf;
      }
    }
  }
}

//------------------------------------------------------------------------------
double vtkMatrixTreeLocator::GetLeafScaleUsed()
{
  return this->Internals->Valid ? this->Internals->LeafScaleUsed : 0.0;
}
double vtkMatrixTreeLocator::GetMaxCandidatesUsed()
{
  return this->Internals->Valid ? this->Internals->MaxCandidatesUsed : 0.0;
}
int vtkMatrixTreeLocator::GetTreeHeight()
{
  return this->Internals->Valid ? this->Internals->Tree.height() : 0;
}
vtkIdType vtkMatrixTreeLocator::GetNumberOfLeaves()
{
  return this->Internals->Valid ? static_cast<vtkIdType>(this->Internals->Stats.leaves) : 0;
}
vtkIdType vtkMatrixTreeLocator::GetNumberOfReferences()
{
  return this->Internals->Valid ? static_cast<vtkIdType>(this->Internals->Stats.references) : 0;
}
vtkIdType vtkMatrixTreeLocator::GetMemorySize()
{
  const vtkMatrixTreeLocatorInternals& in = *this->Internals;
  return in.Valid
    ? static_cast<vtkIdType>(in.Tree.bytes() + in.Cells.bytes() + in.LeafBoxes.size() +
        (in.ShapeMemo ? in.Cells.size() : 0))
    : 0;
}
const char* vtkMatrixTreeLocator::GetBuildPhases()
{
  return this->Internals->Phases.c_str();
}
double vtkMatrixTreeLocator::GetLastBuildTime()
{
  return this->Internals->Stats.totalMs;
}

void vtkMatrixTreeLocator::CopySettings(vtkMatrixTreeLocator* other)
{
  if (!other)
  {
    return;
  }
  this->SetTreeType(other->TreeType);
  this->SetHeight(other->Height);
  this->SetBlockSize(other->BlockSize);
  this->SetLeafScale(other->LeafScale);
  this->SetExactOverlap(other->ExactOverlap);
  this->SetFullSeparatingAxes(other->FullSeparatingAxes);
  this->SetMaxCandidates(other->MaxCandidates);
  this->SetNumberOfThreads(other->NumberOfThreads);
  this->SetBuildSort(other->BuildSort);
  this->SetCellStorage(other->CellStorage);
  this->SetCacheCellBounds(other->CacheCellBounds);
  this->SetUseExistingSearchStructure(other->UseExistingSearchStructure);
  this->SetBackend(other->Backend);
  this->SetOpenCLDevice(other->OpenCLDevice);
  this->SetEngineCellEvaluation(other->EngineCellEvaluation);
  this->SetRayStepTable(other->RayStepTable);
}

//------------------------------------------------------------------------------
void vtkMatrixTreeLocator::PrintSelf(ostream& os, vtkIndent indent)
{
  this->Superclass::PrintSelf(os, indent);
  os << indent << "TreeType: " << (this->TreeType == KDTREE ? "KDTREE" : "OCTREE") << "\n";
  os << indent << "Height: " << this->Height << (this->Height == 0 ? " (automatic)" : "") << "\n";
  os << indent << "BlockSize: " << this->BlockSize << "\n";
  os << indent << "ExactOverlap: " << (this->ExactOverlap ? "On" : "Off") << "\n";
  os << indent << "FullSeparatingAxes: " << (this->FullSeparatingAxes ? "On" : "Off") << "\n";
  os << indent << "LeafScale: " << this->LeafScale << "\n";
  os << indent << "MaxCandidates: " << this->MaxCandidates << "\n";
  os << indent << "NumberOfThreads: " << this->NumberOfThreads << "\n";
  os << indent << "BuildSort: " << this->GetBuildSortAsString() << "\n";
  os << indent << "CellStorage: "
     << (this->CellStorage == CELLS_IN_PLACE ? "in place" : (this->CellStorage == CELLS_COPIED ? "copied" : "automatic"))
     << "\n";
  os << indent << "Backend: " << this->GetBackendAsString() << "\n";
  os << indent << "OpenCLDevice: " << (this->OpenCLDevice ? this->OpenCLDevice : "(default)") << "\n";
  os << indent << "OpenCLDeviceName: " << this->Internals->CLDeviceName << "\n";
  os << indent << "NumberOfOpenCLUploads: " << this->NumberOfOpenCLUploads << "\n";
  os << indent << "LastNumberOfHostResumes: " << this->LastNumberOfHostResumes << "\n";
  os << indent << "LastNumberOfUnconfirmedCells: " << this->LastNumberOfUnconfirmedCells << "\n";
  os << indent << "LastFindCellsPhases: " << this->Internals->FindPhases << "\n";
  os << indent << "EngineCellEvaluation: " << (this->EngineCellEvaluation ? "On" : "Off") << "\n";
  os << indent << "RayStepTable: " << (this->RayStepTable ? "On" : "Off") << "\n";
  os << indent << "Built: " << (this->Internals->Valid ? "yes" : "no") << "\n";
  if (this->Internals->Valid)
  {
    os << indent << "TreeHeight: " << this->GetTreeHeight() << "\n";
    os << indent << "NumberOfLeaves: " << this->GetNumberOfLeaves() << "\n";
    os << indent << "NumberOfReferences: " << this->GetNumberOfReferences() << "\n";
    os << indent << "MemorySize: " << this->GetMemorySize() << " bytes\n";
    os << indent << "LastBuildTime: " << this->GetLastBuildTime() << " ms\n";
  }
}

//------------------------------------------------------------------------------
bool vtkMatrixTreeLocator::QueryStatisticsEnabled()
{
  return kQueryStats;
}

int vtkMatrixTreeLocator::GetNumberOfQueryStatistics()
{
  return kQueryStats ? kNumQueryStats : 0;
}

const char* vtkMatrixTreeLocator::GetQueryStatisticName(int i)
{
  return i >= 0 && i < GetNumberOfQueryStatistics() ? kQueryStatNames[i] : nullptr;
}

vtkTypeUInt64 vtkMatrixTreeLocator::GetQueryStatistic(int i)
{
#if defined(MATRIXTREE_QUERY_STATS) && MATRIXTREE_QUERY_STATS
  return i >= 0 && i < kNumQueryStats ? gQueryStats[i].load(std::memory_order_relaxed) : 0;
#else
  (void)i;
  return 0;
#endif
}

vtkTypeInt64 vtkMatrixTreeLocator::GetCachedMemorySize()
{
  return static_cast<vtkTypeInt64>(mtree::cachedMemoryBytes());
}

vtkTypeInt64 vtkMatrixTreeLocator::ReleaseCachedMemory()
{
  return static_cast<vtkTypeInt64>(mtree::releaseCachedMemory());
}

void vtkMatrixTreeLocator::ResetQueryStatistics()
{
#if defined(MATRIXTREE_QUERY_STATS) && MATRIXTREE_QUERY_STATS
  for (auto& c : gQueryStats)
  {
    c.store(0, std::memory_order_relaxed);
  }
#endif
}

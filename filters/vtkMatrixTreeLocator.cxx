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

#include "mtree/builder.h"
#include "mtree/cells.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <queue>
#include <unordered_set>
#include <vector>

struct vtkMatrixTreeLocatorInternals
{
  mtree::CellSet Cells;
  mtree::MatrixTree Tree;
  mtree::BuildStats Stats;
  std::vector<double> CellBounds; // 6 per cell: xmin xmax ymin ymax zmin zmax
  double MaxCellExtent[3] = { 0, 0, 0 }; // largest cell bounding-box extent per axis
  bool Valid = false;
};

vtkStandardNewMacro(vtkMatrixTreeLocator);

namespace
{
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

inline double BoundsDistance2(const double x[3], const double* b)
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
}

//------------------------------------------------------------------------------
vtkMatrixTreeLocator::vtkMatrixTreeLocator()
  : Internals(new vtkMatrixTreeLocatorInternals)
{
  this->CacheCellBounds = 1;
}

vtkMatrixTreeLocator::~vtkMatrixTreeLocator()
{
  delete this->Internals;
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
  if (!this->DataSet)
  {
    vtkErrorMacro("No data set: call SetDataSet() first.");
    return false;
  }
  if (this->NeedsBuild())
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
  std::vector<double> pts(static_cast<size_t>(np) * 3);
  vtkPointSet* ps = vtkPointSet::SafeDownCast(ds);
  vtkDataArray* pdata = ps && ps->GetPoints() ? ps->GetPoints()->GetData() : nullptr;
  if (auto* dbl = vtkDoubleArray::FastDownCast(pdata))
  {
    std::copy(dbl->GetPointer(0), dbl->GetPointer(0) + 3 * np, pts.begin());
  }
  else if (auto* flt = vtkFloatArray::FastDownCast(pdata))
  {
    std::copy(flt->GetPointer(0), flt->GetPointer(0) + 3 * np, pts.begin());
  }
  else
  {
    for (vtkIdType i = 0; i < np; ++i)
    {
      ds->GetPoint(i, &pts[3 * i]);
    }
  }
  std::vector<int64_t> offsets(static_cast<size_t>(nc) + 1, 0), conn;
  std::vector<uint8_t> types(static_cast<size_t>(nc));
  vtkUnstructuredGrid* ug = vtkUnstructuredGrid::SafeDownCast(ds);
  vtkCellArray* ca = ug ? ug->GetCells() : nullptr;
  if (ca && ug->GetCellTypesArray() && ca->GetNumberOfCells() == nc)
  {
    // Unstructured grids: copy the cell arrays directly (the generic per-cell loop below costs
    // more than the whole tree build).
    const unsigned char* t = ug->GetCellTypesArray()->GetPointer(0);
    std::copy(t, t + nc, types.begin());
    auto copyArrays = [&](auto* off, auto* cn) {
      for (vtkIdType c = 0; c <= nc; ++c)
      {
        offsets[c] = static_cast<int64_t>(off->GetValue(c));
      }
      conn.resize(static_cast<size_t>(cn->GetNumberOfValues()));
      for (size_t k = 0; k < conn.size(); ++k)
      {
        conn[k] = static_cast<int64_t>(cn->GetValue(static_cast<vtkIdType>(k)));
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
  }
  else
  {
    conn.reserve(static_cast<size_t>(nc) * 4);
    vtkNew<vtkIdList> ids;
    for (vtkIdType c = 0; c < nc; ++c)
    {
      types[c] = static_cast<uint8_t>(ds->GetCellType(c));
      ds->GetCellPoints(c, ids);
      for (vtkIdType k = 0; k < ids->GetNumberOfIds(); ++k)
      {
        conn.push_back(ids->GetId(k));
      }
      offsets[c + 1] = static_cast<int64_t>(conn.size());
    }
  }
  double progress = 0.2; // a locator is no algorithm: progress goes out as an event
  this->InvokeEvent(vtkCommand::ProgressEvent, &progress);
  mtree::BuildOptions opt;
  opt.kind = this->TreeType == KDTREE ? mtree::TreeKind::RegularKd : mtree::TreeKind::Octree;
  opt.height = this->Height;
  opt.blockEdge = this->BlockSize;
  opt.leafScale = this->LeafScale;
  opt.overlap = this->ExactOverlap ? mtree::OverlapMode::Exact : mtree::OverlapMode::BoundingBox;
  opt.maxCandidates = this->MaxCandidates;
  opt.threads = this->NumberOfThreads;
  try
  {
    in.Cells = mtree::CellSet(std::move(pts), std::move(offsets), std::move(conn), std::move(types));
    mtree::MatrixTreeBuilder<mtree::CellSet>::build(in.Cells, opt, in.Tree, &in.Stats);
  }
  catch (const std::exception& e)
  {
    vtkErrorMacro("BuildLocator failed: " << e.what());
    return;
  }
  in.CellBounds.resize(static_cast<size_t>(nc) * 6);
  std::fill(in.MaxCellExtent, in.MaxCellExtent + 3, 0.0);
  for (vtkIdType c = 0; c < nc; ++c)
  {
    const mtree::Box bb = in.Cells.bounds(c);
    for (int a = 0; a < 3; ++a)
    {
      in.CellBounds[6 * c + 2 * a] = bb.lo[a];
      in.CellBounds[6 * c + 2 * a + 1] = bb.hi[a];
      in.MaxCellExtent[a] = std::max(in.MaxCellExtent[a], bb.hi[a] - bb.lo[a]);
    }
  }
  in.Valid = true;
  this->BuildTime.Modified();
  progress = 1.0;
  this->InvokeEvent(vtkCommand::ProgressEvent, &progress);
}

void vtkMatrixTreeLocator::FreeSearchStructure()
{
  delete this->Internals;
  this->Internals = new vtkMatrixTreeLocatorInternals;
}

//------------------------------------------------------------------------------
bool vtkMatrixTreeLocator::InsideCellBounds(double x[3], vtkIdType cellId)
{
  if (!this->EnsureBuilt() || cellId < 0 || cellId >= static_cast<vtkIdType>(this->Internals->Cells.size()))
  {
    return false;
  }
  const double* b = &this->Internals->CellBounds[6 * cellId];
  return x[0] >= b[0] && x[0] <= b[1] && x[1] >= b[2] && x[1] <= b[3] && x[2] >= b[4] && x[2] <= b[5];
}

//------------------------------------------------------------------------------
vtkIdType vtkMatrixTreeLocator::FindCell(
  double x[3], double vtkNotUsed(tol2), vtkGenericCell* cell, double pcoords[3], double* weights)
{
  int subId = 0;
  if (!this->EnsureBuilt())
  {
    return -1;
  }
  const vtkMatrixTreeLocatorInternals& in = *this->Internals;
  const mtree::NodeRef n = in.Tree.leafFind(mtree::Vec3(x));
  if (!n.exists)
  {
    return -1;
  }
  const MtLeafRange r = in.Tree.leafRange(n);
  const uint32_t* ids = in.Tree.primitiveIndices().data();
  double closest[3], dist2;
  for (uint32_t k = r.begin; k < r.end; ++k)
  {
    const vtkIdType id = ids[k];
    // Cell bounds first, padded by 1e-3 of the cell's size: EvaluatePosition accepts points a
    // little outside in parametric space, and the bounds test must not reject them.
    const double* b = &in.CellBounds[6 * id];
    const double pad = 1e-3 * std::max({ b[1] - b[0], b[3] - b[2], b[5] - b[4] });
    if (x[0] < b[0] - pad || x[0] > b[1] + pad || x[1] < b[2] - pad || x[1] > b[3] + pad ||
      x[2] < b[4] - pad || x[2] > b[5] + pad)
    {
      continue;
    }
    if (in.Cells.type(id) == mtree::kTetra && !in.Cells.tetraMayContain(id, mtree::Vec3(x), 0.01))
    {
      continue; // VTK accepts barycentrics within 1e-3: outside 1e-2 it surely says no
    }
    this->DataSet->GetCell(id, cell);
    if (cell->EvaluatePosition(x, closest, subId, pcoords, dist2, weights) == 1)
    {
      return id;
    }
  }
  return -1;
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
  const mtree::Vec3 o(p1), d = mtree::Vec3(p2) - mtree::Vec3(p1);
  double best = VTK_DOUBLE_MAX, tt, xx[3], pc[3];
  int sid;
  vtkIdType bestId = -1;
  // Cells span several leaves: a small direct-mapped mailbox skips most repeated tests.
  vtkIdType mailbox[64];
  std::fill(mailbox, mailbox + 64, -1);
  in.Tree.traverseRay(
    o, d, 0.0, 1.0,
    [&](const uint32_t* ids, uint32_t count, double, double tExit) {
      for (uint32_t k = 0; k < count; ++k)
      {
        const vtkIdType id = ids[k];
        vtkIdType& slot = mailbox[id & 63];
        if (slot == id)
        {
          continue;
        }
        slot = id;
        // The segment must meet the cell's bounds (padded by tol) before a cell is fetched.
        const double* cb = &in.CellBounds[6 * id];
        mtree::Box box;
        box.lo = mtree::Vec3(cb[0] - tol, cb[2] - tol, cb[4] - tol);
        box.hi = mtree::Vec3(cb[1] + tol, cb[3] + tol, cb[5] + tol);
        double t0 = 0.0, t1 = std::min(best, 1.0);
        if (!mtree::rayBox(o, d, box, t0, t1))
        {
          continue;
        }
        this->DataSet->GetCell(id, cell);
        if (cell->IntersectWithLine(p1, p2, tol, tt, xx, pc, sid) && tt < best)
        {
          best = tt;
          bestId = id;
          std::copy(xx, xx + 3, x);
          std::copy(pc, pc + 3, pcoords);
          subId = sid;
        }
      }
      return bestId >= 0 && best <= tExit;
    },
    nullptr);
  if (bestId < 0)
  {
    return 0;
  }
  t = best;
  cellId = bestId;
  this->DataSet->GetCell(bestId, cell);
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
  in.Tree.traverseRay(
    o, d, 0.0, 1.0,
    [&](const uint32_t* ids, uint32_t count, double, double) {
      for (uint32_t k = 0; k < count; ++k)
      {
        const vtkIdType id = ids[k];
        if (!seen.insert(id).second)
        {
          continue;
        }
        this->DataSet->GetCell(id, cell);
        Hit h;
        double pc[3];
        int sid;
        h.id = id;
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
        if (BoundsDistance2(x, &in.CellBounds[6 * id]) > best || !tested.insert(id).second)
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
  for (vtkIdType id : found)
  {
    const double* b = &in.CellBounds[6 * id];
    if (b[0] <= bbox[1] && b[1] >= bbox[0] && b[2] <= bbox[3] && b[3] >= bbox[2] && b[4] <= bbox[5] &&
      b[5] >= bbox[4])
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
  return in.Valid ? static_cast<vtkIdType>(in.Tree.bytes() + in.CellBounds.size() * sizeof(double)) : 0;
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
  this->SetMaxCandidates(other->MaxCandidates);
  this->SetNumberOfThreads(other->NumberOfThreads);
  this->SetUseExistingSearchStructure(other->UseExistingSearchStructure);
}

//------------------------------------------------------------------------------
void vtkMatrixTreeLocator::PrintSelf(ostream& os, vtkIndent indent)
{
  this->Superclass::PrintSelf(os, indent);
  os << indent << "TreeType: " << (this->TreeType == KDTREE ? "KDTREE" : "OCTREE") << "\n";
  os << indent << "Height: " << this->Height << (this->Height == 0 ? " (automatic)" : "") << "\n";
  os << indent << "BlockSize: " << this->BlockSize << "\n";
  os << indent << "ExactOverlap: " << (this->ExactOverlap ? "On" : "Off") << "\n";
  os << indent << "LeafScale: " << this->LeafScale << "\n";
  os << indent << "MaxCandidates: " << this->MaxCandidates << "\n";
  os << indent << "NumberOfThreads: " << this->NumberOfThreads << "\n";
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

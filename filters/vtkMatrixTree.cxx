#include "vtkMatrixTree.h"

#include "vtkMatrixTreeBackend.h"
#include "vtkMatrixTreeInternals.h"

#include "vtkDataArray.h"
#include "vtkDoubleArray.h"
#include "vtkIdTypeArray.h"
#include "vtkIntArray.h"
#include "vtkObjectFactory.h"
#include "vtkPoints.h"
#include "vtkPolyData.h"

#include "mtree/device/opencl.h"
#include "mtree/device/opencl_render.h"
#include "mtree/device/opencl_trees.h"
#include "mtree/rays/raycast.h"
#include "mtree/rays/render.h"

#include <algorithm>
#include <chrono>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

static_assert(int(vtkMatrixTree::CPU) == vtkMatrixTreeBackend::CPU &&
    int(vtkMatrixTree::OPENCL) == vtkMatrixTreeBackend::OPENCL,
  "vtkMatrixTree's Backend values are the shared ones");

// The OpenCL backend's objects: the device, the builder (its device buffers are reused by every
// rebuild), the tracer that holds the last OpenCL-built matrix tree for the queries, and the
// tracer that holds the last split tree (built on the CPU) for the rays.
struct vtkMatrixTreeOpenCL
{
  vtkMatrixTreeDevice Device;
  std::unique_ptr<mtree::ocl::Builder> Builder;
  std::unique_ptr<mtree::ocl::Tracer> Tracer;
  std::unique_ptr<mtree::ocl::SplitTreeTracer> SplitTracer;
  bool TreeOnDevice = false;      // Tracer holds the tree
  bool SplitTreeOnDevice = false; // SplitTracer holds the tree
  std::vector<mtree::ocl::KernelTiming> Kernels; // of the last build
};

vtkStandardNewMacro(vtkMatrixTree);
vtkCxxSetObjectMacro(vtkMatrixTree, DataSet, vtkPolyData);

//------------------------------------------------------------------------------
vtkMatrixTree::vtkMatrixTree()
  : OpenCL(new vtkMatrixTreeOpenCL)
  , Internals(new vtkMatrixTreeInternals)
{
}

//------------------------------------------------------------------------------
vtkMatrixTree::~vtkMatrixTree()
{
  this->SetDataSet(nullptr);
  this->SetOpenCLDevice(nullptr);
  delete this->OpenCL;
  delete this->Internals;
}

//------------------------------------------------------------------------------
bool vtkMatrixTree::Build()
{
  vtkMatrixTreeInternals& in = *this->Internals;
  in.Valid = false;
  if (!this->DataSet)
  {
    vtkErrorMacro("Build: no data set; call SetDataSet(polydata) first.");
    return false;
  }
  const int b = this->BlockSize;
  if (b < 1 || b > 32 || (b & (b - 1)))
  {
    vtkErrorMacro("Build: BlockSize must be a power of two in [1, 32], got " << b << ".");
    return false;
  }
  const auto t0 = std::chrono::steady_clock::now();
  std::string error;
  if (!vtkMatrixTreeConvert::ToTriangleMesh(this->DataSet, in.Mesh, in.CellOfTriangle, error))
  {
    vtkErrorMacro("Build: bad input data set: " << error << ".");
    return false;
  }
  this->ConversionTime =
    std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  mtree::BuildOptions opt;
  opt.kind = this->TreeType == KDTREE ? mtree::TreeKind::RegularKd : mtree::TreeKind::Octree;
  opt.height = this->Height;
  opt.blockEdge = this->BlockSize;
  opt.overlap = this->ExactOverlap ? mtree::OverlapMode::Exact : mtree::OverlapMode::BoundingBox;
  opt.leafScale = this->TreeType == HYBRID ? this->HybridLeafScale : this->LeafScale;
  opt.threads = this->NumberOfThreads;
  in.Type = this->TreeType;
  vtkMatrixTreeOpenCL& cl = *this->OpenCL;
  cl.TreeOnDevice = false;
  cl.SplitTreeOnDevice = false;
  cl.Kernels.clear();
  if (this->Backend == OPENCL && in.IsHybrid())
  {
    vtkErrorMacro("Build: the hybrid tree has no OpenCL traversal; use the CPU backend.");
    return false;
  }
  try
  {
    if (this->Backend == OPENCL)
    {
      if (cl.Device.Acquire(this->OpenCLDevice) || !cl.Builder || !cl.Tracer || !cl.SplitTracer)
      {
        cl.Builder.reset(new mtree::ocl::Builder(cl.Device.GetContext()));
        cl.Tracer.reset(new mtree::ocl::Tracer(cl.Device.GetContext()));
        cl.SplitTracer.reset(new mtree::ocl::SplitTreeTracer(cl.Device.GetContext()));
      }
    }
    if (in.IsSplit() || in.IsHybrid())
    {
      vtkMatrixTreeSplitTrees::Build(in, this->Height, opt);
      if (this->Backend == OPENCL)
      {
        cl.SplitTracer->upload(in.Split, in.Mesh);
        cl.SplitTreeOnDevice = true;
      }
    }
    else
    {
      in.Split = mtree::ImplicitSplitTree();
      in.Hybrid = mtree::HybridTree();
      in.PointerBytes = 0;
      if (this->Backend == OPENCL)
      {
        cl.Builder->build(in.Mesh, opt, in.Tree, &in.Stats, &cl.Kernels);
        cl.Tracer->upload(in.Tree, in.Mesh);
        cl.TreeOnDevice = true;
      }
      else
      {
        mtree::MatrixTreeBuilder<mtree::TriangleMesh>::build(in.Mesh, opt, in.Tree, &in.Stats);
      }
    }
    // The matrix trees' leaf triangles are part of the build: timed with it (a "leaf triangles"
    // phase). The split trees and the hybrid test the mesh's triangles through the ids.
    in.Payload.clear();
    if (this->LeafTriangles && this->Backend != OPENCL && !in.IsSplit() && !in.IsHybrid())
    {
      const auto p0 = std::chrono::steady_clock::now();
      in.Payload.build(
        in.Tree.primitiveIndices().data(), in.Tree.primitiveIndices().size(), in.Mesh, this->NumberOfThreads);
      const double ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - p0).count();
      in.Stats.phasesMs.emplace_back("leaf triangles", ms);
      in.Stats.totalMs += ms;
    }
  }
  catch (const std::exception& e)
  {
    vtkErrorMacro("Build failed (" << this->GetBackendAsString() << " backend): " << e.what());
    return false;
  }
  in.Valid = true;
  ++this->NumberOfBuilds;
  this->BuildTime.Modified();
  return true;
}

//------------------------------------------------------------------------------
bool vtkMatrixTree::BuildIfNeeded()
{
  if (this->Internals->Valid && this->DataSet && this->BuildTime > this->GetMTime() &&
    this->BuildTime > this->DataSet->GetMTime() &&
    (!this->DataSet->GetPoints() || this->BuildTime > this->DataSet->GetPoints()->GetMTime()))
  {
    return true;
  }
  return this->Build();
}

bool vtkMatrixTree::IsBuilt() const
{
  return this->Internals->Valid;
}

//------------------------------------------------------------------------------
void vtkMatrixTree::SetTuning(const vtkMatrixTreeTuning& tuning)
{
  vtkMatrixTreeTuning t = tuning;
  t.SplitTraversal = std::min(std::max(t.SplitTraversal, int(vtkMatrixTreeTuning::RESTART)),
    int(vtkMatrixTreeTuning::BACKTRACK));
  this->Internals->Tuning = t;
}

const vtkMatrixTreeTuning& vtkMatrixTree::GetTuning() const
{
  return this->Internals->Tuning;
}

//------------------------------------------------------------------------------
const char* vtkMatrixTree::GetTreeTypeAsString() const
{
  static const char* const names[] = { "octree", "kdtree", "implicit-kd", "bsp", "hybrid" };
  return names[this->TreeType];
}

//------------------------------------------------------------------------------
int vtkMatrixTree::GetTreeHeight() const
{
  const vtkMatrixTreeInternals& in = *this->Internals;
  if (!in.Valid)
  {
    return 0;
  }
  return in.IsSplit() ? in.Stats.height : in.Matrix()->height();
}
vtkIdType vtkMatrixTree::GetNumberOfTriangles() const
{
  return this->Internals->Valid ? static_cast<vtkIdType>(this->Internals->Mesh.size()) : 0;
}
vtkIdType vtkMatrixTree::GetNumberOfLeaves() const
{
  return this->Internals->Valid ? static_cast<vtkIdType>(this->Internals->Stats.leaves) : 0;
}
vtkIdType vtkMatrixTree::GetNumberOfReferences() const
{
  return this->Internals->Valid ? static_cast<vtkIdType>(this->Internals->Stats.references) : 0;
}
vtkIdType vtkMatrixTree::GetNumberOfNodes() const
{
  const vtkMatrixTreeInternals& in = *this->Internals;
  if (!in.Valid)
  {
    return 0;
  }
  if (in.IsSplit())
  {
    return static_cast<vtkIdType>(in.Split.numNodes());
  }
  const uint64_t kd = in.IsHybrid() ? in.Hybrid.kdNodes().size() : 0;
  return static_cast<vtkIdType>(vtkMatrixTreeSplitTrees::CountNodes(*in.Matrix()) + kd);
}
vtkIdType vtkMatrixTree::GetMemorySize() const
{
  const vtkMatrixTreeInternals& in = *this->Internals;
  if (!in.Valid)
  {
    return 0;
  }
  return static_cast<vtkIdType>(
    (in.IsSplit() ? in.Split.bytes() : (in.IsHybrid() ? in.Hybrid.bytes() : in.Tree.bytes())) + in.Payload.bytes());
}
vtkIdType vtkMatrixTree::GetLeafTrianglesMemorySize() const
{
  return this->Internals->Valid ? static_cast<vtkIdType>(this->Internals->Payload.bytes()) : 0;
}
vtkIdType vtkMatrixTree::GetPointerTreeMemorySize() const
{
  return this->Internals->Valid ? static_cast<vtkIdType>(this->Internals->PointerBytes) : 0;
}
namespace
{
// One level's bytes (pointer matrix and blocks) and blocks of the built tree: a matrix level of
// the matrix trees and the hybrid, a split tree's level; {0, 0} for a level it does not have.
struct LevelCost
{
  uint64_t Bytes = 0;
  uint64_t Blocks = 0;
};
LevelCost LevelCostOf(const vtkMatrixTreeInternals& in, int level, int height)
{
  if (!in.Valid || level < 0 || level > height)
  {
    return {};
  }
  if (in.IsSplit())
  {
    const auto& levels = in.Split.levelCosts().levels;
    return level < static_cast<int>(levels.size()) ? LevelCost{ levels[level].bytes, levels[level].blocks }
                                                   : LevelCost{};
  }
  return { in.Matrix()->levelBytes(level), in.Matrix()->levelBlocks(level) };
}
}

vtkIdType vtkMatrixTree::GetLevelMemorySize(int level) const
{
  return static_cast<vtkIdType>(LevelCostOf(*this->Internals, level, this->GetTreeHeight()).Bytes);
}
vtkIdType vtkMatrixTree::GetLevelNumberOfBlocks(int level) const
{
  return static_cast<vtkIdType>(LevelCostOf(*this->Internals, level, this->GetTreeHeight()).Blocks);
}
void vtkMatrixTree::GetRootBounds(double bounds[6]) const
{
  const vtkMatrixTreeInternals& in = *this->Internals;
  const bool split = in.IsSplit();
  const mtree::Box& b = split ? in.Split.rootBox() : in.Matrix()->rootBox();
  const bool ok = in.Valid && !(split ? in.Split.empty() : in.Matrix()->empty());
  for (int a = 0; a < 3; ++a)
  {
    bounds[2 * a] = ok ? b.lo[a] : 0.0;
    bounds[2 * a + 1] = ok ? b.hi[a] : -1.0;
  }
}
int vtkMatrixTree::GetLevelDimension(int level, int axis) const
{
  const vtkMatrixTreeInternals& in = *this->Internals;
  if (!in.Valid || level < 0 || level > this->GetTreeHeight() || axis < 0 || axis >= 3)
  {
    return 0;
  }
  return in.IsSplit() ? 1 << mtree::ImplicitSplitTree::logDim(level, axis) : in.Matrix()->dim(level, axis);
}
double vtkMatrixTree::GetMedianTriangleExtent() const
{
  return this->Internals->Stats.medianPrimitiveExtent;
}
int vtkMatrixTree::GetNumberOfBuildPhases() const
{
  return static_cast<int>(this->Internals->Stats.phasesMs.size());
}
const char* vtkMatrixTree::GetBuildPhaseName(int i) const
{
  const auto& p = this->Internals->Stats.phasesMs;
  return (i >= 0 && i < static_cast<int>(p.size())) ? p[i].first.c_str() : nullptr;
}
double vtkMatrixTree::GetBuildPhaseTime(int i) const
{
  const auto& p = this->Internals->Stats.phasesMs;
  return (i >= 0 && i < static_cast<int>(p.size())) ? p[i].second : 0.0;
}
double vtkMatrixTree::GetBuildTime() const
{
  return this->Internals->Stats.totalMs;
}

//------------------------------------------------------------------------------
void vtkMatrixTree::FindLeaves(vtkDataArray* points, vtkIntArray* result)
{
  if (!points || !result || points->GetNumberOfComponents() != 3)
  {
    vtkErrorMacro("FindLeaves: need an N x 3 points array and a result array.");
    return;
  }
  if (!this->BuildIfNeeded())
  {
    return;
  }
  const vtkIdType n = points->GetNumberOfTuples();
  result->SetNumberOfComponents(5);
  result->SetNumberOfTuples(n);
  const vtkMatrixTreeInternals& in = *this->Internals;
  int* out = result->GetPointer(0);
  if (this->Backend == OPENCL && this->OpenCL->TreeOnDevice)
  {
    std::vector<double> p(3 * static_cast<size_t>(n));
    for (vtkIdType i = 0; i < n; ++i)
    {
      points->GetTuple(i, &p[3 * i]);
    }
    try
    {
      this->OpenCL->Tracer->findLeaves(p.data(), static_cast<size_t>(n), out);
    }
    catch (const std::exception& e)
    {
      vtkErrorMacro("FindLeaves (opencl backend): " << e.what());
      result->SetNumberOfTuples(0);
    }
    return;
  }
  const int threads = mtree::resolveThreads(this->NumberOfThreads);
  const mtree::MatrixTree* matrix = in.Matrix();
#pragma omp parallel for num_threads(threads) schedule(static) if (n > 4096)
  for (vtkIdType i = 0; i < n; ++i)
  {
    double p[3];
    points->GetTuple(i, p);
    int* o = out + 5 * i;
    if (matrix)
    {
      const mtree::NodeRef r = matrix->leafFind(mtree::Vec3(p));
      o[0] = r.level;
      o[1] = r.c[0];
      o[2] = r.c[1];
      o[3] = r.c[2];
      o[4] = r.exists ? 1 : 0;
    }
    else
    {
      const uint32_t w = in.Split.leafFind(mtree::Vec3(p), o[0], o + 1);
      o[4] = o[0] >= 0 && w != mtree::ImplicitSplitTree::kEmpty ? 1 : 0;
    }
  }
}

//------------------------------------------------------------------------------
vtkIdType vtkMatrixTree::IntersectRays(vtkDataArray* origins, vtkDataArray* directions, double tMax,
  vtkDoubleArray* t, vtkIdTypeArray* cellIds)
{
  if (!origins || !directions || !t || !cellIds || origins->GetNumberOfComponents() != 3 ||
    directions->GetNumberOfComponents() != 3 ||
    origins->GetNumberOfTuples() != directions->GetNumberOfTuples())
  {
    vtkErrorMacro("IntersectRays: need N x 3 origins and directions of the same length, and output arrays.");
    return 0;
  }
  if (!this->BuildIfNeeded())
  {
    return 0;
  }
  const vtkIdType n = origins->GetNumberOfTuples();
  t->SetNumberOfComponents(1);
  t->SetNumberOfTuples(n);
  cellIds->SetNumberOfComponents(1);
  cellIds->SetNumberOfTuples(n);
  const vtkMatrixTreeInternals& in = *this->Internals;
  double* tOut = t->GetPointer(0);
  vtkIdType* cOut = cellIds->GetPointer(0);
  vtkIdType hits = 0, visits = 0, tests = 0;
  vtkMatrixTreeOpenCL& cl = *this->OpenCL;
  if (this->Backend == OPENCL && (cl.TreeOnDevice || cl.SplitTreeOnDevice))
  {
    const size_t m = static_cast<size_t>(n);
    std::vector<double> o(3 * m), d(3 * m);
    for (vtkIdType i = 0; i < n; ++i)
    {
      origins->GetTuple(i, &o[3 * i]);
      directions->GetTuple(i, &d[3 * i]);
    }
    std::vector<uint32_t> prim(m);
    uint64_t v = 0, c = 0;
    try
    {
      if (cl.SplitTreeOnDevice)
      {
        cl.SplitTracer->intersectFirst(o.data(), d.data(), m, 0.0, tMax, tOut, prim.data(), &v, &c);
      }
      else
      {
        cl.Tracer->intersectFirst(o.data(), d.data(), m, 0.0, tMax, tOut, prim.data(), &v, &c);
      }
    }
    catch (const std::exception& e)
    {
      vtkErrorMacro("IntersectRays (opencl backend): " << e.what());
      return 0;
    }
    for (size_t i = 0; i < m; ++i)
    {
      cOut[i] = prim[i] == MT_NULL ? -1 : in.CellOfTriangle[prim[i]];
      hits += prim[i] != MT_NULL;
    }
    this->LastNodeVisits = static_cast<vtkIdType>(v);
    this->LastTriangleTests = static_cast<vtkIdType>(c);
    return hits;
  }
  // The built tree's tracer (the matrix trees: the renderer's batch walk, several rays in
  // flight, the leaf triangles' SIMD tests where kept), in chunks over the threads; counted, for
  // GetLastNodeVisits().
  const int threads = mtree::resolveThreads(this->NumberOfThreads);
  in.WithTracer(mtree::TriangleTest::MollerTrumbore, [&](const auto& tracer) {
    constexpr vtkIdType chunk = 1024;
    const vtkIdType chunks = (n + chunk - 1) / chunk;
#pragma omp parallel for num_threads(threads) schedule(dynamic, 1) reduction(+ : hits, visits, tests)
    for (vtkIdType c = 0; c < chunks; ++c)
    {
      const vtkIdType first = c * chunk, m = std::min(chunk, n - first);
      std::vector<mtree::Vec3> o(static_cast<size_t>(m)), d(static_cast<size_t>(m));
      std::vector<double> tmax(static_cast<size_t>(m), tMax);
      for (vtkIdType i = 0; i < m; ++i)
      {
        double a[3], b[3];
        origins->GetTuple(first + i, a);
        directions->GetTuple(first + i, b);
        o[i] = mtree::Vec3(a);
        d[i] = mtree::Vec3(b);
      }
      mtree::RayBatch batch;
      batch.o = o.data();
      batch.d = d.data();
      batch.tmax = tmax.data();
      batch.n = static_cast<size_t>(m);
      std::vector<mtree::RayHit> h(static_cast<size_t>(m));
      std::vector<uint32_t> v(static_cast<size_t>(m), 0), k(static_cast<size_t>(m), 0);
      mtree::detail::firstHits(tracer, batch, h.data(), mtree::RayCounters{ v.data(), k.data() });
      for (vtkIdType i = 0; i < m; ++i)
      {
        tOut[first + i] = h[i].hit() ? h[i].t : std::numeric_limits<double>::infinity();
        cOut[first + i] = h[i].hit() ? in.CellOfTriangle[h[i].prim] : -1;
        hits += h[i].hit();
        visits += v[i];
        tests += k[i];
      }
    }
  });
  this->LastNodeVisits = visits;
  this->LastTriangleTests = tests;
  return hits;
}

//------------------------------------------------------------------------------
void vtkMatrixTree::PrintSelf(ostream& os, vtkIndent indent)
{
  this->Superclass::PrintSelf(os, indent);
  os << indent << "DataSet: " << this->DataSet << "\n";
  os << indent << "TreeType: " << this->GetTreeTypeAsString() << "\n";
  os << indent << "Tuning.SplitTraversal: "
     << mtree::splitTraversalName(static_cast<mtree::SplitTraversal>(this->Internals->Tuning.SplitTraversal)) << "\n";
  os << indent << "Height: " << this->Height << (this->Height == 0 ? " (automatic)" : "") << "\n";
  os << indent << "BlockSize: " << this->BlockSize << "\n";
  os << indent << "ExactOverlap: " << (this->ExactOverlap ? "On" : "Off") << "\n";
  os << indent << "LeafScale: " << this->LeafScale << "\n";
  os << indent << "LeafTriangles: " << (this->LeafTriangles ? "On" : "Off") << "\n";
  os << indent << "HybridLeafScale: " << this->HybridLeafScale << "\n";
  os << indent << "NumberOfThreads: " << this->NumberOfThreads << "\n";
  vtkMatrixTreeBackend::Print(os, indent, this->Backend, this->OpenCLDevice, this->GetOpenCLDeviceName());
  os << indent << "ConversionTime: " << this->ConversionTime << " ms\n";
  os << indent << "LastNodeVisits: " << this->LastNodeVisits << "\n";
  os << indent << "LastTriangleTests: " << this->LastTriangleTests << "\n";
  os << indent << "Built: " << (this->Internals->Valid ? "yes" : "no") << "\n";
  if (this->Internals->Valid)
  {
    os << indent << "TreeHeight: " << this->GetTreeHeight() << "\n";
    os << indent << "NumberOfTriangles: " << this->GetNumberOfTriangles() << "\n";
    os << indent << "NumberOfLeaves: " << this->GetNumberOfLeaves() << "\n";
    os << indent << "NumberOfNodes: " << this->GetNumberOfNodes() << "\n";
    os << indent << "MemorySize: " << this->GetMemorySize() << " bytes (leaf triangles "
       << this->GetLeafTrianglesMemorySize() << ")\n";
    os << indent << "PointerTreeMemorySize: " << this->GetPointerTreeMemorySize() << " bytes\n";
    os << indent << "BuildTime: " << this->GetBuildTime() << " ms\n";
  }
}

//------------------------------------------------------------------------------
const char* vtkMatrixTree::GetOpenCLDeviceName() const
{
  return this->OpenCL->Device.GetDeviceName();
}

const char* vtkMatrixTree::GetBackendAsString() const
{
  return vtkMatrixTreeBackend::Name(this->Backend);
}

mtree::RenderResult vtkMatrixTree::Render(
  const mtree::Camera& camera, const mtree::RenderOptions& options, bool watertight)
{
  if (!this->BuildIfNeeded())
  {
    throw std::runtime_error("the tree could not be built (see the error above)");
  }
  const vtkMatrixTreeInternals& in = *this->Internals;
  mtree::Box scene;
  for (size_t i = 0; i < in.Mesh.numPoints(); ++i)
  {
    scene.extend(mtree::Vec3(&in.Mesh.points()[3 * i]));
  }
  vtkMatrixTreeOpenCL& cl = *this->OpenCL;
  if (this->Backend == OPENCL && (cl.SplitTreeOnDevice || cl.TreeOnDevice) && watertight)
  {
    // The device kernels test triangles with Moller-Trumbore alone (opencl/query.cl): refused
    // rather than traced with a test that lets rays through shared edges.
    throw std::runtime_error("the OpenCL backend has only the Moller-Trumbore triangle test; "
                             "use the CPU backend for the watertight test");
  }
  if (this->Backend == OPENCL && cl.SplitTreeOnDevice)
  {
    return mtree::renderOpenCL(*cl.SplitTracer, in.Mesh, scene, camera, options);
  }
  if (this->Backend == OPENCL && cl.TreeOnDevice)
  {
    return mtree::renderOpenCL(*cl.Tracer, in.Mesh, scene, camera, options);
  }
  const mtree::TriangleTest test = watertight ? mtree::TriangleTest::Watertight : mtree::TriangleTest::MollerTrumbore;
  return in.WithTracer(
    test, [&](const auto& tracer) { return mtree::render(tracer, in.Mesh, scene, camera, options); });
}

int vtkMatrixTree::GetNumberOfOpenCLKernels() const
{
  return static_cast<int>(this->OpenCL->Kernels.size());
}
const char* vtkMatrixTree::GetOpenCLKernelName(int i) const
{
  const auto& k = this->OpenCL->Kernels;
  return i >= 0 && i < static_cast<int>(k.size()) ? k[i].kernel.c_str() : "";
}
double vtkMatrixTree::GetOpenCLKernelTime(int i) const
{
  const auto& k = this->OpenCL->Kernels;
  return i >= 0 && i < static_cast<int>(k.size()) ? k[i].ms : 0.0;
}
int vtkMatrixTree::GetOpenCLKernelLaunches(int i) const
{
  const auto& k = this->OpenCL->Kernels;
  return i >= 0 && i < static_cast<int>(k.size()) ? k[i].launches : 0;
}

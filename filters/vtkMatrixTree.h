/**
 * @class   vtkMatrixTree
 * @brief   a matrix octree or regular kd-tree over the triangles of a vtkPolyData
 *
 * vtkMatrixTree builds the implicit, block-sparse trees of Andrysco & Tricoche ("Implicit and
 * Dynamic Trees for High Performance Rendering", 2011) over the polygons and strips of a
 * vtkPolyData (triangulated internally), with the parallel bottom-up build of their §5.1.
 * Each tree level is one block-sparse matrix, so parent, child and neighbour nodes are
 * computed rather than stored, and leaf finding is a hash plus a binary search over depth.
 *
 * Settings (defaults are what vtkProbeFilter-style NewInstance() users get):
 * - TreeType: OCTREE (default) or KDTREE (regular kd-tree, centre splits, one axis per level).
 * - Height: levels below the root; 0 (default) chooses it from the scene: the shallowest level
 *   whose nodes are at most LeafScale (default 2) times the median triangle extent.
 * - BlockSize: edge B of the B^3 blocks of every level (power of two 1..32, default 8).
 * - ExactOverlap: on (default) puts a triangle only in the leaves it really overlaps
 *   (separating-axis test); off uses its bounding box (faster build, more tests per ray).
 * - LeafTriangles: on (default) keeps, after every CPU build, a copy of the corners of every
 *   triangle the leaves reference, in leaf order (9 doubles, 72 bytes, per reference), which the
 *   ray queries test several at a time without following the ids to the mesh; off saves that
 *   memory and gives the same answers, slower (docs/bench_rays.md has the trade measured).
 * - NumberOfThreads: OpenMP threads for the build and the batched queries (0 = all).
 * - Backend: CPU (default, the OpenMP engine) or OPENCL (the build and the batched queries as
 *   OpenCL kernels, on the device OpenCLDevice selects; the same tree and the same answers).
 *   OPENCL without a device, or in a build without OpenCL, makes Build() fail with an error
 *   that says so.
 *
 * The tree is rebuilt by BuildIfNeeded() only when the data set, its points, or a setting
 * changed since the last build; Build() always rebuilds.
 *
 * Thread safety: the query methods are const on the engine tree and may run concurrently
 * after a build; Build() must not run concurrently with queries.
 *
 * @sa
 * vtkMatrixTreeRayCaster vtkStaticCellLocator vtkCellTreeLocator vtkModifiedBSPTree
 */
#ifndef vtkMatrixTree_h
#define vtkMatrixTree_h

#include "MatrixTreeFiltersModule.h" // For export macro
#include "vtkObject.h"

class vtkDataArray;
class vtkDoubleArray;
class vtkIdTypeArray;
class vtkIntArray;
class vtkPolyData;
struct vtkMatrixTreeInternals;
#ifndef __VTK_WRAP__
namespace mtree
{
namespace ocl
{
class Tracer;
}
}
#endif

class MATRIXTREEFILTERS_EXPORT vtkMatrixTree : public vtkObject
{
public:
  static vtkMatrixTree* New();
  vtkTypeMacro(vtkMatrixTree, vtkObject);
  void PrintSelf(ostream& os, vtkIndent indent) override;

  enum TreeTypes
  {
    OCTREE = 0,
    KDTREE = 1
  };

  ///@{
  /** The data set whose triangles the tree indexes. */
  virtual void SetDataSet(vtkPolyData*);
  vtkGetObjectMacro(DataSet, vtkPolyData);
  ///@}

  ///@{
  /** Tree kind: OCTREE (default) or KDTREE. */
  vtkSetClampMacro(TreeType, int, OCTREE, KDTREE);
  vtkGetMacro(TreeType, int);
  void SetTreeTypeToOctree() { this->SetTreeType(OCTREE); }
  void SetTreeTypeToKdTree() { this->SetTreeType(KDTREE); }
  ///@}

  ///@{
  /** Levels below the root, 0..63; 0 (default) = chosen from the scene. */
  vtkSetClampMacro(Height, int, 0, 63);
  vtkGetMacro(Height, int);
  ///@}

  ///@{
  /** Block edge B (power of two, 1..32; default 8). */
  vtkSetMacro(BlockSize, int);
  vtkGetMacro(BlockSize, int);
  ///@}

  ///@{
  /** Exact triangle/leaf overlap (default on) or bounding-box overlap. */
  vtkSetMacro(ExactOverlap, bool);
  vtkGetMacro(ExactOverlap, bool);
  vtkBooleanMacro(ExactOverlap, bool);
  ///@}

  ///@{
  /** Automatic height: target leaf extent in median triangle extents (default 2, > 0). */
  vtkSetClampMacro(LeafScale, double, 1e-3, 1e3);
  vtkGetMacro(LeafScale, double);
  ///@}

  ///@{
  /** Keep the leaves' triangles in leaf order for the ray queries (default on; see above). */
  vtkSetMacro(LeafTriangles, bool);
  vtkGetMacro(LeafTriangles, bool);
  vtkBooleanMacro(LeafTriangles, bool);
  ///@}

  enum Backends
  {
    CPU = 0,
    OPENCL = 1
  };

  ///@{
  /** Where the build and the batched queries run: CPU (default) or OPENCL. */
  vtkSetClampMacro(Backend, int, CPU, OPENCL);
  vtkGetMacro(Backend, int);
  void SetBackendToCPU() { this->SetBackend(CPU); }
  void SetBackendToOpenCL() { this->SetBackend(OPENCL); }
  const char* GetBackendAsString() const;
  ///@}

  ///@{
  /**
   * OpenCL device selector (default empty: $MATRIXTREE_OPENCL_DEVICE, else the first GPU, else
   * the first device): "P:D" (platform and device index), "N" (N-th device), or part of the
   * platform or device name.
   */
  vtkSetStringMacro(OpenCLDevice);
  vtkGetStringMacro(OpenCLDevice);
  ///@}

  /** Name of the OpenCL device of the last OpenCL build ("" if none). */
  const char* GetOpenCLDeviceName() const;

  ///@{
  /**
   * Device time of every kernel of the last OpenCL build (profiling events, summed over the
   * kernel's launches; "(upload)", "(download)", "(fill)" are the transfers). Empty on the CPU.
   */
  int GetNumberOfOpenCLKernels() const;
  const char* GetOpenCLKernelName(int i) const;
  double GetOpenCLKernelTime(int i) const;
  int GetOpenCLKernelLaunches(int i) const;
  ///@}

  ///@{
  /** OpenMP threads for build and batched queries; 0 (default) = all. */
  vtkSetClampMacro(NumberOfThreads, int, 0, 4096);
  vtkGetMacro(NumberOfThreads, int);
  ///@}

  /** Builds the tree now. Returns false (with an error message) on bad input or settings. */
  bool Build();
  /** Builds only if the data set or a setting changed since the last build. */
  bool BuildIfNeeded();
  /** Number of successful builds so far (BuildIfNeeded() that reused the tree does not count). */
  vtkGetMacro(NumberOfBuilds, vtkIdType);
  /** True after a successful build. */
  bool IsBuilt() const;

  ///@{
  /** Results of the last build. */
  int GetTreeHeight() const;
  vtkIdType GetNumberOfTriangles() const;
  vtkIdType GetNumberOfLeaves() const;
  vtkIdType GetNumberOfReferences() const;
  /**
   * Bytes of the tree: every level's pointer matrix and blocks, the triangle indices, the ray
   * walk's caches (the leaf occupancy bits, the dense upper-level bits, the step table and its
   * empty boxes), and the leaf triangles (LeafTriangles; GetLeafTrianglesMemorySize() alone).
   * GetLevelMemorySize(level) is one level's pointer matrix and blocks alone.
   */
  vtkIdType GetMemorySize() const;
  vtkIdType GetLeafTrianglesMemorySize() const;
  vtkIdType GetLevelMemorySize(int level) const;
  vtkIdType GetLevelNumberOfBlocks(int level) const;
  /** The root box (xmin, xmax, ymin, ymax, zmin, zmax): the triangles' bounds, slightly padded. */
  void GetRootBounds(double bounds[6]) const;
  /** Nodes along `axis` at `level`. */
  int GetLevelDimension(int level, int axis) const;
  double GetMedianTriangleExtent() const;
  int GetNumberOfBuildPhases() const;
  const char* GetBuildPhaseName(int i) const;
  double GetBuildPhaseTime(int i) const;
  /** Total build time in milliseconds (excluding the VTK to engine conversion). */
  double GetBuildTime() const;
  /** Milliseconds spent converting the vtkPolyData to the engine's triangle arrays. */
  vtkGetMacro(ConversionTime, double);
  ///@}

  /**
   * Leaf finding for many points (N x 3 array). `result` gets N tuples of 5 ints:
   * level, i, j, k (node coordinates in that level), exists (1 for an existing leaf, 0 for the
   * largest empty node containing the point); level is -1 for points outside the tree.
   */
  void FindLeaves(vtkDataArray* points, vtkIntArray* result);

  /**
   * First hits of many rays o + t d, t in [0, tMax] (N x 3 origins and directions).
   * `t` gets the hit distance (in units of |d|; inf on a miss), `cellIds` the hit polydata cell
   * (-1 on a miss). Returns the number of hits. Node visits and triangle tests are summed in
   * GetLastNodeVisits() / GetLastTriangleTests().
   */
  vtkIdType IntersectRays(vtkDataArray* origins, vtkDataArray* directions, double tMax, vtkDoubleArray* t,
    vtkIdTypeArray* cellIds);

  ///@{
  /** Counters of the last batched query. */
  vtkGetMacro(LastNodeVisits, vtkIdType);
  vtkGetMacro(LastTriangleTests, vtkIdType);
  ///@}

#ifndef __VTK_WRAP__
  /** The engine objects (for the module's other classes; not wrapped). */
  vtkMatrixTreeInternals* GetInternals() { return this->Internals; }
  /** The OpenCL tracer holding the last OpenCL build's tree (nullptr for the CPU backend). */
  mtree::ocl::Tracer* GetOpenCLTracer();
#endif

protected:
  vtkMatrixTree();
  ~vtkMatrixTree() override;

  vtkPolyData* DataSet = nullptr;
  int TreeType = OCTREE;
  int Height = 0;
  int BlockSize = 8;
  bool ExactOverlap = true;
  double LeafScale = 2.0;
  bool LeafTriangles = true;
  int NumberOfThreads = 0;
  int Backend = CPU;
  char* OpenCLDevice = nullptr;
  struct vtkMatrixTreeOpenCL* OpenCL;
  double ConversionTime = 0;
  vtkIdType LastNodeVisits = 0;
  vtkIdType LastTriangleTests = 0;
  vtkIdType NumberOfBuilds = 0;
  vtkTimeStamp BuildTime;
  vtkMatrixTreeInternals* Internals;

private:
  vtkMatrixTree(const vtkMatrixTree&) = delete;
  void operator=(const vtkMatrixTree&) = delete;
};

#endif

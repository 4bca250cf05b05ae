/**
 * @class   vtkMatrixTree
 * @brief   a matrix octree or kd-tree, an implicit general kd-tree or BSP tree, or the hybrid
 *          matrix/SAH tree over the triangles of a vtkPolyData
 *
 * vtkMatrixTree builds the implicit, block-sparse trees of Andrysco & Tricoche ("Implicit and
 * Dynamic Trees for High Performance Rendering", 2011) over the polygons and strips of a
 * vtkPolyData (triangulated internally). Each tree level is one block-sparse matrix, so parent,
 * child and neighbour nodes are computed rather than stored. Tree types:
 * - OCTREE (default), KDTREE: the matrix trees (§3), regular splits (KDTREE: centre splits, one
 *   axis per level), built by the parallel bottom-up build of §5.1; leaf finding is a hash plus a
 *   binary search over depth. The fastest to build: the choice for meshes that change every frame.
 * - IMPLICIT_KDTREE: a general kd-tree (§4.1) with the splits of a surface-area-heuristic kd-tree
 *   (Wald & Havran's build, single threaded), stored in the same per-level matrices: 4 bytes a
 *   node, no child pointers. It renders slower than the same tree with 8-byte pointer nodes and
 *   its sparse deep levels take more bytes than they do (GetPointerTreeMemorySize()).
 * - BSP_TREE: an implicit BSP tree (§4.2), planes from the 13 directions of a 26-DOP chosen by
 *   the SAH, in the same layout: fewer triangle tests than axis planes, a much slower build
 *   (seconds per 10^4 triangles, single threaded).
 * - HYBRID: the hybrid of §7: a matrix octree with larger leaves (HybridLeafScale) and a small
 *   binned-SAH kd-tree in every occupied leaf with more than 8 triangles: a build between the
 *   octree's and the SAH tree's.
 * docs/trees.md measures the last three against the matrix trees and a pointer SAH kd-tree.
 *
 * Settings (defaults are what vtkProbeFilter-style NewInstance() users get):
 * - TreeType: as above.
 * - Height: matrix trees and the hybrid's matrix part: levels below the root; 0 (default)
 *   chooses it from the scene: the shallowest level whose nodes are at most LeafScale (default 2;
 *   the hybrid: HybridLeafScale, default 4) times the median triangle extent. IMPLICIT_KDTREE and
 *   BSP_TREE: the depth limit of their build (0 = round(8 + 1.3 log2 N); deeper than 46 levels
 *   makes Build() fail).
 * - BlockSize: edge B of the B^3 blocks of every matrix level (power of two 1..32, default 8).
 *   IMPLICIT_KDTREE and BSP_TREE take, per level, the block shape of least bytes instead.
 * - ExactOverlap: on (default) puts a triangle only in the leaves it really overlaps
 *   (separating-axis test); off uses its bounding box (faster build, more tests per ray). Matrix
 *   trees and the hybrid's matrix part.
 * - LeafTriangles: matrix trees on the CPU backend: on (default) keeps, after every build, a copy
 *   of the corners of every triangle the leaves reference, in leaf order (9 doubles, 72 bytes,
 *   per reference), which the ray queries test several at a time without following the ids to
 *   the mesh; off saves that memory and gives the same answers, slower (docs/bench_rays.md has
 *   the trade measured).
 * - NumberOfThreads: OpenMP threads for the build and the batched queries (0 = all). The SAH
 *   and BSP builds run on one thread; the hybrid builds its leaves' kd-trees in parallel.
 * - Backend: CPU (default, the OpenMP engine) or OPENCL (the build and the batched queries as
 *   OpenCL kernels, on the device OpenCLDevice selects; the same tree and the same answers).
 *   OPENCL without a device, or in a build without OpenCL, makes Build() fail with an error
 *   that says so. IMPLICIT_KDTREE and BSP_TREE are built on the CPU and their rays traced on the
 *   device by the stackless walk with derived parents (the same hits as the CPU's), points
 *   located on the CPU; HYBRID has no OpenCL traversal: OPENCL makes Build() fail.
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
struct Camera;
struct RenderOptions;
struct RenderResult;
}
struct vtkMatrixTreeTuning;
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
    KDTREE = 1,
    IMPLICIT_KDTREE = 2,
    BSP_TREE = 3,
    HYBRID = 4
  };

  ///@{
  /** The data set whose triangles the tree indexes. */
  virtual void SetDataSet(vtkPolyData*);
  vtkGetObjectMacro(DataSet, vtkPolyData);
  ///@}

  ///@{
  /** Tree kind: OCTREE (default), KDTREE, IMPLICIT_KDTREE, BSP_TREE or HYBRID. */
  vtkSetClampMacro(TreeType, int, OCTREE, HYBRID);
  vtkGetMacro(TreeType, int);
  void SetTreeTypeToOctree() { this->SetTreeType(OCTREE); }
  void SetTreeTypeToKdTree() { this->SetTreeType(KDTREE); }
  void SetTreeTypeToImplicitKdTree() { this->SetTreeType(IMPLICIT_KDTREE); }
  void SetTreeTypeToBSPTree() { this->SetTreeType(BSP_TREE); }
  void SetTreeTypeToHybrid() { this->SetTreeType(HYBRID); }
  /** "octree", "kdtree", "implicit-kd", "bsp" or "hybrid". */
  const char* GetTreeTypeAsString() const;
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

  ///@{
  /**
   * HYBRID: LeafScale of its matrix part (default 4: leaves one octree level above the matrix
   * trees', left to the kd-trees).
   */
  vtkSetClampMacro(HybridLeafScale, double, 1e-3, 1e3);
  vtkGetMacro(HybridLeafScale, double);
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
  /**
   * Results of the last build. The level getters describe the matrix levels: of the matrix
   * trees, of the split trees (level l is a 2^lx x 2^ly x 2^lz matrix) and of the hybrid's matrix
   * part (its kd-trees lie below its leaves). GetTreeHeight() is the deepest of those levels.
   */
  int GetTreeHeight() const;
  vtkIdType GetNumberOfTriangles() const;
  /** Leaves holding triangles (the hybrid: its kd leaves and its matrix leaves without a kd-tree). */
  vtkIdType GetNumberOfLeaves() const;
  /** (leaf, triangle) pairs stored (the hybrid: its matrix leaves' and its kd leaves'). */
  vtkIdType GetNumberOfReferences() const;
  /**
   * Nodes of the tree: the existing nodes of every matrix level (counted when asked), a split
   * tree's inner nodes and leaves (empty leaves included), the hybrid's matrix nodes plus its kd
   * nodes.
   */
  vtkIdType GetNumberOfNodes() const;
  /**
   * Bytes of the tree: every level's pointer matrix and blocks, the triangle indices, and the
   * ray walk's caches (the leaf occupancy bits, the dense upper-level bits, the step table and its
   * empty boxes) and the leaf triangles (LeafTriangles; GetLeafTrianglesMemorySize() alone);
   * a split tree's levels, leaf table and triangle indices; the hybrid's matrix tree, its table of
   * kd roots, its kd nodes (8 bytes each) and their triangle indices.
   * GetLevelMemorySize(level) is one level's pointer matrix and blocks alone.
   */
  vtkIdType GetMemorySize() const;
  vtkIdType GetLeafTrianglesMemorySize() const;
  vtkIdType GetLevelMemorySize(int level) const;
  vtkIdType GetLevelNumberOfBlocks(int level) const;
  /**
   * IMPLICIT_KDTREE, BSP_TREE: the bytes of the same tree as pointer nodes (8 bytes a node, as
   * SahKdTree's, plus the same triangle indices): what the implicit layout's storage claim (§4.1)
   * is measured against. 0 for the other types.
   */
  vtkIdType GetPointerTreeMemorySize() const;
  /** The root box (xmin, xmax, ymin, ymax, zmin, zmax): the triangles' bounds, slightly padded. */
  void GetRootBounds(double bounds[6]) const;
  /** Nodes along `axis` at `level`. */
  int GetLevelDimension(int level, int axis) const;
  /** Matrix trees and the hybrid (their automatic height); 0 for IMPLICIT_KDTREE and BSP_TREE. */
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
   * IMPLICIT_KDTREE, BSP_TREE: the leaf on the point's side of every plane (the left side for a
   * point on a plane), exists 0 for an empty leaf; HYBRID: its matrix part's answer.
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
  /**
   * Renders the mesh of the last build through its tree (mtree/rays/render.h): on the CPU through
   * the tree's tracer (the Moller-Trumbore or the watertight triangle test), with the OPENCL
   * backend on the device (renderOpenCL, Moller-Trumbore only: watertight with it throws; per-pixel
   * counters 0). Builds if needed; throws std::runtime_error when the tree cannot be built, and
   * the engine's errors.
   */
  mtree::RenderResult Render(const mtree::Camera& camera, const mtree::RenderOptions& options, bool watertight);
  ///@{
  /**
   * Developer settings for tests and benchmarks (vtkMatrixTreeTuning.h, C++ only): alternatives
   * to the production path that give the same answers. Default: the production path. Query
   * settings: a change does not rebuild the tree.
   */
  void SetTuning(const vtkMatrixTreeTuning& tuning);
  const vtkMatrixTreeTuning& GetTuning() const;
  ///@}
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
  double HybridLeafScale = 4.0;
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

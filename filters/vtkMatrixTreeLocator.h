/**
 * @class   vtkMatrixTreeLocator
 * @brief   a cell locator on an implicit, block-sparse matrix tree (octree or regular kd-tree)
 *
 * vtkMatrixTreeLocator indexes the cells of any vtkDataSet (unstructured grids with tetrahedra,
 * hexahedra, wedges, pyramids, voxels or mixed cells; polydata; quadratic cells) in a matrix
 * tree (Andrysco & Tricoche 2011): every level is a block-sparse matrix, built bottom-up in
 * parallel, so finding the leaf that contains a point is a hash plus a binary search over depth.
 * A cell is put in every leaf it overlaps: exactly (separating-axis test) for linear cells,
 * through its bounding box (padded 5%) for higher-order ones, so the leaf containing a point
 * lists every cell that can contain it.
 *
 * Answers are VTK's: candidate cells are evaluated with the cell's own EvaluatePosition /
 * IntersectWithLine, with the usual tolerance semantics, so results match vtkCellLocator and
 * vtkStaticCellLocator on the same data. Where the engine repeats VTK 9.1's arithmetic
 * (FindCell on the linear volume cells, the first-hit ray query's triangle and face tests) it
 * gives VTK's bits and asks VTK wherever a different rounding could change the answer.
 *
 * Settings: TreeType (OCTREE default, KDTREE), Height (0 = chosen from the cells' sizes),
 * BlockSize (8), NumberOfThreads for the build (0 = all). Superclass settings used:
 * UseExistingSearchStructure (keep the tree when the data set changes: the queries then answer
 * for the cells the build saw, whose arrays the locator holds; coordinates changed in place in
 * those arrays need a rebuild, since the tree and the one byte per hexahedron, wedge or pyramid
 * in which rays remember its face planes' planarity and orientation describe the old ones), LazyEvaluation
 * (build on the first query), CacheCellBounds (default off here: the cells' float bounds, 24
 * bytes per cell, are freed after the build; on keeps them for the queries that read them:
 * IntersectWithLine with a tolerance > 0, FindClosestPoint, FindCellsWithinBounds, which
 * otherwise compute them from the points, 10-30% slower; FindCell and IntersectWithLine with
 * tolerance 0 never read them); NumberOfCellsPerNode, MaxLevel, Automatic, Level and Tolerance
 * are ignored: the height rule replaces them.
 *
 * Backend: CPU (default) or OPENCL, for the batched point location FindCells only. With OPENCL
 * the tree is still built on the CPU; the first FindCells after a build copies the tree, the
 * cells and the quantized leaf boxes to the OpenCL device OpenCLDevice selects (kept until the
 * next build or a device change; GetNumberOfOpenCLUploads counts the copies), and a kernel
 * (opencl/query_cells.cl) does per point what the CPU loop does before it calls VTK: leaf find,
 * the leaf's candidates in the CPU's order with the same quantized-box rejections, and for
 * tetrahedra the containment test when its answer is certain. Every other candidate (other
 * cell types, a tetrahedron within ~1e-12 of VTK's 1e-3 tolerance) is left to the host, which
 * goes on with the CPU loop from that candidate; pcoords and weights of found cells come from
 * the host's evaluation (VTK's EvaluatePosition, or the engine's copy of it). The cell ids are therefore exactly the CPU backend's, and
 * pcoords and weights equal. The one-point FindCell overloads, and every other query, always
 * run on the CPU. OPENCL without an OpenCL device, with a selector that matches none, or in a
 * build without OpenCL makes FindCells report a VTK error naming the backend and leave empty
 * outputs (no fallback to the CPU).
 *
 * Thread safety: after the locator is built, FindCell(x, tol2, cell, pcoords, weights), the
 * IntersectWithLine overloads that take a vtkGenericCell, FindClosestPoint with a vtkGenericCell,
 * FindCellsWithinBounds and FindCellsAlongLine may be called concurrently (they only read the
 * tree). Overloads without a vtkGenericCell use an internal cell and are not thread-safe, as in
 * VTK's own locators. Building is not thread-safe, nor is FindCells with Backend OPENCL (it may
 * upload).
 *
 * @sa
 * vtkStaticCellLocator vtkCellLocator vtkCellTreeLocator vtkModifiedBSPTree vtkMatrixTree
 */
#ifndef vtkMatrixTreeLocator_h
#define vtkMatrixTreeLocator_h

#include "MatrixTreeFiltersModule.h" // For export macro
#include "vtkAbstractCellLocator.h"
#include "vtkVersionMacros.h" // For VTK_VERSION_CHECK

class vtkDataArray;
class vtkDoubleArray;
class vtkIdList;
class vtkIdTypeArray;
class vtkPoints;
class vtkGenericCell;
class vtkPolyData;
class vtkUnstructuredGrid;
class vtkMatrixTreeLocatorProcessor;
struct vtkMatrixTreeLocatorTuning;

class MATRIXTREEFILTERS_EXPORT vtkMatrixTreeLocator : public vtkAbstractCellLocator
{
public:
  static vtkMatrixTreeLocator* New();
  vtkTypeMacro(vtkMatrixTreeLocator, vtkAbstractCellLocator);
  void PrintSelf(ostream& os, vtkIndent indent) override;

  using vtkAbstractCellLocator::FindCell;
  using vtkAbstractCellLocator::FindClosestPoint;
  using vtkAbstractCellLocator::FindClosestPointWithinRadius;
  using vtkAbstractCellLocator::IntersectWithLine;

  enum TreeTypes
  {
    OCTREE = 0,
    KDTREE = 1
  };

  ///@{
  /** Tree kind: OCTREE (default) or KDTREE (regular kd-tree). */
  vtkSetClampMacro(TreeType, int, OCTREE, KDTREE);
  vtkGetMacro(TreeType, int);
  void SetTreeTypeToOctree() { this->SetTreeType(OCTREE); }
  void SetTreeTypeToKdTree() { this->SetTreeType(KDTREE); }
  ///@}

  ///@{
  /** Levels below the root, 0..63; 0 (default) = chosen from the cell sizes. */
  vtkSetClampMacro(Height, int, 0, 63);
  vtkGetMacro(Height, int);
  ///@}

  ///@{
  /**
   * Automatic height: target leaf extent in median cell extents (LeafScale), and the largest
   * mean number of candidate leaves per cell before the height steps back up (MaxCandidates).
   * 0, the default of both, chooses from the cells: 1 and 16 when any cell is 3-D (point
   * location tests every candidate of one leaf, so leaves about one cell wide), 4 and 3 when
   * none is (a surface: a triangle then lies in about 2 leaves instead of 6-10; rays, memory
   * and the build gain, see docs/bench_locators.md). Values above 0 are used as given (LeafScale
   * at least 1e-3, MaxCandidates at least 1). GetLeafScaleUsed / GetMaxCandidatesUsed: what the
   * last build used (0 before one).
   */
  vtkSetClampMacro(LeafScale, double, 0.0, 1e3);
  vtkGetMacro(LeafScale, double);
  vtkSetClampMacro(MaxCandidates, double, 0.0, 1e6);
  vtkGetMacro(MaxCandidates, double);
  double GetLeafScaleUsed();
  double GetMaxCandidatesUsed();
  ///@}

  ///@{
  /**
   * Cell/leaf overlap: the cell's bounding box (default off) or a separating-axis test per
   * candidate leaf (on: the box axes and the cell's face normals; conservative, never missing an
   * overlap). Answers are the same either way: each reference's quantized leaf box rejects the
   * extra candidates of the bounding-box overlap before a cell is read, and that build is the
   * cheaper (docs/bench_locators.md, "Bounding-box overlap by default").
   */
  vtkSetMacro(ExactOverlap, bool);
  vtkGetMacro(ExactOverlap, bool);
  vtkBooleanMacro(ExactOverlap, bool);
  ///@}

  ///@{
  /** Block edge of the block-sparse levels (power of two 1..32, default 8). */
  vtkSetMacro(BlockSize, int);
  vtkGetMacro(BlockSize, int);
  ///@}

  ///@{
  /**
   * OpenMP threads for the build and the batched queries (0, default: all for queries; for the
   * build one per 1024 cells, up to all).
   */
  vtkSetClampMacro(NumberOfThreads, int, 0, 4096);
  vtkGetMacro(NumberOfThreads, int);
  ///@}

  enum Backends
  {
    CPU = 0,
    OPENCL = 1
  };

  ///@{
  /**
   * Where FindCells locates the points: CPU (default, OpenMP) or OPENCL (see the class
   * description). Changing it does not rebuild the tree.
   */
  vtkSetClampMacro(Backend, int, CPU, OPENCL);
  vtkGetMacro(Backend, int);
  void SetBackendToCPU() { this->SetBackend(CPU); }
  void SetBackendToOpenCL() { this->SetBackend(OPENCL); }
  const char* GetBackendAsString() const;
  ///@}

  ///@{
  /**
   * OpenCL device selector (default empty: $MATRIXTREE_OPENCL_DEVICE, else the first GPU, else
   * the first device; "P:D" = device D of platform P; "N" = the N-th device; other text = the
   * first device whose name contains it). Used only with Backend OPENCL.
   */
  vtkSetStringMacro(OpenCLDevice);
  vtkGetStringMacro(OpenCLDevice);
  ///@}

  /** Name of the OpenCL device of the last OpenCL FindCells ("" if none). */
  const char* GetOpenCLDeviceName();
  /** Times the tree and cells were copied to an OpenCL device (once per build and device). */
  vtkGetMacro(NumberOfOpenCLUploads, vtkIdType);

  ///@{
  /**
   * Of the last FindCells with Backend OPENCL: the points the host finished from where the
   * device stopped (non-tetrahedral candidates, uncertain tetrahedra), and the points where the
   * device's "found" was not confirmed by VTK's EvaluatePosition (checked when pcoords or
   * weights are asked for; then the host rescans from that candidate, so answers stay the CPU's;
   * expected 0). Milliseconds per phase ("upload ...; points ...; kernel ...; download ...;
   * host ...; total ..."; upload is 0 when the device copy was reused).
   */
  vtkGetMacro(LastNumberOfHostResumes, vtkIdType);
  vtkGetMacro(LastNumberOfUnconfirmedCells, vtkIdType);
  const char* GetLastFindCellsPhases();
  ///@}

#ifndef __VTK_WRAP__
  ///@{
  /**
   * The alternative implementations of the same answers, for tests and benchmarks (C++ only;
   * see vtkMatrixTreeLocatorTuning.h). A change of a build field (BuildSort, CellStorage)
   * rebuilds the tree on the next query; the query fields apply from the next query on.
   */
  void SetTuning(const vtkMatrixTreeLocatorTuning& tuning);
  const vtkMatrixTreeLocatorTuning& GetTuning() const;
  ///@}
#endif

  // ---- vtkLocator ----
  /** Builds the tree if the data set or a setting changed since the last build. */
  void BuildLocator() override;
  /** Builds the tree now. */
  void ForceBuildLocator();
  void FreeSearchStructure() override;
  /**
   * Boxes of the existing nodes of `level` (0 = root; a level past the height, or a negative
   * one, gives the leaves) as quads, with cell data "Level" and "NumberOfCells" (per leaf; 0 for
   * inner nodes).
   */
  void GenerateRepresentation(int level, vtkPolyData* pd) override;
  /**
   * The tree as a data set: one VTK_VOXEL per existing node of levels minLevel..maxLevel
   * (0 = root; a negative or too large maxLevel means the leaf level), with cell data
   * - "level" (int): the node's level;
   * - "occupancy" (double): for an inner node, the fraction of its children that exist; 1 for a
   *   leaf (a leaf exists only when it holds cells);
   * - "cell_count" (vtkIdType): the number of distinct cells of the data set referenced by the
   *   leaves below the node, i.e. the cells that overlap it under the build's overlap test
   *   (exact or bounding box). For a leaf it is the number of candidates a query tests.
   * Field data "tree_height" holds the height. Returns the number of nodes written (0 and an
   * empty output when the locator cannot be built).
   */
  vtkIdType GenerateNodes(int minLevel, int maxLevel, vtkUnstructuredGrid* output);

  // ---- vtkAbstractCellLocator ----
  vtkIdType FindCell(double x[3]) override { return this->Superclass::FindCell(x); }
  vtkIdType FindCell(
    double x[3], double tol2, vtkGenericCell* cell, double pcoords[3], double* weights) override;
#if VTK_VERSION_NUMBER >= VTK_VERSION_CHECK(9, 2, 0)
  vtkIdType FindCell(double x[3], double tol2, vtkGenericCell* cell, int& subId, double pcoords[3],
    double* weights) override;
#endif
  int IntersectWithLine(const double p1[3], const double p2[3], double tol, double& t, double x[3],
    double pcoords[3], int& subId, vtkIdType& cellId, vtkGenericCell* cell) override;
  int IntersectWithLine(const double p1[3], const double p2[3], double tol, double& t, double x[3],
    double pcoords[3], int& subId) override
  {
    return this->Superclass::IntersectWithLine(p1, p2, tol, t, x, pcoords, subId);
  }
  int IntersectWithLine(const double p1[3], const double p2[3], double tol, double& t, double x[3],
    double pcoords[3], int& subId, vtkIdType& cellId) override
  {
    return this->Superclass::IntersectWithLine(p1, p2, tol, t, x, pcoords, subId, cellId);
  }
  /**
   * All intersections of the segment with cells, sorted by t: `points` gets the hit points and
   * `cellIds` the cells (either may be null). Returns the number of hits (VTK's convention for
   * this overload, implemented only by vtkOBBTree, returns -1/0/+1 for closed surfaces; here a
   * count is more useful and documented).
   */
  int IntersectWithLine(
    const double p1[3], const double p2[3], vtkPoints* points, vtkIdList* cellIds) override;
  vtkIdType FindClosestPointWithinRadius(double x[3], double radius, double closestPoint[3],
    vtkGenericCell* cell, vtkIdType& cellId, int& subId, double& dist2, int& inside) override;
  void FindClosestPoint(const double x[3], double closestPoint[3], vtkGenericCell* cell,
    vtkIdType& cellId, int& subId, double& dist2) override;
  void FindCellsWithinBounds(double* bbox, vtkIdList* cells) override;
  void FindCellsAlongLine(
    const double p1[3], const double p2[3], double tolerance, vtkIdList* cells) override;
  bool InsideCellBounds(double x[3], vtkIdType cellId) override;

  ///@{
  /**
   * Batched queries, OpenMP-parallel over the inputs (NumberOfThreads; 0 = all), each answer
   * identical to the one-point call. Outputs are resized and overwritten; optional ones may be
   * nullptr. Bad input (a null or non-3-component array, mismatched lengths) is reported with
   * vtkErrorMacro and leaves the outputs empty.
   *
   * FindCells: per point, FindCell(x, 0, cell, pcoords, weights): cellIds gets the cell or -1;
   * pcoords 3 components; weights GetMaxCellSize() components (unused ones 0); for a point in no
   * cell pcoords and weights are 0. With Backend OPENCL the points are located on the device
   * (same answers; see the class description); a device failure is a VTK error and empty outputs.
   */
  void FindCells(vtkPoints* points, vtkIdTypeArray* cellIds, vtkDoubleArray* pcoords = nullptr,
    vtkDoubleArray* weights = nullptr);
  /**
   * IntersectSegments: per segment p1[i] -> p2[i], the first hit of IntersectWithLine with
   * tolerance tol: t along the segment (0..1; +inf on a miss), cellIds (-1 on a miss) and the
   * hit point (NaN on a miss).
   */
  void IntersectSegments(vtkDataArray* p1, vtkDataArray* p2, double tol, vtkDoubleArray* t,
    vtkIdTypeArray* cellIds, vtkDoubleArray* points = nullptr);
  /**
   * FindClosestPoints: per point, FindClosestPoint: the closest point on the cells, the cell
   * and the squared distance (-1, NaN and +inf for an empty data set).
   */
  void FindClosestPoints(vtkPoints* points, vtkDoubleArray* closestPoints, vtkIdTypeArray* cellIds,
    vtkDoubleArray* dist2 = nullptr);
  ///@}

  ///@{
  /** Build statistics of the last build. */
  int GetTreeHeight();
  vtkIdType GetNumberOfLeaves();
  vtkIdType GetNumberOfReferences();
  /**
   * Bytes held: the tree (pointer matrices, blocks, leaf ranges, cell index lists), the
   * engine's copy of the cells where there is one (points unless they are a float or double
   * array; 32-bit connectivity, 32-bit offsets unless every cell has the same number of points,
   * and types unless all cells have one type, where the cells are copied, see
   * vtkMatrixTreeLocatorTuning::CellStorage; float bounds with CacheCellBounds on), the
   * quantized leaf-local cell boxes (6 bytes per reference) and the ray queries' shape byte per
   * hexahedron, wedge or pyramid. The data set's arrays read in place are not counted; nor are the build's work arrays the tree keeps for the next build, nor the freed
   * large arrays the process keeps for reuse (GetCachedMemorySize).
   */
  vtkIdType GetMemorySize();
  double GetLastBuildTime();
  /**
   * Milliseconds per phase of the last build ("convert 1.2; cellset 0.8; setup ...; release
   * ...; total ..."; the tree phases depend on vtkMatrixTreeLocatorTuning::BuildSort; "release"
   * frees the cell bounds and the build's work arrays).
   */
  const char* GetBuildPhases();
  ///@}

  /**
   * Copies the settings (not the tree), Backend, OpenCLDevice and the tuning included, of
   * another locator.
   */
  void CopySettings(vtkMatrixTreeLocator* other);

  ///@{
  /**
   * The builds' large arrays (2 MiB and up) are memory mappings; freed ones are kept for reuse by
   * later builds in the process (at most 16 of them and 512 MiB), as the C library keeps freed
   * heap blocks, so that a rebuild (a deforming mesh every frame, a build after
   * FreeSearchStructure) writes into pages the process already has: no page faults, no zeroing
   * by the kernel. GetCachedMemorySize: the bytes kept, shared by every locator and tree of the
   * process. ReleaseCachedMemory: unmaps them all and returns their bytes (memory back to the
   * system after the last build). MATRIXTREE_MAP_CACHE=0 in the environment keeps none.
   */
  static vtkTypeInt64 GetCachedMemorySize();
  static vtkTypeInt64 ReleaseCachedMemory();
  ///@}

protected:
  vtkMatrixTreeLocator();
  ~vtkMatrixTreeLocator() override;

  bool NeedsBuild();
  bool EnsureBuilt();

  int TreeType = OCTREE;
  int Height = 0;
  int BlockSize = 8;
  bool ExactOverlap = false;
  double LeafScale = 0.0;
  double MaxCandidates = 0.0;
  int NumberOfThreads = 0;
  int Backend = CPU;
  char* OpenCLDevice = nullptr;
  vtkIdType NumberOfOpenCLUploads = 0;
  vtkIdType LastNumberOfHostResumes = 0;
  vtkIdType LastNumberOfUnconfirmedCells = 0;
  vtkMatrixTreeLocatorProcessor* Processor;

private:
  vtkMatrixTreeLocator(const vtkMatrixTreeLocator&) = delete;
  void operator=(const vtkMatrixTreeLocator&) = delete;
};

#endif

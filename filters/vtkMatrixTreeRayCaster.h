/**
 * @class   vtkMatrixTreeRayCaster
 * @brief   ray casts a triangle mesh through a matrix tree (or the paper's other trees) into an image
 *
 * vtkMatrixTreeRayCaster takes a vtkPolyData, builds (or reuses) a vtkMatrixTree over its
 * triangles, and casts one primary ray per pixel from a pinhole camera, plus one shadow ray per
 * hit towards a point light near the camera, with Lambert shading. OpenMP over image rows.
 *
 * The output vtkImageData (ImageSize[0] x ImageSize[1] x 1) has point arrays
 * - "RGB"            unsigned char, 3 components: the shaded image (also the active scalars);
 * - "NodeVisits"     per pixel node lookups (primary + shadow ray): the paper's Figure 1 heat map
 *                    (with Counters on; zeros otherwise);
 * - "TriangleTests"  per pixel ray/triangle tests (primary + shadow ray; with Counters on);
 * - "Depth"          primary hit distance (inf where the ray missed);
 * - "CellId"         hit polydata cell (-1 where the ray missed).
 *
 * The camera is given by Position, FocalPoint, ViewUp and ViewAngle (degrees, vertical); with
 * AutoCamera on (default) it frames the input's bounds from the +z side, tilted.
 * The tree settings are those of GetTree() (octree, automatic height by default). The tree is
 * rebuilt only when the input or the tree settings change.
 *
 * The accelerator is selectable, so that every tree of the paper renders through the same code:
 * MATRIX_TREE (default) traces through GetTree() with its TreeType: the matrix octree or
 * kd-tree, the implicit general kd-tree or BSP tree, or the hybrid matrix/SAH tree
 * (vtkMatrixTree, docs/trees.md); SetAcceleratorToSAHKdTree() traces
 * through the baseline, a surface-area-heuristic kd-tree (Wald & Havran's O(N log N) build,
 * 8-byte pointer nodes) with the traversal SAHTraversal (KD-Restart, a full stack, or a short
 * stack of ShortStackSize entries). TriangleTest picks Moller-Trumbore (default) or the
 * watertight test of Woop, Benthin & Wald for either accelerator.
 *
 * @sa
 * vtkMatrixTree
 */
#ifndef vtkMatrixTreeRayCaster_h
#define vtkMatrixTreeRayCaster_h

#include "MatrixTreeFiltersModule.h" // For export macro
#include "vtkImageAlgorithm.h"

class vtkMatrixTree;

class MATRIXTREEFILTERS_EXPORT vtkMatrixTreeRayCaster : public vtkImageAlgorithm
{
public:
  static vtkMatrixTreeRayCaster* New();
  vtkTypeMacro(vtkMatrixTreeRayCaster, vtkImageAlgorithm);
  void PrintSelf(ostream& os, vtkIndent indent) override;

  /** The tree used (and its settings). Never null. */
  vtkGetObjectMacro(Tree, vtkMatrixTree);

  ///@{
  /** Image width and height in pixels (default 800 x 800, each 1..16384: RequestData refuses others). */
  vtkSetVector2Macro(ImageSize, int);
  vtkGetVector2Macro(ImageSize, int);
  ///@}

  ///@{
  /**
   * Pinhole camera; used when AutoCamera is off. Position and FocalPoint must be finite and
   * apart (RequestData refuses others); a ViewUp along the view direction is replaced by the y
   * (or x) axis.
   */
  vtkSetVector3Macro(Position, double);
  vtkGetVector3Macro(Position, double);
  vtkSetVector3Macro(FocalPoint, double);
  vtkGetVector3Macro(FocalPoint, double);
  vtkSetVector3Macro(ViewUp, double);
  vtkGetVector3Macro(ViewUp, double);
  vtkSetClampMacro(ViewAngle, double, 0.01, 179.0);
  vtkGetMacro(ViewAngle, double);
  ///@}

  ///@{
  /** Frame the input's bounds automatically (default on). */
  vtkSetMacro(AutoCamera, bool);
  vtkGetMacro(AutoCamera, bool);
  vtkBooleanMacro(AutoCamera, bool);
  ///@}

  ///@{
  /** One shadow ray per hit towards the light (default on). */
  vtkSetMacro(Shadows, bool);
  vtkGetMacro(Shadows, bool);
  vtkBooleanMacro(Shadows, bool);
  ///@}

  ///@{
  /**
   * Count node visits and triangle tests per pixel (default off). Off, the walks run compiled
   * without counters, and NodeVisits, TriangleTests and the totals are 0; on, the same walks
   * count as they go (a few percent slower).
   */
  vtkSetMacro(Counters, bool);
  vtkGetMacro(Counters, bool);
  vtkBooleanMacro(Counters, bool);
  ///@}

  ///@{
  /** OpenMP threads for rendering (0 = all, default). */
  vtkSetClampMacro(NumberOfThreads, int, 0, 4096);
  vtkGetMacro(NumberOfThreads, int);
  ///@}

  ///@{
  /**
   * Backend of the build and of the rays: "cpu" (default) or "opencl" (the tree's backend, see
   * vtkMatrixTree::SetBackend). With "opencl" the primary and the shadow rays are traced as two
   * batches on the device (shading stays on the host); NodeVisits and TriangleTests per pixel
   * are then 0 (only the totals are kept). No device: RequestData fails with an error.
   */
  void SetBackendToCPU();
  void SetBackendToOpenCL();
  int GetBackend();
  ///@}

  ///@{
  /**
   * Accelerator: MATRIX_TREE (default; GetTree() with its TreeType, settings and backend) or
   * SAH_KDTREE (CPU only; rebuilt when the input changes; GetLastBuildTime() is then the SAH build).
   */
  enum Accelerators
  {
    MATRIX_TREE = 0,
    SAH_KDTREE = 1
  };
  vtkSetClampMacro(Accelerator, int, MATRIX_TREE, SAH_KDTREE);
  vtkGetMacro(Accelerator, int);
  void SetAcceleratorToMatrixTree() { this->SetAccelerator(MATRIX_TREE); }
  void SetAcceleratorToSAHKdTree() { this->SetAccelerator(SAH_KDTREE); }
  ///@}

  ///@{
  /** Traversal of the SAH kd-tree: RESTART (KD-Restart), STACK (default), SHORT_STACK. */
  enum SAHTraversals
  {
    RESTART = 0,
    STACK = 1,
    SHORT_STACK = 2
  };
  vtkSetClampMacro(SAHTraversal, int, RESTART, SHORT_STACK);
  vtkGetMacro(SAHTraversal, int);
  /** Entries of the short stack (default 3, the paper's setting); 0 = restarts only. */
  vtkSetClampMacro(ShortStackSize, int, 0, 64);
  vtkGetMacro(ShortStackSize, int);
  ///@}

  ///@{
  /**
   * Ray/triangle test: MOLLER_TRUMBORE (default) or WATERTIGHT (no ray slips between the
   * triangles of a closed mesh; within a few percent of the same speed on the CPU:
   * docs/speed_accuracy.md). The OpenCL backend has Moller-Trumbore only: WATERTIGHT with it
   * makes RequestData fail with an error.
   */
  enum TriangleTests
  {
    MOLLER_TRUMBORE = 0,
    WATERTIGHT = 1
  };
  vtkSetClampMacro(TriangleTest, int, MOLLER_TRUMBORE, WATERTIGHT);
  vtkGetMacro(TriangleTest, int);
  ///@}

  ///@{
  /** Statistics of the last execution. Times in milliseconds. */
  vtkGetMacro(LastBuildTime, double);
  vtkGetMacro(LastRenderTime, double);
  vtkGetMacro(LastRebuilt, bool);
  vtkGetMacro(NumberOfPrimaryRays, vtkIdType);
  vtkGetMacro(NumberOfShadowRays, vtkIdType);
  vtkGetMacro(NumberOfHits, vtkIdType);
  vtkGetMacro(TotalNodeVisits, vtkIdType);
  vtkGetMacro(TotalTriangleTests, vtkIdType);
  ///@}

  /** Includes the tree's modification time. */
  vtkMTimeType GetMTime() override;

protected:
  vtkMatrixTreeRayCaster();
  ~vtkMatrixTreeRayCaster() override;

  int FillInputPortInformation(int port, vtkInformation* info) override;
  int RequestInformation(vtkInformation*, vtkInformationVector**, vtkInformationVector*) override;
  int RequestData(vtkInformation*, vtkInformationVector**, vtkInformationVector*) override;

  vtkMatrixTree* Tree;
  struct SahState;
  SahState* Sah = nullptr;
  int Accelerator = MATRIX_TREE;
  int SAHTraversal = STACK;
  int ShortStackSize = 3;
  int TriangleTest = MOLLER_TRUMBORE;
  int ImageSize[2] = { 800, 800 };
  double Position[3] = { 0, 0, 1 };
  double FocalPoint[3] = { 0, 0, 0 };
  double ViewUp[3] = { 0, 1, 0 };
  double ViewAngle = 30.0;
  bool AutoCamera = true;
  bool Shadows = true;
  bool Counters = false;
  int NumberOfThreads = 0;
  double LastBuildTime = 0;
  double LastRenderTime = 0;
  bool LastRebuilt = false;
  vtkIdType NumberOfPrimaryRays = 0;
  vtkIdType NumberOfShadowRays = 0;
  vtkIdType NumberOfHits = 0;
  vtkIdType TotalNodeVisits = 0;
  vtkIdType TotalTriangleTests = 0;

private:
  vtkMatrixTreeRayCaster(const vtkMatrixTreeRayCaster&) = delete;
  void operator=(const vtkMatrixTreeRayCaster&) = delete;
};

#endif

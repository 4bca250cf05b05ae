/**
 * @class   vtkMatrixTreeVolumeRayCaster
 * @brief   volume ray caster (CPU or OpenCL) on a block-sparse volume with matrix-tree empty-space skipping
 *
 * vtkMatrixTreeVolumeRayCaster renders the point scalars of a vtkImageData (one component, any
 * scalar type, any spacing and origin) with a colour transfer function and a scalar opacity
 * function into an RGBA image seen from a camera. It is the volume-rendering use of the paper's
 * block-sparse matrix (Andrysco & Tricoche 2011, §3): the scalars are stored in 8^3-voxel
 * float blocks, or for 8/16-bit (and integer-valued float) scalars in 8^3-cell bricks with a
 * 1-voxel apron in their own width; other floating-point scalars are quantised into 16-bit bricks
 * (65535 steps over their range) where the lookup table is at least 16 times coarser than a step
 * (TableSize <= 4096: a sample moves by at most 1/32 of a table entry; the error bound is in
 * engine/include/mtree/volume/volume.h, VolumeBuildOptions::quantizeFloat, and GetQuantizationStep
 * reports the step), else kept in float blocks. Only what a visible sample can read is allocated (a cell is visible when
 * the opacity function is non-zero somewhere on its corners' value range); above the blocks, the
 * matrix-tree levels mark which bricks and groups of bricks hold a visible cell, and each ray
 * skips invisible nodes top-down. Skipping is exact: a sample it passes over has opacity 0.
 *
 * Per ray: samples every SampleDistance (world units) from where the ray enters the volume's
 * bounds, trilinear interpolation, post-classification through a TableSize-entry lookup table
 * (the functions sampled over the finite scalar range), opacity corrected for the step
 * (alpha' = 1 - (1 - alpha)^(SampleDistance / ScalarOpacityUnitDistance)), front-to-back
 * compositing, early termination at EarlyTerminationThreshold, optional gradient shading with
 * a headlight. OpenMP over image rows.
 *
 * Backend: CPU (default, the OpenMP marcher above) or OPENCL (mtree::ocl::VolumeRenderer, the
 * kernels of opencl/volume.cl on the device OpenCLDevice selects). The volume is classified and
 * stored on the host either way, in the same storage (float blocks or 8/16-bit apron bricks:
 * every input the CPU path accepts); the OpenCL backend copies that storage to the device as is,
 * so device memory equals AllocatedBytes (less the per-brick value ranges), and keeps the upload
 * across renders: it uploads again only when the volume is reclassified (the conditions below)
 * or the device changes (GetNumberOfOpenCLUploads counts the uploads). The device image equals
 * the CPU's: identical unshaded on PoCL, within ~1e-7 shaded (OpenCL's float sqrt, division and
 * pow are not correctly rounded). OPENCL without an OpenCL device, with a selector that matches
 * none, or in a build without OpenCL makes RequestData fail with an error saying so (empty
 * output); nothing falls back silently to the CPU.
 *
 * The output vtkImageData (ImageSize[0] x ImageSize[1] x 1, row 0 at the bottom) has point arrays
 * - "RGBA"       unsigned char, 4 components: colour composited over black, opacity (active scalars);
 * - "RGBAFloat"  float, 4 components: premultiplied colour and opacity, unquantised.
 *
 * Input handling: non-finite scalars are replaced by the lowest finite scalar; an image with fewer
 * than 2 points along an axis, no scalars, multi-component scalars, a zero spacing or no finite
 * scalar is rejected with an error (empty output). The volume is classified again only when the
 * input, its scalars, the opacity function or TableSize change; colour changes only rebuild the
 * table. The camera is perspective (ViewAngle is vertical) or parallel (ParallelScale); rays
 * start at the camera position (no near clipping). The image data's direction matrix (VTK >= 9.2)
 * is ignored: the volume is axis-aligned.
 *
 * Thread safety: one RequestData at a time per instance; rendering itself is parallel.
 *
 * @sa
 * vtkFixedPointVolumeRayCastMapper vtkMatrixTreeRayCaster vtkColorTransferFunction vtkPiecewiseFunction
 */
#ifndef vtkMatrixTreeVolumeRayCaster_h
#define vtkMatrixTreeVolumeRayCaster_h

#include "MatrixTreeFiltersModule.h" // For export macro
#include "vtkImageAlgorithm.h"

class vtkCamera;
class vtkColorTransferFunction;
class vtkPiecewiseFunction;
struct vtkMatrixTreeVolumeRayCasterInternals;
#ifndef __VTK_WRAP__
struct vtkMatrixTreeVolumeTuning;
#endif

class MATRIXTREEFILTERS_EXPORT vtkMatrixTreeVolumeRayCaster : public vtkImageAlgorithm
{
public:
  static vtkMatrixTreeVolumeRayCaster* New();
  vtkTypeMacro(vtkMatrixTreeVolumeRayCaster, vtkImageAlgorithm);
  void PrintSelf(ostream& os, vtkIndent indent) override;

  ///@{
  /**
   * Colour transfer function (default none: white) and scalar opacity function (default none:
   * a linear ramp from 0 at the lowest to 1 at the highest scalar). Opacity is per
   * ScalarOpacityUnitDistance world units (default 1, as vtkVolumeProperty).
   */
  virtual void SetColorTransferFunction(vtkColorTransferFunction*);
  vtkGetObjectMacro(ColorTransferFunction, vtkColorTransferFunction);
  virtual void SetScalarOpacity(vtkPiecewiseFunction*);
  vtkGetObjectMacro(ScalarOpacity, vtkPiecewiseFunction);
  vtkSetClampMacro(ScalarOpacityUnitDistance, double, 1e-12, 1e30);
  vtkGetMacro(ScalarOpacityUnitDistance, double);
  ///@}

  ///@{
  /** Lookup-table entries over the scalar range (default 4096, 2..65536). */
  vtkSetClampMacro(TableSize, int, 2, 65536);
  vtkGetMacro(TableSize, int);
  ///@}

  ///@{
  /** Image width and height in pixels (default 512 x 512, each 1..16384). */
  vtkSetVector2Macro(ImageSize, int);
  vtkGetVector2Macro(ImageSize, int);
  ///@}

  ///@{
  /** The camera: position, focal point, view up, vertical view angle (degrees, default 30),
   * parallel projection (default off) with ParallelScale (half the view height). */
  vtkSetVector3Macro(Position, double);
  vtkGetVector3Macro(Position, double);
  vtkSetVector3Macro(FocalPoint, double);
  vtkGetVector3Macro(FocalPoint, double);
  vtkSetVector3Macro(ViewUp, double);
  vtkGetVector3Macro(ViewUp, double);
  vtkSetClampMacro(ViewAngle, double, 0.01, 179.0);
  vtkGetMacro(ViewAngle, double);
  vtkSetMacro(ParallelProjection, bool);
  vtkGetMacro(ParallelProjection, bool);
  vtkBooleanMacro(ParallelProjection, bool);
  vtkSetClampMacro(ParallelScale, double, 1e-12, 1e30);
  vtkGetMacro(ParallelScale, double);
  ///@}

  /** Copy position, focal point, view up, view angle and the parallel settings of a vtkCamera. */
  void SetCamera(vtkCamera* camera);

  ///@{
  /**
   * Speed/accuracy controls.
   * SampleDistance: world units between samples along a ray (default 1). Halving it doubles the
   * samples; the error of the Riemann sum shrinks linearly. It must be > 0 and give at most 2^20
   * samples across the volume's diagonal: RequestData reports an error otherwise.
   * ImageSampleDistance: >1 casts ImageSize/ImageSampleDistance rays per axis and interpolates
   * bilinearly (default 1, 1..32).
   * EarlyTerminationThreshold: a ray stops when its opacity reaches it (default 0.99; 1 = never).
   * DoublePrecision: interpolate and composite in double instead of float (default off; the
   * difference is ~1e-6 per channel, the cost ~10%).
   */
  vtkSetMacro(SampleDistance, double);
  vtkGetMacro(SampleDistance, double);
  vtkSetClampMacro(ImageSampleDistance, double, 1.0, 32.0);
  vtkGetMacro(ImageSampleDistance, double);
  vtkSetClampMacro(EarlyTerminationThreshold, double, 0.0, 1.0);
  vtkGetMacro(EarlyTerminationThreshold, double);
  vtkSetMacro(DoublePrecision, bool);
  vtkGetMacro(DoublePrecision, bool);
  vtkBooleanMacro(DoublePrecision, bool);
  ///@}

  ///@{
  /** Gradient shading (default off) with a headlight: ambient (0.2), diffuse (0.7), specular
   * (0.2), specular power (10). The gradient is that of the trilinear interpolant. */
  vtkSetMacro(Shade, bool);
  vtkGetMacro(Shade, bool);
  vtkBooleanMacro(Shade, bool);
  vtkSetClampMacro(Ambient, double, 0.0, 1.0);
  vtkGetMacro(Ambient, double);
  vtkSetClampMacro(Diffuse, double, 0.0, 1.0);
  vtkGetMacro(Diffuse, double);
  vtkSetClampMacro(Specular, double, 0.0, 1.0);
  vtkGetMacro(Specular, double);
  vtkSetClampMacro(SpecularPower, double, 0.0, 128.0);
  vtkGetMacro(SpecularPower, double);
  ///@}

  enum Backends
  {
    CPU = 0,
    OPENCL = 1
  };

  ///@{
  /**
   * Where the rays are marched: CPU (default) or OPENCL (see the class description). Changing it
   * does not reclassify the volume.
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

  /** Name of the OpenCL device of the last OpenCL render ("" if none). */
  const char* GetOpenCLDeviceName() const;

  ///@{
  /** OpenMP threads (0 = all, default). */
  vtkSetClampMacro(NumberOfThreads, int, 0, 4096);
  vtkGetMacro(NumberOfThreads, int);
  ///@}

  /** Classify the volume again on the next update even if nothing changed. */
  void ForceRebuild();

  ///@{
  /**
   * Statistics of the last execution. Times in milliseconds. Blocks are 8^3 voxels;
   * VisibleBlockBytes = (8^3 float blocks holding a corner of a visible cell) * 8^3 * 4, the
   * reference of the memory target; AllocatedBytes is everything held: those blocks (float
   * storage) or the visible 9^3-voxel apron bricks in 8/16 bits with their cell masks (see
   * GetVoxelStorage), plus pointers, per-brick value ranges and the matrix-tree levels;
   * DenseBytes = voxels * 4.
   */
  vtkGetMacro(LastBuildTime, double);
  vtkGetMacro(LastRenderTime, double);
  vtkGetMacro(LastRebuilt, bool);
  vtkGetMacro(NumberOfAllocatedBlocks, vtkIdType);
  vtkGetMacro(NumberOfDenseBlocks, vtkIdType);
  vtkGetMacro(NumberOfVisibleBricks, vtkIdType);
  vtkGetMacro(NumberOfBricks, vtkIdType);
  vtkGetMacro(NumberOfLevels, int);
  vtkGetMacro(VisibleBlockBytes, vtkIdType);
  vtkGetMacro(AllocatedBytes, vtkIdType);
  vtkGetMacro(DenseBytes, vtkIdType);
  vtkGetMacro(NumberOfSamples, vtkIdType);
  vtkGetMacro(NumberOfSkips, vtkIdType);
  vtkGetMacro(NumberOfNonFiniteScalars, vtkIdType);
  /// How the voxels are held: 0 float blocks, 1 8-bit and 2 16-bit bricks with a 1-voxel apron
  /// (8/16-bit integer scalars, or float scalars that hold only integers: lossless; or
  /// floating-point scalars quantised, see QuantizationStep).
  vtkGetMacro(VoxelStorage, int);
  /// The quantisation step of floating-point scalars held in 16-bit bricks (their range / 65535),
  /// 0 where the voxels hold the scalars exactly.
  vtkGetMacro(QuantizationStep, double);
  /// Times the volume was copied to the OpenCL device (once per classification and device).
  vtkGetMacro(NumberOfOpenCLUploads, vtkIdType);
  ///@}

  /** Includes the transfer functions' modification times. */
  vtkMTimeType GetMTime() override;

#ifndef __VTK_WRAP__
  ///@{
  /**
   * Developer settings for tests and benchmarks (vtkMatrixTreeVolumeTuning.h, C++ only):
   * alternatives to the production path that give the same image. Default: the production path.
   */
  void SetTuning(const vtkMatrixTreeVolumeTuning& tuning);
  const vtkMatrixTreeVolumeTuning& GetTuning() const;
  ///@}
#endif

protected:
  vtkMatrixTreeVolumeRayCaster();
  ~vtkMatrixTreeVolumeRayCaster() override;

  int FillInputPortInformation(int port, vtkInformation* info) override;
  int RequestInformation(vtkInformation*, vtkInformationVector**, vtkInformationVector*) override;
  int RequestUpdateExtent(vtkInformation*, vtkInformationVector**, vtkInformationVector*) override;
  int RequestData(vtkInformation*, vtkInformationVector**, vtkInformationVector*) override;

  vtkColorTransferFunction* ColorTransferFunction = nullptr;
  vtkPiecewiseFunction* ScalarOpacity = nullptr;
  double ScalarOpacityUnitDistance = 1.0;
  int TableSize = 4096;
  int ImageSize[2] = { 512, 512 };
  double Position[3] = { 0, 0, 1 };
  double FocalPoint[3] = { 0, 0, 0 };
  double ViewUp[3] = { 0, 1, 0 };
  double ViewAngle = 30.0;
  bool ParallelProjection = false;
  double ParallelScale = 1.0;
  double SampleDistance = 1.0;
  double ImageSampleDistance = 1.0;
  double EarlyTerminationThreshold = 0.99;
  bool DoublePrecision = false;
  bool Shade = false;
  double Ambient = 0.2;
  double Diffuse = 0.7;
  double Specular = 0.2;
  double SpecularPower = 10.0;
  int Backend = CPU;
  char* OpenCLDevice = nullptr;
  int NumberOfThreads = 0;

  double LastBuildTime = 0;
  double LastRenderTime = 0;
  bool LastRebuilt = false;
  vtkIdType NumberOfAllocatedBlocks = 0;
  vtkIdType NumberOfDenseBlocks = 0;
  vtkIdType NumberOfVisibleBricks = 0;
  vtkIdType NumberOfBricks = 0;
  int NumberOfLevels = 0;
  vtkIdType VisibleBlockBytes = 0;
  vtkIdType AllocatedBytes = 0;
  vtkIdType DenseBytes = 0;
  vtkIdType NumberOfSamples = 0;
  vtkIdType NumberOfSkips = 0;
  vtkIdType NumberOfNonFiniteScalars = 0;
  int VoxelStorage = 0;
  double QuantizationStep = 0;
  vtkIdType NumberOfOpenCLUploads = 0;

private:
  vtkMatrixTreeVolumeRayCaster(const vtkMatrixTreeVolumeRayCaster&) = delete;
  void operator=(const vtkMatrixTreeVolumeRayCaster&) = delete;

  vtkMatrixTreeVolumeRayCasterInternals* Internals;
};

#endif

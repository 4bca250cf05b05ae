#include "vtkMatrixTreeVolumeRayCaster.h"

#include "vtkMatrixTreeBackend.h"
#include "vtkMatrixTreeChecks.h"
#include "vtkMatrixTreeVolumeTuning.h"

#include "vtkCamera.h"
#include "vtkColorTransferFunction.h"
#include "vtkDataArray.h"
#include "vtkFloatArray.h"
#include "vtkImageData.h"
#include "vtkInformation.h"
#include "vtkInformationVector.h"
#include "vtkObjectFactory.h"
#include "vtkPiecewiseFunction.h"
#include "vtkPointData.h"
#include "vtkSmartPointer.h"
#include "vtkStreamingDemandDrivenPipeline.h"
#include "vtkUnsignedCharArray.h"

#include "mtree/device/opencl.h"
#include "mtree/volume/volume.h"

#include <algorithm>
#include <cmath>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#include <exception>
#include <limits>
#include <memory>
#include <string>
#include <vector>

struct vtkMatrixTreeVolumeRayCasterInternals
{
  mtree::BlockSparseVolume Volume;
  bool Built = false;
  vtkTimeStamp BuildTime;
  vtkDataArray* Scalars = nullptr;  // identity only, never dereferenced
  vtkPiecewiseFunction* Opacity = nullptr;
  int TableSize = 0;
  bool Dense = false;  // the classification's DenseStorage
  bool Exact = false;  // the classification's ExactFloat
  vtkMatrixTreeVolumeTuning Tuning;
  double Range[2] = { 0, 1 };
  bool Force = false;

  // The OpenCL backend: the device, its renderer, and whether that holds the current
  // classification (cleared by every rebuild, so a render uploads again only after one).
  vtkMatrixTreeDevice CLDevice;
  std::unique_ptr<mtree::ocl::VolumeRenderer> CLRenderer;
  bool CLUploaded = false;

  // The output arrays, kept across renders and reused when nothing else holds them (the pipeline
  // releases the previous output's arrays before RequestData): a frame then writes into memory
  // already mapped instead of 5 fresh MB (page faults), and the CPU backend renders straight
  // into RGBAFloat.
  vtkSmartPointer<vtkFloatArray> RGBAFloat;
  vtkSmartPointer<vtkUnsignedCharArray> RGBA;
};

static_assert(int(vtkMatrixTreeVolumeRayCaster::CPU) == vtkMatrixTreeBackend::CPU &&
    int(vtkMatrixTreeVolumeRayCaster::OPENCL) == vtkMatrixTreeBackend::OPENCL,
  "vtkMatrixTreeVolumeRayCaster's Backend values are the shared ones");

vtkStandardNewMacro(vtkMatrixTreeVolumeRayCaster);
vtkCxxSetObjectMacro(vtkMatrixTreeVolumeRayCaster, ColorTransferFunction, vtkColorTransferFunction);
vtkCxxSetObjectMacro(vtkMatrixTreeVolumeRayCaster, ScalarOpacity, vtkPiecewiseFunction);

//------------------------------------------------------------------------------
vtkMatrixTreeVolumeRayCaster::vtkMatrixTreeVolumeRayCaster()
  : Internals(new vtkMatrixTreeVolumeRayCasterInternals)
{
  this->SetNumberOfInputPorts(1);
  this->SetNumberOfOutputPorts(1);
}

//------------------------------------------------------------------------------
vtkMatrixTreeVolumeRayCaster::~vtkMatrixTreeVolumeRayCaster()
{
  this->SetColorTransferFunction(nullptr);
  this->SetScalarOpacity(nullptr);
  this->SetOpenCLDevice(nullptr);
  delete this->Internals;
}

//------------------------------------------------------------------------------
const char* vtkMatrixTreeVolumeRayCaster::GetOpenCLDeviceName() const
{
  return this->Internals->CLDevice.GetDeviceName();
}

const char* vtkMatrixTreeVolumeRayCaster::GetBackendAsString() const
{
  return vtkMatrixTreeBackend::Name(this->Backend);
}

//------------------------------------------------------------------------------
void vtkMatrixTreeVolumeRayCaster::SetCamera(vtkCamera* camera)
{
  if (!camera)
  {
    vtkErrorMacro("SetCamera: null camera");
    return;
  }
  this->SetPosition(camera->GetPosition());
  this->SetFocalPoint(camera->GetFocalPoint());
  this->SetViewUp(camera->GetViewUp());
  this->SetViewAngle(camera->GetViewAngle());
  this->SetParallelProjection(camera->GetParallelProjection() != 0);
  this->SetParallelScale(camera->GetParallelScale());
}

//------------------------------------------------------------------------------
void vtkMatrixTreeVolumeRayCaster::SetTuning(const vtkMatrixTreeVolumeTuning& tuning)
{
  if (tuning != this->Internals->Tuning)
  {
    this->Internals->Tuning = tuning;
    this->Modified();
  }
}

const vtkMatrixTreeVolumeTuning& vtkMatrixTreeVolumeRayCaster::GetTuning() const
{
  return this->Internals->Tuning;
}

//------------------------------------------------------------------------------
void vtkMatrixTreeVolumeRayCaster::ForceRebuild()
{
  this->Internals->Force = true;
  this->Modified();
}

//------------------------------------------------------------------------------
vtkMTimeType vtkMatrixTreeVolumeRayCaster::GetMTime()
{
  vtkMTimeType t = this->Superclass::GetMTime();
  if (this->ColorTransferFunction)
  {
    t = std::max(t, this->ColorTransferFunction->GetMTime());
  }
  if (this->ScalarOpacity)
  {
    t = std::max(t, this->ScalarOpacity->GetMTime());
  }
  return t;
}

//------------------------------------------------------------------------------
int vtkMatrixTreeVolumeRayCaster::FillInputPortInformation(int, vtkInformation* info)
{
  info->Set(vtkAlgorithm::INPUT_REQUIRED_DATA_TYPE(), "vtkImageData");
  return 1;
}

//------------------------------------------------------------------------------
int vtkMatrixTreeVolumeRayCaster::RequestInformation(
  vtkInformation*, vtkInformationVector**, vtkInformationVector* outputVector)
{
  const int w = std::min(std::max(this->ImageSize[0], 1), 16384);
  const int h = std::min(std::max(this->ImageSize[1], 1), 16384);
  int extent[6] = { 0, w - 1, 0, h - 1, 0, 0 };
  vtkInformation* outInfo = outputVector->GetInformationObject(0);
  outInfo->Set(vtkStreamingDemandDrivenPipeline::WHOLE_EXTENT(), extent, 6);
  double spacing[3] = { 1, 1, 1 }, origin[3] = { 0, 0, 0 };
  outInfo->Set(vtkDataObject::SPACING(), spacing, 3);
  outInfo->Set(vtkDataObject::ORIGIN(), origin, 3);
  vtkDataObject::SetPointDataActiveScalarInfo(outInfo, VTK_UNSIGNED_CHAR, 4);
  return 1;
}

//------------------------------------------------------------------------------
int vtkMatrixTreeVolumeRayCaster::RequestUpdateExtent(
  vtkInformation*, vtkInformationVector** inputVector, vtkInformationVector*)
{
  // The output is an image of the camera, not a piece of the input: always ask for all of it.
  vtkInformation* inInfo = inputVector[0]->GetInformationObject(0);
  if (inInfo && inInfo->Has(vtkStreamingDemandDrivenPipeline::WHOLE_EXTENT()))
  {
    inInfo->Set(vtkStreamingDemandDrivenPipeline::UPDATE_EXTENT(),
      inInfo->Get(vtkStreamingDemandDrivenPipeline::WHOLE_EXTENT()), 6);
  }
  return 1;
}

namespace
{
template <typename T>
void FiniteRange(const T* v, vtkIdType n, double range[2])
{
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (vtkIdType i = 0; i < n; ++i)
  {
    const double x = static_cast<double>(static_cast<float>(v[i]));
    if (std::isfinite(x))
    {
      lo = std::min(lo, x);
      hi = std::max(hi, x);
    }
  }
  range[0] = lo;
  range[1] = hi;
}
}

//------------------------------------------------------------------------------
int vtkMatrixTreeVolumeRayCaster::RequestData(
  vtkInformation*, vtkInformationVector** inputVector, vtkInformationVector* outputVector)
{
  vtkImageData* input = vtkImageData::GetData(inputVector[0], 0);
  vtkImageData* output = vtkImageData::GetData(outputVector, 0);
  if (!output)
  {
    vtkErrorMacro("No output image.");
    return 0;
  }
  const int w = std::min(std::max(this->ImageSize[0], 1), 16384);
  const int h = std::min(std::max(this->ImageSize[1], 1), 16384);
  output->SetDimensions(w, h, 1);
  output->SetSpacing(1, 1, 1);
  output->SetOrigin(0, 0, 0);
  output->GetPointData()->Initialize();
  this->LastRebuilt = false;

  if (!input || input->GetNumberOfPoints() == 0)
  {
    vtkErrorMacro("The input image is empty.");
    return 0;
  }
  vtkDataArray* scalars = input->GetPointData()->GetScalars();
  if (!scalars)
  {
    vtkErrorMacro("The input image has no point scalars.");
    return 0;
  }
  if (scalars->GetNumberOfComponents() != 1)
  {
    vtkErrorMacro("The input scalars have " << scalars->GetNumberOfComponents()
                                            << " components; one is needed (extract one with "
                                               "vtkImageExtractComponents).");
    return 0;
  }
  int dims[3];
  input->GetDimensions(dims);
  if (dims[0] < 2 || dims[1] < 2 || dims[2] < 2)
  {
    vtkErrorMacro("The input image is " << dims[0] << "x" << dims[1] << "x" << dims[2]
                                        << " points: at least 2 along every axis are needed.");
    return 0;
  }
  mtree::VolumeGeometry geo;
  input->GetSpacing(geo.spacing);
  input->GetOrigin(geo.origin);
  // Point (i, j, k) of the scalars is structured point extent[0] + i, ... : its world position is
  // origin + (extent start + index) * spacing, so the engine's origin is the first point's.
  int extent[6];
  input->GetExtent(extent);
  for (int a = 0; a < 3; ++a)
  {
    if (!(geo.spacing[a] != 0) || !std::isfinite(geo.spacing[a]))
    {
      vtkErrorMacro("The input spacing must be finite and non-zero along every axis.");
      return 0;
    }
    geo.origin[a] += extent[2 * a] * geo.spacing[a];
  }
  std::string invalid = vtkMatrixTreeChecks::VolumeSettings(scalars->GetNumberOfTuples(), dims, geo.spacing,
    this->SampleDistance, this->EarlyTerminationThreshold, this->ScalarOpacityUnitDistance);
  if (invalid.empty())
  {
    invalid = vtkMatrixTreeChecks::ImageSize(this->ImageSize);
  }
  if (!invalid.empty())
  {
    vtkErrorMacro(<< invalid << ".");
    return 0;
  }

  vtkMatrixTreeVolumeRayCasterInternals& in = *this->Internals;
  const vtkMTimeType inputTime = std::max(input->GetMTime(), scalars->GetMTime());
  const bool rebuild = !in.Built || in.Force || in.Scalars != scalars || in.Opacity != this->ScalarOpacity ||
    in.TableSize != this->TableSize || in.Dense != in.Tuning.DenseStorage || in.Exact != in.Tuning.ExactFloat || inputTime > in.BuildTime ||
    (this->ScalarOpacity && this->ScalarOpacity->GetMTime() > in.BuildTime);

  // The lookup table spans the finite scalar range.
  if (rebuild)
  {
    double range[2] = { 0, 0 };
    const vtkIdType n = scalars->GetNumberOfTuples();
    switch (scalars->GetDataType())
    {
      vtkTemplateMacro(FiniteRange(static_cast<const VTK_TT*>(scalars->GetVoidPointer(0)), n, range));
      default:
        vtkErrorMacro("Unsupported scalar type " << scalars->GetDataTypeAsString());
        return 0;
    }
    if (!(range[0] <= range[1]))
    {
      vtkErrorMacro("The input scalars hold no finite value.");
      return 0;
    }
    if (range[1] == range[0])
    {
      range[1] = range[0] + 1;
    }
    in.Range[0] = range[0];
    in.Range[1] = range[1];
  }
  const int ne = this->TableSize;
  std::vector<float> rgb(3 * size_t(ne), 1.f), alpha(static_cast<size_t>(ne), 0.f), rgba(4 * size_t(ne), 0.f);
  if (this->ColorTransferFunction)
  {
    this->ColorTransferFunction->GetTable(in.Range[0], in.Range[1], ne, rgb.data());
  }
  if (this->ScalarOpacity)
  {
    this->ScalarOpacity->GetTable(in.Range[0], in.Range[1], ne, alpha.data());
  }
  else
  {
    for (int i = 0; i < ne; ++i)
    {
      alpha[size_t(i)] = float(i) / float(ne - 1);
    }
  }
  for (int i = 0; i < ne; ++i)
  {
    for (int c = 0; c < 3; ++c)
    {
      rgba[4 * size_t(i) + c] = rgb[3 * size_t(i) + c];
    }
    rgba[4 * size_t(i) + 3] = alpha[size_t(i)];
  }

  try
  {
    const mtree::TransferTable table(in.Range[0], in.Range[1], std::move(rgba), this->ScalarOpacityUnitDistance);
    if (rebuild)
    {
      mtree::VolumeBuildOptions bo;
      bo.sparse = !in.Tuning.DenseStorage;
      bo.quantizeFloat = !in.Tuning.ExactFloat;
      bo.threads = this->NumberOfThreads;
      in.Built = false;
      switch (scalars->GetDataType())
      {
        vtkTemplateMacro(
          in.Volume.build(static_cast<const VTK_TT*>(scalars->GetVoidPointer(0)), dims, table, bo));
      }
      in.Built = true;
      in.Force = false;
      in.Scalars = scalars;
      in.Opacity = this->ScalarOpacity;
      in.TableSize = this->TableSize;
      in.Dense = in.Tuning.DenseStorage;
      in.Exact = in.Tuning.ExactFloat;
      in.BuildTime.Modified();
      in.CLUploaded = false;
      this->LastRebuilt = true;
      const mtree::VolumeStats& s = in.Volume.stats();
      this->LastBuildTime = s.buildMs;
      this->NumberOfAllocatedBlocks = s.blocksAllocated;
      this->NumberOfDenseBlocks = s.blocksDense;
      this->NumberOfVisibleBricks = s.bricksVisible;
      this->NumberOfBricks = s.bricks;
      this->NumberOfLevels = s.levels;
      this->VisibleBlockBytes = static_cast<vtkIdType>(s.blockBytes);
      this->AllocatedBytes = static_cast<vtkIdType>(s.bytes);
      this->DenseBytes = static_cast<vtkIdType>(s.denseBytes);
      this->NumberOfNonFiniteScalars = static_cast<vtkIdType>(s.nonFinite);
      this->VoxelStorage = static_cast<int>(s.storage);
      this->QuantizationStep = in.Volume.quantizationStep();
    }

    mtree::VolumeCamera cam;
    cam.position = mtree::Vec3(this->Position);
    cam.focalPoint = mtree::Vec3(this->FocalPoint);
    cam.viewUp = mtree::Vec3(this->ViewUp);
    cam.viewAngle = this->ViewAngle;
    cam.parallel = this->ParallelProjection;
    cam.parallelScale = this->ParallelScale;
    cam.width = w;
    cam.height = h;
    mtree::VolumeRenderOptions ro;
    ro.sampleDistance = this->SampleDistance;
    ro.imageSampleDistance = this->ImageSampleDistance;
    ro.earlyTermination = this->EarlyTerminationThreshold;
    ro.doublePrecision = this->DoublePrecision;
    ro.emptySpaceSkipping = in.Tuning.EmptySpaceSkipping;
    ro.vectorized = in.Tuning.Vectorized;
    ro.shade = this->Shade;
    ro.ambient = this->Ambient;
    ro.diffuse = this->Diffuse;
    ro.specular = this->Specular;
    ro.specularPower = this->SpecularPower;
    ro.threads = this->NumberOfThreads;
    const vtkIdType npix = vtkIdType(w) * h;
    if (!in.RGBAFloat || in.RGBAFloat->GetReferenceCount() > 1 || in.RGBAFloat->GetNumberOfTuples() != npix)
    {
      in.RGBAFloat = vtkSmartPointer<vtkFloatArray>::New();
      in.RGBAFloat->SetName("RGBAFloat");
      in.RGBAFloat->SetNumberOfComponents(4);
      in.RGBAFloat->SetNumberOfTuples(npix);
    }
    if (!in.RGBA || in.RGBA->GetReferenceCount() > 1 || in.RGBA->GetNumberOfTuples() != npix)
    {
      in.RGBA = vtkSmartPointer<vtkUnsignedCharArray>::New();
      in.RGBA->SetName("RGBA");
      in.RGBA->SetNumberOfComponents(4);
      in.RGBA->SetNumberOfTuples(npix);
    }
    float* fp = in.RGBAFloat->GetPointer(0);
    unsigned char* up = in.RGBA->GetPointer(0);
    mtree::VolumeImage img;
    if (this->Backend == OPENCL)
    {
      try
      {
        if (in.CLDevice.Acquire(this->OpenCLDevice) || !in.CLRenderer)
        {
          in.CLUploaded = false;
          in.CLRenderer.reset(new mtree::ocl::VolumeRenderer(in.CLDevice.GetContext()));
        }
        if (!in.CLUploaded)
        {
          in.CLRenderer->upload(in.Volume);
          in.CLUploaded = true;
          ++this->NumberOfOpenCLUploads;
        }
        img = in.CLRenderer->render(geo, table, cam, ro);
        std::copy(img.rgba.begin(), img.rgba.end(), fp);
      }
      catch (const mtree::ocl::Error& e)
      {
        // The volume is classified: keep it, so that a switch to the CPU backend renders at once.
        in.CLUploaded = false;
        vtkErrorMacro("Volume rendering failed (opencl backend): "
          << e.what() << " (or render with SetBackendToCPU())");
        return 0;
      }
    }
    else
    {
      img = mtree::renderVolume(in.Volume, geo, table, cam, ro, fp);
    }
    this->LastRenderTime = img.ms;
    this->NumberOfSamples = static_cast<vtkIdType>(img.samples);
    this->NumberOfSkips = static_cast<vtkIdType>(img.skips);

    vtkIdType i = 0;
#if defined(__SSE2__)
    // 16 at a time, the scalar loop's operations: max(x, 0) then min(x, 1) keep its choices (NaN
    // and -0 give 0), truncation of v * 255 + 0.5 >= 0.5, and packs that cannot saturate (<= 255).
    {
      const __m128 zero = _mm_setzero_ps(), one = _mm_set1_ps(1.f), scale = _mm_set1_ps(255.f),
                   half = _mm_set1_ps(0.5f);
      for (; i + 16 <= 4 * npix; i += 16)
      {
        __m128i q[4];
        for (int j = 0; j < 4; ++j)
        {
          const __m128 v = _mm_min_ps(_mm_max_ps(_mm_loadu_ps(fp + i + 4 * j), zero), one);
          q[j] = _mm_cvttps_epi32(_mm_add_ps(_mm_mul_ps(v, scale), half));
        }
        _mm_storeu_si128(reinterpret_cast<__m128i*>(up + i),
          _mm_packus_epi16(_mm_packs_epi32(q[0], q[1]), _mm_packs_epi32(q[2], q[3])));
      }
    }
#endif
    for (; i < 4 * npix; ++i)
    {
      const float v = std::min(1.f, std::max(0.f, fp[i]));
      up[i] = static_cast<unsigned char>(v * 255.f + 0.5f); // round half up, no libm call
    }
    in.RGBAFloat->Modified();
    in.RGBA->Modified();
    output->GetPointData()->SetScalars(in.RGBA);
    output->GetPointData()->AddArray(in.RGBAFloat);
  }
  catch (const std::exception& e)
  {
    in.Built = in.Built && !rebuild;
    in.CLUploaded = false;
    vtkErrorMacro("Volume rendering failed (" << this->GetBackendAsString() << " backend): " << e.what());
    return 0;
  }
  return 1;
}

//------------------------------------------------------------------------------
void vtkMatrixTreeVolumeRayCaster::PrintSelf(ostream& os, vtkIndent indent)
{
  this->Superclass::PrintSelf(os, indent);
  os << indent << "ColorTransferFunction: " << this->ColorTransferFunction << "\n";
  os << indent << "ScalarOpacity: " << this->ScalarOpacity << "\n";
  os << indent << "ScalarOpacityUnitDistance: " << this->ScalarOpacityUnitDistance << "\n";
  os << indent << "TableSize: " << this->TableSize << "\n";
  os << indent << "ImageSize: " << this->ImageSize[0] << " " << this->ImageSize[1] << "\n";
  os << indent << "Position: " << this->Position[0] << " " << this->Position[1] << " " << this->Position[2] << "\n";
  os << indent << "FocalPoint: " << this->FocalPoint[0] << " " << this->FocalPoint[1] << " "
     << this->FocalPoint[2] << "\n";
  os << indent << "ViewUp: " << this->ViewUp[0] << " " << this->ViewUp[1] << " " << this->ViewUp[2] << "\n";
  os << indent << "ViewAngle: " << this->ViewAngle << "\n";
  os << indent << "ParallelProjection: " << this->ParallelProjection << "\n";
  os << indent << "ParallelScale: " << this->ParallelScale << "\n";
  os << indent << "SampleDistance: " << this->SampleDistance << "\n";
  os << indent << "ImageSampleDistance: " << this->ImageSampleDistance << "\n";
  os << indent << "EarlyTerminationThreshold: " << this->EarlyTerminationThreshold << "\n";
  os << indent << "DoublePrecision: " << this->DoublePrecision << "\n";
  os << indent << "Shade: " << this->Shade << "\n";
  os << indent << "Ambient: " << this->Ambient << "\n";
  os << indent << "Diffuse: " << this->Diffuse << "\n";
  os << indent << "Specular: " << this->Specular << "\n";
  os << indent << "SpecularPower: " << this->SpecularPower << "\n";
  vtkMatrixTreeBackend::Print(os, indent, this->Backend, this->OpenCLDevice, this->GetOpenCLDeviceName());
  os << indent << "NumberOfThreads: " << this->NumberOfThreads << "\n";
  os << indent << "LastBuildTime: " << this->LastBuildTime << "\n";
  os << indent << "LastRenderTime: " << this->LastRenderTime << "\n";
  os << indent << "LastRebuilt: " << this->LastRebuilt << "\n";
  os << indent << "NumberOfAllocatedBlocks: " << this->NumberOfAllocatedBlocks << "\n";
  os << indent << "NumberOfDenseBlocks: " << this->NumberOfDenseBlocks << "\n";
  os << indent << "NumberOfVisibleBricks: " << this->NumberOfVisibleBricks << "\n";
  os << indent << "NumberOfBricks: " << this->NumberOfBricks << "\n";
  os << indent << "NumberOfLevels: " << this->NumberOfLevels << "\n";
  os << indent << "VisibleBlockBytes: " << this->VisibleBlockBytes << "\n";
  os << indent << "AllocatedBytes: " << this->AllocatedBytes << "\n";
  os << indent << "DenseBytes: " << this->DenseBytes << "\n";
  os << indent << "NumberOfSamples: " << this->NumberOfSamples << "\n";
  os << indent << "NumberOfSkips: " << this->NumberOfSkips << "\n";
  os << indent << "NumberOfNonFiniteScalars: " << this->NumberOfNonFiniteScalars << "\n";
  os << indent << "VoxelStorage: " << this->VoxelStorage << "\n";
  os << indent << "QuantizationStep: " << this->QuantizationStep << "\n";
  os << indent << "NumberOfOpenCLUploads: " << this->NumberOfOpenCLUploads << "\n";
  const vtkMatrixTreeVolumeTuning& t = this->Internals->Tuning;
  os << indent << "Tuning: EmptySpaceSkipping " << t.EmptySpaceSkipping << ", DenseStorage " << t.DenseStorage
     << ", Vectorized " << t.Vectorized << ", ExactFloat " << t.ExactFloat << "\n";
}

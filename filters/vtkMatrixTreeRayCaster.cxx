#include "vtkMatrixTreeRayCaster.h"

#include "vtkMatrixTree.h"
#include "vtkMatrixTreeBackend.h"
#include "vtkMatrixTreeChecks.h"
#include "vtkMatrixTreeInternals.h"

#include "vtkFloatArray.h"
#include "vtkIdTypeArray.h"
#include "vtkImageData.h"
#include "vtkInformation.h"
#include "vtkInformationVector.h"
#include "vtkObjectFactory.h"
#include "vtkPointData.h"
#include "vtkPolyData.h"
#include "vtkStreamingDemandDrivenPipeline.h"
#include "vtkUnsignedCharArray.h"
#include "vtkUnsignedIntArray.h"

#include "mtree/rays/render.h"
#include "mtree/rays/sah_kdtree.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <string>
#include <vector>

// The SAH kd-tree accelerator's state: its own copy of the triangles (the matrix tree's copy is
// filled only when that tree is built) and the tree, rebuilt when the input changes, with its
// leaf triangles when the matrix tree keeps them (the same leaf tests for both).
struct vtkMatrixTreeRayCaster::SahState
{
  mtree::TriangleMesh Mesh;
  std::vector<vtkIdType> CellOfTriangle;
  mtree::SahKdTree Tree;
  mtree::LeafTriangles Payload;
  vtkPolyData* Input = nullptr; // identity only, never dereferenced
  vtkMTimeType BuiltAt = 0;
  bool Valid = false;
};

vtkStandardNewMacro(vtkMatrixTreeRayCaster);

//------------------------------------------------------------------------------
vtkMatrixTreeRayCaster::vtkMatrixTreeRayCaster()
  : Tree(vtkMatrixTree::New())
  , Sah(new SahState)
{
  this->SetNumberOfInputPorts(1);
  this->SetNumberOfOutputPorts(1);
}

vtkMatrixTreeRayCaster::~vtkMatrixTreeRayCaster()
{
  delete this->Sah;
  this->Tree->Delete();
}

vtkMTimeType vtkMatrixTreeRayCaster::GetMTime()
{
  return std::max(this->Superclass::GetMTime(), this->Tree->GetMTime());
}

int vtkMatrixTreeRayCaster::FillInputPortInformation(int, vtkInformation* info)
{
  info->Set(vtkAlgorithm::INPUT_REQUIRED_DATA_TYPE(), "vtkPolyData");
  return 1;
}

//------------------------------------------------------------------------------
int vtkMatrixTreeRayCaster::RequestInformation(
  vtkInformation*, vtkInformationVector**, vtkInformationVector* outputVector)
{
  // The extent of a size RequestData will refuse is clamped here: information cannot fail.
  const int w = std::min(std::max(this->ImageSize[0], 1), vtkMatrixTreeChecks::kMaxImageSide);
  const int h = std::min(std::max(this->ImageSize[1], 1), vtkMatrixTreeChecks::kMaxImageSide);
  int extent[6] = { 0, w - 1, 0, h - 1, 0, 0 };
  vtkInformation* outInfo = outputVector->GetInformationObject(0);
  outInfo->Set(vtkStreamingDemandDrivenPipeline::WHOLE_EXTENT(), extent, 6);
  vtkDataObject::SetPointDataActiveScalarInfo(outInfo, VTK_UNSIGNED_CHAR, 3);
  return 1;
}

//------------------------------------------------------------------------------
int vtkMatrixTreeRayCaster::RequestData(
  vtkInformation*, vtkInformationVector** inputVector, vtkInformationVector* outputVector)
{
  vtkPolyData* input = vtkPolyData::GetData(inputVector[0], 0);
  vtkImageData* output = vtkImageData::GetData(outputVector, 0);
  if (!input || !output)
  {
    vtkErrorMacro("RequestData: missing input polydata or output image.");
    return 0;
  }
  std::string invalid = vtkMatrixTreeChecks::ImageSize(this->ImageSize);
  if (invalid.empty() && !this->AutoCamera)
  {
    invalid = vtkMatrixTreeChecks::Camera(this->Position, this->FocalPoint);
  }
  if (!invalid.empty())
  {
    vtkErrorMacro("RequestData: " << invalid << ".");
    return 0;
  }
  const int w = this->ImageSize[0];
  const int h = this->ImageSize[1];
  output->SetExtent(0, w - 1, 0, h - 1, 0, 0);
  output->SetOrigin(0, 0, 0);
  output->SetSpacing(1, 1, 1);

  // Build (or reuse) the accelerator.
  this->UpdateProgress(0.0);
  const bool useSah = this->Accelerator == SAH_KDTREE;
  if (useSah)
  {
    if (this->Tree->GetBackend() != vtkMatrixTreeBackend::CPU)
    {
      vtkErrorMacro("RequestData: the SAH kd-tree runs on the CPU only; set the backend to cpu.");
      return 0;
    }
    SahState& s = *this->Sah;
    if (s.Input != input || s.BuiltAt < input->GetMTime() || s.BuiltAt < this->Tree->GetMTime())
    {
      std::string error;
      s.Valid = false;
      if (!vtkMatrixTreeConvert::ToTriangleMesh(input, s.Mesh, s.CellOfTriangle, error))
      {
        vtkErrorMacro("RequestData: " << error);
        return 0;
      }
      try
      {
        s.Tree.build(s.Mesh);
        s.Payload.clear();
        if (this->Tree->GetLeafTriangles() && !s.Tree.primitiveIndices().empty())
        {
          s.Payload.build(s.Tree.primitiveIndices().data(), s.Tree.primitiveIndices().size(), s.Mesh,
            this->NumberOfThreads);
        }
      }
      catch (const std::exception& e)
      {
        vtkErrorMacro("RequestData: the SAH kd-tree could not be built: " << e.what());
        return 0;
      }
      s.Input = input;
      s.BuiltAt = std::max(input->GetMTime(), this->Tree->GetMTime());
      s.Valid = true;
      this->LastRebuilt = true;
      this->LastBuildTime = s.Tree.stats().buildMs;
    }
    else
    {
      this->LastRebuilt = false;
    }
  }
  else
  {
    if (this->Tree->GetDataSet() != input)
    {
      this->Tree->SetDataSet(input);
    }
    const vtkIdType buildsBefore = this->Tree->GetNumberOfBuilds();
    if (!this->Tree->BuildIfNeeded())
    {
      vtkErrorMacro("RequestData: the " << this->Tree->GetTreeTypeAsString()
                                          << " tree could not be built (see the error above).");
      return 0;
    }
    this->LastRebuilt = this->Tree->GetNumberOfBuilds() != buildsBefore;
    this->LastBuildTime = this->Tree->GetBuildTime();
  }
  this->UpdateProgress(0.3);

  vtkMatrixTreeInternals& in = *this->Tree->GetInternals();
  const mtree::TriangleMesh& mesh = useSah ? this->Sah->Mesh : in.Mesh;
  const std::vector<vtkIdType>& cellOfTriangle = useSah ? this->Sah->CellOfTriangle : in.CellOfTriangle;
  mtree::Box scene;
  for (size_t i = 0; i < mesh.numPoints(); ++i)
  {
    scene.extend(mtree::Vec3(&mesh.points()[3 * i]));
  }
  mtree::Camera cam;
  cam.width = w;
  cam.height = h;
  cam.fovyDegrees = this->ViewAngle;
  if (this->AutoCamera && !scene.empty())
  {
    const mtree::Vec3 c = scene.center();
    const double r = 0.5 * mtree::norm(scene.extent());
    const double dist = r / std::sin(0.5 * this->ViewAngle * M_PI / 180.0) * 1.05;
    const mtree::Vec3 dir = mtree::normalized(mtree::Vec3(0.35, 0.45, 1.0));
    cam.target = c;
    cam.eye = c + dir * dist;
    cam.up = mtree::Vec3(0, 1, 0);
    for (int k = 0; k < 3; ++k)
    {
      this->Position[k] = cam.eye[k];
      this->FocalPoint[k] = cam.target[k];
      this->ViewUp[k] = cam.up[k];
    }
  }
  else
  {
    cam.eye = mtree::Vec3(this->Position);
    cam.target = mtree::Vec3(this->FocalPoint);
    cam.up = mtree::Vec3(this->ViewUp);
  }
  mtree::RenderOptions ro;
  ro.shadows = this->Shadows;
  ro.threads = this->NumberOfThreads;
  ro.counters = this->Counters;
  mtree::RenderResult r;
  const mtree::TriangleTest test =
    this->TriangleTest == WATERTIGHT ? mtree::TriangleTest::Watertight : mtree::TriangleTest::MollerTrumbore;
  if (useSah)
  {
    const mtree::SahTraversal trav = this->SAHTraversal == RESTART
      ? mtree::SahTraversal::Restart
      : (this->SAHTraversal == SHORT_STACK ? mtree::SahTraversal::ShortStack : mtree::SahTraversal::Stack);
    const mtree::SahTracer tracer{ this->Sah->Tree, mesh, trav, test, this->ShortStackSize,
      this->Sah->Payload.empty() ? nullptr : &this->Sah->Payload };
    r = mtree::render(tracer, mesh, scene, cam, ro);
  }
  else
  {
    try
    {
      r = this->Tree->Render(cam, ro, test == mtree::TriangleTest::Watertight);
    }
    catch (const std::exception& e)
    {
      vtkErrorMacro("RequestData (" << this->Tree->GetBackendAsString() << " backend): " << e.what());
      return 0;
    }
  }
  this->UpdateProgress(0.9);

  const vtkIdType npix = static_cast<vtkIdType>(w) * h;
  vtkNew<vtkUnsignedCharArray> rgb;
  rgb->SetName("RGB");
  rgb->SetNumberOfComponents(3);
  rgb->SetNumberOfTuples(npix);
  std::copy(r.rgb.begin(), r.rgb.end(), rgb->GetPointer(0));
  vtkNew<vtkUnsignedIntArray> visits;
  visits->SetName("NodeVisits");
  visits->SetNumberOfTuples(npix);
  std::copy(r.nodeVisits.begin(), r.nodeVisits.end(), visits->GetPointer(0));
  vtkNew<vtkUnsignedIntArray> tests;
  tests->SetName("TriangleTests");
  tests->SetNumberOfTuples(npix);
  std::copy(r.primTests.begin(), r.primTests.end(), tests->GetPointer(0));
  vtkNew<vtkFloatArray> depth;
  depth->SetName("Depth");
  depth->SetNumberOfTuples(npix);
  std::copy(r.depth.begin(), r.depth.end(), depth->GetPointer(0));
  vtkNew<vtkIdTypeArray> cells;
  cells->SetName("CellId");
  cells->SetNumberOfTuples(npix);
  for (vtkIdType i = 0; i < npix; ++i)
  {
    const uint32_t p = r.hitPrim[i];
    cells->SetValue(i, p == MT_NULL ? -1 : cellOfTriangle[p]);
  }
  output->GetPointData()->Initialize();
  output->GetPointData()->SetScalars(rgb);
  output->GetPointData()->AddArray(visits);
  output->GetPointData()->AddArray(tests);
  output->GetPointData()->AddArray(depth);
  output->GetPointData()->AddArray(cells);

  this->LastRenderTime = r.ms;
  this->NumberOfPrimaryRays = static_cast<vtkIdType>(r.primaryRays);
  this->NumberOfShadowRays = static_cast<vtkIdType>(r.shadowRays);
  this->NumberOfHits = static_cast<vtkIdType>(r.hits);
  this->TotalNodeVisits = static_cast<vtkIdType>(r.stats.nodeVisits);
  this->TotalTriangleTests = static_cast<vtkIdType>(r.stats.primTests);
  this->UpdateProgress(1.0);
  return 1;
}

//------------------------------------------------------------------------------
void vtkMatrixTreeRayCaster::SetBackendToCPU()
{
  this->Tree->SetBackendToCPU();
}
void vtkMatrixTreeRayCaster::SetBackendToOpenCL()
{
  this->Tree->SetBackendToOpenCL();
}
int vtkMatrixTreeRayCaster::GetBackend()
{
  return this->Tree->GetBackend();
}

//------------------------------------------------------------------------------
void vtkMatrixTreeRayCaster::PrintSelf(ostream& os, vtkIndent indent)
{
  this->Superclass::PrintSelf(os, indent);
  vtkMatrixTreeBackend::Print(
    os, indent, this->Tree->GetBackend(), this->Tree->GetOpenCLDevice(), this->Tree->GetOpenCLDeviceName());
  os << indent << "Accelerator: "
     << (this->Accelerator == SAH_KDTREE ? "SAH kd-tree" : this->Tree->GetTreeTypeAsString()) << "\n";
  os << indent << "SAHTraversal: " << this->SAHTraversal << "\n";
  os << indent << "ShortStackSize: " << this->ShortStackSize << "\n";
  os << indent << "TriangleTest: " << (this->TriangleTest == WATERTIGHT ? "watertight" : "Moller-Trumbore") << "\n";
  os << indent << "Tree:\n";
  this->Tree->PrintSelf(os, indent.GetNextIndent());
  os << indent << "ImageSize: " << this->ImageSize[0] << " x " << this->ImageSize[1] << "\n";
  os << indent << "Position: " << this->Position[0] << " " << this->Position[1] << " " << this->Position[2] << "\n";
  os << indent << "FocalPoint: " << this->FocalPoint[0] << " " << this->FocalPoint[1] << " "
     << this->FocalPoint[2] << "\n";
  os << indent << "ViewUp: " << this->ViewUp[0] << " " << this->ViewUp[1] << " " << this->ViewUp[2] << "\n";
  os << indent << "ViewAngle: " << this->ViewAngle << "\n";
  os << indent << "AutoCamera: " << (this->AutoCamera ? "On" : "Off") << "\n";
  os << indent << "Shadows: " << (this->Shadows ? "On" : "Off") << "\n";
  os << indent << "Counters: " << (this->Counters ? "On" : "Off") << "\n";
  os << indent << "NumberOfThreads: " << this->NumberOfThreads << "\n";
  os << indent << "LastBuildTime: " << this->LastBuildTime << " ms\n";
  os << indent << "LastRenderTime: " << this->LastRenderTime << " ms\n";
  os << indent << "LastRebuilt: " << this->LastRebuilt << "\n";
  os << indent << "NumberOfPrimaryRays: " << this->NumberOfPrimaryRays << "\n";
  os << indent << "NumberOfShadowRays: " << this->NumberOfShadowRays << "\n";
  os << indent << "NumberOfHits: " << this->NumberOfHits << "\n";
  os << indent << "TotalNodeVisits: " << this->TotalNodeVisits << "\n";
  os << indent << "TotalTriangleTests: " << this->TotalTriangleTests << "\n";
}

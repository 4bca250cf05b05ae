#include "vtkMatrixTreeRayCaster.h"

#include "vtkMatrixTree.h"
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

#include "mtree/opencl.h"
#include "mtree/render.h"
#include "mtree/sah_kdtree.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <string>
#include <vector>

// The SAH kd-tree accelerator's state: its own copy of the triangles (the matrix tree's copy is
// filled only when that tree is built) and the tree, rebuilt when the input changes.
struct vtkMatrixTreeRayCaster::SahState
{
  mtree::TriangleMesh Mesh;
  std::vector<vtkIdType> CellOfTriangle;
  mtree::SahKdTree Tree;
  vtkPolyData* Input = nullptr; // identity only, never dereferenced
  vtkMTimeType BuiltAt = 0;
  bool Valid = false;
};

namespace
{
// render() (mtree/render.h) with the rays traced in two batches on an OpenCL device: all primary
// rays, then the shadow rays of the lit hits. Same camera rays, same shading arithmetic; a shadow
// ray goes from the offset hit point along (light - p), t in [0, 1], instead of the unit direction
// with t in [0, |light - p|] (the batch kernel takes one t range for all rays).
mtree::RenderResult RenderOpenCL(mtree::ocl::Tracer& tracer, const mtree::TriangleMesh& mesh,
  const mtree::Box& sceneBox, const mtree::Camera& cam, const mtree::RenderOptions& opt)
{
  using mtree::Vec3;
  mtree::RenderResult r;
  const int W = cam.width, Hh = cam.height;
  r.width = W;
  r.height = Hh;
  const size_t npix = size_t(W) * Hh;
  r.rgb.assign(npix * 3, 0);
  r.nodeVisits.assign(npix, 0);
  r.primTests.assign(npix, 0);
  r.depth.assign(npix, std::numeric_limits<float>::infinity());
  r.hitPrim.assign(npix, MT_NULL);
  const auto t0 = std::chrono::steady_clock::now();
  const mtree::PinholeRays rays(cam);
  const double diag = sceneBox.empty() ? 1.0 : std::max(mtree::norm(sceneBox.extent()), 1e-300);
  const double eps = 1e-7 * diag + 1e-9 * mtree::norm(sceneBox.center());
  const Vec3 light = opt.lightFromCamera ? cam.eye + rays.up * (0.5 * diag) + rays.right * (0.3 * diag) : opt.light;
  std::vector<double> o(3 * npix), d(3 * npix), t(npix);
  std::vector<uint32_t> prim(npix);
  for (int y = 0; y < Hh; ++y)
  {
    for (int x = 0; x < W; ++x)
    {
      const size_t pix = size_t(y) * W + x;
      const Vec3 dir = rays.direction(x, y);
      for (int k = 0; k < 3; ++k)
      {
        o[3 * pix + k] = cam.eye[k];
        d[3 * pix + k] = dir[k];
      }
    }
  }
  uint64_t v1 = 0, c1 = 0, v2 = 0, c2 = 0;
  tracer.intersectFirst(o.data(), d.data(), npix, 0.0, std::numeric_limits<double>::infinity(), t.data(),
    prim.data(), &v1, &c1);
  // Shading inputs of every hit; shadow rays for the lit ones.
  std::vector<double> diffuse(npix, 0.0), so, sd;
  std::vector<size_t> shadowPix;
  for (size_t pix = 0; pix < npix; ++pix)
  {
    if (prim[pix] == MT_NULL)
    {
      continue;
    }
    const Vec3 dir(&d[3 * pix]);
    const Vec3 a = mesh.vertex(prim[pix], 0), b = mesh.vertex(prim[pix], 1), cc = mesh.vertex(prim[pix], 2);
    Vec3 n = mtree::normalized(mtree::cross(b - a, cc - a));
    if (mtree::dot(n, dir) > 0)
    {
      n = n * -1.0;
    }
    const Vec3 p = cam.eye + dir * t[pix];
    const Vec3 toL = light - p;
    const double distL = mtree::norm(toL);
    diffuse[pix] = std::max(0.0, mtree::dot(n, toL * (1.0 / distL)));
    if (opt.shadows && diffuse[pix] > 0)
    {
      const Vec3 q = p + n * eps;
      const Vec3 toLq = light - q;
      for (int k = 0; k < 3; ++k)
      {
        so.push_back(q[k]);
        sd.push_back(toLq[k]);
      }
      shadowPix.push_back(pix);
    }
  }
  std::vector<uint8_t> blocked(shadowPix.size(), 0);
  tracer.intersectAny(so.data(), sd.data(), shadowPix.size(), 0.0, 1.0, blocked.data(), &v2, &c2);
  for (size_t k = 0; k < shadowPix.size(); ++k)
  {
    if (blocked[k])
    {
      diffuse[shadowPix[k]] = 0;
    }
  }
  for (size_t pix = 0; pix < npix; ++pix)
  {
    Vec3 c = opt.background;
    if (prim[pix] != MT_NULL)
    {
      ++r.hits;
      const double s = opt.ambient + (1 - opt.ambient) * diffuse[pix];
      c = Vec3(opt.albedo.x * s, opt.albedo.y * s, opt.albedo.z * s);
      r.depth[pix] = static_cast<float>(t[pix]);
      r.hitPrim[pix] = prim[pix];
    }
    for (int k = 0; k < 3; ++k)
    {
      r.rgb[pix * 3 + k] = static_cast<uint8_t>(std::min(255.0, std::max(0.0, c[k] * 255.0 + 0.5)));
    }
  }
  r.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  r.primaryRays = npix;
  r.shadowRays = shadowPix.size();
  r.stats.nodeVisits = v1 + v2;
  r.stats.primTests = c1 + c2;
  return r;
}
}

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
  const int w = std::min(std::max(this->ImageSize[0], 1), 16384);
  const int h = std::min(std::max(this->ImageSize[1], 1), 16384);
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
  const int w = std::min(std::max(this->ImageSize[0], 1), 16384);
  const int h = std::min(std::max(this->ImageSize[1], 1), 16384);
  output->SetExtent(0, w - 1, 0, h - 1, 0, 0);
  output->SetOrigin(0, 0, 0);
  output->SetSpacing(1, 1, 1);

  // Build (or reuse) the accelerator.
  this->UpdateProgress(0.0);
  const bool useSah = this->Accelerator == SAH_KDTREE;
  if (useSah)
  {
    if (this->Tree->GetBackend() != 0)
    {
      vtkErrorMacro("RequestData: the SAH kd-tree runs on the CPU only; set the backend to cpu.");
      return 0;
    }
    SahState& s = *this->Sah;
    if (s.Input != input || s.BuiltAt < input->GetMTime())
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
      }
      catch (const std::exception& e)
      {
        vtkErrorMacro("RequestData: the SAH kd-tree could not be built: " << e.what());
        return 0;
      }
      s.Input = input;
      s.BuiltAt = input->GetMTime();
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
      vtkErrorMacro("RequestData: the matrix tree could not be built (see the error above).");
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
  mtree::RenderResult r;
  const mtree::TriangleTest test =
    this->TriangleTest == WATERTIGHT ? mtree::TriangleTest::Watertight : mtree::TriangleTest::MollerTrumbore;
  if (useSah)
  {
    const mtree::SahTraversal trav = this->SAHTraversal == RESTART
      ? mtree::SahTraversal::Restart
      : (this->SAHTraversal == SHORT_STACK ? mtree::SahTraversal::ShortStack : mtree::SahTraversal::Stack);
    const mtree::SahTracer tracer{ this->Sah->Tree, mesh, trav, test, this->ShortStackSize };
    r = mtree::render(tracer, mesh, scene, cam, ro);
  }
  else if (mtree::ocl::Tracer* clTracer = this->Tree->GetOpenCLTracer())
  {
    try
    {
      r = RenderOpenCL(*clTracer, in.Mesh, scene, cam, ro);
    }
    catch (const std::exception& e)
    {
      vtkErrorMacro("RequestData (opencl backend): " << e.what());
      return 0;
    }
  }
  else
  {
    const mtree::MatrixTreeTracer tracer{ in.Tree, in.Mesh, test };
    r = mtree::render(tracer, in.Mesh, scene, cam, ro);
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
  os << indent << "Backend: " << this->Tree->GetBackendAsString() << "\n";
  os << indent << "Accelerator: " << (this->Accelerator == SAH_KDTREE ? "SAH kd-tree" : "matrix tree") << "\n";
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

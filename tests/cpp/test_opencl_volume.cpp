// The OpenCL volume ray caster (opencl/volume.cl, mtree::ocl::VolumeRenderer) against the CPU
// renderer (mtree::renderVolume, the reference), on the first OpenCL device
// ($MATRIXTREE_OPENCL_DEVICE picks another; PoCL on the CI machine):
//   synthetic  blobs on a grid that is not a multiple of the block edge, anisotropic spacing with
//              one negative axis: skipping on/off, float/double accumulation, shading, a parallel
//              camera, imageSampleDistance 2, no early termination;
//   real       ironProt.vtk from the shared data, unshaded and shaded;
//   compact    8/16-bit input (unsigned, and signed: stored with an offset) in the apron-brick
//              storage, every variant above plus a camera inside the grid; headsq (16-bit CT)
//              and ironProt (8-bit) read in their own types;
//   errors     render before upload, bad arguments.
// Every image must match the CPU's per channel within 1e-5 unshaded (they come out identical on
// PoCL) and 1e-4 shaded (OpenCL's float division, sqrt and pow may be a few ulp off where the
// CPU's are correctly rounded; seen: < 1e-7), with the same rays, samples and skipped nodes. Skipped, with the reason printed, when the machine has no OpenCL device.
// Suite "opencl_volume", so that ctest -R opencl selects it.
#include <gtest/gtest.h>

#include <vtkColorTransferFunction.h>
#include <vtkCommand.h>
#include <vtkDataArray.h>
#include <vtkFloatArray.h>
#include <vtkImageData.h>
#include <vtkNew.h>
#include <vtkPiecewiseFunction.h>
#include <vtkPointData.h>
#include <vtkShortArray.h>
#include <vtkStructuredPoints.h>
#include <vtkStructuredPointsReader.h>

#include "vtkMatrixTreeVolumeRayCaster.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "mtree/device/opencl.h"
#include "mtree/volume/volume.h"
#include "opencl_test_util.h"
#include "vtk_test_util.h"
#include "test_util.h"
#include "volume_test_util.h"

namespace {

using namespace mtree;


using mtest::rampTable;

using mtest::lookAt;

/// Largest per-channel difference; counts the channels that differ at all.
double maxDiff(const VolumeImage& a, const VolumeImage& b, size_t* differing) {
  EXPECT_EQ(a.rgba.size(), b.rgba.size());
  double m = 0;
  *differing = 0;
  for (size_t i = 0; i < std::min(a.rgba.size(), b.rgba.size()); ++i) {
    const double d = std::fabs(double(a.rgba[i]) - double(b.rgba[i]));
    if (d > 0) ++*differing;
    m = std::max(m, d);
  }
  return m;
}

/// Renders on both back ends and compares image, rays, samples and skips.
/// tol < 0: 1e-5 unshaded, 1e-4 shaded (OpenCL's float division, sqrt and pow are allowed a few
/// ulp instead of correct rounding; seen: < 1e-6).
void expectSameImage(ocl::VolumeRenderer& dev, const BlockSparseVolume& vol, const VolumeGeometry& geo,
                     const TransferTable& tf, const VolumeCamera& cam, const VolumeRenderOptions& opt,
                     const std::string& what, double tol = -1) {
  SCOPED_TRACE(what);
  const VolumeImage cpu = renderVolume(vol, geo, tf, cam, opt);
  const VolumeImage gpu = dev.render(geo, tf, cam, opt);
  ASSERT_EQ(cpu.width, gpu.width);
  ASSERT_EQ(cpu.height, gpu.height);
  size_t differing = 0;
  const double d = maxDiff(cpu, gpu, &differing);
  double alpha = 0;
  for (size_t i = 3; i < cpu.rgba.size(); i += 4) alpha += cpu.rgba[i];
  std::printf("[ opencl   ] %-34s max |cpu - device| %.3g (%zu of %zu channels differ), cpu %.1f ms, device %.1f ms\n",
              what.c_str(), d, differing, cpu.rgba.size(), cpu.ms, gpu.ms);
  EXPECT_LE(d, tol >= 0 ? tol : opt.shade ? 1e-4 : 1e-5);
  EXPECT_GT(alpha, 1.0) << "the test image should show something";
  EXPECT_EQ(cpu.rays, gpu.rays);
  EXPECT_EQ(cpu.samples, gpu.samples);
  EXPECT_EQ(cpu.skips, gpu.skips);
}

/// expectSameImage over the 8 combinations of empty-space skipping, float/double accumulation and
/// shading (sample distance 0.45, early termination at 0.95).
void expectSameImageAllVariants(ocl::VolumeRenderer& dev, const BlockSparseVolume& vol, const VolumeGeometry& geo,
                                const TransferTable& tf, const VolumeCamera& cam, const std::string& name) {
  for (int variant = 0; variant < 8; ++variant) {
    VolumeRenderOptions opt;
    opt.sampleDistance = 0.45;
    opt.emptySpaceSkipping = !(variant & 1);
    opt.doublePrecision = variant & 2;
    opt.shade = variant & 4;
    opt.earlyTermination = 0.95;
    expectSameImage(dev, vol, geo, tf, cam, opt,
                    name + (opt.emptySpaceSkipping ? " skip" : " noskip") + (opt.doublePrecision ? " double" : " float") +
                        (opt.shade ? " shaded" : ""));
  }
}

/// Gaussian blobs plus a ripple, on an nx x ny x nz grid.
std::vector<float> blobs(const int n[3]) {
  std::vector<float> v(size_t(n[0]) * n[1] * n[2]);
  const double c[3][3] = {{0.3, 0.4, 0.5}, {0.7, 0.6, 0.3}, {0.5, 0.25, 0.75}};
  for (int k = 0; k < n[2]; ++k)
    for (int j = 0; j < n[1]; ++j)
      for (int i = 0; i < n[0]; ++i) {
        const double p[3] = {double(i) / (n[0] - 1), double(j) / (n[1] - 1), double(k) / (n[2] - 1)};
        double s = 5 * std::sin(17 * p[0] + 11 * p[1] * p[2]);
        for (const auto& q : c) {
          const double r2 = (p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) + (p[2] - q[2]) * (p[2] - q[2]);
          s += 100 * std::exp(-r2 / 0.012);
        }
        v[(size_t(k) * n[1] + j) * n[0] + i] = float(s);
      }
  return v;
}

TEST(opencl_volume, SyntheticMatchesCpu) {
  REQUIRE_DEVICE(ctx);
  const int n[3] = {45, 38, 29};
  const std::vector<float> v = blobs(n);
  const TransferTable tf = rampTable(-5, 105, 0.35, 0.6);
  BlockSparseVolume vol;
  vol.build(v.data(), n, tf);
  ASSERT_LT(vol.stats().blocksAllocated, vol.stats().blocksDense) << "the test wants absent blocks";
  VolumeGeometry geo;
  geo.origin[0] = -3;
  geo.origin[1] = 40;
  geo.origin[2] = 2;
  geo.spacing[0] = 0.8;
  geo.spacing[1] = -1.1;  // y runs downwards from 40
  geo.spacing[2] = 1.3;
  const Vec3 centre(-3 + 0.4 * 44, 40 - 0.55 * 37, 2 + 0.65 * 28);
  ocl::VolumeRenderer dev(ctx);
  dev.upload(vol);
  const VolumeCamera cam = lookAt(centre + Vec3(-40, 30, -55), centre, 72, 60);
  expectSameImageAllVariants(dev, vol, geo, tf, cam, "synthetic");
  VolumeRenderOptions opt;
  opt.sampleDistance = 0.6;
  VolumeCamera par = cam;
  par.parallel = true;
  par.parallelScale = 30;
  expectSameImage(dev, vol, geo, tf, par, opt, "synthetic parallel");
  opt.imageSampleDistance = 2;
  expectSameImage(dev, vol, geo, tf, cam, opt, "synthetic imageSampleDistance 2");
  opt.imageSampleDistance = 1;
  opt.earlyTermination = 1.0;
  expectSameImage(dev, vol, geo, tf, cam, opt, "synthetic no early termination");
}

TEST(opencl_volume, IronProteinMatchesCpu) {
  REQUIRE_DEVICE(ctx);
  mtest::FloatVolume fv;
  ASSERT_TRUE(mtest::readFloatVolume("volumes/ironProt.vtk", fv)) << "cannot read ironProt.vtk";
  const TransferTable tf = rampTable(fv.range[0], fv.range[1], 0.4, 0.3);
  BlockSparseVolume vol;
  vol.build(fv.v.data(), fv.dims, tf, mtest::floatBlocks());
  const VolumeGeometry& g = fv.geo;
  ocl::VolumeRenderer dev(ctx);
  dev.upload(vol);
  const VolumeCamera cam = lookAt({-60, 100, -80}, {34, 34, 34}, 96, 96);
  VolumeRenderOptions opt;
  opt.sampleDistance = 0.5;
  expectSameImage(dev, vol, g, tf, cam, opt, "ironProt");
  opt.shade = true;
  expectSameImage(dev, vol, g, tf, cam, opt, "ironProt shaded");
}

/// The blobs of blobs(), quantised to T over [lo, hi] (lo < 0: signed input, stored with an offset).
template <typename T>
std::vector<T> quantised(const std::vector<float>& v, double lo, double hi) {
  const auto mm = std::minmax_element(v.begin(), v.end());
  std::vector<T> q(v.size());
  for (size_t i = 0; i < v.size(); ++i)
    q[i] = static_cast<T>(std::lround(lo + (hi - lo) * (v[i] - *mm.first) / (*mm.second - *mm.first)));
  return q;
}

/// Every CPU marcher variant of one compact volume against the device: skipping on/off,
/// float/double accumulation, shading, a parallel camera, imageSampleDistance 2, no early
/// termination.
template <typename T>
void apronVariants(const std::shared_ptr<ocl::Context>& ctx, const std::vector<T>& q, const int n[3], double lo,
                   double hi, VoxelStorage expected, const std::string& name) {
  const TransferTable tf = rampTable(lo, hi, 0.35, 0.6);
  BlockSparseVolume vol;
  vol.build(q.data(), n, tf);
  ASSERT_EQ(vol.storage(), expected) << name;
  ASSERT_GT(vol.stats().bricksStored, 0u);
  ASSERT_LT(vol.stats().bricksStored, vol.stats().bricks) << "the test wants absent bricks";
  VolumeGeometry geo;
  geo.origin[0] = -3;
  geo.origin[1] = 40;
  geo.origin[2] = 2;
  geo.spacing[0] = 0.8;
  geo.spacing[1] = -1.1;
  geo.spacing[2] = 1.3;
  const Vec3 centre(-3 + 0.4 * (n[0] - 1), 40 - 0.55 * (n[1] - 1), 2 + 0.65 * (n[2] - 1));
  ocl::VolumeRenderer dev(ctx);
  dev.upload(vol);
  const VolumeCamera cam = lookAt(centre + Vec3(-40, 30, -55), centre, 72, 60);
  expectSameImageAllVariants(dev, vol, geo, tf, cam, name);
  VolumeRenderOptions opt;
  opt.sampleDistance = 0.6;
  VolumeCamera par = cam;
  par.parallel = true;
  par.parallelScale = 30;
  expectSameImage(dev, vol, geo, tf, par, opt, name + " parallel");
  opt.imageSampleDistance = 2;
  expectSameImage(dev, vol, geo, tf, cam, opt, name + " imageSampleDistance 2");
  opt.imageSampleDistance = 1;
  opt.earlyTermination = 1.0;
  expectSameImage(dev, vol, geo, tf, cam, opt, name + " no early termination");
  // A camera at the grid's centre looking at the blob at index fraction (0.7, 0.6, 0.3): rays start
  // mid-volume, and the samples on the far faces need clamping.
  const Vec3 blob(0.2 * (n[0] - 1) * 0.8, 0.1 * (n[1] - 1) * -1.1, -0.2 * (n[2] - 1) * 1.3);
  expectSameImage(dev, vol, geo, tf, lookAt(centre, centre + blob, 48, 40, 60), opt, name + " inside");
}

TEST(opencl_volume, Apron8BitMatchesCpu) {
  REQUIRE_DEVICE(ctx);
  const int n[3] = {45, 38, 29};
  const std::vector<float> v = blobs(n);
  apronVariants(ctx, quantised<uint8_t>(v, 0, 255), n, 0, 255, VoxelStorage::UInt8, "uint8");
  apronVariants(ctx, quantised<int8_t>(v, -128, 127), n, -128, 127, VoxelStorage::UInt8, "int8 (offset)");
}

TEST(opencl_volume, Apron16BitMatchesCpu) {
  REQUIRE_DEVICE(ctx);
  const int n[3] = {45, 38, 29};
  const std::vector<float> v = blobs(n);
  apronVariants(ctx, quantised<uint16_t>(v, 0, 60000), n, 0, 60000, VoxelStorage::UInt16, "uint16");
  apronVariants(ctx, quantised<int16_t>(v, -1000, 3000), n, -1000, 3000, VoxelStorage::UInt16, "int16 (offset)");
}

/// headsq (CT head, 64x64x93 int16, spacing 3.2 x 3.2 x 1.5) from the shared data.
std::vector<int16_t> readHeadsq() {
  std::vector<int16_t> raw(size_t(64) * 64 * 93);
  std::FILE* f = std::fopen(mtest::dataPath("volumes/headsq.raw").c_str(), "rb");
  if (!f) return {};
  const size_t got = std::fread(raw.data(), 2, raw.size(), f);
  std::fclose(f);
  if (got != raw.size()) return {};
  return raw;
}

TEST(opencl_volume, RealCompactVolumesMatchCpu) {
  REQUIRE_DEVICE(ctx);
  // headsq: 16-bit CT (signed, stored with an offset).
  const std::vector<int16_t> head = readHeadsq();
  ASSERT_FALSE(head.empty()) << "cannot read " << mtest::dataPath("volumes/headsq.raw");
  const int hd[3] = {64, 64, 93};
  const auto mm = std::minmax_element(head.begin(), head.end());
  const TransferTable htf = rampTable(*mm.first, *mm.second, 0.3, 0.4);
  BlockSparseVolume hv;
  hv.build(head.data(), hd, htf);
  ASSERT_EQ(hv.storage(), VoxelStorage::UInt16);
  VolumeGeometry hg;
  hg.spacing[0] = 3.2;
  hg.spacing[1] = 3.2;
  hg.spacing[2] = 1.5;
  ocl::VolumeRenderer dev(ctx);
  dev.upload(hv);
  const VolumeCamera hc = lookAt({-150, 260, -120}, {102, 102, 69}, 80, 80);
  VolumeRenderOptions opt;
  opt.sampleDistance = 0.75;
  expectSameImage(dev, hv, hg, htf, hc, opt, "headsq uint16");
  opt.doublePrecision = true;
  expectSameImage(dev, hv, hg, htf, hc, opt, "headsq uint16 double");
  opt.doublePrecision = false;
  opt.shade = true;
  expectSameImage(dev, hv, hg, htf, hc, opt, "headsq uint16 shaded");

  // ironProt: 8-bit, read as the file's unsigned chars. The same renderer takes the new upload.
  vtkNew<vtkStructuredPointsReader> r;
  r->SetFileName(mtest::dataPath("volumes/ironProt.vtk").c_str());
  r->Update();
  vtkImageData* im = r->GetOutput();
  vtkDataArray* s = im->GetPointData()->GetScalars();
  ASSERT_NE(s, nullptr);
  ASSERT_EQ(s->GetDataType(), VTK_UNSIGNED_CHAR);
  int dims[3];
  im->GetDimensions(dims);
  const uint8_t* pv = static_cast<const uint8_t*>(s->GetVoidPointer(0));
  const TransferTable itf = rampTable(0, 255, 0.4, 0.3);
  BlockSparseVolume iv;
  iv.build(pv, dims, itf);
  ASSERT_EQ(iv.storage(), VoxelStorage::UInt8);
  VolumeGeometry ig;
  im->GetSpacing(ig.spacing);
  im->GetOrigin(ig.origin);
  dev.upload(iv);
  const VolumeCamera ic = lookAt({-60, 100, -80}, {34, 34, 34}, 96, 96);
  VolumeRenderOptions io;
  io.sampleDistance = 0.5;
  expectSameImage(dev, iv, ig, itf, ic, io, "ironProt uint8");
  io.shade = true;
  expectSameImage(dev, iv, ig, itf, ic, io, "ironProt uint8 shaded");
}

/// headsq as a vtkImageData of shorts (the CT as its file holds it).
vtkSmartPointer<vtkImageData> headsqImage() {
  const std::vector<int16_t> raw = readHeadsq();
  if (raw.empty()) return nullptr;
  auto im = vtkSmartPointer<vtkImageData>::New();
  im->SetDimensions(64, 64, 93);
  im->SetSpacing(3.2, 3.2, 1.5);
  vtkNew<vtkShortArray> a;
  a->SetName("density");
  a->SetNumberOfTuples(vtkIdType(raw.size()));
  std::copy(raw.begin(), raw.end(), a->GetPointer(0));
  im->GetPointData()->SetScalars(a);
  return im;
}

/// The RGBAFloat output of the filter after an Update (empty when it failed).
std::vector<float> rgbaOf(vtkMatrixTreeVolumeRayCaster* f) {
  f->Update();
  vtkFloatArray* a = vtkFloatArray::SafeDownCast(f->GetOutput()->GetPointData()->GetArray("RGBAFloat"));
  if (!a) return {};
  return std::vector<float>(a->GetPointer(0), a->GetPointer(0) + a->GetNumberOfValues());
}

double maxDiff(const std::vector<float>& a, const std::vector<float>& b) {
  EXPECT_EQ(a.size(), b.size());
  double m = 0;
  for (size_t i = 0; i < std::min(a.size(), b.size()); ++i) m = std::max(m, std::fabs(double(a[i]) - double(b[i])));
  return m;
}

using mtest::ErrorCatcher;

/// vtkMatrixTreeVolumeRayCaster with Backend OPENCL against Backend CPU on the headsq CT (16-bit
/// apron bricks): same image, same samples; the device upload is kept across renders (camera
/// and shading changes) and redone after a reclassification, whose image must again match.
TEST(opencl_volume, FilterBackendOpenCLEqualsCpu) {
  REQUIRE_DEVICE(ctx);
  vtkSmartPointer<vtkImageData> im = headsqImage();
  ASSERT_TRUE(im) << "cannot read " << mtest::dataPath("volumes/headsq.raw");
  double range[2];
  im->GetPointData()->GetScalars()->GetRange(range);
  vtkNew<vtkColorTransferFunction> ctf;
  ctf->AddRGBPoint(range[0], 0, 0, 0);
  ctf->AddRGBPoint(0.5 * (range[0] + range[1]), 0.9, 0.5, 0.3);
  ctf->AddRGBPoint(range[1], 1, 1, 0.9);
  vtkNew<vtkPiecewiseFunction> otf;
  otf->AddPoint(range[0], 0);
  otf->AddPoint(range[0] + 0.3 * (range[1] - range[0]), 0);
  otf->AddPoint(range[1], 0.4);
  vtkNew<vtkMatrixTreeVolumeRayCaster> f;
  f->SetInputData(im);
  f->SetColorTransferFunction(ctf);
  f->SetScalarOpacity(otf);
  f->SetScalarOpacityUnitDistance(3.2);
  f->SetImageSize(96, 80);
  f->SetPosition(-150, 260, -120);
  f->SetFocalPoint(102, 102, 69);
  f->SetViewUp(0, 0, 1);
  f->SetSampleDistance(0.75);
  EXPECT_EQ(f->GetBackend(), vtkMatrixTreeVolumeRayCaster::CPU);

  auto compare = [&](const char* what, double tol) {
    SCOPED_TRACE(what);
    f->SetBackendToCPU();
    const std::vector<float> cpu = rgbaOf(f);
    const vtkIdType cpuSamples = f->GetNumberOfSamples();
    f->SetBackendToOpenCL();
    const std::vector<float> dev = rgbaOf(f);
    ASSERT_FALSE(cpu.empty());
    ASSERT_FALSE(dev.empty()) << "the OpenCL render failed";
    EXPECT_FALSE(f->GetLastRebuilt()) << "a backend switch must not reclassify";
    double alpha = 0;
    for (size_t i = 3; i < cpu.size(); i += 4) alpha += cpu[i];
    const double d = maxDiff(cpu, dev);
    std::printf("[ opencl   ] filter headsq %-22s max |cpu - opencl| %.3g, uploads %lld, device %s\n", what, d,
                static_cast<long long>(f->GetNumberOfOpenCLUploads()), f->GetOpenCLDeviceName());
    EXPECT_GT(alpha, 50.0) << "the test image should show the head";
    EXPECT_LE(d, tol);
    EXPECT_EQ(f->GetNumberOfSamples(), cpuSamples);
  };
  compare("unshaded", 1e-5);
  EXPECT_EQ(f->GetVoxelStorage(), 2) << "16-bit input is held as 16-bit apron bricks";
  EXPECT_EQ(f->GetNumberOfOpenCLUploads(), 1);
  EXPECT_STRNE(f->GetOpenCLDeviceName(), "");
  f->SetShade(true);  // 1e-4: OpenCL's float sqrt, division and pow are a few ulp off
  compare("shaded", 1e-4);
  f->SetShade(false);
  f->SetPosition(300, -100, 200);
  f->SetDoublePrecision(true);
  compare("other camera, double", 1e-5);
  EXPECT_EQ(f->GetNumberOfOpenCLUploads(), 1) << "renders must reuse the upload";
  // Reclassify: a narrower opacity ramp. The device must get the new bricks.
  otf->RemoveAllPoints();
  otf->AddPoint(range[0], 0);
  otf->AddPoint(range[0] + 0.5 * (range[1] - range[0]), 0);
  otf->AddPoint(range[1], 0.6);
  f->SetBackendToOpenCL();
  f->Update();
  EXPECT_TRUE(f->GetLastRebuilt());
  EXPECT_EQ(f->GetNumberOfOpenCLUploads(), 2);
  compare("reclassified", 1e-5);
  EXPECT_EQ(f->GetNumberOfOpenCLUploads(), 2);
}

/// Backend OPENCL with a device selector that matches nothing (what a machine without OpenCL
/// gives, too): a VTK error naming the backend, an empty output, no crash; the CPU backend then
/// renders the same filter.
TEST(opencl_volume, FilterOpenCLWithoutDeviceIsAnError) {
  vtkSmartPointer<vtkImageData> im = headsqImage();
  ASSERT_TRUE(im) << "cannot read " << mtest::dataPath("volumes/headsq.raw");
  vtkNew<vtkMatrixTreeVolumeRayCaster> f;
  vtkNew<ErrorCatcher> errors;
  f->AddObserver(vtkCommand::ErrorEvent, errors);
  f->SetInputData(im);
  f->SetImageSize(32, 32);
  f->SetPosition(-150, 260, -120);
  f->SetFocalPoint(102, 102, 69);
  f->SetBackendToOpenCL();
  f->SetOpenCLDevice("no-such-opencl-device-xyz");
  EXPECT_TRUE(rgbaOf(f).empty());
  EXPECT_GE(errors->count, 1);
  EXPECT_NE(errors->message.find("opencl backend"), std::string::npos) << errors->message;
  EXPECT_EQ(f->GetNumberOfOpenCLUploads(), 0);
  std::printf("[ opencl   ] expected error: %s\n", errors->message.c_str());
  const int before = errors->count;
  f->SetBackendToCPU();
  EXPECT_FALSE(rgbaOf(f).empty());
  EXPECT_EQ(errors->count, before);
}

TEST(opencl_volume, Errors) {
  REQUIRE_DEVICE(ctx);
  ocl::VolumeRenderer dev(ctx);
  const int n[3] = {10, 10, 10};
  const std::vector<float> v = blobs(n);
  const TransferTable tf = rampTable(-5, 105, 0.35, 0.6);
  const VolumeCamera cam = lookAt({5, 5, -30}, {5, 5, 5}, 16, 16);
  EXPECT_THROW(dev.render(VolumeGeometry(), tf, cam, VolumeRenderOptions()), ocl::Error) << "render before upload";
  EXPECT_THROW(dev.upload(BlockSparseVolume()), std::invalid_argument) << "an unbuilt volume";
  BlockSparseVolume vol;
  vol.build(v.data(), n, tf);
  dev.upload(vol);
  VolumeRenderOptions bad;
  bad.sampleDistance = 0;
  EXPECT_THROW(dev.render(VolumeGeometry(), tf, cam, bad), std::invalid_argument);
  VolumeGeometry flat;
  flat.spacing[1] = 0;
  EXPECT_THROW(dev.render(flat, tf, cam, VolumeRenderOptions()), std::invalid_argument);
  VolumeCamera degenerate = cam;
  degenerate.focalPoint = degenerate.position;
  EXPECT_THROW(dev.render(VolumeGeometry(), tf, degenerate, VolumeRenderOptions()), std::invalid_argument);
}

}  // namespace

// Timing at a realistic image size (not run by default; docs/bench_opencl.md gives the command):
//   build-cl/bin/test_opencl_volume --gtest_also_run_disabled_tests --gtest_filter='*Timing*'
// 512x512, headsq (64x64x93 shorts) and ironProt (68^3), unshaded and shaded, median of 3 renders
// per back end (the first device render, which compiles the kernel, is not counted).
TEST(opencl_volume, DISABLED_Timing512) {
  REQUIRE_DEVICE(ctx);
  struct Vol {
    std::string name;
    int dims[3];
    std::vector<float> v;
    VolumeGeometry g;
  };
  std::vector<Vol> vols;
  {
    Vol h{"headsq", {64, 64, 93}, {}, {}};
    std::FILE* f = std::fopen(mtest::dataPath("volumes/headsq.raw").c_str(), "rb");
    ASSERT_NE(f, nullptr);
    std::vector<int16_t> raw(size_t(64) * 64 * 93);
    ASSERT_EQ(std::fread(raw.data(), 2, raw.size(), f), raw.size());
    std::fclose(f);
    h.v.assign(raw.begin(), raw.end());
    h.g.spacing[0] = 3.2;
    h.g.spacing[1] = 3.2;
    h.g.spacing[2] = 1.5;
    vols.push_back(std::move(h));
  }
  {
    mtest::FloatVolume fv;
    ASSERT_TRUE(mtest::readFloatVolume("volumes/ironProt.vtk", fv));
    vols.push_back(Vol{"ironProt", {fv.dims[0], fv.dims[1], fv.dims[2]}, std::move(fv.v), fv.geo});
  }
  auto median3 = [](std::vector<double> t) {
    std::sort(t.begin(), t.end());
    return t[t.size() / 2];
  };
  for (const Vol& vv : vols) {
    const auto mm = std::minmax_element(vv.v.begin(), vv.v.end());
    const TransferTable tf = rampTable(*mm.first, *mm.second, 0.3, 0.4);
    BlockSparseVolume vol;
    vol.build(vv.v.data(), vv.dims, tf);
    ocl::VolumeRenderer dev(ctx);
    dev.upload(vol);
    Vec3 lo, hi;
    for (int a = 0; a < 3; ++a) {
      lo[a] = vv.g.origin[a];
      hi[a] = vv.g.origin[a] + vv.g.spacing[a] * (vv.dims[a] - 1);
    }
    const Vec3 c = (lo + hi) * 0.5, e = hi - lo;
    const VolumeCamera cam = lookAt(c + Vec3(-0.9, 0.7, -1.4) * norm(e), c, 512, 512);
    for (int shade = 0; shade < 2; ++shade) {
      VolumeRenderOptions opt;
      opt.sampleDistance = 0.5 * std::min({std::fabs(vv.g.spacing[0]), std::fabs(vv.g.spacing[1]),
                                           std::fabs(vv.g.spacing[2])});
      opt.shade = shade;
      dev.render(vv.g, tf, cam, opt);  // compiles / warms up
      std::vector<double> tc, td, tk;
      VolumeImage a, b;
      for (int k = 0; k < 3; ++k) {
        a = renderVolume(vol, vv.g, tf, cam, opt);
        std::vector<ocl::KernelTiming> kt;
        b = dev.render(vv.g, tf, cam, opt, &kt);
        tc.push_back(a.ms);
        td.push_back(b.ms);
        double kms = 0;
        for (const auto& x : kt)
          if (x.kernel.rfind("mt_volume_march", 0) == 0) kms += x.ms;
        tk.push_back(kms);
      }
      size_t differing = 0;
      const double d = maxDiff(a, b, &differing);
      std::printf("[ opencl   ] %-8s %s 512x512: cpu %.1f ms, device %.1f ms (kernel %.1f ms), %.2f Msamples, "
                  "max diff %.3g\n",
                  vv.name.c_str(), shade ? "shaded  " : "unshaded", median3(tc), median3(td), median3(tk),
                  double(a.samples) * 1e-6, d);
      EXPECT_LE(d, 1e-4);
      EXPECT_EQ(a.samples, b.samples);
    }
  }
}

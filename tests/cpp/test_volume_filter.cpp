// vtkMatrixTreeVolumeRayCaster against its own developer settings (vtkMatrixTreeVolumeTuning,
// C++ only): on the real volumes of the shared data, rendered as matrixtree.render_volume renders
// them (default transfer functions, framing camera, sample distance half the smallest spacing),
// the production path and each alternative give the same image: empty-space skipping off and
// dense storage within 1e-6, the SSE2 marcher bit for bit with the same samples and skips.
#include <gtest/gtest.h>

#include <vtkCamera.h>
#include <vtkColorTransferFunction.h>
#include <vtkDataArray.h>
#include <vtkFloatArray.h>
#include <vtkImageData.h>
#include <vtkNew.h>
#include <vtkPiecewiseFunction.h>
#include <vtkPointData.h>
#include <vtkSmartPointer.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "test_util.h"
#include "vtkMatrixTreeVolumeRayCaster.h"
#include "vtkMatrixTreeVolumeTuning.h"
#include "vtk_volume_util.h"

namespace {

struct Render {
  std::vector<float> rgba;
  vtkIdType samples = 0, skips = 0, allocated = 0, dense = 0, bytes = 0, visibleBytes = 0;
  int storage = -1;
};

/// vtkMatrixTreeVolumeRayCaster with matrixtree.render_volume's settings for `image`: the default
/// transfer functions, opacity unit distance the mean spacing, sample distance half the smallest.
/// One filter for all frames: a tuning change reclassifies the volume only where it must.
class Caster {
 public:
  explicit Caster(vtkImageData* image) {
    mtest::defaultTransferFunctions(image, ctf_, otf_);
    double sp[3];
    image->GetSpacing(sp);
    for (double& s : sp) s = std::fabs(s);
    c_->SetInputData(image);
    c_->SetColorTransferFunction(ctf_);
    c_->SetScalarOpacity(otf_);
    c_->SetScalarOpacityUnitDistance((sp[0] + sp[1] + sp[2]) / 3);
    c_->SetSampleDistance(0.5 * std::min({sp[0], sp[1], sp[2]}));
  }
  Render render(vtkCamera* camera, int w, int h, const vtkMatrixTreeVolumeTuning& tuning) {
    c_->SetImageSize(w, h);
    c_->SetCamera(camera);
    c_->SetTuning(tuning);
    c_->Update();
    Render r;
    vtkFloatArray* a = vtkFloatArray::SafeDownCast(c_->GetOutput()->GetPointData()->GetArray("RGBAFloat"));
    EXPECT_NE(a, nullptr) << "the filter failed";
    if (!a) return r;
    r.rgba.assign(a->GetPointer(0), a->GetPointer(0) + 4 * a->GetNumberOfTuples());
    r.samples = c_->GetNumberOfSamples();
    r.skips = c_->GetNumberOfSkips();
    r.allocated = c_->GetNumberOfAllocatedBlocks();
    r.dense = c_->GetNumberOfDenseBlocks();
    r.bytes = c_->GetAllocatedBytes();
    r.visibleBytes = c_->GetVisibleBlockBytes();
    r.storage = c_->GetVoxelStorage();
    return r;
  }

 private:
  vtkNew<vtkColorTransferFunction> ctf_;
  vtkNew<vtkPiecewiseFunction> otf_;
  vtkNew<vtkMatrixTreeVolumeRayCaster> c_;
};

double maxDiff(const Render& a, const Render& b) {
  EXPECT_EQ(a.rgba.size(), b.rgba.size());
  double m = 0;
  for (size_t i = 0; i < std::min(a.rgba.size(), b.rgba.size()); ++i)
    m = std::max(m, std::fabs(double(a.rgba[i]) - double(b.rgba[i])));
  return m;
}

TEST(VolumeFilter, SkippingAndDenseStorageDoNotChangeTheImage) {
  const vtkSmartPointer<vtkImageData> im = mtest::readVolume(mtest::dataPath("volumes/HeadMRVolume.mhd"));
  const vtkSmartPointer<vtkCamera> cam = mtest::frameCamera(im);
  Caster caster(im);
  const Render a = caster.render(cam, 48, 40, vtkMatrixTreeVolumeTuning());
  vtkMatrixTreeVolumeTuning noSkip;
  noSkip.EmptySpaceSkipping = false;
  const Render b = caster.render(cam, 48, 40, noSkip);
  vtkMatrixTreeVolumeTuning dense;
  dense.DenseStorage = true;
  const Render c = caster.render(cam, 48, 40, dense);
  EXPECT_LE(maxDiff(a, b), 1e-6) << "empty-space skipping off";
  EXPECT_LE(maxDiff(a, c), 1e-6) << "dense storage";
  EXPECT_LT(a.allocated, a.dense);
  EXPECT_EQ(c.allocated, c.dense) << "dense storage allocates every block";
  EXPECT_LE(double(a.bytes), 1.10 * double(a.visibleBytes));
  double alpha = 0;
  for (size_t i = 3; i < a.rgba.size(); i += 4) alpha += a.rgba[i];
  EXPECT_GT(alpha / double(a.rgba.size() / 4), 0.05);
}

/// `im` with its scalars as floats plus a fractional, smooth offset: a float volume that is not
/// integer-valued (so neither 8/16-bit storage applies losslessly).
vtkSmartPointer<vtkImageData> asFractionalFloat(vtkImageData* im) {
  auto out = vtkSmartPointer<vtkImageData>::New();
  out->CopyStructure(im);
  vtkDataArray* s = im->GetPointData()->GetScalars();
  vtkNew<vtkFloatArray> f;
  f->SetName("scalars");
  f->SetNumberOfTuples(s->GetNumberOfTuples());
  for (vtkIdType i = 0; i < s->GetNumberOfTuples(); ++i)
    f->SetValue(i, float(s->GetTuple1(i) + 0.37 * std::sin(0.013 * double(i))));
  out->GetPointData()->SetScalars(f);
  return out;
}

TEST(VolumeFilter, FloatScalarsAreQuantisedWithinTheBoundOfExactFloat) {
  const vtkSmartPointer<vtkImageData> im =
    asFractionalFloat(mtest::readVolume(mtest::dataPath("volumes/HeadMRVolume.mhd")));
  const vtkSmartPointer<vtkCamera> cam = mtest::frameCamera(im);
  Caster caster(im);
  const Render q = caster.render(cam, 48, 40, vtkMatrixTreeVolumeTuning());
  vtkMatrixTreeVolumeTuning exactFloat;
  exactFloat.ExactFloat = true;
  const Render e = caster.render(cam, 48, 40, exactFloat);
  EXPECT_EQ(q.storage, 2) << "float scalars in 16-bit bricks by default";
  EXPECT_EQ(e.storage, 0) << "ExactFloat: float blocks";
  EXPECT_LE(double(q.bytes), 1.10 * double(q.visibleBytes));
  EXPECT_LT(q.bytes, e.bytes);
  // 4096 table entries over the range, 65535 steps: a sample moves by 1/32 entry at most
  // (mtree::VolumeBuildOptions::quantizeFloat); the images agree far below 8-bit resolution.
  EXPECT_LE(maxDiff(q, e), 2.0 / 255);
  double alpha = 0;
  for (size_t i = 3; i < q.rgba.size(); i += 4) alpha += q.rgba[i];
  EXPECT_GT(alpha / double(q.rgba.size() / 4), 0.05);
}

TEST(VolumeFilter, AnExtentNotStartingAtZeroIsPlacedByIt) {
  // Point (i, j, k) of the scalars is structured point extent start + (i, j, k), at origin +
  // that times spacing. The same world volume with its extent starting at (10, -4, 7) and its
  // origin moved back by as much renders the same image, bit for bit.
  const vtkSmartPointer<vtkImageData> im = mtest::readVolume(mtest::dataPath("volumes/ironProt.vtk"));
  int ext[6];
  double o[3], sp[3];
  im->GetExtent(ext);
  im->GetOrigin(o);
  im->GetSpacing(sp);
  ASSERT_EQ(ext[0], 0);
  const int shift[3] = {10, -4, 7};
  auto moved = vtkSmartPointer<vtkImageData>::New();
  moved->SetExtent(ext[0] + shift[0], ext[1] + shift[0], ext[2] + shift[1], ext[3] + shift[1], ext[4] + shift[2],
                   ext[5] + shift[2]);
  moved->SetSpacing(sp);
  moved->SetOrigin(o[0] - shift[0] * sp[0], o[1] - shift[1] * sp[1], o[2] - shift[2] * sp[2]);
  moved->GetPointData()->SetScalars(im->GetPointData()->GetScalars());
  double b0[6], b1[6];
  im->GetBounds(b0);
  moved->GetBounds(b1);
  for (int a = 0; a < 6; ++a) ASSERT_NEAR(b0[a], b1[a], 1e-9) << "the same world box";
  const vtkSmartPointer<vtkCamera> cam = mtest::frameCamera(im);
  Caster a(im), b(moved);
  const Render ra = a.render(cam, 40, 36, vtkMatrixTreeVolumeTuning());
  const Render rb = b.render(cam, 40, 36, vtkMatrixTreeVolumeTuning());
  EXPECT_LE(maxDiff(ra, rb), 1e-6);
  double alpha = 0;
  for (size_t i = 3; i < ra.rgba.size(); i += 4) alpha += ra.rgba[i];
  EXPECT_GT(alpha / double(ra.rgba.size() / 4), 0.02);
  // The same scalars at extent start 0 with the moved origin sit elsewhere: a different image.
  auto atZero = vtkSmartPointer<vtkImageData>::New();
  atZero->SetDimensions(im->GetDimensions());
  atZero->SetSpacing(sp);
  atZero->SetOrigin(moved->GetOrigin());
  atZero->GetPointData()->SetScalars(im->GetPointData()->GetScalars());
  Caster c(atZero);
  EXPECT_GT(maxDiff(ra, c.render(cam, 40, 36, vtkMatrixTreeVolumeTuning())), 0.05);
}

class VolumeFilterSimd : public ::testing::TestWithParam<std::string> {};

/// Where the CPU has AVX2 the unshaded 8/16-bit marcher takes 8 samples at a time; the SSE2
/// marcher (Vectorized off) must give the same image bit for bit (same float operations, same
/// order), the same samples and skipped nodes. Framed and from inside, skipping on and off.
TEST_P(VolumeFilterSimd, VectorizedMarcherEqualsSse2Marcher) {
  const vtkSmartPointer<vtkImageData> im = mtest::readVolume(mtest::dataPath("volumes/" + GetParam()));
  double b[6];
  im->GetBounds(b);
  const double centre[3] = {(b[0] + b[1]) / 2, (b[2] + b[3]) / 2, (b[4] + b[5]) / 2};
  vtkNew<vtkCamera> inside;
  inside->SetPosition(centre[0], centre[1], centre[2]);
  inside->SetFocalPoint(centre[0] + 1, centre[1] + 0.3, centre[2] + 0.2);
  inside->SetViewUp(0, 1, 0);
  inside->SetViewAngle(80);
  const vtkSmartPointer<vtkCamera> framed = mtest::frameCamera(im);
  vtkCamera* cams[2] = {framed, inside};
  Caster caster(im);
  for (int ci = 0; ci < 2; ++ci)
    for (bool skip : {true, false}) {
      SCOPED_TRACE(GetParam() + (ci ? " inside" : " framed") + (skip ? " skip" : " noskip"));
      vtkMatrixTreeVolumeTuning vec, sse;
      vec.EmptySpaceSkipping = sse.EmptySpaceSkipping = skip;
      sse.Vectorized = false;
      const Render a = caster.render(cams[ci], 64, 48, vec);
      const Render c = caster.render(cams[ci], 64, 48, sse);
      EXPECT_TRUE(a.storage == 1 || a.storage == 2) << "8/16-bit bricks, got storage " << a.storage;
      ASSERT_EQ(a.rgba.size(), c.rgba.size());
      size_t differ = 0;
      for (size_t i = 0; i < a.rgba.size(); ++i) differ += a.rgba[i] != c.rgba[i];
      EXPECT_EQ(differ, 0u) << "max difference " << maxDiff(a, c);
      EXPECT_EQ(a.samples, c.samples);
      EXPECT_EQ(a.skips, c.skips);
      float alphaMax = 0;
      for (size_t i = 3; i < a.rgba.size(); i += 4) alphaMax = std::max(alphaMax, a.rgba[i]);
      EXPECT_GT(alphaMax, 0.05f);
    }
}

INSTANTIATE_TEST_SUITE_P(RealVolumes, VolumeFilterSimd,
                         ::testing::Values("HeadMRVolume.mhd", "avg152T1_RL_nifti.nii.gz", "carotid.vtk", "embryo.slc",
                                           "headsq.mhd", "ironProt.vtk"),
                         [](const ::testing::TestParamInfo<std::string>& info) {
                           return info.param.substr(0, info.param.find('.'));
                         });

}  // namespace

// The AVX2 marcher of UInt8/UInt16 apron bricks (engine/src/volume/march_avx2.cpp), and the AVX2
// set-up of 4 perspective rays at once (setupRays4), against the SSE2 marcher and the scalar
// set-up they replace at run time (VolumeRenderOptions::vectorized = false takes both): the same
// image bit for bit (not merely within a tolerance: both do the same float operations in the same
// order, none fused, and composite the samples one after the other), the same samples and skipped
// nodes, on synthetic volumes (partial bricks, rays that start inside, graze faces, miss, cross
// many bricks per step) and on real ones. Where the CPU has no AVX2 both renders take the SSE2
// marcher: the comparison then checks the fallback is chosen and stays consistent, and the test
// says so.
#include <gtest/gtest.h>

#include <vtkDataArray.h>
#include <vtkImageData.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkStructuredPoints.h>
#include <vtkStructuredPointsReader.h>

#include <cmath>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "mtree/volume/volume.h"
#include "volume_test_util.h"

using namespace mtree;
using mtest::lookAt;
using mtest::rampTable;

namespace {

/// Whether renderVolume can pick the AVX2 marcher here (the test's own view of the CPU).
bool avx2Here() {
#if defined(__GNUC__) && defined(__x86_64__)
  __builtin_cpu_init();
  return __builtin_cpu_supports("avx2");
#else
  return false;
#endif
}

/// Renders with the vectorized marcher and with the SSE2 one and expects identical results.
void expectSameAsSse2(const BlockSparseVolume& vol, const VolumeGeometry& g, const TransferTable& tf,
                      const VolumeCamera& cam, VolumeRenderOptions opt, const std::string& what) {
  opt.vectorized = true;
  const VolumeImage a = renderVolume(vol, g, tf, cam, opt);
  opt.vectorized = false;
  const VolumeImage b = renderVolume(vol, g, tf, cam, opt);
  EXPECT_EQ(a.lanes, avx2Here() ? 8 : 1) << what;
  EXPECT_EQ(b.lanes, 1) << what;
  ASSERT_EQ(a.rgba.size(), b.rgba.size()) << what;
  size_t differ = 0, first = a.rgba.size();
  for (size_t i = 0; i < a.rgba.size(); ++i)
    if (std::memcmp(&a.rgba[i], &b.rgba[i], sizeof(float)) != 0) {
      if (!differ) first = i;
      ++differ;
    }
  EXPECT_EQ(differ, 0u) << what << ": first at pixel " << first / 4 << " channel " << first % 4 << ": "
                        << (differ ? a.rgba[first] : 0.f) << " vs " << (differ ? b.rgba[first] : 0.f);
  EXPECT_EQ(a.samples, b.samples) << what;
  EXPECT_EQ(a.skips, b.skips) << what;
  EXPECT_EQ(a.rays, b.rays) << what;
}

/// Gaussian blobs plus a little noise (so visible and invisible cells interleave), scaled to
/// [0, top] and rounded to T; x fastest.
template <typename T>
std::vector<T> noisyBlobs(const int n[3], double top, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  struct Blob {
    double c[3], r;
  };
  std::vector<Blob> blobs;
  for (int b = 0; b < 5; ++b) blobs.push_back({{u(rng) * n[0], u(rng) * n[1], u(rng) * n[2]}, 2 + 5 * u(rng)});
  std::vector<T> v(size_t(n[0]) * n[1] * n[2]);
  for (int k = 0; k < n[2]; ++k)
    for (int j = 0; j < n[1]; ++j)
      for (int i = 0; i < n[0]; ++i) {
        double s = 0.08 * u(rng);
        for (const Blob& b : blobs) {
          const double d2 = (i - b.c[0]) * (i - b.c[0]) + (j - b.c[1]) * (j - b.c[1]) + (k - b.c[2]) * (k - b.c[2]);
          s += std::exp(-d2 / (b.r * b.r));
        }
        v[(size_t(k) * n[1] + j) * n[0] + i] = static_cast<T>(std::lround(top * std::min(1.0, s)));
      }
  return v;
}

/// A parallel camera looking along axis `along` (negative: backwards) whose 1 x 2 pixel rays run
/// exactly on the grid's faces across = 0 and across = n - 1 (spacing 1, origin 0), through the
/// middle of the third axis: every sample grazes a face, the far one needs clamping.
VolumeCamera faceGrazingCamera(const int n[3], int along, int across) {
  const int a = along < 0 ? -along - 1 : along - 1;
  double p[3] = {0.5 * (n[0] - 1), 0.5 * (n[1] - 1), 0.5 * (n[2] - 1)}, f[3], up[3] = {0, 0, 0};
  p[a] = along < 0 ? n[a] + 3 : -4;
  for (int i = 0; i < 3; ++i) f[i] = p[i];
  f[a] += along < 0 ? -10 : 10;
  up[across] = 1;
  VolumeCamera c;
  c.parallel = true;
  c.position = Vec3(p);
  c.focalPoint = Vec3(f);
  c.viewUp = Vec3(up);
  c.parallelScale = n[across] - 1;  // the two rows at centre -+ scale / 2
  c.width = 1;
  c.height = 2;
  return c;
}

template <typename T>
void checkSynthetic(VoxelStorage expected, double top) {
  const int n[3] = {37, 29, 23};  // no axis a multiple of 8: partial bricks on the far faces
  const std::vector<T> v = noisyBlobs<T>(n, top, 17);
  // 2^16 entries: a rounding difference in an interpolated value moves its entry now and then, so
  // a marcher that rounds differently shows in the image.
  const TransferTable tf = rampTable(0, top, 0.35, 0.5, 1 << 16);
  BlockSparseVolume sparse, dense;
  sparse.build(v.data(), n, tf);
  VolumeBuildOptions o;
  o.sparse = false;
  dense.build(v.data(), n, tf, o);
  ASSERT_EQ(sparse.storage(), expected);
  ASSERT_LT(sparse.stats().bricksStored, sparse.stats().bricks) << "the test wants empty bricks";
  ASSERT_EQ(dense.stats().bricksStored, dense.stats().bricks);
  const VolumeCamera cams[] = {
      lookAt({-30, 45, -35}, {18, 14, 11}, 40, 32),        // outside, looking in
      lookAt({50, -20, 40}, {18, 14, 11}, 32, 32, 50),     // from the far corner (negative steps)
      lookAt({18, 14, 11}, {-5, 30, 2}, 24, 24, 90),       // eye inside: rays start mid-volume
      lookAt({36, 28, 22}, {0, 0, 0}, 16, 16, 60),         // eye on the far corner point
      lookAt({-5, 0, 0}, {30, 0, 0}, 12, 12, 20),          // centre ray along the edge y = z = 0
      lookAt({18, 14, 60}, {18, 14, 80}, 8, 8),            // looking away: every ray misses
      lookAt({-40, 70, 11}, {10, 70, 11}, 8, 8),           // passing beside the volume: misses
      // Odd sizes: the middle row and column have direction components exactly 0 (rays parallel
      // to a grid axis: no bound from it, or a miss when the eye is outside that slab), and rows
      // whose last group of 4 set-up lanes runs past the image.
      lookAt({-5, 14, 11}, {30, 14, 11}, 13, 11),          // along +x through the middle
      lookAt({-5, 40, 11}, {30, 40, 11}, 13, 11, 70),      // along +x beside the slab 0 <= y <= 28
      lookAt({-5, 0, 11}, {30, 0, 11}, 13, 11),            // along +x in the face plane y = 0 (0 / 0)
      faceGrazingCamera(n, 1, 1),                          // along +x on the faces y = 0, y = 28
      faceGrazingCamera(n, -2, 2)};                        // along -y on the faces z = 0, z = 22
  const double steps[] = {0.5, 0.37, 3.0};  // 3 voxels: one 8-sample chunk spans several bricks
  const double stops[] = {0.95, 1.0, 0.3};
  int c = 0;
  for (const VolumeCamera& cam : cams) {
    for (int s = 0; s < 3; ++s)
      for (int variant = 0; variant < 4; ++variant) {
        VolumeRenderOptions opt;
        opt.sampleDistance = steps[s];
        opt.earlyTermination = stops[(c + variant) % 3];
        opt.emptySpaceSkipping = variant & 1;
        const BlockSparseVolume& vol = (variant & 2) ? dense : sparse;
        expectSameAsSse2(vol, VolumeGeometry(), tf, cam, opt,
                         "camera " + std::to_string(c) + " step " + std::to_string(steps[s]) + " variant " +
                             std::to_string(variant));
      }
    ++c;
  }
  // A negative and an anisotropic spacing, an offset origin.
  VolumeGeometry g;
  g.spacing[0] = 0.8, g.spacing[1] = -1.3, g.spacing[2] = 0.6;
  g.origin[0] = 2, g.origin[1] = 10, g.origin[2] = -4;
  VolumeRenderOptions opt;
  opt.sampleDistance = 0.31;
  expectSameAsSse2(sparse, g, tf, lookAt({-20, 40, -30}, {16, -8, 3}, 40, 40), opt, "negative spacing");
}

}  // namespace

TEST(VolumeSimd, UInt8SyntheticEqualsSse2) { checkSynthetic<uint8_t>(VoxelStorage::UInt8, 255); }
TEST(VolumeSimd, UInt16SyntheticEqualsSse2) { checkSynthetic<uint16_t>(VoxelStorage::UInt16, 40000); }

TEST(VolumeSimd, RealVolumesEqualSse2) {
  // ironProt: 8-bit input (UInt8); carotid: float holding integers up to ~1000 (UInt16 on request).
  const char* files[] = {"ironProt.vtk", "carotid.vtk"};
  const VoxelStorage storages[] = {VoxelStorage::UInt8, VoxelStorage::UInt16};
  for (int f = 0; f < 2; ++f) {
    mtest::FloatVolume fv;
    ASSERT_TRUE(mtest::readFloatVolume(std::string("volumes/") + files[f], fv)) << files[f];
    const int* dims = fv.dims;
    const TransferTable tf = rampTable(fv.range[0], fv.range[1], 0.25, 0.4, 1 << 16);
    BlockSparseVolume vol;
    vol.build(fv.v.data(), fv.dims, tf);  // integer-valued floats: 8/16-bit bricks (compactIntegralFloat)
    ASSERT_EQ(vol.storage(), storages[f]) << files[f];
    const VolumeGeometry& g = fv.geo;
    const Vec3 lo(g.origin[0], g.origin[1], g.origin[2]);
    const Vec3 size((dims[0] - 1) * g.spacing[0], (dims[1] - 1) * g.spacing[1], (dims[2] - 1) * g.spacing[2]);
    const Vec3 centre = lo + size * 0.5;
    const VolumeCamera cams[] = {lookAt(centre + Vec3(-1.2, 0.9, -1.6) * norm(size), centre, 64, 64),
                                 lookAt(centre + Vec3(0.3, -0.2, 2.0) * norm(size), centre, 48, 48),
                                 lookAt(centre, centre + Vec3(1, 0.3, 0.2), 32, 32, 80)};
    const double minSpacing = std::min(g.spacing[0], std::min(g.spacing[1], g.spacing[2]));
    int c = 0;
    for (const VolumeCamera& cam : cams) {
      for (int variant = 0; variant < 2; ++variant) {
        VolumeRenderOptions opt;
        opt.sampleDistance = 0.5 * minSpacing;
        opt.emptySpaceSkipping = variant == 0;
        expectSameAsSse2(vol, g, tf, cam, opt,
                         std::string(files[f]) + " camera " + std::to_string(c) + " variant " + std::to_string(variant));
      }
      ++c;
    }
  }
  if (!avx2Here()) std::printf("[ note     ] no AVX2 here: both renders took the SSE2 marcher\n");
}

TEST(VolumeSimd, UInt8BothLayoutsEqualSse2) {
  // 8-bit bricks are held in rows of y pairs up to PAIRED_MAX_BRICKS level-0 bricks (the synthetic
  // volumes above) and x fastest beyond (this one: 18 x 17 x 17 bricks), each read by its own
  // AVX2 gathers; both against the SSE2 marcher, which reads them by other code.
  const int n[3] = {140, 131, 130};
  const std::vector<uint8_t> v = noisyBlobs<uint8_t>(n, 255, 29);
  const TransferTable tf = rampTable(0, 255, 0.35, 0.5, 1 << 16);
  BlockSparseVolume vol;
  vol.build(v.data(), n, tf);
  ASSERT_EQ(vol.storage(), VoxelStorage::UInt8);
  ASSERT_GT(vol.stats().bricks, uint32_t(BlockSparseVolume::PAIRED_MAX_BRICKS));
  EXPECT_FALSE(vol.pairedRows());
  const int m[3] = {37, 29, 23};
  BlockSparseVolume small;
  small.build(noisyBlobs<uint8_t>(m, 255, 17).data(), m, tf);
  EXPECT_TRUE(small.pairedRows());
  const VolumeCamera cams[] = {lookAt({-120, 180, -150}, {70, 65, 65}, 40, 32),
                               lookAt({70, 65, 65}, {-5, 90, 20}, 24, 24, 90)};  // from inside
  for (int c = 0; c < 2; ++c)
    for (int variant = 0; variant < 2; ++variant) {
      VolumeRenderOptions opt;
      opt.sampleDistance = variant ? 0.37 : 0.5;
      opt.emptySpaceSkipping = variant == 0;
      expectSameAsSse2(vol, VolumeGeometry(), tf, cams[c], opt,
                       "x-fastest 8-bit bricks, camera " + std::to_string(c) + " variant " + std::to_string(variant));
    }
}

TEST(VolumeSimd, OnlyUnshadedFloatRaysOfApronBricksAreVectorized) {
  const int n[3] = {20, 18, 16};
  const std::vector<uint8_t> v = noisyBlobs<uint8_t>(n, 255, 3);
  const std::vector<float> vf(v.begin(), v.end());
  const TransferTable tf = rampTable(0, 255, 0.3, 0.5);
  BlockSparseVolume compact, flt;
  compact.build(v.data(), n, tf);
  flt.build(vf.data(), n, tf, mtest::floatBlocks());
  ASSERT_EQ(flt.storage(), VoxelStorage::Float32);
  const VolumeCamera cam = lookAt({-20, 30, -25}, {10, 9, 8}, 16, 16);
  VolumeRenderOptions opt;
  EXPECT_EQ(renderVolume(compact, VolumeGeometry(), tf, cam, opt).lanes, avx2Here() ? 8 : 1);
  EXPECT_EQ(renderVolume(flt, VolumeGeometry(), tf, cam, opt).lanes, 1) << "Float32 blocks: march()";
  VolumeRenderOptions shaded = opt, dbl = opt, off = opt;
  shaded.shade = true;
  dbl.doublePrecision = true;
  off.vectorized = false;
  EXPECT_EQ(renderVolume(compact, VolumeGeometry(), tf, cam, shaded).lanes, 1) << "shaded: the SSE2 marcher";
  EXPECT_EQ(renderVolume(compact, VolumeGeometry(), tf, cam, dbl).lanes, 1) << "double: march()";
  EXPECT_EQ(renderVolume(compact, VolumeGeometry(), tf, cam, off).lanes, 1) << "vectorized = false: the SSE2 marcher";
}

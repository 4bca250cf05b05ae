// Volume ray casting on the block-sparse encoding (engine/include/mtree/volume/volume.h), checked
// against analytic transmittance, a dense brute-force sampler and marcher written here, and
// itself with empty-space skipping switched off.
#include <gtest/gtest.h>

#include <vtkDataArray.h>
#include <vtkImageData.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkStructuredPoints.h>
#include <vtkStructuredPointsReader.h>

#include <cmath>
#include <cstdlib>
#include <random>
#include <string>
#include <vector>

#include "mtree/volume/volume.h"
#include "volume_test_util.h"

using namespace mtree;

namespace {

/// White, constant opacity `alpha` per unit length over [lo, hi].
TransferTable constantTable(double lo, double hi, float alpha, int n = 64) {
  std::vector<float> rgba;
  for (int i = 0; i < n; ++i) rgba.insert(rgba.end(), {1.f, 1.f, 1.f, alpha});
  return TransferTable(lo, hi, rgba, 1.0);
}

using mtest::rampTable;

struct Dense {
  int n[3];
  std::vector<float> v;
  float at(int i, int j, int k) const { return v[(size_t(k) * n[1] + j) * n[0] + i]; }
  /// Brute-force trilinear value, in double, straight from the array.
  double sample(double x, double y, double z) const {
    const double q[3] = {x, y, z};
    int c[3];
    double f[3];
    for (int a = 0; a < 3; ++a) {
      c[a] = std::min(std::max(int(std::floor(q[a])), 0), n[a] - 2);
      f[a] = std::min(1.0, std::max(0.0, q[a] - c[a]));
    }
    double s = 0;
    for (int m = 0; m < 8; ++m) {
      const int dx = m & 1, dy = (m >> 1) & 1, dz = m >> 2;
      s += (dx ? f[0] : 1 - f[0]) * (dy ? f[1] : 1 - f[1]) * (dz ? f[2] : 1 - f[2]) *
           at(c[0] + dx, c[1] + dy, c[2] + dz);
    }
    return s;
  }
};

/// Blobs (Gaussian bumps) in a zero background: most of the volume is empty space.
Dense blobs(int nx, int ny, int nz, unsigned seed, double radiusScale = 1) {
  Dense d{{nx, ny, nz}, {}};
  d.v.assign(size_t(nx) * ny * nz, 0.f);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  for (int b = 0; b < 6; ++b) {
    const double cx = u(rng) * nx, cy = u(rng) * ny, cz = u(rng) * nz, r = (2 + 4 * u(rng)) * radiusScale;
    for (int k = 0; k < nz; ++k)
      for (int j = 0; j < ny; ++j)
        for (int i = 0; i < nx; ++i) {
          const double dd = ((i - cx) * (i - cx) + (j - cy) * (j - cy) + (k - cz) * (k - cz)) / (r * r);
          d.v[(size_t(k) * ny + j) * nx + i] += float(100 * std::exp(-dd));
        }
  }
  return d;
}

using mtest::lookAt;

double maxDiff(const VolumeImage& a, const VolumeImage& b) {
  double m = 0;
  for (size_t i = 0; i < a.rgba.size(); ++i) m = std::max(m, double(std::fabs(a.rgba[i] - b.rgba[i])));
  return m;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Analytic: a constant-density box of extinction sigma. The opacity per unit length is
// 1 - exp(-sigma), corrected per step to 1 - exp(-sigma dt); N samples give exp(-sigma N dt),
// N dt in [L, L + dt].

class ConstantBox : public ::testing::Test {
 protected:
  void SetUp() override {
    const int dims[3] = {11, 7, 5};  // box [0,10] x [0,6] x [0,4] at unit spacing (x 0.5 below)
    std::vector<float> v(size_t(dims[0]) * dims[1] * dims[2], 1.f);
    tf = constantTable(0.0, 2.0, float(1 - std::exp(-sigma)));
    vol.build(v.data(), dims, tf, mtest::floatBlocks());
    geo.spacing[0] = 1.0;
    geo.spacing[1] = 0.5;  // world box [0,10] x [0,3] x [0,4]
    geo.spacing[2] = 1.0;
    geo.origin[2] = -2;  // z in [-2, 2]
    opt.sampleDistance = 1e-4;
    opt.earlyTermination = 1.0;
    opt.threads = 1;
  }
  double transmittance(const VolumeCamera& cam) {
    const VolumeImage img = renderVolume(vol, geo, tf, cam, opt);
    return 1.0 - img.rgba[3];
  }
  const double sigma = 0.3;
  TransferTable tf;
  BlockSparseVolume vol;
  VolumeGeometry geo;
  VolumeRenderOptions opt;
};

TEST_F(ConstantBox, AxisRayTransmittanceIsExpMinusSigmaL) {
  // Through the whole box along x at y = 1.5, z = 0.3: L = 10.
  const double T = transmittance(lookAt({-5, 1.5, 0.3}, {20, 1.5, 0.3}));
  EXPECT_NEAR(T, std::exp(-sigma * 10), 1e-3);
  EXPECT_GT(std::fabs(T - std::exp(-sigma * 9.9)), 1e-3) << "the test would not notice a wrong length";
}

TEST_F(ConstantBox, DiagonalRayTransmittance) {
  // From corner (0,0,-2) to corner (10,3,2) and beyond: L = |(10,3,4)|.
  const double L = std::sqrt(100.0 + 9 + 16);
  const double T = transmittance(lookAt({-10, -3, -6}, {20, 6, 6}));
  EXPECT_NEAR(T, std::exp(-sigma * L), 1e-3);
}

TEST_F(ConstantBox, RayStartingInsideTheVolume) {
  // Eye at (4, 1, 0) looking along -x: L = 4.
  const double T = transmittance(lookAt({4, 1, 0}, {-10, 1, 0}));
  EXPECT_NEAR(T, std::exp(-sigma * 4), 1e-3);
}

TEST_F(ConstantBox, RayGrazingAFace) {
  // In the plane y = 0 (the box's lower face) and along the edge y = 3, z = 2: L = 10.
  EXPECT_NEAR(transmittance(lookAt({-5, 0, 0.5}, {20, 0, 0.5})), std::exp(-sigma * 10), 1e-3);
  EXPECT_NEAR(transmittance(lookAt({-5, 3, 2}, {20, 3, 2})), std::exp(-sigma * 10), 1e-3);
}

TEST_F(ConstantBox, RaysMissingTheVolume) {
  // Just above the top face, looking away from the box, and parallel beside it.
  EXPECT_EQ(transmittance(lookAt({-5, 3.001, 0}, {20, 3.001, 0})), 1.0);
  EXPECT_EQ(transmittance(lookAt({-5, 1, 0}, {-20, 1, 0})), 1.0);
  EXPECT_EQ(transmittance(lookAt({5, 1, -2.5}, {5, 1, -20})), 1.0);
}

TEST_F(ConstantBox, ParallelProjectionGivesBoxThickness) {
  // Orthographic view along z: every pixel whose ray hits the box sees L = 4.
  VolumeCamera cam = lookAt({5, 1.5, 10}, {5, 1.5, 0}, 8, 8);
  cam.parallel = true;
  cam.parallelScale = 1.0;  // view [4, 6] x [0.5, 2.5], inside the box's x-y extent
  opt.sampleDistance = 1e-3;
  const VolumeImage img = renderVolume(vol, geo, tf, cam, opt);
  for (int p = 0; p < 64; ++p) EXPECT_NEAR(1.0 - img.rgba[4 * p + 3], std::exp(-sigma * 4), 1e-3);
}

TEST_F(ConstantBox, EveryPixelWhoseRayCrossesTheBoxIsMarched) {
  // renderVolume sets up only the pixels inside the box's projected corners (plus a margin): every
  // pixel whose ray crosses the box over a few samples must still see it, the others nothing.
  // The rays are built here as renderVolume builds them. Views: far, close, wide, from inside,
  // with corners behind the eye, non-square images, parallel.
  opt.sampleDistance = 0.02;
  std::vector<VolumeCamera> cams = {lookAt({-12, 9, -14}, {5, 1.5, 0}, 40, 30),
                                    lookAt({11.5, 3.5, 2.5}, {5, 1.5, 0}, 30, 40, 100),
                                    lookAt({5, 1.5, 0}, {20, 3, 1}, 24, 24, 120),
                                    lookAt({-0.5, 1.5, 0}, {20, 1.5, 0}, 32, 20, 150),
                                    lookAt({30, 30, 30}, {5, 1.5, 0}, 36, 28, 8)};
  VolumeCamera par = lookAt({5, 10, 1}, {5, 0, 0}, 30, 22);
  par.parallel = true;
  par.parallelScale = 4.0;
  cams.push_back(par);
  const double hiIdx[3] = {10, 6, 4};
  int seen = 0, c = 0;
  for (const VolumeCamera& cam : cams) {
    const VolumeImage img = renderVolume(vol, geo, tf, cam, opt);
    const Vec3 fwd = normalized(cam.focalPoint - cam.position), right = normalized(cross(fwd, cam.viewUp));
    const Vec3 up = cross(right, fwd);
    const double th = std::tan(cam.viewAngle * 0.5 * 3.14159265358979323846 / 180.0);
    const double aspect = double(cam.width) / cam.height;
    for (int y = 0; y < cam.height; ++y)
      for (int x = 0; x < cam.width; ++x) {
        const double nx = 2.0 * (x + 0.5) / cam.width - 1.0, ny = 2.0 * (y + 0.5) / cam.height - 1.0;
        const Vec3 o = cam.parallel ? cam.position + right * (nx * cam.parallelScale * aspect) + up * (ny * cam.parallelScale)
                                    : cam.position;
        const Vec3 d = cam.parallel ? fwd : normalized(fwd + right * (nx * th * aspect) + up * (ny * th));
        double t0 = 0, t1 = 1e300;
        for (int a = 0; a < 3; ++a) {
          const double ro = (o[a] - geo.origin[a]) / geo.spacing[a], rd = d[a] / geo.spacing[a];
          if (rd == 0) {
            if (ro < 0 || ro > hiIdx[a]) t1 = -1;
            continue;
          }
          const double ta = (0 - ro) / rd, tb = (hiIdx[a] - ro) / rd;
          t0 = std::max(t0, std::min(ta, tb));
          t1 = std::min(t1, std::max(ta, tb));
        }
        const float alpha = img.rgba[(size_t(y) * cam.width + x) * 4 + 3];
        if (t1 - t0 > 0.1) {
          ++seen;
          EXPECT_GT(alpha, 0.f) << "camera " << c << " pixel " << x << " " << y << ": crosses the box over " << t1 - t0;
        } else if (t1 < t0) {
          EXPECT_EQ(alpha, 0.f) << "camera " << c << " pixel " << x << " " << y << ": misses the box";
        }
      }
    ++c;
  }
  EXPECT_GT(seen, 1500);
}

// ---------------------------------------------------------------------------------------------
// Block-sparse storage against the dense array.

TEST(BlockSparseVolume, SamplingEqualsDenseArray) {
  const Dense d = blobs(37, 29, 21, 7);
  const TransferTable tf = rampTable(0, 100, 0.3, 0.5);
  BlockSparseVolume sparse, full;  // Float32 blocks: the input's values (QuantizedFloat: the default)
  sparse.build(d.v.data(), d.n, tf, mtest::floatBlocks());
  VolumeBuildOptions o = mtest::floatBlocks();
  o.sparse = false;
  full.build(d.v.data(), d.n, tf, o);
  ASSERT_LT(sparse.stats().blocksAllocated, sparse.stats().blocksDense) << "blobs should leave blocks empty";
  EXPECT_EQ(full.stats().blocksAllocated, full.stats().blocksDense);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> ux(-0.5, d.n[0] - 0.5), uy(-0.5, d.n[1] - 0.5), uz(-0.5, d.n[2] - 0.5);
  int present = 0, absent = 0;
  for (int s = 0; s < 20000; ++s) {
    const double x = ux(rng), y = uy(rng), z = uz(rng);
    const double ref = d.sample(x, y, z);
    double v = -1;
    ASSERT_TRUE(full.sample(x, y, z, v));
    EXPECT_NEAR(v, ref, 1e-4);
    if (sparse.sample(x, y, z, v)) {
      ++present;
      EXPECT_NEAR(v, ref, 1e-4);
    } else {
      // An absent block may only be read by an invisible cell: opacity 0 on its corner range.
      ++absent;
      int c[3];
      const double q[3] = {x, y, z};
      for (int a = 0; a < 3; ++a) c[a] = std::min(std::max(int(std::floor(q[a])), 0), d.n[a] - 2);
      float lo = 1e30f, hi = -1e30f;
      for (int m = 0; m < 8; ++m) {
        const float w = d.at(c[0] + (m & 1), c[1] + ((m >> 1) & 1), c[2] + (m >> 2));
        lo = std::min(lo, w);
        hi = std::max(hi, w);
      }
      EXPECT_EQ(tf.maxOpacity(lo, hi), 0.f);
      EXPECT_LT(hi, 30.3f) << "a cell that reaches into the ramp was dropped";
    }
  }
  EXPECT_GT(present, 100);
  EXPECT_GT(absent, 100);
}

TEST(BlockSparseVolume, MemoryIsTheVisibleBlocksPlusTenPercent) {
  const Dense d = blobs(64, 64, 64, 3);
  const TransferTable tf = rampTable(0, 100, 0.3, 0.5);
  BlockSparseVolume vol;
  vol.build(d.v.data(), d.n, tf, mtest::floatBlocks());  // QuantizedFloat checks the 16-bit bricks' memory
  const VolumeStats& s = vol.stats();
  EXPECT_GT(s.blocksAllocated, 0u);
  EXPECT_EQ(s.blockBytes, uint64_t(s.blocksAllocated) * 512 * 4);
  EXPECT_LE(double(s.bytes), 1.10 * double(s.blockBytes));
  EXPECT_LT(s.bytes, s.denseBytes / 2);
  // Every allocated block holds a corner of a visible cell (brute force over the cells).
  std::vector<uint8_t> need(s.blocksDense, 0);
  for (int k = 0; k + 1 < d.n[2]; ++k)
    for (int j = 0; j + 1 < d.n[1]; ++j)
      for (int i = 0; i + 1 < d.n[0]; ++i) {
        float lo = 1e30f, hi = -1e30f;
        for (int m = 0; m < 8; ++m) {
          const float w = d.at(i + (m & 1), j + ((m >> 1) & 1), k + (m >> 2));
          lo = std::min(lo, w);
          hi = std::max(hi, w);
        }
        if (tf.maxOpacity(lo, hi) > 0)
          for (int m = 0; m < 8; ++m)
            need[vol.voxels().pointerIndex(i + (m & 1), j + ((m >> 1) & 1), k + (m >> 2))] = 1;
      }
  uint32_t needed = 0;
  for (size_t p = 0; p < need.size(); ++p) {
    needed += need[p];
    EXPECT_EQ(need[p] != 0, vol.voxels().pointers()[p] != MT_NULL) << "block " << p;
  }
  EXPECT_EQ(needed, s.blocksAllocated);
}

TEST(BlockSparseVolume, EmptyCubesHoldNoVisibleBrickAndAreLargest) {
  // brickDistances (8/16-bit layouts): per brick and octant, the edge r of the largest cube of
  // invisible bricks with the brick at its corner, extending towards the octant (the grid's
  // outside counts as invisible). Checked against the level-0 occupancy by brute force.
  const Dense d = blobs(83, 61, 70, 11);
  std::vector<uint8_t> bytes(d.v.size());
  for (size_t i = 0; i < d.v.size(); ++i) bytes[i] = uint8_t(std::min(255.f, d.v[i] * 2.5f));
  const TransferTable tf = rampTable(0, 255, 0.3, 0.5);
  BlockSparseVolume vol;
  vol.build(bytes.data(), d.n, tf);
  ASSERT_EQ(vol.storage(), VoxelStorage::UInt8);
  const int nb[3] = {vol.levelDim(0, 0), vol.levelDim(0, 1), vol.levelDim(0, 2)};
  const std::vector<uint8_t>& dist = vol.brickDistances();
  ASSERT_EQ(dist.size(), size_t(nb[0]) * nb[1] * nb[2] * 8);
  // Whether the cube of edge e from brick (i, j, k) towards octant o holds a visible brick.
  const auto holdsVisible = [&](int i, int j, int k, int o, int e) {
    for (int c = 0; c < e; ++c)
      for (int b = 0; b < e; ++b)
        for (int a = 0; a < e; ++a) {
          const int x = i + (o & 1 ? -a : a), y = j + (o & 2 ? -b : b), z = k + (o & 4 ? -c : c);
          if (x >= 0 && y >= 0 && z >= 0 && x < nb[0] && y < nb[1] && z < nb[2] && vol.nodeVisible(0, x, y, z))
            return true;
        }
    return false;
  };
  int checked = 0, large = 0;
  for (int k = 0; k < nb[2]; ++k)
    for (int j = 0; j < nb[1]; ++j)
      for (int i = 0; i < nb[0]; ++i)
        for (int o = 0; o < 8; ++o) {
          const int r = dist[((size_t(k) * nb[1] + j) * nb[0] + i) * 8 + o];
          ASSERT_EQ(r == 0, vol.nodeVisible(0, i, j, k)) << i << " " << j << " " << k;
          if (r == 0) continue;
          EXPECT_FALSE(holdsVisible(i, j, k, o, std::min(r, 16))) << i << " " << j << " " << k << " octant " << o;
          if (r < 16) {
            EXPECT_TRUE(holdsVisible(i, j, k, o, r + 1)) << i << " " << j << " " << k << " octant " << o;
          }
          ++checked;
          large += r > 1;
        }
  EXPECT_GT(checked, 100) << "the blobs should leave bricks empty";
  EXPECT_GT(large, 10) << "some empty cubes should be larger than a brick";
}

TEST(BlockSparseVolume, TransparentTransferFunctionAllocatesNothing) {
  const Dense d = blobs(20, 20, 20, 5);
  BlockSparseVolume vol;
  vol.build(d.v.data(), d.n, constantTable(0, 100, 0.f));
  EXPECT_EQ(vol.stats().blocksAllocated, 0u);
  EXPECT_EQ(vol.stats().bricksVisible, 0u);
  const VolumeImage img = renderVolume(vol, VolumeGeometry(), constantTable(0, 100, 0.f),
                                       lookAt({10, 10, -40}, {10, 10, 10}, 16, 16), VolumeRenderOptions());
  for (float f : img.rgba) EXPECT_EQ(f, 0.f);
  EXPECT_EQ(img.samples, 0u);
}

// ---------------------------------------------------------------------------------------------
// Whole renderings: skipping on/off, sparse/dense storage, and an independent brute-force marcher.

namespace {

/// The straightforward ray walk: visit(pixel, sample position in index space) for every sample
/// k dt of every pixel's ray inside the box of `n` points, front to back.
template <typename Visit>
void forEachRaySample(const int n[3], const VolumeGeometry& g, const VolumeCamera& cam, double dt, Visit visit) {
  const Vec3 fwd = normalized(cam.focalPoint - cam.position);
  const Vec3 right = normalized(cross(fwd, cam.viewUp)), up = cross(right, fwd);
  const double th = std::tan(cam.viewAngle * M_PI / 360), aspect = double(cam.width) / cam.height;
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x) {
      const Vec3 dir = normalized(fwd + right * ((2.0 * (x + 0.5) / cam.width - 1) * th * aspect) +
                                  up * ((2.0 * (y + 0.5) / cam.height - 1) * th));
      double t0 = 0, t1 = 1e300;
      for (int a = 0; a < 3; ++a) {
        const double lo = g.origin[a], hi = g.origin[a] + (n[a] - 1) * g.spacing[a];
        double ta = (std::min(lo, hi) - cam.position[a]) / dir[a], tb = (std::max(lo, hi) - cam.position[a]) / dir[a];
        if (ta > tb) std::swap(ta, tb);
        t0 = std::max(t0, ta);
        t1 = std::min(t1, tb);
      }
      for (int k = 0; t0 <= t1 && t0 + k * dt <= t1; ++k) {
        const Vec3 p = cam.position + dir * (t0 + k * dt);
        visit(size_t(y) * cam.width + x, (p.x - g.origin[0]) / g.spacing[0], (p.y - g.origin[1]) / g.spacing[1],
              (p.z - g.origin[2]) / g.spacing[2]);
      }
    }
}

/// A table entry as the brute-force marcher composites it: premultiplied colour, opacity for dt.
void stepEntry(const TransferTable& tf, double v, double dt, double e[4]) {
  const float* t = tf.rgba().data() + 4 * tf.index(v);
  e[3] = 1 - std::pow(1 - double(t[3]), dt / tf.unitDistance());
  for (int ch = 0; ch < 3; ++ch) e[ch] = t[ch] * e[3];
}

/// The straightforward marcher: every sample from the dense array, no storage, no skipping.
std::vector<double> bruteForce(const Dense& d, const VolumeGeometry& g, const TransferTable& tf,
                               const VolumeCamera& cam, double dt) {
  std::vector<double> out(size_t(cam.width) * cam.height * 4, 0.0);
  forEachRaySample(d.n, g, cam, dt, [&](size_t pixel, double x, double y, double z) {
    double e[4];
    stepEntry(tf, d.sample(x, y, z), dt, e);
    double* o = out.data() + pixel * 4;
    for (int ch = 0; ch < 4; ++ch) o[ch] += (1 - o[3]) * e[ch];  // o[3] last: the opacity before
  });
  return out;
}

}  // namespace

TEST(VolumeRender, EqualsDenseBruteForceMarcher) {
  const Dense d = blobs(33, 30, 27, 9);
  const TransferTable tf = rampTable(0, 100, 0.25, 0.6);
  VolumeGeometry g;
  g.spacing[0] = 0.9, g.spacing[1] = 1.2, g.spacing[2] = -0.7;  // a negative spacing too
  g.origin[0] = -3, g.origin[1] = 2, g.origin[2] = 5;
  BlockSparseVolume vol;
  vol.build(d.v.data(), d.n, tf, mtest::floatBlocks());  // the exact values (QuantizedFloat: the default)
  const VolumeCamera cam = lookAt({-20, 40, -30}, {11, 20, -5}, 24, 20);
  VolumeRenderOptions opt;
  opt.sampleDistance = 0.5;
  opt.earlyTermination = 1.0;
  opt.doublePrecision = true;
  const VolumeImage img = renderVolume(vol, g, tf, cam, opt);
  const std::vector<double> ref = bruteForce(d, g, tf, cam, opt.sampleDistance);
  double m = 0, sumA = 0;
  for (size_t i = 0; i < ref.size(); ++i) m = std::max(m, std::fabs(ref[i] - img.rgba[i]));
  for (size_t i = 3; i < ref.size(); i += 4) sumA += ref[i];
  EXPECT_GT(sumA, 5.0) << "the view should see the blobs";
  EXPECT_LT(m, 1e-4);
}

// Floating-point input quantised into 16-bit bricks (VolumeBuildOptions::quantizeFloat) against
// the exact Float32 path: the error bound stated there, sample by sample and pixel by pixel.
TEST(QuantizedFloat, ImageWithinTheBoundOfTheExactPath) {
  Dense d = blobs(41, 37, 29, 5);
  std::mt19937 rng(17);
  std::normal_distribution<float> noise(0.f, 1.5f);
  for (float& x : d.v) x += noise(rng);  // CT-like: noisy, not integer-valued
  const TransferTable tf = rampTable(0, 100, 0.25, 0.6);  // 1024 entries
  BlockSparseVolume q, e;
  q.build(d.v.data(), d.n, tf);
  e.build(d.v.data(), d.n, tf, mtest::floatBlocks());
  ASSERT_EQ(q.storage(), VoxelStorage::UInt16);
  ASSERT_EQ(e.storage(), VoxelStorage::Float32);
  const double lo = q.minValue(), hi = q.maxValue(), step = q.quantizationStep();
  EXPECT_NEAR(step, (hi - lo) / 65535.0, 1e-6 * step);
  EXPECT_LE(VolumeBuildOptions::QUANTIZE_RATIO * step, (tf.hi() - tf.lo()) / (tf.size() - 1)) << "the rule";
  EXPECT_EQ(e.quantizationStep(), 0.f);
  EXPECT_LE(double(q.stats().bytes), 1.10 * double(q.stats().blockBytes)) << "memory: the visible blocks + 10%";
  EXPECT_LT(q.stats().bytes, e.stats().bytes) << "16-bit bricks hold less than the float blocks";

  // The field the quantised volume holds: every corner of a visible cell within step / 2 of the
  // input (plus the float rounding of s * step + min).
  Dense dq = d;
  for (float& x : dq.v) x = float(std::nearbyint((double(x) - lo) / step)) * q.storageScale() + q.storageOffset();
  int checked = 0;
  for (int k = 0; k + 1 < d.n[2]; ++k)
    for (int j = 0; j + 1 < d.n[1]; ++j)
      for (int i = 0; i + 1 < d.n[0]; ++i) {
        float c[8];
        if (!q.cellCorners(i, j, k, c)) continue;
        ++checked;
        for (int m = 0; m < 8; ++m) {
          const int x = i + (m & 1), y = j + ((m >> 1) & 1), z = k + (m >> 2);
          ASSERT_EQ(c[m], dq.at(x, y, z));
          ASSERT_LE(std::fabs(double(c[m]) - d.at(x, y, z)), step / 2 + 1e-6 * (std::fabs(hi) + std::fabs(lo)));
        }
      }
  EXPECT_GT(checked, 1000);

  // Per pixel: the exact and the quantised rays sample the same points; the bound is the sum,
  // over the samples whose table entry differs, of that change in premultiplied colour plus
  // opacity. Samples move by at most step / 2 <= 1/32 entry: an entry changes by at most one.
  VolumeGeometry g;
  g.spacing[0] = 0.9, g.spacing[1] = 1.1, g.spacing[2] = 0.8;
  const VolumeCamera cam = lookAt({-25, 45, -30}, {18, 20, 11}, 32, 28);
  VolumeRenderOptions opt;
  opt.sampleDistance = 0.5;
  opt.earlyTermination = 1.0;  // no ray stops at a different sample
  std::vector<double> bound(size_t(cam.width) * cam.height * 4, 0.0);
  uint64_t samples = 0, changed = 0;
  forEachRaySample(d.n, g, cam, opt.sampleDistance, [&](size_t pixel, double x, double y, double z) {
    const double ve = d.sample(x, y, z), vq = dq.sample(x, y, z);
    EXPECT_LE(std::fabs(ve - vq), step / 2 + 1e-6 * (std::fabs(hi) + std::fabs(lo)));
    const int ie = tf.index(ve), iq = tf.index(vq);
    EXPECT_LE(std::abs(ie - iq), 1);
    ++samples;
    if (ie == iq) return;
    ++changed;
    double ee[4], eq[4];
    stepEntry(tf, ve, opt.sampleDistance, ee);
    stepEntry(tf, vq, opt.sampleDistance, eq);
    for (int ch = 0; ch < 4; ++ch) bound[pixel * 4 + ch] += std::fabs(ee[ch] - eq[ch]) + std::fabs(ee[3] - eq[3]);
  });
  EXPECT_LT(double(changed), 4.0 * step / ((tf.hi() - tf.lo()) / (tf.size() - 1)) * double(samples) + 10)
      << "only samples within step / 2 of an entry boundary change entry";
  for (bool dbl : {false, true}) {
    VolumeRenderOptions o = opt;
    o.doublePrecision = dbl;
    const VolumeImage a = renderVolume(q, g, tf, cam, o), b = renderVolume(e, g, tf, cam, o);
    double sumA = 0, worst = 0;
    for (size_t i = 0; i < a.rgba.size(); ++i) {
      EXPECT_LE(std::fabs(a.rgba[i] - b.rgba[i]), bound[i] + 2e-4) << "pixel " << i / 4 << " channel " << i % 4;
      worst = std::max(worst, double(std::fabs(a.rgba[i] - b.rgba[i])));
    }
    for (size_t i = 3; i < b.rgba.size(); i += 4) sumA += b.rgba[i];
    EXPECT_GT(sumA, 5.0) << "the view should see the blobs";
    EXPECT_LT(worst, 2.0 / 255) << "invisible in an 8-bit image";
    // The quantised image is the brute-force image of the field it holds.
    const std::vector<double> ref = bruteForce(dq, g, tf, cam, opt.sampleDistance);
    double m = 0;
    for (size_t i = 0; i < ref.size(); ++i) m = std::max(m, std::fabs(ref[i] - a.rgba[i]));
    EXPECT_LT(m, 1e-4) << (dbl ? "double" : "float");
  }
}

TEST(QuantizedFloat, FineTablesAndWideRangesKeepFloatBlocks) {
  Dense d = blobs(20, 18, 16, 4);
  for (float& x : d.v) x += 0.3f;
  BlockSparseVolume a, b, c;
  a.build(d.v.data(), d.n, rampTable(0, 100, 0.2, 0.5, 1024));
  EXPECT_EQ(a.storage(), VoxelStorage::UInt16);
  // A table with entries finer than 16 quantisation steps: the exact float path.
  b.build(d.v.data(), d.n, rampTable(0, 100, 0.2, 0.5, 65536));
  EXPECT_EQ(b.storage(), VoxelStorage::Float32);
  // A table over a narrow window of a wide range: its entries are finer than 16 steps too.
  d.v[3] = 1e6f;
  c.build(d.v.data(), d.n, rampTable(0, 100, 0.2, 0.5, 1024));
  EXPECT_EQ(c.storage(), VoxelStorage::Float32);
  const std::vector<double> dv(d.v.begin(), d.v.end());
  BlockSparseVolume dd;
  dd.build(dv.data(), d.n, rampTable(0, 2e6, 0.2, 0.5, 1024));
  EXPECT_EQ(dd.storage(), VoxelStorage::UInt16) << "double input is quantised alike";
}

TEST(VolumeRender, SkippingEqualsNoSkippingOnBlobs) {
  const Dense d = blobs(70, 50, 40, 21);
  const TransferTable tf = rampTable(0, 100, 0.3, 0.4);
  BlockSparseVolume flt, quantized;
  flt.build(d.v.data(), d.n, tf, mtest::floatBlocks());
  quantized.build(d.v.data(), d.n, tf);
  ASSERT_EQ(quantized.storage(), VoxelStorage::UInt16);
  const VolumeCamera cam = lookAt({-30, 70, -50}, {35, 25, 20}, 48, 40);
  for (int variant = 0; variant < 8; ++variant) {
    // Float32 blocks sample every cell of a visible brick; apron bricks only the visible cells,
    // with or without skipping.
    const BlockSparseVolume& vol = variant & 4 ? quantized : flt;
    VolumeRenderOptions opt;
    opt.sampleDistance = 0.37;
    opt.doublePrecision = variant & 1;
    opt.shade = variant & 2;
    opt.earlyTermination = 0.95;
    VolumeRenderOptions noSkip = opt;
    noSkip.emptySpaceSkipping = false;
    const VolumeImage a = renderVolume(vol, VolumeGeometry(), tf, cam, opt);
    const VolumeImage b = renderVolume(vol, VolumeGeometry(), tf, cam, noSkip);
    EXPECT_LE(maxDiff(a, b), 1e-6) << "variant " << variant;
    EXPECT_GT(a.skips, 0u);
    if (variant & 4) EXPECT_EQ(a.samples, b.samples) << "the visible cells, either way";
    else EXPECT_LT(a.samples, b.samples) << "skipping should classify fewer samples";
  }
}

TEST(VolumeRender, SkippingEqualsNoSkippingOnIronProtein) {
  mtest::FloatVolume fv;
  ASSERT_TRUE(mtest::readFloatVolume("volumes/ironProt.vtk", fv));
  const TransferTable tf = rampTable(fv.range[0], fv.range[1], 0.4, 0.3);
  BlockSparseVolume sparse, full;
  sparse.build(fv.v.data(), fv.dims, tf, mtest::floatBlocks());
  VolumeBuildOptions o = mtest::floatBlocks();
  o.sparse = false;
  full.build(fv.v.data(), fv.dims, tf, o);
  const VolumeGeometry& g = fv.geo;
  const VolumeCamera cam = lookAt({-60, 100, -80}, {34, 34, 34}, 40, 40);
  VolumeRenderOptions opt;
  opt.sampleDistance = 0.5;
  VolumeRenderOptions noSkip = opt;
  noSkip.emptySpaceSkipping = false;
  const VolumeImage a = renderVolume(sparse, g, tf, cam, opt);
  const VolumeImage b = renderVolume(sparse, g, tf, cam, noSkip);
  const VolumeImage c = renderVolume(full, g, tf, cam, noSkip);
  EXPECT_LE(maxDiff(a, b), 1e-6);
  EXPECT_LE(maxDiff(a, c), 1e-6) << "absent blocks must not change the picture";
  double sumA = 0;
  for (size_t i = 3; i < a.rgba.size(); i += 4) sumA += a.rgba[i];
  EXPECT_GT(sumA, 10.0);
  EXPECT_LT(sparse.stats().blocksAllocated, sparse.stats().blocksDense);
}

TEST(VolumeRender, ImageSampleDistanceInterpolatesACoarseImage) {
  const Dense d = blobs(30, 30, 30, 2);
  const TransferTable tf = rampTable(0, 100, 0.3, 0.5);
  BlockSparseVolume vol;
  vol.build(d.v.data(), d.n, tf);
  VolumeRenderOptions opt;
  const VolumeCamera cam = lookAt({15, 15, -60}, {15, 15, 15}, 64, 64);
  const VolumeImage full = renderVolume(vol, VolumeGeometry(), tf, cam, opt);
  opt.imageSampleDistance = 2;
  const VolumeImage half = renderVolume(vol, VolumeGeometry(), tf, cam, opt);
  EXPECT_EQ(half.rays, 32u * 32u);
  EXPECT_EQ(half.rgba.size(), full.rgba.size());
  double err = 0, sum = 0;
  for (size_t i = 0; i < full.rgba.size(); ++i) {
    err += std::fabs(full.rgba[i] - half.rgba[i]);
    sum += full.rgba[i];
  }
  EXPECT_GT(sum, 1.0);
  EXPECT_LT(err / sum, 0.25);
}

TEST(VolumeRender, RenderingIntoACallerBufferGivesTheSameImage) {
  // The overload the VTK filter uses (it keeps its output array across frames): full size and
  // with an image sample distance (rendered small, then upsampled into the buffer).
  const Dense d = blobs(30, 26, 22, 5);
  const TransferTable tf = rampTable(0, 100, 0.3, 0.5);
  BlockSparseVolume vol;
  vol.build(d.v.data(), d.n, tf);
  const VolumeCamera cam = lookAt({15, 40, -50}, {15, 13, 11}, 40, 30);
  for (double isd : {1.0, 2.5}) {
    VolumeRenderOptions opt;
    opt.imageSampleDistance = isd;
    const VolumeImage a = renderVolume(vol, VolumeGeometry(), tf, cam, opt);
    std::vector<float> buf(size_t(40) * 30 * 4, -1.f);  // stale content must be overwritten
    const VolumeImage b = renderVolume(vol, VolumeGeometry(), tf, cam, opt, buf.data());
    EXPECT_TRUE(b.rgba.empty());
    EXPECT_EQ(a.rgba, buf) << "image sample distance " << isd;
    EXPECT_EQ(a.samples, b.samples);
    EXPECT_EQ(a.rays, b.rays);
  }
}

// ---------------------------------------------------------------------------------------------
// Bad input: a clear exception, never a crash.

TEST(VolumeEdgeCases, BadInputIsRejectedClearly) {
  BlockSparseVolume vol;
  const TransferTable tf = constantTable(0, 1, 0.5f);
  std::vector<float> v(100, 1.f);
  const int thin[3] = {10, 10, 1};
  EXPECT_THROW(vol.build(v.data(), thin, tf), std::invalid_argument);
  const int zero[3] = {0, 0, 0};
  EXPECT_THROW(vol.build(v.data(), zero, tf), std::invalid_argument);
  const int ok[3] = {5, 5, 4};
  EXPECT_THROW(vol.build(static_cast<const float*>(nullptr), ok, tf), std::invalid_argument);
  std::vector<float> nan(100, std::nanf(""));
  EXPECT_THROW(vol.build(nan.data(), ok, tf), std::invalid_argument);
  EXPECT_THROW(TransferTable(1, 1, std::vector<float>(8, 0.f)), std::invalid_argument);
  EXPECT_THROW(TransferTable(0, 1, std::vector<float>(3, 0.f)), std::invalid_argument);
  EXPECT_THROW(renderVolume(vol, VolumeGeometry(), tf, VolumeCamera(), VolumeRenderOptions()), std::invalid_argument)
      << "rendering an unbuilt volume";

  vol.build(v.data(), ok, tf, mtest::floatBlocks());
  VolumeGeometry g;
  g.spacing[1] = 0;
  EXPECT_THROW(renderVolume(vol, g, tf, VolumeCamera(), VolumeRenderOptions()), std::invalid_argument);
  VolumeRenderOptions bad;
  bad.sampleDistance = 0;
  EXPECT_THROW(renderVolume(vol, VolumeGeometry(), tf, VolumeCamera(), bad), std::invalid_argument);
  VolumeCamera same;
  same.focalPoint = same.position;
  EXPECT_THROW(renderVolume(vol, VolumeGeometry(), tf, same, VolumeRenderOptions()), std::invalid_argument);
}

TEST(VolumeEdgeCases, NonFiniteScalarsBecomeTheLowestFiniteValue) {
  std::vector<float> v(4 * 4 * 4, 5.f);
  v[10] = std::nanf("");
  v[20] = std::numeric_limits<float>::infinity();
  v[30] = 2.f;
  const int dims[3] = {4, 4, 4};
  BlockSparseVolume vol;
  vol.build(v.data(), dims, constantTable(0, 10, 0.5f));
  EXPECT_EQ(vol.stats().nonFinite, 2u);
  EXPECT_EQ(vol.minValue(), 2.f);
  EXPECT_EQ(vol.maxValue(), 5.f);
  double at10 = -1;
  ASSERT_TRUE(vol.sample(2, 2, 0, at10));  // index 10 = (2, 2, 0)
  EXPECT_EQ(at10, 2.0);
  BlockSparseVolume exact;
  exact.build(v.data(), dims, constantTable(0, 10, 0.5f), mtest::floatBlocks());
  EXPECT_EQ(exact.voxels().get(2, 2, 0), 2.f);
  const VolumeImage img = renderVolume(vol, VolumeGeometry(), constantTable(0, 10, 0.5f),
                                       lookAt({1.5, 1.5, -10}, {1.5, 1.5, 1.5}, 8, 8), VolumeRenderOptions());
  for (float f : img.rgba) EXPECT_TRUE(std::isfinite(f));
}

TEST(VolumeEdgeCases, IntegerScalarsAndTwoVoxelAxes) {
  std::vector<int16_t> v(2 * 3 * 2, 300);
  const int dims[3] = {2, 3, 2};
  BlockSparseVolume vol;
  vol.build(v.data(), dims, constantTable(0, 1000, 0.2f));
  EXPECT_EQ(vol.stats().cells, 2u);
  double s = 0;
  ASSERT_TRUE(vol.sample(0.5, 1.5, 0.5, s));
  EXPECT_EQ(s, 300.0);
}

// ---------------------------------------------------------------------------------------------
// UInt8/UInt16 apron bricks (8/16-bit input, or integer-valued float with compactIntegralFloat)
// against the Float32 blocks and the dense array; their SSE2 marcher against the general one.

namespace {

/// Blobs rounded to integers in [lo, lo + 255 * scale], as type T.
template <typename T>
std::vector<T> integerBlobs(const Dense& d, double lo, double scale) {
  std::vector<T> v(d.v.size());
  for (size_t i = 0; i < v.size(); ++i) v[i] = static_cast<T>(std::lround(lo + d.v[i] * 2.55 * scale));
  return v;
}

/// The 8-bit layout renderVolume reads: rows of y pairs up to PAIRED_MAX_BRICKS level-0 bricks.
bool pairedExpected(VoxelStorage s, const int n[3]) {
  const int64_t bricks = int64_t((n[0] + 6) / 8) * ((n[1] + 6) / 8) * ((n[2] + 6) / 8);
  return s == VoxelStorage::UInt8 && bricks <= BlockSparseVolume::PAIRED_MAX_BRICKS;
}

/// `large`: a grid of more than PAIRED_MAX_BRICKS bricks (8-bit: the x-fastest 9^3 layout).
template <typename T>
void expectCompactMatchesFloat(VoxelStorage expected, double lo, double scale, bool large = false) {
  const Dense d = large ? blobs(137, 129, 129, 13, 5.0) : blobs(41, 35, 29, 13);
  const std::vector<T> vi = integerBlobs<T>(d, lo, scale);
  Dense asFloat{{d.n[0], d.n[1], d.n[2]}, std::vector<float>(vi.begin(), vi.end())};
  const double hi = lo + 255 * scale;
  const TransferTable tf = rampTable(lo, hi, 0.3, 0.5);
  BlockSparseVolume compact, flt;
  compact.build(vi.data(), d.n, tf);
  VolumeBuildOptions o = mtest::floatBlocks();
  o.compact = false;
  flt.build(vi.data(), d.n, tf, o);
  ASSERT_EQ(compact.storage(), expected);
  ASSERT_EQ(flt.storage(), VoxelStorage::Float32);
  EXPECT_EQ(compact.pairedRows(), pairedExpected(expected, d.n));
  EXPECT_EQ(compact.pairedRows(), expected == VoxelStorage::UInt8 && !large) << "the test wants both 8-bit layouts";
  EXPECT_EQ(compact.stats().blocksAllocated, flt.stats().blocksAllocated);
  EXPECT_EQ(compact.stats().blockBytes, flt.stats().blockBytes);
  EXPECT_LE(double(compact.stats().bytes), 1.10 * double(compact.stats().blockBytes));
  EXPECT_LT(compact.stats().bricksStored, compact.stats().bricks) << "blobs should leave bricks empty";
  // Sampling: the apron bricks hold every corner of a visible cell, exactly.
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> ux(-0.5, d.n[0] - 0.5), uy(-0.5, d.n[1] - 0.5), uz(-0.5, d.n[2] - 0.5);
  int present = 0;
  for (int s = 0; s < 20000; ++s) {
    const double x = ux(rng), y = uy(rng), z = uz(rng);
    double a = 0, b = 0;
    const bool pa = compact.sample(x, y, z, a), pb = flt.sample(x, y, z, b);
    if (pa) {
      ++present;
      EXPECT_NEAR(a, asFloat.sample(x, y, z), 1e-6 * std::max(1.0, std::fabs(hi)));
    }
    if (pa != pb) {
      // Present in one layout only (the apron brick holds all its cells, the float blocks the
      // corners of visible cells): the cell must be invisible.
      int c[3];
      const double q[3] = {x, y, z};
      for (int a3 = 0; a3 < 3; ++a3) c[a3] = std::min(std::max(int(std::floor(q[a3])), 0), d.n[a3] - 2);
      float mn = 1e30f, mx = -1e30f;
      for (int m = 0; m < 8; ++m) {
        const float w = asFloat.at(c[0] + (m & 1), c[1] + ((m >> 1) & 1), c[2] + (m >> 2));
        mn = std::min(mn, w);
        mx = std::max(mx, w);
      }
      EXPECT_EQ(tf.maxOpacity(mn, mx), 0.f) << "a visible cell missing from one layout";
    }
  }
  EXPECT_GT(present, 1000);
  // Whole images: the SSE2 float marcher and the general double one, skipping on and off, and the
  // float blocks, on a perspective view through the blobs.
  VolumeGeometry g;
  g.spacing[0] = 0.8, g.spacing[1] = 1.1, g.spacing[2] = 1.3;
  const VolumeCamera cam = large ? lookAt({-80, 160, -130}, {55, 70, 84}, 48, 40)
                                 : lookAt({-25, 50, -40}, {16, 19, 19}, 40, 36);
  for (int variant = 0; variant < 4; ++variant) {
    VolumeRenderOptions opt;
    opt.sampleDistance = 0.45;
    opt.shade = variant & 1;
    opt.earlyTermination = (variant & 2) ? 1.0 : 0.95;
    VolumeRenderOptions noSkip = opt, dbl = opt;
    noSkip.emptySpaceSkipping = false;
    dbl.doublePrecision = true;
    const VolumeImage a = renderVolume(compact, g, tf, cam, opt);
    const VolumeImage b = renderVolume(compact, g, tf, cam, noSkip);
    const VolumeImage c = renderVolume(flt, g, tf, cam, opt);
    const VolumeImage e = renderVolume(compact, g, tf, cam, dbl);
    const VolumeImage f = renderVolume(flt, g, tf, cam, dbl);
    EXPECT_EQ(maxDiff(a, b), 0.0) << "variant " << variant << ": skipping must not change the image";
    EXPECT_EQ(a.samples, b.samples);
    EXPECT_GT(a.skips, 0u);
    EXPECT_LE(maxDiff(a, c), 2e-4) << "variant " << variant << ": compact vs float storage";
    EXPECT_LE(maxDiff(a, e), 2e-4) << "variant " << variant << ": SSE2 float marcher vs general double";
    EXPECT_LE(maxDiff(e, f), 1e-5) << "variant " << variant << ": double precision, compact vs float";
    double sumA = 0;
    for (size_t i = 3; i < a.rgba.size(); i += 4) sumA += a.rgba[i];
    EXPECT_GT(sumA, 5.0);
  }
}

}  // namespace

TEST(CompactStorage, UInt8MatchesFloat) { expectCompactMatchesFloat<uint8_t>(VoxelStorage::UInt8, 0, 1); }
TEST(CompactStorage, UInt8LargeGridMatchesFloat) {
  expectCompactMatchesFloat<uint8_t>(VoxelStorage::UInt8, 0, 1, true);
}
TEST(CompactStorage, Int8MatchesFloat) { expectCompactMatchesFloat<int8_t>(VoxelStorage::UInt8, -128, 1); }
TEST(CompactStorage, UInt16MatchesFloat) { expectCompactMatchesFloat<uint16_t>(VoxelStorage::UInt16, 1000, 200); }
TEST(CompactStorage, Int16MatchesFloat) { expectCompactMatchesFloat<int16_t>(VoxelStorage::UInt16, -20000, 150); }

TEST(CompactStorage, IntegerValuedFloatIsStoredLosslessly) {
  const Dense d = blobs(20, 18, 16, 4);
  std::vector<float> v(d.v.size());
  for (size_t i = 0; i < v.size(); ++i) v[i] = std::round(d.v[i] * 3.f);  // 0..300: needs 16 bits
  const TransferTable tf = rampTable(0, 300, 0.2, 0.5);
  BlockSparseVolume a, b;
  a.build(v.data(), d.n, tf, mtest::floatBlocks());
  EXPECT_EQ(a.storage(), VoxelStorage::Float32) << "compactIntegralFloat off: float blocks";
  const VolumeBuildOptions o;
  EXPECT_TRUE(o.compactIntegralFloat) << "on by default, as vtkMatrixTreeVolumeRayCaster builds";
  b.build(v.data(), d.n, tf, o);
  EXPECT_EQ(b.storage(), VoxelStorage::UInt16);
  v[7] += 0.5f;  // one fractional value: stays float (or is quantised, quantizeFloat)
  VolumeBuildOptions exact = o;
  exact.quantizeFloat = false;
  BlockSparseVolume c;
  c.build(v.data(), d.n, tf, exact);
  EXPECT_EQ(c.storage(), VoxelStorage::Float32);
  const VolumeCamera cam = lookAt({-20, 30, -30}, {10, 9, 8}, 24, 24);
  VolumeRenderOptions opt;
  opt.sampleDistance = 0.5;
  EXPECT_LE(maxDiff(renderVolume(a, VolumeGeometry(), tf, cam, opt), renderVolume(b, VolumeGeometry(), tf, cam, opt)),
            2e-4);
}

TEST(CompactStorage, RaysAlongAxesAndFromInsideOnFarFaces) {
  // Axis-aligned rays on the grid's last plane (every sample on the far face needs clamping) and
  // an eye inside the volume: the SSE2 marcher's general-path fallback against the double one.
  std::vector<uint8_t> v(size_t(17) * 9 * 12);
  for (size_t i = 0; i < v.size(); ++i) v[i] = uint8_t((i * 37) % 251);
  const int dims[3] = {17, 9, 12};
  const TransferTable tf = rampTable(0, 255, 0.1, 0.3);
  BlockSparseVolume vol;
  vol.build(v.data(), dims, tf);
  ASSERT_EQ(vol.storage(), VoxelStorage::UInt8);
  const VolumeCamera cams[] = {lookAt({-5, 8, 11}, {30, 8, 11}, 9, 9), lookAt({16, -4, 0}, {16, 30, 0}, 9, 9),
                               lookAt({8, 4, 5}, {30, 20, 40}, 9, 9), lookAt({16, 8, 30}, {16, 8, -10}, 9, 9)};
  for (const VolumeCamera& cam : cams) {
    VolumeRenderOptions opt;
    opt.sampleDistance = 0.25;
    opt.earlyTermination = 1.0;
    VolumeRenderOptions dbl = opt;
    dbl.doublePrecision = true;
    const VolumeImage a = renderVolume(vol, VolumeGeometry(), tf, cam, opt);
    const VolumeImage b = renderVolume(vol, VolumeGeometry(), tf, cam, dbl);
    EXPECT_LE(maxDiff(a, b), 2e-4);
    EXPECT_EQ(a.samples, b.samples);
  }
}

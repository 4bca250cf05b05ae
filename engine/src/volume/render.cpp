// renderVolume: the frame's constants, the image in tiles of rays, and for each ray its marcher
// (march.h: march or the SSE2 marchApron; march_avx2.cpp: the AVX2 marcher, chosen at run time).
// See engine/include/mtree/volume/volume.h for the design and why skipping is exact.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include <omp.h>

#include "frame.h"
#include "march.h"
#include "mtree/core/parallel.h"
#include "mtree/volume/volume.h"

namespace mtree {
namespace volume_detail {

#if MATRIXTREE_VOLUME_AVX2
bool clampedSampleUnshaded(const Frame& F, const float p[4], float C[4], float& T, uint64_t& samples) {
  AccT acc;
  acc.c = _mm_loadu_ps(C);
  acc.T = T;
  const bool opaque = apronClampedSampleAt<false>(F, p, nullptr, acc, samples);
  _mm_storeu_ps(C, acc.c);
  T = acc.T;
  return opaque;
}
#endif

namespace {

/// The CPU runs AVX2 (and the OS saves its registers: GCC's cpu model checks both), and the
/// engine was built with march_avx2.cpp.
bool cpuHasAvx2() {
#if MATRIXTREE_VOLUME_AVX2
  static const bool has = [] {
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx2") != 0;
  }();
  return has;
#else
  return false;
#endif
}

/// The pixels whose rays can meet the volume's box, conservatively: the rectangle around its 8
/// corners projected onto the image, widened by 2 pixels (round-off of the projection is far
/// below that); the whole image when a corner is not in front of a perspective eye. A pixel
/// outside it is not set up at all: its ray would miss the box anyway (the box is convex, so it
/// projects into the corners' hull), and its pixel stays 0 as a missing ray leaves it.
struct PixelRect {
  int x0, x1, y0, y1;  // inclusive
};
PixelRect hitRect(const VolumeGeometry& geo, const VolumeCamera& cam, const int n[3], int w, int h, double aspect,
                  double th, Vec3 fwd, Vec3 right, Vec3 up) {
  const PixelRect all{0, w - 1, 0, h - 1};
  double nx0 = std::numeric_limits<double>::infinity(), nx1 = -nx0, ny0 = nx0, ny1 = -nx0;
  for (int c = 0; c < 8; ++c) {
    Vec3 p;
    for (int a = 0; a < 3; ++a) p[a] = geo.origin[a] + ((c >> a) & 1 ? double(n[a] - 1) : 0.0) * geo.spacing[a];
    const Vec3 v = p - cam.position;
    double sx, sy;  // the corner's normalized image coordinates (-1..1 across the image)
    if (cam.parallel) {
      sx = dot(v, right) / (cam.parallelScale * aspect);
      sy = dot(v, up) / cam.parallelScale;
    } else {
      const double z = dot(v, fwd);
      if (!(z > 1e-6 * norm(v))) return all;  // behind or beside the eye: no bound from this view
      sx = dot(v, right) / (z * th * aspect);
      sy = dot(v, up) / (z * th);
    }
    nx0 = std::min(nx0, sx), nx1 = std::max(nx1, sx), ny0 = std::min(ny0, sy), ny1 = std::max(ny1, sy);
  }
  if (!std::isfinite(nx0 + nx1 + ny0 + ny1)) return all;
  // Pixel x has nx = 2 (x + 0.5) / w - 1, so x = (nx + 1) w / 2 - 0.5.
  const auto lo = [](double v, int size) { return int(std::max(-1.0, std::min(double(size), std::floor(v) - 2))); };
  const auto hi = [](double v, int size) { return int(std::max(-1.0, std::min(double(size), std::ceil(v) + 2))); };
  PixelRect r;
  r.x0 = std::max(0, lo((nx0 + 1) * w / 2 - 0.5, w));
  r.x1 = std::min(w - 1, hi((nx1 + 1) * w / 2 - 0.5, w));
  r.y0 = std::max(0, lo((ny0 + 1) * h / 2 - 0.5, h));
  r.y1 = std::min(h - 1, hi((ny1 + 1) * h / 2 - 0.5, h));
  return r;
}

/// The last part of every camera's ray set-up: the interval of the ray ro + t r.rd (index space)
/// inside the volume's box [0, hiIdx] (an axis the ray is parallel to sets no bound, and misses
/// when ro lies outside it), then r.t0, r.hit and r.kEnd, the number of steps dt that fit.
inline void clipPixelRay(const double ro[3], const double hiIdx[3], double dt, PixelRay& r) {
  double t0 = 0, t1 = std::numeric_limits<double>::infinity();
  bool miss = false;
  for (int a = 0; a < 3; ++a) {
    if (r.rd[a] == 0) {
      if (ro[a] < 0 || ro[a] > hiIdx[a]) miss = true;
      continue;
    }
    double ta = (0 - ro[a]) / r.rd[a], tb = (hiIdx[a] - ro[a]) / r.rd[a];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
  }
  r.t0 = t0;
  r.hit = !miss && t0 <= t1;
  r.kEnd = 0;
  if (r.hit) {
    const double kx = std::floor((t1 - t0) / dt);
    r.kEnd = kx > 4e15 ? int64_t(4e15) : static_cast<int64_t>(kx);
  }
}

/// The scalar set-up of pixel column x of the row in S: marchImage's per-pixel arithmetic.
inline PixelRay setupRay(const RaySetupFrame& S, int x) {
  PixelRay r;
  const Vec3 d = normalized(Vec3(S.fwd[0], S.fwd[1], S.fwd[2]) + Vec3(S.rightX[0][x], S.rightX[1][x], S.rightX[2][x]) +
                            Vec3(S.upY[0], S.upY[1], S.upY[2]));
  for (int a = 0; a < 3; ++a) {
    r.d[a] = d[a];
    r.rd[a] = d[a] / S.spacing[a];
  }
  clipPixelRay(S.roEye, S.hiIdx, S.dt, r);
  return r;
}

/// march() for every storage; for UInt8/UInt16 in float the SSE2 marcher (the rays the AVX2
/// marcher takes are queued by the image loop instead: pairable).
template <typename R, bool Skip, bool Shade, typename Fetch>
inline void marchRay(const Frame& F, const Fetch& fetch, const double o[3], const double d[3], double t0,
                     int64_t kEnd, const double viewDir[3], float out[4], uint64_t& samples, uint64_t& skips) {
  march<R, Fetch, Skip, Shade>(F, fetch, o, d, t0, kEnd, viewDir, out, samples, skips);
}
#if defined(__SSE2__)
template <typename R, bool Skip, bool Shade, typename T>
inline void marchRay(const Frame& F, const ApronFetch<T>& fetch, const double o[3], const double d[3], double t0,
                     int64_t kEnd, const double viewDir[3], float out[4], uint64_t& samples, uint64_t& skips) {
  if constexpr (std::is_same<R, float>::value)
    marchApron<T, Skip, Shade>(F, fetch, o, d, t0, kEnd, viewDir, out, samples, skips);
  else
    march<R, ApronFetch<T>, Skip, Shade>(F, fetch, o, d, t0, kEnd, viewDir, out, samples, skips);
}
#endif

/// Whether the image loop queues a ray for the AVX2 marcher (unshaded float rays of apron bricks,
/// where renderVolume chose it: F.lanes == 8), and the queue's consumer: nothing for other
/// storages or settings.
template <typename R, bool Shade, typename Fetch>
inline bool pairable(const Frame&, const Fetch&, int64_t) {
  return false;
}
template <typename R, bool Skip, bool Shade, typename Fetch>
inline void marchPending(const Frame&, const Fetch&, const PendingRayList&, uint64_t&, uint64_t&) {}
#if MATRIXTREE_VOLUME_AVX2
template <typename T>
constexpr ApronVoxel apronVoxel() {
  return std::is_same<T, Paired8>::value ? ApronVoxel::Paired8
                                         : (std::is_same<T, uint8_t>::value ? ApronVoxel::UInt8 : ApronVoxel::UInt16);
}
template <typename R, bool Shade, typename T>
inline bool pairable(const Frame& F, const ApronFetch<T>&, int64_t kEnd) {
  return std::is_same<R, float>::value && !Shade && F.lanes == 8 && kEnd < (int64_t(1) << 24) - 8;
}
template <typename R, bool Skip, bool Shade, typename T>
inline void marchPending(const Frame& F, const ApronFetch<T>& fetch, const PendingRayList& list, uint64_t& samples,
                         uint64_t& skips) {
  marchApronAvx2(F, fetch.bricks(), apronVoxel<T>(), Skip, list.rays, list.count, samples, skips);
}
#endif

template <typename R, typename Fetch, bool Skip, bool Shade>
void marchImage(const Frame& F, const Fetch& fetch, const VolumeGeometry& geo, const VolumeCamera& cam, int w, int h,
                double aspect, int threads, float* rgba, uint64_t& samples, uint64_t& skips,
                uint64_t& rays) {
  const Vec3 pos = cam.position;
  const Vec3 fwd = normalized(cam.focalPoint - cam.position);
  const Vec3 right = normalized(cross(fwd, cam.viewUp));
  const Vec3 up = cross(right, fwd);
  const double th = std::tan(cam.viewAngle * 0.5 * 3.14159265358979323846 / 180.0);
  const double hiIdx[3] = {double(F.n[0] - 1), double(F.n[1] - 1), double(F.n[2] - 1)};
  const PixelRect hit = hitRect(geo, cam, F.n, w, h, aspect, th, fwd, right, up);
  // What depends on the column or the row only, computed once (the same expressions as per pixel):
  // nx, ny; a perspective ray's direction terms right * (nx th aspect), up * (ny th); its origin.
  std::vector<double> nxs(static_cast<size_t>(w)), nys(static_cast<size_t>(h));
  std::vector<Vec3> rightX(static_cast<size_t>(w)), upY(static_cast<size_t>(h));
  std::vector<double> rightXa[3];  // the same per axis, padded by 3 columns for setupRays4
  for (int a = 0; a < 3; ++a) rightXa[a].assign(size_t(w) + 3, 0.0);
  for (int x = 0; x < w; ++x) {
    nxs[size_t(x)] = 2.0 * (x + 0.5) / w - 1.0;
    rightX[size_t(x)] = right * (nxs[size_t(x)] * th * aspect);
    for (int a = 0; a < 3; ++a) rightXa[a][size_t(x)] = rightX[size_t(x)][a];
  }
  for (int y = 0; y < h; ++y) {
    nys[size_t(y)] = 2.0 * (y + 0.5) / h - 1.0;
    upY[size_t(y)] = up * (nys[size_t(y)] * th);
  }
  double roEye[3];
  for (int a = 0; a < 3; ++a) roEye[a] = (pos[a] - geo.origin[a]) / geo.spacing[a];
  RaySetupFrame S0;
  for (int a = 0; a < 3; ++a) {
    S0.fwd[a] = fwd[a];
    S0.spacing[a] = geo.spacing[a];
    S0.roEye[a] = roEye[a];
    S0.hiIdx[a] = hiIdx[a];
    S0.rightX[a] = rightXa[a].data();
  }
  S0.dt = F.dt;
#if MATRIXTREE_VOLUME_AVX2
  const bool setup4 = F.setup4 && !cam.parallel;
#else
  const bool setup4 = false;
#endif
  constexpr int TILE = 8;
  static_assert(TILE * TILE <= PendingRayList::CAPACITY, "a tile's rays must fit the queue");
  const int tx = (w + TILE - 1) / TILE, ty = (h + TILE - 1) / TILE;
  constexpr int GROUP = 4;
  const int gx = (tx + GROUP - 1) / GROUP, gy = (ty + GROUP - 1) / GROUP;
  uint64_t sTotal = 0, kTotal = 0, rTotal = 0;
#pragma omp parallel for num_threads(threads) schedule(dynamic, 1) reduction(+ : sTotal, kTotal, rTotal)
  for (int tile = 0; tile < gx * gy * GROUP * GROUP; ++tile) {
    // Tiles in groups of GROUP x GROUP (32 x 32 pixels), the groups row by row: consecutive tiles'
    // rays cross the same bricks, which then stay cached (avg152T1 -2.6%, embryo -1.6%).
    const int group = tile / (GROUP * GROUP), in = tile % (GROUP * GROUP);
    const int tix = (group % gx) * GROUP + in % GROUP, tiy = (group / gx) * GROUP + in / GROUP;
    if (tix >= tx || tiy >= ty) continue;
    const int x0 = tix * TILE, y0 = tiy * TILE;
    const int x1 = std::min(w, x0 + TILE), y1 = std::min(h, y0 + TILE);
    RaySetupFrame S = S0;
    PendingRayList pending;  // this tile's rays for the AVX2 marcher (at most TILE^2 = 64)
    for (int y = y0; y < y1; ++y) {
      for (int a = 0; a < 3; ++a) S.upY[a] = upY[size_t(y)][a];
      const bool rowHit = y >= hit.y0 && y <= hit.y1;
      for (int xg = x0; xg < x1; xg += 4) {
        PixelRay group[4];
        const bool grouped = setup4 && rowHit && xg + 3 >= hit.x0 && xg <= hit.x1;
#if MATRIXTREE_VOLUME_AVX2
        if (grouped) setupRays4(S, xg, group);
#endif
        for (int x = xg; x < std::min(x1, xg + 4); ++x) {
          float* out = rgba + (size_t(y) * w + x) * 4;
          ++rTotal;
          if (!rowHit || x < hit.x0 || x > hit.x1) {  // misses the box: left 0
            out[0] = out[1] = out[2] = out[3] = 0.f;
            continue;
          }
          double ro[3];
          PixelRay r;
          if (cam.parallel) {
            const double nx = nxs[size_t(x)], ny = nys[size_t(y)];
            const Vec3 o = pos + right * (nx * cam.parallelScale * aspect) + up * (ny * cam.parallelScale);
            for (int a = 0; a < 3; ++a) {
              r.d[a] = fwd[a];
              ro[a] = (o[a] - geo.origin[a]) / geo.spacing[a];
              r.rd[a] = fwd[a] / geo.spacing[a];
            }
            clipPixelRay(ro, hiIdx, F.dt, r);
          } else {
            for (int a = 0; a < 3; ++a) ro[a] = roEye[a];
            r = grouped ? group[x - xg] : setupRay(S, x);
          }
          if (!r.hit) {
            out[0] = out[1] = out[2] = out[3] = 0.f;
            continue;
          }
          if (pairable<R, Shade>(F, fetch, r.kEnd)) {
            PendingRay& q = pending.rays[pending.count++];
            for (int a = 0; a < 3; ++a) {
              q.ro[a] = ro[a];
              q.rd[a] = r.rd[a];
            }
            q.t0 = r.t0;
            q.kEnd = r.kEnd;
            q.out = out;
            continue;
          }
          marchRay<R, Skip, Shade>(F, fetch, ro, r.rd, r.t0, r.kEnd, r.d, out, sTotal, kTotal);
        }
      }
    }
    if (pending.count) marchPending<R, Skip, Shade>(F, fetch, pending, sTotal, kTotal);
  }
  samples += sTotal;
  skips += kTotal;
  rays += rTotal;
}

template <typename R, typename Fetch>
void dispatch(bool skip, bool shade, const Frame& F, const Fetch& fetch, const VolumeGeometry& geo,
              const VolumeCamera& cam, int w, int h, double aspect, int threads, VolumeImage& img,
              float* rgba) {
  if (skip && shade)
    marchImage<R, Fetch, true, true>(F, fetch, geo, cam, w, h, aspect, threads, rgba, img.samples, img.skips, img.rays);
  else if (skip)
    marchImage<R, Fetch, true, false>(F, fetch, geo, cam, w, h, aspect, threads, rgba, img.samples, img.skips, img.rays);
  else if (shade)
    marchImage<R, Fetch, false, true>(F, fetch, geo, cam, w, h, aspect, threads, rgba, img.samples, img.skips, img.rays);
  else
    marchImage<R, Fetch, false, false>(F, fetch, geo, cam, w, h, aspect, threads, rgba, img.samples, img.skips, img.rays);
}

template <typename R>
void dispatchStorage(const BlockSparseVolume& vol, bool skip, bool shade, const Frame& F, const VolumeGeometry& geo,
                     const VolumeCamera& cam, int w, int h, double aspect, int threads, VolumeImage& img,
                     float* rgba) {
  const int nb0 = vol.levelDim(0, 0), nb1 = vol.levelDim(0, 1);
  const uint32_t* ptr = vol.brickPointers().data();
  const uint64_t* masks = vol.cellMasks().data();
  switch (vol.storage()) {
    case VoxelStorage::UInt8:
      if (vol.pairedRows())
        dispatch<R>(skip, shade, F, ApronFetch<Paired8>(ApronBricks{ptr, vol.bricks8().data(), masks, nb0, nb1}), geo,
                    cam, w, h, aspect, threads, img, rgba);
      else
        dispatch<R>(skip, shade, F, ApronFetch<uint8_t>(ApronBricks{ptr, vol.bricks8().data(), masks, nb0, nb1}), geo,
                    cam, w, h, aspect, threads, img, rgba);
      break;
    case VoxelStorage::UInt16:
      dispatch<R>(skip, shade, F, ApronFetch<uint16_t>(ApronBricks{ptr, vol.bricks16().data(), masks, nb0, nb1}), geo,
                  cam, w, h, aspect, threads, img, rgba);
      break;
    default:
      dispatch<R>(skip, shade, F, FloatFetch(vol.voxels()), geo, cam, w, h, aspect, threads, img, rgba);
  }
}

}  // namespace
}  // namespace volume_detail

using namespace volume_detail;

void checkVolumeRenderArguments(const VolumeGeometry& geo, const TransferTable& tf, const VolumeCamera& cam,
                                const VolumeRenderOptions& opt, const char* who) {
  const std::string w(who);
  if (tf.size() < 2) throw std::invalid_argument(w + ": empty transfer table");
  for (int a = 0; a < 3; ++a)
    if (!(geo.spacing[a] != 0) || !std::isfinite(geo.spacing[a]) || !std::isfinite(geo.origin[a]))
      throw std::invalid_argument(w + ": spacing must be finite and non-zero, origin finite");
  if (!(opt.sampleDistance > 0) || !std::isfinite(opt.sampleDistance))
    throw std::invalid_argument(w + ": sample distance must be positive");
  if (!(opt.imageSampleDistance >= 1) || !std::isfinite(opt.imageSampleDistance))
    throw std::invalid_argument(w + ": image sample distance must be >= 1");
  if (cam.width < 1 || cam.height < 1 || cam.width > 16384 || cam.height > 16384)
    throw std::invalid_argument(w + ": image size must be in 1..16384");
  const Vec3 fwd = cam.focalPoint - cam.position;
  if (!isFinite(cam.position) || !isFinite(cam.focalPoint) || norm(fwd) == 0 || norm(cross(fwd, cam.viewUp)) == 0 ||
      (!cam.parallel && !(cam.viewAngle > 0 && cam.viewAngle < 180)) || (cam.parallel && !(cam.parallelScale > 0)))
    throw std::invalid_argument(w + ": degenerate camera (position = focal point, view up along the view, "
                                    "or view angle/parallel scale out of range)");
}

VolumeImage renderVolume(const BlockSparseVolume& vol, const VolumeGeometry& geo, const TransferTable& tf,
                         const VolumeCamera& cam, const VolumeRenderOptions& opt) {
  checkVolumeRenderArguments(geo, tf, cam, opt, "renderVolume");  // before sizing the image
  std::vector<float> rgba(size_t(cam.width) * cam.height * 4);
  VolumeImage img = renderVolume(vol, geo, tf, cam, opt, rgba.data());
  img.rgba = std::move(rgba);
  return img;
}

VolumeImage renderVolume(const BlockSparseVolume& vol, const VolumeGeometry& geo, const TransferTable& tf,
                         const VolumeCamera& cam, const VolumeRenderOptions& opt, float* rgba) {
  const auto start = std::chrono::steady_clock::now();
  if (vol.levelCount() == 0) throw std::invalid_argument("renderVolume: the volume was not built");
  checkVolumeRenderArguments(geo, tf, cam, opt, "renderVolume");
  std::vector<float> table = stepCorrectedTable(tf, opt.sampleDistance);
  table.insert(table.end(), 4, 0.f);  // an all-zero entry past the last one (the AVX2 marcher's invisible cells)

  Frame F;
  F.vol = &vol;
  for (int a = 0; a < 3; ++a) {
    F.n[a] = vol.dim(a);
    F.nb[a] = vol.levelDim(0, a);
    F.spacing[a] = geo.spacing[a];
  }
  F.table = table.data();
  F.table8 = nullptr;
  const SampleUnits units = sampleUnits(vol, tf);
  F.tlo = units.tableLo;
  F.tscale = units.tableScale;
  F.tlast = tf.lastIndex();
  F.offset = units.offset;
  F.dt = opt.sampleDistance;
  F.threshold = earlyTerminationThreshold(opt);
  F.dist = vol.brickDistances().data();
  F.ambient = opt.ambient;
  F.diffuse = opt.diffuse;
  F.specular = opt.specular;
  F.specularPower = opt.specularPower;
  const bool apron = vol.storage() != VoxelStorage::Float32;
  // The AVX2 marcher indexes voxels (stored brick * 9^3 or BRICK_BYTES8 + offset) and mask words (level-0 brick
  // * 16 + word) with 32-bit integers.
  const bool indexable = uint64_t(vol.stats().bricksStored + 1) * BlockSparseVolume::BRICK_BYTES8 < (uint64_t(1) << 31) &&
                         uint64_t(vol.stats().bricks) * 2 * DIM < (uint64_t(1) << 31);
  F.setup4 = opt.vectorized && cpuHasAvx2();
  F.lanes = apron && !opt.doublePrecision && !opt.shade && indexable && opt.vectorized && cpuHasAvx2() ? 8 : 1;
  // The AVX2 marcher's table: entry e at float 8 e, 32-byte aligned. 1 - a is the same float
  // operation the SSE2 marcher does per sample, so the transmittance gets the same bits.
  std::vector<float> table8Store;
  if (F.lanes == 8) {
    const size_t ne = table.size() / 4;  // with the all-zero entry
    table8Store.assign(ne * 8 + 8, 0.f);
    float* t8 = table8Store.data() + (8 - (reinterpret_cast<uintptr_t>(table8Store.data()) / 4) % 8) % 8;
    for (size_t e = 0; e < ne; ++e) {
      for (int c = 0; c < 4; ++c) t8[8 * e + c] = table[4 * e + c];
      for (int c = 4; c < 8; ++c) t8[8 * e + c] = 1.f - table[4 * e + 3];
    }
    F.table8 = t8;
  }
  // The bricks the AVX2 marcher may march through, as the entry of their first voxel (stored brick
  // times the brick's entries: no multiply between the gather of it and the corner gathers): the
  // stored ones, but with skipping only the visible ones (all bricks are stored when the volume
  // was built dense); MT_NULL elsewhere.
  std::vector<uint32_t> runBricks;
  F.runBricks = nullptr;
  if (F.lanes == 8) {
    const uint32_t entries = vol.pairedRows() ? BlockSparseVolume::BRICK_BYTES8 : BlockSparseVolume::BRICK_VOLUME;
    runBricks = vol.brickPointers();
    for (int k = 0; k < F.nb[2]; ++k)
      for (int j = 0; j < F.nb[1]; ++j)
        for (int i = 0; i < F.nb[0]; ++i) {
          uint32_t& b = runBricks[(size_t(k) * F.nb[1] + j) * F.nb[0] + i];
          if (b != MT_NULL) b = opt.emptySpaceSkipping && !vol.nodeVisible(0, i, j, k) ? MT_NULL : b * entries;
        }
    F.runBricks = runBricks.data();
  }

  VolumeImage img;
  img.lanes = F.lanes;
  img.width = cam.width;
  img.height = cam.height;
  const int w = std::max(1, static_cast<int>(std::lround(cam.width / opt.imageSampleDistance)));
  const int h = std::max(1, static_cast<int>(std::lround(cam.height / opt.imageSampleDistance)));
  const double aspect = double(cam.width) / cam.height;
  const int threads = resolveThreads(opt.threads);
  // Full size: straight into rgba; else a small image, then upsampled into it.
  const bool full = w == cam.width && h == cam.height;
  std::vector<float> small(full ? 0 : size_t(w) * h * 4);
  float* target = full ? rgba : small.data();
  if (opt.doublePrecision)
    dispatchStorage<double>(vol, opt.emptySpaceSkipping, opt.shade, F, geo, cam, w, h, aspect, threads, img, target);
  else
    dispatchStorage<float>(vol, opt.emptySpaceSkipping, opt.shade, F, geo, cam, w, h, aspect, threads, img, target);
  if (!full) {
    const std::vector<float> up = upsampleRGBA(small, w, h, cam.width, cam.height, threads);
    std::copy(up.begin(), up.end(), rgba);
  }
  img.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return img;
}

}  // namespace mtree

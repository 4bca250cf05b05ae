// Block-sparse volume: classification, the matrix-tree levels over the bricks, and the ray
// marcher. See engine/include/mtree/volume.h for the design and why skipping is exact.
#include "mtree/volume.h"

#include <chrono>

#include <omp.h>

#include "mtree/parallel.h"

namespace mtree {

// ------------------------------------------------------------------------------- TransferTable

TransferTable::TransferTable(double lo, double hi, std::vector<float> rgba, double unitDistance)
    : lo_(lo), hi_(hi), unit_(unitDistance), rgba_(std::move(rgba)) {
  if (rgba_.size() < 8 || rgba_.size() % 4)
    throw std::invalid_argument("TransferTable: need 4 floats per entry and at least 2 entries");
  if (!std::isfinite(lo) || !std::isfinite(hi) || !(hi > lo))
    throw std::invalid_argument("TransferTable: need finite lo < hi");
  if (!(unitDistance > 0) || !std::isfinite(unitDistance))
    throw std::invalid_argument("TransferTable: unit distance must be positive");
  for (float& f : rgba_) f = std::isfinite(f) ? std::min(1.f, std::max(0.f, f)) : 0.f;
  const int n = size();
  last_ = n - 1;
  flo_ = static_cast<float>(lo);
  fscale_ = static_cast<float>(last_ / (hi - lo));
  rangeMax_.clear();
  rangeMax_.emplace_back(n);
  for (int i = 0; i < n; ++i) rangeMax_[0][i] = rgba_[4 * size_t(i) + 3];
  for (int l = 1; (1 << l) <= n; ++l) {
    const std::vector<float>& prev = rangeMax_[l - 1];
    std::vector<float> cur(size_t(n - (1 << l) + 1));
    for (size_t i = 0; i < cur.size(); ++i) cur[i] = std::max(prev[i], prev[i + (size_t(1) << (l - 1))]);
    rangeMax_.push_back(std::move(cur));
  }
}

float TransferTable::maxOpacity(float a, float b) const {
  if (rgba_.empty()) return 0.f;
  int i = index(std::min(a, b)) - 1, j = index(std::max(a, b)) + 1;
  i = std::max(i, 0);
  j = std::min(j, last_);
  int l = 0;
  while ((2 << l) <= j - i + 1) ++l;
  return std::max(rangeMax_[l][i], rangeMax_[l][j - (1 << l) + 1]);
}

// --------------------------------------------------------------------------- BlockSparseVolume

void BlockSparseVolume::classify(const TransferTable& tf, const VolumeBuildOptions& opt, std::vector<float>& dense) {
  const auto start = std::chrono::steady_clock::now();
  const int threads = resolveThreads(opt.threads);
  const int n[3] = {vox_.dim(0), vox_.dim(1), vox_.dim(2)};
  const int nb[3] = {(n[0] - 1 + DIM - 1) / DIM, (n[1] - 1 + DIM - 1) / DIM, (n[2] - 1 + DIM - 1) / DIM};
  const int64_t nBricks = int64_t(nb[0]) * nb[1] * nb[2];
  const size_t sx = 1, sy = size_t(n[0]), sz = size_t(n[0]) * n[1];
  auto at = [&](int i, int j, int k) { return dense[size_t(k) * sz + size_t(j) * sy + size_t(i) * sx]; };

  brickMin_.assign(size_t(nBricks), 0.f);
  brickMax_.assign(size_t(nBricks), 0.f);
  levels_.assign(1, LevelGrid{});
  LevelGrid& l0 = levels_[0];
  for (int a = 0; a < 3; ++a) l0.n[a] = nb[a];
  l0.occ.assign(size_t(nBricks), 0);
  std::vector<uint8_t> marks(vox_.pointerCount(), opt.sparse ? 0 : 1);
  uint64_t visibleCells = 0;

#pragma omp parallel for num_threads(threads) schedule(dynamic, 4) reduction(+ : visibleCells)
  for (int64_t b = 0; b < nBricks; ++b) {
    const int bi = int(b % nb[0]), bj = int((b / nb[0]) % nb[1]), bk = int(b / (int64_t(nb[0]) * nb[1]));
    const int c0[3] = {bi * DIM, bj * DIM, bk * DIM};
    const int c1[3] = {std::min(c0[0] + DIM, n[0] - 1), std::min(c0[1] + DIM, n[1] - 1),
                       std::min(c0[2] + DIM, n[2] - 1)};  // cells [c0, c1), voxels [c0, c1]
    float mn = std::numeric_limits<float>::infinity(), mx = -mn;
    for (int k = c0[2]; k <= c1[2]; ++k)
      for (int j = c0[1]; j <= c1[1]; ++j)
        for (int i = c0[0]; i <= c1[0]; ++i) {
          const float v = at(i, j, k);
          mn = std::min(mn, v);
          mx = std::max(mx, v);
        }
    brickMin_[size_t(b)] = mn;
    brickMax_[size_t(b)] = mx;
    if (tf.maxOpacity(mn, mx) <= 0.f) continue;  // the whole brick is transparent
    uint64_t vis = 0;
    for (int k = c0[2]; k < c1[2]; ++k)
      for (int j = c0[1]; j < c1[1]; ++j)
        for (int i = c0[0]; i < c1[0]; ++i) {
          float lo = at(i, j, k), hi = lo;
          for (int c = 1; c < 8; ++c) {
            const float v = at(i + (c & 1), j + ((c >> 1) & 1), k + (c >> 2));
            lo = std::min(lo, v);
            hi = std::max(hi, v);
          }
          if (tf.maxOpacity(lo, hi) <= 0.f) continue;
          ++vis;
          if (!opt.sparse) continue;
          for (int c = 0; c < 8; ++c) {
            const size_t p = vox_.pointerIndex(i + (c & 1), j + ((c >> 1) & 1), k + (c >> 2));
            if (!marks[p]) {
#pragma omp atomic write
              marks[p] = 1;
            }
          }
        }
    if (vis) l0.occ[size_t(b)] = 1;
    visibleCells += vis;
  }

  // §5.1 steps 3-4: scan the marks into block indices, then fill the blocks from the dense copy.
  vox_.allocateMarked(marks.data(), threads);
  const MtSparseDesc& d = vox_.desc();
  std::vector<float>& data = vox_.data();
  const int e[3] = {1 << d.logBlock[0], 1 << d.logBlock[1], 1 << d.logBlock[2]};
#pragma omp parallel for num_threads(threads) schedule(static)
  for (int64_t b = 0; b < int64_t(d.numBlocks); ++b) {
    int o[3];
    vox_.entryCoords(uint32_t(b) * d.blockVolume, o);
    float* dst = data.data() + size_t(b) * d.blockVolume;
    for (int k = 0; k < e[2]; ++k)
      for (int j = 0; j < e[1]; ++j)
        for (int i = 0; i < e[0]; ++i) {
          const int x = o[0] + i, y = o[1] + j, z = o[2] + k;
          if (x < n[0] && y < n[1] && z < n[2])
            dst[(size_t(k) * e[1] + j) * e[0] + i] = at(x, y, z);
        }
  }
  ptr_ = vox_.pointers().data();
  data_ = vox_.data().data();
  std::vector<float>().swap(dense);

  // Matrix-tree levels above the bricks: level l+1 node = OR of its 2x2x2 children.
  while (levels_.back().n[0] > 1 || levels_.back().n[1] > 1 || levels_.back().n[2] > 1) {
    const LevelGrid& c = levels_.back();
    LevelGrid p;
    for (int a = 0; a < 3; ++a) p.n[a] = (c.n[a] + 1) / 2;
    p.occ.assign(size_t(p.n[0]) * p.n[1] * p.n[2], 0);
    for (int k = 0; k < c.n[2]; ++k)
      for (int j = 0; j < c.n[1]; ++j)
        for (int i = 0; i < c.n[0]; ++i)
          if (c.occ[(size_t(k) * c.n[1] + j) * c.n[0] + i])
            p.occ[(size_t(k / 2) * p.n[1] + j / 2) * p.n[0] + i / 2] = 1;
    levels_.push_back(std::move(p));
  }

  VolumeStats& s = stats_;
  s.voxels = uint64_t(n[0]) * n[1] * n[2];
  s.cells = uint64_t(n[0] - 1) * (n[1] - 1) * (n[2] - 1);
  s.visibleCells = visibleCells;
  s.blocksAllocated = d.numBlocks;
  s.blocksDense = static_cast<uint32_t>(vox_.pointerCount());
  s.bricks = static_cast<uint32_t>(nBricks);
  s.bricksVisible = 0;
  for (uint8_t o : levels_[0].occ) s.bricksVisible += o;  // (l0 dangles after the push_backs)
  s.blockBytes = vox_.blockBytes();
  uint64_t levelBytes = 0;
  for (const LevelGrid& g : levels_) levelBytes += g.occ.size();
  s.bytes = vox_.bytes() + (brickMin_.size() + brickMax_.size()) * sizeof(float) + levelBytes;
  s.denseBytes = s.voxels * sizeof(float);
  s.levels = levelCount();
  s.buildMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

namespace {

inline int clampCell(double q, int n, double& f) {
  // floor without a libm call (no SSE4.1 round instruction in baseline x86-64); q is clamped
  // first so the conversion cannot overflow.
  const double qc = std::min(std::max(q, -1.0), double(n));
  int c = static_cast<int>(qc);
  c -= (qc < c);
  c = std::min(std::max(c, 0), n - 2);
  f = std::min(1.0, std::max(0.0, q - c));
  return c;
}

template <typename R>
inline R trilinear(const float c[8], R fx, R fy, R fz) {
  const R x00 = c[0] + fx * (c[1] - c[0]), x10 = c[2] + fx * (c[3] - c[2]);
  const R x01 = c[4] + fx * (c[5] - c[4]), x11 = c[6] + fx * (c[7] - c[6]);
  const R y0 = x00 + fy * (x10 - x00), y1 = x01 + fy * (x11 - x01);
  return y0 + fz * (y1 - y0);
}

}  // namespace

bool BlockSparseVolume::sample(double x, double y, double z, double& v) const {
  double f[3];
  const int i = clampCell(x, dim(0), f[0]), j = clampCell(y, dim(1), f[1]), k = clampCell(z, dim(2), f[2]);
  float c[8];
  if (!cellCorners(i, j, k, c)) return false;
  v = trilinear<double>(c, f[0], f[1], f[2]);
  return true;
}

// --------------------------------------------------------------------------------- renderVolume

namespace {

/// The block-sparse matrix's addressing, unpacked once per frame for the inner loop.
struct BlockAddress {
  const uint32_t* ptr;
  const float* data;
  int lb0, lb1, lb2, m0, m1, m2, pd0, pd1;
  uint32_t bv;
  explicit BlockAddress(const BlockSparseMatrix<float>& m)
      : ptr(m.pointers().data()), data(m.data().data()), lb0(m.desc().logBlock[0]), lb1(m.desc().logBlock[1]),
        lb2(m.desc().logBlock[2]), m0((1 << lb0) - 1), m1((1 << lb1) - 1), m2((1 << lb2) - 1),
        pd0(m.desc().ptrDims[0]), pd1(m.desc().ptrDims[1]), bv(m.desc().blockVolume) {}
  /// BlockSparseVolume::cellCorners, with the 8 corners addressed per axis.
  bool corners(int i, int j, int k, float c[8]) const {
    const int bx0 = i >> lb0, by0 = j >> lb1, bz0 = k >> lb2;
    const int bx1 = (i + 1) >> lb0, by1 = (j + 1) >> lb1, bz1 = (k + 1) >> lb2;
    const int lx0 = i & m0, ly0 = j & m1, lz0 = k & m2;
    if (((bx0 ^ bx1) | (by0 ^ by1) | (bz0 ^ bz1)) == 0) {
      const uint32_t b = ptr[(size_t(bz0) * pd1 + by0) * pd0 + bx0];
      if (b == MT_NULL) return false;
      const float* p = data + size_t(b) * bv + ((lz0 << (lb0 + lb1)) | (ly0 << lb0) | lx0);
      const int sy = 1 << lb0, sz = 1 << (lb0 + lb1);
      c[0] = p[0]; c[1] = p[1]; c[2] = p[sy]; c[3] = p[sy + 1];
      c[4] = p[sz]; c[5] = p[sz + 1]; c[6] = p[sz + sy]; c[7] = p[sz + sy + 1];
      return true;
    }
    const int bx[2] = {bx0, bx1}, by[2] = {by0, by1}, bz[2] = {bz0, bz1};
    const int lx[2] = {lx0, (i + 1) & m0}, ly[2] = {ly0 << lb0, ((j + 1) & m1) << lb0},
              lz[2] = {lz0 << (lb0 + lb1), ((k + 1) & m2) << (lb0 + lb1)};
    for (int n = 0; n < 8; ++n) {
      const int dx = n & 1, dy = (n >> 1) & 1, dz = n >> 2;
      const uint32_t b = ptr[(size_t(bz[dz]) * pd1 + by[dy]) * pd0 + bx[dx]];
      if (b == MT_NULL) return false;
      c[n] = data[size_t(b) * bv + (lz[dz] | ly[dy] | lx[dx])];
    }
    return true;
  }
};

struct MarchContext {
  const BlockSparseVolume* vol;
  const TransferTable* tf;
  const float* table;  // premultiplied, opacity corrected for the step: 4 per entry
  int n[3];
  double dt;
  double threshold;
  double spacing[3];
  double ambient, diffuse, specular, specularPower;
};

struct Ray {
  double o[3], d[3];  // index space; t is world length
};

/// t where the ray leaves the index-space box [lo, hi] (the ray is inside it at some t).
inline double exitT(const Ray& r, const double lo[3], const double hi[3]) {
  double t = std::numeric_limits<double>::infinity();
  for (int a = 0; a < 3; ++a) {
    if (r.d[a] > 0) t = std::min(t, (hi[a] - r.o[a]) / r.d[a]);
    else if (r.d[a] < 0) t = std::min(t, (lo[a] - r.o[a]) / r.d[a]);
  }
  return t;
}

/// Marches one ray over samples k = 0..kEnd at t_k = t0 + k dt. Returns premultiplied RGBA.
template <typename R, bool Skip, bool Shade>
void march(const MarchContext& c, const Ray& ray, double t0, int64_t kEnd, const double viewDir[3], float out[4],
           uint64_t& samplesOut, uint64_t& skipsOut) {
  uint64_t samples = 0, skips = 0;  // locals: a counter behind a reference is stored every sample
  const BlockSparseVolume& vol = *c.vol;
  const BlockAddress addr(vol.voxels());
  R A = 0, Cr = 0, Cg = 0, Cb = 0;
  const R thr = static_cast<R>(c.threshold);
  int64_t k = 0;
  const int levels = vol.levelCount();
  while (k <= kEnd) {
    int64_t kStop = k;  // sample k..kStop, then look again
    if (Skip) {
      const double t = t0 + double(k) * c.dt;
      double f;
      const int ci = clampCell(ray.o[0] + ray.d[0] * t, c.n[0], f);
      const int cj = clampCell(ray.o[1] + ray.d[1] * t, c.n[1], f);
      const int ck = clampCell(ray.o[2] + ray.d[2] * t, c.n[2], f);
      const int bi = ci >> BlockSparseVolume::LOG2DIM, bj = cj >> BlockSparseVolume::LOG2DIM,
                bk = ck >> BlockSparseVolume::LOG2DIM;
      // Coarsest empty ancestor (top-down over the matrix-tree levels); -1 if the brick is visible.
      int empty = -1;
      for (int L = levels - 1; L >= 0; --L)
        if (!vol.nodeVisible(L, bi >> L, bj >> L, bk >> L)) {
          empty = L;
          break;
        }
      const int L = empty < 0 ? 0 : empty;
      const double edge = double(BlockSparseVolume::DIM << L);
      const double lo[3] = {double(bi >> L) * edge, double(bj >> L) * edge, double(bk >> L) * edge};
      const double hi[3] = {lo[0] + edge, lo[1] + edge, lo[2] + edge};
      const double tx = exitT(ray, lo, hi);
      // Last sample at or before the node's exit (floor: never jump over a sample that might
      // lie beyond it in a visible node; an extra sample in an empty node adds exactly 0).
      const double kx = std::floor((tx - t0) / c.dt);
      const int64_t kLast = kx >= double(kEnd) ? kEnd : std::max<int64_t>(k, static_cast<int64_t>(kx));
      if (empty >= 0) {
        ++skips;
        k = std::max(k + 1, kLast);
        continue;
      }
      kStop = kLast;
    }
    for (; k <= kStop; ++k) {
      const double t = t0 + double(k) * c.dt;
      double fx, fy, fz;
      const int ci = clampCell(ray.o[0] + ray.d[0] * t, c.n[0], fx);
      const int cj = clampCell(ray.o[1] + ray.d[1] * t, c.n[1], fy);
      const int ck = clampCell(ray.o[2] + ray.d[2] * t, c.n[2], fz);
      float cc[8];
      if (!addr.corners(ci, cj, ck, cc)) continue;
      ++samples;
      const R v = trilinear<R>(cc, R(fx), R(fy), R(fz));
      const float* e = c.table + 4 * c.tf->index(v);
      const R a = e[3];
      if (a <= 0) continue;
      R r = e[0], g = e[1], b = e[2];
      if (Shade) {
        // Gradient of the trilinear interpolant (index space), then to world space.
        const R gx = (1 - fy) * (1 - fz) * (cc[1] - cc[0]) + fy * (1 - fz) * (cc[3] - cc[2]) +
                     (1 - fy) * fz * (cc[5] - cc[4]) + fy * fz * (cc[7] - cc[6]);
        const R gy = (1 - fx) * (1 - fz) * (cc[2] - cc[0]) + fx * (1 - fz) * (cc[3] - cc[1]) +
                     (1 - fx) * fz * (cc[6] - cc[4]) + fx * fz * (cc[7] - cc[5]);
        const R gz = (1 - fx) * (1 - fy) * (cc[4] - cc[0]) + fx * (1 - fy) * (cc[5] - cc[1]) +
                     (1 - fx) * fy * (cc[6] - cc[2]) + fx * fy * (cc[7] - cc[3]);
        const R wx = gx / R(c.spacing[0]), wy = gy / R(c.spacing[1]), wz = gz / R(c.spacing[2]);
        const R len = std::sqrt(wx * wx + wy * wy + wz * wz);
        if (len > 0) {
          // Headlight: light and viewer along the ray; two-sided (|n.l|).
          const R ndl = std::fabs(wx * R(viewDir[0]) + wy * R(viewDir[1]) + wz * R(viewDir[2])) / len;
          const R s = R(c.ambient) + R(c.diffuse) * ndl;
          const R spec = R(c.specular) * std::pow(ndl, R(c.specularPower)) * a;
          r = r * s + spec;
          g = g * s + spec;
          b = b * s + spec;
        }
      }
      const R w = 1 - A;
      Cr += w * r;
      Cg += w * g;
      Cb += w * b;
      A += w * a;
      if (A >= thr) {
        k = kEnd + 1;
        break;
      }
    }
  }
  samplesOut += samples;
  skipsOut += skips;
  out[0] = float(Cr);
  out[1] = float(Cg);
  out[2] = float(Cb);
  out[3] = float(A);
}

template <typename R, bool Skip, bool Shade>
void marchImage(const MarchContext& c, const VolumeGeometry& geo, const VolumeCamera& cam, int w, int h,
                double aspect, int threads, std::vector<float>& rgba, uint64_t& samples, uint64_t& skips,
                uint64_t& rays) {
  const Vec3 pos = cam.position;
  const Vec3 fwd = normalized(cam.focalPoint - cam.position);
  const Vec3 right = normalized(cross(fwd, cam.viewUp));
  const Vec3 up = cross(right, fwd);
  const double th = std::tan(cam.viewAngle * 0.5 * 3.14159265358979323846 / 180.0);
  const double hiIdx[3] = {double(c.n[0] - 1), double(c.n[1] - 1), double(c.n[2] - 1)};
  uint64_t sTotal = 0, kTotal = 0, rTotal = 0;
#pragma omp parallel for num_threads(threads) schedule(dynamic, 1) reduction(+ : sTotal, kTotal, rTotal)
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      float* out = rgba.data() + (size_t(y) * w + x) * 4;
      const double nx = 2.0 * (x + 0.5) / w - 1.0, ny = 2.0 * (y + 0.5) / h - 1.0;
      Vec3 o, d;
      if (cam.parallel) {
        o = pos + right * (nx * cam.parallelScale * aspect) + up * (ny * cam.parallelScale);
        d = fwd;
      } else {
        o = pos;
        d = normalized(fwd + right * (nx * th * aspect) + up * (ny * th));
      }
      Ray ray;
      double t0 = 0, t1 = std::numeric_limits<double>::infinity();
      bool miss = false;
      for (int a = 0; a < 3; ++a) {
        ray.o[a] = (o[a] - geo.origin[a]) / geo.spacing[a];
        ray.d[a] = d[a] / geo.spacing[a];
        if (ray.d[a] == 0) {
          if (ray.o[a] < 0 || ray.o[a] > hiIdx[a]) miss = true;
          continue;
        }
        double ta = (0 - ray.o[a]) / ray.d[a], tb = (hiIdx[a] - ray.o[a]) / ray.d[a];
        if (ta > tb) std::swap(ta, tb);
        t0 = std::max(t0, ta);
        t1 = std::min(t1, tb);
      }
      ++rTotal;
      if (miss || !(t0 <= t1)) {
        out[0] = out[1] = out[2] = out[3] = 0.f;
        continue;
      }
      const double kx = std::floor((t1 - t0) / c.dt);
      const int64_t kEnd = kx > 4e15 ? int64_t(4e15) : static_cast<int64_t>(kx);
      // Light direction in world space for the headlight: the ray direction.
      const double viewDir[3] = {d.x, d.y, d.z};
      march<R, Skip, Shade>(c, ray, t0, kEnd, viewDir, out, sTotal, kTotal);
    }
  }
  samples += sTotal;
  skips += kTotal;
  rays += rTotal;
}

template <typename R>
void dispatch(bool skip, bool shade, const MarchContext& c, const VolumeGeometry& geo, const VolumeCamera& cam,
              int w, int h, double aspect, int threads, VolumeImage& img, std::vector<float>& rgba) {
  if (skip && shade) marchImage<R, true, true>(c, geo, cam, w, h, aspect, threads, rgba, img.samples, img.skips, img.rays);
  else if (skip) marchImage<R, true, false>(c, geo, cam, w, h, aspect, threads, rgba, img.samples, img.skips, img.rays);
  else if (shade) marchImage<R, false, true>(c, geo, cam, w, h, aspect, threads, rgba, img.samples, img.skips, img.rays);
  else marchImage<R, false, false>(c, geo, cam, w, h, aspect, threads, rgba, img.samples, img.skips, img.rays);
}

}  // namespace

VolumeImage renderVolume(const BlockSparseVolume& vol, const VolumeGeometry& geo, const TransferTable& tf,
                         const VolumeCamera& cam, const VolumeRenderOptions& opt) {
  const auto start = std::chrono::steady_clock::now();
  if (vol.levelCount() == 0) throw std::invalid_argument("renderVolume: the volume was not built");
  if (tf.size() < 2) throw std::invalid_argument("renderVolume: empty transfer table");
  for (int a = 0; a < 3; ++a)
    if (!(geo.spacing[a] != 0) || !std::isfinite(geo.spacing[a]) || !std::isfinite(geo.origin[a]))
      throw std::invalid_argument("renderVolume: spacing must be finite and non-zero, origin finite");
  if (!(opt.sampleDistance > 0) || !std::isfinite(opt.sampleDistance))
    throw std::invalid_argument("renderVolume: sample distance must be positive");
  if (!(opt.imageSampleDistance >= 1) || !std::isfinite(opt.imageSampleDistance))
    throw std::invalid_argument("renderVolume: image sample distance must be >= 1");
  if (cam.width < 1 || cam.height < 1 || cam.width > 16384 || cam.height > 16384)
    throw std::invalid_argument("renderVolume: image size must be in 1..16384");
  const Vec3 fwd = cam.focalPoint - cam.position;
  if (!isFinite(cam.position) || !isFinite(cam.focalPoint) || norm(fwd) == 0 || norm(cross(fwd, cam.viewUp)) == 0 ||
      (!cam.parallel && !(cam.viewAngle > 0 && cam.viewAngle < 180)) || (cam.parallel && !(cam.parallelScale > 0)))
    throw std::invalid_argument("renderVolume: degenerate camera (position = focal point, view up along the view, "
                                "or view angle/parallel scale out of range)");

  // Opacity correction for the step: alpha' = 1 - (1 - alpha)^(step / unit), colour premultiplied.
  const int ne = tf.size();
  std::vector<float> table(size_t(ne) * 4);
  const double ratio = opt.sampleDistance / tf.unitDistance();
  for (int i = 0; i < ne; ++i) {
    const float* e = tf.rgba().data() + 4 * size_t(i);
    const double a = e[3] >= 1.f ? 1.0 : 1.0 - std::pow(1.0 - double(e[3]), ratio);
    for (int ch = 0; ch < 3; ++ch) table[4 * size_t(i) + ch] = static_cast<float>(e[ch] * a);
    table[4 * size_t(i) + 3] = static_cast<float>(a);
  }

  MarchContext c;
  c.vol = &vol;
  c.tf = &tf;
  c.table = table.data();
  for (int a = 0; a < 3; ++a) {
    c.n[a] = vol.dim(a);
    c.spacing[a] = geo.spacing[a];
  }
  c.dt = opt.sampleDistance;
  c.threshold = opt.earlyTermination >= 1 ? 2.0 : std::max(0.0, opt.earlyTermination);
  c.ambient = opt.ambient;
  c.diffuse = opt.diffuse;
  c.specular = opt.specular;
  c.specularPower = opt.specularPower;

  VolumeImage img;
  img.width = cam.width;
  img.height = cam.height;
  const int w = std::max(1, static_cast<int>(std::lround(cam.width / opt.imageSampleDistance)));
  const int h = std::max(1, static_cast<int>(std::lround(cam.height / opt.imageSampleDistance)));
  const double aspect = double(cam.width) / cam.height;
  const int threads = resolveThreads(opt.threads);
  std::vector<float> small(size_t(w) * h * 4);
  if (opt.doublePrecision) dispatch<double>(opt.emptySpaceSkipping, opt.shade, c, geo, cam, w, h, aspect, threads, img, small);
  else dispatch<float>(opt.emptySpaceSkipping, opt.shade, c, geo, cam, w, h, aspect, threads, img, small);

  if (w == cam.width && h == cam.height) {
    img.rgba = std::move(small);
  } else {
    // Bilinear reconstruction from the coarse image (VTK's ImageSampleDistance), pixel centres aligned.
    img.rgba.assign(size_t(cam.width) * cam.height * 4, 0.f);
    const int W = cam.width, H = cam.height;
#pragma omp parallel for num_threads(threads) schedule(static)
    for (int y = 0; y < H; ++y) {
      const double sy = std::min(std::max((y + 0.5) * h / H - 0.5, 0.0), double(h - 1));
      const int y0 = std::min(static_cast<int>(sy), h - 1), y1 = std::min(y0 + 1, h - 1);
      const float fy = float(sy - y0);
      for (int x = 0; x < W; ++x) {
        const double sx = std::min(std::max((x + 0.5) * w / W - 0.5, 0.0), double(w - 1));
        const int x0 = std::min(static_cast<int>(sx), w - 1), x1 = std::min(x0 + 1, w - 1);
        const float fx = float(sx - x0);
        for (int ch = 0; ch < 4; ++ch) {
          const float a = small[(size_t(y0) * w + x0) * 4 + ch], b = small[(size_t(y0) * w + x1) * 4 + ch];
          const float cc = small[(size_t(y1) * w + x0) * 4 + ch], d = small[(size_t(y1) * w + x1) * 4 + ch];
          img.rgba[(size_t(y) * W + x) * 4 + ch] = (a + fx * (b - a)) * (1 - fy) + (cc + fx * (d - cc)) * fy;
        }
      }
    }
  }
  img.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return img;
}

}  // namespace mtree

// Private to engine/src/volume: the marchers and what they are made of, for render.cpp and
// march_avx2.cpp (see frame.h). Everything here is in an unnamed namespace: each file that
// includes it compiles its own copy, so march_avx2.cpp's AVX2-compiled copies never stand in for
// another file's (the linker would merge same-named inline functions).
//
//   march()       every storage and precision: positions in double, brick by brick (the general
//                 marcher, the arithmetic of opencl/volume.cl's mt_volume_march_*)
//   marchApron()  UInt8/UInt16 apron bricks in float: positions P0 + k S in float, 4-wide SSE2
//   (march_avx2.cpp's marcher takes the unshaded rays of marchApron 8 samples at a time)
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "frame.h"
#include "mtree/volume/volume.h"

namespace mtree {
namespace volume_detail {
namespace {

/// std::min and std::max (the same operand on ties and NaN) and infinity, as this file's own code
/// where march_avx2.cpp uses it: an unoptimized build emits std::min and the like as shared
/// functions, and an AVX2-compiled copy of one could then serve every caller.
template <typename T>
inline T lesser(T a, T b) {
  return b < a ? b : a;
}
template <typename T>
inline T greater(T a, T b) {
  return a < b ? b : a;
}
constexpr double kInfinity = std::numeric_limits<double>::infinity();

/// The marchers' per-sample and per-brick steps, inlined into every marcher whatever the size of
/// the file that instantiates them (the compiler's budget for inlining grows with the file).
#if defined(__GNUC__)
#define MT_MARCH_INLINE __attribute__((always_inline)) inline
#else
#define MT_MARCH_INLINE inline
#endif

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

/// Fetch policies: enter(brick) resolves a brick's storage once; corners(local cell) reads the 8
/// corners (x fastest) of a cell of that brick as floats (offset not applied). false: the cell
/// reads an absent block, so it is invisible (opacity 0).

/// An 8-bit voxel of bricks held in rows of y pairs (BlockSparseVolume::pairedRows): its own type,
/// so that the marchers pick that layout at compile time.
struct Paired8 {
  uint8_t v;
};
inline float voxelValue(uint8_t x) { return float(x); }
inline float voxelValue(uint16_t x) { return float(x); }
inline float voxelValue(Paired8 x) { return float(x.v); }

/// Where the corners of a brick's local cell (lx, ly, lz) are: corner 0 at entry cell(l), corner n
/// (x fastest, then y, then z) at cell(l) + corner[n]; BRICK entries a brick.
template <typename T>
struct ApronLayout {  // uint8_t, uint16_t: APRON^3 entries, x fastest
  static constexpr int SY = BlockSparseVolume::APRON, SZ = SY * SY, BRICK = BlockSparseVolume::BRICK_VOLUME;
  static constexpr int corner[8] = {0, 1, SY, SY + 1, SZ, SZ + 1, SZ + SY, SZ + SY + 1};
  static int cell(int lx, int ly, int lz) { return lx + SY * ly + SZ * lz; }
};
template <>
struct ApronLayout<Paired8> {  // rows of y pairs
  static constexpr int SZ = BlockSparseVolume::PAIR_SZ, BRICK = BlockSparseVolume::BRICK_BYTES8;
  static constexpr int corner[8] = {0, 2, 1, 3, SZ, SZ + 2, SZ + 1, SZ + 3};
  static int cell(int lx, int ly, int lz) { return BlockSparseVolume::pairOffset(lx, ly, lz); }
};

/// UInt8/UInt16 apron bricks: every corner inside the brick, fixed offsets.
template <typename T>
struct ApronFetch {
  using Layout = ApronLayout<T>;
  const uint32_t* ptr;
  const T* data;
  const uint64_t* masks;
  int nb0, nb1;
  const T* base = nullptr;
  const uint64_t* mask = nullptr;  // the brick's visible cells, one word per z layer
  explicit ApronFetch(const ApronBricks& b)
      : ptr(b.ptr), data(static_cast<const T*>(b.data)), masks(b.masks), nb0(b.nb0), nb1(b.nb1) {}
  ApronBricks bricks() const { return ApronBricks{ptr, data, masks, nb0, nb1}; }
  bool enter(int bi, int bj, int bk) {
    const size_t i = (size_t(bk) * nb1 + bj) * nb0 + bi;
    const uint32_t b = ptr[i];
    if (b == MT_NULL) return false;
    base = data + size_t(b) * Layout::BRICK;
    mask = masks + i * DIM;
    return true;
  }
  bool corners(int lx, int ly, int lz, float c[8]) const {
    if (!((mask[lz] >> (lx + DIM * ly)) & 1)) return false;  // invisible cell: opacity 0
    const T* p = base + Layout::cell(lx, ly, lz);
    for (int n = 0; n < 8; ++n) c[n] = voxelValue(p[Layout::corner[n]]);
    return true;
  }
};

/// Float32 block-sparse matrix (no apron): on entry, the brick's block and its 7 neighbours
/// towards +x/+y/+z; a cell whose corners all lie in the brick's block (7/8 per axis) reads them
/// at fixed offsets, the others pick each corner's block by the carry of its local index.
struct FloatFetch {
  const uint32_t* ptr;
  const float* data;
  int lb0, lb1, lb2, pd0, pd1, pd2, e0, e1, e2;
  uint32_t bv;
  const float* nbr[8] = {nullptr, nullptr, nullptr, nullptr, nullptr, nullptr, nullptr, nullptr};
  explicit FloatFetch(const BlockSparseMatrix<float>& m)
      : ptr(m.pointers().data()), data(m.data().data()), lb0(m.desc().logBlock[0]), lb1(m.desc().logBlock[1]),
        lb2(m.desc().logBlock[2]), pd0(m.desc().ptrDims[0]), pd1(m.desc().ptrDims[1]), pd2(m.desc().ptrDims[2]),
        e0((1 << lb0) - 1), e1((1 << lb1) - 1), e2((1 << lb2) - 1), bv(m.desc().blockVolume) {}
  bool enter(int bi, int bj, int bk) {
    // A block edge below DIM only happens on an axis that has a single block: brick = block.
    for (int n = 0; n < 8; ++n) {
      const int x = bi + (n & 1), y = bj + ((n >> 1) & 1), z = bk + (n >> 2);
      const uint32_t b = (x < pd0 && y < pd1 && z < pd2) ? ptr[(size_t(z) * pd1 + y) * pd0 + x] : MT_NULL;
      nbr[n] = b == MT_NULL ? nullptr : data + size_t(b) * bv;
    }
    return nbr[0] != nullptr;  // every cell of the brick has a corner in its own block
  }
  MT_MARCH_INLINE bool corners(int lx, int ly, int lz, float c[8]) const {
    const int sy = 1 << lb0, sz = 1 << (lb0 + lb1);
    if (lx < e0 && ly < e1 && lz < e2) {
      const float* p = nbr[0] + ((lz << (lb0 + lb1)) | (ly << lb0) | lx);
      c[0] = p[0]; c[1] = p[1]; c[2] = p[sy]; c[3] = p[sy + 1];
      c[4] = p[sz]; c[5] = p[sz + 1]; c[6] = p[sz + sy]; c[7] = p[sz + sy + 1];
      return true;
    }
    const int cx = lx == e0, cy = ly == e1, cz = lz == e2;
    const int ox[2] = {lx, (lx + 1) & e0}, oy[2] = {ly << lb0, ((ly + 1) & e1) << lb0},
              oz[2] = {lz << (lb0 + lb1), ((lz + 1) & e2) << (lb0 + lb1)};
    for (int n = 0; n < 8; ++n) {
      const int dx = n & 1, dy = (n >> 1) & 1, dz = n >> 2;
      const float* b = nbr[(dx & cx) | ((dy & cy) << 1) | ((dz & cz) << 2)];
      if (!b) return false;
      c[n] = b[oz[dz] | oy[dy] | ox[dx]];
    }
    return true;
  }
};

/// Front-to-back accumulator: premultiplied colour and opacity.
template <typename R>
struct Acc {
  R c[4] = {0, 0, 0, 0};
  R alpha() const { return c[3]; }
  void add(R r, R g, R b, R a) {
    const R w = 1 - c[3];
    c[0] += w * r;
    c[1] += w * g;
    c[2] += w * b;
    c[3] += w * a;
  }
  void add(const float* e) { add(R(e[0]), R(e[1]), R(e[2]), R(e[3])); }
  void store(float out[4]) const {
    for (int ch = 0; ch < 4; ++ch) out[ch] = float(c[ch]);
  }
};

#if defined(__GNUC__)
typedef float v4f __attribute__((vector_size(16)));
/// float: the four channels in one SSE register, one multiply-add per sample.
template <>
struct Acc<float> {
  v4f c = {0, 0, 0, 0};
  float alpha() const { return c[3]; }
  void add(const float* e) {
    v4f v;
    __builtin_memcpy(&v, e, sizeof v);
    c += (1.f - c[3]) * v;
  }
  void add(float r, float g, float b, float a) {
    const v4f v = {r, g, b, a};
    c += (1.f - c[3]) * v;
  }
  void store(float out[4]) const { __builtin_memcpy(out, &c, sizeof c); }
};
#endif

/// The shaded colour of a sample (headlight, two-sided), from the trilinear interpolant's gradient.
template <typename R, typename Accumulator>
inline void shadeSample(const Frame& F, const float cc[8], R fx, R fy, R fz, const float* e, const double viewDir[3],
                        Accumulator& acc) {
  const R gx = (1 - fy) * (1 - fz) * (cc[1] - cc[0]) + fy * (1 - fz) * (cc[3] - cc[2]) +
               (1 - fy) * fz * (cc[5] - cc[4]) + fy * fz * (cc[7] - cc[6]);
  const R gy = (1 - fx) * (1 - fz) * (cc[2] - cc[0]) + fx * (1 - fz) * (cc[3] - cc[1]) +
               (1 - fx) * fz * (cc[6] - cc[4]) + fx * fz * (cc[7] - cc[5]);
  const R gz = (1 - fx) * (1 - fy) * (cc[4] - cc[0]) + fx * (1 - fy) * (cc[5] - cc[1]) +
               (1 - fx) * fy * (cc[6] - cc[2]) + fx * fy * (cc[7] - cc[3]);
  const R wx = gx / R(F.spacing[0]), wy = gy / R(F.spacing[1]), wz = gz / R(F.spacing[2]);
  const R len = std::sqrt(wx * wx + wy * wy + wz * wz);
  R r = e[0], g = e[1], b = e[2];
  const R a = e[3];
  if (len > 0) {
    const R ndl = std::fabs(wx * R(viewDir[0]) + wy * R(viewDir[1]) + wz * R(viewDir[2])) / len;
    const R s = R(F.ambient) + R(F.diffuse) * ndl;
    const R spec = R(F.specular) * std::pow(ndl, R(F.specularPower)) * a;
    r = r * s + spec;
    g = g * s + spec;
    b = b * s + spec;
  }
  acc.add(r, g, b, a);
}

/// TransferTable::index: clamped into [0, last] as a float, before the cast (a float past
/// INT_MAX has no int); NaN goes to 0 (std::max(0, NaN) is 0).
inline int tableIndex(const Frame& F, float v) {
  const float x = (v - F.tlo) * F.tscale + 0.5f;
  return static_cast<int>(std::min(std::max(0.f, x), float(F.tlast)));
}

/// The t where the index-space ray (o, d) leaves the box [lo, hi] (it is inside at some t).
inline double exitT(const double o[3], const double d[3], const double lo[3], const double hi[3]) {
  double t = std::numeric_limits<double>::infinity();
  for (int a = 0; a < 3; ++a) {
    if (d[a] > 0) t = std::min(t, (hi[a] - o[a]) / d[a]);
    else if (d[a] < 0) t = std::min(t, (lo[a] - o[a]) / d[a]);
  }
  return t;
}

/// Classifies and composites one sample of cell corners `cc` at fractions (fx, fy, fz).
/// Returns true when the ray is opaque (early termination).
template <typename R, bool Shade>
MT_MARCH_INLINE bool composite(const Frame& F, const float cc[8], R fx, R fy, R fz, const double viewDir[3], Acc<R>& acc,
                      float offset) {
  const float v = float(trilinear<R>(cc, fx, fy, fz) + R(offset));
  const float* e = F.table + 4 * tableIndex(F, v);
  if (Shade) {
    if (!(e[3] > 0.f)) return false;
    shadeSample<R>(F, cc, fx, fy, fz, e, viewDir, acc);
  } else {
    // No branch on a transparent entry (it is 0 0 0 0: adding (1 - A) * 0 leaves the sums
    // exactly as they are), so a ray crossing the opacity threshold costs no mispredictions.
    acc.add(e);
  }
  return acc.alpha() >= R(F.threshold);
}

/// The coarsest empty ancestor of brick (bi, bj, bk) as a level (0: the brick itself), or -1 when
/// the brick may be visible. Levels are ORs of their children: climb while empty.
MT_MARCH_INLINE int coarsestInvisible(const BlockSparseVolume& vol, int levels, int bi, int bj, int bk) {
  if (vol.nodeVisible(0, bi, bj, bk)) return -1;
  int empty = 0;
  while (empty + 1 < levels && !vol.nodeVisible(empty + 1, bi >> (empty + 1), bj >> (empty + 1), bk >> (empty + 1)))
    ++empty;
  return empty;
}

/// The corners and fractions of the cell of position (x, y, z), clamped into the grid (clampCell);
/// false where the cell is invisible. The marchers' rare path (the grid's far faces, round-off
/// across a brick face): kept out of their loops.
#if defined(__GNUC__)
__attribute__((noinline, cold)) inline
#endif
bool clampedCorners(const BlockSparseVolume& vol, const int n[3], double x, double y, double z, float cc[8],
                    double f[3]) {
  const int ci = clampCell(x, n[0], f[0]), cj = clampCell(y, n[1], f[1]), ck = clampCell(z, n[2], f[2]);
  return vol.cellCornersInSampleUnits(ci, cj, ck, cc);
}

/// Marches one ray over samples k = 0..kEnd at t_k = t0 + k dt, position o + d t_k (index
/// space, double, the arithmetic of opencl/volume.cl, so both back ends see the same samples).
/// The ray is walked brick by brick: at sample k the brick is looked up (and, skipping, its
/// coarsest empty ancestor is left at its exit); samples up to the brick's exit then read the
/// brick's storage directly, without clamping or pointer-matrix reads.
template <typename R, typename Fetch, bool Skip, bool Shade>
void march(const Frame& F, Fetch fetch, const double o[3], const double d[3], double t0, int64_t kEnd,
           const double viewDir[3], float out[4], uint64_t& samplesOut, uint64_t& skipsOut) {
  const BlockSparseVolume& vol = *F.vol;
  uint64_t samples = 0, skips = 0;
  Acc<R> acc;
  const double dt = F.dt;
  const int levels = vol.levelCount();
  int64_t k = 0;
  while (k <= kEnd) {
    const double t = t0 + double(k) * dt;
    int cell[3];
    for (int a = 0; a < 3; ++a) {
      double f;
      cell[a] = clampCell(o[a] + d[a] * t, F.n[a], f);
    }
    const int bi = cell[0] >> LOG2DIM, bj = cell[1] >> LOG2DIM, bk = cell[2] >> LOG2DIM;
    const int empty = Skip ? coarsestInvisible(vol, levels, bi, bj, bk) : -1;
    const int L = empty < 0 ? 0 : empty;
    const double edge = double(DIM << L);
    const double lo[3] = {double(bi >> L) * edge, double(bj >> L) * edge, double(bk >> L) * edge};
    const double hi[3] = {lo[0] + edge, lo[1] + edge, lo[2] + edge};
    // Last sample at or before the node's exit (floor: never jump over a sample that might lie
    // beyond it in a visible node; an extra sample in an empty node adds exactly 0).
    const double kx = std::floor((exitT(o, d, lo, hi) - t0) / dt);
    const int64_t kLast = kx >= double(kEnd) ? kEnd : std::max<int64_t>(k, static_cast<int64_t>(kx));
    if (empty >= 0) {
      ++skips;
      k = std::max(k + 1, kLast);
      continue;
    }
    if (!fetch.enter(bi, bj, bk)) {  // an absent brick (not skipping): every cell is invisible
      k = kLast + 1;
      continue;
    }
    const int ox = bi << LOG2DIM, oy = bj << LOG2DIM, oz = bk << LOG2DIM;
    const unsigned mx = unsigned(std::min(DIM - 1, F.n[0] - 2 - ox)), my = unsigned(std::min(DIM - 1, F.n[1] - 2 - oy)),
                   mz = unsigned(std::min(DIM - 1, F.n[2] - 2 - oz));
    double kd = double(k);
    for (; k <= kLast; ++k, kd += 1.0) {
      const double ts = t0 + kd * dt;
      const double x = o[0] + d[0] * ts, y = o[1] + d[1] * ts, z = o[2] + d[2] * ts;
      const int ix = static_cast<int>(x), iy = static_cast<int>(y), iz = static_cast<int>(z);
      const int lx = ix - ox, ly = iy - oy, lz = iz - oz;
      float cc[8];
      R fx, fy, fz;
      float offset = F.offset;  // the fetch reads stored values; cellCornersInSampleUnits() adds it
      if (((unsigned(lx) > mx) | (unsigned(ly) > my) | (unsigned(lz) > mz)) == 0) {
        // In the brick and in [0, n-1): clampCell's cell is the truncation (x in (-1, 0)
        // truncates to 0 with fraction 0) and its fraction x - cell.
        fx = R(std::max(x - double(ix), 0.0));
        fy = R(std::max(y - double(iy), 0.0));
        fz = R(std::max(z - double(iz), 0.0));
        if (!fetch.corners(lx, ly, lz, cc)) continue;
      } else {
        // Round-off put the sample in a neighbouring brick, or it needs clamping: general path.
        double f[3];
        if (!clampedCorners(vol, F.n, x, y, z, cc, f)) continue;
        fx = R(f[0]), fy = R(f[1]), fz = R(f[2]);
        offset = 0.f;
      }
      ++samples;
      if (composite<R, Shade>(F, cc, fx, fy, fz, viewDir, acc, offset)) {
        k = kEnd + 1;
        break;
      }
    }
    k = std::max(k, kLast + 1);
  }
  samplesOut += samples;
  skipsOut += skips;
  acc.store(out);
}

#if defined(__SSE2__)
/// Transmittance-form accumulator: C += T e, T *= 1 - a. The loop-carried chain is one multiply
/// (the A += (1 - A) a form is a subtract, a multiply and an add), which bounds a ray's rate.
struct AccT {
  __m128 c = _mm_setzero_ps();
  float T = 1.f;
  void add(const float* e) {
    c = _mm_add_ps(c, _mm_mul_ps(_mm_set1_ps(T), _mm_loadu_ps(e)));
    T *= 1.f - e[3];
  }
  void add(float r, float g, float b, float a) {
    c = _mm_add_ps(c, _mm_mul_ps(_mm_set1_ps(T), _mm_setr_ps(r, g, b, a)));
    T *= 1.f - a;
  }
};

/// The 8 corners of local cell `off` of an apron brick as two vectors: z = 0 (x fastest, then y)
/// and z = 1.
inline void apronCorners(const uint8_t* p, __m128& lo, __m128& hi) {
  constexpr int SY = BlockSparseVolume::APRON, SZ = SY * SY;
  uint16_t a, b, c, d;
  std::memcpy(&a, p, 2);
  std::memcpy(&b, p + SY, 2);
  std::memcpy(&c, p + SZ, 2);
  std::memcpy(&d, p + SZ + SY, 2);
  const __m128i z = _mm_setzero_si128();
  __m128i v = _mm_cvtsi32_si128(int(uint32_t(a) | (uint32_t(b) << 16)));
  v = _mm_insert_epi16(v, c, 2);
  v = _mm_insert_epi16(v, d, 3);
  const __m128i w = _mm_unpacklo_epi8(v, z);
  lo = _mm_cvtepi32_ps(_mm_unpacklo_epi16(w, z));
  hi = _mm_cvtepi32_ps(_mm_unpackhi_epi16(w, z));
}
inline void apronCorners(const Paired8* q, __m128& lo, __m128& hi) {
  const uint8_t* p = &q->v;
  uint32_t a, b;  // bytes (x, y), (x, y + 1), (x + 1, y), (x + 1, y + 1) of planes z and z + 1
  std::memcpy(&a, p, 4);
  std::memcpy(&b, p + BlockSparseVolume::PAIR_SZ, 4);
  const __m128i z = _mm_setzero_si128();
  const __m128i w = _mm_unpacklo_epi8(_mm_unpacklo_epi32(_mm_cvtsi32_si128(int(a)), _mm_cvtsi32_si128(int(b))), z);
  const __m128 l = _mm_cvtepi32_ps(_mm_unpacklo_epi16(w, z)), h = _mm_cvtepi32_ps(_mm_unpackhi_epi16(w, z));
  lo = _mm_shuffle_ps(l, l, _MM_SHUFFLE(3, 1, 2, 0));  // (x, y), (x + 1, y), (x, y + 1), (x + 1, y + 1)
  hi = _mm_shuffle_ps(h, h, _MM_SHUFFLE(3, 1, 2, 0));
}
inline void apronCorners(const uint16_t* p, __m128& lo, __m128& hi) {
  constexpr int SY = BlockSparseVolume::APRON, SZ = SY * SY;
  uint32_t a, b, c, d;
  std::memcpy(&a, p, 4);
  std::memcpy(&b, p + SY, 4);
  std::memcpy(&c, p + SZ, 4);
  std::memcpy(&d, p + SZ + SY, 4);
  const __m128i z = _mm_setzero_si128();
  const __m128i v0 = _mm_unpacklo_epi32(_mm_cvtsi32_si128(int(a)), _mm_cvtsi32_si128(int(b)));
  const __m128i v1 = _mm_unpacklo_epi32(_mm_cvtsi32_si128(int(c)), _mm_cvtsi32_si128(int(d)));
  lo = _mm_cvtepi32_ps(_mm_unpacklo_epi16(v0, z));
  hi = _mm_cvtepi32_ps(_mm_unpacklo_epi16(v1, z));
}

/// x * s per 32-bit lane for s in {-1, 1} (SSE2 has no pmulld): x, or -x where s is -1.
inline __m128i _mm_mullo_epi32_sse2(__m128i x, __m128i s) {
  const __m128i neg = _mm_srai_epi32(s, 31);
  return _mm_sub_epi32(_mm_xor_si128(x, neg), neg);
}

/// Per-ray constants of the UInt8/UInt16 float marchers: sample k sits at P0 + k S, each axis in
/// float (a multiply, then an add: never fused, so every marcher and the OpenCL kernel agree).
struct ApronRay {
  float P0s[3], Ss[3];
  __m128 P0, S;
  __m128 nf;     // points per axis (float; 1 in lane 3)
  __m128i nm2;   // the last cell per axis, n - 2 (0 in lane 3)
  __m128i sign;  // per axis -1 where the ray runs towards lower indices, else 1 (1 in lane 3)
  int octant;    // bit a set: negative along axis a (BlockSparseVolume::brickDistances)
  ApronRay() = default;
  ApronRay(const Frame& F, const double o[3], const double d[3], double t0) { set(F, o, d, t0); }
  void set(const Frame& F, const double o[3], const double d[3], double t0) {
    for (int a = 0; a < 3; ++a) {
      P0s[a] = float(o[a] + d[a] * t0);
      Ss[a] = float(d[a] * F.dt);
    }
    P0 = _mm_setr_ps(P0s[0], P0s[1], P0s[2], 0.f);
    S = _mm_setr_ps(Ss[0], Ss[1], Ss[2], 0.f);
    nf = _mm_setr_ps(float(F.n[0]), float(F.n[1]), float(F.n[2]), 1.f);
    nm2 = _mm_setr_epi32(F.n[0] - 2, F.n[1] - 2, F.n[2] - 2, 0);
    octant = (Ss[0] < 0 ? 1 : 0) | (Ss[1] < 0 ? 2 : 0) | (Ss[2] < 0 ? 4 : 0);
    sign = _mm_setr_epi32(Ss[0] < 0 ? -1 : 1, Ss[1] < 0 ? -1 : 1, Ss[2] < 0 ? -1 : 1, 1);
  }
  __m128 at(float kf) const { return _mm_add_ps(P0, _mm_mul_ps(_mm_set1_ps(kf), S)); }
  /// clampCell's cells of a position's three coordinates at once, in float (exact: the input is a
  /// float, the points per axis < 2^24): clamped into [-1, n], floor, clamped into [0, n - 2];
  /// NaN gives cell 0 as there.
  __m128i cells(__m128 p) const {
    const __m128 pc = _mm_min_ps(_mm_max_ps(p, _mm_set1_ps(-1.f)), nf);  // maxps(NaN, -1) = -1
    __m128i c = _mm_cvttps_epi32(pc);
    c = _mm_add_epi32(c, _mm_castps_si128(_mm_cmplt_ps(pc, _mm_cvtepi32_ps(c))));  // truncation -> floor
    c = _mm_and_si128(c, _mm_cmpgt_epi32(c, _mm_set1_epi32(-1)));                   // max(c, 0)
    const __m128i over = _mm_cmpgt_epi32(c, nm2);
    return _mm_or_si128(_mm_and_si128(over, nm2), _mm_andnot_si128(over, c));      // min(c, n - 2)
  }
};

/// One step of the apron walk at sample k: looks up the brick holding it (clamped into the grid).
/// True when that brick is stored and visible (`fetch` has entered it; its first cell is returned
/// in o). Otherwise the ray is in an empty node (with skipping: the brick's coarsest empty
/// ancestor; without: the absent brick) and k moves to the last sample at or before the node's
/// exit (floor, as march(); at least k + 1).
template <typename T, bool Skip>
inline bool apronEnter(const Frame& F, const ApronRay& ray, int64_t kEnd, ApronFetch<T>& fetch,
                       int64_t& k, uint64_t& skips, int o[3]) {
  const __m128i brick = _mm_srai_epi32(ray.cells(ray.at(float(k))), LOG2DIM);
  const int bi = _mm_cvtsi128_si32(brick), bj = _mm_cvtsi128_si32(_mm_shuffle_epi32(brick, 0x55)),
            bk = _mm_cvtsi128_si32(_mm_shuffle_epi32(brick, 0xAA));
  int r = Skip ? F.dist[((size_t(bk) * F.nb[1] + bj) * F.nb[0] + bi) * 8 + ray.octant] : 0;
  if (r == 0 && !fetch.enter(bi, bj, bk)) r = 1;  // visible, but no brick stored
  if (r == 0) {
    o[0] = bi << LOG2DIM;
    o[1] = bj << LOG2DIM;
    o[2] = bk << LOG2DIM;
    return true;
  }
  // The cube of r^3 invisible bricks from b towards the ray's octant: its far faces.
  const int node[3] = {bi, bj, bk};
  double kx = kInfinity;
  for (int a = 0; a < 3; ++a) {
    const double s = double(ray.Ss[a]);
    if (s > 0) kx = lesser(kx, (double((node[a] + r) * DIM) - double(ray.P0s[a])) / s);
    else if (s < 0) kx = lesser(kx, (double((node[a] - r + 1) * DIM) - double(ray.P0s[a])) / s);
  }
  const double kf = std::floor(kx);
  const int64_t kLast = kf >= double(kEnd) ? kEnd : greater<int64_t>(k, static_cast<int64_t>(kf));
  if (Skip) ++skips;
  if (kLast > k) {
    // The exit is rounded down, so sample kLast is usually still in the cube (its brick at most
    // r - 1 ahead on every axis): then it is skipped too, counted as one more skip.
    const __m128i ahead = _mm_mullo_epi32_sse2(_mm_sub_epi32(_mm_srai_epi32(ray.cells(ray.at(float(kLast))), LOG2DIM), brick), ray.sign);
    if ((_mm_movemask_epi8(_mm_cmpgt_epi32(ahead, _mm_set1_epi32(r - 1))) & 0xFFF) == 0) {
      if (Skip) ++skips;
      k = kLast + 1;
      return false;
    }
  }
  k = greater(k + 1, kLast);
  return false;
}

/// The sample at position p (x, y, z, then any) where it needs clamping (the grid's far face, or
/// outside it by round-off): the general path (clampCell, cellCorners, x-first interpolation).
/// True when the ray is opaque.
template <bool Shade>
inline bool apronClampedSampleAt(const Frame& F, const float p[4], const double viewDir[3], AccT& acc,
                                 uint64_t& samples) {
  double f[3];
  int c[3];
  for (int a = 0; a < 3; ++a) c[a] = clampCell(double(p[a]), F.n[a], f[a]);
  float cc[8];
  if (!F.vol->cellCornersInSampleUnits(c[0], c[1], c[2], cc)) return false;
  ++samples;
  const float v = trilinear<float>(cc, float(f[0]), float(f[1]), float(f[2]));  // offset is in cc
  const float* e = F.table + 4 * tableIndex(F, v);
  if constexpr (Shade) {
    if (e[3] > 0.f) shadeSample<float>(F, cc, float(f[0]), float(f[1]), float(f[2]), e, viewDir, acc);
  } else {
    acc.add(e);
  }
  return acc.T <= 1.f - F.threshold;
}
/// apronClampedSampleAt at sample k of `ray`.
template <bool Shade>
inline bool apronClampedSample(const Frame& F, const ApronRay& ray, int64_t k, const double viewDir[3], AccT& acc,
                               uint64_t& samples) {
  alignas(16) float p[4];
  _mm_store_ps(p, ray.at(float(k)));
  return apronClampedSampleAt<Shade>(F, p, viewDir, acc, samples);
}

/// The UInt8/UInt16 marcher (float accumulation): positions P0 + k S in float, 4-wide (x, y, z in
/// one register: one multiply-add, one conversion, one bounds test per sample), corners fetched
/// and interpolated as vectors, branch-free classification. Same walk as march(): brick lookup
/// and coarsest-empty-ancestor skipping at sample k, samples inside a stored brick read it
/// directly, a sample needing clamping takes the general path.
template <typename T, bool Skip, bool Shade>
void marchApron(const Frame& F, ApronFetch<T> fetch, const double o[3], const double d[3], double t0, int64_t kEnd,
                const double viewDir[3], float out[4], uint64_t& samplesOut, uint64_t& skipsOut) {
  uint64_t samples = 0, skips = 0;
  AccT acc;
  const float Tmin = 1.f - F.threshold;  // stop when the transmittance falls to this
  const ApronRay ray(F, o, d, t0);
  const __m128 zero = _mm_setzero_ps();
  const __m128 tlo = _mm_set_ss(F.tlo), tscale = _mm_set_ss(F.tscale), half = _mm_set_ss(0.5f);
  const __m128 tlast = _mm_set_ss(float(F.tlast));
  const float* const table = F.table;
  const float offset = F.offset;
  int64_t k = 0;
  while (k <= kEnd) {
    int bo[3];
    if (!apronEnter<T, Skip>(F, ray, kEnd, fetch, k, skips, bo)) continue;
    const __m128i org = _mm_setr_epi32(bo[0], bo[1], bo[2], 0);
    const __m128i lim = _mm_setr_epi32(std::min(DIM - 1, F.n[0] - 2 - bo[0]), std::min(DIM - 1, F.n[1] - 2 - bo[1]),
                                       std::min(DIM - 1, F.n[2] - 2 - bo[2]), 0);
    const __m128i zeroi = _mm_setzero_si128();
    const int64_t kStart = k;
    bool done = false;
    float kf = float(k);
    for (; k <= kEnd; ++k, kf += 1.f) {
      const __m128 pos = ray.at(kf);
      const __m128i ip = _mm_cvttps_epi32(pos);
      const __m128i l = _mm_sub_epi32(ip, org);
      const __m128i out4 = _mm_or_si128(_mm_cmpgt_epi32(l, lim), _mm_cmpgt_epi32(zeroi, l));
      if (_mm_movemask_epi8(out4)) break;  // left the brick (or needs clamping)
      // x in (-1, 0) truncates to cell 0: the clamped fraction is 0, as clampCell gives.
      const __m128 f = _mm_max_ps(_mm_sub_ps(pos, _mm_cvtepi32_ps(ip)), zero);
      const int lx = _mm_cvtsi128_si32(l), ly = _mm_cvtsi128_si32(_mm_shuffle_epi32(l, 0x55)),
                lz = _mm_cvtsi128_si32(_mm_shuffle_epi32(l, 0xAA));
      // An invisible cell (opacity 0 on its whole value range, see the header) adds exactly 0.
      if (!((fetch.mask[lz] >> (lx + DIM * ly)) & 1)) continue;
      __m128 c0, c1;
      apronCorners(fetch.base + ApronFetch<T>::Layout::cell(lx, ly, lz), c0, c1);
      const __m128 fz = _mm_shuffle_ps(f, f, 0xAA), fy = _mm_shuffle_ps(f, f, 0x55);
      const __m128 zl = _mm_add_ps(c0, _mm_mul_ps(fz, _mm_sub_ps(c1, c0)));  // (x0y0, x1y0, x0y1, x1y1)
      const __m128 yl = _mm_add_ps(zl, _mm_mul_ps(fy, _mm_sub_ps(_mm_movehl_ps(zl, zl), zl)));  // (x0, x1)
      const __m128 x1 = _mm_shuffle_ps(yl, yl, 0x55);
      const __m128 v = _mm_add_ss(_mm_add_ss(yl, _mm_mul_ss(f, _mm_sub_ss(x1, yl))), _mm_set_ss(offset));
      ++samples;
      // TransferTable::index, branch-free: clamped into [0, last] as a float (NaN to 0: maxss
      // returns its second operand then), then truncated; a float past INT_MAX has no int.
      const __m128 x = _mm_add_ss(_mm_mul_ss(_mm_sub_ss(v, tlo), tscale), half);
      const int idx = _mm_cvttss_si32(_mm_min_ss(_mm_max_ss(x, zero), tlast));
      const float* e = table + 4 * idx;
      if (Shade) {
        if (!(e[3] > 0.f)) continue;
        alignas(16) float cc[8], fs[4];
        _mm_store_ps(cc, c0);
        _mm_store_ps(cc + 4, c1);
        _mm_store_ps(fs, f);
        shadeSample<float>(F, cc, fs[0], fs[1], fs[2], e, viewDir, acc);
      } else {
        acc.add(e);  // a transparent entry is 0 0 0 0: no change
      }
      if (acc.T <= Tmin) {
        done = true;
        break;
      }
    }
    if (done) break;
    if (k == kStart) {
      if (apronClampedSample<Shade>(F, ray, k, viewDir, acc, samples)) break;
      ++k;
    }
  }
  samplesOut += samples;
  skipsOut += skips;
  _mm_storeu_ps(out, acc.c);
}
#endif  // __SSE2__

}  // namespace
}  // namespace volume_detail
}  // namespace mtree

// The AVX2 marcher of UInt8/UInt16 apron bricks and the AVX2 set-up of 4 perspective rays: the
// one file of the engine compiled for AVX2 (engine/CMakeLists.txt: -mavx2 on this file only, and
// MATRIXTREE_VOLUME_AVX2 for the engine). renderVolume calls into it only where the CPU runs AVX2
// (render.cpp: cpuHasAvx2), else the SSE2 marcher and the scalar set-up, which give the same image
// bit for bit: the same float operations in the same order, none fused (no -mfma: a fused
// multiply-add rounds once where the SSE2 marcher rounds twice).
//
// What this file runs for AVX2 is its own: march.h's code comes in its unnamed namespace, this
// file's in its own, and BlockSparseVolume::cellCornersInSampleUnits (inline, shared) is reached only through
// clampedSampleUnshaded, compiled in render.cpp. So no AVX2-compiled copy of a shared inline
// function can stand in for the baseline one.
#if MATRIXTREE_VOLUME_AVX2

#if !defined(__AVX2__)
#error "march_avx2.cpp must be compiled with -mavx2 (engine/CMakeLists.txt)"
#endif

#include <immintrin.h>

#include "march.h"

namespace mtree {
namespace volume_detail {
namespace {

/// The 8 corners (x fastest, then y, then z) of 8 cells of apron bricks, corner 0 of lane j at
/// entry off[j] of `base` (ApronLayout), as floats. uint8_t/uint16_t: one 32-bit gather per
/// corner pair (x, x + 1) (8-bit: it reads 2 bytes past the pair; the brick array is padded for
/// it, see BlockSparseVolume::BRICK_PAD); Paired8: one per z plane (its 4 corners are
/// consecutive bytes).
__attribute__((always_inline)) inline void gatherCorners(const uint8_t* base, __m256i off, __m256 c[8]) {
  constexpr int SY = BlockSparseVolume::APRON, SZ = SY * SY;
  const int rows[4] = {0, SY, SZ, SZ + SY};
  const __m256i m = _mm256_set1_epi32(0xFF);
  // Byte 1 of each 32-bit lane into byte 0, zeros above (one shuffle for a shift and a mask).
  const __m256i byte1 = _mm256_setr_epi8(1, -1, -1, -1, 5, -1, -1, -1, 9, -1, -1, -1, 13, -1, -1, -1,
                                         1, -1, -1, -1, 5, -1, -1, -1, 9, -1, -1, -1, 13, -1, -1, -1);
  for (int r = 0; r < 4; ++r) {
    const __m256i w = _mm256_i32gather_epi32(reinterpret_cast<const int*>(base),
                                             r ? _mm256_add_epi32(off, _mm256_set1_epi32(rows[r])) : off, 1);
    c[2 * r] = _mm256_cvtepi32_ps(_mm256_and_si256(w, m));
    c[2 * r + 1] = _mm256_cvtepi32_ps(_mm256_shuffle_epi8(w, byte1));
  }
}
__attribute__((always_inline)) inline void gatherCorners(const uint16_t* base, __m256i off, __m256 c[8]) {
  constexpr int SY = BlockSparseVolume::APRON, SZ = SY * SY;
  const int rows[4] = {0, SY, SZ, SZ + SY};
  for (int r = 0; r < 4; ++r) {
    const __m256i w = _mm256_i32gather_epi32(reinterpret_cast<const int*>(base),
                                             r ? _mm256_add_epi32(off, _mm256_set1_epi32(rows[r])) : off, 2);
    c[2 * r] = _mm256_cvtepi32_ps(_mm256_and_si256(w, _mm256_set1_epi32(0xFFFF)));
    c[2 * r + 1] = _mm256_cvtepi32_ps(_mm256_srli_epi32(w, 16));
  }
}
__attribute__((always_inline)) inline void gatherCorners(const Paired8* base, __m256i off, __m256 c[8]) {
  const __m256i m = _mm256_set1_epi32(0xFF);
  const __m256i byte1 = _mm256_setr_epi8(1, -1, -1, -1, 5, -1, -1, -1, 9, -1, -1, -1, 13, -1, -1, -1,
                                         1, -1, -1, -1, 5, -1, -1, -1, 9, -1, -1, -1, 13, -1, -1, -1);
  const __m256i byte2 = _mm256_setr_epi8(2, -1, -1, -1, 6, -1, -1, -1, 10, -1, -1, -1, 14, -1, -1, -1,
                                         2, -1, -1, -1, 6, -1, -1, -1, 10, -1, -1, -1, 14, -1, -1, -1);
  for (int z = 0; z < 2; ++z) {
    const __m256i w = _mm256_i32gather_epi32(
        reinterpret_cast<const int*>(base), z ? _mm256_add_epi32(off, _mm256_set1_epi32(BlockSparseVolume::PAIR_SZ)) : off, 1);
    c[4 * z + 0] = _mm256_cvtepi32_ps(_mm256_and_si256(w, m));         // (x, y)
    c[4 * z + 2] = _mm256_cvtepi32_ps(_mm256_shuffle_epi8(w, byte1));  // (x, y + 1)
    c[4 * z + 1] = _mm256_cvtepi32_ps(_mm256_shuffle_epi8(w, byte2));  // (x + 1, y)
    c[4 * z + 3] = _mm256_cvtepi32_ps(_mm256_srli_epi32(w, 24));       // (x + 1, y + 1)
  }
}

/// Entry of corner 0 of local cell (lx, ly, lz) of the stored brick whose first entry is `first`
/// (Frame::runBricks), bit = lx + 8 ly + 64 lz (ApronLayout, 8 lanes). 9^3 entries: first + lx +
/// 9 ly + 81 lz = first + bit + ly + 17 lz; Paired8: first + 2 lx + 18 ly + 144 lz = first + 2 (bit +
/// ly + 8 lz).
template <typename T>
__attribute__((always_inline)) inline __m256i cornerEntry(const T*, __m256i first, __m256i bit, __m256i ly,
                                                                 __m256i lz) {
  return _mm256_add_epi32(first, _mm256_add_epi32(bit, _mm256_add_epi32(ly, _mm256_add_epi32(_mm256_slli_epi32(lz, 4), lz))));
}
__attribute__((always_inline)) inline __m256i cornerEntry(const Paired8*, __m256i first, __m256i bit, __m256i ly,
                                                                 __m256i lz) {
  return _mm256_add_epi32(first, _mm256_slli_epi32(_mm256_add_epi32(bit, _mm256_add_epi32(ly, _mm256_slli_epi32(lz, 3))), 1));
}

/// The per-ray constants of the AVX2 chunks (broadcast once per ray).
template <typename T>
struct Avx2Ray {  // scalars, broadcast where used (a load each, like a vector constant's)
  float P0x, P0y, P0z, Sx, Sy, Sz;
  int mx, my, mz;  // n - 2 per axis: cells that need no clamping are 0..n-2
  int nb0, nb01;   // level-0 bricks along x, in an xy layer
  float tlo, tscale, offset;
  int tlast, zeroEntry;
  const int* bricks;  // F.runBricks: MT_NULL (-1) where the walk takes over
  const int* words;   // per level-0 brick 16 mask words: bit x + 8 y + 64 z
  const T* data;
};

/// One chunk of 8 consecutive samples k..k+7 (kf = k as a float): how many leading lanes are
/// taken (n: the cell needs no clamping, its brick is stored and visible, and the sample is one of
/// the ray's, i.e. lane <= left = kEnd - k), which of those lanes' cells are visible (vis), and
/// each lane's offset into Frame::table8 (idx; the all-zero entry for an invisible cell). Only computed
/// when vis != 0.
struct Avx2Chunk {
  int n;
  unsigned vis;
  __m256i idx;
};

template <typename T>
__attribute__((always_inline)) inline void avx2Chunk(const Avx2Ray<T>& R, float kf, int64_t left,
                                                              Avx2Chunk& out) {
  static_assert(BlockSparseVolume::APRON == 9 && DIM == 8, "the offsets below assume 9^3-voxel bricks of 8^3 cells");
  const __m256i seven = _mm256_set1_epi32(DIM - 1);
  const __m256 P0x = _mm256_set1_ps(R.P0x), P0y = _mm256_set1_ps(R.P0y), P0z = _mm256_set1_ps(R.P0z);
  const __m256 Sx = _mm256_set1_ps(R.Sx), Sy = _mm256_set1_ps(R.Sy), Sz = _mm256_set1_ps(R.Sz);
  const __m256i mx = _mm256_set1_epi32(R.mx), my = _mm256_set1_epi32(R.my), mz = _mm256_set1_epi32(R.mz);
  const __m256 kv = _mm256_add_ps(_mm256_set1_ps(kf), _mm256_setr_ps(0.f, 1.f, 2.f, 3.f, 4.f, 5.f, 6.f, 7.f));
  const __m256 px = _mm256_add_ps(P0x, _mm256_mul_ps(kv, Sx));
  const __m256 py = _mm256_add_ps(P0y, _mm256_mul_ps(kv, Sy));
  const __m256 pz = _mm256_add_ps(P0z, _mm256_mul_ps(kv, Sz));
  const __m256i ix = _mm256_cvttps_epi32(px), iy = _mm256_cvttps_epi32(py), iz = _mm256_cvttps_epi32(pz);
  // Cells that need no clamping: 0 <= i <= n - 2 per axis, i.e. i <= n - 2 as unsigned.
  const __m256i inside = _mm256_and_si256(
      _mm256_and_si256(_mm256_cmpeq_epi32(_mm256_min_epu32(ix, mx), ix), _mm256_cmpeq_epi32(_mm256_min_epu32(iy, my), iy)),
      _mm256_cmpeq_epi32(_mm256_min_epu32(iz, mz), iz));
  // Level-0 brick of each cell (brick 0 where the cell needs clamping: read, then ignored).
  const __m256i bz = _mm256_srli_epi32(iz, LOG2DIM), by = _mm256_srli_epi32(iy, LOG2DIM), bx = _mm256_srli_epi32(ix, LOG2DIM);
  // bx + nb0 by + nb0 nb1 bz: the two products side by side, not nested (the index is on the
  // path to every gather).
  const __m256i b = _mm256_and_si256(
      inside, _mm256_add_epi32(_mm256_add_epi32(_mm256_mullo_epi32(bz, _mm256_set1_epi32(R.nb01)), bx),
                               _mm256_mullo_epi32(by, _mm256_set1_epi32(R.nb0))));
  const __m256i ptr = _mm256_i32gather_epi32(R.bricks, b, 4);
  // Visible-cell bit of each cell (clamped lanes read brick 0's, ignored): word 16 b + bit / 32
  // of the masks, issued without waiting for the brick pointers; shifted into the sign bit.
  const __m256i lx = _mm256_and_si256(ix, seven), ly = _mm256_and_si256(iy, seven), lz = _mm256_and_si256(iz, seven);
  const __m256i bit = _mm256_add_epi32(lx, _mm256_add_epi32(_mm256_slli_epi32(ly, 3), _mm256_slli_epi32(lz, 6)));
  const __m256i word = _mm256_i32gather_epi32(R.words, _mm256_add_epi32(_mm256_slli_epi32(b, 4), _mm256_srli_epi32(bit, 5)), 4);
  const __m256 vbit = _mm256_castsi256_ps(_mm256_sllv_epi32(word, _mm256_andnot_si256(bit, _mm256_set1_epi32(31))));
  // Lanes taken: no clamping, and a brick marched through.
  const __m256i take = _mm256_andnot_si256(_mm256_cmpeq_epi32(ptr, _mm256_set1_epi32(-1)), inside);
  unsigned go = unsigned(_mm256_movemask_ps(_mm256_castsi256_ps(take)));
  if (left < 7) go &= (2u << left) - 1u;  // lanes 0..left are samples of the ray
  const int n = __builtin_ctz(~go);       // leading lanes taken (go < 256: at most 8)
  out.n = n;
  out.vis = n == 0 ? 0u : unsigned(_mm256_movemask_ps(vbit)) & ((2u << (n - 1)) - 1u);
  if (!out.vis) return;
  const __m256 zero = _mm256_setzero_ps();
  const __m256 fx = _mm256_max_ps(_mm256_sub_ps(px, _mm256_cvtepi32_ps(ix)), zero);
  const __m256 fy = _mm256_max_ps(_mm256_sub_ps(py, _mm256_cvtepi32_ps(iy)), zero);
  const __m256 fz = _mm256_max_ps(_mm256_sub_ps(pz, _mm256_cvtepi32_ps(iz)), zero);
  // Entry of corner 0 (0 in the lanes without a brick), then the 8 corners.
  const __m256i off = _mm256_and_si256(take, cornerEntry(R.data, ptr, bit, ly, lz));
  __m256 c[8];  // corner dx + 2 dy + 4 dz
  gatherCorners(R.data, off, c);
  const __m256 c0 = c[0], c1 = c[1], c2 = c[2], c3 = c[3], c4 = c[4], c5 = c[5], c6 = c[6], c7 = c[7];
  const __m256 z0 = _mm256_add_ps(c0, _mm256_mul_ps(fz, _mm256_sub_ps(c4, c0)));
  const __m256 z1 = _mm256_add_ps(c1, _mm256_mul_ps(fz, _mm256_sub_ps(c5, c1)));
  const __m256 z2 = _mm256_add_ps(c2, _mm256_mul_ps(fz, _mm256_sub_ps(c6, c2)));
  const __m256 z3 = _mm256_add_ps(c3, _mm256_mul_ps(fz, _mm256_sub_ps(c7, c3)));
  const __m256 y0 = _mm256_add_ps(z0, _mm256_mul_ps(fy, _mm256_sub_ps(z2, z0)));
  const __m256 y1 = _mm256_add_ps(z1, _mm256_mul_ps(fy, _mm256_sub_ps(z3, z1)));
  const __m256 v = _mm256_add_ps(_mm256_add_ps(y0, _mm256_mul_ps(fx, _mm256_sub_ps(y1, y0))), _mm256_set1_ps(R.offset));
  // TransferTable::index: clamped into [0, last] as floats (NaN to 0: maxps returns its second
  // operand then), then truncated; a float past INT_MAX has no int.
  const __m256 x =
      _mm256_add_ps(_mm256_mul_ps(_mm256_sub_ps(v, _mm256_set1_ps(R.tlo)), _mm256_set1_ps(R.tscale)), _mm256_set1_ps(0.5f));
  const __m256i raw =
      _mm256_cvttps_epi32(_mm256_min_ps(_mm256_max_ps(x, _mm256_setzero_ps()), _mm256_set1_ps(float(R.tlast))));
  // Entry offsets into Frame::table8 (8 floats an entry); an invisible cell reads the all-zero
  // entry renderVolume appends to the table (1 - 0 = 1 in its second half): C + T * 0 = C and
  // T * 1 = T exactly, as when marchApron skips the cell.
  const __m256i e4 = _mm256_slli_epi32(raw, 3);
  const __m256 zeroEntry = _mm256_castsi256_ps(_mm256_set1_epi32(R.zeroEntry));
  out.idx = _mm256_castps_si256(_mm256_blendv_ps(zeroEntry, _mm256_castsi256_ps(e4), vbit));
}

/// One ray of the AVX2 marcher as a resumable state: start() sets it up, each step() does one
/// step of the walk or one chunk and returns false once the ray is done (its pixel written), so
/// that two rays can be marched in turns (marchApronAvx2Pair): the serial latency of one ray's
/// walk and compositing then overlaps the other ray's work.
template <typename T, bool Skip>
struct Avx2RayMarch {
  Avx2Ray<T> R;
  ApronRay ray;
  ApronFetch<T> fetch;
  __m128 C, T4;  // AccT's sums with the transmittance broadcast (the same float operations lane by lane)
  Avx2Chunk cur;
  const Frame* F;
  float* out;
  int64_t k, kEnd;
  uint64_t samples, skips;
  float kf, Tmin;
  bool chunk;  // in a run of chunks (cur is the next one to composite); else the walk is next

  explicit Avx2RayMarch(const ApronFetch<T>& f) : fetch(f) {}

  __attribute__((always_inline)) inline void start(const Frame& Fr, const double o[3], const double d[3],
                                                           double t0, int64_t kEnd_, float* out_) {
    F = &Fr;
    out = out_;
    kEnd = kEnd_;
    k = 0;
    samples = skips = 0;
    chunk = false;
    Tmin = 1.f - Fr.threshold;
    ray.set(Fr, o, d, t0);
    R.P0x = ray.P0s[0], R.P0y = ray.P0s[1], R.P0z = ray.P0s[2];
    R.Sx = ray.Ss[0], R.Sy = ray.Ss[1], R.Sz = ray.Ss[2];
    R.mx = Fr.n[0] - 2, R.my = Fr.n[1] - 2, R.mz = Fr.n[2] - 2;
    R.nb0 = Fr.nb[0], R.nb01 = Fr.nb[0] * Fr.nb[1];
    R.tlo = Fr.tlo, R.tscale = Fr.tscale, R.offset = Fr.offset;
    R.tlast = Fr.tlast;
    R.zeroEntry = 8 * (Fr.tlast + 1);
    R.bricks = reinterpret_cast<const int*>(Fr.runBricks);
    R.words = reinterpret_cast<const int*>(fetch.masks);
    R.data = fetch.data;
    C = _mm_setzero_ps();
    T4 = _mm_set1_ps(1.f);
  }

  /// The ray is done: its pixel and counts.
  __attribute__((always_inline)) inline bool finish(uint64_t& samplesOut, uint64_t& skipsOut) {
    _mm_storeu_ps(out, C);
    samplesOut += samples;
    skipsOut += skips;
    return false;
  }

  __attribute__((noinline)) bool step(uint64_t& samplesOut, uint64_t& skipsOut) {
    const Frame& Fr = *F;
    if (!chunk) {
      // The walk: to the first sample in a stored visible brick (or one that needs clamping).
      if (k > kEnd) return finish(samplesOut, skipsOut);
      int bo[3];
      if (!apronEnter<T, Skip>(Fr, ray, kEnd, fetch, k, skips, bo)) return true;
      kf = float(k);
      avx2Chunk(R, kf, kEnd - k, cur);
      if (cur.n == 0) {  // sample k needs clamping: the general path
        alignas(16) float p[4], c[4];
        _mm_store_ps(p, ray.at(float(k)));
        _mm_storeu_ps(c, C);
        float t = _mm_cvtss_f32(T4);
        const bool opaque = clampedSampleUnshaded(Fr, p, c, t, samples);
        C = _mm_loadu_ps(c);
        T4 = _mm_set1_ps(t);
        if (opaque) return finish(samplesOut, skipsOut);
        ++k;
        return true;
      }
      chunk = true;
    }
    // The run of chunks (in locals: registers): each one's successor is prepared first (nothing
    // in it depends on this one's compositing), so that its gathers' latency overlaps the serial
    // compositing.
    __m128 Cr = C, Tr = T4;
    int64_t kr = k;
    float kfr = kf;
    Avx2Chunk c = cur;
    const float* const table = Fr.table8;
    const float Tm = Tmin;
    const int64_t ke = kEnd;
    alignas(32) int32_t idx[8];
    for (;;) {
      const bool more = c.n == 8 && ke - kr >= 8;
      Avx2Chunk next{};  // (idx unset when vis is 0)
      if (more) avx2Chunk(R, kfr + 8.f, ke - kr - 8, next);
      if (c.vis) {
        _mm256_store_si256(reinterpret_cast<__m256i*>(idx), c.idx);
        const int n = c.n;
        // The lanes without a termination test: T never grows (each factor 1 - a is in [0, 1] and
        // rounding is monotone), so it fell to Tmin within the chunk iff it is there at its end;
        // only then is the chunk composited again from its start, lane by lane with the test.
        const __m128 C0 = Cr, T0 = Tr;
        const auto add = [&](int j) __attribute__((always_inline)) {
          const float* e = table + idx[j];  // colour and opacity, then 1 - opacity 4 times
          Cr = _mm_add_ps(Cr, _mm_mul_ps(Tr, _mm_load_ps(e)));
          Tr = _mm_mul_ps(Tr, _mm_load_ps(e + 4));
        };
        if (n == 8) {
          for (int j = 0; j < 8; ++j) add(j);
        } else {
          for (int j = 0; j < n; ++j) add(j);
        }
        if (_mm_cvtss_f32(Tr) <= Tm) {
          Cr = C0;
          Tr = T0;
          int j = 0;
          for (; j < n - 1; ++j) {
            add(j);
            if (_mm_cvtss_f32(Tr) <= Tm) break;
          }
          if (j == n - 1) add(j);  // (the last lane: where the end test found it)
          samples += __builtin_popcount(c.vis & ((2u << j) - 1u));
          C = Cr;
          return finish(samplesOut, skipsOut);
        }
        samples += __builtin_popcount(c.vis);
      }
      if (!more) {
        kr += c.n;
        break;
      }
      kr += 8;  // not k += n: the next chunk's positions need not wait for this one's gathers
      kfr += 8.f;
      c = next;
    }
    C = Cr;
    T4 = Tr;
    k = kr;
    chunk = false;
    return true;
  }
};

/// `count` rays, SLOTS at a time in turns (a finished ray's slot takes the next one): every
/// ray's steps are those of a ray marched alone, only their order across rays changes, so the
/// images and counts are the same. A step (one walk step, or one run of
/// chunks) is a call, so the rays' latency chains overlap across calls.
template <typename T, bool Skip, int SLOTS = 2>
void marchApronAvx2Pair(const Frame& F, const ApronFetch<T>& fetch, const PendingRay* rays, int count,
                                uint64_t& samplesOut, uint64_t& skipsOut) {
  Avx2RayMarch<T, Skip> m[SLOTS] = {Avx2RayMarch<T, Skip>(fetch), Avx2RayMarch<T, Skip>(fetch)};
  bool live[SLOTS];
  int next = 0, active = 0;
  for (int i = 0; i < SLOTS; ++i) {
    live[i] = next < count;
    if (live[i]) {
      m[i].start(F, rays[next].ro, rays[next].rd, rays[next].t0, rays[next].kEnd, rays[next].out);
      ++next;
      ++active;
    }
  }
  while (active) {
    for (int i = 0; i < SLOTS; ++i) {
      if (live[i] && !m[i].step(samplesOut, skipsOut)) {
        live[i] = next < count;
        if (live[i]) {
          m[i].start(F, rays[next].ro, rays[next].rd, rays[next].t0, rays[next].kEnd, rays[next].out);
          ++next;
        } else {
          --active;
        }
      }
    }
  }
}

}  // namespace

/// marchApron<T, Skip, false> for 8 consecutive samples at a time. The same walk (apronEnter,
/// apronClampedSample) finds the first sample in a stored visible brick; from there samples
/// k..k+7 get their positions (lane j: P0 + (kf + j) S, the same float operations as the SSE2
/// marcher), cells, bricks (F.runBricks), and visible-cell bits at once, across brick faces. The
/// leading lanes whose cell needs no clamping and whose brick is stored and visible, up to kEnd,
/// are taken; at the first other lane the walk takes over again, as the SSE2 marcher does when it
/// leaves a brick (its next brick lookup then lands in the same place, so it skips the same
/// nodes). A chunk whose taken cells are all invisible costs no corner reads; otherwise their
/// corners are gathered and interpolated (z, then y, then x, as marchApron), the table indices
/// computed, and the taken lanes composited one after the other, in order, an invisible cell's
/// lane with an all-zero entry (which changes nothing, exactly; it is not counted as a sample):
/// the image, the early-termination point and the sample and skip counts are marchApron's
/// exactly. Rays with more than 2^24 - 8 samples are not sent here (kf + j must be exact).
void marchApronAvx2(const Frame& F, const ApronBricks& bricks, ApronVoxel voxel, bool skip, const PendingRay* rays,
                    int count, uint64_t& samples, uint64_t& skips) {
  switch (voxel) {
    case ApronVoxel::Paired8:
      if (skip) marchApronAvx2Pair<Paired8, true>(F, ApronFetch<Paired8>(bricks), rays, count, samples, skips);
      else marchApronAvx2Pair<Paired8, false>(F, ApronFetch<Paired8>(bricks), rays, count, samples, skips);
      break;
    case ApronVoxel::UInt8:
      if (skip) marchApronAvx2Pair<uint8_t, true>(F, ApronFetch<uint8_t>(bricks), rays, count, samples, skips);
      else marchApronAvx2Pair<uint8_t, false>(F, ApronFetch<uint8_t>(bricks), rays, count, samples, skips);
      break;
    case ApronVoxel::UInt16:
      if (skip) marchApronAvx2Pair<uint16_t, true>(F, ApronFetch<uint16_t>(bricks), rays, count, samples, skips);
      else marchApronAvx2Pair<uint16_t, false>(F, ApronFetch<uint16_t>(bricks), rays, count, samples, skips);
      break;
  }
}

/// setupRay (render.cpp) for columns x..x+3 at once, in AVX2 doubles: the same operations in the same order
/// (additions, products, the square root and the divisions are correctly rounded in every lane;
/// nothing is fused), so every lane is setupRay's ray bit for bit. max/min keep std::max/min's
/// operand choice on ties (vmaxpd/vminpd return the second operand then), and an axis the ray
/// is parallel to sets no bound, as there.
void setupRays4(const RaySetupFrame& S, int x, PixelRay r[4]) {
  __m256d d[3];
  for (int a = 0; a < 3; ++a)
    d[a] = _mm256_add_pd(_mm256_add_pd(_mm256_set1_pd(S.fwd[a]), _mm256_loadu_pd(S.rightX[a] + x)),
                         _mm256_set1_pd(S.upY[a]));
  const __m256d n = _mm256_sqrt_pd(_mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(d[0], d[0]), _mm256_mul_pd(d[1], d[1])),
                                                 _mm256_mul_pd(d[2], d[2])));
  const __m256d inv = _mm256_div_pd(_mm256_set1_pd(1.0), n);
  const __m256d pos = _mm256_cmp_pd(n, _mm256_setzero_pd(), _CMP_GT_OQ);
  __m256d t0 = _mm256_setzero_pd(), t1 = _mm256_set1_pd(kInfinity);
  __m256d miss = _mm256_setzero_pd();
  const __m256d inf = _mm256_set1_pd(kInfinity);
  const __m256d ninf = _mm256_set1_pd(-kInfinity);
  alignas(32) double dd[3][4], rdd[3][4];
  for (int a = 0; a < 3; ++a) {
    d[a] = _mm256_blendv_pd(d[a], _mm256_mul_pd(d[a], inv), pos);
    const __m256d rd = _mm256_div_pd(d[a], _mm256_set1_pd(S.spacing[a]));
    _mm256_store_pd(dd[a], d[a]);
    _mm256_store_pd(rdd[a], rd);
    const __m256d zero = _mm256_cmp_pd(rd, _mm256_setzero_pd(), _CMP_EQ_OQ);
    if (S.roEye[a] < 0 || S.roEye[a] > S.hiIdx[a]) miss = _mm256_or_pd(miss, zero);
    const __m256d ta = _mm256_div_pd(_mm256_set1_pd(0 - S.roEye[a]), rd);
    const __m256d tb = _mm256_div_pd(_mm256_set1_pd(S.hiIdx[a] - S.roEye[a]), rd);
    const __m256d swap = _mm256_cmp_pd(ta, tb, _CMP_GT_OQ);
    const __m256d lo = _mm256_blendv_pd(_mm256_blendv_pd(ta, tb, swap), ninf, zero);
    const __m256d hi = _mm256_blendv_pd(_mm256_blendv_pd(tb, ta, swap), inf, zero);
    t0 = _mm256_max_pd(lo, t0);  // std::max(t0, lo): lo only when t0 < lo
    t1 = _mm256_min_pd(hi, t1);  // std::min(t1, hi): hi only when hi < t1
  }
  const int hit = _mm256_movemask_pd(_mm256_andnot_pd(miss, _mm256_cmp_pd(t0, t1, _CMP_LE_OQ)));
  alignas(32) double t0s[4], kx[4];
  _mm256_store_pd(t0s, t0);
  _mm256_store_pd(kx, _mm256_floor_pd(_mm256_div_pd(_mm256_sub_pd(t1, t0), _mm256_set1_pd(S.dt))));
  for (int l = 0; l < 4; ++l) {
    for (int a = 0; a < 3; ++a) {
      r[l].d[a] = dd[a][l];
      r[l].rd[a] = rdd[a][l];
    }
    r[l].t0 = t0s[l];
    r[l].hit = (hit >> l) & 1;
    r[l].kEnd = !r[l].hit ? 0 : kx[l] > 4e15 ? int64_t(4e15) : static_cast<int64_t>(kx[l]);
  }
}

}  // namespace volume_detail
}  // namespace mtree

#endif  // MATRIXTREE_VOLUME_AVX2

/* Volume ray marching through the block-sparse volume (engine/include/mtree/volume/volume.h): one
 * work-item per ray, the same arithmetic in the same order as renderVolume() (engine/src/volume/
 * render.cpp and march.h: ray set-up and positions in double, interpolation and compositing in
 * float, or in double for doublePrecision), so that the device image matches the CPU's:
 *   - trilinear interpolation of the 8 cell corners read through the pointer matrix and the
 *     DIM^3 blocks (a cell with an absent corner block is invisible: no sample);
 *   - post-classification through the premultiplied, step-corrected RGBA table the host built
 *     exactly as renderVolume does (nearest entry, clamped);
 *   - front-to-back compositing with early termination at `threshold`;
 *   - empty-space skipping over the matrix-tree levels above the bricks: the coarsest empty
 *     ancestor of the sample's brick is left at the last sample at or before its exit, so
 *     samples sit at t0 + k*dt with and without skipping (renderVolume's rule, bit for bit);
 *     the 8/16-bit float marchers leave instead the brick's empty cube for the ray's octant
 *     (BlockSparseVolume::brickDistances, uploaded as `dist`), as marchApron does;
 *   - optional gradient shading (headlight, two-sided), as renderVolume's Shade path.
 * Shading uses float division, sqrt and pow, whose OpenCL precision is a few ulp rather than
 * correctly rounded: shaded images agree with the CPU's to ~1e-6, unshaded ones bit for bit on
 * PoCL (no contraction into fma: common.clh switches FP_CONTRACT off).
 *
 * Every kernel's parameters are one MtVolumeParams (engine/include/mtree/core/layout.h), filled by
 * VolumeRenderer::render (engine/src/device/opencl_volume.cpp). */

#define VR_LOG2DIM 3
#define VR_DIM 8

/* clampCell: floor of q clamped into [0, n-2] and the fraction in [0, 1]. */
inline int vr_clamp_cell(double q, int n, double* f) {
  const double qc = mt_min(mt_max(q, -1.0), (double)n);
  int c = (int)qc;
  c -= (qc < (double)c) ? 1 : 0;
  c = min(max(c, 0), n - 2);
  *f = mt_min(1.0, mt_max(0.0, q - (double)c));
  return c;
}

/* TransferTable::index: nearest entry, clamped (NaN -> 0). */
inline int vr_index(float v, float flo, float fscale, int last) {
  const float x = (v - flo) * fscale + 0.5f;
  if (!(x > 0.f)) return 0;
  if (x >= (float)last) return last;
  const int i = (int)x;
  return i < last ? i : last;
}

/* The t where the index-space ray leaves the box [lo, hi]. */
inline double vr_exit_t(const double o[3], const double d[3], const double lo[3], const double hi[3]) {
  double t = (double)INFINITY;
  for (int a = 0; a < 3; ++a) {
    if (d[a] > 0) t = mt_min(t, (hi[a] - o[a]) / d[a]);
    else if (d[a] < 0) t = mt_min(t, (lo[a] - o[a]) / d[a]);
  }
  return t;
}

/* The 8 corners of cell (i, j, k), x fastest; 0 when a corner's block is absent. */
inline int vr_corners(__global const uint* ptr, __global const float* data, __global const MtVolumeParams* P, int i,
                      int j, int k, float c[8]) {
  const int lb0 = P->logBlock[0], lb1 = P->logBlock[1], lb2 = P->logBlock[2], pd0 = P->ptrDims[0], pd1 = P->ptrDims[1];
  const uint bv = P->blockVolume;
  const int m0 = (1 << lb0) - 1, m1 = (1 << lb1) - 1, m2 = (1 << lb2) - 1;
  const int bx0 = i >> lb0, by0 = j >> lb1, bz0 = k >> lb2;
  const int bx1 = (i + 1) >> lb0, by1 = (j + 1) >> lb1, bz1 = (k + 1) >> lb2;
  const int lx0 = i & m0, ly0 = j & m1, lz0 = k & m2;
  if (((bx0 ^ bx1) | (by0 ^ by1) | (bz0 ^ bz1)) == 0) {
    const uint b = ptr[((size_t)bz0 * pd1 + by0) * pd0 + bx0];
    if (b == MT_NULL) return 0;
    __global const float* p = data + (size_t)b * bv + ((lz0 << (lb0 + lb1)) | (ly0 << lb0) | lx0);
    const int sy = 1 << lb0, sz = 1 << (lb0 + lb1);
    c[0] = p[0]; c[1] = p[1]; c[2] = p[sy]; c[3] = p[sy + 1];
    c[4] = p[sz]; c[5] = p[sz + 1]; c[6] = p[sz + sy]; c[7] = p[sz + sy + 1];
    return 1;
  }
  const int bx[2] = {bx0, bx1}, by[2] = {by0, by1}, bz[2] = {bz0, bz1};
  const int lx[2] = {lx0, (i + 1) & m0}, ly[2] = {ly0 << lb0, ((j + 1) & m1) << lb0},
            lz[2] = {lz0 << (lb0 + lb1), ((k + 1) & m2) << (lb0 + lb1)};
  for (int n = 0; n < 8; ++n) {
    const int dx = n & 1, dy = (n >> 1) & 1, dz = n >> 2;
    const uint b = ptr[((size_t)bz[dz] * pd1 + by[dy]) * pd0 + bx[dx]];
    if (b == MT_NULL) return 0;
    c[n] = data[(size_t)b * bv + (uint)(lz[dz] | ly[dy] | lx[dx])];
  }
  return 1;
}

/* Level-L node (i, j, k) of the empty-space hierarchy holds a visible cell. */
inline int vr_visible(__global const uchar* occ, __global const MtVolumeParams* P, int L, int i, int j, int k) {
  __global const MtVolumeLevel* g = P->level + L;
  return occ[(size_t)g->occOffset + ((size_t)k * g->dims[1] + j) * g->dims[0] + i] != 0;
}

/* The index-space ray of pixel (x, y) of a w x h image and its [t0, t1] inside the grid;
 * 0 when it misses the grid. d_world: the world direction (the headlight). */
inline int vr_setup_ray(__global const MtVolumeParams* P, int x, int y, int w, int h, double o_i[3], double d_i[3],
                        double d_world[3], double* t0o, double* t1o) {
  const double nx = 2.0 * (x + 0.5) / w - 1.0, ny = 2.0 * (y + 0.5) / h - 1.0;
  double o[3], d[3];
  if (P->parallel) {
    const double sx = nx * P->parallelScale * P->aspect, sy = ny * P->parallelScale;
    for (int a = 0; a < 3; ++a) {
      o[a] = P->eye[a] + P->right[a] * sx + P->up[a] * sy;
      d[a] = P->forward[a];
    }
  } else {
    const double sx = nx * P->tanHalfAngle * P->aspect, sy = ny * P->tanHalfAngle;
    for (int a = 0; a < 3; ++a) {
      o[a] = P->eye[a];
      d[a] = P->forward[a] + P->right[a] * sx + P->up[a] * sy;
    }
    const double nn = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    if (nn > 0) {
      const double inv = 1.0 / nn;
      for (int a = 0; a < 3; ++a) d[a] = d[a] * inv;
    }
  }
  double t0 = 0, t1 = (double)INFINITY;
  int miss = 0;
  for (int a = 0; a < 3; ++a) {
    d_world[a] = d[a];
    const double hiIdx = (double)(P->dims[a] - 1);
    o_i[a] = (o[a] - P->origin[a]) / P->spacing[a];
    d_i[a] = d[a] / P->spacing[a];
    if (d_i[a] == 0) {
      if (o_i[a] < 0 || o_i[a] > hiIdx) miss = 1;
      continue;
    }
    double ta = (0 - o_i[a]) / d_i[a], tb = (hiIdx - o_i[a]) / d_i[a];
    if (ta > tb) {
      const double s = ta;
      ta = tb;
      tb = s;
    }
    t0 = mt_max(t0, ta);
    t1 = mt_min(t1, tb);
  }
  *t0o = t0;
  *t1o = t1;
  return !(miss || !(t0 <= t1));
}

/* The marchers' shared start: the work-item's pixel and ray (a missed ray writes zeros and returns),
 * the volume and table parameters, the last sample kEnd, the counters. */
#define VR_RAY_PROLOGUE                                                                                            \
    const int gid = (int)get_global_id(0);                                                                         \
    if (gid >= w * h) return;                                                                                      \
    const int x = gid % w, y = gid / w;                                                                            \
    double o[3], d[3], vd[3], t0, t1;                                                                              \
    __global float* res = out + 4 * (size_t)gid;                                                                   \
    if (!vr_setup_ray(P, x, y, w, h, o, d, vd, &t0, &t1)) {                                                        \
      VR_RAY_RESULT(0.f, 0.f, 0.f, 0.f, 0, 0);                                                                     \
      return;                                                                                                      \
    }                                                                                                              \
    const int n[3] = {P->dims[0], P->dims[1], P->dims[2]};                                                         \
    const int levels = P->levels, last = P->lastEntry, skip = P->skip, shade = P->shade;                           \
    const double dt = P->dt;                                                                                       \
    const float flo = P->tableLo, fscale = P->tableScale;                                                          \
    const double kxe = floor((t1 - t0) / dt);                                                                      \
    const long kEnd = kxe > 4e15 ? (long)4e15 : (long)kxe;                                                         \
    uint samples = 0, skips = 0

/* The ray's result: premultiplied RGBA, then its samples and skipped nodes. */
#define VR_RAY_RESULT(r, g, b, a, nSamples, nSkips)                                                                \
  do {                                                                                                             \
    res[0] = (float)(r);                                                                                           \
    res[1] = (float)(g);                                                                                           \
    res[2] = (float)(b);                                                                                           \
    res[3] = (float)(a);                                                                                           \
    counts[2 * (size_t)gid] = (nSamples);                                                                          \
    counts[2 * (size_t)gid + 1] = (nSkips);                                                                        \
  } while (0)

/* Front-to-back compositing of a sample (r, g, b, a) into (Cr, Cg, Cb, A) in R, as march()'s Acc;
 * at the threshold the ray is done: k passes kEnd and the sample loop is left. */
#define VR_COMPOSITE(R, r, g, b, a)                                                                                 \
  {                                                                                                                \
    const R wgt = 1 - A;                                                                                           \
    Cr += wgt * (r);                                                                                               \
    Cg += wgt * (g);                                                                                               \
    Cb += wgt * (b);                                                                                               \
    A += wgt * (a);                                                                                                \
    if (A >= thr) {                                                                                                \
      k = kEnd + 1;                                                                                                \
      break;                                                                                                       \
    }                                                                                                              \
  }

/* The shaded colour of a sample (renderVolume's shadeSample), in R. */
#define VR_SHADE(R, cc, fx, fy, fz, e, vd, P, r, g, b)                                                              \
  do {                                                                                                             \
    const R gx_ = (1 - (fy)) * (1 - (fz)) * ((cc)[1] - (cc)[0]) + (fy) * (1 - (fz)) * ((cc)[3] - (cc)[2]) +         \
                  (1 - (fy)) * (fz) * ((cc)[5] - (cc)[4]) + (fy) * (fz) * ((cc)[7] - (cc)[6]);                      \
    const R gy_ = (1 - (fx)) * (1 - (fz)) * ((cc)[2] - (cc)[0]) + (fx) * (1 - (fz)) * ((cc)[3] - (cc)[1]) +         \
                  (1 - (fx)) * (fz) * ((cc)[6] - (cc)[4]) + (fx) * (fz) * ((cc)[7] - (cc)[5]);                      \
    const R gz_ = (1 - (fx)) * (1 - (fy)) * ((cc)[4] - (cc)[0]) + (fx) * (1 - (fy)) * ((cc)[5] - (cc)[1]) +         \
                  (1 - (fx)) * (fy) * ((cc)[6] - (cc)[2]) + (fx) * (fy) * ((cc)[7] - (cc)[3]);                      \
    const R wx_ = gx_ / (R)(P)->spacing[0], wy_ = gy_ / (R)(P)->spacing[1], wz_ = gz_ / (R)(P)->spacing[2];         \
    const R len_ = sqrt(wx_ * wx_ + wy_ * wy_ + wz_ * wz_);                                                        \
    r = (e)[0];                                                                                                    \
    g = (e)[1];                                                                                                    \
    b = (e)[2];                                                                                                    \
    if (len_ > 0) {                                                                                                \
      const R ndl_ = fabs(wx_ * (R)(vd)[0] + wy_ * (R)(vd)[1] + wz_ * (R)(vd)[2]) / len_;                          \
      const R s_ = (R)(P)->ambient + (R)(P)->diffuse * ndl_;                                                       \
      const R spec_ = (R)(P)->specular * pow(ndl_, (R)(P)->specularPower) * (R)(e)[3];                             \
      r = r * s_ + spec_;                                                                                          \
      g = g * s_ + spec_;                                                                                          \
      b = b * s_ + spec_;                                                                                          \
    }                                                                                                              \
  } while (0)

/* The marcher, once per accumulation type R (float: renderVolume's default; double:
 * doublePrecision). out: premultiplied RGBA per ray; counts: samples and skips per ray. */
#define VR_DEFINE_MARCH(R, SFX)                                                                                      \
  __kernel void mt_volume_march_##SFX(__global const uint* ptr, __global const float* vdata,                       \
                                      __global const uchar* occ, __global const MtVolumeParams* P,                 \
                                      __global const float* table, __global float* out, __global uint* counts,     \
                                      int w, int h) {                                                              \
    VR_RAY_PROLOGUE;                                                                                               \
    R A = 0, Cr = 0, Cg = 0, Cb = 0;                                                                               \
    const R thr = (R)P->threshold;                                                                                 \
    long k = 0;                                                                                                    \
    while (k <= kEnd) {                                                                                            \
      long kStop = k;                                                                                              \
      if (skip) {                                                                                                  \
        const double t = t0 + (double)k * dt;                                                                      \
        double f;                                                                                                  \
        const int ci = vr_clamp_cell(o[0] + d[0] * t, n[0], &f);                                                   \
        const int cj = vr_clamp_cell(o[1] + d[1] * t, n[1], &f);                                                   \
        const int ck = vr_clamp_cell(o[2] + d[2] * t, n[2], &f);                                                   \
        const int bi = ci >> VR_LOG2DIM, bj = cj >> VR_LOG2DIM, bk = ck >> VR_LOG2DIM;                             \
        int empty = -1;                                                                                            \
        for (int L = levels - 1; L >= 0; --L)                                                                      \
          if (!vr_visible(occ, P, L, bi >> L, bj >> L, bk >> L)) {                                                 \
            empty = L;                                                                                             \
            break;                                                                                                 \
          }                                                                                                        \
        const int L = empty < 0 ? 0 : empty;                                                                       \
        const double edge = (double)(VR_DIM << L);                                                                 \
        const double lo[3] = {(double)(bi >> L) * edge, (double)(bj >> L) * edge, (double)(bk >> L) * edge};       \
        const double hi[3] = {lo[0] + edge, lo[1] + edge, lo[2] + edge};                                           \
        const double tx = vr_exit_t(o, d, lo, hi);                                                                 \
        const double kx = floor((tx - t0) / dt);                                                                   \
        const long kLast = kx >= (double)kEnd ? kEnd : max(k, (long)kx);                                           \
        if (empty >= 0) {                                                                                          \
          ++skips;                                                                                                 \
          k = max(k + 1, kLast);                                                                                   \
          continue;                                                                                                \
        }                                                                                                          \
        kStop = kLast;                                                                                             \
      }                                                                                                            \
      for (; k <= kStop; ++k) {                                                                                    \
        const double t = t0 + (double)k * dt;                                                                      \
        double fxd, fyd, fzd;                                                                                      \
        const int ci = vr_clamp_cell(o[0] + d[0] * t, n[0], &fxd);                                                 \
        const int cj = vr_clamp_cell(o[1] + d[1] * t, n[1], &fyd);                                                 \
        const int ck = vr_clamp_cell(o[2] + d[2] * t, n[2], &fzd);                                                 \
        float cc[8];                                                                                               \
        if (!vr_corners(ptr, vdata, P, ci, cj, ck, cc)) continue;                                                  \
        ++samples;                                                                                                 \
        const R fx = (R)fxd, fy = (R)fyd, fz = (R)fzd;                                                             \
        const R x00 = cc[0] + fx * (cc[1] - cc[0]), x10 = cc[2] + fx * (cc[3] - cc[2]);                            \
        const R x01 = cc[4] + fx * (cc[5] - cc[4]), x11 = cc[6] + fx * (cc[7] - cc[6]);                            \
        const R y0 = x00 + fy * (x10 - x00), y1 = x01 + fy * (x11 - x01);                                          \
        const R v = y0 + fz * (y1 - y0);                                                                           \
        __global const float* e = table + 4 * vr_index((float)v, flo, fscale, last);                              \
        const R a = e[3];                                                                                          \
        if (a <= 0) continue;                                                                                      \
        R r = e[0], g = e[1], b = e[2];                                                                            \
        if (shade) VR_SHADE(R, cc, fx, fy, fz, e, vd, P, r, g, b);                                                 \
        VR_COMPOSITE(R, r, g, b, a);                                                                               \
      }                                                                                                            \
    }                                                                                                              \
    VR_RAY_RESULT(Cr, Cg, Cb, A, samples, skips);                                                                  \
  }

VR_DEFINE_MARCH(float, f)
VR_DEFINE_MARCH(double, d)

/* ------------------------------------------------------------------------------------------------
 * UInt8/UInt16 storage: bricks of DIM^3 cells held as APRON^3 = 9^3 voxels in the input's width
 * (a 1-voxel apron towards +x/+y/+z, so a cell's 8 corners are in its brick), brick pointers in
 * level-0 order (MT_NULL = absent), one 64-bit visible-cell mask per brick z layer, and an offset
 * added to a stored value (signed input). The two marchers below follow the CPU's two marchers
 * for this storage step for step (engine/src/volume/march.h), so each gives the CPU's image:
 *   float accumulation  marchApron(): positions P0 + k S in float, interpolation z, then y, then x,
 *                       the offset added after it, transmittance compositing (C += T e,
 *                       T *= 1 - a), termination at T <= 1 - threshold;
 *   double accumulation march() with the apron fetch: positions in double, brick by brick.
 * Both leave an invisible cell (mask bit clear) unsampled, as the CPU does, so the sample counts
 * agree too. The level-0 bricks along x and y are the first level's dims; the storage offset is
 * MtVolumeParams::offset. */

#define VR_SY 9
#define VR_SZ 81
#define VR_BRICK 729
/* 8-bit bricks of grids of at most 4096 level-0 bricks are held in rows of y pairs
 * (BlockSparseVolume::pairedRows, BRICK_BYTES8): byte 2 x + dy of row (y, z) at 18 y + 144 z
 * holds voxel (x, y + dy, z), so the 4 corners of a cell in a z plane are 4 consecutive bytes. The
 * rule depends on the dimensions only: VR_PAIRED(T, n, nb0, nb1) derives it as the host did. */
#define VR_PSY 18
#define VR_PSZ 144
#define VR_PBRICK 1296
#define VR_PAIRED_MAX_BRICKS 4096
#define VR_PAIRED(T, n, nb0, nb1)                                                                                   \
  (sizeof(T) == 1 && (long)(nb0) * (nb1) * (((n)[2] - 1 + VR_DIM - 1) >> VR_LOG2DIM) <= VR_PAIRED_MAX_BRICKS)

/* x86's truncating conversions (cvttss2si/cvttsd2si), which the CPU marchers use: the integer
 * part, or INT_MIN when it does not fit (and for NaN). OpenCL's (int) leaves that undefined. */
inline int vr_trunc_f(float x) {
  return (x > -2147483649.0f && x < 2147483648.0f) ? (int)x : (int)0x80000000;
}
inline int vr_trunc_d(double x) {
  return (x > -2147483649.0 && x < 2147483648.0) ? (int)x : (int)0x80000000;
}

/* The storage-typed helpers, once per voxel type T. */
#define VR_DEFINE_APRON_HELPERS(T, SFX)                                                                             \
  /* Entry of corner n (x fastest) of the cell whose corner 0 is at entry 0 (9^3 or paired rows). */               \
  inline int vr_corner_##SFX(int n, int paired) {                                                                  \
    return paired ? 2 * (n & 1) + ((n >> 1) & 1) + VR_PSZ * (n >> 2)                                                \
                  : (n & 1) + VR_SY * ((n >> 1) & 1) + VR_SZ * (n >> 2);                                            \
  }                                                                                                                \
  /* Entry of corner 0 of local cell (lx, ly, lz) of a brick. */                                                   \
  inline int vr_local_##SFX(int lx, int ly, int lz, int paired) {                                                  \
    return paired ? 2 * lx + VR_PSY * ly + VR_PSZ * lz : lx + VR_SY * ly + VR_SZ * lz;                             \
  }                                                                                                                \
  /* BlockSparseVolume::cellCorners: the stored corners plus the offset (float), 0 if absent. */                   \
  inline int vr_apron_cell_##SFX(__global const uint* bptr, __global const T* bricks, int nb0, int nb1,           \
                                 float offset, int i, int j, int k, float c[8], int paired) {                      \
    const uint b = bptr[((size_t)(k >> VR_LOG2DIM) * nb1 + (j >> VR_LOG2DIM)) * nb0 + (i >> VR_LOG2DIM)];          \
    if (b == MT_NULL) return 0;                                                                                    \
    __global const T* p = bricks + (size_t)b * (paired ? VR_PBRICK : VR_BRICK) +                                  \
                          vr_local_##SFX(i & (VR_DIM - 1), j & (VR_DIM - 1), k & (VR_DIM - 1), paired);            \
    for (int n = 0; n < 8; ++n)                                                                                    \
      c[n] = (float)p[vr_corner_##SFX(n, paired)] + offset;                                                        \
    return 1;                                                                                                      \
  }                                                                                                                \
  /* The stored corners (no offset) of local cell (lx, ly, lz) of the brick at `base`. */                          \
  inline void vr_apron_local_##SFX(__global const T* base, int lx, int ly, int lz, float c[8], int paired) {        \
    __global const T* p = base + vr_local_##SFX(lx, ly, lz, paired);                                               \
    for (int n = 0; n < 8; ++n)                                                                                    \
      c[n] = (float)p[vr_corner_##SFX(n, paired)];                                                                 \
  }

VR_DEFINE_APRON_HELPERS(uchar, u8)
VR_DEFINE_APRON_HELPERS(ushort, u16)

/* The coarsest empty ancestor of brick (bi, bj, bk), -1 when the brick is visible (levels are ORs
 * of their children: climb while empty, as the CPU does). */
inline int vr_empty_level(__global const uchar* occ, __global const MtVolumeParams* P, int levels, int bi, int bj,
                          int bk) {
  if (vr_visible(occ, P, 0, bi, bj, bk)) return -1;
  int e = 0;
  while (e + 1 < levels && !vr_visible(occ, P, e + 1, bi >> (e + 1), bj >> (e + 1), bk >> (e + 1))) ++e;
  return e;
}

/* Table entry of value v: TransferTable::index as the CPU's apron marcher computes it (truncation,
 * then clamped into [0, last]). */
inline int vr_apron_index(float v, float flo, float fscale, int last) {
  return min(max(vr_trunc_f((v - flo) * fscale + 0.5f), 0), last);
}

/* The apron marchers' start, after VR_RAY_PROLOGUE: the level-0 bricks along x and y, the brick
 * layout (VR_PAIRED) and the storage offset. */
#define VR_APRON_PROLOGUE(T)                                                                                        \
    const int nb0 = P->level[0].dims[0], nb1 = P->level[0].dims[1];                                                \
    const int paired = VR_PAIRED(T, n, nb0, nb1);                                                                  \
    const float offset = P->offset

/* An apron marcher's signature: the bricks of voxel type T, their cell masks, the brick table it
 * walks by (LEVELS: the empty cubes `dist` or the occupancy levels `occ`), the parameters, the
 * transfer table and the outputs. */
#define VR_APRON_KERNEL(T, NAME, LEVELS)                                                                            \
  __kernel void NAME(__global const uint* bptr, __global const T* bricks, __global const ulong* masks,             \
                     __global const uchar* LEVELS, __global const MtVolumeParams* P, __global const float* table,  \
                     __global float* out, __global uint* counts, int w, int h)

/* The float marcher (marchApron): one work-item per ray. */
#define VR_DEFINE_APRON_MARCH_F(T, SFX)                                                                             \
  VR_APRON_KERNEL(T, mt_volume_apron_##SFX##_f, dist) {                                                            \
    VR_RAY_PROLOGUE;                                                                                               \
    VR_APRON_PROLOGUE(T);                                                                                          \
    const float Tmin = 1.f - (float)P->threshold;                                                                  \
    const float P0[3] = {(float)(o[0] + d[0] * t0), (float)(o[1] + d[1] * t0), (float)(o[2] + d[2] * t0)};         \
    const float S[3] = {(float)(d[0] * dt), (float)(d[1] * dt), (float)(d[2] * dt)};                               \
    const int octant = (S[0] < 0.f ? 1 : 0) | (S[1] < 0.f ? 2 : 0) | (S[2] < 0.f ? 4 : 0);                         \
    float Cr = 0.f, Cg = 0.f, Cb = 0.f, Ca = 0.f, Tr = 1.f;                                                        \
    long k = 0;                                                                                                    \
    while (k <= kEnd) {                                                                                            \
      const float kf0 = (float)k;                                                                                  \
      int cell[3];                                                                                                 \
      for (int a = 0; a < 3; ++a) {                                                                                \
        double f;                                                                                                  \
        cell[a] = vr_clamp_cell((double)(P0[a] + kf0 * S[a]), n[a], &f);                                           \
      }                                                                                                            \
      const int bi = cell[0] >> VR_LOG2DIM, bj = cell[1] >> VR_LOG2DIM, bk = cell[2] >> VR_LOG2DIM;                \
      const size_t bidx = ((size_t)bk * nb1 + bj) * nb0 + bi;                                                      \
      /* The cube of r^3 invisible bricks from this one towards the ray's octant (the host's      \
       * BlockSparseVolume::brickDistances; r = 1: the brick alone, e.g. an absent one). */      \
      int r = skip ? (int)dist[bidx * 8 + octant] : 0;                                                             \
      const uint bp = r == 0 ? bptr[bidx] : MT_NULL;                                                               \
      if (r == 0 && bp == MT_NULL) r = 1;                                                                          \
      if (r > 0) {                                                                                                 \
        /* Leave the cube at the last sample at or before its exit. */                                             \
        const int node[3] = {bi, bj, bk};                                                                          \
        double kx = (double)INFINITY;                                                                              \
        for (int a = 0; a < 3; ++a) {                                                                              \
          const double s = (double)S[a];                                                                           \
          if (s > 0) kx = mt_min(kx, ((double)((node[a] + r) * VR_DIM) - (double)P0[a]) / s);                      \
          else if (s < 0) kx = mt_min(kx, ((double)((node[a] - r + 1) * VR_DIM) - (double)P0[a]) / s);             \
        }                                                                                                          \
        const double kfl = floor(kx);                                                                              \
        const long kLast = kfl >= (double)kEnd ? kEnd : (kfl <= (double)k ? k : (long)kfl);                        \
        if (skip) ++skips;                                                                                         \
        if (kLast > k) {                                                                                           \
          /* Sample kLast still in the cube (its brick at most r - 1 ahead per axis): skipped too. */              \
          const float kfl1 = (float)kLast;                                                                         \
          int in = 1;                                                                                              \
          for (int a = 0; a < 3; ++a) {                                                                            \
            double f;                                                                                              \
            const int ahead = ((vr_clamp_cell((double)(P0[a] + kfl1 * S[a]), n[a], &f) >> VR_LOG2DIM) - node[a]) * \
                              (S[a] < 0.f ? -1 : 1);                                                               \
            in &= ahead <= r - 1;                                                                                  \
          }                                                                                                        \
          if (in) {                                                                                                \
            if (skip) ++skips;                                                                                     \
            k = kLast + 1;                                                                                         \
            continue;                                                                                              \
          }                                                                                                        \
        }                                                                                                          \
        k = max(k + 1, kLast);                                                                                     \
        continue;                                                                                                  \
      }                                                                                                            \
      __global const T* base = bricks + (size_t)bp * (paired ? VR_PBRICK : VR_BRICK);                                  \
      __global const ulong* mask = masks + bidx * VR_DIM;                                                          \
      const int org[3] = {bi << VR_LOG2DIM, bj << VR_LOG2DIM, bk << VR_LOG2DIM};                                   \
      const int lim[3] = {min(VR_DIM - 1, n[0] - 2 - org[0]), min(VR_DIM - 1, n[1] - 2 - org[1]),                  \
                          min(VR_DIM - 1, n[2] - 2 - org[2])};                                                     \
      const long kStart = k;                                                                                       \
      int done = 0;                                                                                                \
      float kf = (float)k;                                                                                         \
      for (; k <= kEnd; ++k, kf += 1.f) {                                                                          \
        float pos[3], fr[3];                                                                                       \
        int l[3], outside = 0;                                                                                     \
        for (int a = 0; a < 3; ++a) {                                                                              \
          pos[a] = P0[a] + kf * S[a];                                                                              \
          const int t = vr_trunc_f(pos[a]);                                                                        \
          l[a] = (int)((uint)t - (uint)org[a]);                                                                    \
          outside |= (l[a] > lim[a]) | (l[a] < 0);                                                                 \
          const float fa = pos[a] - (float)t;                                                                      \
          fr[a] = fa > 0.f ? fa : 0.f;                                                                             \
        }                                                                                                          \
        if (outside) break; /* left the brick (or needs clamping) */                                               \
        if (!((mask[l[2]] >> (l[0] + VR_DIM * l[1])) & 1)) continue; /* invisible cell: adds exactly 0 */          \
        float cc[8];                                                                                               \
        vr_apron_local_##SFX(base, l[0], l[1], l[2], cc, paired);                                                      \
        const float fx = fr[0], fy = fr[1], fz = fr[2];                                                            \
        const float z0 = cc[0] + fz * (cc[4] - cc[0]), z1 = cc[1] + fz * (cc[5] - cc[1]);                          \
        const float z2 = cc[2] + fz * (cc[6] - cc[2]), z3 = cc[3] + fz * (cc[7] - cc[3]);                          \
        const float y0 = z0 + fy * (z2 - z0), y1 = z1 + fy * (z3 - z1);                                            \
        const float v = (y0 + fx * (y1 - y0)) + offset;                                                            \
        ++samples;                                                                                                 \
        __global const float* e = table + 4 * vr_apron_index(v, flo, fscale, last);                                \
        float r = e[0], g = e[1], b = e[2];                                                                        \
        const float a = e[3];                                                                                      \
        if (shade) {                                                                                               \
          if (!(a > 0.f)) continue;                                                                                \
          VR_SHADE(float, cc, fx, fy, fz, e, vd, P, r, g, b);                                                      \
        }                                                                                                          \
        Cr = Cr + Tr * r;                                                                                          \
        Cg = Cg + Tr * g;                                                                                          \
        Cb = Cb + Tr * b;                                                                                          \
        Ca = Ca + Tr * a;                                                                                          \
        Tr *= 1.f - a;                                                                                             \
        if (Tr <= Tmin) {                                                                                          \
          done = 1;                                                                                                \
          break;                                                                                                   \
        }                                                                                                          \
      }                                                                                                            \
      if (done) break;                                                                                             \
      if (k == kStart) {                                                                                           \
        /* The sample needs clamping (the grid's far face, or outside by round-off). */                            \
        const float kf1 = (float)k;                                                                                \
        double f[3];                                                                                               \
        int c[3];                                                                                                  \
        for (int a = 0; a < 3; ++a) c[a] = vr_clamp_cell((double)(P0[a] + kf1 * S[a]), n[a], &f[a]);              \
        float cc[8];                                                                                               \
        if (vr_apron_cell_##SFX(bptr, bricks, nb0, nb1, offset, c[0], c[1], c[2], cc, paired)) {                       \
          ++samples;                                                                                               \
          const float fx = (float)f[0], fy = (float)f[1], fz = (float)f[2];                                        \
          const float x00 = cc[0] + fx * (cc[1] - cc[0]), x10 = cc[2] + fx * (cc[3] - cc[2]);                      \
          const float x01 = cc[4] + fx * (cc[5] - cc[4]), x11 = cc[6] + fx * (cc[7] - cc[6]);                      \
          const float y0 = x00 + fy * (x10 - x00), y1 = x01 + fy * (x11 - x01);                                    \
          const float v = y0 + fz * (y1 - y0);                                                                     \
          __global const float* e = table + 4 * vr_apron_index(v, flo, fscale, last);                              \
          float r = e[0], g = e[1], b = e[2];                                                                      \
          const float a = e[3];                                                                                    \
          if (!shade || a > 0.f) {                                                                                 \
            if (shade) VR_SHADE(float, cc, fx, fy, fz, e, vd, P, r, g, b);                                         \
            Cr = Cr + Tr * r;                                                                                      \
            Cg = Cg + Tr * g;                                                                                      \
            Cb = Cb + Tr * b;                                                                                      \
            Ca = Ca + Tr * a;                                                                                      \
            Tr *= 1.f - a;                                                                                         \
          }                                                                                                        \
          if (Tr <= Tmin) break;                                                                                   \
        }                                                                                                          \
        ++k;                                                                                                       \
      }                                                                                                            \
    }                                                                                                              \
    VR_RAY_RESULT(Cr, Cg, Cb, Ca, samples, skips);                                                                 \
  }

/* The double marcher (march() with the apron fetch): positions in double, brick by brick. */
#define VR_DEFINE_APRON_MARCH_D(T, SFX)                                                                             \
  VR_APRON_KERNEL(T, mt_volume_apron_##SFX##_d, occ) {                                                             \
    VR_RAY_PROLOGUE;                                                                                               \
    VR_APRON_PROLOGUE(T);                                                                                          \
    const double thr = (double)(float)P->threshold;                                                                \
    double A = 0, Cr = 0, Cg = 0, Cb = 0;                                                                          \
    long k = 0;                                                                                                    \
    while (k <= kEnd) {                                                                                            \
      const double t = t0 + (double)k * dt;                                                                        \
      double f;                                                                                                    \
      const int bi = vr_clamp_cell(o[0] + d[0] * t, n[0], &f) >> VR_LOG2DIM;                                       \
      const int bj = vr_clamp_cell(o[1] + d[1] * t, n[1], &f) >> VR_LOG2DIM;                                       \
      const int bk = vr_clamp_cell(o[2] + d[2] * t, n[2], &f) >> VR_LOG2DIM;                                       \
      const int empty = skip ? vr_empty_level(occ, P, levels, bi, bj, bk) : -1;                                    \
      const int L = empty < 0 ? 0 : empty;                                                                         \
      const double edge = (double)(VR_DIM << L);                                                                   \
      const double lo[3] = {(double)(bi >> L) * edge, (double)(bj >> L) * edge, (double)(bk >> L) * edge};         \
      const double hi[3] = {lo[0] + edge, lo[1] + edge, lo[2] + edge};                                             \
      const double kx = floor((vr_exit_t(o, d, lo, hi) - t0) / dt);                                                \
      const long kLast = kx >= (double)kEnd ? kEnd : (kx <= (double)k ? k : (long)kx);                             \
      if (empty >= 0) {                                                                                            \
        ++skips;                                                                                                   \
        k = max(k + 1, kLast);                                                                                     \
        continue;                                                                                                  \
      }                                                                                                            \
      const size_t bidx = ((size_t)bk * nb1 + bj) * nb0 + bi;                                                      \
      const uint bp = bptr[bidx];                                                                                  \
      if (bp == MT_NULL) { /* an absent brick (not skipping): every cell is invisible */                           \
        k = kLast + 1;                                                                                             \
        continue;                                                                                                  \
      }                                                                                                            \
      __global const T* base = bricks + (size_t)bp * (paired ? VR_PBRICK : VR_BRICK);                                  \
      __global const ulong* mask = masks + bidx * VR_DIM;                                                          \
      const int ox = bi << VR_LOG2DIM, oy = bj << VR_LOG2DIM, oz = bk << VR_LOG2DIM;                               \
      const uint mx = (uint)min(VR_DIM - 1, n[0] - 2 - ox), my = (uint)min(VR_DIM - 1, n[1] - 2 - oy),             \
                 mz = (uint)min(VR_DIM - 1, n[2] - 2 - oz);                                                        \
      double kd = (double)k;                                                                                       \
      for (; k <= kLast; ++k, kd += 1.0) {                                                                         \
        const double ts = t0 + kd * dt;                                                                            \
        const double px = o[0] + d[0] * ts, py = o[1] + d[1] * ts, pz = o[2] + d[2] * ts;                          \
        const int ix = vr_trunc_d(px), iy = vr_trunc_d(py), iz = vr_trunc_d(pz);                                   \
        const int lx = (int)((uint)ix - (uint)ox), ly = (int)((uint)iy - (uint)oy), lz = (int)((uint)iz - (uint)oz); \
        float cc[8];                                                                                               \
        double fx, fy, fz, off;                                                                                    \
        if ((((uint)lx > mx) | ((uint)ly > my) | ((uint)lz > mz)) == 0) {                                          \
          fx = mt_max(px - (double)ix, 0.0);                                                                       \
          fy = mt_max(py - (double)iy, 0.0);                                                                       \
          fz = mt_max(pz - (double)iz, 0.0);                                                                       \
          if (!((mask[lz] >> (lx + VR_DIM * ly)) & 1)) continue;                                                   \
          vr_apron_local_##SFX(base, lx, ly, lz, cc, paired);                                                          \
          off = (double)offset;                                                                                    \
        } else {                                                                                                   \
          double g[3];                                                                                             \
          const int ci = vr_clamp_cell(px, n[0], &g[0]), cj = vr_clamp_cell(py, n[1], &g[1]),                      \
                    ck = vr_clamp_cell(pz, n[2], &g[2]);                                                           \
          if (!vr_apron_cell_##SFX(bptr, bricks, nb0, nb1, offset, ci, cj, ck, cc, paired)) continue;                  \
          fx = g[0];                                                                                               \
          fy = g[1];                                                                                               \
          fz = g[2];                                                                                               \
          off = 0.0;                                                                                               \
        }                                                                                                          \
        ++samples;                                                                                                 \
        const double x00 = cc[0] + fx * (cc[1] - cc[0]), x10 = cc[2] + fx * (cc[3] - cc[2]);                      \
        const double x01 = cc[4] + fx * (cc[5] - cc[4]), x11 = cc[6] + fx * (cc[7] - cc[6]);                       \
        const double y0 = x00 + fy * (x10 - x00), y1 = x01 + fy * (x11 - x01);                                     \
        const float v = (float)((y0 + fz * (y1 - y0)) + off);                                                      \
        __global const float* e = table + 4 * vr_index(v, flo, fscale, last);                                      \
        const double a = e[3];                                                                                     \
        double r = e[0], g = e[1], b = e[2];                                                                       \
        if (shade) {                                                                                               \
          if (!(e[3] > 0.f)) continue;                                                                             \
          VR_SHADE(double, cc, fx, fy, fz, e, vd, P, r, g, b);                                                     \
        }                                                                                                          \
        VR_COMPOSITE(double, r, g, b, a);                                                                          \
      }                                                                                                            \
      k = max(k, kLast + 1);                                                                                       \
    }                                                                                                              \
    VR_RAY_RESULT(Cr, Cg, Cb, A, samples, skips);                                                                  \
  }

VR_DEFINE_APRON_MARCH_F(uchar, u8)
VR_DEFINE_APRON_MARCH_F(ushort, u16)
VR_DEFINE_APRON_MARCH_D(uchar, u8)
VR_DEFINE_APRON_MARCH_D(ushort, u16)

/* Volume ray marching through the block-sparse volume (engine/include/mtree/volume.h): one
 * work-item per ray, the same arithmetic in the same order as renderVolume() in
 * engine/src/volume.cpp (ray set-up and positions in double, interpolation and compositing in
 * float, or in double for doublePrecision), so that the device image matches the CPU's:
 *   - trilinear interpolation of the 8 cell corners read through the pointer matrix and the
 *     DIM^3 blocks (a cell with an absent corner block is invisible: no sample);
 *   - post-classification through the premultiplied, step-corrected RGBA table the host built
 *     exactly as renderVolume does (nearest entry, clamped);
 *   - front-to-back compositing with early termination at `threshold`;
 *   - empty-space skipping over the matrix-tree levels above the bricks: the coarsest empty
 *     ancestor of the sample's brick is left at the last sample at or before its exit, so
 *     samples sit at t0 + k*dt with and without skipping (renderVolume's rule, bit for bit);
 *   - optional gradient shading (headlight, two-sided), as renderVolume's Shade path.
 * Shading uses float division, sqrt and pow, whose OpenCL precision is a few ulp rather than
 * correctly rounded: shaded images agree with the CPU's to ~1e-6, unshaded ones bit for bit on
 * PoCL (no contraction into fma: common.clh switches FP_CONTRACT off).
 *
 * Integer parameters ip[]: 0-2 grid points per axis, 3-5 log2 block edge per axis, 6-7 pointer
 * matrix dims x/y, 8 block volume, 9 level count, 10 last table entry, 11 skip, 12 shade,
 * 13 parallel projection, then per level l: 14+4l.. = dims x/y/z and offset into occ[].
 * Double parameters dp[]: 0-2 eye, 3-5 forward, 6-8 right, 9-11 up, 12 tan(angle/2), 13 aspect,
 * 14 parallel scale, 15-17 origin, 18-20 spacing, 21 dt, 22 threshold, 23 ambient, 24 diffuse,
 * 25 specular, 26 specular power, 27 table lo (as float), 28 table scale (as float). */

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
inline int vr_corners(__global const uint* ptr, __global const float* data, __global const int* ip, int i, int j,
                      int k, float c[8]) {
  const int lb0 = ip[3], lb1 = ip[4], lb2 = ip[5], pd0 = ip[6], pd1 = ip[7];
  const uint bv = (uint)ip[8];
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
inline int vr_visible(__global const uchar* occ, __global const int* ip, int L, int i, int j, int k) {
  __global const int* g = ip + 14 + 4 * L;
  return occ[(size_t)g[3] + ((size_t)k * g[1] + j) * g[0] + i] != 0;
}

/* The index-space ray of pixel (x, y) of a w x h image and its [t0, t1] inside the grid;
 * 0 when it misses the grid. d_world: the world direction (the headlight). */
inline int vr_setup_ray(__global const int* ip, __global const double* dp, int x, int y, int w, int h, double o_i[3],
                        double d_i[3], double d_world[3], double* t0o, double* t1o) {
  const double nx = 2.0 * (x + 0.5) / w - 1.0, ny = 2.0 * (y + 0.5) / h - 1.0;
  double o[3], d[3];
  if (ip[13]) {
    const double sx = nx * dp[14] * dp[13], sy = ny * dp[14];
    for (int a = 0; a < 3; ++a) {
      o[a] = dp[a] + dp[6 + a] * sx + dp[9 + a] * sy;
      d[a] = dp[3 + a];
    }
  } else {
    const double sx = nx * dp[12] * dp[13], sy = ny * dp[12];
    for (int a = 0; a < 3; ++a) {
      o[a] = dp[a];
      d[a] = dp[3 + a] + dp[6 + a] * sx + dp[9 + a] * sy;
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
    const double hiIdx = (double)(ip[a] - 1);
    o_i[a] = (o[a] - dp[15 + a]) / dp[18 + a];
    d_i[a] = d[a] / dp[18 + a];
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

/* The marcher, once per accumulation type R (float: renderVolume's default; double:
 * doublePrecision). out: premultiplied RGBA per ray; counts: samples and skips per ray. */
#define VR_DEFINE_MARCH(R, SFX)                                                                                      \
  __kernel void mt_volume_march_##SFX(__global const uint* ptr, __global const float* vdata,                       \
                                      __global const uchar* occ, __global const int* ip, __global const double* dp, \
                                      __global const float* table, __global float* out, __global uint* counts,     \
                                      int w, int h) {                                                              \
    const int gid = (int)get_global_id(0);                                                                         \
    if (gid >= w * h) return;                                                                                      \
    const int x = gid % w, y = gid / w;                                                                            \
    double o[3], d[3], vd[3], t0, t1;                                                                              \
    __global float* res = out + 4 * (size_t)gid;                                                                   \
    if (!vr_setup_ray(ip, dp, x, y, w, h, o, d, vd, &t0, &t1)) {                                                   \
      res[0] = res[1] = res[2] = res[3] = 0.f;                                                                     \
      counts[2 * (size_t)gid] = 0;                                                                                 \
      counts[2 * (size_t)gid + 1] = 0;                                                                             \
      return;                                                                                                      \
    }                                                                                                              \
    const int n[3] = {ip[0], ip[1], ip[2]};                                                                        \
    const int levels = ip[9], last = ip[10], skip = ip[11], shade = ip[12];                                        \
    const double dt = dp[21];                                                                                      \
    const float flo = (float)dp[27], fscale = (float)dp[28];                                                       \
    const double kxe = floor((t1 - t0) / dt);                                                                      \
    const long kEnd = kxe > 4e15 ? (long)4e15 : (long)kxe;                                                         \
    uint samples = 0, skips = 0;                                                                                   \
    R A = 0, Cr = 0, Cg = 0, Cb = 0;                                                                               \
    const R thr = (R)dp[22];                                                                                       \
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
          if (!vr_visible(occ, ip, L, bi >> L, bj >> L, bk >> L)) {                                                \
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
        if (!vr_corners(ptr, vdata, ip, ci, cj, ck, cc)) continue;                                                 \
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
        if (shade) {                                                                                               \
          const R gx = (1 - fy) * (1 - fz) * (cc[1] - cc[0]) + fy * (1 - fz) * (cc[3] - cc[2]) +                   \
                       (1 - fy) * fz * (cc[5] - cc[4]) + fy * fz * (cc[7] - cc[6]);                                \
          const R gy = (1 - fx) * (1 - fz) * (cc[2] - cc[0]) + fx * (1 - fz) * (cc[3] - cc[1]) +                   \
                       (1 - fx) * fz * (cc[6] - cc[4]) + fx * fz * (cc[7] - cc[5]);                                \
          const R gz = (1 - fx) * (1 - fy) * (cc[4] - cc[0]) + fx * (1 - fy) * (cc[5] - cc[1]) +                   \
                       (1 - fx) * fy * (cc[6] - cc[2]) + fx * fy * (cc[7] - cc[3]);                                \
          const R wx = gx / (R)dp[18], wy = gy / (R)dp[19], wz = gz / (R)dp[20];                                   \
          const R len = sqrt(wx * wx + wy * wy + wz * wz);                                                         \
          if (len > 0) {                                                                                           \
            const R ndl = fabs(wx * (R)vd[0] + wy * (R)vd[1] + wz * (R)vd[2]) / len;                               \
            const R s = (R)dp[23] + (R)dp[24] * ndl;                                                               \
            const R spec = (R)dp[25] * pow(ndl, (R)dp[26]) * a;                                                    \
            r = r * s + spec;                                                                                      \
            g = g * s + spec;                                                                                      \
            b = b * s + spec;                                                                                      \
          }                                                                                                        \
        }                                                                                                          \
        const R wgt = 1 - A;                                                                                       \
        Cr += wgt * r;                                                                                             \
        Cg += wgt * g;                                                                                             \
        Cb += wgt * b;                                                                                             \
        A += wgt * a;                                                                                              \
        if (A >= thr) {                                                                                            \
          k = kEnd + 1;                                                                                            \
          break;                                                                                                   \
        }                                                                                                          \
      }                                                                                                            \
    }                                                                                                              \
    res[0] = (float)Cr;                                                                                            \
    res[1] = (float)Cg;                                                                                            \
    res[2] = (float)Cb;                                                                                            \
    res[3] = (float)A;                                                                                             \
    counts[2 * (size_t)gid] = samples;                                                                             \
    counts[2 * (size_t)gid + 1] = skips;                                                                           \
  }

VR_DEFINE_MARCH(float, f)
VR_DEFINE_MARCH(double, d)

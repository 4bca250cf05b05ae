/* Split-plane trees stored implicitly (engine/include/mtree/trees/implicit_tree.h): the implicit
 * general kd-tree and the implicit BSP tree, traversed without a stack by derived-parent
 * backtracking (ImplicitSplitTree::walkBacktrack), one work-item per ray:
 *   mt_split_first_hit  closest hit (ties to the smaller triangle id);
 *   mt_split_any_hit    shadow rays: stop at the first hit found.
 * The walk is the CPU's step for step, in doubles, with contraction off (common.clh), so the
 * hits, node visits and triangle tests equal the CPU's. The triangle test is query.cl's
 * mt_ray_triangle (rayTriangleMT), which precedes this file in the program (files are embedded
 * in name order).
 *
 * The tree arrives as flat arrays: levels[l] (MtSparseDesc: shape, block shape, and where the
 * level's pointer matrix starts in ptrs and its entries in words), the leaf table leafStart and
 * the triangle lists prims; planes = per direction normal (3), anchor, scale (5 doubles each);
 * box = root lo (3), root hi (3). */

#define MT_SPLIT_PARAMS                                                                              \
  __global const MtSparseDesc *levels, __global const uint *ptrs, __global const uint *words,       \
      __global const uint *leafStart, __global const uint *prims, __global const double *planes,    \
      __global const double *box, int dirs, int tagBits
#define MT_SPLIT_ARGS levels, ptrs, words, leafStart, prims, planes, box, dirs, tagBits
#define MT_SPLIT_MAX_DIRS 13
#define MT_SPLIT_EMPTY 0xFFFFFFFFu
#define MT_SPLIT_TPAD 0x1p-30

/* ImplicitSplitTree::word. */
inline uint mt_split_word(__global const MtSparseDesc* levels, __global const uint* ptrs, __global const uint* words,
                          int l, int x, int y, int z) {
  const MtSparseDesc d = levels[l];
  const uint b = ptrs[d.ptrOffset + mt_pointer_index(&d, x, y, z)];
  if (b == MT_NULL) return MT_SPLIT_EMPTY;
  return words[d.dataOffset + b * d.blockVolume + mt_local_index(&d, x, y, z)];
}

inline int mt_split_log_dim(int level, int axis) { return (level + 2 - axis) / 3; }

inline double mt_split_world(__global const double* planes, int k, uint w, uint mask) {
  const float s = as_float(w & ~mask);
  return planes[5 * k + 3] + (double)s * planes[5 * k + 4];
}

inline double mt_split_before(double t) { return t - MT_SPLIT_TPAD * fabs(t); }

/* The derived-parent walk with intersectFirst's (anyHit = 0) or intersectAny's (anyHit = 1) leaf
 * test. Returns the hit triangle or MT_NULL; *tHit the hit distance. */
inline uint mt_split_trace(MT_SPLIT_PARAMS, __global const double* pts, __global const uint* tris, mt_v3 o, mt_v3 d,
                           double tmin, double tmax, int anyHit, double* tHit, uint* visits, uint* tests) {
  double best = tmax;
  uint bestPrim = MT_NULL;
  *tHit = INFINITY;
  if (!isfinite(o.x) || !isfinite(o.y) || !isfinite(o.z) || !isfinite(d.x) || !isfinite(d.y) || !isfinite(d.z) ||
      !(tmin <= tmax))
    return MT_NULL;
  if (d.x == 0 && d.y == 0 && d.z == 0) return MT_NULL;
  double ro[MT_SPLIT_MAX_DIRS], rinv[MT_SPLIT_MAX_DIRS];
  int rpar[MT_SPLIT_MAX_DIRS], rneg[MT_SPLIT_MAX_DIRS];
  for (int k = 0; k < dirs; ++k) {
    const mt_v3 n = mt_v(planes[5 * k], planes[5 * k + 1], planes[5 * k + 2]);
    ro[k] = mt_dot(n, o);
    const double inv = 1.0 / mt_dot(n, d);
    rpar[k] = !(fabs(inv) < INFINITY);
    rinv[k] = rpar[k] ? 0.0 : inv;
    rneg[k] = inv < 0 ? 1 : 0;
  }
  double t0 = tmin, t1 = tmax;
  for (int a = 0; a < 3; ++a) {
    const double da = mt_at(d, a), oa = mt_at(o, a);
    const double inv = 1.0 / da;
    if (!(fabs(inv) < INFINITY)) {
      if (oa < box[a] || oa > box[3 + a]) return MT_NULL;
      continue;
    }
    double tn = (box[a] - oa) * inv, tf = (box[3 + a] - oa) * inv;
    if (tn > tf) { const double x = tn; tn = tf; tf = x; }
    if (tn > t0) t0 = tn;
    if (tf < t1) t1 = tf;
  }
  {
    const double a0 = t0 - MT_SPLIT_TPAD * fabs(t0), a1 = t1 + MT_SPLIT_TPAD * fabs(t1);
    t0 = a0;
    t1 = a1;
  }
  if (!(t0 <= t1)) return MT_NULL;

  const uint mask = (1u << tagBits) - 1u;
  ulong pending = 0;
  int level = 0, c[3] = {0, 0, 0};
  double tMin = t0, tMax = t1;
  for (;;) {
    uint w = mt_split_word(levels, ptrs, words, level, c[0], c[1], c[2]);
    ++*visits;
    while ((w & mask) != mask) {
      const int k = (int)(w & mask);
      const double p = mt_split_world(planes, k, w, mask);
      int side;
      if (rpar[k]) {
        side = ro[k] <= p ? 0 : 1;
      } else {
        const double ts = (p - ro[k]) * rinv[k];
        const int first = rneg[k];
        if (ts >= tMax) {
          side = first;
        } else if (ts <= tMin) {
          side = 1 - first;
        } else {
          pending |= (ulong)1 << level;
          tMax = ts;
          side = first;
        }
      }
      const int a = level % 3;
      c[a] = 2 * c[a] + side;
      ++level;
      w = mt_split_word(levels, ptrs, words, level, c[0], c[1], c[2]);
      ++*visits;
    }
    if (w != MT_SPLIT_EMPTY) {
      const uint li = w >> tagBits;
      const uint e = leafStart[li + 1];
      for (uint i = leafStart[li]; i < e; ++i) {
        const uint id = prims[i];
        double t;
        ++*tests;
        if (mt_ray_triangle(o, d, mt_vertex(pts, tris, id, 0), mt_vertex(pts, tris, id, 1),
                            mt_vertex(pts, tris, id, 2), tmin, anyHit ? tmax : best, &t)) {
          if (anyHit) {
            *tHit = t;
            return id;
          }
          if (t < best || (t == best && id < bestPrim)) {
            best = t;
            bestPrim = id;
          }
        }
      }
    }
    const double cutoff = bestPrim != MT_NULL ? best : INFINITY;
    if (pending == 0 || cutoff < mt_split_before(tMax)) break;
    /* The deepest ancestor the ray split: its far child spans [ts_p, ts_q]. */
    const int p = 63 - (int)clz(pending);
    pending &= ~((ulong)1 << p);
    int ap[3];
    for (int a = 0; a < 3; ++a) ap[a] = c[a] >> (mt_split_log_dim(level, a) - mt_split_log_dim(p, a));
    const uint wp = mt_split_word(levels, ptrs, words, p, ap[0], ap[1], ap[2]);
    ++*visits;
    const int kp = (int)(wp & mask);
    tMin = (mt_split_world(planes, kp, wp, mask) - ro[kp]) * rinv[kp];
    if (pending) {
      const int q = 63 - (int)clz(pending);
      int aq[3];
      for (int a = 0; a < 3; ++a) aq[a] = c[a] >> (mt_split_log_dim(level, a) - mt_split_log_dim(q, a));
      const uint wq = mt_split_word(levels, ptrs, words, q, aq[0], aq[1], aq[2]);
      ++*visits;
      const int kq = (int)(wq & mask);
      tMax = (mt_split_world(planes, kq, wq, mask) - ro[kq]) * rinv[kq];
    } else {
      tMax = t1;
    }
    const int a = p % 3;
    ap[a] = 2 * ap[a] + (1 - rneg[kp]);
    level = p + 1;
    c[0] = ap[0];
    c[1] = ap[1];
    c[2] = ap[2];
  }
  if (bestPrim != MT_NULL) *tHit = best;
  return bestPrim;
}

__kernel void mt_split_first_hit(MT_SPLIT_PARAMS, __global const double* pts, __global const uint* tris,
                                 __global const double* orig, __global const double* dirsIn, uint n, double tmin,
                                 double tmax, __global double* tOut, __global uint* primOut,
                                 __global uint* counters) {
  const uint q = get_global_id(0);
  if (q >= n) return;
  uint visits = 0, tests = 0;
  double t;
  primOut[q] = mt_split_trace(MT_SPLIT_ARGS, pts, tris, mt_load3(orig, q), mt_load3(dirsIn, q), tmin, tmax, 0, &t,
                              &visits, &tests);
  tOut[q] = t;
  if (counters) {
    counters[2 * q] = visits;
    counters[2 * q + 1] = tests;
  }
}

__kernel void mt_split_any_hit(MT_SPLIT_PARAMS, __global const double* pts, __global const uint* tris,
                               __global const double* orig, __global const double* dirsIn, uint n, double tmin,
                               double tmax, __global uchar* hit, __global uint* counters) {
  const uint q = get_global_id(0);
  if (q >= n) return;
  uint visits = 0, tests = 0;
  double t;
  hit[q] = mt_split_trace(MT_SPLIT_ARGS, pts, tris, mt_load3(orig, q), mt_load3(dirsIn, q), tmin, tmax, 1, &t,
                          &visits, &tests) != MT_NULL;
  if (counters) {
    counters[2 * q] = visits;
    counters[2 * q + 1] = tests;
  }
}

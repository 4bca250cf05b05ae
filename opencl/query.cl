/* Queries through a matrix tree (matrix_tree.h, raycast.h), one work-item per point or ray:
 *   mt_find_leaves  batched leaf finding: hash into the leaf level, binary search over depth;
 *   mt_first_hit    closest hit (ties to the smaller triangle id), Moller-Trumbore;
 *   mt_any_hit      shadow rays: stop at the first hit found.
 * The walker is MatrixTree::traverseRay step for step (neighbour finding across the exit face,
 * exact integer step on the exit axis), in doubles, so hits equal the CPU engine's.
 *
 * The tree arrives as flat arrays: levels[l] (MtLevelDesc: shape and where its pointer matrix
 * starts in ptrs and its entries in inner / leaves), and its geometry (MtTreeGeom: the root box,
 * 1 / leaf size, the node size of every level; engine/include/mtree/core/layout.h). */

#define MT_TREE_PARAMS                                                                            \
  __global const MtLevelDesc *levels, __global const uint *ptrs, __global const uchar *inner,     \
      __global const MtLeafRange *leaves, __global const MtTreeGeom *geom, int H
#define MT_TREE_ARGS levels, ptrs, inner, leaves, geom, H


typedef struct {
  int level; /* < 0: outside the tree */
  int c[3];
  int exists;
} mt_node;

inline int mt_log_dim(__global const MtLevelDesc* levels, int l, int a) { return levels[l].logDims[a]; }

inline bool mt_node_exists(MT_TREE_PARAMS, int l, const int c[3]) {
  const MtSparseDesc d = levels[l].matrix;
  const uint b = ptrs[d.ptrOffset + mt_pointer_index(&d, c[0], c[1], c[2])];
  if (b == MT_NULL) return false;
  const uint s = b * d.blockVolume + mt_local_index(&d, c[0], c[1], c[2]);
  return l == H ? leaves[d.dataOffset + s].begin != MT_NULL : inner[d.dataOffset + s] != 0;
}

inline void mt_ancestor(__global const MtLevelDesc* levels, int H, const int L[3], int l, int c[3]) {
  for (int a = 0; a < 3; ++a) c[a] = L[a] >> (mt_log_dim(levels, H, a) - mt_log_dim(levels, l, a));
}

/* MatrixTree::locate: level lo is known to exist on the path, level hi known absent (H+1 = unknown). */
inline mt_node mt_locate(MT_TREE_PARAMS, const int L[3], int lo, int hi, uint* visits) {
  mt_node r;
  if (hi > H) {
    ++*visits;
    if (mt_node_exists(MT_TREE_ARGS, H, L)) {
      r.level = H;
      r.c[0] = L[0]; r.c[1] = L[1]; r.c[2] = L[2];
      r.exists = 1;
      return r;
    }
    hi = H;
  }
  int c[3];
  while (hi - lo > 1) {
    const int mid = (lo + hi) / 2;
    mt_ancestor(levels, H, L, mid, c);
    ++*visits;
    if (mt_node_exists(MT_TREE_ARGS, mid, c)) lo = mid;
    else hi = mid;
  }
  r.level = hi;
  mt_ancestor(levels, H, L, hi, r.c);
  r.exists = 0;
  return r;
}

/* MatrixTree::neighbourFind. */
inline mt_node mt_neighbour(MT_TREE_PARAMS, const mt_node* n, int axis, int dir, const int L[3], uint* visits) {
  int c[3] = {n->c[0], n->c[1], n->c[2]};
  c[axis] += dir;
  if (c[axis] < 0 || c[axis] >= (1 << mt_log_dim(levels, n->level, axis))) {
    mt_node out;
    out.level = -1;
    return out;
  }
  ++*visits;
  if (mt_node_exists(MT_TREE_ARGS, n->level, c)) {
    if (n->level == H) {
      mt_node r;
      r.level = H;
      r.c[0] = L[0]; r.c[1] = L[1]; r.c[2] = L[2];
      r.exists = 1;
      return r;
    }
    return mt_locate(MT_TREE_ARGS, L, n->level, H + 1, visits);
  }
  return mt_locate(MT_TREE_ARGS, L, 0, n->level, visits);
}

inline bool mt_finite3(mt_v3 a) { return isfinite(a.x) && isfinite(a.y) && isfinite(a.z); }

/* MatrixTree::leafFind: the leaf, or the largest empty node, holding point p; false when p is
 * not finite or outside the root box (*r untouched). */
inline bool mt_leaf_find(MT_TREE_PARAMS, mt_v3 p, mt_node* r) {
  if (!mt_finite3(p)) return false;
  for (int a = 0; a < 3; ++a)
    if (!(mt_at(p, a) >= geom->lo[a] && mt_at(p, a) <= geom->hi[a])) return false;
  int L[3];
  for (int a = 0; a < 3; ++a)
    L[a] = mt_cell_index((mt_at(p, a) - geom->lo[a]) * geom->invLeaf[a], 0, (1 << mt_log_dim(levels, H, a)) - 1);
  uint visits = 0;
  *r = mt_locate(MT_TREE_ARGS, L, 0, H + 1, &visits);
  return true;
}

/* Points: 3 doubles each. out: 5 ints per point (level, i, j, k, exists); level -1 outside. */
__kernel void mt_find_leaves(MT_TREE_PARAMS, __global const double* pts, uint n, __global int* out) {
  const uint q = get_global_id(0);
  if (q >= n) return;
  const mt_v3 p = mt_load3(pts, q);
  __global int* o = out + 5 * q;
  o[0] = -1; o[1] = 0; o[2] = 0; o[3] = 0; o[4] = 0;
  mt_node r;
  if (!mt_leaf_find(MT_TREE_ARGS, p, &r)) return;
  o[0] = r.level; o[1] = r.c[0]; o[2] = r.c[1]; o[3] = r.c[2]; o[4] = r.exists;
}

/* rayTriangleMT (geometry.h), Moller & Trumbore 1997. */
inline bool mt_ray_triangle(mt_v3 o, mt_v3 d, mt_v3 a, mt_v3 b, mt_v3 c, double tmin, double tmax, double* t) {
  const mt_v3 e1 = mt_sub(b, a), e2 = mt_sub(c, a);
  const mt_v3 p = mt_cross(d, e2);
  const double det = mt_dot(e1, p);
  if (det == 0.0 || !isfinite(det)) return false;
  /* The edge tests on the unscaled numerators, det's sign folded in; the division after them. */
  const double sg = det > 0 ? 1.0 : -1.0, adet = det * sg;
  const mt_v3 s = mt_sub(o, a);
  const double un = mt_dot(s, p) * sg;
  if (!(un >= 0.0 && un <= adet)) return false;
  const mt_v3 q = mt_cross(s, e1);
  const double vn = mt_dot(d, q) * sg;
  if (!(vn >= 0.0 && un + vn <= adet)) return false;
  const double inv = 1.0 / det;
  const double tt = mt_dot(e2, q) * inv;
  if (!(tt >= tmin && tt <= tmax)) return false;
  *t = tt;
  return true;
}

/* The walk of MatrixTree::traverseRay with the leaf callback of intersectFirst (anyHit = 0) or
 * intersectAny (anyHit = 1). Returns the hit triangle or MT_NULL; *tHit the hit distance. */
inline uint mt_trace(MT_TREE_PARAMS, __global const uint* prims, __global const double* pts,
                     __global const uint* tris, mt_v3 o, mt_v3 d, double tmin, double tmax, int anyHit,
                     double* tHit, uint* visits, uint* tests) {
  double best = tmax;
  uint bestPrim = MT_NULL;
  *tHit = INFINITY;
  if (!mt_finite3(o) || !mt_finite3(d) || !(tmin <= tmax)) return MT_NULL;
  if (d.x == 0 && d.y == 0 && d.z == 0) return MT_NULL;
  double t0 = tmin, t1 = tmax;
  for (int a = 0; a < 3; ++a) { /* rayBox */
    const double da = mt_at(d, a), oa = mt_at(o, a), lo = geom->lo[a], hi = geom->hi[a];
    if (da == 0.0) {
      if (oa < lo || oa > hi) return MT_NULL;
      continue;
    }
    const double inv = 1.0 / da;
    double tn = (lo - oa) * inv, tf = (hi - oa) * inv;
    if (tn > tf) { const double x = tn; tn = tf; tf = x; }
    t0 = mt_max(t0, tn);
    t1 = mt_min(t1, tf);
    if (t0 > t1) return MT_NULL;
  }
  const mt_v3 ol = mt_v(o.x - geom->lo[0], o.y - geom->lo[1], o.z - geom->lo[2]);
  int dimH[3];
  for (int a = 0; a < 3; ++a) dimH[a] = 1 << mt_log_dim(levels, H, a);
  int L[3];
  for (int a = 0; a < 3; ++a) {
    const double p = mt_at(ol, a) + mt_at(d, a) * t0;
    L[a] = mt_cell_index(p * geom->invLeaf[a], 0, dimH[a] - 1);
  }
  mt_node n = mt_locate(MT_TREE_ARGS, L, 0, H + 1, visits);
  double tEnter = t0;
  const int maxSteps = 3 * (dimH[0] + dimH[1] + dimH[2]) + 8;
  for (int step = 0; step < maxSteps; ++step) {
    __global const double* cs = geom->cellSize[n.level];
    double tExit = t1;
    int exitAxis = -1;
    for (int a = 0; a < 3; ++a) {
      const double da = mt_at(d, a);
      if (da > 0) {
        const double t = ((n.c[a] + 1) * cs[a] - mt_at(ol, a)) / da;
        if (t < tExit) { tExit = t; exitAxis = a; }
      } else if (da < 0) {
        const double t = (n.c[a] * cs[a] - mt_at(ol, a)) / da;
        if (t < tExit) { tExit = t; exitAxis = a; }
      }
    }
    tExit = mt_max(tExit, tEnter);
    if (n.exists) {
      const MtSparseDesc ld = levels[H].matrix;
      const uint s = mt_storage_index(&ld, ptrs + ld.ptrOffset, n.c[0], n.c[1], n.c[2]);
      const MtLeafRange r = leaves[ld.dataOffset + s];
      for (uint k = r.begin; k < r.end; ++k) {
        const uint id = prims[k];
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
      /* A hit inside this node (t <= tExit) cannot be beaten by a later node. */
      if (!anyHit && bestPrim != MT_NULL && best <= tExit) break;
    }
    if (exitAxis < 0) break;
    const int sh = mt_log_dim(levels, H, exitAxis) - mt_log_dim(levels, n.level, exitAxis);
    const int dir = mt_at(d, exitAxis) > 0 ? 1 : -1;
    L[exitAxis] = dir > 0 ? ((n.c[exitAxis] + 1) << sh) : ((n.c[exitAxis] << sh) - 1);
    if (L[exitAxis] < 0 || L[exitAxis] >= dimH[exitAxis]) break;
    for (int a = 0; a < 3; ++a) {
      if (a == exitAxis) continue;
      const int s = mt_log_dim(levels, H, a) - mt_log_dim(levels, n.level, a);
      const int lo = n.c[a] << s, hi = ((n.c[a] + 1) << s) - 1;
      L[a] = mt_cell_index((mt_at(ol, a) + mt_at(d, a) * tExit) * geom->invLeaf[a], lo, hi);
    }
    n = mt_neighbour(MT_TREE_ARGS, &n, exitAxis, dir, L, visits);
    if (n.level < 0) break;
    tEnter = tExit;
  }
  if (bestPrim != MT_NULL) *tHit = best;
  return bestPrim;
}

/* Rays: origins and directions 3 doubles each, t in [tmin, tmax]. Outputs per ray: t (inf on a
 * miss), the triangle (MT_NULL on a miss); counters (node visits, triangle tests) when given. */
__kernel void mt_first_hit(MT_TREE_PARAMS, __global const uint* prims, __global const double* pts,
                           __global const uint* tris, __global const double* orig, __global const double* dirs,
                           uint n, double tmin, double tmax, __global double* tOut, __global uint* primOut,
                           __global uint* counters) {
  const uint q = get_global_id(0);
  if (q >= n) return;
  uint visits = 0, tests = 0;
  double t;
  primOut[q] = mt_trace(MT_TREE_ARGS, prims, pts, tris, mt_load3(orig, q), mt_load3(dirs, q), tmin, tmax, 0, &t,
                        &visits, &tests);
  tOut[q] = t;
  if (counters) {
    counters[2 * q] = visits;
    counters[2 * q + 1] = tests;
  }
}

/* Shadow rays: hit[q] = 1 if anything lies on the ray within [tmin, tmax]. */
__kernel void mt_any_hit(MT_TREE_PARAMS, __global const uint* prims, __global const double* pts,
                         __global const uint* tris, __global const double* orig, __global const double* dirs,
                         uint n, double tmin, double tmax, __global uchar* hit, __global uint* counters) {
  const uint q = get_global_id(0);
  if (q >= n) return;
  uint visits = 0, tests = 0;
  double t;
  hit[q] = mt_trace(MT_TREE_ARGS, prims, pts, tris, mt_load3(orig, q), mt_load3(dirs, q), tmin, tmax, 1, &t,
                    &visits, &tests) != MT_NULL;
  if (counters) {
    counters[2 * q] = visits;
    counters[2 * q + 1] = tests;
  }
}

/* The §5.1 bottom-up build of a matrix tree over triangles (Andrysco & Tricoche 2011, after
 * Kalojanov & Slusallek 2009), one kernel per step. The host (engine/src/device/opencl_build.cpp)
 * runs them in order:
 *   mt_bounds         root box: per-group min/max of the triangles' vertices (step 1's reduction)
 *   mt_count_mark     step 2: per triangle, count overlapped leaves, mark their blocks
 *   mt_scan_* (scan.cl) + mt_finish_alloc   steps 3-4: block pointers from the scanned marks
 *   mt_scan_*         step 5: pair offsets from the scanned counts
 *   mt_write_pairs    step 6: (leaf storage index, triangle) pairs at the scanned offsets
 *   mt_radix_* (sort.cl)  step 7: stable radix sort of the pairs by leaf
 *   mt_leaf_offsets   step 8: leaf ranges from neighbouring keys
 *   mt_parent_mark + scan + mt_finish_alloc + mt_parent_scatter   step 9, level by level
 * Every kernel mirrors the loop body of MatrixTreeBuilder<TriangleMesh>::build (builder.h) so
 * that the trees are identical, not just equivalent. */

/* The build parameters are one MtBuildParams (engine/include/mtree/core/layout.h): the leaf grid's
 * origin, 1 / leaf size, leaf size and padded half size, as the CPU builder computes them. */

/* TriangleBoxTester (geometry.h): the 10 non-trivial separating axes computed once. */
typedef struct {
  double ax[10][3];
  double lo[10], hi[10], r[10];
  int n;
} mt_tester;

inline void mt_tester_add(mt_tester* T, mt_v3 a, mt_v3 b, mt_v3 c, mt_v3 hs, mt_v3 ax) {
  if (ax.x == 0 && ax.y == 0 && ax.z == 0) return;
  const double p0 = mt_dot(a, ax), p1 = mt_dot(b, ax), p2 = mt_dot(c, ax);
  const int n = T->n;
  T->ax[n][0] = ax.x;
  T->ax[n][1] = ax.y;
  T->ax[n][2] = ax.z;
  T->lo[n] = mt_min(p0, mt_min(p1, p2));
  T->hi[n] = mt_max(p0, mt_max(p1, p2));
  T->r[n] = hs.x * fabs(ax.x) + hs.y * fabs(ax.y) + hs.z * fabs(ax.z);
  T->n = n + 1;
}

inline void mt_tester_init(mt_tester* T, mt_v3 a, mt_v3 b, mt_v3 c, mt_v3 hs) {
  T->n = 0;
  mt_v3 e[3];
  e[0] = mt_sub(b, a);
  e[1] = mt_sub(c, b);
  e[2] = mt_sub(a, c);
  mt_tester_add(T, a, b, c, hs, mt_cross(e[0], e[1]));
  for (int k = 0; k < 3; ++k) {
    const mt_v3 d = e[k];
    mt_tester_add(T, a, b, c, hs, mt_v(0, -d.z, d.y));
    mt_tester_add(T, a, b, c, hs, mt_v(d.z, 0, -d.x));
    mt_tester_add(T, a, b, c, hs, mt_v(-d.y, d.x, 0));
  }
}

inline bool mt_tester_overlaps(const mt_tester* T, mt_v3 c) {
  for (int k = 0; k < T->n; ++k) {
    const double pc = c.x * T->ax[k][0] + c.y * T->ax[k][1] + c.z * T->ax[k][2];
    if (T->lo[k] - pc > T->r[k] || T->hi[k] - pc < -T->r[k]) return false;
  }
  return true;
}

/* Centre of leaf (i, j, k): org + (i + 0.5) * leafSize, per axis. */
inline mt_v3 mt_cell_centre(__global const MtBuildParams* P, int i, int j, int k) {
  return mt_v(P->origin[0] + (i + 0.5) * P->leafSize[0], P->origin[1] + (j + 0.5) * P->leafSize[1],
              P->origin[2] + (k + 0.5) * P->leafSize[2]);
}

/* Candidate leaf range of a triangle: its bounding box in leaf cells, clamped. */
inline void mt_cell_range(__global const MtBuildParams* P, const int dims[3], mt_v3 a, mt_v3 b, mt_v3 c, int lo[3],
                          int hi[3]) {
  for (int ax = 0; ax < 3; ++ax) {
    const double va = mt_at(a, ax), vb = mt_at(b, ax), vc = mt_at(c, ax);
    const double bl = mt_min(mt_min(va, vb), vc), bh = mt_max(mt_max(va, vb), vc);
    lo[ax] = mt_cell_index((bl - P->origin[ax]) * P->invLeaf[ax], 0, dims[ax] - 1);
    hi[ax] = mt_cell_index((bh - P->origin[ax]) * P->invLeaf[ax], 0, dims[ax] - 1);
  }
}

/* Root box: per work-group min and max of the referenced vertices, 6 doubles per group
 * (lo xyz, hi xyz). Min and max are exact, so the host's final reduction gives the CPU's box. */
__kernel void mt_bounds(__global const double* pts, __global const uint* tris, uint n,
                        __global double* groupBox) {
  __local double sh[6][MT_WG];
  const uint lid = get_local_id(0);
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (uint t = get_global_id(0); t < n; t += get_global_size(0))
    for (int k = 0; k < 3; ++k) {
      const mt_v3 v = mt_vertex(pts, tris, t, k);
      lo[0] = mt_min(lo[0], v.x); lo[1] = mt_min(lo[1], v.y); lo[2] = mt_min(lo[2], v.z);
      hi[0] = mt_max(hi[0], v.x); hi[1] = mt_max(hi[1], v.y); hi[2] = mt_max(hi[2], v.z);
    }
  for (int a = 0; a < 3; ++a) {
    sh[a][lid] = lo[a];
    sh[3 + a][lid] = hi[a];
  }
  barrier(CLK_LOCAL_MEM_FENCE);
  for (uint s = MT_WG / 2; s > 0; s >>= 1) {
    if (lid < s)
      for (int a = 0; a < 3; ++a) {
        sh[a][lid] = mt_min(sh[a][lid], sh[a][lid + s]);
        sh[3 + a][lid] = mt_max(sh[3 + a][lid], sh[3 + a][lid + s]);
      }
    barrier(CLK_LOCAL_MEM_FENCE);
  }
  if (lid == 0)
    for (int a = 0; a < 6; ++a) groupBox[6 * get_group_id(0) + a] = sh[a][0];
}

/* Step 2. One work-item per triangle: counts[t] = overlapped leaves; masks[t] bit c = verdict
 * of candidate c < 64 (exact mode); marks[block] = 1 for every block holding one of them. */
__kernel void mt_count_mark(__global const double* pts, __global const uint* tris, uint n,
                            __global const MtBuildParams* P, MtSparseDesc leafDesc, int exact,
                            __global uint* counts, __global ulong* masks, __global uchar* marks) {
  const uint t = get_global_id(0);
  if (t >= n) return;
  const mt_v3 a = mt_vertex(pts, tris, t, 0), b = mt_vertex(pts, tris, t, 1), c = mt_vertex(pts, tris, t, 2);
  int lo[3], hi[3];
  mt_cell_range(P, leafDesc.dims, a, b, c, lo, hi);
  const int thin = (lo[0] == hi[0]) + (lo[1] == hi[1]) + (lo[2] == hi[2]);
  const bool test = exact && thin < 2;
  mt_tester T;
  if (test) mt_tester_init(&T, a, b, c, mt_v(P->halfSize[0], P->halfSize[1], P->halfSize[2]));
  uint cnt = 0, cand = 0;
  ulong mask = 0;
  uint lastBlock = MT_NULL;
  for (int k = lo[2]; k <= hi[2]; ++k)
    for (int j = lo[1]; j <= hi[1]; ++j)
      for (int i = lo[0]; i <= hi[0]; ++i, ++cand) {
        if (test && !mt_tester_overlaps(&T, mt_cell_centre(P, i, j, k))) continue;
        if (cand < 64) mask |= (ulong)1 << cand;
        ++cnt;
        const uint blk = mt_pointer_index(&leafDesc, i, j, k);
        if (blk != lastBlock) {
          marks[blk] = 1; /* every writer stores 1: the order does not matter */
          lastBlock = blk;
        }
      }
  counts[t] = cnt;
  if (exact) masks[t] = mask;
}

/* Steps 3-4 (and 9): ptr holds the exclusive scan of marks; unmarked cells become MT_NULL and
 * every allocated block records its pointer-matrix position (for mt_entry_coords). */
__kernel void mt_finish_alloc(__global const uchar* marks, __global uint* ptr, uint n, __global uint* blockPos) {
  const uint i = get_global_id(0);
  if (i >= n) return;
  if (marks[i]) blockPos[ptr[i]] = i;
  else ptr[i] = MT_NULL;
}

/* Step 6. One work-item per triangle writes its pairs at its scanned offset, in candidate order;
 * beyond the 64 masked candidates the overlap test is repeated (as in builder.h). */
__kernel void mt_write_pairs(__global const double* pts, __global const uint* tris, uint n,
                             __global const MtBuildParams* P, MtSparseDesc leafDesc, __global const uint* leafPtr,
                             int exact, __global const uint* offsets, __global const ulong* masks,
                             __global uint* keys, __global uint* values) {
  const uint t = get_global_id(0);
  if (t >= n) return;
  const mt_v3 a = mt_vertex(pts, tris, t, 0), b = mt_vertex(pts, tris, t, 1), c = mt_vertex(pts, tris, t, 2);
  int lo[3], hi[3];
  mt_cell_range(P, leafDesc.dims, a, b, c, lo, hi);
  uint out = offsets[t], cand = 0;
  const ulong mask = exact ? masks[t] : ~(ulong)0;
  const int thin = (lo[0] == hi[0]) + (lo[1] == hi[1]) + (lo[2] == hi[2]);
  const bool test = exact && thin < 2;
  const bool big = test && (ulong)(hi[0] - lo[0] + 1) * (ulong)(hi[1] - lo[1] + 1) * (ulong)(hi[2] - lo[2] + 1) > 64;
  mt_tester T;
  if (big) mt_tester_init(&T, a, b, c, mt_v(P->halfSize[0], P->halfSize[1], P->halfSize[2]));
  for (int k = lo[2]; k <= hi[2]; ++k)
    for (int j = lo[1]; j <= hi[1]; ++j)
      for (int i = lo[0]; i <= hi[0]; ++i, ++cand) {
        bool in;
        if (cand < 64) in = ((mask >> cand) & 1) != 0;
        else in = big ? mt_tester_overlaps(&T, mt_cell_centre(P, i, j, k)) : !test;
        if (!in) continue;
        keys[out] = mt_storage_index(&leafDesc, leafPtr, i, j, k);
        values[out] = t;
        ++out;
      }
}

/* Step 8. One work-item per sorted pair; a key differing from its predecessor starts a leaf.
 * The leaf array is pre-filled with MT_NULL by the host. */
__kernel void mt_leaf_offsets(__global const uint* keys, uint m, __global MtLeafRange* leaves,
                              __global uint* leafCount) {
  const uint i = get_global_id(0);
  if (i >= m) return;
  const uint k = keys[i];
  if (i == 0 || k != keys[i - 1]) {
    atomic_inc(leafCount);
    leaves[k].begin = i;
    if (i > 0) leaves[keys[i - 1]].end = i;
  }
  if (i == m - 1) leaves[k].end = m;
}

/* Step 9a. One work-item per child pointer-matrix cell: a child block lies inside exactly one
 * parent block; mark it. sh = child logDims - parent logDims per axis. */
__kernel void mt_parent_mark(__global const uint* cptr, MtSparseDesc cd, MtSparseDesc pd, int sh0, int sh1,
                             int sh2, __global uchar* pmarks) {
  const uint p = get_global_id(0);
  const uint ncp = (uint)cd.ptrDims[0] * (uint)cd.ptrDims[1] * (uint)cd.ptrDims[2];
  if (p >= ncp || cptr[p] == MT_NULL) return;
  const int bx = (int)(p % (uint)cd.ptrDims[0]);
  const int by = (int)((p / (uint)cd.ptrDims[0]) % (uint)cd.ptrDims[1]);
  const int bz = (int)(p / ((uint)cd.ptrDims[0] * (uint)cd.ptrDims[1]));
  const int i = (bx << cd.logBlock[0]) >> sh0, j = (by << cd.logBlock[1]) >> sh1, k = (bz << cd.logBlock[2]) >> sh2;
  pmarks[mt_pointer_index(&pd, i, j, k)] = 1;
}

/* Step 9b. One work-item per allocated child entry: an existing child makes its parent exist.
 * leafData != 0: the child level is the leaf level (exists = begin != MT_NULL); else innerData. */
__kernel void mt_parent_scatter(int childIsLeaf, __global const MtLeafRange* leafData,
                                __global const uchar* innerData, uint nce, MtSparseDesc cd,
                                __global const uint* cBlockPos, MtSparseDesc pd, __global const uint* pptr,
                                int sh0, int sh1, int sh2, __global uchar* pdata) {
  const uint e = get_global_id(0);
  if (e >= nce) return;
  const bool exists = childIsLeaf ? leafData[e].begin != MT_NULL : innerData[e] != 0;
  if (!exists) return;
  int c[3];
  mt_entry_coords(&cd, cBlockPos, e, c);
  pdata[mt_storage_index(&pd, pptr, c[0] >> sh0, c[1] >> sh1, c[2] >> sh2)] = 1;
}

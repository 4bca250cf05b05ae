/* Batched point location in the cells of an unstructured grid (mtree::ocl::CellLocator), one
 * work-item per point. It is the CPU loop of vtkMatrixTreeLocator::FindCell up to the point where
 * that loop asks VTK:
 *   1. leafFind (mt_locate of query.cl: hash into the leaf level, binary search over depth);
 *   2. the leaf's candidates in tree order, each tested against its quantized leaf-local box, in
 *      the host's double arithmetic and operation order (contraction off), so the rejections are
 *      the CPU's;
 *   3. a tetrahedron is decided here when the answer is certain (mt_tetra_side); anything else
 *      stops the scan and hands the candidate's position to the host, which goes on with the CPU
 *      loop (VTK's EvaluatePosition) from there.
 * The answer the host completes is therefore the CPU's, cell for cell.
 *
 * Uses query.cl (MT_TREE_PARAMS, mt_locate, mt_finite3): the embedder concatenates the kernel
 * files in name order, and "query.cl" sorts before "query_cells.cl".
 *
 * out, 2 uints per point: (MT_LOC_NONE, 0): no cell; (MT_LOC_FOUND, k): the tetrahedron prims[k]
 * contains the point; (MT_LOC_RESUME, k): the host scans on from position k. */

#define MT_LOC_NONE 0u
#define MT_LOC_FOUND 1u
#define MT_LOC_RESUME 2u
#define MT_VTK_TETRA 10

inline double mt_length(mt_v3 a) { return sqrt(mt_dot(a, a)); }

/* Is x in the tetrahedron (point ids ids[0..3]) within tol on every barycentric coordinate, as
 * vtkTetra::EvaluatePosition decides (coordinates of points 1, 2, 3 and 1 minus their sum, each
 * in [-tol, 1 + tol])? 1: surely inside, -1: surely outside, 0: too close to call.
 *
 * The coordinates are computed as CellSet::tetraMayContain does (the CPU's pre-test), VTK by
 * Cramer's rule on the same edge vectors: different roundings of the same quotients of
 * determinants. Each determinant is off by a few ulp of |r||b||d|-like products, so a coordinate
 * by about 1e-15 S^3/|det| (S: the longest of the edges and of x - p0) in either computation;
 * the margin m = 1e-12 (1 + S^3/|det|) is 100 times that. Only a point within m of the tolerance
 * boundary, or a degenerate or non-finite tetrahedron (m infinite or undefined), is left to VTK. */
inline int mt_tetra_side(__global const double* pts, __global const uint* ids, mt_v3 x, double tol) {
  const mt_v3 p0 = mt_load3(pts, ids[0]), p1 = mt_load3(pts, ids[1]), p2 = mt_load3(pts, ids[2]),
              p3 = mt_load3(pts, ids[3]);
  const mt_v3 a = mt_sub(p1, p0), b = mt_sub(p2, p0), d = mt_sub(p3, p0), r = mt_sub(x, p0);
  const mt_v3 bd = mt_cross(b, d);
  const double det = mt_dot(a, bd);
  if (!(fabs(det) > 0.0) || !isfinite(det)) return 0;
  const double inv = 1.0 / det;
  const double u = mt_dot(r, bd) * inv, v = mt_dot(a, mt_cross(r, d)) * inv, w = mt_dot(a, mt_cross(b, r)) * inv;
  const double s = 1.0 - u - v - w;
  const double S = mt_max(mt_max(mt_length(a), mt_length(b)), mt_max(mt_length(d), mt_length(r)));
  const double m = 1e-12 * (1.0 + S * S * S / fabs(det));
  if (!(m < 1e-4)) return 0; /* ill-conditioned (or overflow): VTK decides */
  const double lo = -tol, hi = 1.0 + tol;
  if (u < lo - m || u > hi + m || v < lo - m || v > hi + m || w < lo - m || w > hi + m || s < lo - m || s > hi + m)
    return -1;
  if (u >= lo + m && u <= hi - m && v >= lo + m && v <= hi - m && w >= lo + m && w <= hi - m && s >= lo + m &&
      s <= hi - m)
    return 1;
  return 0;
}

/* Tree: MT_TREE_PARAMS (query.cl). prims: the tree's primitive indices; boxes: 6 uchars per
 * primitive index (the cell's box in its leaf, lo/hi per axis in 1/255 of the leaf); pts (3
 * doubles per point), offsets (cells + 1), conn, types (VTK codes): the cells. query: n points,
 * 3 doubles each. tol: VTK's tetrahedron tolerance (1e-3). */
__kernel void mt_locate_cells(MT_TREE_PARAMS, __global const uint* prims, __global const uchar* boxes,
                              __global const double* pts, __global const uint* offsets, __global const uint* conn,
                              __global const uchar* types, __global const double* query, uint n, double tol,
                              __global uint* out) {
  const uint q = get_global_id(0);
  if (q >= n) return;
  __global uint* o = out + 2 * (size_t)q;
  o[0] = MT_LOC_NONE;
  o[1] = 0;
  const mt_v3 p = mt_load3(query, q);
  mt_node leaf;
  if (!mt_leaf_find(MT_TREE_ARGS, p, &leaf) || !leaf.exists) return;
  const MtSparseDesc ld = levels[H].matrix;
  const uint st = mt_storage_index(&ld, ptrs + ld.ptrOffset, leaf.c[0], leaf.c[1], leaf.c[2]);
  const MtLeafRange range = leaves[ld.dataOffset + st];
  /* The point in the leaf's quantized frame: MatrixTree::nodeBox, then the locator's clamp. */
  __global const double* cs = geom->cellSize[H];
  double qx[3];
  for (int a = 0; a < 3; ++a) {
    const double lo = geom->lo[a] + leaf.c[a] * cs[a];
    const double hi = geom->lo[a] + (leaf.c[a] + 1) * cs[a];
    qx[a] = mt_min(255.0, mt_max(0.0, (mt_at(p, a) - lo) * (255.0 / (hi - lo))));
  }
  for (uint k = range.begin; k < range.end; ++k) {
    __global const uchar* b = boxes + 6 * (size_t)k;
    if (qx[0] < b[0] || qx[0] > b[1] || qx[1] < b[2] || qx[1] > b[3] || qx[2] < b[4] || qx[2] > b[5]) continue;
    const uint id = prims[k];
    const uint first = offsets[id];
    int side = 0;
    if (types[id] == MT_VTK_TETRA && offsets[id + 1] - first == 4) side = mt_tetra_side(pts, conn + first, p, tol);
    if (side < 0) continue;
    o[0] = side > 0 ? MT_LOC_FOUND : MT_LOC_RESUME;
    o[1] = k;
    return;
  }
}

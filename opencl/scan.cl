/* Exclusive scan (Blelloch 1990; Harris, Sengupta & Owens, GPU Gems 3 ch. 39), in two kernels
 * around a host step:
 *   mt_scan_tiles_*  each work-group scans one tile of MT_TILE elements (MT_ITEMS consecutive
 *                    elements per work-item, then a Hillis-Steele scan of the work-items' sums
 *                    in local memory) and writes the tile's total as a 64-bit sum;
 *   (host)           the tile totals (n / MT_TILE of them) are scanned in 64 bits on the host,
 *                    which also gives the grand total with an overflow check against 2^32;
 *   mt_scan_add      adds each tile's offset to its elements.
 * The result does not depend on the device: integer sums in a fixed order. */

#define MT_SCAN_TILES(NAME, T)                                                                  \
  __kernel void NAME(__global const T* in, __global uint* out, uint n, __global ulong* tileSums) { \
    __local ulong sh[MT_WG];                                                                     \
    const uint lid = get_local_id(0), g = get_group_id(0);                                      \
    const uint base = g * MT_TILE + lid * MT_ITEMS;                                             \
    uint pre[MT_ITEMS];                                                                         \
    ulong s = 0;                                                                                \
    for (int t = 0; t < MT_ITEMS; ++t) {                                                        \
      const uint idx = base + t;                                                                \
      pre[t] = (uint)s;                                                                         \
      s += idx < n ? (ulong)in[idx] : 0ul;                                                       \
    }                                                                                           \
    sh[lid] = s;                                                                                \
    barrier(CLK_LOCAL_MEM_FENCE);                                                               \
    for (uint off = 1; off < MT_WG; off <<= 1) {                                                \
      const ulong y = lid >= off ? sh[lid - off] : 0ul;                                         \
      barrier(CLK_LOCAL_MEM_FENCE);                                                             \
      sh[lid] += y;                                                                             \
      barrier(CLK_LOCAL_MEM_FENCE);                                                             \
    }                                                                                           \
    const uint excl = (uint)(sh[lid] - s);                                                            \
    for (int t = 0; t < MT_ITEMS; ++t) {                                                        \
      const uint idx = base + t;                                                                \
      if (idx < n) out[idx] = excl + pre[t];                                                    \
    }                                                                                           \
    if (lid == MT_WG - 1) tileSums[g] = sh[lid];                                                 \
  }

/* Sums are kept in 64 bits inside a tile: a total past 2^32 is then seen by the host, and the
 * 32-bit outputs (wrapped only in that case) are never used. */
MT_SCAN_TILES(mt_scan_tiles_u8, uchar)
MT_SCAN_TILES(mt_scan_tiles_u32, uint)

__kernel void mt_scan_add(__global uint* out, uint n, __global const uint* tileOffsets) {
  const uint i = get_global_id(0);
  if (i < n) out[i] += tileOffsets[i / MT_TILE];
}

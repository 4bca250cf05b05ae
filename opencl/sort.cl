/* Stable LSD radix sort of (key, value) pairs, MT_RADIX_BITS bits per pass (Satish, Harris &
 * Garland 2009, simplified): per pass
 *   mt_radix_hist     per tile, the count of each digit, stored digit-major
 *                     (hist[digit * numTiles + tile]), so one exclusive scan of hist gives
 *                     every (digit, tile) its first output position in stable order;
 *   (scan.cl)         exclusive scan of hist;
 *   mt_radix_scatter  per tile, each work-item's MT_ITEMS consecutive elements go out in order,
 *                     after the elements of the same digit in earlier work-items and tiles.
 * Stable, so equal keys keep their order: the same pair order as the CPU engine's sort. */

inline void mt_digit_counts(__global const uint* keys, uint n, int shift, uint c[MT_RADIX]) {
  const uint base = get_group_id(0) * MT_TILE + get_local_id(0) * MT_ITEMS;
  for (int d = 0; d < MT_RADIX; ++d) c[d] = 0;
  for (int t = 0; t < MT_ITEMS; ++t) {
    const uint idx = base + t;
    if (idx < n) ++c[(keys[idx] >> shift) & (MT_RADIX - 1)];
  }
}

__kernel void mt_radix_hist(__global const uint* keys, uint n, int shift, __global uint* hist) {
  __local uint cnt[MT_RADIX * MT_WG];
  const uint lid = get_local_id(0), g = get_group_id(0), tiles = get_num_groups(0);
  uint c[MT_RADIX];
  mt_digit_counts(keys, n, shift, c);
  for (int d = 0; d < MT_RADIX; ++d) cnt[d * MT_WG + lid] = c[d];
  barrier(CLK_LOCAL_MEM_FENCE);
  if (lid < MT_RADIX) {
    uint s = 0;
    for (uint w = 0; w < MT_WG; ++w) s += cnt[lid * MT_WG + w];
    hist[lid * tiles + g] = s;
  }
}

__kernel void mt_radix_scatter(__global const uint* keys, __global const uint* values, uint n, int shift,
                               __global const uint* histScan, __global uint* outKeys, __global uint* outValues) {
  __local uint cnt[MT_RADIX * MT_WG];
  const uint lid = get_local_id(0), g = get_group_id(0), tiles = get_num_groups(0);
  uint c[MT_RADIX];
  mt_digit_counts(keys, n, shift, c);
  for (int d = 0; d < MT_RADIX; ++d) cnt[d * MT_WG + lid] = c[d];
  barrier(CLK_LOCAL_MEM_FENCE);
  if (lid < MT_RADIX) {  /* exclusive prefix over the work-items, per digit */
    uint s = histScan[lid * tiles + g];
    for (uint w = 0; w < MT_WG; ++w) {
      const uint x = cnt[lid * MT_WG + w];
      cnt[lid * MT_WG + w] = s;
      s += x;
    }
  }
  barrier(CLK_LOCAL_MEM_FENCE);
  for (int d = 0; d < MT_RADIX; ++d) c[d] = cnt[d * MT_WG + lid];
  const uint base = g * MT_TILE + lid * MT_ITEMS;
  for (int t = 0; t < MT_ITEMS; ++t) {
    const uint idx = base + t;
    if (idx < n) {
      const uint k = keys[idx];
      const uint pos = c[(k >> shift) & (MT_RADIX - 1)]++;
      outKeys[pos] = k;
      outValues[pos] = values[idx];
    }
  }
}

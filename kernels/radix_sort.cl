/* Stable LSD radix sort of (ulong key, uint value) pairs on the significant key bits only.
 * Multi-work-group pass = spx_sort_hist (per-block digit counts, digit-major so one exclusive
 * scan gives every (digit, block) its output start) → spx_scan_block/spx_scan_add (device-side
 * exclusive scan, recursive over block sums) → spx_sort_scatter (stable local ranking).
 * spx_sort_single does the whole sort in one work-group launch for small inputs.
 * Host side: lib/render/sort.c; reference: lib/render/sort_ref.c. */
#include "radix_sort.h"

/* Digit counts of this work-group's block (the keys spx_sort_scatter will rank), digit-major. */
__kernel __attribute__((reqd_work_group_size(SPX_SORT_WG, 1, 1))) void
spx_sort_hist(__global const ulong *keys, uint n, uint shift, uint dmask, __global uint *hist, uint nblocks) {
  __local uint cnt[SPX_RADIX * SPX_SORT_WG], tot[SPX_RADIX];
  uint lid = get_local_id(0), blk = get_group_id(0);
  for (uint d = 0; d < SPX_RADIX; d++) cnt[d * SPX_SORT_WG + lid] = 0;
  uint first = blk * SPX_SORT_BLOCK + lid * SPX_SORT_ITEMS;
  for (uint i = 0; i < SPX_SORT_ITEMS; i++)
    if (first + i < n) cnt[spx_digit(keys[first + i], shift) * SPX_SORT_WG + lid]++;
  barrier(CLK_LOCAL_MEM_FENCE);
  spx_sum_counts(cnt, tot);
  barrier(CLK_LOCAL_MEM_FENCE);
  for (uint d = lid; d < SPX_RADIX; d += SPX_SORT_WG) hist[d * nblocks + blk] = tot[d];
}

/* Exclusive scan of each SPX_SORT_BLOCK chunk of data in place; chunk totals go to sums[]. */
__kernel __attribute__((reqd_work_group_size(SPX_SORT_WG, 1, 1))) void
spx_scan_block(__global uint *data, uint n, __global uint *sums) {
  __local uint tmp[SPX_SORT_WG];
  uint lid = get_local_id(0);
  uint first = get_group_id(0) * SPX_SORT_BLOCK + lid * SPX_SORT_ITEMS;
  uint s = 0;
  for (uint i = 0; i < SPX_SORT_ITEMS; i++)
    if (first + i < n) s += data[first + i];
  uint tot;
  uint pre = spx_wg_scan_excl(tmp, s, &tot);
  for (uint i = 0; i < SPX_SORT_ITEMS; i++)
    if (first + i < n) {
      uint c = data[first + i];
      data[first + i] = pre;
      pre += c;
    }
  if (lid == 0) sums[get_group_id(0)] = tot;
}

__kernel void spx_scan_add(__global uint *data, uint n, __global const uint *sums) {
  uint j = get_global_id(0);
  if (j < n) data[j] += sums[j / SPX_SORT_BLOCK];
}

__kernel __attribute__((reqd_work_group_size(SPX_SORT_WG, 1, 1))) void
spx_sort_scatter(__global const ulong *ks, __global const uint *vs, uint n, uint shift, uint dmask, __global const uint *offs,
                 uint nblocks, __global ulong *kd, __global uint *vd) {
  __local uint cnt[SPX_RADIX * SPX_SORT_WG], tmp[SPX_SORT_WG], dbase[SPX_RADIX], adj[SPX_RADIX];
  uint lid = get_local_id(0), blk = get_group_id(0);
  for (uint d = lid; d < SPX_RADIX; d += SPX_SORT_WG) dbase[d] = offs[d * nblocks + blk];
  barrier(CLK_LOCAL_MEM_FENCE);
  spx_rank_scatter(ks, vs, n, blk * SPX_SORT_BLOCK, shift, dmask, kd, vd, cnt, tmp, dbase, adj);
}

__kernel __attribute__((reqd_work_group_size(SPX_SORT_WG, 1, 1))) void
spx_sort_single(__global ulong *ka, __global uint *va, __global ulong *kb, __global uint *vb, uint n, uint lo_bit,
                uint key_bits) {
  __local uint cnt[SPX_RADIX * SPX_SORT_WG], tmp[SPX_SORT_WG], dbase[SPX_RADIX], adj[SPX_RADIX];
  spx_sort_wg(ka, va, kb, vb, n, lo_bit, key_bits, cnt, tmp, dbase, adj);
}

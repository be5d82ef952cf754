/* Work-group building blocks of the LSD radix sort of (ulong key, uint value) pairs, shared by
 * kernels/radix_sort.cl and kernels/project.cl (which #include this file; the program loader
 * pastes it in). Tunables (lib/cl/tuning.c): SPX_SORT_BITS digit bits, SPX_SORT_WG work-items
 * per group, SPX_SORT_ITEMS keys per work-item. All functions must be reached by every
 * work-item of the group (they contain barriers). */
#ifndef SPX_RADIX_SORT_H
#define SPX_RADIX_SORT_H

#ifndef SPX_SORT_BITS
#define SPX_SORT_BITS 4
#endif
#ifndef SPX_SORT_WG
#define SPX_SORT_WG 64
#endif
#ifndef SPX_SORT_ITEMS
#define SPX_SORT_ITEMS 4
#endif
#define SPX_RADIX (1u << SPX_SORT_BITS)
#define SPX_SORT_BLOCK ((uint)(SPX_SORT_WG * SPX_SORT_ITEMS))

/* Digit of k at `shift`; the last pass masks off bits at and above key_bits (they are ignored). */
static inline uint spx_digit_mask(uint shift, uint key_bits) {
  return key_bits - shift >= SPX_SORT_BITS ? SPX_RADIX - 1u : (1u << (key_bits - shift)) - 1u;
}
#define spx_digit(k, shift) ((uint)((k) >> (shift)) & dmask)

/* Exclusive prefix sum of x over the work-group; *total gets the sum of all x. */
static inline uint spx_wg_scan_excl(__local uint *tmp, uint x, uint *total) {
  uint lid = get_local_id(0);
  tmp[lid] = x;
  barrier(CLK_LOCAL_MEM_FENCE);
  for (uint off = 1; off < SPX_SORT_WG; off <<= 1) {
    uint y = lid >= off ? tmp[lid - off] : 0u;
    barrier(CLK_LOCAL_MEM_FENCE);
    tmp[lid] += y;
    barrier(CLK_LOCAL_MEM_FENCE);
  }
  *total = tmp[SPX_SORT_WG - 1];
  uint r = tmp[lid] - x;
  barrier(CLK_LOCAL_MEM_FENCE);
  return r;
}

/* Stable scatter of the block [base, base + SPX_SORT_BLOCK) ∩ [0, n) of (ks, vs) by the digit
 * at `shift`. Work-item lid owns the SPX_SORT_ITEMS consecutive keys starting at base +
 * lid*SPX_SORT_ITEMS; each key's rank inside the block is (keys of smaller digits in the block)
 * + (keys of its digit owned by lower work-items) + (earlier keys of its digit in its own run),
 * from a scan of the per-(digit, work-item) counts laid out digit-major.
 * dbase[d] holds on entry the output position of the block's first key of digit d and is
 * advanced by the block's count of d on return (so consecutive blocks chain).
 * Local memory: cnt[SPX_RADIX * SPX_SORT_WG], tmp[SPX_SORT_WG], dbase/adj[SPX_RADIX]. */
static inline void spx_rank_scatter(__global const ulong *ks, __global const uint *vs, uint n, uint base, uint shift, uint dmask,
                             __global ulong *kd, __global uint *vd, __local uint *cnt, __local uint *tmp,
                             __local uint *dbase, __local uint *adj) {
  uint lid = get_local_id(0);
  for (uint d = 0; d < SPX_RADIX; d++) cnt[d * SPX_SORT_WG + lid] = 0;
  uint first = base + lid * SPX_SORT_ITEMS;
  for (uint i = 0; i < SPX_SORT_ITEMS; i++) {
    uint j = first + i;
    if (j < n) cnt[spx_digit(ks[j], shift) * SPX_SORT_WG + lid]++;
  }
  barrier(CLK_LOCAL_MEM_FENCE);
  /* exclusive scan of the flattened counts: work-item lid walks flat entries [lid*RADIX, +RADIX) */
  uint s = 0;
  for (uint e = 0; e < SPX_RADIX; e++) s += cnt[lid * SPX_RADIX + e];
  uint tot;
  uint pre = spx_wg_scan_excl(tmp, s, &tot);
  for (uint e = 0; e < SPX_RADIX; e++) {
    uint c = cnt[lid * SPX_RADIX + e];
    cnt[lid * SPX_RADIX + e] = pre;
    pre += c;
  }
  barrier(CLK_LOCAL_MEM_FENCE);
  for (uint d = lid; d < SPX_RADIX; d += SPX_SORT_WG) {
    uint sd = cnt[d * SPX_SORT_WG];
    uint ed = d + 1 < SPX_RADIX ? cnt[(d + 1) * SPX_SORT_WG] : tot;
    adj[d] = dbase[d] - sd; /* modular: adj + in-block rank = output position */
    dbase[d] += ed - sd;
  }
  barrier(CLK_LOCAL_MEM_FENCE);
  for (uint i = 0; i < SPX_SORT_ITEMS; i++) {
    uint j = first + i;
    if (j < n) {
      ulong k = ks[j];
      uint d = spx_digit(k, shift);
      uint pos = adj[d] + cnt[d * SPX_SORT_WG + lid]++;
      kd[pos] = k;
      vd[pos] = vs[j];
    }
  }
  barrier(CLK_LOCAL_MEM_FENCE);
}

/* Per-digit totals of the keys this work-group sees (each work-item counts its own keys into
 * column lid of cnt; no atomics), summed into tot[d]. Call after the counts are in cnt. */
static inline void spx_sum_counts(__local uint *cnt, __local uint *tot) {
  for (uint d = get_local_id(0); d < SPX_RADIX; d += SPX_SORT_WG) {
    uint s = 0;
    for (uint w = 0; w < SPX_SORT_WG; w++) s += cnt[d * SPX_SORT_WG + w];
    tot[d] = s;
  }
}

/* The whole stable LSD sort of n pairs by key bits [lo_bit, key_bits) inside ONE work-group,
 * ping-ponging between (ka, va) and (kb, vb); the result is left in (ka, va). */
static inline void spx_sort_wg(__global ulong *ka, __global uint *va, __global ulong *kb, __global uint *vb, uint n,
                        uint lo_bit, uint key_bits, __local uint *cnt, __local uint *tmp, __local uint *dbase,
                        __local uint *adj) {
  uint lid = get_local_id(0);
  uint pass = 0;
  for (uint shift = lo_bit; shift < key_bits; shift += SPX_SORT_BITS, pass++) {
    __global ulong *ks = (pass & 1u) ? kb : ka;
    __global uint *vs = (pass & 1u) ? vb : va;
    __global ulong *kd = (pass & 1u) ? ka : kb;
    __global uint *vd = (pass & 1u) ? va : vb;
    uint dmask = spx_digit_mask(shift, key_bits);
    for (uint d = 0; d < SPX_RADIX; d++) cnt[d * SPX_SORT_WG + lid] = 0;
    for (uint j = lid; j < n; j += SPX_SORT_WG) cnt[spx_digit(ks[j], shift) * SPX_SORT_WG + lid]++;
    barrier(CLK_LOCAL_MEM_FENCE);
    spx_sum_counts(cnt, dbase);
    barrier(CLK_LOCAL_MEM_FENCE);
    if (lid == 0) {
      uint run = 0;
      for (uint d = 0; d < SPX_RADIX; d++) {
        uint c = dbase[d];
        dbase[d] = run;
        run += c;
      }
    }
    barrier(CLK_LOCAL_MEM_FENCE);
    for (uint base = 0; base < n; base += SPX_SORT_BLOCK)
      spx_rank_scatter(ks, vs, n, base, shift, dmask, kd, vd, cnt, tmp, dbase, adj);
    barrier(CLK_GLOBAL_MEM_FENCE | CLK_LOCAL_MEM_FENCE);
  }
  if (pass & 1u) {
    for (uint j = lid; j < n; j += SPX_SORT_WG) {
      ka[j] = kb[j];
      va[j] = vb[j];
    }
    barrier(CLK_GLOBAL_MEM_FENCE);
  }
}

#endif

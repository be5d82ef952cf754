/* Private: stable LSD radix sort of (uint64 key, uint32 value) pairs on the device
 * (kernels/radix_sort.cl), and its plain-C reference. */
#ifndef SPX_RENDER_SORT_H
#define SPX_RENDER_SORT_H

#include "cl/cl_internal.h"

#define SPX_SORT_MAX_N 100000000u /* 10^8: far above the 10^7 the sort is sized for */
#define SPX_SORT_LEVELS 8

/* Scratch (grow-only) of one sorter; zero-initialise, release with spx_sorter_release. */
typedef struct spx_sorter {
  spx_cl_buf keys2, vals2; /* ping-pong partners */
  spx_cl_buf hist;         /* 2^bits x blocks digit counts, scanned in place */
  spx_cl_buf sums[SPX_SORT_LEVELS];
} spx_sorter;
void spx_sorter_release(spx_sorter *s);

typedef enum spx_sort_path { SPX_SORT_AUTO = 0, SPX_SORT_SINGLE = 1, SPX_SORT_MULTI = 2 } spx_sort_path;

/* Sort n pairs in place by key bits [lo_bit, key_bits) (0 <= lo_bit <= key_bits <= 64; other
 * bits are carried along but ignored), stable: equal sort bits keep their input order. AUTO picks the one-launch
 * single-work-group path up to the SPX_SORT_SINGLE_MAX tunable. Only enqueues work. */
spx_status spx_radix_sort(spx_ctx *ctx, spx_sorter *s, cl_mem keys, cl_mem vals, size_t n, int lo_bit, int key_bits,
                          spx_sort_path path);

/* Exclusive prefix sum of n uints in place on the device (uses s->sums). */
spx_status spx_scan_exclusive(spx_ctx *ctx, spx_sorter *s, cl_mem data, size_t n);

/* Reference: stable sort by key bits [lo_bit, key_bits) (qsort on (those bits, input position)). */
spx_status spx_radix_sort_ref(spx_ctx *ctx, uint64_t *keys, uint32_t *vals, size_t n, int lo_bit, int key_bits);

#endif

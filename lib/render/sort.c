/* Host side of the device radix sort (kernels/radix_sort.cl): pass loop, device-side scan,
 * and the single-work-group fast path. */
#include "render/sort.h"

void spx_sorter_release(spx_sorter *s) {
  if (!s) return;
  spx_cl_buf_release(&s->keys2);
  spx_cl_buf_release(&s->vals2);
  spx_cl_buf_release(&s->hist);
  for (int i = 0; i < SPX_SORT_LEVELS; i++) spx_cl_buf_release(&s->sums[i]);
}

static spx_status scan_level(spx_ctx *ctx, spx_sorter *s, cl_mem data, cl_uint n, int level) {
  if (level >= SPX_SORT_LEVELS) return spx_fail(ctx, SPX_E_ARG, "spx_scan_exclusive: too many elements");
  size_t wg = (size_t)ctx->dev->tune.sort_wg, block = wg * (size_t)ctx->dev->tune.sort_items;
  cl_uint nb = (cl_uint)((n + block - 1) / block);
  spx_status st = spx_cl_buf_ensure(ctx, &s->sums[level], (size_t)nb * sizeof(cl_uint), "radix sort scan sums");
  if (st) return st;
  cl_kernel kb, ka;
  if ((st = spx_cl_kernel(ctx, SPX_K_SCAN_BLOCK, &kb))) return st;
  if ((st = spx_cl_kernel(ctx, SPX_K_SCAN_ADD, &ka))) return st;
  cl_mem sums = s->sums[level].mem;
  cl_int e = SPX_ARG(kb, 0, data) | SPX_ARG(kb, 1, n) | SPX_ARG(kb, 2, sums);
  if ((st = spx_cl_check(ctx, e, "spx_scan_block args"))) return st;
  size_t g = (size_t)nb * wg;
  if ((st = spx_cl_run(ctx, kb, 1, &g, &wg, "spx_scan_block"))) return st;
  if (nb <= 1) return SPX_OK;
  if ((st = scan_level(ctx, s, sums, nb, level + 1))) return st;
  e = SPX_ARG(ka, 0, data) | SPX_ARG(ka, 1, n) | SPX_ARG(ka, 2, sums);
  if ((st = spx_cl_check(ctx, e, "spx_scan_add args"))) return st;
  size_t ga = n, la = (size_t)ctx->dev->tune.wg;
  return spx_cl_run(ctx, ka, 1, &ga, &la, "spx_scan_add");
}

spx_status spx_scan_exclusive(spx_ctx *ctx, spx_sorter *s, cl_mem data, size_t n) {
  if (n > SPX_SORT_MAX_N * 256u) return spx_fail(ctx, SPX_E_ARG, "spx_scan_exclusive: %zu elements is too many", n);
  if (n == 0) return SPX_OK;
  return scan_level(ctx, s, data, (cl_uint)n, 0);
}

spx_status spx_radix_sort(spx_ctx *ctx, spx_sorter *s, cl_mem keys, cl_mem vals, size_t n, int lo_bit, int key_bits,
                          spx_sort_path path) {
  spx_status st = spx_cl_require(ctx, "spx_radix_sort");
  if (st) return st;
  if (key_bits < 0 || key_bits > 64 || lo_bit < 0 || lo_bit > key_bits)
    return spx_fail(ctx, SPX_E_ARG, "spx_radix_sort: key bits [%d, %d) not within 0..64", lo_bit, key_bits);
  if (n > SPX_SORT_MAX_N)
    return spx_fail(ctx, SPX_E_ARG, "spx_radix_sort: %zu keys is more than the supported %u", n, SPX_SORT_MAX_N);
  if (n < 2 || key_bits == lo_bit) return SPX_OK;
  int bits = ctx->dev->tune.sort_bits;
  size_t wg = (size_t)ctx->dev->tune.sort_wg, block = wg * (size_t)ctx->dev->tune.sort_items;
  if (path == SPX_SORT_AUTO) path = n <= (size_t)ctx->dev->tune.sort_single_max ? SPX_SORT_SINGLE : SPX_SORT_MULTI;
  if ((st = spx_cl_buf_ensure(ctx, &s->keys2, n * sizeof(cl_ulong), "radix sort keys"))) return st;
  if ((st = spx_cl_buf_ensure(ctx, &s->vals2, n * sizeof(cl_uint), "radix sort values"))) return st;
  cl_uint un = (cl_uint)n, ubits = (cl_uint)key_bits, ulo = (cl_uint)lo_bit;
  cl_int e;
  if (path == SPX_SORT_SINGLE) {
    cl_kernel k;
    if ((st = spx_cl_kernel(ctx, SPX_K_SORT_SINGLE, &k))) return st;
    e = SPX_ARG(k, 0, keys) | SPX_ARG(k, 1, vals) | SPX_ARG(k, 2, s->keys2.mem) | SPX_ARG(k, 3, s->vals2.mem) |
        SPX_ARG(k, 4, un) | SPX_ARG(k, 5, ulo) | SPX_ARG(k, 6, ubits);
    if ((st = spx_cl_check(ctx, e, "spx_sort_single args"))) return st;
    return spx_cl_run(ctx, k, 1, &wg, &wg, "spx_sort_single");
  }
  cl_uint nb = (cl_uint)((n + block - 1) / block);
  size_t radix = (size_t)1 << bits;
  if ((st = spx_cl_buf_ensure(ctx, &s->hist, radix * nb * sizeof(cl_uint), "radix sort histogram"))) return st;
  cl_kernel kh, ks;
  if ((st = spx_cl_kernel(ctx, SPX_K_SORT_HIST, &kh))) return st;
  if ((st = spx_cl_kernel(ctx, SPX_K_SORT_SCATTER, &ks))) return st;
  cl_mem a_k = keys, a_v = vals, b_k = s->keys2.mem, b_v = s->vals2.mem;
  size_t g = (size_t)nb * wg;
  int pass = 0;
  for (cl_uint shift = ulo; shift < ubits; shift += (cl_uint)bits, pass++) {
    cl_uint left = (cl_uint)key_bits - shift;
    cl_uint dmask = left >= (cl_uint)bits ? (cl_uint)radix - 1u : (1u << left) - 1u;
    e = SPX_ARG(kh, 0, a_k) | SPX_ARG(kh, 1, un) | SPX_ARG(kh, 2, shift) | SPX_ARG(kh, 3, dmask) |
        SPX_ARG(kh, 4, s->hist.mem) | SPX_ARG(kh, 5, nb);
    if ((st = spx_cl_check(ctx, e, "spx_sort_hist args"))) return st;
    if ((st = spx_cl_run(ctx, kh, 1, &g, &wg, "spx_sort_hist"))) return st;
    if ((st = spx_scan_exclusive(ctx, s, s->hist.mem, radix * nb))) return st;
    e = SPX_ARG(ks, 0, a_k) | SPX_ARG(ks, 1, a_v) | SPX_ARG(ks, 2, un) | SPX_ARG(ks, 3, shift) |
        SPX_ARG(ks, 4, dmask) | SPX_ARG(ks, 5, s->hist.mem) | SPX_ARG(ks, 6, nb) | SPX_ARG(ks, 7, b_k) |
        SPX_ARG(ks, 8, b_v);
    if ((st = spx_cl_check(ctx, e, "spx_sort_scatter args"))) return st;
    if ((st = spx_cl_run(ctx, ks, 1, &g, &wg, "spx_sort_scatter"))) return st;
    cl_mem t = a_k;
    a_k = b_k;
    b_k = t;
    t = a_v;
    a_v = b_v;
    b_v = t;
  }
  if (pass & 1) {
    if ((st = spx_cl_copy(ctx, a_k, keys, 0, 0, n * sizeof(cl_ulong), "radix sort copy keys")) ||
        (st = spx_cl_copy(ctx, a_v, vals, 0, 0, n * sizeof(cl_uint), "radix sort copy values")))
      return st;
  }
  return SPX_OK;
}

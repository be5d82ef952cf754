/* What the convolution algorithms share: the padded / dilated copy of an input in a workspace
 * slot (kernels/conv2d.cl's spx_conv2d_pad) and the prepared weights an inference convolution
 * keeps between calls (spx_conv2d_wprep, lib/nn/conv2d.h). */
#include "nn/conv2d_internal.h"

/* Padded/dilated copy of src [nc][h][w] into a new scratch buffer (see spx_conv2d_pad). */
spx_status spx_conv2d_pad_copy(spx_ctx *ctx, spx_op_workspace *ws, int slot, cl_mem src, size_t src_off, int nc,
                               int h, int w, int hp, int wp, int plane, int top, int left, int d, size_t total,
                               spx_op_scratch *out) {
  cl_kernel k;
  spx_status st = spx_cl_kernel(ctx, SPX_K_CONV2D_PAD, &k);
  if (st) return st;
  if ((st = spx_op_scratch_get(ctx, ws, slot, total * sizeof(float), "conv2d padded scratch", out))) return st;
  cl_ulong so = src_off;
  cl_int e = SPX_ARG(k, 0, src) | SPX_ARG(k, 1, so) | SPX_ARG(k, 2, out->mem) | SPX_ARG(k, 3, h) | SPX_ARG(k, 4, w) |
             SPX_ARG(k, 5, hp) | SPX_ARG(k, 6, wp) | SPX_ARG(k, 7, plane) | SPX_ARG(k, 8, top) |
             SPX_ARG(k, 9, left) | SPX_ARG(k, 10, d);
  if ((st = spx_cl_check(ctx, e, "spx_conv2d_pad args"))) return st;
  size_t gl[3] = {(size_t)wp, ((size_t)plane + wp - 1) / wp, (size_t)nc};
  size_t lo[3] = {(size_t)ctx->dev->tune.wg, 1, 1};
  if ((size_t)wp < lo[0]) lo[0] = (size_t)wp;
  if ((st = spx_cl_run(ctx, k, 3, gl, lo, "spx_conv2d_pad"))) return st;
  size_t used = (size_t)nc * plane;
  return spx_cl_fill_f32(ctx, out->mem, used, total - used, 0.0f);
}

void spx_conv2d_wprep_release(spx_conv2d_wprep *wp) {
  if (!wp) return;
  spx_cl_free(&wp->mem);
  wp->cap = 0, wp->key = 0;
}

spx_status spx_conv2d_wprep_lookup(spx_ctx *ctx, spx_conv2d_wprep *wp, const int *what, int nwhat,
                                   const spx_tensor *w, size_t bytes, int *hit, cl_mem *mem) {
  uint64_t key = spx_hash64(what, (size_t)nwhat * sizeof(int), 0x9e3779b97f4a7c15ull);
  cl_mem wm = w->mem;
  size_t wo = w->off;
  key = spx_hash64(&wm, sizeof wm, key);
  key = spx_hash64(&wo, sizeof wo, key);
  key |= 1; /* never 0 */
  *hit = wp->key == key && wp->mem && wp->cap >= bytes;
  if (!*hit) {
    wp->key = 0;
    if (wp->cap < bytes) {
      spx_cl_free(&wp->mem);
      wp->cap = 0;
      spx_status st = spx_cl_alloc(ctx, bytes, "conv2d prepared weights", &wp->mem);
      if (st) return st;
      wp->cap = bytes;
    }
  }
  *mem = wp->mem;
  if (!*hit) wp->key = key; /* valid once the caller's enqueued preparation runs */
  return SPX_OK;
}

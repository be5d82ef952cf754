/* Local-memory tiled 3x3 stride-1 forward (kernels/conv2d_lds.cl) for GPU-class devices: when it
 * applies and its launch shape. lib/nn/conv2d.c's run_fwd sets the arguments (the kernel takes the
 * direct kernel's) and launches it in place of spx_conv2d_fwd_k3s1, so the forward and the
 * backward-data convolutions both use it. */
#include "nn/conv2d.h"

int spx_conv2d_lds_applies(const spx_ctx *ctx, int k, int stride) {
  const struct spx_tunables *t = &ctx->dev->tune;
  if (k != 3 || stride != 1 || !t->conv_lds || t->conv_vw != 1) return 0;
  int lws = t->conv_lws, tx = t->conv_lds_tx, tn = t->conv_tn, cb = t->conv_lds_cb, tm = t->conv_tm;
  if (tx < 1 || lws % tx) return 0;
  uint64_t local = 4ull * cb * ((uint64_t)(lws / tx * tn + 2) * (tx + 2) + 9ull * tm);
  return local <= ctx->dev->info.local_mem;
}

size_t spx_conv2d_lds_groups(const spx_ctx *ctx, int coutp, int ho, int wo) {
  const struct spx_tunables *t = &ctx->dev->tune;
  int tx = t->conv_lds_tx, ty = t->conv_lws / tx * t->conv_tn, tm = t->conv_tm;
  return (size_t)(coutp / tm) * (size_t)((wo + tx - 1) / tx) * (size_t)((ho + ty - 1) / ty);
}

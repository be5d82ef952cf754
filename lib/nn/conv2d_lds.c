/* Local-memory tiled 3x3 stride-1 forward (kernels/conv2d_lds.cl) for GPU-class devices: when it
 * applies, which of its two kernels runs and its launch shape. lib/nn/conv2d_direct.c's run_fwd sets the
 * arguments (the kernels take the direct kernel's) and launches it in place of
 * spx_conv2d_fwd_k3s1, so the forward and the backward-data convolutions both use it.
 *   CONV_LDS = 1: tiles of CONV_LDS_TX columns x CONV_LWS / CONV_LDS_TX * CONV_TN rows, one
 *                 channel tile of CONV_TM outputs per work-group (spx_conv2d_fwd_k3s1_lds);
 *   CONV_LDS = 2: a work-item's CONV_TN outputs are adjacent columns; tiles of CONV_LDS_TX
 *                 columns x (CONV_LWS / CONV_LDS_CG) / (CONV_LDS_TX / CONV_TN) rows and
 *                 CONV_LDS_CG channel tiles per work-group (spx_conv2d_fwd_k3s1_lds2). */
#include "nn/conv2d.h"

/* Tile of the selected kernel: columns, rows, channel tiles per group; 0 when the tunables do
 * not make one (the kernel is then not compiled: see its #if). */
typedef struct lds_tile {
  int tx, ty, cg;
} lds_tile;

static lds_tile tile_of(const struct spx_tunables *t) {
  lds_tile r = {0, 0, 0};
  int lws = t->conv_lws, tx = t->conv_lds_tx, tn = t->conv_tn;
  if (tx < 1 || tn < 1) return r;
  if (t->conv_lds == 1) {
    if (lws % tx == 0) r = (lds_tile){tx, lws / tx * tn, 1};
  } else if (t->conv_lds == 2) {
    int cg = t->conv_lds_cg, pt = cg > 0 && lws % cg == 0 ? lws / cg : 0, px = tx % tn == 0 ? tx / tn : 0;
    if (pt > 0 && px > 0 && pt % px == 0) r = (lds_tile){tx, pt / px, cg};
  }
  return r;
}

int spx_conv2d_lds_applies(const spx_ctx *ctx, int k, int stride) {
  const struct spx_tunables *t = &ctx->dev->tune;
  if (k != 3 || stride != 1 || !t->conv_lds || t->conv_vw != 1) return 0;
  lds_tile L = tile_of(t);
  if (!L.tx) return 0;
  uint64_t local = 4ull * t->conv_lds_cb * ((uint64_t)(L.ty + 2) * (L.tx + 2) + 9ull * t->conv_tm * L.cg);
  return local <= ctx->dev->info.local_mem;
}

spx_kernel_id spx_conv2d_lds_kernel(const spx_ctx *ctx) {
  return ctx->dev->tune.conv_lds == 2 ? SPX_K_CONV2D_FWD_K3S1_LDS2 : SPX_K_CONV2D_FWD_K3S1_LDS;
}

size_t spx_conv2d_lds_groups(const spx_ctx *ctx, int coutp, int ho, int wo) {
  const struct spx_tunables *t = &ctx->dev->tune;
  lds_tile L = tile_of(t);
  if (!L.tx) return 0;
  size_t ncot = (size_t)(coutp / t->conv_tm), chan = (ncot + (size_t)L.cg - 1) / (size_t)L.cg;
  return chan * (size_t)((wo + L.tx - 1) / L.tx) * (size_t)((ho + L.ty - 1) / L.ty);
}

/* The convolution algorithms as a table (lib/nn/conv2d_internal.h): one row per algorithm, in the
 * order spx_conv2d_choose tries them, with the Winograd rows' adapters to their launchers. Which
 * rows apply follows the tunables (lib/cl/tuning.c), so `smplpix tune` searches over the rows
 * through them: CONV_WINO_MINC / CONV_WINO_TRAIN / CONV_WINO_LDS / CONV_WINO_DW (Winograd),
 * CONV_THIN_MAXC, CONV_GEMM, CONV_LDS; the direct row applies to everything.
 *
 * Class defaults (benchmarks/RESULTS.md has the measurements): the CPU class runs Winograd for
 * wide 3x3 layers and the register tiles for the rest; the GPU class runs every stride-1 pass
 * on the GEMM engine and the 1x1 output layer on the bandwidth kernel, the direct kernels for
 * the rest (strided forwards and weight gradients). */
#include <string.h>

#include "nn/conv2d_internal.h"

/* ---- Winograd rows (lib/nn/conv2d_winograd*.c) ---- */

/* the forward asks with the layer's channels; the data gradient is the conv of dy (channels swapped) */
static int wino_applies(const spx_ctx *ctx, const spx_conv2d_shape *s, int pass, int inference) {
  const int fwd = pass == SPX_CONV_PASS_FWD;
  const int ho = spx_conv2d_out_size(s->h, s->k, s->stride, s->pad), wo = spx_conv2d_out_size(s->w, s->k, s->stride, s->pad);
  return fwd ? spx_conv2d_winograd_applies(ctx, s->k, s->stride, s->pad, s->cin, s->cout, ho * wo, inference)
             : spx_conv2d_winograd_applies(ctx, s->k, s->stride, s->pad, s->cout, s->cin, s->h * s->w, 0);
}
static int wino_fused_applies(const spx_ctx *ctx, const spx_conv2d_shape *s, int pass, int inference) {
  return spx_conv2d_winograd_lds_applies(ctx) && wino_applies(ctx, s, pass, inference);
}
static int wino_split_applies(const spx_ctx *ctx, const spx_conv2d_shape *s, int pass, int inference) {
  return !spx_conv2d_winograd_lds_applies(ctx) && wino_applies(ctx, s, pass, inference);
}

/* (3x3 stride-1 pad-1: the output is the input's size) */
static void wino_need(const spx_ctx *ctx, const spx_conv2d_shape *s, int pass, spx_ws_need *need) {
  const int fwd = pass == SPX_CONV_PASS_FWD;
  spx_conv2d_winograd_need(ctx, s->n, fwd ? s->cin : s->cout, s->h, s->w, fwd ? s->cout : s->cin, need);
}

static spx_status wino_run(spx_ctx *ctx, const spx_conv_job *j) {
  if (j->pass == SPX_CONV_PASS_FWD)
    return spx_conv2d_winograd(ctx, j->ws, j->x, j->w, 0, j->bias, j->scale, j->scale ? j->shift : NULL, j->relu, 0,
                               j->out, j->prep);
  return spx_conv2d_winograd(ctx, j->ws, j->dy, j->w, 1, NULL, NULL, NULL, 0, 1, j->out, NULL);
}

static int wino_dw_applies(const spx_ctx *ctx, const spx_conv2d_shape *s, int pass, int inference) {
  (void)pass, (void)inference;
  return spx_conv2d_winograd_dw_applies(ctx, s->k, s->stride, s->pad, s->cin, s->cout, s->h, s->w);
}

static void wino_dw_need(const spx_ctx *ctx, const spx_conv2d_shape *s, int pass, spx_ws_need *need) {
  (void)pass;
  size_t b[3];
  spx_conv2d_winograd_dw_need(ctx, s->n, s->cin, s->cout, s->h, s->w, b);
  memset(need, 0, sizeof *need);
  for (int i = 0; i < 3; i++) need->slot[i] = b[i];
}

static spx_status wino_dw_run(spx_ctx *ctx, const spx_conv_job *j) {
  return spx_conv2d_winograd_dw(ctx, j->ws, j->x, j->dy, j->out);
}

static const spx_conv_algo_row row_wino_fused = {"winograd_fused", SPX_CONV_PASS_FWD | SPX_CONV_PASS_BWD_DATA,
                                                 wino_fused_applies, wino_need, wino_run};
static const spx_conv_algo_row row_wino = {"winograd", SPX_CONV_PASS_FWD | SPX_CONV_PASS_BWD_DATA, wino_split_applies,
                                           wino_need, wino_run};
static const spx_conv_algo_row row_wino_dw = {"winograd_dw", SPX_CONV_PASS_BWD_WEIGHTS, wino_dw_applies, wino_dw_need,
                                              wino_dw_run};

/* ---- the table ---- */

/* by spx_conv_algo id, in the order spx_conv2d_choose tries them */
static const spx_conv_algo_row *const rows[SPX_CONV_ALGO_COUNT] = {
    [SPX_CONV_ALGO_WINO_FUSED] = &row_wino_fused, [SPX_CONV_ALGO_WINO] = &row_wino,
    [SPX_CONV_ALGO_WINO_DW] = &row_wino_dw,       [SPX_CONV_ALGO_THIN] = &spx_conv_row_thin,
    [SPX_CONV_ALGO_GEMM] = &spx_conv_row_gemm,    [SPX_CONV_ALGO_LDS] = &spx_conv_row_lds,
    [SPX_CONV_ALGO_DIRECT] = &spx_conv_row_direct,
};

const spx_conv_algo_row *spx_conv2d_row(int algo) {
  return algo > SPX_CONV_ALGO_AUTO && algo < SPX_CONV_ALGO_COUNT ? rows[algo] : NULL;
}

const char *spx_conv2d_algo_name(int algo) {
  const spx_conv_algo_row *r = spx_conv2d_row(algo);
  return r ? r->name : NULL;
}

int spx_conv2d_choose(const spx_ctx *ctx, const spx_conv2d_shape *s, int pass, int inference) {
  for (int a = SPX_CONV_ALGO_AUTO + 1; a < SPX_CONV_ALGO_COUNT; a++)
    if ((rows[a]->passes & pass) && rows[a]->applies(ctx, s, pass, inference)) return a;
  return SPX_CONV_ALGO_DIRECT; /* (it applies to every shape and pass) */
}

void spx_conv2d_workspace_need(const spx_ctx *ctx, const spx_conv2d_shape *s, int passes, int inference,
                               const int *algo, spx_ws_need *need) {
  memset(need, 0, sizeof *need);
  if (s->n < 1 || s->cin < 1 || s->cout < 1 || s->k < 1 || s->stride < 1 || s->pad < 0 || s->pad >= s->k) return;
  if (spx_conv2d_out_size(s->h, s->k, s->stride, s->pad) < 1 || spx_conv2d_out_size(s->w, s->k, s->stride, s->pad) < 1)
    return;
  for (int pass = SPX_CONV_PASS_FWD; pass <= SPX_CONV_PASS_BWD_WEIGHTS; pass <<= 1) {
    if (!(passes & pass)) continue;
    const int inf = pass == SPX_CONV_PASS_FWD && inference, given = algo ? algo[spx_conv2d_pass_index(pass)] : 0;
    const spx_conv_algo_row *r = spx_conv2d_row(given ? given : spx_conv2d_choose(ctx, s, pass, inf));
    if (!r || !(r->passes & pass)) continue; /* the launcher refuses it */
    spx_ws_need one;
    r->need(ctx, s, pass, &one);
    spx_ws_need_max(need, &one);
  }
}

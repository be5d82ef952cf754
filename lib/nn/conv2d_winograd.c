/* Winograd F(4x4,3x3) convolution: launchers for kernels/conv2d_winograd.cl (the four stages and
 * the buffer layouts are described at the top of the kernel file). Called by the table
 * (lib/nn/conv2d_algo.c) for the forward and backward-data convolutions of 3x3 / stride 1 / pad 1
 * layers. Scratch: the caller's workspace slots 0 (M, the products), 1 (U, transformed weights),
 * 2 (V, transformed input), else buffers allocated per call and released after enqueueing. On
 * the GPU class with the GEMM engine (CONV_GEMM) and input channels a whole number of its slices,
 * a sample's 36 GEMMs are one strided-batched launch of the engine (spx_conv2d_gemm_batched,
 * kernels/conv2d_gemm.cl) on U packed as [e][ci][Coutp] (spx_gemm_wino_pack). */
#include <limits.h>
#include <string.h>

#include "nn/conv2d_internal.h"

int spx_conv2d_winograd_applies(const spx_ctx *ctx, int k, int stride, int pad, int cin, int cout, int hw,
                                int inference) {
  int minc = ctx->dev->tune.conv_wino_minc;
  if (!inference && !ctx->dev->tune.conv_wino_train) return 0;
  /* small images: the transforms' scratch stays in cache, so fewer channels pay (inference only:
   * training keeps one rule for its forward, data and weight gradients) */
  if (inference && hw <= ctx->dev->tune.conv_wino_small_hw) minc = (minc + 1) / 2;
  return minc > 0 && k == 3 && stride == 1 && pad == 1 && cin >= minc && cout >= minc;
}

void spx_conv2d_wino_tiles(const spx_ctx *ctx, int h, int w, int *th, int *twp) {
  const int vw = ctx->dev->tune.conv_vw, tw = (w + 3) / 4;
  *th = (h + 3) / 4, *twp = (tw + vw - 1) / vw * vw;
}

/* Tile geometry and scratch of one call: spx_conv2d_winograd and spx_conv2d_winograd_need size
 * the slots from this alone. */
typedef struct wlay {
  int th, tw, twp, tws, T, coutp, nb;
  int engine; /* the 36 GEMMs on the GEMM engine (GPU class, CONV_GEMM; input channels a whole number of slices) */
  size_t quantum, tp, f0, f2;
  spx_ws_need need;
} wlay;

static void layout(const spx_ctx *ctx, int n, int cin, int h, int wd, int cout, wlay *L) {
  const int tm = ctx->dev->tune.conv_tm, tn = ctx->dev->tune.conv_tn, vw = ctx->dev->tune.conv_vw;
  const int lws = ctx->dev->tune.conv_lws;
  /* tiles: TH rows of TWp (TW rounded up to the vector width, so a vector of tiles is one row);
   * stored (the GEMM's columns) TWs to a row: TWp, or packed (TWs = TW, CONV_WINO_PACK) where the
   * rounding would add more than 10% */
  spx_conv2d_wino_tiles(ctx, h, wd, &L->th, &L->twp);
  L->tw = (wd + 3) / 4, L->tws = L->twp;
  if (ctx->dev->tune.conv_wino_pack && 10 * (L->twp - L->tw) > L->twp) L->tws = L->tw;
  L->T = L->th * L->tws;
  L->quantum = (size_t)lws * tn * vw;
  L->tp = ((size_t)L->T + L->quantum - 1) / L->quantum * L->quantum;
  L->engine = ctx->dev->tune.conv_gemm && cin % ctx->dev->tune.conv_gemm_ks == 0;
  const int cm = L->engine ? ctx->dev->tune.conv_gemm_bm : tm; /* the GEMM's column tile */
  L->coutp = (cout + cm - 1) / cm * cm;
  /* per sample: slot 0 holds the products M, slot 2 V */
  L->f0 = (size_t)36 * L->coutp * L->tp;
  L->f2 = (size_t)36 * cin * L->tp;
  /* samples per pass: the scratch is sized for as many as fit in CONV_WINO_CHUNK x 2^20 floats (at
   * least one), so a batch-4 training step does not hold 4x the largest layer's transforms; each
   * sample's arithmetic is the same whatever the chunk, so results do not depend on it */
  int nb = (int)(((size_t)ctx->dev->tune.conv_wino_chunk << 20) / (L->f0 + L->f2));
  L->nb = nb < 1 ? 1 : nb > n ? n : nb;
  memset(&L->need, 0, sizeof L->need);
  L->need.slot[0] = L->nb * L->f0 * sizeof(float);
  L->need.slot[1] = (size_t)36 * cin * L->coutp * sizeof(float);
  L->need.slot[2] = L->nb * L->f2 * sizeof(float);
}

void spx_conv2d_winograd_need(const spx_ctx *ctx, int n, int cin, int h, int w, int cout, spx_ws_need *need) {
  if (spx_conv2d_winograd_lds_applies(ctx)) { /* as spx_conv2d_winograd dispatches */
    spx_conv2d_winograd_lds_need(ctx, cin, cout, need);
    return;
  }
  wlay L;
  layout(ctx, n, cin, h, w, cout, &L);
  *need = L.need;
}

spx_status spx_conv2d_wino_input(spx_ctx *ctx, const spx_tensor *x, int s0, int m, int tws, int Tp, cl_mem V) {
  const int cin = x->c, h = x->h, wd = x->w, vw = ctx->dev->tune.conv_vw;
  int th, twp;
  spx_conv2d_wino_tiles(ctx, h, wd, &th, &twp);
  const int T = th * tws;
  cl_kernel kin;
  spx_status st;
  if ((st = spx_cl_kernel(ctx, SPX_K_WINO_IN, &kin))) return st;
  cl_ulong xo = x->off + (size_t)s0 * cin * h * wd;
  cl_int e = SPX_ARG(kin, 0, x->mem) | SPX_ARG(kin, 1, xo) | SPX_ARG(kin, 2, V) | SPX_ARG(kin, 3, cin) |
             SPX_ARG(kin, 4, h) | SPX_ARG(kin, 5, wd) | SPX_ARG(kin, 6, twp) | SPX_ARG(kin, 7, T) | SPX_ARG(kin, 8, Tp) |
             SPX_ARG(kin, 9, tws);
  if ((st = spx_cl_check(ctx, e, "spx_wino_in args"))) return st;
  /* one work-item per CONV_VW tiles of a tile row (row-padded grid); row-padded storage (tws =
   * twp) also zeroes the GEMM's padding columns up to Tp */
  size_t groups = (size_t)th * (size_t)(twp / vw), cols = (size_t)Tp / (size_t)vw;
  size_t gi[3] = {groups > cols ? groups : cols, (size_t)cin, (size_t)m}, li[3] = {1, 1, 1};
  return spx_cl_run(ctx, kin, 3, gi, vw > 1 ? li : NULL, "spx_wino_in");
}

spx_status spx_conv2d_winograd(spx_ctx *ctx, spx_op_workspace *ws, const spx_tensor *x, const spx_tensor *w,
                               int flip, const spx_tensor *bias, const spx_tensor *scale, const spx_tensor *shift,
                               int relu, int accumulate, const spx_tensor *y, spx_conv2d_wprep *wp) {
  if (spx_conv2d_winograd_lds_applies(ctx)) /* GPU class: the fused local-memory variant */
    return spx_conv2d_winograd_lds(ctx, ws, x, w, flip, bias, scale, shift, relu, accumulate, y);
  const int n = x->n, cin = x->c, h = x->h, wd = x->w, cout = y->c;
  const int Cout = w->n, Cin = w->c; /* the weight tensor's own dimensions */
  const int tm = ctx->dev->tune.conv_tm, vw = ctx->dev->tune.conv_vw, lws = ctx->dev->tune.conv_lws;
  wlay L;
  layout(ctx, n, cin, h, wd, cout, &L);
  const int twp = L.twp, tws = L.tws, T = L.T, coutp = L.coutp, nb = L.nb;
  const size_t quantum = L.quantum, tp = L.tp;
  const double vmax = 36.0 * nb * (double)(cin > coutp ? cin : coutp) * (double)tp;
  if (vmax > (double)INT_MAX)
    return spx_fail(ctx, SPX_E_UNSUPPORTED, "conv2d winograd: %.0f transformed elements exceed the index range", vmax);
  const int Tp = (int)tp;
  spx_op_scratch XM = {0}, U = {0}, V = {0};
  int have_u = 0; /* U already in wp (prepared weights kept between inference calls) */
  spx_status st;
  cl_kernel kw, kg, ko;
  if ((st = spx_cl_kernel(ctx, SPX_K_WINO_WEIGHTS, &kw)) ||
      (st = spx_cl_kernel(ctx, SPX_K_WINO_GEMM, &kg)) ||
      (st = spx_cl_kernel(ctx, SPX_K_WINO_OUT, &ko)))
    return st;
  if (wp) {
    const int what[] = {2, Cout, Cin, coutp, tm, flip, L.engine};
    if ((st = spx_conv2d_wprep_lookup(ctx, wp, what, 7, w, L.need.slot[1], &have_u, &U.mem))) goto done;
  }
  if ((st = spx_op_scratch_get(ctx, ws, 0, L.need.slot[0], "winograd products", &XM)) ||
      (!wp && (st = spx_op_scratch_get(ctx, ws, 1, L.need.slot[1], "winograd weight transform", &U))) ||
      (st = spx_op_scratch_get(ctx, ws, 2, L.need.slot[2], "winograd input transform", &V)))
    goto done;
  const size_t wg = (size_t)ctx->dev->tune.wg;
  if (!have_u && L.engine) { /* U[e][ci][coutp] */
    if ((st = spx_cl_kernel(ctx, SPX_K_GEMM_WINO_PACK, &kw))) goto done;
    cl_ulong wo = w->off;
    cl_int e = SPX_ARG(kw, 0, w->mem) | SPX_ARG(kw, 1, wo) | SPX_ARG(kw, 2, U.mem) | SPX_ARG(kw, 3, Cout) |
               SPX_ARG(kw, 4, Cin) | SPX_ARG(kw, 5, coutp) | SPX_ARG(kw, 6, flip);
    size_t gl = (size_t)cin * coutp;
    if ((st = spx_cl_check(ctx, e, "spx_gemm_wino_pack args")) ||
        (st = spx_cl_run(ctx, kw, 1, &gl, &wg, "spx_gemm_wino_pack")))
      goto done;
  } else if (!have_u) {
    cl_ulong wo = w->off;
    cl_int e = SPX_ARG(kw, 0, w->mem) | SPX_ARG(kw, 1, wo) | SPX_ARG(kw, 2, U.mem) | SPX_ARG(kw, 3, Cout) |
               SPX_ARG(kw, 4, Cin) | SPX_ARG(kw, 5, coutp) | SPX_ARG(kw, 6, flip);
    if ((st = spx_cl_check(ctx, e, "spx_wino_weights args"))) goto done;
    size_t gl = (size_t)cin * (coutp / tm);
    if ((st = spx_cl_run(ctx, kw, 1, &gl, &wg, "spx_wino_weights"))) goto done;
  }
  for (int s0 = 0; s0 < n; s0 += nb) {
    const int m = n - s0 < nb ? n - s0 : nb; /* samples in this pass */
    if ((st = spx_conv2d_wino_input(ctx, x, s0, m, tws, Tp, V.mem))) goto done;
    for (int i = 0; L.engine && i < m; i++) /* M[i][e] = U[e]^T V[i][.][e]: 36 GEMMs of a sample, one launch */
      if ((st = spx_conv2d_gemm_batched(ctx, U.mem, V.mem, (size_t)i * cin * 36 * tp, XM.mem, (size_t)i * 36 * coutp * tp,
                                        cin, cout, coutp, Tp, 36 * Tp, 36, (size_t)cin * coutp, tp,
                                        (size_t)coutp * tp)))
        goto done;
    if (!L.engine) {
      cl_int e = SPX_ARG(kg, 0, V.mem) | SPX_ARG(kg, 1, U.mem) | SPX_ARG(kg, 2, XM.mem) | SPX_ARG(kg, 3, cin) |
                 SPX_ARG(kg, 4, coutp) | SPX_ARG(kg, 5, Tp);
      if ((st = spx_cl_check(ctx, e, "spx_wino_gemm args"))) goto done;
      size_t gl[2] = {(size_t)(coutp / tm) * (tp / quantum) * lws, (size_t)m * 36}, lo[2] = {(size_t)lws, 1};
      if ((st = spx_cl_run(ctx, kg, 2, gl, lo, "spx_wino_gemm"))) goto done;
    }
    {
      int flags = (accumulate ? SPX_CONV_FL_ACCUM : 0) | (bias ? SPX_CONV_FL_BIAS : 0) |
                  (scale ? SPX_CONV_FL_SCALE : 0) | (scale && shift ? SPX_CONV_FL_SHIFT : 0) |
                  (relu ? SPX_CONV_FL_RELU : 0);
      cl_mem bm = bias ? bias->mem : XM.mem, scm = scale ? scale->mem : XM.mem;
      cl_mem shm = scale && shift ? shift->mem : XM.mem;
      cl_ulong yo = y->off + (size_t)s0 * cout * h * wd, bo = bias ? bias->off : 0, sco = scale ? scale->off : 0;
      cl_ulong sho = scale && shift ? shift->off : 0;
      cl_int e = SPX_ARG(ko, 0, XM.mem) | SPX_ARG(ko, 1, y->mem) | SPX_ARG(ko, 2, yo) | SPX_ARG(ko, 3, bm) |
                 SPX_ARG(ko, 4, bo) | SPX_ARG(ko, 5, scm) | SPX_ARG(ko, 6, sco) | SPX_ARG(ko, 7, shm) |
                 SPX_ARG(ko, 8, sho) | SPX_ARG(ko, 9, cout) | SPX_ARG(ko, 10, coutp) | SPX_ARG(ko, 11, h) |
                 SPX_ARG(ko, 12, wd) | SPX_ARG(ko, 13, twp) | SPX_ARG(ko, 14, T) | SPX_ARG(ko, 15, Tp) |
                 SPX_ARG(ko, 16, flags) | SPX_ARG(ko, 17, tws);
      if ((st = spx_cl_check(ctx, e, "spx_wino_out args"))) goto done;
      size_t gl[3] = {(size_t)L.th * (size_t)(twp / vw), (size_t)cout, (size_t)m}, lo[3] = {1, 1, 1};
      if ((st = spx_cl_run(ctx, ko, 3, gl, vw > 1 ? lo : NULL, "spx_wino_out"))) goto done;
    }
  }
done:
  if (st && wp && !have_u) wp->key = 0; /* the preparation may not have run */
  spx_op_scratch_put(&XM);
  spx_op_scratch_put(&U);
  spx_op_scratch_put(&V);
  return st;
}

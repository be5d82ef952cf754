/* Winograd F(4x4,3x3) weight gradient: launchers for kernels/conv2d_winograd_dw.cl (the stages and
 * layouts are described at the top of the kernel file). Called by the table (lib/nn/conv2d_algo.c)
 * for the weight gradient of 3x3 / stride 1 / pad 1 layers when spx_conv2d_winograd_dw_applies. Scratch: the
 * caller's workspace slots 0 (Q, the transformed output gradients),
 * 1 (P, the 36 gradient GEMMs' sums) and 2 (V, the transformed input), sized by
 * spx_conv2d_winograd_dw_need, else buffers allocated per call and released after enqueueing. */
#include <limits.h>

#include "nn/conv2d.h"

int spx_conv2d_winograd_dw_applies(const spx_ctx *ctx, int k, int stride, int pad, int cin, int cout, int h, int w) {
  const int minc = ctx->dev->tune.conv_wino_dw;
  return ctx->dev->tune.conv_wino_train && minc > 0 && k == 3 && stride == 1 && pad == 1 && cin >= minc &&
         cout >= minc && (double)h * w >= ctx->dev->tune.conv_wino_dw_minhw;
}


int spx_conv2d_winograd_dw_need(const spx_ctx *ctx, int n, int cin, int cout, int h, int w, size_t bytes[3]) {
  int th, twp;
  spx_conv2d_wino_tiles(ctx, h, w, &th, &twp);
  const size_t T = (size_t)th * twp;
  /* per sample: slot 0 Q, slot 2 V */
  const size_t f0 = 36 * (size_t)cout * T;
  const size_t f2 = 36 * (size_t)cin * T;
  /* samples per pass as the forward's (CONV_WINO_CHUNK x 2^20 floats, at least one) */
  size_t nb = ((size_t)ctx->dev->tune.conv_wino_chunk << 20) / (f0 + f2);
  nb = nb < 1 ? 1 : nb > (size_t)n ? (size_t)n : nb;
  bytes[0] = nb * f0 * sizeof(float);
  bytes[1] = 36 * (size_t)cout * cin * sizeof(float);
  bytes[2] = nb * f2 * sizeof(float);
  return (int)nb;
}

spx_status spx_conv2d_winograd_dw(spx_ctx *ctx, spx_op_workspace *ws, const spx_tensor *x, const spx_tensor *dy,
                                  const spx_tensor *dw) {
  const int n = x->n, cin = x->c, h = x->h, wd = x->w, cout = dy->c, vw = ctx->dev->tune.conv_vw;
  int th, twp;
  spx_conv2d_wino_tiles(ctx, h, wd, &th, &twp);
  const int T = th * twp;
  size_t bytes[3];
  const int nb = spx_conv2d_winograd_dw_need(ctx, n, cin, cout, h, wd, bytes);
  const double big = (bytes[0] > bytes[2] ? bytes[0] : bytes[2]) / (double)sizeof(float);
  if (big > (double)INT_MAX || 36.0 * cout * cin > (double)INT_MAX)
    return spx_fail(ctx, SPX_E_UNSUPPORTED, "conv2d winograd weight gradient: %.0f transformed elements exceed the index range",
                    big);
  spx_op_scratch XQ = {0}, P = {0}, V = {0};
  spx_status st;
  cl_kernel kq, kg, kw;
  if ((st = spx_cl_kernel(ctx, SPX_K_WINO_DW_GRAD, &kq)) || (st = spx_cl_kernel(ctx, SPX_K_WINO_DW_GEMM, &kg)) ||
      (st = spx_cl_kernel(ctx, SPX_K_WINO_DW_WEIGHTS, &kw)))
    return st;
  if ((st = spx_op_scratch_get(ctx, ws, 0, bytes[0], "winograd dw output-gradient transform", &XQ)) ||
      (st = spx_op_scratch_get(ctx, ws, 1, bytes[1], "winograd dw gradient sums", &P)) ||
      (st = spx_op_scratch_get(ctx, ws, 2, bytes[2], "winograd dw input transform", &V)))
    goto done;
  const int tm = ctx->dev->tune.conv_dw_tm, tn = ctx->dev->tune.conv_dw_tn, gg = ctx->dev->tune.conv_dw_g;
  for (int s0 = 0; s0 < n; s0 += nb) {
    const int m = n - s0 < nb ? n - s0 : nb; /* samples in this pass */
    /* V, with the tile count unpadded (Tp = T, a multiple of CONV_VW) */
    if ((st = spx_conv2d_wino_input(ctx, x, s0, m, twp, T, V.mem))) goto done;
    {
      cl_ulong dyo = dy->off + (size_t)s0 * cout * h * wd;
      cl_int e = SPX_ARG(kq, 0, dy->mem) | SPX_ARG(kq, 1, dyo) | SPX_ARG(kq, 2, XQ.mem) | SPX_ARG(kq, 3, cout) |
                 SPX_ARG(kq, 4, h) | SPX_ARG(kq, 5, wd) | SPX_ARG(kq, 6, twp) | SPX_ARG(kq, 7, T);
      if ((st = spx_cl_check(ctx, e, "spx_wino_dw_grad args"))) goto done;
      size_t gl[3] = {(size_t)T / vw, (size_t)cout, (size_t)m}, lo[3] = {1, 1, 1};
      if ((st = spx_cl_run(ctx, kq, 3, gl, vw > 1 ? lo : NULL, "spx_wino_dw_grad"))) goto done;
    }
    {
      int accum = s0 > 0;
      cl_int e = SPX_ARG(kg, 0, XQ.mem) | SPX_ARG(kg, 1, V.mem) | SPX_ARG(kg, 2, P.mem) | SPX_ARG(kg, 3, cin) |
                 SPX_ARG(kg, 4, cout) | SPX_ARG(kg, 5, T) | SPX_ARG(kg, 6, m) | SPX_ARG(kg, 7, accum);
      if ((st = spx_cl_check(ctx, e, "spx_wino_dw_gemm args"))) goto done;
      const size_t nct = ((size_t)cin + tn - 1) / tn, lws = (size_t)ctx->dev->tune.conv_dw_lws;
      size_t gl[3] = {((nct + gg - 1) / gg + lws - 1) / lws * lws, ((size_t)cout + tm - 1) / tm, 36};
      size_t lo[3] = {lws, 1, 1};
      if ((st = spx_cl_run(ctx, kg, 3, gl, lo, "spx_wino_dw_gemm"))) goto done;
    }
  }
  {
    cl_ulong dwo = dw->off;
    cl_int e = SPX_ARG(kw, 0, P.mem) | SPX_ARG(kw, 1, dw->mem) | SPX_ARG(kw, 2, dwo) | SPX_ARG(kw, 3, cout) |
               SPX_ARG(kw, 4, cin);
    if ((st = spx_cl_check(ctx, e, "spx_wino_dw_weights args"))) goto done;
    size_t gl = (size_t)cout * cin;
    st = spx_cl_run(ctx, kw, 1, &gl, NULL, "spx_wino_dw_weights");
  }
done:
  spx_op_scratch_put(&XQ);
  spx_op_scratch_put(&P);
  spx_op_scratch_put(&V);
  return st;
}

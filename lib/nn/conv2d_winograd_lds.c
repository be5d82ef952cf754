/* Winograd F(4x4,3x3) for GPU-class devices: launchers for kernels/conv2d_winograd_lds.cl (one
 * fused kernel with local-memory tiles; the layout is described at the top of the kernel file).
 * lib/nn/conv2d_winograd.c hands a call here when spx_conv2d_winograd_lds_applies. Scratch: the
 * caller's workspace slot 1 (U, the transformed weights), else a buffer allocated per call and
 * released after enqueueing; unlike the CPU variant there is no padded input, V or M. */
#include <limits.h>
#include <string.h>

#include "nn/conv2d.h"

/* Local floats of the kernel's pool (the macros WL_POOL .. of the kernel file). */
static uint64_t pool_floats(const struct spx_tunables *t) {
  uint64_t bm = (uint64_t)t->conv_wlds_wm * t->conv_wlds_tm, bn = (uint64_t)t->conv_wlds_wn * t->conv_wlds_tn;
  uint64_t kb = (uint64_t)t->conv_wlds_kb;
  uint64_t block = kb * 6 * (4 * bn + 2) + kb * 36 * bn + kb * 36 * bm, prod = 36 * bm * bn;
  return block > prod ? block : prod;
}

int spx_conv2d_winograd_lds_applies(const spx_ctx *ctx) {
  const struct spx_tunables *t = &ctx->dev->tune;
  if (!t->conv_wino_lds) return 0;
  uint64_t items = 36ull * t->conv_wlds_wm * t->conv_wlds_wn;
  return items <= ctx->dev->info.max_work_group && 4 * pool_floats(t) <= ctx->dev->info.local_mem;
}

void spx_conv2d_winograd_lds_need(const spx_ctx *ctx, int cin, int cout, spx_ws_need *need) {
  const int bm = ctx->dev->tune.conv_wlds_wm * ctx->dev->tune.conv_wlds_tm, coutp = (cout + bm - 1) / bm * bm;
  memset(need, 0, sizeof *need);
  need->slot[1] = (size_t)36 * cin * coutp * sizeof(float);
}

spx_status spx_conv2d_winograd_lds(spx_ctx *ctx, spx_op_workspace *ws, const spx_tensor *x, const spx_tensor *w,
                                   int flip, const spx_tensor *bias, const spx_tensor *scale,
                                   const spx_tensor *shift, int relu, int accumulate, const spx_tensor *y) {
  const struct spx_tunables *t = &ctx->dev->tune;
  const int n = x->n, cin = x->c, h = x->h, wd = x->w, cout = y->c;
  const int Cout = w->n, Cin = w->c; /* the weight tensor's own dimensions */
  const int bm = t->conv_wlds_wm * t->conv_wlds_tm, bn = t->conv_wlds_wn * t->conv_wlds_tn;
  const int th = (h + 3) / 4, tw = (wd + 3) / 4, twp = (tw + bn - 1) / bn * bn;
  const int coutp = (cout + bm - 1) / bm * bm;
  const double ubig = 36.0 * cin * coutp;
  if (ubig > (double)INT_MAX)
    return spx_fail(ctx, SPX_E_UNSUPPORTED, "conv2d winograd (local memory): %.0f transformed weights exceed the "
                    "index range", ubig);
  cl_kernel kw, kc;
  spx_status st;
  if ((st = spx_cl_kernel(ctx, SPX_K_WINO_LDS_WEIGHTS, &kw)) || (st = spx_cl_kernel(ctx, SPX_K_WINO_LDS, &kc)))
    return st;
  spx_op_scratch U = {0};
  spx_ws_need need;
  spx_conv2d_winograd_lds_need(ctx, cin, cout, &need);
  if ((st = spx_op_scratch_get(ctx, ws, 1, need.slot[1], "winograd weight transform", &U))) return st;
  {
    cl_ulong wo = w->off;
    cl_int e = SPX_ARG(kw, 0, w->mem) | SPX_ARG(kw, 1, wo) | SPX_ARG(kw, 2, U.mem) | SPX_ARG(kw, 3, Cout) |
               SPX_ARG(kw, 4, Cin) | SPX_ARG(kw, 5, coutp) | SPX_ARG(kw, 6, flip);
    size_t gl = (size_t)cin * coutp, lo = (size_t)t->wg;
    if ((st = spx_cl_check(ctx, e, "spx_wino_lds_weights args")) ||
        (st = spx_cl_run(ctx, kw, 1, &gl, &lo, "spx_wino_lds_weights")))
      goto done;
  }
  {
    int flags = (accumulate ? SPX_CONV_FL_ACCUM : 0) | (bias ? SPX_CONV_FL_BIAS : 0) |
                (scale ? SPX_CONV_FL_SCALE : 0) | (scale && shift ? SPX_CONV_FL_SHIFT : 0) |
                (relu ? SPX_CONV_FL_RELU : 0);
    /* absent epilogue operands: any valid buffer (the flags keep the kernel from reading it) */
    cl_mem bm_ = bias ? bias->mem : U.mem, scm = scale ? scale->mem : U.mem, shm = scale && shift ? shift->mem : U.mem;
    cl_ulong xo = x->off, yo = y->off, bo = bias ? bias->off : 0, sco = scale ? scale->off : 0;
    cl_ulong sho = scale && shift ? shift->off : 0;
    cl_int e = SPX_ARG(kc, 0, x->mem) | SPX_ARG(kc, 1, xo) | SPX_ARG(kc, 2, U.mem) | SPX_ARG(kc, 3, y->mem) |
               SPX_ARG(kc, 4, yo) | SPX_ARG(kc, 5, bm_) | SPX_ARG(kc, 6, bo) | SPX_ARG(kc, 7, scm) |
               SPX_ARG(kc, 8, sco) | SPX_ARG(kc, 9, shm) | SPX_ARG(kc, 10, sho) | SPX_ARG(kc, 11, cin) |
               SPX_ARG(kc, 12, cout) | SPX_ARG(kc, 13, coutp) | SPX_ARG(kc, 14, h) | SPX_ARG(kc, 15, wd) |
               SPX_ARG(kc, 16, twp) | SPX_ARG(kc, 17, flags);
    const size_t items = (size_t)36 * t->conv_wlds_wm * t->conv_wlds_wn;
    size_t gl[2] = {(size_t)(coutp / bm) * th * (twp / bn) * items, (size_t)n}, lo[2] = {items, 1};
    if ((st = spx_cl_check(ctx, e, "spx_wino_lds args")) || (st = spx_cl_run(ctx, kc, 2, gl, lo, "spx_wino_lds")))
      goto done;
  }
done:
  spx_op_scratch_put(&U);
  return st;
}

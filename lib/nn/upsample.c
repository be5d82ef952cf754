/* Launchers for kernels/upsample.cl.
 * Why output rows 2i-1 .. 2i+3 hold every output that reads input row i (the backward gather
 * window): output d reads rows floor(src) and floor(src)+1, so it reads i only if
 * i-1 < src < i+1. align_corners=false: src = d/2 - 1/4, so 2i-1.5 < d < 2i+2.5, i.e.
 * d in [2i-1, 2i+2]. align_corners=true: src = d s with s = (in-1)/(2in-1) < 1/2, so
 * d > (i-1)/s >= 2i-2 (so d >= 2i-1; for i = 1, d = 0 has src = 0 exactly and reads row 1 with
 * weight 0) and d < (i+1)/s = 2i+2 + (i+1)/(in-1) <= 2i+4 (in >= 2; for in == 1 every output
 * reads row 0 and there are only rows 0 and 1). Float rounding of src moves it by ~d*eps, far
 * less than the margins (~1/(2in) relative) of these bounds. */
#include "nn/upsample.h"

#include "nn/nn_internal.h"

static float scale_of(int in, int align) {
  int out = 2 * in;
  if (align) return out > 1 ? (float)(in - 1) / (float)(out - 1) : 0.0f;
  return 0.5f;
}

static spx_status run(spx_ctx *ctx, const char *op, const char *kname, const spx_tensor *src, const spx_tensor *dst,
                      const spx_tensor *small, const spx_tensor *big, int align, const spx_tensor *range) {
  spx_status st;
  cl_kernel k;
  if ((st = spx_nn_check(ctx, src, op, "input")) || (st = spx_nn_check(ctx, dst, op, "output"))) return st;
  if (big->n != small->n || big->c != small->c || (long)big->h != 2L * small->h || (long)big->w != 2L * small->w)
    return spx_fail(ctx, SPX_E_ARG, "%s: %dx%dx%dx%d is not the x2 upsampling of %dx%dx%dx%d", op, big->n, big->c,
                    big->h, big->w, small->n, small->c, small->h, small->w);
  if ((st = spx_cl_kernel(ctx, "upsample.cl", kname, &k))) return st;
  cl_int al = align ? 1 : 0;
  float sh = scale_of(small->h, align), sw = scale_of(small->w, align);
  cl_int e = spx_nn_arg(k, 0, src) | spx_nn_arg(k, 2, dst) | SPX_ARG(k, 4, small->h) | SPX_ARG(k, 5, small->w) |
             SPX_ARG(k, 6, sh) | SPX_ARG(k, 7, sw) | SPX_ARG(k, 8, al);
  if ((st = spx_cl_check(ctx, e, kname))) return st;
  return spx_nn_run3d(ctx, k, (size_t)range->w, (size_t)range->h, (size_t)range->n * (size_t)range->c, kname);
}

spx_status spx_upsample2x_forward(spx_ctx *ctx, const spx_tensor *x, int align_corners, const spx_tensor *y) {
  if (!x || !y) return spx_fail(ctx, SPX_E_ARG, "upsample2x_forward: missing tensor");
  return run(ctx, "upsample2x_forward", "spx_upsample2x_fwd", x, y, x, y, align_corners, y);
}

spx_status spx_upsample2x_backward(spx_ctx *ctx, const spx_tensor *dy, int align_corners, const spx_tensor *dx) {
  if (!dx) return SPX_OK;
  if (!dy) return spx_fail(ctx, SPX_E_ARG, "upsample2x_backward: missing dy");
  return run(ctx, "upsample2x_backward", "spx_upsample2x_bwd", dy, dx, dx, dy, align_corners, dx);
}

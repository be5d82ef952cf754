/* Launchers for kernels/upsample.cl.
 * Why rows 2i-4 .. 2i+5 hold every output that reads input row i (the backward gather window):
 * an output d reads rows floor(src) and floor(src)+1, so it reads i only if i-1 < src < i+1.
 * align_corners=false: src = d/2 - 1/4, so 2i-1.5 < d < 2i+2.5. align_corners=true:
 * src = d (in-1)/(2in-1) with scale < 1/2, so d > 2(i-1) and d < (i+1)(2 + 1/(in-1)) <= 2i+4
 * (in >= 2; in == 1 has only rows 0 and 1). */
#include "nn/upsample.h"

#include "nn/nn_internal.h"

static float scale_of(int in, int align) {
  int out = 2 * in;
  if (align) return out > 1 ? (float)(in - 1) / (float)(out - 1) : 0.0f;
  return 0.5f;
}

static spx_status run(spx_ctx *ctx, const char *op, const char *kname, const spx_tensor *src, const spx_tensor *dst,
                      const spx_tensor *small, const spx_tensor *big, int align, size_t count) {
  spx_status st;
  cl_kernel k;
  if ((st = spx_nn_check(ctx, src, op, "input")) || (st = spx_nn_check(ctx, dst, op, "output"))) return st;
  if (big->n != small->n || big->c != small->c || (long)big->h != 2L * small->h || (long)big->w != 2L * small->w)
    return spx_fail(ctx, SPX_E_ARG, "%s: %dx%dx%dx%d is not the x2 upsampling of %dx%dx%dx%d", op, big->n, big->c,
                    big->h, big->w, small->n, small->c, small->h, small->w);
  if ((st = spx_cl_kernel(ctx, "upsample.cl", kname, &k))) return st;
  cl_int nc = small->n * small->c, al = align ? 1 : 0;
  float sh = scale_of(small->h, align), sw = scale_of(small->w, align);
  cl_int e = spx_nn_arg(k, 0, src) | spx_nn_arg(k, 2, dst) | SPX_ARG(k, 4, nc) | SPX_ARG(k, 5, small->h) |
             SPX_ARG(k, 6, small->w) | SPX_ARG(k, 7, sh) | SPX_ARG(k, 8, sw) | SPX_ARG(k, 9, al);
  if ((st = spx_cl_check(ctx, e, kname))) return st;
  return spx_nn_run1d(ctx, k, count, kname);
}

spx_status spx_upsample2x_forward(spx_ctx *ctx, const spx_tensor *x, int align_corners, const spx_tensor *y) {
  if (!x || !y) return spx_fail(ctx, SPX_E_ARG, "upsample2x_forward: missing tensor");
  return run(ctx, "upsample2x_forward", "spx_upsample2x_fwd", x, y, x, y, align_corners, spx_tensor_numel(y));
}

spx_status spx_upsample2x_backward(spx_ctx *ctx, const spx_tensor *dy, int align_corners, const spx_tensor *dx) {
  if (!dx) return SPX_OK;
  if (!dy) return spx_fail(ctx, SPX_E_ARG, "upsample2x_backward: missing dy");
  return run(ctx, "upsample2x_backward", "spx_upsample2x_bwd", dy, dx, dx, dy, align_corners, spx_tensor_numel(dx));
}

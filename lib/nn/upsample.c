/* Launchers for kernels/upsample.cl.
 * Why output rows 2i-1 .. 2i+3 hold every output that reads input row i (the backward gather
 * window): output d reads rows floor(src) and floor(src)+1, so it reads i only if
 * i-1 < src < i+1. align_corners=false: src = d/2 - 1/4, so 2i-1.5 < d < 2i+2.5, i.e.
 * d in [2i-1, 2i+2]. align_corners=true: src = d s with s = (in-1)/(2in-1) < 1/2, so
 * d > (i-1)/s >= 2i-2 (so d >= 2i-1; for i = 1, d = 0 has src = 0 exactly and reads row 1 with
 * weight 0) and d < (i+1)/s = 2i+2 + (i+1)/(in-1) <= 2i+4 (in >= 2; for in == 1 every output
 * reads row 0 and there are only rows 0 and 1). Float rounding of src moves it by ~d*eps, far
 * less than the margins (~1/(2in) relative) of these bounds. */
#include <string.h>

#include "nn/upsample.h"

#include "nn/nn_internal.h"

static float scale_of(int in, int align) {
  int out = 2 * in;
  if (align) return out > 1 ? (float)(in - 1) / (float)(out - 1) : 0.0f;
  return 0.5f;
}

static spx_status run(spx_ctx *ctx, const char *op, spx_kernel_id kid, const spx_tensor *src, const spx_tensor *dst,
                      const spx_tensor *small, const spx_tensor *big, int align, const spx_tensor *range) {
  spx_status st;
  cl_kernel k;
  if ((st = spx_nn_check(ctx, src, op, "input")) || (st = spx_nn_check(ctx, dst, op, "output"))) return st;
  if (big->n != small->n || big->c != small->c || (long)big->h != 2L * small->h || (long)big->w != 2L * small->w)
    return spx_fail(ctx, SPX_E_ARG, "%s: %dx%dx%dx%d is not the x2 upsampling of %dx%dx%dx%d", op, big->n, big->c,
                    big->h, big->w, small->n, small->c, small->h, small->w);
  const char *kname = spx_cl_kernel_name(kid);
  if ((st = spx_cl_kernel(ctx, kid, &k))) return st;
  cl_int al = align ? 1 : 0;
  float sh = scale_of(small->h, align), sw = scale_of(small->w, align);
  cl_int e = spx_nn_arg(k, 0, src) | spx_nn_arg(k, 2, dst) | SPX_ARG(k, 4, small->h) | SPX_ARG(k, 5, small->w) |
             SPX_ARG(k, 6, sh) | SPX_ARG(k, 7, sw) | SPX_ARG(k, 8, al);
  if ((st = spx_cl_check(ctx, e, kname))) return st;
  return spx_nn_run3d(ctx, k, (size_t)range->w, (size_t)range->h, (size_t)range->n * (size_t)range->c, kname);
}

spx_status spx_upsample2x_forward(spx_ctx *ctx, const spx_tensor *x, int align_corners, const spx_tensor *y) {
  if (!x || !y) return spx_fail(ctx, SPX_E_ARG, "upsample2x_forward: missing tensor");
  return run(ctx, "upsample2x_forward", SPX_K_UPSAMPLE2X_FWD, x, y, x, y, align_corners, y);
}

/* scratch floats: the row-pass result (half of dy), then the x and y weight tables */
static size_t bwd_scratch(int n, int c, int h, int w) {
  return (size_t)n * c * 2 * h * w + 5 * (size_t)w + 5 * (size_t)h;
}

void spx_upsample2x_backward_need(int n, int c, int h, int w, spx_ws_need *need) {
  memset(need, 0, sizeof *need);
  if (n > 0 && c > 0 && h > 0 && w > 0) need->slot[0] = bwd_scratch(n, c, h, w) * sizeof(float);
}

spx_status spx_upsample2x_backward(spx_ctx *ctx, const spx_tensor *dy, int align_corners, const spx_tensor *dx) {
  return spx_upsample2x_backward_ws(ctx, dy, align_corners, dx, NULL);
}

spx_status spx_upsample2x_backward_ws(spx_ctx *ctx, const spx_tensor *dy, int align_corners, const spx_tensor *dx,
                                      spx_conv2d_workspace *ws) {
  const char *op = "upsample2x_backward";
  spx_status st;
  cl_kernel k1, k2;
  spx_conv2d_scratch sc = {0};
  cl_mem t = NULL;
  if (!dx) return SPX_OK;
  if (!dy) return spx_fail(ctx, SPX_E_ARG, "%s: missing dy", op);
  if ((st = spx_nn_check(ctx, dy, op, "dy")) || (st = spx_nn_check(ctx, dx, op, "dx"))) return st;
  if (dy->n != dx->n || dy->c != dx->c || (long)dy->h != 2L * dx->h || (long)dy->w != 2L * dx->w)
    return spx_fail(ctx, SPX_E_ARG, "%s: %dx%dx%dx%d is not the x2 upsampling of %dx%dx%dx%d", op, dy->n, dy->c, dy->h,
                    dy->w, dx->n, dx->c, dx->h, dx->w);
  size_t planes = (size_t)dx->n * (size_t)dx->c, rows = 2 * (size_t)dx->h;
  if (planes * rows * (size_t)dx->w == 0) return SPX_OK;
  cl_kernel kw;
  if ((st = spx_cl_kernel(ctx, SPX_K_UPSAMPLE2X_BWD_ROWS, &k1)) ||
      (st = spx_cl_kernel(ctx, SPX_K_UPSAMPLE2X_BWD_COLS, &k2)) ||
      (st = spx_cl_kernel(ctx, SPX_K_UPSAMPLE2X_WEIGHTS, &kw)))
    return st;
  /* scratch: the row-pass result (half of dy), then the x and y weight tables (5 per input
   * column / row); released right after enqueueing, OpenCL keeps it alive until the queued
   * kernels are done */
  size_t tn = planes * rows * (size_t)dx->w, wxo = tn, wyo = tn + 5 * (size_t)dx->w;
  size_t total = bwd_scratch(dx->n, dx->c, dx->h, dx->w);
  if (total > (size_t)INT_MAX) return spx_fail(ctx, SPX_E_ARG, "%s: tensor too large", op);
  if ((st = spx_conv2d_scratch_get(ctx, ws, 0, total * sizeof(float), "upsample backward scratch", &sc))) return st;
  t = sc.mem;
  cl_int al = align_corners ? 1 : 0, go = (cl_int)dy->off, wxoi = (cl_int)wxo, wyoi = (cl_int)wyo;
  float sh = scale_of(dx->h, align_corners), sw = scale_of(dx->w, align_corners);
  cl_int e = SPX_ARG(kw, 0, t) | SPX_ARG(kw, 1, wxoi) | SPX_ARG(kw, 2, dx->w) | SPX_ARG(kw, 3, sw) | SPX_ARG(kw, 4, al);
  if ((st = spx_cl_check(ctx, e, "spx_upsample2x_weights")) ||
      (st = spx_nn_run1d(ctx, kw, (size_t)dx->w, "spx_upsample2x_weights")))
    goto done;
  e = SPX_ARG(kw, 0, t) | SPX_ARG(kw, 1, wyoi) | SPX_ARG(kw, 2, dx->h) | SPX_ARG(kw, 3, sh) | SPX_ARG(kw, 4, al);
  if ((st = spx_cl_check(ctx, e, "spx_upsample2x_weights")) ||
      (st = spx_nn_run1d(ctx, kw, (size_t)dx->h, "spx_upsample2x_weights")))
    goto done;
  e = SPX_ARG(k1, 0, dy->mem) | SPX_ARG(k1, 1, go) | SPX_ARG(k1, 2, t) | SPX_ARG(k1, 3, t) | SPX_ARG(k1, 4, wxoi) |
      SPX_ARG(k1, 5, dx->h) | SPX_ARG(k1, 6, dx->w);
  if ((st = spx_cl_check(ctx, e, "spx_upsample2x_bwd_rows")) ||
      (st = spx_nn_run3d(ctx, k1, (size_t)dx->w, rows, planes, "spx_upsample2x_bwd_rows")))
    goto done;
  e = SPX_ARG(k2, 0, t) | SPX_ARG(k2, 1, t) | SPX_ARG(k2, 2, wyoi) | spx_nn_arg(k2, 3, dx) | SPX_ARG(k2, 5, dx->h) |
      SPX_ARG(k2, 6, dx->w);
  if (!(st = spx_cl_check(ctx, e, "spx_upsample2x_bwd_cols")))
    st = spx_nn_run3d(ctx, k2, (size_t)dx->w, (size_t)dx->h, planes, "spx_upsample2x_bwd_cols");
done:
  spx_conv2d_scratch_put(&sc);
  return st;
}

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
#include "nn/tensor_ops.h"

static float scale_of(int in, int align) {
  int out = 2 * in;
  if (align) return out > 1 ? (float)(in - 1) / (float)(out - 1) : 0.0f;
  return 0.5f;
}

/* Planes per work-item of the row-vector kernel: the source indices and weights are computed
 * once for this many planes. */
#define UP_ROWS_PLANES 16

/* y (planes ps apart from yo, rows rs apart) = the x2 upsampling of x: `planes` planes. Per
 * output (spx_upsample2x_fwd) or 16 columns of a row per work-item (spx_upsample2x_fwd_rows,
 * tunable SPX_ROW_VEC): the same bits. */
static spx_status up_forward(spx_ctx *ctx, cl_mem x, size_t xo, int h, int w, size_t planes, cl_mem y, size_t yo,
                             size_t ps, size_t rs, int align) {
  const int rows = ctx->dev->tune.row_vec;
  const spx_kernel_id id = rows ? SPX_K_UPSAMPLE2X_FWD_ROWS : SPX_K_UPSAMPLE2X_FWD;
  const char *kname = spx_cl_kernel_name(id);
  cl_kernel k;
  spx_status st = spx_cl_kernel(ctx, id, &k);
  if (st) return st;
  if (planes > (size_t)INT_MAX) return spx_fail(ctx, SPX_E_ARG, "upsample2x_forward: tensor too large");
  cl_int al = align ? 1 : 0, xoi = (cl_int)xo, yoi = (cl_int)yo, psi = (cl_int)ps, rsi = (cl_int)rs;
  cl_int np = (cl_int)planes, pb = UP_ROWS_PLANES;
  float sh = scale_of(h, align), sw = scale_of(w, align);
  cl_int e = SPX_ARG(k, 0, x) | SPX_ARG(k, 1, xoi) | SPX_ARG(k, 2, y) | SPX_ARG(k, 3, yoi) | SPX_ARG(k, 4, h) |
             SPX_ARG(k, 5, w) | SPX_ARG(k, 6, sh) | SPX_ARG(k, 7, sw) | SPX_ARG(k, 8, al) | SPX_ARG(k, 9, psi) |
             SPX_ARG(k, 10, rsi);
  if (rows) e |= SPX_ARG(k, 11, np) | SPX_ARG(k, 12, pb);
  if ((st = spx_cl_check(ctx, e, kname))) return st;
  if (rows)
    return spx_nn_run3d(ctx, k, (2 * (size_t)w + 15) / 16, 2 * (size_t)h, (planes + UP_ROWS_PLANES - 1) / UP_ROWS_PLANES,
                        kname);
  return spx_nn_run3d(ctx, k, 2 * (size_t)w, 2 * (size_t)h, planes, kname);
}

spx_status spx_upsample2x_forward(spx_ctx *ctx, const spx_tensor *x, int align_corners, const spx_tensor *y) {
  const char *op = "upsample2x_forward";
  spx_status st;
  if (!x || !y) return spx_fail(ctx, SPX_E_ARG, "%s: missing tensor", op);
  if ((st = spx_nn_check(ctx, x, op, "input")) || (st = spx_nn_check(ctx, y, op, "output"))) return st;
  if (y->n != x->n || y->c != x->c || (long)y->h != 2L * x->h || (long)y->w != 2L * x->w)
    return spx_fail(ctx, SPX_E_ARG, "%s: %dx%dx%dx%d is not the x2 upsampling of %dx%dx%dx%d", op, y->n, y->c, y->h,
                    y->w, x->n, x->c, x->h, x->w);
  return up_forward(ctx, x->mem, x->off, x->h, x->w, (size_t)x->n * x->c, y->mem, y->off, (size_t)y->h * y->w,
                    (size_t)y->w, align_corners);
}

/* scratch floats of the backward for dx of n x c x h x w: the row-pass result (half of dy), then
 * the x and y weight tables (5 per input column / row) */
static size_t bwd_scratch(int n, int c, int h, int w) {
  return (size_t)n * c * 2 * h * w + 5 * (size_t)w + 5 * (size_t)h;
}

void spx_upsample2x_backward_need(int n, int c, int h, int w, spx_ws_need *need) {
  memset(need, 0, sizeof *need);
  if (n > 0 && c > 0 && h > 0 && w > 0) need->slot[0] = bwd_scratch(n, c, h, w) * sizeof(float);
}

/* dx += the x2-upsampling backward of the gradient dy (planes addressed by strides, see
 * spx_upsample2x_bwd_rows; the samples' planes start ns apart at dyo, each ps apart): the shared
 * body of the plain and the fused (up-block) backward. Plain: one row-pass launch over all the
 * planes; strided: one per sample. Scratch: slot 0 of ws (NULL: allocated per call). */
static spx_status up_backward(spx_ctx *ctx, const char *op, cl_mem dy, size_t dyo, size_t ns, size_t ps, size_t rs,
                              int align_corners, const spx_tensor *dx, spx_op_workspace *ws) {
  spx_status st;
  cl_kernel k1, k2, kw;
  spx_op_scratch sc = {0};
  cl_mem t = NULL;
  size_t planes = (size_t)dx->n * (size_t)dx->c, rows = 2 * (size_t)dx->h;
  if (planes * rows * (size_t)dx->w == 0) return SPX_OK;
  /* one work-item per output, or 16 consecutive columns (tunable SPX_ROW_VEC): the same bits */
  const int vec = ctx->dev->tune.row_vec;
  const char *n1 = vec ? "spx_upsample2x_bwd_rows_v" : "spx_upsample2x_bwd_rows";
  const char *n2 = vec ? "spx_upsample2x_bwd_cols_v" : "spx_upsample2x_bwd_cols";
  const size_t gx = vec ? ((size_t)dx->w + 15) / 16 : (size_t)dx->w;
  if ((st = spx_cl_kernel(ctx, vec ? SPX_K_UPSAMPLE2X_BWD_ROWS_V : SPX_K_UPSAMPLE2X_BWD_ROWS, &k1)) ||
      (st = spx_cl_kernel(ctx, vec ? SPX_K_UPSAMPLE2X_BWD_COLS_V : SPX_K_UPSAMPLE2X_BWD_COLS, &k2)) ||
      (st = spx_cl_kernel(ctx, SPX_K_UPSAMPLE2X_WEIGHTS, &kw)))
    return st;
  /* scratch: the row-pass result (half of dy), then the x and y weight tables (5 per input
   * column / row); released right after enqueueing, OpenCL keeps it alive until the queued
   * kernels are done */
  size_t tn = planes * rows * (size_t)dx->w, wxo = tn, wyo = tn + 5 * (size_t)dx->w;
  size_t total = bwd_scratch(dx->n, dx->c, dx->h, dx->w);
  if (total > (size_t)INT_MAX || dyo + (size_t)dx->n * ns > (size_t)INT_MAX)
    return spx_fail(ctx, SPX_E_ARG, "%s: tensor too large", op);
  if ((st = spx_op_scratch_get(ctx, ws, 0, total * sizeof(float), "upsample backward scratch", &sc))) return st;
  t = sc.mem;
  cl_int al = align_corners ? 1 : 0, wxoi = (cl_int)wxo, wyoi = (cl_int)wyo, psi = (cl_int)ps, rsi = (cl_int)rs;
  float sh = scale_of(dx->h, align_corners), sw = scale_of(dx->w, align_corners);
  cl_int e = SPX_ARG(kw, 0, t) | SPX_ARG(kw, 1, wxoi) | SPX_ARG(kw, 2, dx->w) | SPX_ARG(kw, 3, sw) | SPX_ARG(kw, 4, al);
  if ((st = spx_cl_check(ctx, e, "spx_upsample2x_weights")) ||
      (st = spx_nn_run1d(ctx, kw, (size_t)dx->w, "spx_upsample2x_weights")))
    goto done;
  e = SPX_ARG(kw, 0, t) | SPX_ARG(kw, 1, wyoi) | SPX_ARG(kw, 2, dx->h) | SPX_ARG(kw, 3, sh) | SPX_ARG(kw, 4, al);
  if ((st = spx_cl_check(ctx, e, "spx_upsample2x_weights")) ||
      (st = spx_nn_run1d(ctx, kw, (size_t)dx->h, "spx_upsample2x_weights")))
    goto done;
  const int whole = ns == (size_t)dx->c * ps; /* the samples' planes are contiguous */
  for (int k = 0; k < (whole ? 1 : dx->n); k++) {
    cl_int go = (cl_int)(dyo + (size_t)k * ns), to = (cl_int)((size_t)k * dx->c * rows * (size_t)dx->w);
    e = SPX_ARG(k1, 0, dy) | SPX_ARG(k1, 1, go) | SPX_ARG(k1, 2, t) | SPX_ARG(k1, 3, to) | SPX_ARG(k1, 4, t) |
        SPX_ARG(k1, 5, wxoi) | SPX_ARG(k1, 6, dx->h) | SPX_ARG(k1, 7, dx->w) | SPX_ARG(k1, 8, psi) |
        SPX_ARG(k1, 9, rsi);
    if ((st = spx_cl_check(ctx, e, n1)) || (st = spx_nn_run3d(ctx, k1, gx, rows, whole ? planes : (size_t)dx->c, n1)))
      goto done;
  }
  e = SPX_ARG(k2, 0, t) | SPX_ARG(k2, 1, t) | SPX_ARG(k2, 2, wyoi) | spx_nn_arg(k2, 3, dx) | SPX_ARG(k2, 5, dx->h) |
      SPX_ARG(k2, 6, dx->w);
  if (!(st = spx_cl_check(ctx, e, n2))) st = spx_nn_run3d(ctx, k2, gx, (size_t)dx->h, planes, n2);
done:
  spx_op_scratch_put(&sc);
  return st;
}

spx_status spx_upsample2x_backward(spx_ctx *ctx, const spx_tensor *dy, int align_corners, const spx_tensor *dx) {
  return spx_upsample2x_backward_ws(ctx, dy, align_corners, dx, NULL);
}

spx_status spx_upsample2x_backward_ws(spx_ctx *ctx, const spx_tensor *dy, int align_corners, const spx_tensor *dx,
                                      spx_op_workspace *ws) {
  const char *op = "upsample2x_backward";
  spx_status st;
  if (!dx) return SPX_OK;
  if (!dy) return spx_fail(ctx, SPX_E_ARG, "%s: missing dy", op);
  if ((st = spx_nn_check(ctx, dy, op, "dy")) || (st = spx_nn_check(ctx, dx, op, "dx"))) return st;
  if (dy->n != dx->n || dy->c != dx->c || (long)dy->h != 2L * dx->h || (long)dy->w != 2L * dx->w)
    return spx_fail(ctx, SPX_E_ARG, "%s: %dx%dx%dx%d is not the x2 upsampling of %dx%dx%dx%d", op, dy->n, dy->c, dy->h,
                    dy->w, dx->n, dx->c, dx->h, dx->w);
  size_t ps = (size_t)dy->h * (size_t)dy->w;
  return up_backward(ctx, op, dy->mem, dy->off, (size_t)dy->c * ps, ps, (size_t)dy->w, align_corners, dx, ws);
}

/* skip, x, out: the up-block's shapes (out = concat(skip, pad(upsample2x(x)))), pads >= 0. */
static spx_status upcat_check(spx_ctx *ctx, const char *op, const spx_tensor *skip, const spx_tensor *x,
                              const spx_tensor *out, int top, int left) {
  if (skip->n != out->n || x->n != out->n || skip->h != out->h || skip->w != out->w ||
      (long)skip->c + x->c != out->c || top < 0 || left < 0 || 2L * x->h + top > out->h ||
      2L * x->w + left > out->w)
    return spx_fail(ctx, SPX_E_ARG,
                    "%s: %dx%dx%dx%d upsampled x2 at (%d, %d) and concatenated after %dx%dx%dx%d does not give "
                    "%dx%dx%dx%d",
                    op, x->n, x->c, x->h, x->w, top, left, skip->n, skip->c, skip->h, skip->w, out->n, out->c, out->h,
                    out->w);
  return SPX_OK;
}

spx_status spx_upcat_forward(spx_ctx *ctx, const spx_tensor *skip, const spx_tensor *x, int top, int left,
                             int align_corners, const spx_tensor *out) {
  const char *op = "upcat_forward";
  spx_status st;
  cl_kernel k;
  if (!skip || !x || !out) return spx_fail(ctx, SPX_E_ARG, "%s: missing tensor", op);
  if ((st = spx_nn_check(ctx, skip, op, "skip")) || (st = spx_nn_check(ctx, x, op, "x")) ||
      (st = spx_nn_check(ctx, out, op, "out")) || (st = upcat_check(ctx, op, skip, x, out, top, left)))
    return st;
  if (spx_tensor_numel(out) > (size_t)INT_MAX) return spx_fail(ctx, SPX_E_ARG, "%s: tensor too large", op);
  if ((st = spx_cl_kernel(ctx, SPX_K_UPCAT_BORDER, &k))) return st;
  /* skip into channels [0, cs); per sample, the upsampled x straight into its channels at the pad
   * offset, then the zero border around it (two thin launches, only where there is padding) */
  const int uh = 2 * x->h, uw = 2 * x->w, pads = out->h > uh || out->w > uw;
  cl_int e = SPX_ARG(k, 0, out->mem) | SPX_ARG(k, 2, out->h) | SPX_ARG(k, 3, out->w) | SPX_ARG(k, 4, top) |
             SPX_ARG(k, 5, left) | SPX_ARG(k, 6, uh) | SPX_ARG(k, 7, uw);
  /* (a tape may have planned the skip inside the output already, lib/nn/tape_plan.c: no copy) */
  const int in_place = skip->mem == out->mem && skip->off == out->off && out->n == 1;
  if ((st = spx_cl_check(ctx, e, "spx_upcat_border")) || (!in_place && (st = spx_channel_place(ctx, skip, out, 0))))
    return st;
  size_t ps = (size_t)out->h * out->w, xs = (size_t)x->h * x->w;
  for (int s = 0; s < out->n && !st; s++) {
    size_t oo = out->off + ((size_t)s * out->c + skip->c) * ps;
    st = up_forward(ctx, x->mem, x->off + (size_t)s * x->c * xs, x->h, x->w, (size_t)x->c, out->mem,
                    oo + (size_t)top * out->w + (size_t)left, ps, (size_t)out->w, align_corners);
    for (int rows = 1; rows >= 0 && pads && !st; rows--) {
      size_t gx = rows ? (size_t)out->w : (size_t)(out->w - uw), gy = rows ? (size_t)(out->h - uh) : (size_t)uh;
      cl_int ooi = (cl_int)oo;
      if (gx * gy == 0) continue;
      e = SPX_ARG(k, 1, ooi) | SPX_ARG(k, 8, rows);
      if (!(st = spx_cl_check(ctx, e, "spx_upcat_border")))
        st = spx_nn_run3d(ctx, k, gx, gy, (size_t)x->c, "spx_upcat_border");
    }
  }
  return st;
}

spx_status spx_upcat_backward(spx_ctx *ctx, const spx_tensor *dout, int top, int left, int align_corners,
                              const spx_tensor *dskip, const spx_tensor *dx) {
  return spx_upcat_backward_ws(ctx, dout, top, left, align_corners, dskip, dx, NULL);
}

spx_status spx_upcat_backward_ws(spx_ctx *ctx, const spx_tensor *dout, int top, int left, int align_corners,
                                 const spx_tensor *dskip, const spx_tensor *dx, spx_op_workspace *ws) {
  const char *op = "upcat_backward";
  spx_status st;
  if (!dout) return spx_fail(ctx, SPX_E_ARG, "%s: missing dout", op);
  if ((st = spx_nn_check(ctx, dout, op, "dout"))) return st;
  if (dskip && (st = spx_concat_backward(ctx, dout, dskip, NULL))) return st;
  if (!dx) return SPX_OK;
  if ((st = spx_nn_check(ctx, dx, op, "dx"))) return st;
  if (dx->n != dout->n || dx->c > dout->c || top < 0 || left < 0 || 2L * dx->h + top > dout->h ||
      2L * dx->w + left > dout->w)
    return spx_fail(ctx, SPX_E_ARG, "%s: dx %dx%dx%dx%d upsampled x2 at (%d, %d) does not fit dout %dx%dx%dx%d", op,
                    dx->n, dx->c, dx->h, dx->w, top, left, dout->n, dout->c, dout->h, dout->w);
  /* x's gradient is the cropped last dx->c channels of dout, read in place */
  size_t ps = (size_t)dout->h * (size_t)dout->w;
  size_t off = dout->off + (size_t)(dout->c - dx->c) * ps + (size_t)top * dout->w + (size_t)left;
  return up_backward(ctx, op, dout->mem, off, (size_t)dout->c * ps, ps, (size_t)dout->w, align_corners, dx, ws);
}

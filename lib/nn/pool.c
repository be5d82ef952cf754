/* Launchers for kernels/pool.cl. */
#include "nn/pool.h"

#include "nn/nn_internal.h"

static spx_status shapes(spx_ctx *ctx, const char *op, const spx_tensor *x, const spx_tensor *y, const char *yname) {
  spx_status st;
  if ((st = spx_nn_check(ctx, x, op, "x")) || (st = spx_nn_check(ctx, y, op, yname))) return st;
  if (y->n != x->n || y->c != x->c || y->h != x->h / 2 || y->w != x->w / 2)
    return spx_fail(ctx, SPX_E_ARG, "%s: %s is %dx%dx%dx%d, 2x2 pooling of %dx%dx%dx%d gives %dx%dx%dx%d", op, yname,
                    y->n, y->c, y->h, y->w, x->n, x->c, x->h, x->w, x->n, x->c, x->h / 2, x->w / 2);
  return SPX_OK;
}

spx_status spx_maxpool_forward(spx_ctx *ctx, const spx_tensor *x, const spx_tensor *y) {
  spx_status st;
  cl_kernel k;
  /* per window, or 16 windows of a row per work-item (tunable SPX_ROW_VEC): the same bits */
  const int rows = ctx->dev->tune.row_vec;
  const char *name = rows ? "spx_maxpool_fwd_rows" : "spx_maxpool_fwd";
  if ((st = shapes(ctx, "maxpool_forward", x, y, "y")) ||
      (st = spx_cl_kernel(ctx, rows ? SPX_K_MAXPOOL_FWD_ROWS : SPX_K_MAXPOOL_FWD, &k)))
    return st;
  cl_int e = spx_nn_arg(k, 0, x) | spx_nn_arg(k, 2, y) | SPX_ARG(k, 4, x->h) | SPX_ARG(k, 5, x->w);
  if ((st = spx_cl_check(ctx, e, name))) return st;
  return spx_nn_run3d(ctx, k, rows ? ((size_t)y->w + 15) / 16 : (size_t)y->w, (size_t)y->h,
                      (size_t)y->n * (size_t)y->c, name);
}

spx_status spx_maxpool_backward(spx_ctx *ctx, const spx_tensor *x, const spx_tensor *dy, const spx_tensor *dx) {
  spx_status st;
  cl_kernel k;
  if (!dx) return SPX_OK;
  if ((st = shapes(ctx, "maxpool_backward", x, dy, "dy")) || (st = spx_nn_check(ctx, dx, "maxpool_backward", "dx")))
    return st;
  if (!spx_nn_same_shape(x, dx)) return spx_nn_shape_mismatch(ctx, "maxpool_backward", "dx vs x", dx, x);
  /* per window, or 16 windows of a row per work-item (tunable SPX_ROW_VEC): the same bits */
  const int rows = ctx->dev->tune.row_vec;
  const char *name = rows ? "spx_maxpool_bwd_rows" : "spx_maxpool_bwd";
  if ((st = spx_cl_kernel(ctx, rows ? SPX_K_MAXPOOL_BWD_ROWS : SPX_K_MAXPOOL_BWD, &k))) return st;
  cl_int e = spx_nn_arg(k, 0, x) | spx_nn_arg(k, 2, dy) | spx_nn_arg(k, 4, dx) | SPX_ARG(k, 6, x->h) |
             SPX_ARG(k, 7, x->w);
  if ((st = spx_cl_check(ctx, e, name))) return st;
  return spx_nn_run3d(ctx, k, rows ? ((size_t)dy->w + 15) / 16 : (size_t)dy->w, (size_t)dy->h,
                      (size_t)dy->n * (size_t)dy->c, name);
}

static spx_status avg_shapes(spx_ctx *ctx, const char *op, const spx_tensor *x, const spx_tensor *y, const char *xn,
                             const char *yn) {
  spx_status st;
  if ((st = spx_nn_check(ctx, x, op, xn)) || (st = spx_nn_check(ctx, y, op, yn))) return st;
  if (x->h < 1 || x->w < 1 || y->n != x->n || y->c != x->c || y->h != spx_avgpool3_out(x->h) ||
      y->w != spx_avgpool3_out(x->w))
    return spx_fail(ctx, SPX_E_ARG, "%s: %s is %dx%dx%dx%d, 3x3/2 pooling of %dx%dx%dx%d gives %dx%dx%dx%d", op, yn,
                    y->n, y->c, y->h, y->w, x->n, x->c, x->h, x->w, x->n, x->c, spx_avgpool3_out(x->h),
                    spx_avgpool3_out(x->w));
  return SPX_OK;
}

/* spx_avgpool3_fwd (in = x, out = y) or spx_avgpool3_bwd (in = dy, out = dx): full is the
 * un-pooled tensor (x or dx), one work-item per element of grid (y or dx). */
static spx_status avg_run(spx_ctx *ctx, spx_kernel_id id, const spx_tensor *in, const spx_tensor *out,
                          const spx_tensor *full, const spx_tensor *grid) {
  const char *name = spx_cl_kernel_name(id);
  cl_kernel k;
  spx_status st = spx_cl_kernel(ctx, id, &k);
  if (st) return st;
  cl_int e = spx_nn_arg(k, 0, in) | spx_nn_arg(k, 2, out) | SPX_ARG(k, 4, full->h) | SPX_ARG(k, 5, full->w);
  if ((st = spx_cl_check(ctx, e, name))) return st;
  return spx_nn_run3d(ctx, k, (size_t)grid->w, (size_t)grid->h, (size_t)grid->n * (size_t)grid->c, name);
}

spx_status spx_avgpool3_forward(spx_ctx *ctx, const spx_tensor *x, const spx_tensor *y) {
  spx_status st = avg_shapes(ctx, "avgpool3_forward", x, y, "x", "y");
  return st ? st : avg_run(ctx, SPX_K_AVGPOOL3_FWD, x, y, x, y);
}

spx_status spx_avgpool3_backward(spx_ctx *ctx, const spx_tensor *dy, const spx_tensor *dx) {
  if (!dx) return SPX_OK;
  spx_status st = avg_shapes(ctx, "avgpool3_backward", dx, dy, "dx", "dy");
  return st ? st : avg_run(ctx, SPX_K_AVGPOOL3_BWD, dy, dx, dx, dx);
}

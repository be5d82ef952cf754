/* Launchers for kernels/instnorm.cl (lib/nn/instnorm.h). */
#include "nn/instnorm.h"

#include "nn/nn_internal.h"

/* spx_instnorm_fwd (x, save, y = a, eps) or spx_instnorm_bwd (x, save, dy = a, dx = b): one work-group
 * per plane. */
static spx_status launch(spx_ctx *ctx, spx_kernel_id id, const spx_tensor *x, const spx_tensor *save,
                         const spx_tensor *a, const spx_tensor *b, float eps) {
  const char *name = spx_cl_kernel_name(id);
  cl_kernel k;
  spx_status st = spx_cl_kernel(ctx, id, &k);
  if (st) return st;
  cl_int planes = x->n * x->c, hw = x->h * x->w, i = b ? 8 : 6;
  cl_int e = spx_nn_arg(k, 0, x) | spx_nn_arg(k, 2, save) | spx_nn_arg(k, 4, a) | SPX_ARG(k, i, planes) |
             SPX_ARG(k, i + 1, hw);
  e |= b ? spx_nn_arg(k, 6, b) : SPX_ARG(k, 8, eps);
  if ((st = spx_cl_check(ctx, e, name))) return st;
  return spx_nn_run_groups(ctx, k, (size_t)planes, name);
}

spx_status spx_instnorm_forward(spx_ctx *ctx, const spx_tensor *x, float eps, const spx_tensor *save,
                                const spx_tensor *y) {
  const char *op = "instnorm_forward";
  spx_status st;
  if ((st = spx_nn_check(ctx, x, op, "x")) || (st = spx_nn_check(ctx, y, op, "y")) ||
      (st = spx_nn_check_numel(ctx, save, op, "save", 2 * (size_t)x->n * (size_t)x->c)))
    return st;
  if (!spx_nn_same_shape(x, y)) return spx_nn_shape_mismatch(ctx, op, "y vs x", y, x);
  if (!(eps >= 0) || !isfinite(eps)) return spx_fail(ctx, SPX_E_ARG, "%s: eps %g invalid", op, eps);
  if (x->n < 1 || x->c < 1 || x->h < 1 || x->w < 1) return spx_fail(ctx, SPX_E_ARG, "%s: empty input", op);
  return launch(ctx, SPX_K_INSTNORM_FWD, x, save, y, NULL, eps);
}

spx_status spx_instnorm_backward(spx_ctx *ctx, const spx_tensor *x, const spx_tensor *save, const spx_tensor *dy,
                                 const spx_tensor *dx) {
  const char *op = "instnorm_backward";
  spx_status st;
  if (!dx) return SPX_OK;
  if ((st = spx_nn_check(ctx, x, op, "x")) || (st = spx_nn_check(ctx, dy, op, "dy")) ||
      (st = spx_nn_check(ctx, dx, op, "dx")) ||
      (st = spx_nn_check_numel(ctx, save, op, "save", 2 * (size_t)x->n * (size_t)x->c)))
    return st;
  if (!spx_nn_same_shape(x, dy)) return spx_nn_shape_mismatch(ctx, op, "dy vs x", dy, x);
  if (!spx_nn_same_shape(x, dx)) return spx_nn_shape_mismatch(ctx, op, "dx vs x", dx, x);
  return launch(ctx, SPX_K_INSTNORM_BWD, x, save, dy, dx, 0);
}

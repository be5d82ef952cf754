/* Launchers for kernels/batchnorm.cl. */
#include "nn/batchnorm.h"

#include "nn/nn_internal.h"

#include <string.h>

/* The argument checks the train-mode forward launchers share (the sync one adds its own). */
static spx_status fwd_check(spx_ctx *ctx, const char *op, const spx_tensor *x, const spx_tensor *weight,
                            const spx_tensor *bias, const spx_tensor *running_mean, const spx_tensor *running_var,
                            int update_running, const spx_tensor *save, const spx_tensor *y) {
  spx_status st;
  if ((st = spx_nn_check(ctx, x, op, "x")) || (st = spx_nn_check(ctx, y, op, "y"))) return st;
  size_t c = (size_t)x->c;
  if ((st = spx_nn_check_numel(ctx, weight, op, "weight", c)) || (st = spx_nn_check_numel(ctx, bias, op, "bias", c)) ||
      (st = spx_nn_check_numel(ctx, save, op, "save", 2 * c)))
    return st;
  if (update_running &&
      ((st = spx_nn_check_numel(ctx, running_mean, op, "running_mean", c)) ||
       (st = spx_nn_check_numel(ctx, running_var, op, "running_var", c))))
    return st;
  if (!spx_nn_same_shape(x, y)) return spx_nn_shape_mismatch(ctx, op, "y vs x", y, x);
  return SPX_OK;
}

/* ... and the backward ones. */
static spx_status bwd_check(spx_ctx *ctx, const char *op, const spx_tensor *x, const spx_tensor *weight,
                            const spx_tensor *save, const spx_tensor *dy, const spx_tensor *dx,
                            const spx_tensor *dweight, const spx_tensor *dbias) {
  spx_status st;
  if ((st = spx_nn_check(ctx, x, op, "x")) || (st = spx_nn_check(ctx, dy, op, "dy"))) return st;
  size_t c = (size_t)x->c;
  if ((st = spx_nn_check_numel(ctx, weight, op, "weight", c)) ||
      (st = spx_nn_check_numel(ctx, save, op, "save", 2 * c)))
    return st;
  if (!spx_nn_same_shape(x, dy)) return spx_nn_shape_mismatch(ctx, op, "dy vs x", dy, x);
  if (dx && (st = spx_nn_check(ctx, dx, op, "dx"))) return st;
  if (dx && !spx_nn_same_shape(x, dx)) return spx_nn_shape_mismatch(ctx, op, "dx vs x", dx, x);
  if ((dweight && (st = spx_nn_check_numel(ctx, dweight, op, "dweight", c))) ||
      (dbias && (st = spx_nn_check_numel(ctx, dbias, op, "dbias", c))))
    return st;
  return SPX_OK;
}

spx_status spx_bn_train_forward(spx_ctx *ctx, const spx_tensor *x, const spx_tensor *weight, const spx_tensor *bias,
                                const spx_tensor *running_mean, const spx_tensor *running_var, float momentum,
                                float eps, int update_running, const spx_tensor *save, const spx_tensor *y) {
  return spx_bn_relu_train_forward(ctx, x, weight, bias, running_mean, running_var, momentum, eps, update_running, save,
                                   0, y);
}

spx_status spx_bn_relu_train_forward(spx_ctx *ctx, const spx_tensor *x, const spx_tensor *weight,
                                     const spx_tensor *bias, const spx_tensor *running_mean,
                                     const spx_tensor *running_var, float momentum, float eps, int update_running,
                                     const spx_tensor *save, int relu, const spx_tensor *y) {
  const char *op = relu ? "bn_relu_train_forward" : "bn_train_forward";
  spx_status st;
  cl_kernel k;
  if ((st = fwd_check(ctx, op, x, weight, bias, running_mean, running_var, update_running, save, y))) return st;
  if ((long)x->n * x->h * x->w <= 1)
    return spx_fail(ctx, SPX_E_ARG, "%s: expected more than 1 value per channel when training, got input %dx%dx%dx%d", op,
                    x->n, x->c, x->h, x->w);
  if (!isfinite(momentum) || !isfinite(eps) || eps < 0)
    return spx_fail(ctx, SPX_E_ARG, "%s: momentum %g / eps %g invalid", op, momentum, eps);
  if ((st = spx_cl_kernel(ctx, SPX_K_BN_TRAIN_FWD, &k))) return st;
  const spx_tensor *rm = update_running ? running_mean : x, *rv = update_running ? running_var : x; /* unused if !update */
  cl_int hw = x->h * x->w, upd = update_running ? 1 : 0, rl = relu != 0;
  cl_int e = spx_nn_arg(k, 0, x) | spx_nn_arg(k, 2, weight) | spx_nn_arg(k, 4, bias) | spx_nn_arg(k, 6, rm) |
             spx_nn_arg(k, 8, rv) | spx_nn_arg(k, 10, save) | spx_nn_arg(k, 12, y) | SPX_ARG(k, 14, x->n) |
             SPX_ARG(k, 15, x->c) | SPX_ARG(k, 16, hw) | SPX_ARG(k, 17, momentum) | SPX_ARG(k, 18, eps) |
             SPX_ARG(k, 19, upd) | SPX_ARG(k, 20, rl);
  if ((st = spx_cl_check(ctx, e, "spx_bn_train_fwd"))) return st;
  return spx_nn_run_groups(ctx, k, (size_t)x->c, "spx_bn_train_fwd");
}

spx_status spx_bn_eval_forward(spx_ctx *ctx, const spx_tensor *x, const spx_tensor *weight, const spx_tensor *bias,
                               const spx_tensor *running_mean, const spx_tensor *running_var, float eps,
                               const spx_tensor *y) {
  const char *op = "bn_eval_forward";
  spx_status st;
  cl_kernel k;
  if ((st = spx_nn_check(ctx, x, op, "x")) || (st = spx_nn_check(ctx, y, op, "y"))) return st;
  size_t c = (size_t)x->c;
  if ((st = spx_nn_check_numel(ctx, weight, op, "weight", c)) || (st = spx_nn_check_numel(ctx, bias, op, "bias", c)) ||
      (st = spx_nn_check_numel(ctx, running_mean, op, "running_mean", c)) ||
      (st = spx_nn_check_numel(ctx, running_var, op, "running_var", c)))
    return st;
  if (!spx_nn_same_shape(x, y)) return spx_nn_shape_mismatch(ctx, op, "y vs x", y, x);
  if ((st = spx_cl_kernel(ctx, SPX_K_BN_EVAL_FWD, &k))) return st;
  cl_int hw = x->h * x->w, planes = x->n * x->c;
  cl_int e = spx_nn_arg(k, 0, x) | spx_nn_arg(k, 2, weight) | spx_nn_arg(k, 4, bias) | spx_nn_arg(k, 6, running_mean) |
             spx_nn_arg(k, 8, running_var) | spx_nn_arg(k, 10, y) | SPX_ARG(k, 12, x->c) | SPX_ARG(k, 13, hw) |
             SPX_ARG(k, 14, planes) | SPX_ARG(k, 15, eps);
  if ((st = spx_cl_check(ctx, e, "spx_bn_eval_fwd"))) return st;
  return spx_nn_run3d(ctx, k, (size_t)hw, (size_t)x->n * (size_t)x->c, 1, "spx_bn_eval_fwd");
}

spx_status spx_bn_train_backward(spx_ctx *ctx, const spx_tensor *x, const spx_tensor *weight, const spx_tensor *save,
                                 const spx_tensor *dy, const spx_tensor *dx, const spx_tensor *dweight,
                                 const spx_tensor *dbias) {
  return spx_bn_relu_train_backward(ctx, x, weight, NULL, save, dy, dx, dweight, dbias);
}

spx_status spx_bn_relu_train_backward(spx_ctx *ctx, const spx_tensor *x, const spx_tensor *weight,
                                      const spx_tensor *bias, const spx_tensor *save, const spx_tensor *dy,
                                      const spx_tensor *dx, const spx_tensor *dweight, const spx_tensor *dbias) {
  const char *op = bias ? "bn_relu_train_backward" : "bn_train_backward";
  spx_status st;
  cl_kernel k;
  if (!dx && !dweight && !dbias) return SPX_OK;
  if ((st = bwd_check(ctx, op, x, weight, save, dy, dx, dweight, dbias)) ||
      (bias && (st = spx_nn_check_numel(ctx, bias, op, "bias", (size_t)x->c))))
    return st;
  if ((st = spx_cl_kernel(ctx, SPX_K_BN_TRAIN_BWD, &k))) return st;
  cl_int hw = x->h * x->w, want = (dx ? 1 : 0) | (dweight ? 2 : 0) | (dbias ? 4 : 0);
  /* unwanted outputs get a harmless stand-in buffer that the kernel never writes */
  cl_int e = spx_nn_arg(k, 0, x) | spx_nn_arg(k, 2, weight) | spx_nn_arg(k, 4, save) | spx_nn_arg(k, 6, dy) |
             spx_nn_arg(k, 8, dx ? dx : dy) | spx_nn_arg(k, 10, dweight ? dweight : weight) |
             spx_nn_arg(k, 12, dbias ? dbias : weight) | SPX_ARG(k, 14, x->n) | SPX_ARG(k, 15, x->c) |
             SPX_ARG(k, 16, hw) | SPX_ARG(k, 17, want);
  cl_int rl = bias != NULL;
  e |= spx_nn_arg(k, 18, bias ? bias : weight) | SPX_ARG(k, 20, rl);
  if ((st = spx_cl_check(ctx, e, "spx_bn_train_bwd"))) return st;
  return spx_nn_run_groups(ctx, k, (size_t)x->c, "spx_bn_train_bwd");
}

/* ------------------------------------------------------------------ data-parallel (sync) */

static spx_status sync_sum(spx_ctx *ctx, const spx_bn_sync *s, const spx_tensor *scratch, size_t from, size_t count,
                           size_t to, int mean_of) {
  float *h = s->host;
  spx_status st = spx_cl_read(ctx, scratch->mem, (scratch->off + from) * sizeof(float), count * sizeof(float), h);
  if (st) return st;
  if (s->empty) memset(h, 0, count * sizeof(float)); /* a stand-in sample adds nothing */
  if (s->comm->allreduce_sum(s->comm->self, h, count))
    return spx_fail(ctx, SPX_E_IO, "batchnorm: summing %zu statistics over %d ranks failed", count, s->comm->size);
  if (mean_of) {
    float cnt = (float)s->count;
    for (size_t i = 0; i < count; i++) h[i] = h[i] / cnt;
  }
  return spx_cl_write(ctx, scratch->mem, (scratch->off + to) * sizeof(float), count * sizeof(float), h);
}

static spx_status sync_part(spx_ctx *ctx, const spx_tensor *x, const spx_tensor *dy, const spx_tensor *mean,
                            size_t mean_off, const spx_tensor *scratch, int mode) {
  cl_kernel k;
  spx_status st;
  if ((st = spx_cl_kernel(ctx, SPX_K_BN_SYNC_PART, &k))) return st;
  cl_int hw = x->h * x->w, mo = (cl_int)(mean->off + mean_off), md = mode;
  cl_int e = spx_nn_arg(k, 0, x) | spx_nn_arg(k, 2, dy) | SPX_ARG(k, 4, mean->mem) |
             SPX_ARG(k, 5, mo) | spx_nn_arg(k, 6, scratch) | SPX_ARG(k, 8, x->n) | SPX_ARG(k, 9, x->c) |
             SPX_ARG(k, 10, hw) | SPX_ARG(k, 11, md);
  if ((st = spx_cl_check(ctx, e, "spx_bn_sync_part"))) return st;
  return spx_nn_run_groups(ctx, k, (size_t)x->c, "spx_bn_sync_part");
}

static spx_status sync_check(spx_ctx *ctx, const char *op, const spx_tensor *x, const spx_tensor *scratch,
                             const spx_bn_sync *s) {
  spx_status st;
  if (!s || !s->comm || !s->comm->allreduce_sum || !s->host)
    return spx_fail(ctx, SPX_E_ARG, "%s: no communicator or host scratch", op);
  if (!(s->count > 1))
    return spx_fail(ctx, SPX_E_ARG, "%s: expected more than 1 value per channel in the global batch, got %.0f", op,
                    s->count);
  if ((st = spx_nn_check(ctx, x, op, "x"))) return st;
  return spx_nn_check_numel(ctx, scratch, op, "scratch", 4 * (size_t)x->c);
}

spx_status spx_bn_sync_train_forward(spx_ctx *ctx, const spx_tensor *x, const spx_tensor *weight,
                                     const spx_tensor *bias, const spx_tensor *running_mean,
                                     const spx_tensor *running_var, float momentum, float eps, int update_running,
                                     const spx_tensor *save, const spx_tensor *scratch, const spx_tensor *y,
                                     const spx_bn_sync *s) {
  const char *op = "bn_sync_train_forward";
  spx_status st;
  cl_kernel k;
  if ((st = sync_check(ctx, op, x, scratch, s)) ||
      (st = fwd_check(ctx, op, x, weight, bias, running_mean, running_var, update_running, save, y)))
    return st;
  size_t c = (size_t)x->c;
  if (!isfinite(momentum) || !isfinite(eps) || eps < 0)
    return spx_fail(ctx, SPX_E_ARG, "%s: momentum %g / eps %g invalid", op, momentum, eps);
  /* scratch: [0, c) this rank's partial sums, [2c, 3c) the global mean, [3c, 4c) the global variance */
  if ((st = sync_part(ctx, x, x, scratch, 0, scratch, 0)) || (st = sync_sum(ctx, s, scratch, 0, c, 2 * c, 1)) ||
      (st = sync_part(ctx, x, x, scratch, 2 * c, scratch, 1)) || (st = sync_sum(ctx, s, scratch, 0, c, 3 * c, 1)))
    return st;
  if ((st = spx_cl_kernel(ctx, SPX_K_BN_SYNC_FWD, &k))) return st;
  const spx_tensor *rm = update_running ? running_mean : x, *rv = update_running ? running_var : x;
  spx_tensor stats = *scratch;
  stats.off += 2 * c;
  cl_int hw = x->h * x->w, upd = update_running ? 1 : 0;
  cl_float cnt = (cl_float)s->count;
  cl_int e = spx_nn_arg(k, 0, x) | spx_nn_arg(k, 2, weight) | spx_nn_arg(k, 4, bias) | spx_nn_arg(k, 6, rm) |
             spx_nn_arg(k, 8, rv) | spx_nn_arg(k, 10, &stats) | spx_nn_arg(k, 12, save) | spx_nn_arg(k, 14, y) |
             SPX_ARG(k, 16, x->n) | SPX_ARG(k, 17, x->c) | SPX_ARG(k, 18, hw) | SPX_ARG(k, 19, cnt) |
             SPX_ARG(k, 20, momentum) | SPX_ARG(k, 21, eps) | SPX_ARG(k, 22, upd);
  if ((st = spx_cl_check(ctx, e, "spx_bn_sync_fwd"))) return st;
  return spx_nn_run_groups(ctx, k, (size_t)x->c, "spx_bn_sync_fwd");
}

spx_status spx_bn_sync_train_backward(spx_ctx *ctx, const spx_tensor *x, const spx_tensor *weight,
                                      const spx_tensor *save, const spx_tensor *scratch, const spx_tensor *dy,
                                      const spx_tensor *dx, const spx_tensor *dweight, const spx_tensor *dbias,
                                      const spx_bn_sync *s) {
  const char *op = "bn_sync_train_backward";
  spx_status st;
  cl_kernel k;
  if ((st = sync_check(ctx, op, x, scratch, s)) || (st = bwd_check(ctx, op, x, weight, save, dy, dx, dweight, dbias)))
    return st;
  size_t c = (size_t)x->c;
  /* every rank takes part in the sums even when it wants no gradient (the others wait for it) */
  if ((st = sync_part(ctx, x, dy, save, 0, scratch, 2)) || (st = sync_sum(ctx, s, scratch, 0, 2 * c, 2 * c, 0)))
    return st;
  if (s->empty) return SPX_OK; /* a stand-in: nothing of it may reach a gradient */
  if (!dx && !dweight && !dbias) return SPX_OK;
  if ((st = spx_cl_kernel(ctx, SPX_K_BN_SYNC_BWD, &k))) return st;
  cl_int hw = x->h * x->w, want = (dx ? 1 : 0) | (dweight ? 2 : 0) | (dbias ? 4 : 0);
  cl_float cnt = (cl_float)s->count;
  cl_int e = spx_nn_arg(k, 0, x) | spx_nn_arg(k, 2, weight) | spx_nn_arg(k, 4, save) | spx_nn_arg(k, 6, dy) |
             spx_nn_arg(k, 8, dx ? dx : dy) | spx_nn_arg(k, 10, dweight ? dweight : weight) |
             spx_nn_arg(k, 12, dbias ? dbias : weight) | spx_nn_arg(k, 14, scratch) | SPX_ARG(k, 16, x->n) |
             SPX_ARG(k, 17, x->c) | SPX_ARG(k, 18, hw) | SPX_ARG(k, 19, cnt) | SPX_ARG(k, 20, want);
  if ((st = spx_cl_check(ctx, e, "spx_bn_sync_bwd"))) return st;
  return spx_nn_run_groups(ctx, k, (size_t)x->c, "spx_bn_sync_bwd");
}

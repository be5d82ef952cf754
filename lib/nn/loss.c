/* Launchers for kernels/loss.cl: two-stage deterministic reductions and L1 / MSE losses. */
#include <string.h>

#include "nn/loss.h"

#include "nn/nn_internal.h"

/* Work-groups (= partial sums) of a reduction over n elements. */
static size_t reduce_groups(const spx_ctx *ctx, size_t n) {
  size_t wg = (size_t)ctx->dev->tune.red_wg, maxg = (size_t)ctx->dev->tune.red_groups;
  size_t groups = (n + wg - 1) / wg;
  if (groups > maxg) groups = maxg;
  return groups < 1 ? 1 : groups;
}

void spx_loss_forward_need(const spx_ctx *ctx, size_t numel, spx_ws_need *need) {
  memset(need, 0, sizeof *need);
  need->slot[0] = reduce_groups(ctx, numel) * sizeof(float);
}

/* kind: 0 value, 1 L1, 2 MSE (the kernel's term). b may equal a for kind 0. */
static spx_status reduce_run(spx_ctx *ctx, const char *op, int kind, const spx_tensor *a, const spx_tensor *b, float div,
                             const spx_tensor *out, spx_op_workspace *ws) {
  spx_status st;
  cl_kernel k1, k2;
  spx_op_scratch ps = {0};
  size_t wg = (size_t)ctx->dev->tune.red_wg;
  if (wg > ctx->dev->info.max_work_group)
    return spx_fail(ctx, SPX_E_UNSUPPORTED, "%s: SPX_RED_WG=%zu exceeds the device's work-group limit %zu", op, wg,
                    ctx->dev->info.max_work_group);
  if (spx_tensor_numel(out) != 1) return spx_fail(ctx, SPX_E_ARG, "%s: out must have one element", op);
  size_t n = spx_tensor_numel(a), groups = reduce_groups(ctx, n);
  if (n > (size_t)INT_MAX - groups * wg) /* the kernel's grid-stride index must not overflow */
    return spx_fail(ctx, SPX_E_ARG, "%s: %zu elements are too many for one reduction", op, n);
  if ((st = spx_cl_kernel(ctx, SPX_K_REDUCE_STAGE1, &k1)) ||
      (st = spx_cl_kernel(ctx, SPX_K_REDUCE_STAGE2, &k2)))
    return st;
  /* released right after enqueueing: OpenCL frees it once the queued kernels are done */
  if ((st = spx_op_scratch_get(ctx, ws, 0, groups * sizeof(float), "reduction partial sums", &ps))) return st;
  cl_mem partial = ps.mem;
  cl_int ni = (cl_int)n, kd = kind, np = (cl_int)groups;
  cl_int e = spx_nn_arg(k1, 0, a) | spx_nn_arg(k1, 2, b) | SPX_ARG(k1, 4, ni) | SPX_ARG(k1, 5, kd) |
             SPX_ARG(k1, 6, partial);
  size_t g1 = groups * wg;
  if (!(st = spx_cl_check(ctx, e, "spx_reduce_stage1")) && !(st = spx_cl_run(ctx, k1, 1, &g1, &wg, "spx_reduce_stage1"))) {
    e = SPX_ARG(k2, 0, partial) | SPX_ARG(k2, 1, np) | spx_nn_arg(k2, 2, out) | SPX_ARG(k2, 4, div);
    if (!(st = spx_cl_check(ctx, e, "spx_reduce_stage2"))) st = spx_cl_run(ctx, k2, 1, &wg, &wg, "spx_reduce_stage2");
  }
  spx_op_scratch_put(&ps);
  return st;
}

spx_status spx_reduce(spx_ctx *ctx, spx_reduction r, const spx_tensor *x, const spx_tensor *out) {
  spx_status st;
  if ((st = spx_nn_check(ctx, x, "reduce", "x")) || (st = spx_nn_check(ctx, out, "reduce", "out"))) return st;
  float div = r == SPX_REDUCE_MEAN ? (float)spx_tensor_numel(x) : 1.0f;
  return reduce_run(ctx, "reduce", 0, x, x, div, out, NULL);
}

static spx_status loss_check(spx_ctx *ctx, const char *op, spx_loss_kind kind, spx_reduction r, const spx_tensor *pred,
                             const spx_tensor *target) {
  spx_status st;
  if (kind != SPX_LOSS_L1 && kind != SPX_LOSS_MSE) return spx_fail(ctx, SPX_E_ARG, "%s: unknown loss %d", op, (int)kind);
  if (r != SPX_REDUCE_MEAN && r != SPX_REDUCE_SUM) return spx_fail(ctx, SPX_E_ARG, "%s: unknown reduction %d", op, (int)r);
  if ((st = spx_nn_check(ctx, pred, op, "pred")) || (st = spx_nn_check(ctx, target, op, "target"))) return st;
  if (!spx_nn_same_shape(pred, target)) return spx_nn_shape_mismatch(ctx, op, "target vs pred", target, pred);
  return SPX_OK;
}

spx_status spx_loss_forward(spx_ctx *ctx, spx_loss_kind kind, spx_reduction r, const spx_tensor *pred,
                            const spx_tensor *target, const spx_tensor *out) {
  return spx_loss_forward_ws(ctx, kind, r, pred, target, out, NULL);
}

spx_status spx_loss_forward_ws(spx_ctx *ctx, spx_loss_kind kind, spx_reduction r, const spx_tensor *pred,
                               const spx_tensor *target, const spx_tensor *out, spx_op_workspace *ws) {
  spx_status st;
  if ((st = loss_check(ctx, "loss_forward", kind, r, pred, target)) || (st = spx_nn_check(ctx, out, "loss_forward", "out")))
    return st;
  float div = r == SPX_REDUCE_MEAN ? (float)spx_tensor_numel(pred) : 1.0f;
  return reduce_run(ctx, "loss_forward", (int)kind, pred, target, div, out, ws);
}

static spx_status loss_grad(spx_ctx *ctx, spx_loss_kind kind, spx_reduction r, const spx_tensor *pred,
                            const spx_tensor *target, const spx_tensor *dout, const spx_tensor *d, float sign) {
  spx_status st;
  cl_kernel k;
  if ((st = spx_nn_check(ctx, d, "loss_backward", sign > 0 ? "dpred" : "dtarget"))) return st;
  if (!spx_nn_same_shape(pred, d)) return spx_nn_shape_mismatch(ctx, "loss_backward", "gradient vs pred", d, pred);
  if ((st = spx_cl_kernel(ctx, SPX_K_LOSS_BWD, &k))) return st;
  size_t n = spx_tensor_numel(pred);
  cl_int ni = (cl_int)n, kd = (cl_int)kind;
  float div = r == SPX_REDUCE_MEAN ? (float)n : 1.0f;
  float norm = (float)(r == SPX_REDUCE_MEAN ? 2.0 / (double)n : 2.0);
  cl_int e = spx_nn_arg(k, 0, pred) | spx_nn_arg(k, 2, target) | spx_nn_arg(k, 4, dout) | spx_nn_arg(k, 6, d) |
             SPX_ARG(k, 8, ni) | SPX_ARG(k, 9, kd) | SPX_ARG(k, 10, div) | SPX_ARG(k, 11, norm) | SPX_ARG(k, 12, sign);
  if ((st = spx_cl_check(ctx, e, "spx_loss_bwd"))) return st;
  return spx_nn_run1d(ctx, k, n, "spx_loss_bwd");
}

spx_status spx_loss_backward(spx_ctx *ctx, spx_loss_kind kind, spx_reduction r, const spx_tensor *pred,
                             const spx_tensor *target, const spx_tensor *dout, const spx_tensor *dpred,
                             const spx_tensor *dtarget) {
  spx_status st;
  if (!dpred && !dtarget) return SPX_OK;
  if ((st = loss_check(ctx, "loss_backward", kind, r, pred, target)) ||
      (st = spx_nn_check(ctx, dout, "loss_backward", "dout")))
    return st;
  if (spx_tensor_numel(dout) != 1) return spx_fail(ctx, SPX_E_ARG, "loss_backward: dout must have one element");
  if (dpred && (st = loss_grad(ctx, kind, r, pred, target, dout, dpred, 1.0f))) return st;
  if (dtarget && (st = loss_grad(ctx, kind, r, pred, target, dout, dtarget, -1.0f))) return st;
  return SPX_OK;
}

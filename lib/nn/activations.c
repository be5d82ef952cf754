/* Launchers for kernels/activations.cl. */
#include "nn/activations.h"

#include "nn/nn_internal.h"

#define FWD(ID, name, saves, f, df) SPX_K_##ID##_FWD,
#define BWD(ID, name, saves, f, df) SPX_K_##ID##_BWD,
#define NAME(ID, name, saves, f, df) name,
static const spx_kernel_id fwd_kernels[] = {SPX_ACT_LIST(FWD)};
static const spx_kernel_id bwd_kernels[] = {SPX_ACT_LIST(BWD)};
static const char *const names[] = {SPX_ACT_LIST(NAME)};
#undef FWD
#undef BWD
#undef NAME

const char *spx_act_name(spx_act_kind k) { return k >= 0 && k < SPX_ACT_COUNT ? names[k] : "?"; }

static spx_status check_kind(spx_ctx *ctx, spx_act_kind kind, float slope, const char *op) {
  if (kind < 0 || kind >= SPX_ACT_COUNT) return spx_fail(ctx, SPX_E_ARG, "%s: unknown activation %d", op, (int)kind);
  if (kind == SPX_ACT_LEAKY_RELU && !isfinite(slope))
    return spx_fail(ctx, SPX_E_ARG, "%s: LeakyReLU slope is not finite", op);
  return SPX_OK;
}

spx_status spx_act_forward(spx_ctx *ctx, spx_act_kind kind, float slope, const spx_tensor *x, const spx_tensor *y) {
  spx_status st;
  cl_kernel k;
  if ((st = check_kind(ctx, kind, slope, "act_forward")) || (st = spx_nn_check(ctx, x, "act_forward", "x")) ||
      (st = spx_nn_check(ctx, y, "act_forward", "y")))
    return st;
  if (!spx_nn_same_shape(x, y)) return spx_nn_shape_mismatch(ctx, "act_forward", "y vs x", y, x);
  const char *kname = spx_cl_kernel_name(fwd_kernels[kind]);
  if ((st = spx_cl_kernel(ctx, fwd_kernels[kind], &k))) return st;
  cl_int n = (cl_int)spx_tensor_numel(x);
  cl_int e = spx_nn_arg(k, 0, x) | spx_nn_arg(k, 2, y) | SPX_ARG(k, 4, n) | SPX_ARG(k, 5, slope);
  if ((st = spx_cl_check(ctx, e, kname))) return st;
  return spx_nn_run1d(ctx, k, (size_t)n, kname);
}

spx_status spx_act_backward(spx_ctx *ctx, spx_act_kind kind, float slope, const spx_tensor *s, const spx_tensor *dy,
                            const spx_tensor *dx) {
  spx_status st;
  cl_kernel k;
  if (!dx) return SPX_OK;
  if ((st = check_kind(ctx, kind, slope, "act_backward")) || (st = spx_nn_check(ctx, s, "act_backward", "saved")) ||
      (st = spx_nn_check(ctx, dy, "act_backward", "dy")) || (st = spx_nn_check(ctx, dx, "act_backward", "dx")))
    return st;
  if (!spx_nn_same_shape(s, dy)) return spx_nn_shape_mismatch(ctx, "act_backward", "dy vs saved", dy, s);
  if (!spx_nn_same_shape(s, dx)) return spx_nn_shape_mismatch(ctx, "act_backward", "dx vs saved", dx, s);
  const char *kname = spx_cl_kernel_name(bwd_kernels[kind]);
  if ((st = spx_cl_kernel(ctx, bwd_kernels[kind], &k))) return st;
  cl_int n = (cl_int)spx_tensor_numel(s);
  cl_int e = spx_nn_arg(k, 0, s) | spx_nn_arg(k, 2, dy) | spx_nn_arg(k, 4, dx) | SPX_ARG(k, 6, n) | SPX_ARG(k, 7, slope);
  if ((st = spx_cl_check(ctx, e, kname))) return st;
  return spx_nn_run1d(ctx, k, (size_t)n, kname);
}

/* Launchers for kernels/optim.cl. Scalars are computed here in double, as torch.optim does in
 * Python, and handed to the kernel as floats. */
#include <math.h>

#include "nn/optim.h"

#include "nn/nn_internal.h"

static spx_status flat_check(spx_ctx *ctx, const char *op, const spx_tensor *t, const char *name, size_t n) {
  spx_status st = spx_nn_check(ctx, t, op, name);
  if (st) return st;
  if (spx_tensor_numel(t) != n)
    return spx_fail(ctx, SPX_E_ARG, "%s: %s has %zu elements, params have %zu", op, name, spx_tensor_numel(t), n);
  return SPX_OK;
}

spx_status spx_adam_step(spx_ctx *ctx, const spx_adam_params *hp, int64_t step, const spx_tensor *params,
                         const spx_tensor *grads, const spx_tensor *m, const spx_tensor *v) {
  const char *op = "adam_step";
  spx_status st;
  cl_kernel k;
  if (!hp) return spx_fail(ctx, SPX_E_ARG, "%s: missing hyper-parameters", op);
  if (!(hp->lr >= 0) || !(hp->beta1 >= 0 && hp->beta1 < 1) || !(hp->beta2 >= 0 && hp->beta2 < 1) || !(hp->eps >= 0) ||
      !(hp->weight_decay >= 0) || !isfinite(hp->lr) || !isfinite(hp->eps) || !isfinite(hp->weight_decay))
    return spx_fail(ctx, SPX_E_ARG, "%s: invalid hyper-parameters (lr %g, betas %g %g, eps %g, weight_decay %g)", op,
                    hp->lr, hp->beta1, hp->beta2, hp->eps, hp->weight_decay);
  if (step < 1) return spx_fail(ctx, SPX_E_ARG, "%s: step %lld, must be >= 1", op, (long long)step);
  if ((st = spx_nn_check(ctx, params, op, "params"))) return st;
  size_t n = spx_tensor_numel(params);
  if ((st = flat_check(ctx, op, grads, "grads", n)) || (st = flat_check(ctx, op, m, "m", n)) ||
      (st = flat_check(ctx, op, v, "v", n)) || (st = spx_cl_kernel(ctx, SPX_K_ADAM_STEP, &k)))
    return st;
  double bc1 = 1.0 - pow(hp->beta1, (double)step), bc2 = 1.0 - pow(hp->beta2, (double)step);
  float beta1 = (float)hp->beta1, beta2 = (float)hp->beta2, omb1 = (float)(1.0 - hp->beta1),
        omb2 = (float)(1.0 - hp->beta2), bc2_sqrt = (float)sqrt(bc2), neg_step = (float)(-(hp->lr / bc1)),
        eps = (float)hp->eps, wd = (float)hp->weight_decay;
  cl_int ni = (cl_int)n;
  cl_int e = spx_nn_arg(k, 0, params) | spx_nn_arg(k, 2, grads) | spx_nn_arg(k, 4, m) | spx_nn_arg(k, 6, v) |
             SPX_ARG(k, 8, ni) | SPX_ARG(k, 9, beta1) | SPX_ARG(k, 10, beta2) | SPX_ARG(k, 11, omb1) |
             SPX_ARG(k, 12, omb2) | SPX_ARG(k, 13, bc2_sqrt) | SPX_ARG(k, 14, neg_step) | SPX_ARG(k, 15, eps) |
             SPX_ARG(k, 16, wd);
  if ((st = spx_cl_check(ctx, e, "spx_adam_step"))) return st;
  return spx_nn_run1d(ctx, k, n, "spx_adam_step");
}

spx_status spx_sgd_step(spx_ctx *ctx, const spx_sgd_params *hp, int first_step, const spx_tensor *params,
                        const spx_tensor *grads, const spx_tensor *buf) {
  const char *op = "sgd_step";
  spx_status st;
  cl_kernel k;
  if (!hp) return spx_fail(ctx, SPX_E_ARG, "%s: missing hyper-parameters", op);
  if (!(hp->lr >= 0) || !(hp->momentum >= 0) || !(hp->weight_decay >= 0) || !isfinite(hp->lr) ||
      !isfinite(hp->momentum) || !isfinite(hp->dampening) || !isfinite(hp->weight_decay))
    return spx_fail(ctx, SPX_E_ARG, "%s: invalid hyper-parameters (lr %g, momentum %g, dampening %g, weight_decay %g)",
                    op, hp->lr, hp->momentum, hp->dampening, hp->weight_decay);
  if (hp->nesterov && (hp->momentum <= 0 || hp->dampening != 0))
    return spx_fail(ctx, SPX_E_ARG, "%s: nesterov momentum requires a momentum and zero dampening", op);
  if ((st = spx_nn_check(ctx, params, op, "params"))) return st;
  size_t n = spx_tensor_numel(params);
  int use_m = hp->momentum != 0;
  if ((st = flat_check(ctx, op, grads, "grads", n))) return st;
  if (use_m && (st = flat_check(ctx, op, buf, "momentum buffer", n))) return st;
  if ((st = spx_cl_kernel(ctx, SPX_K_SGD_STEP, &k))) return st;
  float neg_lr = (float)-hp->lr, mom = (float)hp->momentum, omd = (float)(1.0 - hp->dampening),
        wd = (float)hp->weight_decay;
  cl_int ni = (cl_int)n, um = use_m, first = first_step ? 1 : 0, nest = hp->nesterov ? 1 : 0;
  const spx_tensor *b = use_m ? buf : grads; /* stand-in, never touched without momentum */
  cl_int e = spx_nn_arg(k, 0, params) | spx_nn_arg(k, 2, grads) | spx_nn_arg(k, 4, b) | SPX_ARG(k, 6, ni) |
             SPX_ARG(k, 7, neg_lr) | SPX_ARG(k, 8, mom) | SPX_ARG(k, 9, omd) | SPX_ARG(k, 10, wd) | SPX_ARG(k, 11, um) |
             SPX_ARG(k, 12, first) | SPX_ARG(k, 13, nest);
  if ((st = spx_cl_check(ctx, e, "spx_sgd_step"))) return st;
  return spx_nn_run1d(ctx, k, n, "spx_sgd_step");
}

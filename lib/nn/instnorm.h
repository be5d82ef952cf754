/* Private: instance norm 2d without affine parameters (torch.nn.InstanceNorm2d(affine=False,
 * track_running_stats=False)): every (n, c) plane is normalised by its own mean and BIASED
 * variance, y = (x - mean) / sqrt(var + eps). Kernels: kernels/instnorm.cl; reference:
 * lib/nn/instnorm_ref.c; tests: tests/test_nn_instnorm.c (FD, device vs reference, PyTorch golden).
 *
 * save holds 2 * n * c floats: [mean of every plane, then 1 / sqrt(var + eps) of every plane];
 * forward writes it, backward reads it. Backward ACCUMULATES into dx:
 *   dx += invstd * (dy - mean(dy) - xhat * mean(dy * xhat)),  xhat = (x - mean) * invstd. */
#ifndef SPX_NN_INSTNORM_H
#define SPX_NN_INSTNORM_H

#include "nn/tensor.h"

#define SPX_IN_EPS 1e-5f

spx_status spx_instnorm_forward(spx_ctx *ctx, const spx_tensor *x, float eps, const spx_tensor *save,
                                const spx_tensor *y);
spx_status spx_instnorm_backward(spx_ctx *ctx, const spx_tensor *x, const spx_tensor *save, const spx_tensor *dy,
                                 const spx_tensor *dx);

void spx_ref_instnorm_forward(const double *x, int planes, int hw, double eps, double *save, double *y);
void spx_ref_instnorm_backward(const double *x, int planes, int hw, const double *save, const double *dy, double *dx);

#endif

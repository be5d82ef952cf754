/* Private: 2x2 stride-2 max pooling, floor mode (kernels/pool.cl), with double references.
 * y is n x c x (h/2) x (w/2). Backward takes the forward INPUT x (the argmax is recomputed:
 * first maximum in row-major window order, NaN wins, like PyTorch) and ACCUMULATES into dx. */
#ifndef SPX_NN_POOL_H
#define SPX_NN_POOL_H

#include "nn/tensor.h"

spx_status spx_maxpool_forward(spx_ctx *ctx, const spx_tensor *x, const spx_tensor *y);
spx_status spx_maxpool_backward(spx_ctx *ctx, const spx_tensor *x, const spx_tensor *dy, const spx_tensor *dx);

void spx_ref_maxpool_forward(const double *x, int n, int c, int h, int w, double *y);
void spx_ref_maxpool_backward(const double *x, const double *dy, int n, int c, int h, int w, double *dx);

#endif

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

/* 3x3 average pooling, stride 2, zero padding 1, count_include_pad = False, floor mode: like
 * nn.AvgPool2d(3, stride=2, padding=1, count_include_pad=False), pix2pixHD's downsampler between
 * discriminator scales. y is n x c x ((h-1)/2+1) x ((w-1)/2+1); every output is the mean of the
 * window's in-image elements. Backward gathers (each dx element sums the outputs whose window
 * holds it): no atomics, deterministic; it ACCUMULATES into dx. */
static inline int spx_avgpool3_out(int in) { return (in - 1) / 2 + 1; }
spx_status spx_avgpool3_forward(spx_ctx *ctx, const spx_tensor *x, const spx_tensor *y);
spx_status spx_avgpool3_backward(spx_ctx *ctx, const spx_tensor *dy, const spx_tensor *dx);

void spx_ref_avgpool3_forward(const double *x, int n, int c, int h, int w, double *y);
void spx_ref_avgpool3_backward(const double *dy, int n, int c, int h, int w, double *dx);

#endif

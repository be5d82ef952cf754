/* Private pieces of lib/metrics: the device max pooling of LPIPS's AlexNet (kernels/metrics.cl) and
 * its plain-C reference (lib/metrics/lpips_ref.c); tests/test_metrics_pool.c compares them. */
#ifndef SPX_METRICS_INTERNAL_H
#define SPX_METRICS_INTERNAL_H

#include "nn/tensor.h"

/* 3x3 stride-2 max pooling without padding, floor mode: y is n x c x ((h-3)/2+1) x ((w-3)/2+1)
 * (x needs h, w >= 3). NaN wins. */
static inline int spx_maxpool3s2_out(int in) { return in < 3 ? 0 : (in - 3) / 2 + 1; }
spx_status spx_maxpool3s2_forward(spx_ctx *ctx, const spx_tensor *x, const spx_tensor *y);
void spx_ref_maxpool3s2_forward(const double *x, int planes, int h, int w, double *y);

#endif

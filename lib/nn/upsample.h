/* Private: bilinear x2 upsampling (kernels/upsample.cl) with PyTorch's formulas for
 * align_corners true and false, and double references. y is n x c x 2h x 2w.
 * Backward ACCUMULATES into dx (deterministic gather, no atomics). */
#ifndef SPX_NN_UPSAMPLE_H
#define SPX_NN_UPSAMPLE_H

#include "nn/tensor.h"

spx_status spx_upsample2x_forward(spx_ctx *ctx, const spx_tensor *x, int align_corners, const spx_tensor *y);
spx_status spx_upsample2x_backward(spx_ctx *ctx, const spx_tensor *dy, int align_corners, const spx_tensor *dx);

void spx_ref_upsample2x_forward(const double *x, int n, int c, int h, int w, int align_corners, double *y);
void spx_ref_upsample2x_backward(const double *dy, int n, int c, int h, int w, int align_corners, double *dx);

#endif

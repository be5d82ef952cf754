/* Private: tensor helpers of the network engine (kernels/tensor_ops.cl):
 * fill/copy/axpy/scale/add, zero pad / crop and channel concat, with double references.
 * Forward ops overwrite their output; backward ops ACCUMULATE into the input gradients. */
#ifndef SPX_NN_TENSOR_OPS_H
#define SPX_NN_TENSOR_OPS_H

#include "nn/tensor.h"

spx_status spx_fill(spx_ctx *ctx, const spx_tensor *t, float value);
spx_status spx_copy(spx_ctx *ctx, const spx_tensor *x, const spx_tensor *y);                  /* y = x  */
spx_status spx_axpy(spx_ctx *ctx, float alpha, const spx_tensor *x, const spx_tensor *y);     /* y += alpha x */
spx_status spx_scale(spx_ctx *ctx, float alpha, const spx_tensor *x);                         /* x *= alpha */
spx_status spx_add(spx_ctx *ctx, const spx_tensor *a, const spx_tensor *b, const spx_tensor *out); /* out = a+b */

/* F.pad(x, (left, right, top, bottom)) with zeros; negative amounts crop. out must be
 * n x c x (h+top+bottom) x (w+left+right). Backward: dx += the matching window of dout. */
spx_status spx_pad_forward(spx_ctx *ctx, const spx_tensor *x, int left, int right, int top, int bottom,
                           const spx_tensor *out);
spx_status spx_pad_backward(spx_ctx *ctx, const spx_tensor *dout, int left, int right, int top, int bottom,
                            const spx_tensor *dx);

/* torch.cat([a, b], dim=1). Backward splits dout and accumulates into da / db (either may be NULL). */
spx_status spx_concat_forward(spx_ctx *ctx, const spx_tensor *a, const spx_tensor *b, const spx_tensor *out);
spx_status spx_concat_backward(spx_ctx *ctx, const spx_tensor *dout, const spx_tensor *da, const spx_tensor *db);
/* One half of concat forward: src (n x cs x h x w) into channels [c0, c0 + cs) of dst (n x cd x
 * h x w); the caller checks the shapes. */
spx_status spx_channel_place(spx_ctx *ctx, const spx_tensor *src, const spx_tensor *dst, int c0);

/* References (double, NCHW, same semantics). */
void spx_ref_pad_forward(const double *x, int n, int c, int h, int w, int left, int right, int top, int bottom,
                         double *out);
void spx_ref_pad_backward(const double *dout, int n, int c, int h, int w, int left, int right, int top, int bottom,
                          double *dx);
void spx_ref_concat_forward(const double *a, const double *b, int n, int ca, int cb, int hw, double *out);
void spx_ref_concat_backward(const double *dout, int n, int ca, int cb, int hw, double *da, double *db);

#endif

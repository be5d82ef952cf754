/* Private: bilinear x2 upsampling (kernels/upsample.cl) with PyTorch's formulas for
 * align_corners true and false, and double references. y is n x c x 2h x 2w.
 * Backward ACCUMULATES into dx (deterministic gather, no atomics). */
#ifndef SPX_NN_UPSAMPLE_H
#define SPX_NN_UPSAMPLE_H

#include "nn/tensor.h"
#include "nn/workspace.h"

spx_status spx_upsample2x_forward(spx_ctx *ctx, const spx_tensor *x, int align_corners, const spx_tensor *y);
spx_status spx_upsample2x_backward(spx_ctx *ctx, const spx_tensor *dy, int align_corners, const spx_tensor *dx);
/* The same with its scratch (slot 0) from ws (NULL: allocated per call); its need for dx of
 * n x c x h x w from spx_upsample2x_backward_need. */
spx_status spx_upsample2x_backward_ws(spx_ctx *ctx, const spx_tensor *dy, int align_corners, const spx_tensor *dx,
                                      spx_op_workspace *ws);
void spx_upsample2x_backward_need(int n, int c, int h, int w, spx_ws_need *need);

/* The UNet up-block's input in one op: out = concat(skip, pad(upsample2x(x))) along channels,
 * the upsampled x at (top, left) of skip's plane (pads >= 0), zeros around it; bit-identical to
 * the three ops. Backward accumulates: dskip += dout[:, :cs], dx += the upsampling backward of
 * the cropped rest (read in place). Either gradient may be NULL. */
spx_status spx_upcat_forward(spx_ctx *ctx, const spx_tensor *skip, const spx_tensor *x, int top, int left,
                             int align_corners, const spx_tensor *out);
spx_status spx_upcat_backward(spx_ctx *ctx, const spx_tensor *dout, int top, int left, int align_corners,
                              const spx_tensor *dskip, const spx_tensor *dx);
/* The same with the upsampling backward's scratch from ws (its need: spx_upsample2x_backward_need
 * of dx's shape). */
spx_status spx_upcat_backward_ws(spx_ctx *ctx, const spx_tensor *dout, int top, int left, int align_corners,
                                 const spx_tensor *dskip, const spx_tensor *dx, spx_op_workspace *ws);

void spx_ref_upsample2x_forward(const double *x, int n, int c, int h, int w, int align_corners, double *y);
void spx_ref_upsample2x_backward(const double *dy, int n, int c, int h, int w, int align_corners, double *dx);

/* References of the fused op: out is n x (cs + cx) x oh x ow, x is n x cx x h x w. */
void spx_ref_upcat_forward(const double *skip, const double *x, int n, int cs, int cx, int h, int w, int oh, int ow,
                           int top, int left, int align_corners, double *out);
void spx_ref_upcat_backward(const double *dout, int n, int cs, int cx, int h, int w, int oh, int ow, int top, int left,
                            int align_corners, double *dskip, double *dx);

#endif

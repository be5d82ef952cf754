/* Private: deterministic reductions and the L1 / MSE losses (kernels/loss.cl), with double
 * references. Scalars (loss values, upstream gradients) are 1-element device tensors.
 * Losses follow F.l1_loss / F.mse_loss with reduction "mean" or "sum"; backward ACCUMULATES
 * into dpred and dtarget (either may be NULL). */
#ifndef SPX_NN_LOSS_H
#define SPX_NN_LOSS_H

#include "nn/tensor.h"
#include "nn/workspace.h"

typedef enum spx_loss_kind { SPX_LOSS_L1 = 1, SPX_LOSS_MSE = 2 } spx_loss_kind;
typedef enum spx_reduction { SPX_REDUCE_MEAN = 0, SPX_REDUCE_SUM = 1 } spx_reduction;

/* out[0] = sum(x) or mean(x) (mean of nothing is NaN, like torch). */
spx_status spx_reduce(spx_ctx *ctx, spx_reduction r, const spx_tensor *x, const spx_tensor *out);

spx_status spx_loss_forward(spx_ctx *ctx, spx_loss_kind kind, spx_reduction r, const spx_tensor *pred,
                            const spx_tensor *target, const spx_tensor *out);
/* The same with the reduction's partial sums (slot 0) from ws (NULL: allocated per call); their
 * need for a pred of numel elements from spx_loss_forward_need. */
spx_status spx_loss_forward_ws(spx_ctx *ctx, spx_loss_kind kind, spx_reduction r, const spx_tensor *pred,
                               const spx_tensor *target, const spx_tensor *out, spx_op_workspace *ws);
void spx_loss_forward_need(const spx_ctx *ctx, size_t numel, spx_ws_need *need);
spx_status spx_loss_backward(spx_ctx *ctx, spx_loss_kind kind, spx_reduction r, const spx_tensor *pred,
                             const spx_tensor *target, const spx_tensor *dout, const spx_tensor *dpred,
                             const spx_tensor *dtarget);

double spx_ref_reduce(spx_reduction r, const double *x, size_t n);
double spx_ref_loss_forward(spx_loss_kind kind, spx_reduction r, const double *pred, const double *target, size_t n);
void spx_ref_loss_backward(spx_loss_kind kind, spx_reduction r, const double *pred, const double *target, size_t n,
                           double dout, double *dpred, double *dtarget);

#endif

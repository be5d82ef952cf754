/* Private: batch norm 2d (kernels/batchnorm.cl) with PyTorch BatchNorm2d semantics (affine,
 * eps, momentum; num_batches_tracked is the caller's counter), and double references.
 *  - weight, bias, running_mean, running_var: C floats each (any tensor shape with C elements).
 *  - save: 2*C floats written by the train forward ([mean, invstd] of the batch), read by the
 *    train backward. Train mode needs more than one value per channel (N*H*W > 1).
 *  - backward (train mode) ACCUMULATES into dx, dweight, dbias; any of them may be NULL. */
#ifndef SPX_NN_BATCHNORM_H
#define SPX_NN_BATCHNORM_H

#include "nn/tensor.h"
#include "smplpix/comm.h"

#define SPX_BN_MOMENTUM 0.1f
#define SPX_BN_EPS 1e-5f

/* update_running: 0 leaves running_mean/var untouched (they may then be NULL). */
spx_status spx_bn_train_forward(spx_ctx *ctx, const spx_tensor *x, const spx_tensor *weight, const spx_tensor *bias,
                                const spx_tensor *running_mean, const spx_tensor *running_var, float momentum,
                                float eps, int update_running, const spx_tensor *save, const spx_tensor *y);
spx_status spx_bn_eval_forward(spx_ctx *ctx, const spx_tensor *x, const spx_tensor *weight, const spx_tensor *bias,
                               const spx_tensor *running_mean, const spx_tensor *running_var, float eps,
                               const spx_tensor *y);
spx_status spx_bn_train_backward(spx_ctx *ctx, const spx_tensor *x, const spx_tensor *weight, const spx_tensor *save,
                                 const spx_tensor *dy, const spx_tensor *dx, const spx_tensor *dweight,
                                 const spx_tensor *dbias);
/* Batch norm + ReLU fused (training): the forward with relu != 0 writes relu(batch norm of x)
 * (the same bits as spx_bn_train_forward then the ReLU of lib/nn/activations.h); the backward takes
 * the gradient of that output and the forward's bias (bias NULL: the plain batch norm backward)
 * and recomputes the ReLU's mask from x, save, weight and bias (the same bits as the ReLU
 * backward into a zeroed gradient, then spx_bn_train_backward). */
spx_status spx_bn_relu_train_forward(spx_ctx *ctx, const spx_tensor *x, const spx_tensor *weight,
                                     const spx_tensor *bias, const spx_tensor *running_mean,
                                     const spx_tensor *running_var, float momentum, float eps, int update_running,
                                     const spx_tensor *save, int relu, const spx_tensor *y);
spx_status spx_bn_relu_train_backward(spx_ctx *ctx, const spx_tensor *x, const spx_tensor *weight,
                                      const spx_tensor *bias, const spx_tensor *save, const spx_tensor *dy,
                                      const spx_tensor *dx, const spx_tensor *dweight, const spx_tensor *dbias);

/* Data-parallel ("synchronised") batch norm: the batch is spread over comm's ranks and the
 * statistics are those of the whole batch (PyTorch's SyncBatchNorm). Every rank calls these with
 * its own shard x in the same order; the per-channel partial sums go through
 * comm->allreduce_sum (2 calls in the forward, 1 in the backward). scratch: 4*C floats of device
 * memory the forward fills and the backward reuses. dweight / dbias receive this rank's part of
 * the gradient (summed over the ranks by the gradient all-reduce before the optimizer step); dx
 * is exact for the global batch. The result equals spx_bn_train_forward / backward on the
 * concatenated batch up to float summation order (tests/test_nn_batchnorm_sync.c). */
typedef struct spx_bn_sync {
  const spx_comm *comm;
  double count; /* values per channel in the global batch (every rank's n * h * w) */
  int empty;    /* this rank has no sample this step: x is a stand-in that contributes nothing */
  float *host;  /* host scratch of at least 2*C floats */
} spx_bn_sync;
spx_status spx_bn_sync_train_forward(spx_ctx *ctx, const spx_tensor *x, const spx_tensor *weight,
                                     const spx_tensor *bias, const spx_tensor *running_mean,
                                     const spx_tensor *running_var, float momentum, float eps, int update_running,
                                     const spx_tensor *save, const spx_tensor *scratch, const spx_tensor *y,
                                     const spx_bn_sync *s);
spx_status spx_bn_sync_train_backward(spx_ctx *ctx, const spx_tensor *x, const spx_tensor *weight,
                                      const spx_tensor *save, const spx_tensor *scratch, const spx_tensor *dy,
                                      const spx_tensor *dx, const spx_tensor *dweight, const spx_tensor *dbias,
                                      const spx_bn_sync *s);

/* References: x is n x c x hw. rm/rv may be NULL (no update). save_mean/save_invstd: c each. */
void spx_ref_bn_train_forward(const double *x, int n, int c, int hw, const double *weight, const double *bias,
                              double *rm, double *rv, double momentum, double eps, double *save_mean,
                              double *save_invstd, double *y);
void spx_ref_bn_eval_forward(const double *x, int n, int c, int hw, const double *weight, const double *bias,
                             const double *rm, const double *rv, double eps, double *y);
void spx_ref_bn_train_backward(const double *x, int n, int c, int hw, const double *weight, const double *save_mean,
                               const double *save_invstd, const double *dy, double *dx, double *dweight,
                               double *dbias);
/* The fused ReLU's backward: dy masked where (x - mean) * invstd * weight + bias > 0, then
 * spx_ref_bn_train_backward. Returns -1 when out of memory (nothing written), else 0. */
int spx_ref_bn_relu_train_backward(const double *x, int n, int c, int hw, const double *weight, const double *bias,
                                   const double *save_mean, const double *save_invstd, const double *dy, double *dx,
                                   double *dweight, double *dbias);

#endif

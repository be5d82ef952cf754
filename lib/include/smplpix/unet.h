/* The SMPLpix UNet (paper §3.2): 4 down / 4 up levels, double conv = [Conv3x3, BatchNorm, ReLU] x2,
 * max-pool down, bilinear x2 (align_corners) up + pad to the skip + concat [skip, up], 1x1 output
 * conv; 4 input channels (RGB-D), 3 output channels, optional sigmoid. Tensor names and shapes are
 * those of the PyTorch "milesial" UNet with bilinear upsampling, so checkpoints move both ways.
 *
 * Tensors cross the API as host float32 NCHW arrays, or, for inference, as a device tensor
 * (smplpix/device.h: e.g. straight from spx_project_to_tensor); everything else stays on the
 * device. Any
 * batch >= 1 and any H, W >= 16 work (odd sizes included). Memory for activations and gradients
 * is planned once per (batch, H, W, mode) and reused. */
#ifndef SMPLPIX_UNET_H
#define SMPLPIX_UNET_H

#include "smplpix/comm.h"
#include "smplpix/core.h"
#include "smplpix/device.h"
#include "smplpix/safetensors.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct spx_unet spx_unet;

#define SPX_UNET_IN_CHANNELS 4
#define SPX_UNET_OUT_CHANNELS 3

/* A new network of base width 8, 16, 32 or 64 (64 = the paper) with PyTorch's default
 * initialisation (Kaiming-uniform convs, BN gamma 1 / beta 0) drawn from `seed`. Needs an open
 * device. */
spx_status spx_unet_create(spx_ctx *ctx, int width, int sigmoid, uint64_t seed, spx_unet **out);
void spx_unet_destroy(spx_unet *u);
int spx_unet_width(const spx_unet *u);
int spx_unet_sigmoid(const spx_unet *u);
void spx_unet_set_sigmoid(spx_unet *u, int on);
/* Number of Adam steps taken so far (restored by spx_unet_load). */
int64_t spx_unet_step(const spx_unet *u);
/* Bytes of device memory the network holds now: parameters, gradients, Adam moments, batch-norm
 * state, the activation (+ gradient) arenas and the convolution scratch. All are grow-only, so
 * after a forward / training step this is the peak of the shapes seen so far (short-lived scratch
 * of a few ops, released within the call, excluded). */
size_t spx_unet_device_bytes(const spx_unet *u);

/* Forward. input [n,4,h,w]; output [n,3,h,w] (may be NULL in training mode).
 * train = 0: inference (batch norm folded into the convolutions, running statistics used,
 * nothing recorded). train = 1: batch statistics, running statistics updated, the pass is
 * recorded for spx_unet_backward. */
spx_status spx_unet_forward(spx_unet *u, const float *input, int n, int h, int w, int train, float *output);
/* Inference forward (as train = 0) reading its input from a device tensor of shape [n, 4, h, w]
 * (smplpix/device.h; e.g. written by spx_project_to_tensor): the input is copied on the device,
 * never through the host, and the result equals spx_unet_forward on the same values bit for bit.
 * output: host [n,3,h,w], or NULL to leave the result on the device (e.g. when timing). */
spx_status spx_unet_forward_tensor(spx_unet *u, const spx_device_tensor *input, float *output);
/* Training forward followed by the mean L1 loss to target [n,3,h,w]; *loss receives its value. */
spx_status spx_unet_forward_loss(spx_unet *u, const float *input, const float *target, int n, int h, int w,
                                 float *output, float *loss);
/* Gradients of the loss of the last spx_unet_forward_loss, ADDED to the parameter gradients. */
spx_status spx_unet_backward(spx_unet *u);
spx_status spx_unet_zero_grad(spx_unet *u);
/* One Adam step (betas 0.9 / 0.999, eps 1e-8, PyTorch's update) over every parameter. */
spx_status spx_unet_adam_step(spx_unet *u, double lr);
/* The same with every hyper-parameter (torch.optim.Adam(lr, betas=(beta1, beta2), eps)). */
spx_status spx_unet_adam_step_ex(spx_unet *u, double lr, double beta1, double beta2, double eps);

/* Data-parallel training (smplpix/comm.h): one network per process, each training step on one
 * shard of a global batch. With a comm of size > 1, spx_unet_adam_step* first sums the gradients
 * over the ranks (a fixed rank order: bit-reproducible), and with sync_bn every training batch
 * norm uses the statistics of the global batch (PyTorch's SyncBatchNorm; without it each rank
 * normalises its shard alone, like PyTorch's DistributedDataParallel). comm must outlive the
 * network's use of it; NULL or size 1 = a single process, exactly as without the call.
 * set_shard: the next steps hold local_n of the global batch's global_n samples on this rank; the
 * loss gradients are scaled by local_n / global_n, so the summed gradients are those of the
 * global batch's mean loss. local_n = 0: this rank has no sample this step; it must still take
 * part (every rank runs every step), on any one stand-in sample, which then contributes nothing.
 * broadcast: rank 0's weights, batch-norm statistics, Adam state and step count into every rank's
 * network (same width everywhere). */
spx_status spx_unet_set_comm(spx_unet *u, const spx_comm *comm, int sync_bn);
spx_status spx_unet_set_shard(spx_unet *u, int local_n, int global_n);
spx_status spx_unet_broadcast(spx_unet *u);

/* Forget the optimizer state: Adam moments to zero, step count to 0 (fine-tuning from weights). */
spx_status spx_unet_reset_optimizer(spx_unet *u);

/* Checkpoints (safetensors). save writes the state_dict names (+ optimizer.<param>.exp_avg,
 * optimizer.<param>.exp_avg_sq and optimizer.step when with_optimizer) to a temporary file renamed
 * over path. load reads the base width from inc.double_conv.0.weight, accepts F32 or F16 weights,
 * ignores tensors it does not know, and restores the optimizer state when optimizer.step is
 * present; the sigmoid flag comes from the metadata key "smplpix.sigmoid" (default off). */
/* Most extra metadata pairs spx_unet_save_meta / spx_unet_save_half take. */
#define SPX_UNET_MAX_META 32
spx_status spx_unet_save(spx_unet *u, const char *path, int with_optimizer);
/* spx_unet_save with extra "__metadata__" string pairs (e.g. the training stage). */
spx_status spx_unet_save_meta(spx_unet *u, const char *path, int with_optimizer, const char *const *keys,
                              const char *const *values, int count);
/* spx_unet_save_meta without the optimizer state, with nextra more tensors (whose names must
 * differ from the network's) in the same file: spx_unet_load skips them. */
spx_status spx_unet_save_extra(spx_unet *u, const char *path, const spx_st_entry *extra, int nextra,
                               const char *const *keys, const char *const *values, int count);
spx_status spx_unet_load(spx_ctx *ctx, const char *path, spx_unet **out);
/* The shipping format: the state_dict (weights, batch-norm running statistics and
 * num_batches_tracked; no optimizer state) as float16 (I64 counters), the metadata of
 * spx_unet_save plus `count` extra string pairs (at most SPX_UNET_MAX_META). PyTorch loads it into the milesial
 * UNet with load_state_dict(strict=True) after .float(); spx_unet_load reads it back. Fails
 * (SPX_E_NUMERIC, naming the tensor) when a value does not fit in float16 (|v| > 65504). */
spx_status spx_unet_save_half(spx_unet *u, const char *path, const char *const *keys, const char *const *values,
                              int count);

/* Introspection, by state_dict name (also "optimizer.<param>.exp_avg" / ".exp_avg_sq"). */
int spx_unet_tensor_count(const spx_unet *u);
/* Name and shape of tensor i (ndim 1 or 4; num_batches_tracked has ndim 0 and is excluded). */
const char *spx_unet_tensor_name(const spx_unet *u, int i, int *ndim, int64_t shape[4]);
typedef enum spx_unet_field { SPX_UNET_VALUE = 0, SPX_UNET_GRAD = 1, SPX_UNET_EXP_AVG = 2, SPX_UNET_EXP_AVG_SQ = 3 } spx_unet_field;
/* Copy a tensor (count floats) to dst; gradients and moments exist for parameters only. */
spx_status spx_unet_read(spx_unet *u, const char *name, spx_unet_field field, float *dst, size_t count);
spx_status spx_unet_write(spx_unet *u, const char *name, const float *src, size_t count);

#ifdef __cplusplus
}
#endif
#endif

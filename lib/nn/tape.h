/* Private: the autodiff tape of the network engine.
 *
 * A tape owns every float of a network: trainable parameters, their gradients and Adam moments
 * (four flat slabs with the same layout, so an optimizer step is one kernel), non-trainable
 * state (batch-norm running statistics), and one arena for the activations and activation gradients
 * for the forward/backward of one input shape.
 *
 * Values are small integer ids (SPX_TAPE_NONE: no value). Parameters and state are declared once
 * (spx_tape_param / spx_tape_state, then spx_tape_alloc_params). A forward pass is one call,
 * spx_tape_pass(t, train, plan_key, build, user): the network's build function creates its inputs
 * and calls the ops (spx_tape_conv, ...); every op creates its output value in the arena, appends
 * a node (kind, input/output ids, saved ids, typed arguments) to the tape and runs. Inference
 * records the nodes too (the liveness plan and the profile read them), but no value needs a
 * gradient: no gradient storage is planned and backward is refused (SPX_E_STATE).
 *
 * Build, plan, run: memory is planned once per plan key (the input shape and anything else that
 * changes the graph). When spx_tape_pass sees a key it has not planned, it first runs the build
 * as a MEASURING pass: the ops only record the graph and run nothing (inputs, device inputs and
 * transfers into the tape are not copied); the recorded graph is planned by liveness
 * (lib/nn/tape_plan.c), the arena sized (grow-only), and the build runs again on the plan. The
 * build therefore runs once or twice per pass and must only call the tape (and compute the same
 * graph each time); the steady state creates no buffers at all.
 *
 * spx_tape_backward(t, loss) walks the nodes in reverse; every op's backward ACCUMULATES into the
 * gradients of its inputs (activation gradients are zeroed when their storage is born; parameter gradients are only
 * zeroed by spx_tape_zero_grad, so gradients of several backward passes add up).
 *
 * Two backends with identical semantics: DEVICE (float32 cl_mem slabs, the lib/nn launchers)
 * and HOST (double arrays, the spx_ref_* references) used by the finite-difference test of the
 * whole graph and as a double-precision oracle.
 *
 * Errors are sticky: after the first failing op every later op is a no-op returning -1, and
 * spx_tape_pass / backward() return the recorded status. */
#ifndef SPX_NN_TAPE_H
#define SPX_NN_TAPE_H

#include "nn/activations.h"
#include "nn/tensor.h"
#include "smplpix/comm.h"

typedef enum spx_tape_backend { SPX_TAPE_DEVICE = 0, SPX_TAPE_HOST = 1 } spx_tape_backend;

typedef struct spx_tape spx_tape;

spx_status spx_tape_create(spx_ctx *ctx, spx_tape_backend backend, spx_tape **out);
void spx_tape_destroy(spx_tape *t);
spx_tape_backend spx_tape_get_backend(const spx_tape *t);

/* ---- parameters and state (declare all, then allocate once) ---- */
int spx_tape_param(spx_tape *t, int32_t n, int32_t c, int32_t h, int32_t w); /* trainable */
int spx_tape_state(spx_tape *t, int32_t n, int32_t c, int32_t h, int32_t w); /* not trainable */
/* Allocate and zero the param/grad/m/v and state slabs. */
spx_status spx_tape_alloc_params(spx_tape *t);
size_t spx_tape_param_count(const spx_tape *t); /* floats in the parameter slab */
/* Bytes of every device buffer the tape holds now: the param/grad/Adam/state slabs and the
 * activation arena, which also holds the ops' scratch (all grow-only, and a planned pass allocates
 * nothing, so after a pass this is the pass's peak). 0 on the host backend. */
size_t spx_tape_device_bytes(const spx_tape *t);

/* Host access to any value's data / gradient as float32 (values of the last forward, params,
 * state). Gradients of state values do not exist. */
spx_status spx_tape_read(spx_tape *t, int id, float *dst);
spx_status spx_tape_write(spx_tape *t, int id, const float *src);
spx_status spx_tape_read_grad(spx_tape *t, int id, float *dst);
/* Host backend: direct double pointers (NULL on the device backend). */
double *spx_tape_host(spx_tape *t, int id);
double *spx_tape_host_grad(spx_tape *t, int id);
/* Device backend: tensor views (mem NULL on the host backend). */
spx_tensor spx_tape_tensor(const spx_tape *t, int id);
spx_tensor spx_tape_grad_tensor(const spx_tape *t, int id);
void spx_tape_shape(const spx_tape *t, int id, int32_t shape[4]);
size_t spx_tape_numel(const spx_tape *t, int id);

/* Optimizer slabs: exp_avg (m) and exp_avg_sq (v) of a parameter. */
spx_status spx_tape_read_moments(spx_tape *t, int id, float *m, float *v);
spx_status spx_tape_write_moments(spx_tape *t, int id, const float *m, const float *v);

/* ---- forward passes (lib/nn/tape_pass.c) ---- */
#define SPX_TAPE_NONE (-1) /* "no value" for optional value arguments (a bias, an axpby's y) */
/* A network's forward: creates its inputs, calls the ops, marks values (keep, requires_grad) and
 * returns SPX_OK, or the failure of a step of its own (op failures are sticky on the tape and
 * reported by spx_tape_pass). */
typedef spx_status (*spx_tape_build_fn)(spx_tape *t, void *user);
/* One forward pass of build (train: record it for backward) under plan_key, planned first when
 * the key is new (the measuring run above). Returns the first failure of the build or an op. */
spx_status spx_tape_pass(spx_tape *t, int train, uint64_t plan_key, spx_tape_build_fn build, void *user);
/* Number of measuring (planning) passes so far. */
int spx_tape_plan_count(const spx_tape *t);
/* A new activation value (inside a build), filled from host data (data NULL: left for a transfer
 * or written later). */
int spx_tape_input(spx_tape *t, int32_t n, int32_t c, int32_t h, int32_t w, const float *data);
/* The same, filled on the device from n*c*h*w floats of src at byte offset `offset` (device
 * backend): no host round trip. */
int spx_tape_input_device(spx_tape *t, int32_t n, int32_t c, int32_t h, int32_t w, cl_mem src, size_t offset);

/* Ops (lib/nn/tape_op_*.c): each returns the output value id (-1 after an error). */
/* ---- convolutions (tape_op_conv.c); bias: a value id or SPX_TAPE_NONE ---- */
/* k x k convolution (k odd), stride 1, zero padding k / 2: the output has x's size. */
int spx_tape_conv(spx_tape *t, int x, int w, int bias);
/* k x k convolution with stride and zero padding (0 <= pad < k): PatchGAN's 4x4 convs. */
int spx_tape_conv_strided(spx_tape *t, int x, int w, int bias, int stride, int pad);
/* Inference only (not differentiable): relu(scale * conv(x, w) + shift) per output channel, k odd,
 * stride 1, padding k / 2: a convolution with its batch norm folded in (scale, shift: values). */
int spx_tape_conv_bn_relu(spx_tape *t, int x, int w, int scale, int shift);
/* ---- normalisations (tape_op_norm.c) ---- */
/* Batch norm over N,H,W in training mode (batch statistics; running_mean/var updated with
 * momentum, unbiased variance, like torch.nn.BatchNorm2d). gamma/beta params, rmean/rvar state. */
int spx_tape_batchnorm(spx_tape *t, int x, int gamma, int beta, int rmean, int rvar, float momentum, float eps);
/* relu(batch norm of x) as one node: the same values and gradients, bit for bit, as
 * spx_tape_batchnorm then spx_tape_act(SPX_ACT_RELU), with one pass over the activation less each
 * way and no stored pre-activation (kernels/batchnorm.cl); two nodes under a synchronised batch
 * norm. */
int spx_tape_batchnorm_relu(spx_tape *t, int x, int gamma, int beta, int rmean, int rvar, float momentum, float eps);
/* InstanceNorm2d(affine=False): per-(n, c) plane mean and biased variance, eps. */
int spx_tape_instnorm(spx_tape *t, int x, float eps);
/* ---- elementwise (tape_op_pointwise.c) ---- */
int spx_tape_act(spx_tape *t, spx_act_kind kind, float slope, int x);
/* a * x + b * y elementwise (y = SPX_TAPE_NONE: a * x); x and y have the same number of
 * elements. Weighted sums of scalar losses are chains of these. */
int spx_tape_axpby(spx_tape *t, float a, int x, float b, int y);
/* ---- resampling (tape_op_resample.c) ---- */
int spx_tape_maxpool2(spx_tape *t, int x);
/* AvgPool2d(3, stride=2, padding=1, count_include_pad=False). */
int spx_tape_avgpool3(spx_tape *t, int x);
int spx_tape_upsample2(spx_tape *t, int x); /* bilinear x2, align_corners = true */
/* ---- layout (tape_op_layout.c) ---- */
int spx_tape_pad(spx_tape *t, int x, int left, int right, int top, int bottom);
int spx_tape_concat(spx_tape *t, int a, int b); /* channels: [a, b] */
/* concat(skip, pad(upsample2(x))) in one op and pass, the pads splitting the size difference like
 * the UNet's up block (F.pad(x, [dx / 2, dx - dx / 2, dy / 2, dy - dy / 2])); bit-identical to the
 * three ops. skip must not be smaller than the upsampled x. */
int spx_tape_upcat(spx_tape *t, int skip, int x);
/* ---- losses (tape_op_loss.c): 1-element values ---- */
/* mean |pred - target|. */
int spx_tape_l1(spx_tape *t, int pred, int target);
/* mean (x - target)^2 over all elements (least-squares GAN). */
int spx_tape_mse_const(spx_tape *t, int x, float target);

/* ---- values without ops (lib/nn/tape.c) ---- */
/* The same data as x, but no gradient flows back through it (torch's .detach()). No copy. */
int spx_tape_detach(spx_tape *t, int x);
/* Samples [n0, n0 + count) of x as a value of its own (no copy); gradients given to the slice land
 * in x's gradient. */
int spx_tape_slice_batch(spx_tape *t, int x, int n0, int count);
/* Mark an activation (an input) as wanting its gradient: call right after creating it, before
 * any op uses it. Its gradient is then readable after backward (spx_tape_read_grad / transfer). */
spx_status spx_tape_requires_grad(spx_tape *t, int id);
/* Keep an activation (and its gradient) alive to the end of the pass and its backward, for reads
 * or gradient transfers from outside after its last reader inside the tape has run. Call it in
 * the build, like requires_grad. Values nothing reads (the outputs) are kept without it. */
spx_status spx_tape_keep(spx_tape *t, int id);
/* Copy (accumulate = 0) or add (accumulate = 1) `count` floats from the value or gradient
 * (src_grad) of src's value sid at float offset soff into the value or gradient (dst_grad) of
 * dst's value did at offset doff. Tapes of one context and backend; the device path stays on the
 * device. This is how networks hand tensors forward (G's image into D's input, inside D's build:
 * nothing is copied while dst's pass measures) and gradients back (D's input gradient into G's
 * output gradient, between backward_begin and backward_run). */
spx_status spx_tape_transfer(spx_tape *dst, int did, size_t doff, int dst_grad, spx_tape *src, int sid, size_t soff,
                             int src_grad, size_t count, int accumulate);

/* ---- kept copies (lib/nn/tape_buf.c) ----
 * A buffer outside the arena, on the tape's backend (float32 device memory, or host doubles), for
 * a value's data to outlive its pass: spx_tape_save copies `count` floats of a live value at
 * offset off into b at boff (after the value's forward, like a read); spx_tape_restore copies them
 * back into a value of a later pass (in its build, like spx_tape_input's data: nothing while the
 * pass measures; errors are recorded on the tape). The bits are kept exactly. */
typedef struct spx_tape_buf {
  cl_mem mem;   /* DEVICE */
  double *host; /* HOST */
  size_t count; /* floats */
} spx_tape_buf;
spx_status spx_tape_buf_alloc(spx_tape *t, size_t count, const char *what, spx_tape_buf *b);
void spx_tape_buf_free(spx_tape_buf *b);
spx_status spx_tape_save(spx_tape *t, int id, size_t off, spx_tape_buf *b, size_t boff, size_t count);
spx_status spx_tape_restore(spx_tape *t, int id, size_t off, const spx_tape_buf *b, size_t boff, size_t count);

/* ---- memory (plans: lib/nn/tape_plan.c; the current one followed: tape_live.c) ----
 * All activations and activation gradients of a pass live in ONE arena, at offsets planned from
 * the graph the measuring run recorded: a value's storage is reused once nothing later in the
 * forward or the backward reads it (see tape_plan.c for the rules). Reading a value or gradient
 * after its storage was given away fails with SPX_E_STATE (spx_tape_keep it). On the device each
 * op's scratch (lib/nn/workspace.h) is planned too, sized by the op's need function: inside the
 * arena at that op's step (tunable TAPE_WS_ARENA, the CPU column), else in one separate buffer of
 * the largest op's size; either way no scratch is allocated while a planned pass runs. A value's
 * data and gradient are valid until the next pass of the tape (the arena is shared). */
/* Bytes of the arena the current pass's plan needs, and (without_reuse, may be NULL) the sum of all
 * its activations and gradients plus the largest op scratch, i.e. what it would need without
 * reuse. 0 before a planned pass. */
size_t spx_tape_plan_bytes(const spx_tape *t, size_t *without_reuse);
/* Bytes of the inference convolutions' prepared weights the tape holds now (CONV_WPREP; part of
 * spx_tape_device_bytes; 0 after any parameter write, Adam step or broadcast). */
size_t spx_tape_wprep_bytes(const spx_tape *t);
/* Backward may run more than once over one forward (torch's retain_graph): everything backward
 * reads stays alive. Set before the pass; plans are made per setting. */
void spx_tape_set_retain(spx_tape *t, int on);
/* 0: no reuse at all (every value keeps its own memory; tests compare against it). Default 1. */
void spx_tape_set_reuse(spx_tape *t, int on);
/* Debug: fill every storage with NaN the moment it dies (also the context switch
 * SPX_DEBUG_TAPE_POISON, read when the tape is created), so a read after the planned last use
 * shows in the results. */
void spx_tape_set_poison(spx_tape *t, int on);

/* ---- backward and optimizer (lib/nn/tape_backward.c) ---- */
/* backward(t, loss) = backward_begin (activation gradients of the pass zeroed) + seed(loss, 1) +
 * backward_run. Several roots and external gradients: begin, then seed scalars and/or transfer
 * gradients into any activation's gradient (accumulate = 1), then run. */
spx_status spx_tape_backward(spx_tape *t, int loss);
spx_status spx_tape_backward_begin(spx_tape *t);
spx_status spx_tape_seed(spx_tape *t, int scalar_id, float value); /* d scalar += value */
spx_status spx_tape_backward_run(spx_tape *t);
spx_status spx_tape_zero_grad(spx_tape *t);
/* Zero the Adam moments (exp_avg, exp_avg_sq). */
spx_status spx_tape_zero_moments(spx_tape *t);
/* One Adam step (PyTorch semantics, no weight decay) over the whole parameter slab; `step` is the
 * 1-based step number used for bias correction. */
spx_status spx_tape_adam(spx_tape *t, double lr, double beta1, double beta2, double eps, int64_t step);

/* ---- data-parallel training (lib/nn/tape_dist.c; smplpix/comm.h) ----
 * With a comm of size > 1: spx_tape_adam first sums the parameter gradients over the ranks
 * (spx_tape_grad_allreduce), and training batch norms (when sync_bn) use the statistics of the
 * global batch (spx_bn_sync_*; device backend only). The shard (local of global samples of this
 * step) scales every backward seed by local / global, so that each rank's mean loss becomes its
 * part of the global batch's mean and the summed gradients are those of the global batch; a rank
 * with local = 0 runs a stand-in sample that contributes nothing (statistics and gradients
 * zeroed, running statistics untouched by its local batch norms). Without a shard the seed is 1
 * and nothing changes. comm is not copied: it must outlive its use. */
void spx_tape_set_comm(spx_tape *t, const spx_comm *comm, int sync_bn);
const spx_comm *spx_tape_comm(const spx_tape *t); /* NULL: a single process */
void spx_tape_set_shard(spx_tape *t, int local_n, int global_n);
void spx_tape_copy_shard(spx_tape *dst, const spx_tape *src);
float spx_tape_seed_scale(const spx_tape *t);
int spx_tape_shard_empty(const spx_tape *t);
/* Training batch norms of this tape are synchronised over the ranks. */
int spx_tape_sync_bn(const spx_tape *t);
/* Samples of the global batch when a shard was given, else `local`. */
int spx_tape_global_batch(const spx_tape *t, int local);
spx_status spx_tape_grad_allreduce(spx_tape *t);
/* Rank 0's parameters, Adam moments and state into every rank's tape (same layout required). */
spx_status spx_tape_broadcast(spx_tape *t);
/* Host staging of at least n floats for the comm (owned by the tape). */
spx_status spx_tape_xfer(spx_tape *t, size_t n, float **out);

#endif

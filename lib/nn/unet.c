/* The SMPLpix UNet on the tape (smplpix/unet.h, lib/nn/unet.h).
 *
 * Parameters are declared in state_dict order, so the parameter slab is the concatenation of
 * the trainable tensors in the order PyTorch's model.parameters() yields them. Inference folds
 * each batch norm into the preceding convolution (scale = gamma / sqrt(var + eps),
 * shift = beta - mean * scale, then ReLU, all in the convolution's epilogue); the folded
 * vectors live in the state slab and are recomputed when weights or running statistics change. */
#include "nn/st_take.h"
#include "nn/unet.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cl/tensor.h"
#include "nn/batchnorm.h"
#include "smplpix/safetensors.h"

#define NDC 9 /* inc, down1..4, up1..4 */

enum { E_PARAM, E_STATE, E_NBT };

typedef struct entry {
  char name[128];
  int kind;  /* E_PARAM (trainable), E_STATE (running stats), E_NBT (num_batches_tracked) */
  int id;    /* tape value (E_NBT: index of the double conv * 2 + which bn) */
  int ndim;  /* 4 for conv weights, 1 otherwise, 0 for num_batches_tracked */
  int64_t shape[4];
} entry;

typedef struct dconv {
  int w[2], g[2], b[2], rm[2], rv[2]; /* conv weight, bn gamma/beta, running mean/var */
  int fs[2], fh[2];                   /* folded scale / shift (state) */
  int64_t nbt[2];
} dconv;

struct spx_unet {
  spx_ctx *ctx;
  spx_tape *tape;
  int width, sigmoid;
  dconv dc[NDC];
  int outw, outb;
  entry *ents;
  int nents;
  int64_t step;
  int fold_dirty;
  int loss_id, out_id, last_train;
};

static const char *const dc_prefix[NDC] = {
    "inc.double_conv",
    "down1.maxpool_conv.1.double_conv",
    "down2.maxpool_conv.1.double_conv",
    "down3.maxpool_conv.1.double_conv",
    "down4.maxpool_conv.1.double_conv",
    "up1.conv.double_conv",
    "up2.conv.double_conv",
    "up3.conv.double_conv",
    "up4.conv.double_conv",
};

static void add_entry(spx_unet *u, const char *prefix, const char *suffix, int kind, int id, int ndim, int64_t a,
                      int64_t b, int64_t c, int64_t d) {
  entry *e = &u->ents[u->nents++];
  snprintf(e->name, sizeof e->name, "%s%s", prefix, suffix);
  e->kind = kind, e->id = id, e->ndim = ndim;
  e->shape[0] = a, e->shape[1] = b, e->shape[2] = c, e->shape[3] = d;
}

/* splitmix64 -> uniform in [lo, hi) */
static double rnd(uint64_t *s, double lo, double hi) {
  return lo + (hi - lo) * (double)(spx_splitmix64(s) >> 11) * (1.0 / 9007199254740992.0);
}

static spx_status init_weights(spx_unet *u, uint64_t seed) {
  spx_status st = SPX_OK;
  for (int i = 0; i < u->nents && !st; i++) {
    const entry *e = &u->ents[i];
    if (e->kind == E_NBT) continue;
    size_t n = spx_tape_numel(u->tape, e->id);
    float *buf = malloc(n * sizeof(float));
    if (!buf) return spx_fail(u->ctx, SPX_E_NOMEM, "unet: out of memory");
    const char *leaf = strrchr(e->name, '.') + 1;
    int is_bn = e->ndim == 1 && strncmp(e->name, "outc", 4) != 0;
    if (e->ndim == 4 || !is_bn) { /* conv weight / outc bias: U(-1/sqrt(fan_in), 1/sqrt(fan_in)) */
      int32_t shp[4];
      spx_tape_shape(u->tape, u->ents[e->ndim == 4 ? i : i - 1].id, shp);
      double bound = 1.0 / sqrt((double)shp[1] * shp[2] * shp[3]);
      for (size_t k = 0; k < n; k++) buf[k] = (float)rnd(&seed, -bound, bound);
    } else {
      float v = (!strcmp(leaf, "weight") || !strcmp(leaf, "running_var")) ? 1.0f : 0.0f;
      for (size_t k = 0; k < n; k++) buf[k] = v;
    }
    st = spx_tape_write(u->tape, e->id, buf);
    free(buf);
  }
  u->fold_dirty = 1;
  return st;
}

spx_status spx_unet_create_ex(spx_ctx *ctx, int width, int sigmoid, uint64_t seed, spx_tape_backend backend,
                              spx_unet **out) {
  *out = NULL;
  if (width < 1 || width > 1024) return spx_fail(ctx, SPX_E_ARG, "unet: width %d out of range", width);
  spx_unet *u = calloc(1, sizeof *u);
  if (!u) return spx_fail(ctx, SPX_E_NOMEM, "unet: out of memory");
  u->ctx = ctx;
  u->width = width;
  u->sigmoid = sigmoid != 0;
  u->loss_id = u->out_id = -1;
  spx_status st = spx_tape_create(ctx, backend, &u->tape);
  if (st) goto fail;
  u->ents = calloc(NDC * 12 + 2, sizeof(entry));
  if (!u->ents) {
    st = spx_fail(ctx, SPX_E_NOMEM, "unet: out of memory");
    goto fail;
  }
  int w = width;
  /* (in, mid, out) of each double conv */
  const int io[NDC][3] = {{4, w, w},           {w, 2 * w, 2 * w},       {2 * w, 4 * w, 4 * w},
                          {4 * w, 8 * w, 8 * w}, {8 * w, 8 * w, 8 * w},   {16 * w, 8 * w, 4 * w},
                          {8 * w, 4 * w, 2 * w}, {4 * w, 2 * w, w},       {2 * w, w, w}};
  spx_tape *t = u->tape;
  for (int i = 0; i < NDC; i++) {
    dconv *d = &u->dc[i];
    for (int j = 0; j < 2; j++) {
      int cin = j ? io[i][1] : io[i][0], cout = j ? io[i][2] : io[i][1];
      d->w[j] = spx_tape_param(t, cout, cin, 3, 3);
      d->g[j] = spx_tape_param(t, cout, 1, 1, 1);
      d->b[j] = spx_tape_param(t, cout, 1, 1, 1);
    }
  }
  u->outw = spx_tape_param(t, SPX_UNET_OUT_CHANNELS, w, 1, 1);
  u->outb = spx_tape_param(t, SPX_UNET_OUT_CHANNELS, 1, 1, 1);
  for (int i = 0; i < NDC; i++) {
    dconv *d = &u->dc[i];
    for (int j = 0; j < 2; j++) {
      int c = j ? io[i][2] : io[i][1];
      d->rm[j] = spx_tape_state(t, c, 1, 1, 1);
      d->rv[j] = spx_tape_state(t, c, 1, 1, 1);
      d->fs[j] = spx_tape_state(t, c, 1, 1, 1);
      d->fh[j] = spx_tape_state(t, c, 1, 1, 1);
    }
  }
  /* entries in state_dict order: per bn, weight, bias, running_mean, running_var, nbt */
  for (int i = 0; i < NDC; i++) {
    dconv *d = &u->dc[i];
    for (int j = 0; j < 2; j++) {
      int32_t s[4];
      spx_tape_shape(t, d->w[j], s);
      char conv[16], pre[64];
      snprintf(conv, sizeof conv, ".%d.weight", 3 * j);
      add_entry(u, dc_prefix[i], conv, E_PARAM, d->w[j], 4, s[0], s[1], 3, 3);
      snprintf(pre, sizeof pre, "%s.%d.", dc_prefix[i], 3 * j + 1);
      add_entry(u, pre, "weight", E_PARAM, d->g[j], 1, s[0], 0, 0, 0);
      add_entry(u, pre, "bias", E_PARAM, d->b[j], 1, s[0], 0, 0, 0);
      add_entry(u, pre, "running_mean", E_STATE, d->rm[j], 1, s[0], 0, 0, 0);
      add_entry(u, pre, "running_var", E_STATE, d->rv[j], 1, s[0], 0, 0, 0);
      add_entry(u, pre, "num_batches_tracked", E_NBT, 2 * i + j, 0, 0, 0, 0, 0);
    }
  }
  add_entry(u, "outc.conv.", "weight", E_PARAM, u->outw, 4, SPX_UNET_OUT_CHANNELS, w, 1, 1);
  add_entry(u, "outc.conv.", "bias", E_PARAM, u->outb, 1, SPX_UNET_OUT_CHANNELS, 0, 0, 0);
  if ((st = spx_tape_alloc_params(t)) || (st = init_weights(u, seed))) goto fail;
  *out = u;
  return SPX_OK;
fail:
  spx_unet_destroy(u);
  return st;
}

spx_status spx_unet_create(spx_ctx *ctx, int width, int sigmoid, uint64_t seed, spx_unet **out) {
  *out = NULL;
  if (width != 8 && width != 16 && width != 32 && width != 64)
    return spx_fail(ctx, SPX_E_ARG, "unet: width %d is not one of 8, 16, 32, 64", width);
  return spx_unet_create_ex(ctx, width, sigmoid, seed, SPX_TAPE_DEVICE, out);
}

void spx_unet_destroy(spx_unet *u) {
  if (!u) return;
  spx_tape_destroy(u->tape);
  free(u->ents);
  free(u);
}

int spx_unet_width(const spx_unet *u) { return u->width; }
int spx_unet_sigmoid(const spx_unet *u) { return u->sigmoid; }
void spx_unet_set_sigmoid(spx_unet *u, int on) { u->sigmoid = on != 0; }
int64_t spx_unet_step(const spx_unet *u) { return u->step; }
spx_tape *spx_unet_tape(spx_unet *u) { return u->tape; }
size_t spx_unet_device_bytes(const spx_unet *u) { return u ? spx_tape_device_bytes(u->tape) : 0; }
int spx_unet_loss_id(const spx_unet *u) { return u->loss_id; }
int spx_unet_output_id(const spx_unet *u) { return u->out_id; }
spx_ctx *spx_unet_ctx(spx_unet *u) { return u->ctx; }

static const entry *find_entry(const spx_unet *u, const char *name) {
  for (int i = 0; i < u->nents; i++)
    if (!strcmp(u->ents[i].name, name)) return &u->ents[i];
  return NULL;
}
int spx_unet_value_id(const spx_unet *u, const char *name) {
  const entry *e = find_entry(u, name);
  return e && e->kind != E_NBT ? e->id : -1;
}

/* ------------------------------------------------------------------ forward */

static spx_status refold(spx_unet *u) {
  if (!u->fold_dirty) return SPX_OK;
  spx_status st = SPX_OK;
  size_t cmax = (size_t)16 * u->width;
  float *buf = malloc(6 * cmax * sizeof(float));
  if (!buf) return spx_fail(u->ctx, SPX_E_NOMEM, "unet: out of memory");
  float *g = buf, *b = g + cmax, *m = b + cmax, *v = m + cmax, *s = v + cmax, *h = s + cmax;
  for (int i = 0; i < NDC && !st; i++)
    for (int j = 0; j < 2 && !st; j++) {
      const dconv *d = &u->dc[i];
      size_t c = spx_tape_numel(u->tape, d->g[j]);
      if ((st = spx_tape_read(u->tape, d->g[j], g)) || (st = spx_tape_read(u->tape, d->b[j], b)) ||
          (st = spx_tape_read(u->tape, d->rm[j], m)) || (st = spx_tape_read(u->tape, d->rv[j], v)))
        break;
      for (size_t k = 0; k < c; k++) {
        double sc = (double)g[k] / sqrt((double)v[k] + (double)SPX_BN_EPS);
        s[k] = (float)sc;
        h[k] = (float)((double)b[k] - (double)m[k] * sc);
      }
      if ((st = spx_tape_write(u->tape, d->fs[j], s)) || (st = spx_tape_write(u->tape, d->fh[j], h))) break;
    }
  free(buf);
  if (!st) u->fold_dirty = 0;
  return st;
}

static int double_conv(spx_unet *u, int x, int i, int train) {
  spx_tape *t = u->tape;
  dconv *d = &u->dc[i];
  for (int j = 0; j < 2; j++) {
    if (train) {
      x = spx_tape_conv(t, x, d->w[j], SPX_TAPE_NONE);
      x = spx_tape_batchnorm_relu(t, x, d->g[j], d->b[j], d->rm[j], d->rv[j], SPX_BN_MOMENTUM, SPX_BN_EPS);
    } else {
      x = spx_tape_conv_bn_relu(t, x, d->w[j], d->fs[j], d->fh[j]);
    }
  }
  return x;
}

/* Up(): upsample x2, pad to the skip's size, concat(skip, up), double conv; the first three are
 * one fused op (spx_tape_upcat, the same numbers as spx_tape_upsample2 / _pad / _concat). */
static int up_block(spx_unet *u, int x, int skip, int i, int train) {
  return double_conv(u, spx_tape_upcat(u->tape, skip, x), i, train);
}

/* One forward's inputs, and the ids its build leaves behind. */
typedef struct unet_pass {
  spx_unet *u;
  const float *input, *target; /* host data; input NULL: dev_in */
  cl_mem dev_in;
  size_t dev_off;
  int n, h, w, train;
  int y, loss;
} unet_pass;

static spx_status unet_build(spx_tape *t, void *user) {
  unet_pass *p = user;
  spx_unet *u = p->u;
  const int train = p->train;
  int in = p->dev_in ? spx_tape_input_device(t, p->n, SPX_UNET_IN_CHANNELS, p->h, p->w, p->dev_in, p->dev_off)
                     : spx_tape_input(t, p->n, SPX_UNET_IN_CHANNELS, p->h, p->w, p->input);
  int x1 = double_conv(u, in, 0, train);
  int x2 = double_conv(u, spx_tape_maxpool2(t, x1), 1, train);
  int x3 = double_conv(u, spx_tape_maxpool2(t, x2), 2, train);
  int x4 = double_conv(u, spx_tape_maxpool2(t, x3), 3, train);
  int x5 = double_conv(u, spx_tape_maxpool2(t, x4), 4, train);
  int x = up_block(u, x5, x4, 5, train);
  x = up_block(u, x, x3, 6, train);
  x = up_block(u, x, x2, 7, train);
  x = up_block(u, x, x1, 8, train);
  int y = spx_tape_conv(t, x, u->outw, u->outb);
  if (u->sigmoid) y = spx_tape_act(t, SPX_ACT_SIGMOID, 0.0f, y);
  if (y >= 0) spx_tape_keep(t, y); /* read by the caller; the GAN step hands gradients into it */
  p->y = y, p->loss = -1;
  if (p->target)
    p->loss = spx_tape_l1(t, y, spx_tape_input(t, p->n, SPX_UNET_OUT_CHANNELS, p->h, p->w, p->target));
  return SPX_OK;
}

static spx_status run_forward(spx_unet *u, const float *input, cl_mem dev_in, size_t dev_off, const float *target,
                              int n, int h, int w, int train, float *output, float *loss) {
  spx_status st;
  if (!input && !dev_in) return spx_fail(u->ctx, SPX_E_ARG, "unet: input is NULL");
  if (n < 1 || h < 16 || w < 16 || n > 4096 || h > 16384 || w > 16384)
    return spx_fail(u->ctx, SPX_E_ARG, "unet: input %dx%dx%dx%d: need batch >= 1 and height, width in [16, 16384]", n,
                    SPX_UNET_IN_CHANNELS, h, w);
  /* synchronised batch norm: the statistics are those of the global batch */
  long nstat = spx_tape_sync_bn(u->tape) ? spx_tape_global_batch(u->tape, n) : n;
  if (train && nstat * (h / 16) * (w / 16) < 2)
    return spx_fail(u->ctx, SPX_E_ARG,
                    "unet: training on %dx%dx%dx%d leaves one value per channel at the %dx%d bottleneck (batch norm "
                    "needs two): use a larger batch or image",
                    n, SPX_UNET_IN_CHANNELS, h, w, h / 16, w / 16);
  if (!train && (st = refold(u))) return st;
  uint64_t key = spx_hash64(&n, sizeof n, SPX_FNV_SEED);
  key = spx_hash64(&h, sizeof h, key);
  key = spx_hash64(&w, sizeof w, key);
  int flags = (target ? 1 : 0) | (u->sigmoid ? 2 : 0);
  key = spx_hash64(&flags, sizeof flags, key);
  spx_tape *t = u->tape;
  unet_pass p = {u, dev_in ? NULL : input, target, dev_in, dev_off, n, h, w, train, -1, -1};
  st = spx_tape_pass(t, train, key, unet_build, &p);
  u->loss_id = u->out_id = -1;
  if (st) return st;
  u->out_id = p.y;
  u->loss_id = p.loss;
  u->last_train = train;
  if (train) { /* running statistics moved */
    u->fold_dirty = 1;
    for (int i = 0; i < NDC; i++) u->dc[i].nbt[0]++, u->dc[i].nbt[1]++;
  }
  if (output && (st = spx_tape_read(t, p.y, output))) return st;
  if (loss && p.loss >= 0 && (st = spx_tape_read(t, p.loss, loss))) return st;
  return SPX_OK;
}

spx_status spx_unet_forward(spx_unet *u, const float *input, int n, int h, int w, int train, float *output) {
  return run_forward(u, input, NULL, 0, NULL, n, h, w, train, output, NULL);
}

spx_status spx_unet_forward_device(spx_unet *u, cl_mem input, size_t offset, int n, int h, int w, float *output) {
  if (!input) return spx_fail(u->ctx, SPX_E_ARG, "unet: device input is NULL");
  if (spx_tape_get_backend(u->tape) != SPX_TAPE_DEVICE)
    return spx_fail(u->ctx, SPX_E_ARG, "unet: a device input needs the device backend");
  size_t size = 0;
  cl_int e = clGetMemObjectInfo(input, CL_MEM_SIZE, sizeof size, &size, NULL);
  if (e != CL_SUCCESS) return spx_fail(u->ctx, SPX_E_CL, "unet: device input: clGetMemObjectInfo failed (%d)", (int)e);
  size_t need = (size_t)(n > 0 ? n : 0) * SPX_UNET_IN_CHANNELS * (size_t)(h > 0 ? h : 0) * (size_t)(w > 0 ? w : 0) *
                sizeof(float);
  if (offset > size || size - offset < need)
    return spx_fail(u->ctx, SPX_E_ARG, "unet: device input holds %zu bytes after offset %zu, need %zu for %dx%dx%dx%d",
                    offset > size ? 0 : size - offset, offset, need, n, SPX_UNET_IN_CHANNELS, h, w);
  return run_forward(u, NULL, input, offset, NULL, n, h, w, 0, output, NULL);
}

spx_status spx_unet_forward_tensor(spx_unet *u, const spx_device_tensor *input, float *output) {
  spx_status st = spx_device_tensor_check(u->ctx, input, "spx_unet_forward_tensor");
  if (st) return st;
  if (input->shape[1] != SPX_UNET_IN_CHANNELS)
    return spx_fail(u->ctx, SPX_E_ARG, "spx_unet_forward_tensor: input has %d channels, the network takes %d",
                    input->shape[1], SPX_UNET_IN_CHANNELS);
  return spx_unet_forward_device(u, input->mem, 0, input->shape[0], input->shape[2], input->shape[3], output);
}

spx_status spx_unet_forward_loss(spx_unet *u, const float *input, const float *target, int n, int h, int w,
                                 float *output, float *loss) {
  if (!target) return spx_fail(u->ctx, SPX_E_ARG, "unet: target is NULL");
  return run_forward(u, input, NULL, 0, target, n, h, w, 1, output, loss);
}

spx_status spx_unet_backward(spx_unet *u) {
  if (u->loss_id < 0 || !u->last_train)
    return spx_fail(u->ctx, SPX_E_STATE, "unet: backward needs a preceding spx_unet_forward_loss");
  return spx_tape_backward(u->tape, u->loss_id);
}

spx_status spx_unet_zero_grad(spx_unet *u) { return spx_tape_zero_grad(u->tape); }

spx_status spx_unet_adam_step_ex(spx_unet *u, double lr, double beta1, double beta2, double eps) {
  if (!(lr > 0.0) || !isfinite(lr)) return spx_fail(u->ctx, SPX_E_ARG, "unet: learning rate %g is not positive", lr);
  if (!(beta1 >= 0.0 && beta1 < 1.0) || !(beta2 >= 0.0 && beta2 < 1.0) || !(eps >= 0.0) || !isfinite(eps))
    return spx_fail(u->ctx, SPX_E_ARG, "unet: Adam betas (%g, %g) must be in [0, 1) and eps %g >= 0", beta1, beta2,
                    eps);
  spx_status st = spx_tape_adam(u->tape, lr, beta1, beta2, eps, u->step + 1);
  if (st) return st;
  u->step++;
  u->fold_dirty = 1;
  return SPX_OK;
}

spx_status spx_unet_reset_optimizer(spx_unet *u) {
  spx_status st = spx_tape_zero_moments(u->tape);
  if (!st) u->step = 0;
  return st;
}

spx_status spx_unet_adam_step(spx_unet *u, double lr) { return spx_unet_adam_step_ex(u, lr, 0.9, 0.999, 1e-8); }

/* ------------------------------------------------------------------ data-parallel training */

spx_status spx_unet_set_comm(spx_unet *u, const spx_comm *comm, int sync_bn) {
  if (comm && comm->size > 1 && (!comm->allreduce_sum || !comm->broadcast || comm->rank < 0 || comm->rank >= comm->size))
    return spx_fail(u->ctx, SPX_E_ARG, "unet: comm of %d ranks lacks a callback or has rank %d", comm->size, comm->rank);
  spx_tape_set_comm(u->tape, comm, sync_bn);
  return SPX_OK;
}

spx_status spx_unet_set_shard(spx_unet *u, int local_n, int global_n) {
  if (local_n < 0 || global_n < 1 || local_n > global_n)
    return spx_fail(u->ctx, SPX_E_ARG, "unet: shard of %d samples in a global batch of %d", local_n, global_n);
  spx_tape_set_shard(u->tape, local_n, global_n);
  return SPX_OK;
}

spx_status spx_unet_broadcast(spx_unet *u) {
  const spx_comm *c = spx_tape_comm(u->tape);
  if (!c) return SPX_OK;
  int64_t meta[2 + 2 * NDC] = {u->step, u->sigmoid};
  for (int i = 0; i < NDC; i++) meta[2 + 2 * i] = u->dc[i].nbt[0], meta[3 + 2 * i] = u->dc[i].nbt[1];
  if (c->broadcast(c->self, meta, sizeof meta))
    return spx_fail(u->ctx, SPX_E_IO, "unet: broadcast over %d ranks failed", c->size);
  u->step = meta[0], u->sigmoid = (int)meta[1];
  for (int i = 0; i < NDC; i++) u->dc[i].nbt[0] = meta[2 + 2 * i], u->dc[i].nbt[1] = meta[3 + 2 * i];
  u->fold_dirty = 1;
  return spx_tape_broadcast(u->tape);
}

/* ------------------------------------------------------------------ introspection */

int spx_unet_tensor_count(const spx_unet *u) {
  int n = 0;
  for (int i = 0; i < u->nents; i++) n += u->ents[i].kind != E_NBT;
  return n;
}

const char *spx_unet_tensor_name(const spx_unet *u, int i, int *ndim, int64_t shape[4]) {
  for (int k = 0; k < u->nents; k++) {
    if (u->ents[k].kind == E_NBT) continue;
    if (i-- == 0) {
      if (ndim) *ndim = u->ents[k].ndim;
      if (shape) memcpy(shape, u->ents[k].shape, sizeof u->ents[k].shape);
      return u->ents[k].name;
    }
  }
  return NULL;
}

static spx_status lookup(spx_unet *u, const char *name, spx_unet_field *field, const entry **out) {
  char base[128];
  *out = NULL;
  if (!name) return spx_fail(u->ctx, SPX_E_ARG, "unet: tensor name is NULL");
  size_t len = strlen(name);
  if (!strncmp(name, "optimizer.", 10) && len < sizeof base + 10) {
    const char *rest = name + 10;
    const char *dot = strrchr(rest, '.');
    if (dot && (!strcmp(dot, ".exp_avg") || !strcmp(dot, ".exp_avg_sq"))) {
      memcpy(base, rest, (size_t)(dot - rest));
      base[dot - rest] = 0;
      *field = !strcmp(dot, ".exp_avg") ? SPX_UNET_EXP_AVG : SPX_UNET_EXP_AVG_SQ;
      name = base;
    }
  }
  const entry *e = find_entry(u, name);
  if (!e || e->kind == E_NBT) return spx_fail(u->ctx, SPX_E_ARG, "unet: no tensor named %s", name);
  if (*field != SPX_UNET_VALUE && e->kind != E_PARAM)
    return spx_fail(u->ctx, SPX_E_ARG, "unet: %s is not trainable (no gradient or optimizer state)", name);
  *out = e;
  return SPX_OK;
}

spx_status spx_unet_read(spx_unet *u, const char *name, spx_unet_field field, float *dst, size_t count) {
  const entry *e;
  spx_status st = lookup(u, name, &field, &e);
  if (st) return st;
  size_t n = spx_tape_numel(u->tape, e->id);
  if (count != n) return spx_fail(u->ctx, SPX_E_ARG, "unet: %s has %zu elements, not %zu", name, n, count);
  if (field == SPX_UNET_VALUE) return spx_tape_read(u->tape, e->id, dst);
  if (field == SPX_UNET_GRAD) return spx_tape_read_grad(u->tape, e->id, dst);
  float *tmp = malloc(n * sizeof(float));
  if (!tmp) return spx_fail(u->ctx, SPX_E_NOMEM, "unet: out of memory");
  st = field == SPX_UNET_EXP_AVG ? spx_tape_read_moments(u->tape, e->id, dst, tmp)
                                 : spx_tape_read_moments(u->tape, e->id, tmp, dst);
  free(tmp);
  return st;
}

spx_status spx_unet_write(spx_unet *u, const char *name, const float *src, size_t count) {
  const entry *e;
  spx_unet_field field = SPX_UNET_VALUE;
  spx_status st = lookup(u, name, &field, &e);
  if (st) return st;
  size_t n = spx_tape_numel(u->tape, e->id);
  if (count != n) return spx_fail(u->ctx, SPX_E_ARG, "unet: %s has %zu elements, not %zu", name, n, count);
  u->fold_dirty = 1;
  if (field == SPX_UNET_VALUE) return spx_tape_write(u->tape, e->id, src);
  float *m = malloc(2 * n * sizeof(float));
  if (!m) return spx_fail(u->ctx, SPX_E_NOMEM, "unet: out of memory");
  float *v = m + n;
  if (!(st = spx_tape_read_moments(u->tape, e->id, m, v))) {
    memcpy(field == SPX_UNET_EXP_AVG ? m : v, src, n * sizeof(float));
    st = spx_tape_write_moments(u->tape, e->id, m, v);
  }
  free(m);
  return st;
}

/* ------------------------------------------------------------------ checkpoints */

spx_status spx_unet_save(spx_unet *u, const char *path, int with_optimizer) {
  return spx_unet_save_meta(u, path, with_optimizer, NULL, NULL, 0);
}

static spx_status save_impl(spx_unet *u, const char *path, int with_optimizer, int half, const spx_st_entry *extra,
                            int nextra, const char *const *mkeys, const char *const *mvalues, int count);

spx_status spx_unet_save_meta(spx_unet *u, const char *path, int with_optimizer, const char *const *mkeys,
                              const char *const *mvalues, int count) {
  return save_impl(u, path, with_optimizer, 0, NULL, 0, mkeys, mvalues, count);
}

spx_status spx_unet_save_extra(spx_unet *u, const char *path, const spx_st_entry *extra, int nextra,
                               const char *const *keys, const char *const *values, int count) {
  if (nextra < 0 || (nextra && !extra)) return spx_fail(u->ctx, SPX_E_ARG, "unet: %d extra tensors", nextra);
  return save_impl(u, path, 0, 0, extra, nextra, keys, values, count);
}

spx_status spx_unet_save_half(spx_unet *u, const char *path, const char *const *keys, const char *const *values,
                              int count) {
  return save_impl(u, path, 0, 1, NULL, 0, keys, values, count);
}

static spx_status save_impl(spx_unet *u, const char *path, int with_optimizer, int half, const spx_st_entry *extra,
                            int nextra, const char *const *mkeys, const char *const *mvalues, int count) {
  spx_status st = SPX_OK;
  if (count < 0 || count > SPX_UNET_MAX_META || (count && (!mkeys || !mvalues)))
    return spx_fail(u->ctx, SPX_E_ARG, "unet: %d extra metadata entries (at most %d)", count, SPX_UNET_MAX_META);
  int cap = u->nents * 3 + 1 + nextra;
  spx_st_entry *es = calloc((size_t)cap, sizeof *es);
  float **bufs = calloc((size_t)cap, sizeof *bufs);
  char(*names)[160] = calloc((size_t)cap, sizeof *names);
  int64_t *nbt = calloc((size_t)u->nents + 1, sizeof(int64_t));
  int ne = 0;
  if (!es || !bufs || !names || !nbt) {
    st = spx_fail(u->ctx, SPX_E_NOMEM, "unet: out of memory");
    goto done;
  }
  for (int pass = 0; pass < (with_optimizer ? 3 : 1) && !st; pass++)
    for (int i = 0; i < u->nents && !st; i++) {
      const entry *e = &u->ents[i];
      if (pass && e->kind != E_PARAM) continue;
      spx_st_entry *o = &es[ne];
      if (pass == 0) snprintf(names[ne], sizeof names[ne], "%s", e->name);
      else snprintf(names[ne], sizeof names[ne], "optimizer.%s.%s", e->name, pass == 1 ? "exp_avg" : "exp_avg_sq");
      o->name = names[ne];
      if (e->kind == E_NBT) {
        nbt[i] = u->dc[e->id / 2].nbt[e->id % 2];
        o->dtype = SPX_I64;
        o->ndim = 0;
        o->data = &nbt[i];
        ne++;
        continue;
      }
      o->dtype = SPX_F32;
      o->ndim = e->ndim;
      memcpy(o->shape, e->shape, sizeof e->shape);
      size_t n = spx_tape_numel(u->tape, e->id);
      if (!(bufs[ne] = malloc(n * sizeof(float)))) {
        st = spx_fail(u->ctx, SPX_E_NOMEM, "unet: out of memory");
        break;
      }
      o->data = bufs[ne];
      spx_unet_field f = pass == 0 ? SPX_UNET_VALUE : pass == 1 ? SPX_UNET_EXP_AVG : SPX_UNET_EXP_AVG_SQ;
      st = spx_unet_read(u, o->name, f, bufs[ne], n);
      if (!st && half) { /* in place: the halves fill the front of the float buffer */
        unsigned char *hb = (unsigned char *)bufs[ne];
        for (size_t k = 0; k < n && !st; k++) {
          float v;
          uint16_t h = 0;
          memcpy(&v, hb + 4 * k, 4);
          if (spx_float_to_half(v, &h)) memcpy(hb + 2 * k, &h, 2);
          else
            st = spx_fail(u->ctx, SPX_E_NUMERIC, "%s: tensor %s element %zu (%g) does not fit in float16", path,
                          o->name, k, (double)v);
        }
        o->dtype = SPX_F16;
      }
      ne++;
    }
  if (!st && with_optimizer) {
    nbt[u->nents] = u->step;
    es[ne].name = "optimizer.step";
    es[ne].dtype = SPX_I64;
    es[ne].ndim = 0;
    es[ne].data = &nbt[u->nents];
    ne++;
  }
  for (int i = 0; i < nextra && !st; i++) es[ne++] = extra[i]; /* spx_st_save refuses a name given twice */
  if (!st) {
    char wbuf[16];
    snprintf(wbuf, sizeof wbuf, "%d", u->width);
    const char *keys[3 + SPX_UNET_MAX_META] = {"format", "smplpix.sigmoid", "smplpix.width"};
    const char *vals[3 + SPX_UNET_MAX_META] = {"pt", u->sigmoid ? "1" : "0", wbuf};
    for (int i = 0; i < count; i++) keys[3 + i] = mkeys[i], vals[3 + i] = mvalues[i];
    st = spx_st_save(u->ctx, path, es, ne, keys, vals, 3 + count);
  }
done:
  if (bufs)
    for (int i = 0; i < cap; i++) free(bufs[i]);
  free(bufs), free(es), free(names), free(nbt);
  return st;
}

/* Copy tensor `name` from the file (F32 or F16, shape checked) into dst. */
static spx_status load_floats(spx_ctx *ctx, const char *path, const spx_st_file *f, const char *name, int ndim,
                              const int64_t *shape, float *dst) {
  const spx_st_tensor *t;
  spx_status st = spx_nn_st_find_shaped(ctx, path, f, name, ndim, shape, &t);
  if (st) return st;
  size_t n = 1;
  for (int d = 0; d < ndim; d++) n *= (size_t)shape[d];
  const unsigned char *p = t->data;
  for (size_t i = 0; i < n; i++) {
    float v;
    if (t->dtype == SPX_F32) {
      memcpy(&v, p + 4 * i, 4);
    } else if (t->dtype == SPX_F16) {
      uint16_t hv;
      memcpy(&hv, p + 2 * i, 2);
      v = spx_half_to_float(hv);
    } else {
      return spx_fail(ctx, SPX_E_FORMAT, "%s: tensor %s has dtype %s, expected F32 or F16", path, name,
                      spx_dtype_name(t->dtype));
    }
    if (!isfinite(v)) return spx_fail(ctx, SPX_E_NUMERIC, "%s: tensor %s holds NaN or Inf at element %zu", path, name, i);
    dst[i] = v;
  }
  return SPX_OK;
}

static spx_status load_int(spx_ctx *ctx, const char *path, const spx_st_file *f, const char *name, int64_t *out) {
  const spx_st_tensor *t = spx_st_find(f, name);
  if (!t) return spx_fail(ctx, SPX_E_FORMAT, "%s: missing tensor %s (expected an integer scalar)", path, name);
  size_t numel = 1;
  for (int d = 0; d < t->ndim; d++) numel *= (size_t)t->shape[d];
  if (numel != 1) return spx_fail(ctx, SPX_E_FORMAT, "%s: tensor %s is not a scalar", path, name);
  if (t->dtype == SPX_I64) {
    memcpy(out, t->data, 8);
  } else if (t->dtype == SPX_I32) {
    int32_t v;
    memcpy(&v, t->data, 4);
    *out = v;
  } else if (t->dtype == SPX_F32) { /* some writers store the Adam step as a float */
    float v;
    memcpy(&v, t->data, 4);
    if (!isfinite(v) || v < 0 || v > 9e15f) return spx_fail(ctx, SPX_E_FORMAT, "%s: tensor %s is not a count", path, name);
    *out = (int64_t)v;
  } else {
    return spx_fail(ctx, SPX_E_FORMAT, "%s: tensor %s has dtype %s, expected I64", path, name, spx_dtype_name(t->dtype));
  }
  if (*out < 0) return spx_fail(ctx, SPX_E_FORMAT, "%s: tensor %s is negative", path, name);
  return SPX_OK;
}

spx_status spx_unet_load(spx_ctx *ctx, const char *path, spx_unet **out) {
  *out = NULL;
  spx_st_file f;
  memset(&f, 0, sizeof f);
  spx_status st = spx_st_load(ctx, path, &f);
  if (st) return st;
  spx_unet *u = NULL;
  float *buf = NULL, *buf2 = NULL;
  const spx_st_tensor *t0 = spx_st_find(&f, "inc.double_conv.0.weight");
  if (!t0) {
    st = spx_fail(ctx, SPX_E_FORMAT, "%s: missing tensor inc.double_conv.0.weight (expected shape [W, 4, 3, 3])", path);
    goto done;
  }
  if (t0->ndim != 4 || t0->shape[1] != SPX_UNET_IN_CHANNELS || t0->shape[2] != 3 || t0->shape[3] != 3 ||
      t0->shape[0] < 1 || t0->shape[0] > 1024) {
    char got[96];
    spx_nn_shape_str(got, sizeof got, t0->ndim, t0->shape);
    st = spx_fail(ctx, SPX_E_FORMAT, "%s: tensor inc.double_conv.0.weight has shape %s, expected [W, 4, 3, 3]", path,
                  got);
    goto done;
  }
  /* before allocating anything for width W, the file must hold the largest weight (8W x 16W x 3 x 3):
   * device memory stays proportional to the file size, whatever its first shape claims */
  {
    int64_t wd = t0->shape[0], big[4] = {8 * wd, 16 * wd, 3, 3};
    const char *bn = "up1.conv.double_conv.0.weight";
    const spx_st_tensor *tb = spx_st_find(&f, bn);
    char want[96], got[96];
    spx_nn_shape_str(want, sizeof want, 4, big);
    if (!tb) {
      st = spx_fail(ctx, SPX_E_FORMAT, "%s: missing tensor %s (expected shape %s)", path, bn, want);
      goto done;
    }
    if (tb->ndim != 4 || memcmp(tb->shape, big, sizeof big)) {
      spx_nn_shape_str(got, sizeof got, tb->ndim, tb->shape);
      st = spx_fail(ctx, SPX_E_FORMAT, "%s: tensor %s has shape %s, expected %s", path, bn, got, want);
      goto done;
    }
  }
  /* the metadata this library writes must agree with the tensors (or be absent: PyTorch files) */
  const char *sig = spx_st_meta(&f, "smplpix.sigmoid"), *mw = spx_st_meta(&f, "smplpix.width");
  if (sig && strcmp(sig, "0") && strcmp(sig, "1")) {
    st = spx_fail(ctx, SPX_E_FORMAT, "%s: metadata smplpix.sigmoid = \"%.40s\" is not 0 or 1", path, sig);
    goto done;
  }
  if (mw) {
    char wbuf[24];
    snprintf(wbuf, sizeof wbuf, "%lld", (long long)t0->shape[0]);
    if (strcmp(mw, wbuf)) {
      st = spx_fail(ctx, SPX_E_FORMAT, "%s: metadata smplpix.width = \"%.40s\" disagrees with the tensors (width %s)",
                    path, mw, wbuf);
      goto done;
    }
  }
  if ((st = spx_unet_create_ex(ctx, (int)t0->shape[0], sig && !strcmp(sig, "1"), 0, SPX_TAPE_DEVICE, &u))) goto done;
  size_t cmax = 0;
  for (int i = 0; i < u->nents; i++)
    if (u->ents[i].kind != E_NBT && spx_tape_numel(u->tape, u->ents[i].id) > cmax)
      cmax = spx_tape_numel(u->tape, u->ents[i].id);
  buf = malloc(cmax * sizeof(float));
  buf2 = malloc(cmax * sizeof(float));
  if (!buf || !buf2) {
    st = spx_fail(ctx, SPX_E_NOMEM, "unet: out of memory");
    goto done;
  }
  int has_opt = spx_st_find(&f, "optimizer.step") != NULL;
  for (int i = 0; i < u->nents && !st; i++) {
    const entry *e = &u->ents[i];
    if (e->kind == E_NBT) { /* informational only (momentum is fixed): optional */
      if (spx_st_find(&f, e->name)) st = load_int(ctx, path, &f, e->name, &u->dc[e->id / 2].nbt[e->id % 2]);
      continue;
    }
    size_t n = spx_tape_numel(u->tape, e->id);
    if ((st = load_floats(ctx, path, &f, e->name, e->ndim, e->shape, buf)) || (st = spx_tape_write(u->tape, e->id, buf)))
      break;
    if (e->kind == E_STATE && !strcmp(strrchr(e->name, '.'), ".running_var"))
      for (size_t k = 0; k < n; k++)
        if (buf[k] < 0) {
          st = spx_fail(ctx, SPX_E_NUMERIC, "%s: tensor %s has a negative variance at element %zu", path, e->name, k);
          break;
        }
    if (!st && has_opt && e->kind == E_PARAM) {
      char nm[160];
      snprintf(nm, sizeof nm, "optimizer.%s.exp_avg", e->name);
      if ((st = load_floats(ctx, path, &f, nm, e->ndim, e->shape, buf))) break;
      snprintf(nm, sizeof nm, "optimizer.%s.exp_avg_sq", e->name);
      if ((st = load_floats(ctx, path, &f, nm, e->ndim, e->shape, buf2))) break;
      st = spx_tape_write_moments(u->tape, e->id, buf, buf2);
    }
  }
  if (!st && has_opt) st = load_int(ctx, path, &f, "optimizer.step", &u->step);
  u->fold_dirty = 1;
done:
  free(buf), free(buf2);
  spx_st_free(&f);
  if (st) spx_unet_destroy(u);
  else *out = u;
  return st;
}

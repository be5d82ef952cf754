/* The frozen VGG perceptual losses (smplpix/vgg.h): VGG19 (eq. 5) and VGG16 (the official SMPLpix
 * code's). The convolutions' weights live in the tape's STATE slab (no gradient or Adam slabs exist
 * for them), so backward computes only the input gradients. VGG19's ImageNet normalisation is a
 * 1x1 convolution with the diagonal weights 1/std and bias -mean/std (exactly the per-channel
 * affine map, differentiable like any conv). */
#include "nn/vgg.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "nn/st_take.h"
#include "smplpix/device.h"
#include "smplpix/safetensors.h"

/* The convolutions each loss uses (torchvision's features.N), their output channels (x the base
 * width), which are followed by a 2x2 max pool, and which ReLU outputs are the loss's features
 * (1-based feature number, 0 = none). */
typedef struct vgg_arch {
  const char *name;
  int nconv;
  int index[SPX_VGG_NCONV], mult[SPX_VGG_NCONV], pool_after[SPX_VGG_NCONV], feat_after[SPX_VGG_NCONV];
  const char *mark, *not_mark; /* a conv of this network only; the same index's conv of the other */
} vgg_arch;

static const vgg_arch arch[2] = {
    /* VGG19 (cfg "E"): relu1_1, relu2_1, relu3_1, relu4_1, relu5_1 */
    {"VGG19", 13, {0, 2, 5, 7, 10, 12, 14, 16, 19, 21, 23, 25, 28}, {1, 1, 2, 2, 4, 4, 4, 4, 8, 8, 8, 8, 8},
     {0, 1, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0}, {1, 0, 2, 0, 3, 0, 0, 0, 4, 0, 0, 0, 5}, "features.16.weight",
     "features.17.weight"},
    /* VGG16 (cfg "D") up to relu4_3: relu1_2, relu2_2, relu3_3, relu4_3 */
    {"VGG16", 10, {0, 2, 5, 7, 10, 12, 14, 17, 19, 21}, {1, 1, 2, 2, 4, 4, 4, 8, 8, 8},
     {0, 1, 0, 1, 0, 0, 1, 0, 0, 0}, {0, 1, 0, 2, 0, 0, 3, 0, 0, 4}, "features.17.weight", "features.16.weight"},
};

struct spx_vgg {
  spx_ctx *ctx;
  spx_tape *tape;
  spx_vgg_kind kind;
  int width;
  int w[SPX_VGG_NCONV], b[SPX_VGG_NCONV];
  int nw, nb;   /* VGG19: the normalisation 1x1 conv */
  float img_l1;          /* spx_vgg_set_image_l1 */
  spx_vgg_cache *cache;  /* spx_vgg_set_target_cache; NULL: none */
};

spx_tape *spx_vgg_tape(spx_vgg *v) { return v->tape; }
int spx_vgg_width(const spx_vgg *v) { return v->width; }

float spx_vgg_image_l1(const spx_vgg *v) { return v->img_l1; }

spx_status spx_vgg_set_image_l1(spx_vgg *v, double w) {
  if (!v) return SPX_E_ARG;
  if (!(w >= 0 && w <= 1e3)) return spx_fail(v->ctx, SPX_E_ARG, "vgg: image L1 weight %g is not in [0, 1000]", w);
  v->img_l1 = (float)w;
  return SPX_OK;
}
spx_vgg_kind spx_vgg_get_kind(const spx_vgg *v) { return v->kind; }

spx_status spx_vgg_set_target_cache(spx_vgg *v, size_t max_bytes) {
  if (!v) return SPX_E_ARG;
  return spx_vgg_cache_set(v->ctx, &v->cache, max_bytes);
}

size_t spx_vgg_target_cache_bytes(const spx_vgg *v) { return v ? spx_vgg_cache_bytes(v->cache) : 0; }

size_t spx_vgg_target_bytes(const spx_vgg *v, int h, int w) {
  if (!v || h < 1 || w < 1) return 0;
  const vgg_arch *a = &arch[v->kind];
  size_t floats = (size_t)3 * (size_t)h * (size_t)w; /* the image copy */
  int fh = h, fw = w;
  for (int i = 0; i < a->nconv; i++) {
    if (a->feat_after[i]) floats += (size_t)a->mult[i] * (size_t)v->width * (size_t)fh * (size_t)fw;
    if (a->pool_after[i]) fh /= 2, fw /= 2;
  }
  return floats * sizeof(float);
}

size_t spx_vgg_target_cache_fit(spx_vgg *v, int count, int h, int w) {
  spx_device_info info;
  if (!v || count < 1 || spx_device_get_info(v->ctx, &info)) return 0;
  size_t want = (size_t)count * spx_vgg_target_bytes(v, h, w), cap = (size_t)(info.global_mem / 4);
  return want < cap ? want : cap;
}

void spx_vgg_destroy(spx_vgg *v) {
  if (!v) return;
  spx_vgg_cache_free(v->cache);
  spx_tape_destroy(v->tape);
  free(v);
}

spx_status spx_vgg_open_ex(spx_ctx *ctx, const char *path, spx_vgg_kind kind, spx_tape_backend backend,
                           spx_vgg **out) {
  *out = NULL;
  if (kind != SPX_VGG19_EQ5 && kind != SPX_VGG16_SMPLPIX) return spx_fail(ctx, SPX_E_ARG, "vgg: unknown kind %d", kind);
  const vgg_arch *a = &arch[kind];
  spx_st_file f;
  memset(&f, 0, sizeof f);
  spx_status st = spx_st_load(ctx, path, &f);
  if (st) return st;
  spx_vgg *v = NULL;
  float *buf = NULL;
  const spx_st_tensor *t0 = spx_st_find(&f, "features.0.weight");
  if (!t0 || t0->ndim != 4 || t0->shape[1] != 3 || t0->shape[2] != 3 || t0->shape[3] != 3 || t0->shape[0] < 1 ||
      t0->shape[0] > 64) {
    st = spx_fail(ctx, SPX_E_FORMAT, "%s: %s tensor features.0.weight of shape [64, 3, 3, 3] (a torchvision %s "
                  "state_dict)", path, t0 ? "needs a" : "missing", a->name);
    goto done;
  }
  if (!spx_st_find(&f, a->mark) && spx_st_find(&f, a->not_mark)) {
    st = spx_fail(ctx, SPX_E_FORMAT, "%s: holds a %s (it has %s, no %s); this loss needs torchvision's %s", path,
                  arch[1 - kind].name, a->not_mark, a->mark, a->name);
    goto done;
  }
  if (!(v = calloc(1, sizeof *v))) {
    st = spx_fail(ctx, SPX_E_NOMEM, "vgg: out of memory");
    goto done;
  }
  v->ctx = ctx;
  v->kind = kind;
  v->width = (int)t0->shape[0];
  v->nw = v->nb = -1;
  if ((st = spx_tape_create(ctx, backend, &v->tape))) goto done;
  int cin = 3;
  for (int i = 0; i < a->nconv; i++) {
    int co = a->mult[i] * v->width;
    v->w[i] = spx_tape_state(v->tape, co, cin, 3, 3);
    v->b[i] = spx_tape_state(v->tape, co, 1, 1, 1);
    cin = co;
  }
  if (kind == SPX_VGG19_EQ5) {
    v->nw = spx_tape_state(v->tape, 3, 3, 1, 1);
    v->nb = spx_tape_state(v->tape, 3, 1, 1, 1);
  }
  if ((st = spx_tape_alloc_params(v->tape))) goto done;
  size_t cap = (size_t)64 * 8 * 8 * 64 * 9;
  if (!(buf = malloc(cap * sizeof(float)))) {
    st = spx_fail(ctx, SPX_E_NOMEM, "vgg: out of memory");
    goto done;
  }
  cin = 3;
  for (int i = 0; i < a->nconv && !st; i++) {
    int co = a->mult[i] * v->width;
    char name[64];
    int64_t ws[4] = {co, cin, 3, 3}, bs[1] = {co};
    snprintf(name, sizeof name, "features.%d.weight", a->index[i]);
    if ((st = spx_nn_st_take_f32(ctx, path, &f, name, 4, ws, buf)) || (st = spx_tape_write(v->tape, v->w[i], buf))) break;
    snprintf(name, sizeof name, "features.%d.bias", a->index[i]);
    if ((st = spx_nn_st_take_f32(ctx, path, &f, name, 1, bs, buf)) || (st = spx_tape_write(v->tape, v->b[i], buf))) break;
    cin = co;
  }
  if (!st && kind == SPX_VGG19_EQ5) {
    static const double mean[3] = {0.485, 0.456, 0.406}, sd[3] = {0.229, 0.224, 0.225};
    float nw[9] = {0}, nb[3];
    for (int c = 0; c < 3; c++) nw[c * 3 + c] = (float)(1.0 / sd[c]), nb[c] = (float)(-mean[c] / sd[c]);
    if (!(st = spx_tape_write(v->tape, v->nw, nw))) st = spx_tape_write(v->tape, v->nb, nb);
  }
done:
  free(buf);
  spx_st_free(&f);
  if (st) spx_vgg_destroy(v);
  else *out = v;
  return st;
}

spx_status spx_vgg_open(spx_ctx *ctx, const char *path, spx_vgg **out) {
  return spx_vgg_open_ex(ctx, path, SPX_VGG19_EQ5, SPX_TAPE_DEVICE, out);
}

spx_status spx_vgg16_open(spx_ctx *ctx, const char *path, spx_vgg **out) {
  return spx_vgg_open_ex(ctx, path, SPX_VGG16_SMPLPIX, SPX_TAPE_DEVICE, out);
}

/* The features of x (ids into feat[0 .. 4] for VGG19, [0 .. 3] for VGG16); VGG19 first
 * normalises x. */
static void features(spx_vgg *v, int x, int *feat) {
  spx_tape *t = v->tape;
  const vgg_arch *a = &arch[v->kind];
  int h = v->kind == SPX_VGG19_EQ5 ? spx_tape_conv(t, x, v->nw, v->nb) : x;
  for (int i = 0; i < a->nconv; i++) {
    h = spx_tape_act(t, SPX_ACT_RELU, 0.0f, spx_tape_conv(t, h, v->w[i], v->b[i]));
    if (a->feat_after[i]) feat[a->feat_after[i] - 1] = h;
    if (a->pool_after[i]) h = spx_tape_maxpool2(t, h);
  }
}

static int nfeat(const spx_vgg *v) { return v->kind == SPX_VGG16_SMPLPIX ? 4 : 5; }

/* pred's features into fp and gt's into fg: gt run through the network (then kept for the cache
 * when b has one), or, when b found every target, restored from the cache in pred's shapes.
 * -1 after a tape error. */
static int both_features(spx_vgg *v, int pred, int gt, spx_vgg_batch *b, int *fp, int *fg) {
  if (b && b->hit) {
    features(v, pred, fp);
    return spx_vgg_cache_restore(v->cache, v->tape, b->slot, b->n, fp, nfeat(v), fg);
  }
  features(v, gt, fg);
  features(v, pred, fp);
  for (int k = 0; b && b->on && k < nfeat(v); k++) {
    if (fg[k] < 0 || spx_tape_keep(v->tape, fg[k])) return -1;
    b->feat[k] = fg[k];
  }
  return 0;
}

/* VGG16: pieces x, relu1_2, relu2_2, relu3_3, relu4_3 weighted 1, 1/16, 1/8, 1/4, 1 and one mean
 * over all their elements, i.e. sum_k w_k (count_k / total) mean_k |f_k(pred) - f_k(gt)|. */
static int loss16(spx_vgg *v, int pred, int gt, spx_vgg_batch *b) {
  spx_tape *t = v->tape;
  static const double wk[5] = {1.0, 1.0 / 16, 1.0 / 8, 1.0 / 4, 1.0};
  int fp[5] = {pred, -1, -1, -1, -1}, fg[5] = {gt, -1, -1, -1, -1};
  if (both_features(v, pred, gt, b, fp + 1, fg + 1)) return -1;
  double cnt[5], total = 0;
  for (int k = 0; k < 5; k++) {
    if (fp[k] < 0 || fg[k] < 0) return -1; /* the tape's error is recorded */
    cnt[k] = (double)spx_tape_numel(t, fp[k]);
    total += cnt[k];
  }
  int loss = -1;
  for (int k = 0; k < 5; k++) {
    float c = (float)(wk[k] * cnt[k] / total);
    int l1 = spx_tape_l1(t, fp[k], fg[k]);
    loss = k ? spx_tape_axpby(t, 1.0f, loss, c, l1) : spx_tape_axpby(t, c, l1, 0.0f, -1);
  }
  return loss;
}

static int loss19(spx_vgg *v, int pred, int gt, spx_vgg_batch *b) {
  spx_tape *t = v->tape;
  int fp[5], fg[5];
  if (both_features(v, pred, gt, b, fp, fg)) return -1;
  int loss = spx_tape_axpby(t, 1.0f / 32.0f, spx_tape_l1(t, pred, gt), 0.0f, -1);
  for (int k = 1; k <= 5; k++)
    loss = spx_tape_axpby(t, 1.0f, loss, 1.0f / (float)(1 << (5 - k)), spx_tape_l1(t, fp[k - 1], fg[k - 1]));
  return loss;
}

int spx_vgg_loss_batch(spx_vgg *v, int pred, int gt, spx_vgg_batch *b) {
  int loss = v->kind == SPX_VGG16_SMPLPIX ? loss16(v, pred, gt, b) : loss19(v, pred, gt, b);
  if (loss < 0 || v->img_l1 <= 0) return loss;
  return spx_tape_axpby(v->tape, 1.0f, loss, v->img_l1, spx_tape_l1(v->tape, pred, gt));
}

int spx_vgg_loss(spx_vgg *v, int pred, int gt) { return spx_vgg_loss_batch(v, pred, gt, NULL); }

spx_status spx_vgg_batch_begin(spx_vgg *v, const float *target, int n, int h, int w, spx_vgg_batch *b) {
  memset(b, 0, sizeof *b);
  b->target = target, b->n = n, b->h = h, b->w = w;
  for (int k = 0; k < 5; k++) b->feat[k] = -1;
  if (!spx_vgg_cache_on(v->cache)) return SPX_OK;
  if (!(b->slot = malloc((size_t)n * sizeof *b->slot))) return spx_fail(v->ctx, SPX_E_NOMEM, "vgg: out of memory");
  b->on = 1;
  b->hit = spx_vgg_cache_find(v->cache, target, n, h, w, b->slot);
  return SPX_OK;
}

uint64_t spx_vgg_batch_key(const spx_vgg_batch *b, uint64_t key) {
  int mode = b->on + 2 * b->hit;
  return spx_hash64(&mode, sizeof mode, key);
}

spx_status spx_vgg_batch_end(spx_vgg *v, spx_vgg_batch *b, int forward_ran) {
  spx_status st = SPX_OK;
  if (forward_ran && b->on && !b->hit)
    st = spx_vgg_cache_put(v->ctx, v->cache, v->tape, b->target, b->n, b->h, b->w, b->feat, nfeat(v));
  free(b->slot);
  b->slot = NULL;
  return st;
}

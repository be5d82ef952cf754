/* The frozen VGG19 perceptual loss (smplpix/vgg.h). The 13 convolutions' weights live in the
 * tape's STATE slab (no gradient or Adam slabs exist for them), so backward computes only the
 * input gradients. The ImageNet normalisation is a 1x1 convolution with the diagonal weights
 * 1/std and bias -mean/std (exactly the per-channel affine map, differentiable like any conv). */
#include "nn/vgg.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "nn/st_take.h"
#include "smplpix/safetensors.h"

static const int conv_index[SPX_VGG_NCONV] = {0, 2, 5, 7, 10, 12, 14, 16, 19, 21, 23, 25, 28};
/* channel multiplier of each conv's output (x width) */
static const int conv_mult[SPX_VGG_NCONV] = {1, 1, 2, 2, 4, 4, 4, 4, 8, 8, 8, 8, 8};

struct spx_vgg {
  spx_ctx *ctx;
  spx_tape *tape;
  int width;
  int w[SPX_VGG_NCONV], b[SPX_VGG_NCONV];
  int nw, nb; /* normalisation 1x1 conv */
};

spx_tape *spx_vgg_tape(spx_vgg *v) { return v->tape; }
int spx_vgg_width(const spx_vgg *v) { return v->width; }

void spx_vgg_destroy(spx_vgg *v) {
  if (!v) return;
  spx_tape_destroy(v->tape);
  free(v);
}

spx_status spx_vgg_open_ex(spx_ctx *ctx, const char *path, spx_tape_backend backend, spx_vgg **out) {
  *out = NULL;
  spx_st_file f;
  memset(&f, 0, sizeof f);
  spx_status st = spx_st_load(ctx, path, &f);
  if (st) return st;
  spx_vgg *v = NULL;
  float *buf = NULL;
  const spx_st_tensor *t0 = spx_st_find(&f, "features.0.weight");
  if (!t0 || t0->ndim != 4 || t0->shape[1] != 3 || t0->shape[2] != 3 || t0->shape[3] != 3 || t0->shape[0] < 1 ||
      t0->shape[0] > 64) {
    st = spx_fail(ctx, SPX_E_FORMAT, "%s: %s tensor features.0.weight of shape [64, 3, 3, 3] (a torchvision VGG19 "
                  "state_dict)", path, t0 ? "needs a" : "missing");
    goto done;
  }
  if (!(v = calloc(1, sizeof *v))) {
    st = spx_fail(ctx, SPX_E_NOMEM, "vgg: out of memory");
    goto done;
  }
  v->ctx = ctx;
  v->width = (int)t0->shape[0];
  if ((st = spx_tape_create(ctx, backend, &v->tape))) goto done;
  int cin = 3;
  for (int i = 0; i < SPX_VGG_NCONV; i++) {
    int co = conv_mult[i] * v->width;
    v->w[i] = spx_tape_state(v->tape, co, cin, 3, 3);
    v->b[i] = spx_tape_state(v->tape, co, 1, 1, 1);
    cin = co;
  }
  v->nw = spx_tape_state(v->tape, 3, 3, 1, 1);
  v->nb = spx_tape_state(v->tape, 3, 1, 1, 1);
  if ((st = spx_tape_alloc_params(v->tape))) goto done;
  size_t cap = (size_t)64 * 8 * 8 * 64 * 9;
  if (!(buf = malloc(cap * sizeof(float)))) {
    st = spx_fail(ctx, SPX_E_NOMEM, "vgg: out of memory");
    goto done;
  }
  cin = 3;
  for (int i = 0; i < SPX_VGG_NCONV && !st; i++) {
    int co = conv_mult[i] * v->width;
    char name[64];
    int64_t ws[4] = {co, cin, 3, 3}, bs[1] = {co};
    snprintf(name, sizeof name, "features.%d.weight", conv_index[i]);
    if ((st = spx_nn_st_take_f32(ctx, path, &f, name, 4, ws, buf)) || (st = spx_tape_write(v->tape, v->w[i], buf))) break;
    snprintf(name, sizeof name, "features.%d.bias", conv_index[i]);
    if ((st = spx_nn_st_take_f32(ctx, path, &f, name, 1, bs, buf)) || (st = spx_tape_write(v->tape, v->b[i], buf))) break;
    cin = co;
  }
  if (!st) {
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
  return spx_vgg_open_ex(ctx, path, SPX_TAPE_DEVICE, out);
}

/* The features f_1..f_5 of x (ids into feat[0..4]). */
static void features(spx_vgg *v, int x, int feat[5]) {
  spx_tape *t = v->tape;
  /* conv i is followed by a max pool before conv i+1 for i = 1, 3, 7, 11 (features 4, 9, 18, 27) */
  static const int pool_after[SPX_VGG_NCONV] = {0, 1, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0};
  /* the slice ends (relu1_1 .. relu5_1) come after convs 0, 2, 4, 8, 12 */
  static const int feat_after[SPX_VGG_NCONV] = {1, 0, 2, 0, 3, 0, 0, 0, 4, 0, 0, 0, 5};
  int h = spx_tape_conv(t, x, v->nw, v->nb);
  for (int i = 0; i < SPX_VGG_NCONV; i++) {
    h = spx_tape_act(t, SPX_ACT_RELU, 0.0f, spx_tape_conv(t, h, v->w[i], v->b[i]));
    if (feat_after[i]) feat[feat_after[i] - 1] = h;
    if (pool_after[i]) h = spx_tape_maxpool2(t, h);
  }
}

int spx_vgg_loss(spx_vgg *v, int pred, int gt) {
  spx_tape *t = v->tape;
  int fp[5], fg[5];
  features(v, gt, fg);
  features(v, pred, fp);
  int loss = spx_tape_axpby(t, 1.0f / 32.0f, spx_tape_l1(t, pred, gt), 0.0f, -1);
  for (int k = 1; k <= 5; k++)
    loss = spx_tape_axpby(t, 1.0f, loss, 1.0f / (float)(1 << (5 - k)), spx_tape_l1(t, fp[k - 1], fg[k - 1]));
  return loss;
}

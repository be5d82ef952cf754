/* One stage-2 step: UNet generator + multi-scale PatchGAN (lib/nn/gan_step.h). */
#include "nn/gan_step.h"

#include "nn/vgg.h"

#include "core/internal.h"

#include <stdlib.h>
#include <string.h>

/* acc + wt * term (acc < 0: wt * term) */
static int wadd(spx_tape *t, int acc, float wt, int term) {
  return acc < 0 ? spx_tape_axpby(t, wt, term, 0.0f, -1) : spx_tape_axpby(t, 1.0f, acc, wt, term);
}

typedef struct dpass {
  spx_patchgan *d;
  spx_tape *gt; /* G's tape and output: the fake half's images */
  int gy;
  const float *xhost;
  int n, h, w;
  float lambda_fm;
  int x, gadv, dloss, gan, fm, dfake, dreal; /* ids the build leaves behind */
} dpass;

static spx_status d_build(spx_tape *t, void *user) {
  dpass *p = user;
  const int n = p->n, num_d = spx_patchgan_num_d(p->d);
  size_t hw = (size_t)p->h * (size_t)p->w;
  p->x = spx_tape_input(t, 2 * n, 7, p->h, p->w, p->xhost);
  spx_status st = p->x >= 0 ? spx_tape_requires_grad(t, p->x) : SPX_OK;
  for (int i = 0; i < n && !st && p->x >= 0; i++) /* the generated images into the fake half */
    st = spx_tape_transfer(t, p->x, ((size_t)i * 7 + 4) * hw, 0, p->gt, p->gy, (size_t)i * 3 * hw, 0, 3 * hw, 0);
  if (st) return st;
  int feat[SPX_PG_MAX_D][SPX_PG_LAYERS];
  spx_patchgan_forward(p->d, p->x, feat);
  p->gan = p->fm = p->dfake = p->dreal = -1;
  for (int k = 0; k < num_d; k++) {
    int last = feat[k][SPX_PG_LAYERS - 1];
    int fake = spx_tape_slice_batch(t, last, 0, n), real = spx_tape_slice_batch(t, last, n, n);
    p->gan = wadd(t, p->gan, 1.0f, spx_tape_mse_const(t, fake, 1.0f));
    p->dfake = wadd(t, p->dfake, 1.0f, spx_tape_mse_const(t, fake, 0.0f));
    p->dreal = wadd(t, p->dreal, 1.0f, spx_tape_mse_const(t, real, 1.0f));
    for (int j = 0; j < SPX_PG_LAYERS - 1; j++) { /* l1's target (the real half) gets no gradient */
      int f = feat[k][j];
      float wt = (1.0f / (float)num_d) * (4.0f / (3.0f + 1.0f));
      p->fm = wadd(t, p->fm, wt, spx_tape_l1(t, spx_tape_slice_batch(t, f, 0, n), spx_tape_slice_batch(t, f, n, n)));
    }
  }
  p->gadv = spx_tape_axpby(t, 1.0f, p->gan, p->lambda_fm, p->fm);
  p->dloss = spx_tape_axpby(t, 0.5f, p->dfake, 0.5f, p->dreal);
  int terms[6] = {p->gan, p->fm, p->gadv, p->dfake, p->dreal, p->dloss}; /* read after the backward */
  for (int i = 0; i < 6; i++)
    if (terms[i] >= 0) spx_tape_keep(t, terms[i]);
  return SPX_OK;
}

static spx_status d_forward(dpass *p) {
  spx_tape *t = spx_patchgan_tape(p->d);
  uint64_t key = spx_hash64(&p->n, sizeof p->n, SPX_FNV_SEED);
  key = spx_hash64(&p->h, sizeof p->h, key);
  key = spx_hash64(&p->w, sizeof p->w, key);
  spx_tape_set_retain(t, 1); /* backward runs twice over this pass: G's adversarial loss, then D's */
  return spx_tape_pass(t, 1, key, d_build, p);
}

/* VGG pass: pred (handed over from G's output, gradient wanted) and gt (no gradient). */
typedef struct vpass {
  spx_vgg *v;
  spx_tape *gt;
  int gy;
  const float *target;
  int n, h, w;
  spx_vgg_batch b; /* the target-feature cache's lookup */
  int x, loss;     /* ids the build leaves behind */
} vpass;

static spx_status vgg_build(spx_tape *t, void *user) {
  vpass *p = user;
  p->x = spx_tape_input(t, p->n, 3, p->h, p->w, NULL);
  int tg = spx_tape_input(t, p->n, 3, p->h, p->w, p->target);
  spx_status st = p->x >= 0 ? spx_tape_requires_grad(t, p->x) : SPX_OK;
  if (!st && p->x >= 0)
    st = spx_tape_transfer(t, p->x, 0, 0, p->gt, p->gy, 0, 0, (size_t)p->n * 3 * p->h * p->w, 0);
  if (st) return st;
  p->loss = spx_vgg_loss_batch(p->v, p->x, tg, &p->b);
  return SPX_OK;
}

static spx_status vgg_forward(vpass *p) {
  uint64_t key = spx_hash64(&p->n, sizeof p->n, SPX_FNV_SEED ^ 0x7667ULL);
  key = spx_hash64(&p->h, sizeof p->h, key);
  key = spx_hash64(&p->w, sizeof p->w, key);
  float wl1 = spx_vgg_image_l1(p->v); /* the loss's image L1 weight is a constant of the graph */
  key = spx_hash64(&wl1, sizeof wl1, key);
  spx_status st = spx_vgg_batch_begin(p->v, p->target, p->n, p->h, p->w, &p->b);
  if (st) return st;
  st = spx_tape_pass(spx_vgg_tape(p->v), 1, spx_vgg_batch_key(&p->b, key), vgg_build, p);
  spx_status end = spx_vgg_batch_end(p->v, &p->b, st == SPX_OK);
  return st ? st : end;
}

spx_status spx_gan_step(spx_ctx *ctx, spx_unet *g, spx_patchgan *d, spx_vgg *vgg, const float *in,
                        const float *target, int n, int h, int w, const spx_gan_opts *o, spx_gan_losses *terms) {
  spx_tape *gt = spx_unet_tape(g), *dt = d ? spx_patchgan_tape(d) : NULL, *vt = vgg ? spx_vgg_tape(vgg) : NULL;
  spx_status st;
  if (d && spx_patchgan_in_channels(d) != SPX_UNET_IN_CHANNELS + SPX_UNET_OUT_CHANNELS)
    return spx_fail(ctx, SPX_E_ARG, "gan: the discriminator takes %d channels, not 7", spx_patchgan_in_channels(d));
  size_t hw = (size_t)h * (size_t)w;
  float *xh = d ? calloc((size_t)2 * n * 7 * hw, sizeof(float)) : NULL;
  if (d && !xh) {
    return spx_fail(ctx, SPX_E_NOMEM, "gan: out of memory for a batch of %d %dx%d images", 2 * n, h, w);
  }
  for (int i = 0; i < n && xh; i++) { /* [in, (fake)] then [in, real] */
    memcpy(xh + (size_t)i * 7 * hw, in + (size_t)i * 4 * hw, 4 * hw * sizeof(float));
    memcpy(xh + (size_t)(n + i) * 7 * hw, in + (size_t)i * 4 * hw, 4 * hw * sizeof(float));
    memcpy(xh + ((size_t)(n + i) * 7 + 4) * hw, target + (size_t)i * 3 * hw, 3 * hw * sizeof(float));
  }
  if (dt) spx_tape_copy_shard(dt, gt); /* data-parallel: D's and VGG's seeds take G's share of the batch */
  if (vt) spx_tape_copy_shard(vt, gt);
  float rec = 0, vl = 0;
  if ((st = spx_unet_zero_grad(g)) || (st = spx_unet_forward_loss(g, in, target, n, h, w, NULL, &rec))) goto done;
  int gy = spx_unet_output_id(g);
  dpass p = {d, gt, gy, xh, n, h, w, o->lambda_fm, -1, -1, -1, -1, -1, -1, -1};
  vpass vp = {vgg, gt, gy, target, n, h, w, {0}, -1, -1};
  if (d && (st = d_forward(&p))) goto done;
  if (vgg && (st = vgg_forward(&vp))) goto done;
  /* G: through D (its input gradient, fake half, image channels), through VGG, plus its own L1 */
  if ((d && (st = spx_tape_backward(dt, p.gadv))) || (vgg && (st = spx_tape_backward(vt, vp.loss))) ||
      (st = spx_tape_backward_begin(gt)) || (!vgg && (st = spx_tape_seed(gt, spx_unet_loss_id(g), o->lambda_rec))))
    goto done;
  for (int i = 0; i < n && !st && d; i++)
    st = spx_tape_transfer(gt, gy, (size_t)i * 3 * hw, 1, dt, p.x, ((size_t)i * 7 + 4) * hw, 1, 3 * hw, 1);
  if (!st && vgg) st = spx_tape_transfer(gt, gy, 0, 1, vt, vp.x, 0, 1, (size_t)n * 3 * hw, 1);
  if (st || (st = spx_tape_backward_run(gt)) || (st = spx_unet_adam_step_ex(g, o->lr_g, o->beta1, o->beta2, o->eps)))
    goto done;
  /* D: its own loss, its own gradients only */
  if (d && ((st = spx_tape_zero_grad(dt)) || (st = spx_tape_backward(dt, p.dloss)) ||
            (st = spx_patchgan_adam(d, o->lr_d, o->beta1, o->beta2, o->eps))))
    goto done;
  if (vgg && (st = spx_tape_read(vt, vp.loss, &vl))) goto done;
  if (terms) {
    float v[6] = {0};
    int ids[6] = {p.gan, p.fm, p.gadv, p.dfake, p.dreal, p.dloss};
    for (int i = 0; i < 6 && !st && d; i++) st = spx_tape_read(dt, ids[i], &v[i]);
    terms->rec = rec, terms->vgg = vl, terms->gan = v[0], terms->fm = v[1];
    terms->g_total = (vgg ? vl : o->lambda_rec * rec) + v[2];
    terms->d_fake = v[3], terms->d_real = v[4], terms->d_total = v[5];
  }
done:
  free(xh);
  return st;
}

spx_status spx_unet_gan_step(spx_unet *g, spx_patchgan *d, spx_vgg *vgg, const float *input, const float *target,
                             int n, int h, int w, double lr_g, double lr_d, spx_gan_losses *out) {
  spx_ctx *ctx = spx_unet_ctx(g);
  if (!input || !target || !d) return spx_fail(ctx, SPX_E_ARG, "gan: input, target or discriminator is NULL");
  spx_gan_opts o = {lr_g, lr_d, 0.9, 0.999, 1e-8, 0.1f, 1.0f};
  return spx_gan_step(ctx, g, d, vgg, input, target, n, h, w, &o, out);
}

spx_status spx_unet_vgg_step(spx_unet *g, spx_vgg *vgg, const float *input, const float *target, int n, int h, int w,
                             double lr, spx_gan_losses *out) {
  spx_ctx *ctx = spx_unet_ctx(g);
  if (!input || !target || !vgg) return spx_fail(ctx, SPX_E_ARG, "vgg: input, target or network is NULL");
  spx_gan_opts o = {lr, lr, 0.9, 0.999, 1e-8, 0.1f, 1.0f};
  return spx_gan_step(ctx, g, NULL, vgg, input, target, n, h, w, &o, out);
}

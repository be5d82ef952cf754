/* The paper's training recipe for `smplpix train` (see apps/train_recipe.h). */
#include "train_recipe.h"

#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const char *const loss_names[3][2] = {{"l1", "l1+gan"}, {"vgg", "vgg+gan"}, {"vgg16", "vgg16+gan"}};

int train_loss_parse(const char *name, int *gan, int *vgg) {
  for (int v = 0; v < 3; v++)
    for (int g = 0; g < 2; g++)
      if (!strcmp(name, loss_names[v][g])) return *vgg = v, *gan = g, 0;
  *gan = *vgg = 0;
  return spx_cli_usage("train", "--loss must be l1, l1+gan, vgg, vgg+gan, vgg16 or vgg16+gan, not '%s'", name);
}

const char *train_loss_name(const train_recipe *r) { return loss_names[r->vgg][r->gan[r->stage] ? 1 : 0]; }

int64_t train_recipe_step_count(const train_recipe *r, const spx_unet *u) { return r->base + spx_unet_step(u); }

static char *disc_path_of(const char *outp) {
  size_t n = strlen(outp);
  const char *suf = ".safetensors";
  size_t ls = strlen(suf), keep = n >= ls && !strcmp(outp + n - ls, suf) ? n - ls : n;
  char *p = malloc(keep + 32);
  if (p) snprintf(p, keep + 32, "%.*s.disc.safetensors", (int)keep, outp);
  return p;
}

static int need_disc(spx_ctx *ctx, train_recipe *r, int load) {
  if (r->d || !r->gan[r->stage]) return 0;
  spx_status st = load ? spx_patchgan_open(ctx, r->disc_path, &r->d)
                       : spx_patchgan_new(ctx, r->disc_width, r->num_d, r->seed ^ 0xd15cULL, &r->d);
  if (!st && r->comm) st = spx_patchgan_set_comm(r->d, r->comm);
  if (st) return spx_cli_error("train", ctx);
  if (load && spx_patchgan_ndf(r->d) != r->disc_width) /* the record and the tensors must agree */
    return spx_cli_errorf("train", "%s has width %d, but the checkpoint records disc width %d", r->disc_path,
                          spx_patchgan_ndf(r->d), r->disc_width);
  return 0;
}

int train_recipe_start(spx_ctx *ctx, train_recipe *r, spx_unet *u, const char *outp, const char *from,
                       const spx_train_state *rec) {
  r->stage = r->schedule ? 1 : (r->gan[2] ? 2 : 1);
  r->base = 0;
  if (!(r->disc_path = disc_path_of(outp))) return spx_cli_errorf("train", "out of memory");
  if ((r->gan[1] || r->gan[2]) && (!r->comm || r->comm->rank == 0)) { /* W.disc: writable, no input */
    spx_tx chk;
    spx_tx_begin(&chk, "train", 0);
    int rc = spx_tx_check(&chk, r->disc_path);
    spx_tx_end(&chk);
    if (rc) return rc;
  }
  int resume = rec != NULL;
  if (rec) { /* the stage record of the checkpoint (spx_train_state_read checked its ranges) */
    if (!r->schedule && strcmp(train_loss_name(r), rec->loss)) /* cmd_train takes the loss from rec */
      return spx_cli_errorf("train", "%s was trained with --loss %s, not %s (start a new run with --init)", from,
                            rec->loss, train_loss_name(r));
    r->stage = (int)rec->stage, r->base = rec->stage_base;
    if (r->schedule) r->stage1_steps = rec->stage1_steps;
  }
  if (r->vgg && (r->vgg == TRAIN_VGG16 ? spx_vgg16_open(ctx, r->vgg_path, &r->net_vgg)
                                       : spx_vgg_open(ctx, r->vgg_path, &r->net_vgg)))
    return spx_cli_error("train", ctx);
  if (r->vgg_cached && spx_vgg_width(r->net_vgg) != 64) /* the loader takes narrow test networks */
    return spx_cli_errorf("train", "%s: a VGG16 of width %d (features.0.weight [%d, 3, 3, 3]), but the cached weights "
                          "must be torchvision's, width 64 (`make weights` fetches them; --vgg takes another file)",
                          r->vgg_path, spx_vgg_width(r->net_vgg), spx_vgg_width(r->net_vgg));
  int load = resume && r->gan[r->stage] && (!r->comm || r->comm->rank == 0); /* else rank 0's comes later */
  int rc = need_disc(ctx, r, load);
  if (rc) return rc;
  if (r->d && load && spx_patchgan_step(r->d) != spx_unet_step(u))
    return spx_cli_errorf("train", "%s has %" PRId64 " discriminator steps but %s has %" PRId64
                          " generator steps in stage %d: they are not from the same run",
                          r->disc_path, spx_patchgan_step(r->d), from, spx_unet_step(u), r->stage);
  return 0;
}

int train_recipe_step(spx_ctx *ctx, train_recipe *r, spx_unet *u, const float *in, const float *tg, int n, int h,
                      int w, float *loss) {
  spx_status st;
  if (r->schedule && r->stage == 1 && train_recipe_step_count(r, u) >= r->stage1_steps) { /* stage 2 begins */
    int64_t now = train_recipe_step_count(r, u);
    if (spx_unet_reset_optimizer(u)) return spx_cli_error("train", ctx);
    r->stage = 2;
    r->base = now;
    int rc = need_disc(ctx, r, 0);
    if (rc) return rc;
    printf("step %" PRId64 ": stage 2 (--loss %s, Adam restarted, lr %g)\n", now, train_loss_name(r), r->lr2);
    fflush(stdout);
  }
  double lr = train_recipe_lr(r, train_recipe_step_count(r, u));
  spx_gan_losses gl;
  memset(&gl, 0, sizeof gl);
  if (r->gan[r->stage]) {
    st = spx_unet_gan_step(u, r->d, r->net_vgg, in, tg, n, h, w, lr, lr, &gl);
    if (!st) *loss = gl.g_total;
  } else if (r->vgg) {
    st = spx_unet_vgg_step(u, r->net_vgg, in, tg, n, h, w, lr, &gl);
    if (!st) *loss = gl.vgg;
  } else {
    if (!(st = spx_unet_zero_grad(u)) && !(st = spx_unet_forward_loss(u, in, tg, n, h, w, NULL, loss)) &&
        !(st = spx_unet_backward(u)))
      st = spx_unet_adam_step(u, lr);
    gl.rec = *loss;
  }
  if (!st) {
    double v[6] = {*loss, gl.rec, gl.gan, gl.fm, gl.d_total, gl.vgg};
    if (r->comm) { /* the global batch's mean terms: the ranks' means weighted by their shares */
      float g[6];
      for (int i = 0; i < 6; i++) g[i] = (float)(v[i] * r->share);
      if (r->comm->allreduce_sum(r->comm->self, g, 6))
        return spx_cli_errorf("train", "rank %d: summing the loss over %d ranks failed", r->comm->rank, r->comm->size);
      for (int i = 0; i < 6; i++) v[i] = g[i];
      *loss = g[0];
    }
    for (int i = 0; i < 6; i++) r->sum[i] += v[i];
  }
  if (st) return st == SPX_E_DEVMEM || st == SPX_E_NOMEM
                     ? spx_cli_errorf("train", "a step on %d images of %dx%d at width %d: %s (try a smaller --batch or "
                                      "--width)", n, w, h, spx_unet_width(u), spx_ctx_message(ctx))
                     : spx_cli_error("train", ctx);
  r->count++;
  return 0;
}

double train_recipe_lr(const train_recipe *r, int64_t now) {
  double lr = r->schedule && r->stage == 2 ? r->lr2 : r->lr1;
  if (!r->cosine) return lr;
  int64_t start = r->base, end = r->schedule && r->stage == 1 ? r->stage1_steps : r->end;
  double t = end > start ? (double)(now - start) / (double)(end - start) : 1;
  t = t < 0 ? 0 : t > 1 ? 1 : t;
  return lr * 0.5 * (1 + cos(3.14159265358979323846 * t));
}

void train_recipe_terms(const train_recipe *r, char *buf, size_t cap) {
  buf[0] = 0;
  if ((!r->gan[r->stage] && !r->vgg) || !r->count) return;
  double c = r->count;
  size_t n = 0;
  n += (size_t)snprintf(buf, cap, " (");
  if (r->vgg && n < cap) n += (size_t)snprintf(buf + n, cap - n, "VGG %.4f, ", r->sum[5] / c);
  if (n < cap) n += (size_t)snprintf(buf + n, cap - n, "L1 %.4f", r->sum[1] / c);
  if (r->gan[r->stage] && n < cap)
    n += (size_t)snprintf(buf + n, cap - n, ", GAN %.4f, FM %.4f, D %.4f", r->sum[2] / c, r->sum[3] / c, r->sum[4] / c);
  if (n < cap) snprintf(buf + n, cap - n, ")");
}

void train_recipe_epoch_reset(train_recipe *r) {
  memset(r->sum, 0, sizeof r->sum);
  r->count = 0;
}

void train_recipe_record(const train_recipe *r, spx_train_state *s) {
  snprintf(s->loss, sizeof s->loss, "%s", train_loss_name(r));
  snprintf(s->schedule, sizeof s->schedule, "%s", r->schedule ? "paper" : "");
  snprintf(s->lr_decay, sizeof s->lr_decay, "%s", r->cosine ? "cosine" : "");
  s->stage = r->stage, s->stage_base = r->base, s->stage1_steps = r->schedule ? r->stage1_steps : 0;
  s->lr = r->lr1, s->lr2 = r->lr2, s->disc_width = r->disc_width;
}

spx_patchgan *train_recipe_disc(const train_recipe *r) { return r->d && r->gan[r->stage] ? r->d : NULL; }

void train_recipe_free(train_recipe *r) {
  spx_patchgan_destroy(r->d);
  spx_vgg_destroy(r->net_vgg);
  r->net_vgg = NULL;
  free(r->disc_path);
  r->d = NULL;
  r->disc_path = NULL;
}

/* The per-subject network of `smplpix avatar` (apps/avatar_app.h): steps1 Adam steps on the mean
 * L1 loss (lr1), then Adam restarted and steps2 steps on the VGG16 perceptual loss (lr2, the
 * official SMPLpix loss, smplpix/vgg.h) plus image_l1 x the image's mean L1 (the colour the
 * perceptual loss alone lets drift), batches in a seeded order per epoch
 * (spx_cli_epoch_order). The checkpoint OUT/work/net.safetensors (weights, Adam state, and the
 * metadata smplpix.avatar.train.{step,stage,cpu}) is rewritten durably every save_every steps,
 * at the end of stage 1 and on Ctrl-C, so a run continues from it bit for bit: the data set is
 * rebuilt identically, the order depends on (seed, epoch) only, and the stage and step come from
 * the file. Validation PSNR and LPIPS are printed every val_every steps and at the end of each
 * stage. The frozen VGG16 keeps the training targets' features (spx_vgg_set_target_cache): the
 * same bits, with only the prediction through the VGG16 after the first epoch. */
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "avatar_app.h"
#include "test_hooks.h"

/* The state of one training run. */
typedef struct av_run {
  const char *cmd;
  spx_ctx *ctx;
  const av_train_cfg *cfg;
  spx_unet *u;
  spx_vgg *vgg;
  spx_lpips *lp;
  int64_t step, total;  /* global steps done, steps1 + steps2 */
  double cpu_prev, cpu0; /* CPU seconds of earlier sittings; av_cpu_now() when this one began */
  float *in, *tg, *out, *hwc_a, *hwc_b;
  int *perm;
  double loss_sum;
  int loss_count;
  double t0;
  double val_psnr, val_lpips; /* the last validation (NAN before the first) */
  int tty, bar_shown;         /* the in-place progress bar on a terminal */
  double bar_t, start_t;
  int64_t start_step;
} av_run;

double av_cpu_now(void) {
  struct timespec ts;
  return clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts) == 0 ? (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec : 0;
}

static void bar_clear(av_run *r) {
  if (!r->bar_shown) return;
  fputs("\r\033[K", stderr);
  fflush(stderr);
  r->bar_shown = 0;
}

static int stage_of(const av_run *r, int64_t step) { return step < r->cfg->steps1 ? 1 : 2; }

static int save(av_run *r) {
  char step[32], stage[8], cpu[48];
  snprintf(step, sizeof step, "%lld", (long long)r->step);
  snprintf(stage, sizeof stage, "%d", stage_of(r, r->step > 0 ? r->step - 1 : 0));
  snprintf(cpu, sizeof cpu, "%.17g", r->cpu_prev + av_cpu_now() - r->cpu0);
  const char *keys[] = {"smplpix.avatar.train.step", "smplpix.avatar.train.stage", "smplpix.avatar.train.cpu"};
  const char *vals[] = {step, stage, cpu};
  spx_tx tx;
  spx_tx_begin(&tx, r->cmd, 1);
  const char *tmp = spx_tx_stage(&tx, r->cfg->ckpt);
  int rc = SPX_EXIT_ERROR;
  if (tmp && spx_unet_save_meta(r->u, tmp, 1, keys, vals, 3)) rc = spx_tx_error(&tx, r->ctx);
  else if (tmp) rc = spx_tx_commit(&tx);
  spx_tx_end(&tx);
  return rc;
}

/* A new network, or the checkpoint's (its step and CPU time). */
static int open_net(av_run *r) {
  const av_train_cfg *c = r->cfg;
  if (access(c->ckpt, F_OK) != 0) {
    if (spx_unet_create(r->ctx, c->width, 0, c->seed, &r->u)) return spx_cli_error(r->cmd, r->ctx);
    return SPX_EXIT_OK;
  }
  spx_st_file f;
  memset(&f, 0, sizeof f);
  if (spx_st_load(r->ctx, c->ckpt, &f)) return spx_cli_error(r->cmd, r->ctx);
  const char *s = spx_st_meta(&f, "smplpix.avatar.train.step"), *cpu = spx_st_meta(&f, "smplpix.avatar.train.cpu");
  char *end = NULL;
  long long step = s ? strtoll(s, &end, 10) : -1;
  int ok = s && end != s && !*end && step >= 0 && step <= r->total && cpu;
  r->step = ok ? step : 0, r->cpu_prev = ok ? strtod(cpu, NULL) : 0;
  spx_st_free(&f);
  if (!ok) return spx_cli_errorf(r->cmd, "%s: records no training step within 0..%lld", c->ckpt, (long long)r->total);
  if (spx_unet_load(r->ctx, c->ckpt, &r->u)) return spx_cli_error(r->cmd, r->ctx);
  int64_t base = stage_of(r, r->step > 0 ? r->step - 1 : 0) == 2 ? c->steps1 : 0;
  if (spx_unet_width(r->u) != c->width || spx_unet_step(r->u) != r->step - base)
    return spx_cli_errorf(r->cmd, "%s: width %d and %lld Adam steps do not continue this run (width %d, step %lld)",
                          c->ckpt, spx_unet_width(r->u), (long long)spx_unet_step(r->u), c->width, (long long)r->step);
  return SPX_EXIT_OK;
}

/* Mean PSNR and LPIPS of the network's output (clamped to [0,1]) over a split. */
static int validate(av_run *r, const av_set *s, double *psnr, double *lpips) {
  size_t hw = (size_t)s->W * s->H;
  double ps = 0, ls = 0;
  for (int i = 0; i < s->n; i++) {
    if (spx_unet_forward(r->u, s->in + (size_t)i * SPX_UNET_IN_CHANNELS * hw, 1, s->H, s->W, 0, r->out))
      return spx_cli_error(r->cmd, r->ctx);
    const float *tg = s->tg + (size_t)i * SPX_UNET_OUT_CHANNELS * hw;
    for (size_t q = 0; q < hw; q++)
      for (int c = 0; c < 3; c++) {
        float o = r->out[(size_t)c * hw + q];
        r->hwc_a[q * 3 + (size_t)c] = o < 0 ? 0 : o > 1 ? 1 : o;
        r->hwc_b[q * 3 + (size_t)c] = tg[(size_t)c * hw + q];
      }
    spx_image a = {s->W, s->H, 3, r->hwc_a}, b = {s->W, s->H, 3, r->hwc_b};
    spx_metrics m;
    double l = 0;
    if (spx_image_metrics(r->ctx, &a, &b, NULL, &m) || spx_lpips_distance(r->lp, &a, &b, &l))
      return spx_cli_error(r->cmd, r->ctx);
    ps += m.psnr, ls += l;
  }
  *psnr = s->n ? ps / s->n : 0, *lpips = s->n ? ls / s->n : 0;
  return SPX_EXIT_OK;
}

/* One optimizer step on the batch of global step r->step. */
static int one_step(av_run *r, const av_set *tr) {
  const av_train_cfg *c = r->cfg;
  int b = c->batch < tr->n ? c->batch : tr->n;
  int64_t spe = (tr->n + b - 1) / b, epoch = r->step / spe, pos = r->step % spe;
  spx_cli_epoch_order(r->perm, tr->n, c->seed, epoch, 1);
  int first = (int)(pos * b), n = tr->n - first < b ? tr->n - first : b;
  size_t hw = (size_t)tr->W * tr->H, ni = SPX_UNET_IN_CHANNELS * hw, no = SPX_UNET_OUT_CHANNELS * hw;
  for (int k = 0; k < n; k++) {
    memcpy(r->in + (size_t)k * ni, tr->in + (size_t)r->perm[first + k] * ni, ni * sizeof(float));
    memcpy(r->tg + (size_t)k * no, tr->tg + (size_t)r->perm[first + k] * no, no * sizeof(float));
  }
  if (r->step == c->steps1 && spx_unet_reset_optimizer(r->u)) /* stage 2 */
    return bar_clear(r), spx_cli_error(r->cmd, r->ctx);
  float loss = 0;
  spx_status st;
  if (stage_of(r, r->step) == 1) {
    if (!(st = spx_unet_zero_grad(r->u)) && !(st = spx_unet_forward_loss(r->u, r->in, r->tg, n, tr->H, tr->W, NULL, &loss)) &&
        !(st = spx_unet_backward(r->u)))
      st = spx_unet_adam_step(r->u, c->lr1);
  } else {
    spx_gan_losses gl;
    st = spx_unet_vgg_step(r->u, r->vgg, r->in, r->tg, n, tr->H, tr->W, c->lr2, &gl);
    loss = gl.vgg;
  }
  if (st) return bar_clear(r), spx_cli_error(r->cmd, r->ctx);
  if (!isfinite(loss))
    return bar_clear(r), spx_cli_errorf(r->cmd, "the training loss became %g at step %lld", loss, (long long)r->step);
  r->loss_sum += loss, r->loss_count++;
  r->step++;
  return SPX_EXIT_OK;
}

/* On a terminal: [####......] step, stage, loss, the last validation scores, time per step, ETA
 * (redrawn at most 10 times a second). */
static void bar_show(av_run *r) {
  double t = spx_now();
  if (!r->tty || r->cfg->quiet || (r->bar_shown && t - r->bar_t < 0.1 && r->step < r->total)) return;
  double per = r->step > r->start_step ? (t - r->start_t) / (double)(r->step - r->start_step) : 0;
  char bar[21], val[64] = "";
  int fill = (int)(20 * r->step / (r->total ? r->total : 1));
  for (int k = 0; k < 20; k++) bar[k] = k < fill ? '#' : '.';
  bar[20] = 0;
  if (isfinite(r->val_psnr)) snprintf(val, sizeof val, "  validation %.2f dB, LPIPS %.4f", r->val_psnr, r->val_lpips);
  fprintf(stderr, "\r\033[K[%s] step %lld/%lld (%s) loss %.5f%s  %.2f s/step  ETA %.0f s", bar, (long long)r->step,
          (long long)r->total, stage_of(r, r->step > 0 ? r->step - 1 : 0) == 1 ? "L1" : "VGG16",
          r->loss_count ? r->loss_sum / r->loss_count : 0.0, val, per, per * (double)(r->total - r->step));
  fflush(stderr);
  r->bar_shown = 1, r->bar_t = t;
}

/* The progress line of the steps since the last one, with the validation scores. */
static int report(av_run *r, const av_set *val) {
  double ps = 0, lp = 0;
  bar_clear(r);
  int rc = val->n ? validate(r, val, &ps, &lp) : SPX_EXIT_OK;
  r->val_psnr = ps, r->val_lpips = lp;
  if (rc || r->cfg->quiet) return rc;
  double el = spx_now() - r->t0, per = r->loss_count ? el / r->loss_count : 0;
  printf("step %lld/%lld (%s): loss %.5f, validation PSNR %.2f dB, LPIPS %.4f, %.2f s/step, ETA %.0f s\n",
         (long long)r->step, (long long)r->total, stage_of(r, r->step - 1) == 1 ? "L1" : "VGG16",
         r->loss_count ? r->loss_sum / r->loss_count : 0.0, ps, lp, per, per * (double)(r->total - r->step));
  fflush(stdout);
  r->loss_sum = 0, r->loss_count = 0, r->t0 = spx_now();
  return SPX_EXIT_OK;
}

static int loop(av_run *r, const av_set *tr, const av_set *val) {
  const av_train_cfg *c = r->cfg;
  int stop = spx_test_hook_int("SPX_TEST_AVATAR_STOP_STEP"), sig = spx_test_hook_int("SPX_TEST_AVATAR_STOP_SIGNAL");
  r->t0 = r->start_t = spx_now(), r->start_step = r->step;
  while (r->step < r->total) {
    int rc = one_step(r, tr);
    if (rc) return rc;
    bar_show(r);
    if (r->step == stop) raise(sig > 0 ? sig : SIGKILL); /* the tests' kill at a step */
    int end_stage = r->step == c->steps1 || r->step == r->total;
    if ((r->step % c->val_every == 0 || end_stage) && (rc = report(r, val))) return rc;
    if ((r->step % c->save_every == 0 || end_stage || *c->interrupted) && (bar_clear(r), rc = save(r))) return rc;
    if (*c->interrupted && r->step < r->total) {
      bar_clear(r);
      fprintf(stderr, "smplpix %s: interrupted after training step %lld of %lld: saved %s (continue with --resume)\n",
              r->cmd, (long long)r->step, (long long)r->total, c->ckpt);
      return 128 + (int)*c->interrupted;
    }
  }
  return SPX_EXIT_OK;
}

int av_train(const char *cmd, spx_ctx *ctx, const av_train_cfg *cfg, const av_set *train, const av_set *val,
             spx_unet **u, double *cpu) {
  av_run r;
  memset(&r, 0, sizeof r);
  r.cmd = cmd, r.ctx = ctx, r.cfg = cfg, r.total = cfg->steps1 + cfg->steps2, r.cpu0 = av_cpu_now();
  r.val_psnr = r.val_lpips = NAN, r.tty = isatty(STDERR_FILENO);
  size_t hw = (size_t)train->W * train->H, b = (size_t)(cfg->batch < train->n ? cfg->batch : train->n);
  r.in = malloc(b * SPX_UNET_IN_CHANNELS * hw * sizeof(float));
  r.tg = malloc(b * SPX_UNET_OUT_CHANNELS * hw * sizeof(float));
  r.out = malloc(SPX_UNET_OUT_CHANNELS * hw * sizeof(float));
  r.hwc_a = malloc(3 * hw * sizeof(float)), r.hwc_b = malloc(3 * hw * sizeof(float));
  r.perm = malloc((size_t)train->n * sizeof(int));
  int rc = SPX_EXIT_OK;
  if (!r.in || !r.tg || !r.out || !r.hwc_a || !r.hwc_b || !r.perm) rc = spx_cli_errorf(cmd, "out of memory for training");
  if (!rc) rc = open_net(&r);
  if (!rc && (spx_vgg16_open(ctx, cfg->vgg16, &r.vgg) || spx_vgg_set_image_l1(r.vgg, cfg->image_l1) ||
              spx_vgg_set_target_cache(r.vgg, spx_vgg_target_cache_fit(r.vgg, train->n, train->H, train->W)) || spx_lpips_load(ctx, cfg->lpips, &r.lp)))
    rc = spx_cli_error(cmd, ctx);
  char extra[64] = "";
  if (cfg->image_l1 > 0) snprintf(extra, sizeof extra, " + %g x L1", cfg->image_l1);
  if (!rc && !cfg->quiet)
    printf("training: %d views (%dx%d), width %d, batch %zu: %lld steps L1 (lr %g), then %lld VGG16%s (lr %g)\n",
           train->n, train->W, train->H, cfg->width, b, (long long)cfg->steps1, cfg->lr1, (long long)cfg->steps2, extra,
           cfg->lr2);
  if (!rc && r.step && !cfg->quiet) printf("continuing at step %lld of %lld\n", (long long)r.step, (long long)r.total);
  fflush(stdout);
  if (!rc) rc = loop(&r, train, val);
  bar_clear(&r);
  *cpu = r.cpu_prev + av_cpu_now() - r.cpu0;
  spx_vgg_destroy(r.vgg);
  spx_lpips_free(r.lp);
  free(r.in), free(r.tg), free(r.out), free(r.hwc_a), free(r.hwc_b), free(r.perm);
  if (rc) spx_unet_destroy(r.u);
  else *u = r.u;
  return rc;
}

/* The autodiff tape (lib/nn/tape.h) on a whole tiny UNet.
 *  - finite differences: the HOST backend runs the double-precision references, so the gradient
 *    of the L1 loss with respect to parameters of every tensor (every op kind: conv, batch norm,
 *    ReLU, max pool, bilinear upsampling, pad, concat, 1x1 conv with bias, sigmoid, L1) is
 *    checked against central differences with a tight tolerance;
 *  - accumulation: two backward passes give twice the gradients; zero_grad clears them;
 *  - planning: a second pass of the same shape plans nothing, a new shape plans once;
 *  - inference: backward after an eval forward is refused;
 *  - the DEVICE backend matches the HOST backend (same init) on outputs, loss and gradients;
 *  - the op table (lib/nn/tape_ops.c) has a complete row for every op kind, names unique. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "nn/tape_internal.h"
#include "nn/unet.h"
#include "nn_testutil.h"
#include "smplpix/smplpix.h"
#include "smplpix/unet.h"

/* Odd sizes: 37x35 -> 18x17 -> 9x8 -> 4x4 -> 2x2, so three of the four up blocks pad. */
enum { N = 2, H = 37, W = 35, WIDTH = 2 };

static void make_data(float *in, float *tg) {
  unsigned long long s = 0x5eed;
  spx_nt_rand(in, (size_t)N * 4 * H * W, 0.0f, 1.0f, &s);
  spx_nt_rand(tg, (size_t)N * 3 * H * W, 0.0f, 1.0f, &s);
}

static double host_loss(spx_unet *u, const float *in, const float *tg) {
  if (spx_unet_forward_loss(u, in, tg, N, H, W, NULL, NULL)) return NAN;
  return spx_tape_host(spx_unet_tape(u), spx_unet_loss_id(u))[0];
}

/* A host-tape UNet (width WIDTH) in a new context *ctx, and its data *in / *tg (make_data); NULL, the
 * context destroyed, when it cannot be made. */
static spx_unet *host_unet(spx_ctx **ctx, int sigmoid, uint64_t seed, float **in, float **tg) {
  *ctx = NULL;
  CHECK(spx_t_ctx_create(ctx) == SPX_OK);
  spx_unet *u = NULL;
  CHECK_OK(*ctx, spx_unet_create_ex(*ctx, WIDTH, sigmoid, seed, SPX_TAPE_HOST, &u));
  if (!u) {
    spx_ctx_destroy(*ctx);
    return NULL;
  }
  *in = malloc((size_t)N * 4 * H * W * sizeof(float)), *tg = malloc((size_t)N * 3 * H * W * sizeof(float));
  make_data(*in, *tg);
  return u;
}

static void test_fd_whole_unet(void) {
  spx_ctx *ctx;
  float *in, *tg;
  spx_unet *u = host_unet(&ctx, 1, 7, &in, &tg);
  if (!u) return;
  spx_tape *t = spx_unet_tape(u);
  /* BN betas start at 0 and gammas at 1: perturb them so nothing is at a special point */
  unsigned long long s = 99;
  for (int i = 0; i < spx_unet_tensor_count(u); i++) {
    const char *name = spx_unet_tensor_name(u, i, NULL, NULL);
    int id = spx_unet_value_id(u, name);
    double *p = spx_tape_host(t, id);
    for (size_t k = 0; k < spx_tape_numel(t, id); k++)
      if (strstr(name, "running_var")) p[k] = 0.5 + spx_t_uniform(&s);
      else if (!strstr(name, "running_mean")) p[k] += 0.2 * (spx_t_uniform(&s) - 0.5);
  }
  CHECK_OK(ctx, spx_unet_zero_grad(u));
  CHECK_OK(ctx, spx_unet_forward_loss(u, in, tg, N, H, W, NULL, NULL));
  CHECK_OK(ctx, spx_unet_backward(u));
  /* central differences on 3 entries of every parameter tensor. A ReLU or max-pool kink inside
   * [x-h, x+h] shows as one-sided differences that disagree: such samples are skipped (and
   * counted; they must stay rare). */
  double worst = 0, h = 1e-6, l0 = host_loss(u, in, tg); /* loss at the unperturbed point */
  int checked = 0, kinks = 0;
  for (int i = 0; i < spx_unet_tensor_count(u); i++) {
    const char *name = spx_unet_tensor_name(u, i, NULL, NULL);
    if (strstr(name, "running_")) continue;
    int id = spx_unet_value_id(u, name);
    double *p = spx_tape_host(t, id), *g = spx_tape_host_grad(t, id);
    size_t n = spx_tape_numel(t, id);
    double gmax = 1e-3; /* floor: below it the ~1e-10 rounding noise of the differences dominates */
    for (size_t k = 0; k < n; k++) gmax = fmax(gmax, fabs(g[k]));
    for (int r = 0; r < 3; r++) {
      size_t k = (size_t)(spx_t_uniform(&s) * (double)n);
      double p0 = p[k];
      p[k] = p0 + h;
      double lp = host_loss(u, in, tg);
      p[k] = p0 - h;
      double lm = host_loss(u, in, tg);
      p[k] = p0;
      double num = (lp - lm) / (2 * h), e = fabs(num - g[k]) / gmax;
      if (fabs((lp - l0) - (l0 - lm)) / h > 1e-5 + 1e-3 * fabs(num)) { /* h*f'' is far below */
        kinks++;
        continue;
      }
      if (!(e <= worst)) worst = e;
      if (!(e <= (getenv("SPX_FD_VERBOSE") ? 1e-8 : 1e-5)))
        fprintf(stderr, "  %s[%zu]: analytic %.9g numeric %.9g\n", name, k, g[k], num);
      checked++;
    }
  }
  fprintf(stderr,
          "  FD over %d parameters of a width-%d UNet (%dx4x%dx%d): max error %.3g (relative to tensor max), "
          "%d samples at a kink skipped\n",
          checked, WIDTH, N, H, W, worst, kinks);
  /* double precision everywhere. Central differences with h = 1e-6 carry ~1e-10 of rounding
   * noise (loss ~0.5 summed over ~7e3 terms, / 2h) and ~h^2 of truncation error, so right
   * gradients land near 1e-7 of the tensor's largest gradient (floored at 1e-3); 1e-5 still
   * catches any wiring or accumulation error, which is O(1). */
  CHECK_MSG(worst <= 1e-5, "max FD error %.3g", worst);
  CHECK(kinks <= 8);
  CHECK(checked > 100);
  free(in), free(tg);
  spx_unet_destroy(u);
  spx_ctx_destroy(ctx);
}

static void test_accumulate_and_plans(void) {
  spx_ctx *ctx;
  float *in, *tg;
  spx_unet *u = host_unet(&ctx, 0, 3, &in, &tg);
  if (!u) return;
  spx_tape *t = spx_unet_tape(u);
  int id = spx_unet_value_id(u, "up2.conv.double_conv.3.weight");
  size_t n = spx_tape_numel(t, id);
  double *g1 = malloc(n * sizeof(double));
  CHECK_OK(ctx, spx_unet_forward_loss(u, in, tg, N, H, W, NULL, NULL));
  int plans = spx_tape_plan_count(t);
  CHECK(plans == 1);
  CHECK_OK(ctx, spx_unet_backward(u));
  memcpy(g1, spx_tape_host_grad(t, id), n * sizeof(double));
  double gmax = 0;
  for (size_t k = 0; k < n; k++) gmax = fmax(gmax, fabs(g1[k]));
  CHECK(gmax > 0);
  /* same inputs again (batch-norm statistics do not depend on the running stats): grads double */
  CHECK_OK(ctx, spx_unet_forward_loss(u, in, tg, N, H, W, NULL, NULL));
  CHECK(spx_tape_plan_count(t) == plans); /* steady state: nothing planned */
  CHECK_OK(ctx, spx_unet_backward(u));
  double e = 0;
  for (size_t k = 0; k < n; k++) e = fmax(e, fabs(spx_tape_host_grad(t, id)[k] - 2 * g1[k]));
  CHECK_MSG(e <= 1e-12 * gmax, "accumulated gradient off by %.3g", e);
  CHECK_OK(ctx, spx_unet_zero_grad(u));
  e = 0;
  for (size_t k = 0; k < n; k++) e = fmax(e, fabs(spx_tape_host_grad(t, id)[k]));
  CHECK(e == 0);
  /* inference: a new plan for the new mode, no gradients, backward refused */
  size_t nout = (size_t)N * 3 * H * W;
  float *out = malloc(nout * sizeof(float));
  CHECK_OK(ctx, spx_unet_forward(u, in, N, H, W, 0, out));
  CHECK(spx_tape_plan_count(t) == plans + 1);
  CHECK(spx_unet_backward(u) == SPX_E_STATE);
  CHECK_OK(ctx, spx_unet_forward(u, in, N, H, W, 0, out));
  CHECK(spx_tape_plan_count(t) == plans + 1);
  /* a new shape plans once more; too small an input is refused with a message */
  CHECK_OK(ctx, spx_unet_forward(u, in, 1, H, W, 0, out));
  CHECK(spx_tape_plan_count(t) == plans + 2);
  CHECK(spx_unet_forward(u, in, 1, 15, 40, 0, out) == SPX_E_ARG);
  CHECK(strstr(spx_ctx_message(ctx), "16") != NULL);
  free(out), free(g1), free(in), free(tg);
  spx_unet_destroy(u);
  spx_ctx_destroy(ctx);
}

/* Device tape vs host tape, same initialisation. float32 vs double: the losses agree to ~1e-6
 * relative; gradients of a tensor agree to ~1e-4 of that tensor's largest gradient (batch norm on
 * a 2x2 bottleneck amplifies rounding), so 2e-3 catches any wiring error (those are O(1)). */
static void test_device_matches_host(void) {
  spx_ctx *ctx = spx_nt_require();
  if (!ctx) return;
  spx_ctx *hctx = NULL;
  CHECK(spx_t_ctx_create(&hctx) == SPX_OK);
  spx_unet *ud = NULL, *uh = NULL;
  CHECK_OK(ctx, spx_unet_create_ex(ctx, WIDTH, 1, 11, SPX_TAPE_DEVICE, &ud));
  CHECK_OK(hctx, spx_unet_create_ex(hctx, WIDTH, 1, 11, SPX_TAPE_HOST, &uh));
  size_t nin = (size_t)N * 4 * H * W, nout = (size_t)N * 3 * H * W;
  float *in = malloc(nin * sizeof(float)), *tg = malloc(nout * sizeof(float));
  float *od = malloc(nout * sizeof(float)), *oh = malloc(nout * sizeof(float));
  make_data(in, tg);
  if (ud && uh) {
    float ld = 0, lh = 0;
    CHECK_OK(ctx, spx_unet_forward_loss(ud, in, tg, N, H, W, od, &ld));
    CHECK_OK(hctx, spx_unet_forward_loss(uh, in, tg, N, H, W, oh, &lh));
    CHECK_NEAR(ld, lh, 0, 1e-5);
    double *ohd = malloc(nout * sizeof(double));
    spx_nt_to_double(oh, ohd, nout);
    CHECK_CLOSE_ARR(od, ohd, nout, 1e-3, 1e-3);
    free(ohd);
    CHECK_OK(ctx, spx_unet_backward(ud));
    CHECK_OK(hctx, spx_unet_backward(uh));
    spx_tape *th = spx_unet_tape(uh);
    double worst = 0;
    for (int i = 0; i < spx_unet_tensor_count(ud); i++) {
      const char *name = spx_unet_tensor_name(ud, i, NULL, NULL);
      if (strstr(name, "running_")) continue;
      int id = spx_unet_value_id(uh, name);
      size_t n = spx_tape_numel(th, id);
      float *g = malloc(n * sizeof(float));
      CHECK_OK(ctx, spx_unet_read(ud, name, SPX_UNET_GRAD, g, n));
      const double *gh = spx_tape_host_grad(th, id);
      double gmax = 1e-12, e = 0;
      for (size_t k = 0; k < n; k++) gmax = fmax(gmax, fabs(gh[k]));
      for (size_t k = 0; k < n; k++) e = fmax(e, fabs(g[k] - gh[k]) / gmax);
      if (!(e <= worst)) worst = e;
      free(g);
    }
    fprintf(stderr, "  device vs host gradients: max error %.3g (relative to tensor max)\n", worst);
    CHECK_MSG(worst <= 2e-3, "device gradients differ from the host tape by %.3g", worst);
  }
  free(in), free(tg), free(od), free(oh);
  spx_unet_destroy(ud);
  spx_unet_destroy(uh);
  spx_ctx_destroy(hctx);
  spx_ctx_destroy(ctx);
}

static void test_op_table(void) {
  for (int k = 0; k < NOPS; k++) {
    const tp_op *op = spx_tp_op(k);
    const char *name = spx_tp_op_name(k);
    CHECK_MSG(op && op->back_host && op->back_dev, "op kind %d: incomplete table row", k);
    CHECK_MSG(strcmp(name, "?") != 0, "op kind %d has no name", k);
    for (int j = 0; j < k; j++)
      CHECK_MSG(strcmp(name, spx_tp_op_name(j)) != 0, "op kinds %d and %d share the name %s", j, k, name);
  }
  CHECK(spx_tp_op(NOPS) == NULL && spx_tp_op(-1) == NULL && !strcmp(spx_tp_op_name(NOPS), "?") &&
        !strcmp(spx_tp_op_name(-1), "?"));
}

int main(void) {
  SPX_RUN(test_op_table);
  SPX_RUN(test_fd_whole_unet);
  SPX_RUN(test_accumulate_and_plans);
  SPX_RUN(test_device_matches_host);
  return spx_test_summary();
}

/* The multi-network tape ops (lib/nn/tape_op_*.c: strided conv, instance norm, average pool, MSE,
 * axpby; detach / slice aliases and transfers in lib/nn/tape.c) on a tiny PatchGAN-like graph:
 * 4x4 convolutions with stride 2 / 1 and padding 2, instance norm, LeakyReLU, 3x3 average
 * pooling, batch slices, MSE against constants, L1, weighted sums (axpby).
 *  - finite differences on the HOST backend (double references) for every parameter and the input;
 *  - detach: a detached branch adds nothing to the gradients (and the same branch undetached does);
 *  - two tapes chained by spx_tape_transfer (values forward, the input gradient back between
 *    backward_begin and backward_run) give the gradients of the single-tape graph;
 *  - the DEVICE backend matches the HOST backend on the loss and every gradient. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "nn/tape.h"
#include "nn_testutil.h"

enum { N = 2, C = 3, H = 13, W = 15 };
enum { P_W1, P_B1, P_W2, P_B2, P_W3, P_B3, NP };
static const int pshape[NP][4] = {{4, 3, 4, 4}, {4, 1, 1, 1}, {5, 4, 4, 4}, {5, 1, 1, 1}, {1, 5, 4, 4}, {1, 1, 1, 1}};

typedef struct net {
  spx_tape *t;
  int p[NP];
  int x, loss;
  int detach_mode, pool; /* the graph forward_one builds */
  spx_tape *src;         /* two tapes: the tape of a, handed in as the input */
  int a;
} net;

static int declare(net *nt, spx_tape *t, int first, int last) {
  nt->t = t;
  for (int i = 0; i < NP; i++) nt->p[i] = -1;
  for (int i = first; i <= last; i++) nt->p[i] = spx_tape_param(t, pshape[i][0], pshape[i][1], pshape[i][2], pshape[i][3]);
  return spx_tape_alloc_params(t) == SPX_OK;
}

static void init_params(net *nt, int first, int last) {
  unsigned long long s = 1234;
  for (int i = 0; i < first; i++)
    for (int k = 0; k < pshape[i][0] * pshape[i][1] * pshape[i][2] * pshape[i][3]; k++) spx_t_uniform(&s);
  for (int i = first; i <= last; i++) {
    size_t n = (size_t)pshape[i][0] * pshape[i][1] * pshape[i][2] * pshape[i][3];
    float *v = malloc(4 * n);
    spx_nt_rand(v, n, -0.4f, 0.4f, &s);
    spx_tape_write(nt->t, nt->p[i], v);
    free(v);
  }
}

static float g_x[N * C * H * W], g_tg[1 * 5 * 8 * 9];

/* Part A: x -> a (the "generator" half). */
static int part_a(net *nt, int x) {
  spx_tape *t = nt->t;
  int a = spx_tape_conv_strided(t, x, nt->p[P_W1], nt->p[P_B1], 2, 2);
  return spx_tape_act(t, SPX_ACT_LEAKY_RELU, 0.2f, a);
}

/* Part B: a (and x) -> loss. detach_mode: 0 no extra term, 1 a detached extra term, 2 the same
 * term undetached. */
static int part_b(net *nt, int a, int x_pool_src, int detach_mode) {
  spx_tape *t = nt->t;
  int b = spx_tape_conv_strided(t, a, nt->p[P_W2], nt->p[P_B2], 1, 2);
  b = spx_tape_act(t, SPX_ACT_LEAKY_RELU, 0.2f, spx_tape_instnorm(t, b, 1e-5f));
  int c = spx_tape_conv_strided(t, b, nt->p[P_W3], nt->p[P_B3], 1, 2);
  int fake = spx_tape_slice_batch(t, c, 0, 1), real = spx_tape_slice_batch(t, c, 1, 1);
  int l_gan = spx_tape_mse_const(t, fake, 1.0f);
  int l_d = spx_tape_axpby(t, 0.5f, spx_tape_mse_const(t, fake, 0.0f), 0.5f, spx_tape_mse_const(t, real, 1.0f));
  int tg = spx_tape_input(t, 1, 5, 8, 9, g_tg);
  int fm = spx_tape_l1(t, spx_tape_slice_batch(t, b, 1, 1), tg);
  int loss = spx_tape_axpby(t, 1.0f, l_gan, 0.1f, fm);
  loss = spx_tape_axpby(t, 1.0f, loss, 0.7f, l_d);
  if (x_pool_src >= 0) { /* the next scale: pooled input through the shared first conv */
    int d = spx_tape_conv_strided(t, spx_tape_avgpool3(t, x_pool_src), nt->p[P_W1], nt->p[P_B1], 2, 2);
    loss = spx_tape_axpby(t, 1.0f, loss, 0.3f, spx_tape_mse_const(t, d, 0.2f));
  }
  if (detach_mode) {
    int e = detach_mode == 1 ? spx_tape_detach(t, b) : b;
    loss = spx_tape_axpby(t, 1.0f, loss, 2.0f, spx_tape_mse_const(t, e, 0.5f));
  }
  return loss;
}

/* The whole graph on one tape (pool: with the pooled branch). */
static spx_status build_one(spx_tape *t, void *user) {
  net *nt = user;
  nt->x = spx_tape_input(t, N, C, H, W, g_x);
  spx_tape_requires_grad(t, nt->x); /* in the build: it is part of the plan */
  nt->loss = part_b(nt, part_a(nt, nt->x), nt->pool ? nt->x : -1, nt->detach_mode);
  return SPX_OK;
}

static spx_status forward_one(net *nt, int detach_mode) {
  nt->detach_mode = detach_mode, nt->pool = 1;
  return spx_tape_pass(nt->t, 1, 7 + (uint64_t)detach_mode, build_one, nt);
}

/* Two tapes: A's part, x -> a */
static spx_status build_a(spx_tape *t, void *user) {
  net *nt = user;
  nt->x = spx_tape_input(t, N, C, H, W, g_x);
  spx_tape_requires_grad(t, nt->x);
  nt->a = part_a(nt, nt->x);
  return SPX_OK;
}

/* ... and B's, z (= A's a, handed over) -> loss */
static spx_status build_b(spx_tape *t, void *user) {
  net *nt = user;
  int32_t sa[4];
  spx_tape_shape(nt->src, nt->a, sa);
  nt->x = spx_tape_input(t, sa[0], sa[1], sa[2], sa[3], NULL);
  spx_tape_requires_grad(t, nt->x);
  spx_status st = spx_tape_transfer(t, nt->x, 0, 0, nt->src, nt->a, 0, 0, spx_tape_numel(nt->src, nt->a), 0);
  nt->loss = part_b(nt, nt->x, -1, 0);
  return st;
}

static double loss_of(net *nt) {
  float v = NAN;
  if (forward_one(nt, 0) || spx_tape_read(nt->t, nt->loss, &v)) return NAN;
  return spx_tape_get_backend(nt->t) == SPX_TAPE_HOST ? spx_tape_host(nt->t, nt->loss)[0] : v;
}

static void make_data(void) {
  unsigned long long s = 77;
  spx_nt_rand(g_x, sizeof g_x / 4, -1, 1, &s);
  spx_nt_rand(g_tg, sizeof g_tg / 4, -1, 1, &s);
}

static void test_fd(void) {
  spx_ctx *ctx = NULL;
  CHECK(spx_t_ctx_create(&ctx) == SPX_OK);
  spx_tape *t = NULL;
  CHECK_OK(ctx, spx_tape_create(ctx, SPX_TAPE_HOST, &t));
  net nt;
  CHECK(declare(&nt, t, 0, NP - 1));
  init_params(&nt, 0, NP - 1);
  CHECK_OK(ctx, forward_one(&nt, 0));
  CHECK_OK(ctx, spx_tape_zero_grad(t));
  CHECK_OK(ctx, spx_tape_backward(t, nt.loss));
  double worst = 0, h = 1e-6;
  int kinks = 0, checked = 0;
  unsigned long long s = 5;
  double *gs[NP + 1]; /* the input's gradient lives in the arena: the next pass reuses it */
  for (int i = 0; i <= NP; i++) {
    int id = i < NP ? nt.p[i] : nt.x;
    gs[i] = malloc(8 * spx_tape_numel(t, id));
    memcpy(gs[i], spx_tape_host_grad(t, id), 8 * spx_tape_numel(t, id));
  }
  for (int i = 0; i <= NP; i++) {
    int id = i < NP ? nt.p[i] : nt.x;
    size_t n = spx_tape_numel(t, id);
    double *g = gs[i], gmax = 1e-3;
    for (size_t k = 0; k < n; k++) gmax = fmax(gmax, fabs(g[k]));
    for (int r = 0; r < (i == NP ? 12 : 6); r++) {
      size_t k = (size_t)(spx_t_uniform(&s) * (double)n);
      double *p = i < NP ? spx_tape_host(t, id) : NULL, p0;
      if (i < NP) p0 = p[k], p[k] = p0 + h;
      else p0 = g_x[k], g_x[k] = (float)p0, p0 = g_x[k];
      double lp, lm, l0;
      if (i < NP) {
        lp = loss_of(&nt);
        p = spx_tape_host(t, id), p[k] = p0 - h, lm = loss_of(&nt);
        p = spx_tape_host(t, id), p[k] = p0 + 2 * h, l0 = loss_of(&nt); /* one-sided check for kinks */
        p = spx_tape_host(t, id), p[k] = p0;
      } else { /* the input is float: perturb by a representable step */
        float hf = 1.0f / 1024;
        g_x[k] = (float)p0 + hf, lp = loss_of(&nt);
        g_x[k] = (float)p0 - hf, lm = loss_of(&nt);
        g_x[k] = (float)p0 + 2 * hf, l0 = loss_of(&nt);
        g_x[k] = (float)p0;
        double num = (lp - lm) / (2 * hf), num2 = (l0 - lp) / hf, e = fabs(num - g[k]) / gmax;
        if (fabs(num - num2) > 1e-3 * gmax + 0.05 * fabs(num)) { /* curvature or kink: skip */
          kinks++;
          continue;
        }
        worst = fmax(worst, e > 1e-2 ? e : 0); /* second-order term at this step size */
        checked++;
        continue;
      }
      double num = (lp - lm) / (2 * h), num2 = (l0 - lp) / h, e = fabs(num - g[k]) / gmax;
      if (fabs(num - num2) > 1e-4 * gmax + 1e-3 * fabs(num)) {
        kinks++;
        continue;
      }
      worst = fmax(worst, e);
      checked++;
    }
    free(g);
  }
  printf("  FD: %d entries checked (%d skipped at kinks), worst relative error %.3g\n", checked, kinks, worst);
  CHECK_MSG(worst < 1e-5, "fd error %.3g", worst);
  CHECK(kinks * 4 < checked);
  spx_tape_destroy(t);
  spx_ctx_destroy(ctx);
}

static void grads(net *nt, double **out) {
  for (int i = 0; i <= NP; i++) {
    int id = i < NP ? nt->p[i] : nt->x;
    size_t n = spx_tape_numel(nt->t, id);
    float *f = malloc(4 * n);
    out[i] = malloc(8 * n);
    spx_tape_read_grad(nt->t, id, f);
    spx_nt_to_double(f, out[i], n);
    free(f);
  }
}

/* max |a - b| / max(max |b|, 1e-3): the floor because a conv bias before an instance norm has a
 * zero gradient (the norm removes per-channel constants), which float32 gives as ~1e-9 noise. */
static double max_rel(const double *a, const double *b, size_t n) {
  double num = 0, den = 1e-3;
  for (size_t i = 0; i < n; i++) num = fmax(num, fabs(a[i] - b[i])), den = fmax(den, fabs(b[i]));
  return num / den;
}

static size_t numel_of(int i) {
  return i < NP ? (size_t)pshape[i][0] * pshape[i][1] * pshape[i][2] * pshape[i][3] : (size_t)N * C * H * W;
}

static void run_backend(spx_ctx *ctx, spx_tape_backend be, double **ref_grads, double *ref_loss, double **keep) {
  spx_tape *t = NULL;
  if (spx_tape_create(ctx, be, &t)) return;
  net nt;
  CHECK(declare(&nt, t, 0, NP - 1));
  init_params(&nt, 0, NP - 1);
  double *g0[NP + 1], *g1[NP + 1], *g2[NP + 1];
  /* detach: the detached term changes the loss but no gradient */
  CHECK_OK(ctx, forward_one(&nt, 0));
  float l0 = 0, l1 = 0;
  spx_tape_read(t, nt.loss, &l0);
  CHECK_OK(ctx, spx_tape_zero_grad(t));
  CHECK_OK(ctx, spx_tape_backward(t, nt.loss));
  grads(&nt, g0);
  CHECK_OK(ctx, forward_one(&nt, 1));
  spx_tape_read(t, nt.loss, &l1);
  CHECK(l1 != l0);
  CHECK_OK(ctx, spx_tape_zero_grad(t));
  CHECK_OK(ctx, spx_tape_backward(t, nt.loss));
  grads(&nt, g1);
  CHECK_OK(ctx, forward_one(&nt, 2));
  CHECK_OK(ctx, spx_tape_zero_grad(t));
  CHECK_OK(ctx, spx_tape_backward(t, nt.loss));
  grads(&nt, g2);
  int same = 1, differ = 0;
  for (int i = 0; i <= NP; i++) {
    same &= memcmp(g0[i], g1[i], 8 * numel_of(i)) == 0;
    differ |= memcmp(g0[i], g2[i], 8 * numel_of(i)) != 0;
  }
  CHECK_MSG(same, "a detached term changed a gradient");
  CHECK_MSG(differ, "the undetached term changed no gradient");
  /* two tapes: A holds w1/b1 and the input, B the rest; a handed over, its gradient handed back */
  spx_tape *ta = NULL, *tb = NULL;
  CHECK_OK(ctx, spx_tape_create(ctx, be, &ta));
  CHECK_OK(ctx, spx_tape_create(ctx, be, &tb));
  net na, nb;
  CHECK(declare(&na, ta, P_W1, P_B1) && declare(&nb, tb, P_W2, P_B3));
  init_params(&na, P_W1, P_B1), init_params(&nb, P_W2, P_B3);
  CHECK_OK(ctx, spx_tape_pass(ta, 1, 1, build_a, &na));
  nb.src = ta, nb.a = na.a;
  CHECK_OK(ctx, spx_tape_pass(tb, 1, 1, build_b, &nb));
  const int a = na.a, z = nb.x;
  CHECK_OK(ctx, spx_tape_zero_grad(ta));
  CHECK_OK(ctx, spx_tape_zero_grad(tb));
  CHECK_OK(ctx, spx_tape_backward(tb, nb.loss));
  CHECK_OK(ctx, spx_tape_backward_begin(ta));
  CHECK_OK(ctx, spx_tape_transfer(ta, a, 0, 1, tb, z, 0, 1, spx_tape_numel(ta, a), 1));
  CHECK_OK(ctx, spx_tape_backward_run(ta));
  /* the single-tape graph without the pooled branch, for comparison */
  nt.detach_mode = 0, nt.pool = 0;
  CHECK_OK(ctx, spx_tape_pass(t, 1, 10, build_one, &nt)); /* a graph of its own: a key of its own */
  CHECK_OK(ctx, spx_tape_zero_grad(t));
  CHECK_OK(ctx, spx_tape_backward(t, nt.loss));
  double e2 = 0;
  for (int i = 0; i <= NP; i++) {
    spx_tape *owner = i == NP ? ta : i <= P_B1 ? ta : tb;
    int id = i == NP ? na.x : i <= P_B1 ? na.p[i] : nb.p[i];
    int id1 = i == NP ? nt.x : nt.p[i];
    size_t n = numel_of(i);
    float *f1 = malloc(4 * n), *f2 = malloc(4 * n);
    spx_tape_read_grad(owner, id, f1);
    spx_tape_read_grad(t, id1, f2);
    double *d1 = malloc(8 * n), *d2 = malloc(8 * n);
    spx_nt_to_double(f1, d1, n), spx_nt_to_double(f2, d2, n);
    e2 = fmax(e2, max_rel(d1, d2, n));
    free(f1), free(f2), free(d1), free(d2);
  }
  printf("  %s: two tapes vs one tape, max gradient difference %.3g\n", be == SPX_TAPE_HOST ? "host" : "device", e2);
  CHECK_MSG(e2 < 1e-6, "two-tape gradients differ by %.3g", e2);
  spx_tape_destroy(ta);
  spx_tape_destroy(tb);
  if (ref_grads) {
    double e = 0;
    for (int i = 0; i <= NP; i++) {
      double ei = max_rel(g0[i], ref_grads[i], numel_of(i));
      if (!(ei < 2e-4)) printf("  tensor %d: device vs host %.3g\n", i, ei);
      e = fmax(e, ei);
    }
    double el = fabs(l0 - *ref_loss) / fabs(*ref_loss);
    printf("  device vs host: loss %.3g, gradients %.3g\n", el, e);
    /* float32 sums in the device's orders against double: the worst gradient is a bias behind an
     * instance norm, whose backward cancels (relative to the tensor's largest value: 5.4e-5 with
     * the CPU class's kernels, 9.5e-5 with the GPU class's direct ones, 1.44e-4 with its GEMM
     * engine, which sums a data gradient's taps in another order) */
    CHECK_MSG(el < 1e-5 && e < 2e-4, "device vs host: loss %.3g gradients %.3g", el, e);
  }
  *ref_loss = l0;
  for (int i = 0; i <= NP; i++) {
    free(g1[i]), free(g2[i]);
    if (keep) keep[i] = g0[i];
    else free(g0[i]);
  }
  spx_tape_destroy(t);
}

static void test_backends(void) {
  spx_ctx *ctx = NULL;
  CHECK(spx_t_ctx_create(&ctx) == SPX_OK);
  double loss = 0, *host[NP + 1] = {0};
  run_backend(ctx, SPX_TAPE_HOST, NULL, &loss, host);
  spx_ctx_destroy(ctx);
  ctx = spx_nt_open();
  CHECK(ctx != NULL);
  if (ctx) {
    run_backend(ctx, SPX_TAPE_DEVICE, host, &loss, NULL);
    spx_ctx_destroy(ctx);
  }
  for (int i = 0; i <= NP; i++) free(host[i]);
}

int main(void) {
  make_data();
  SPX_RUN(test_fd);
  SPX_RUN(test_backends);
  return spx_test_summary();
}
